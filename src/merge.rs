//! `vdbphoton merge`: tiles of a frame assembled into one image, and renders
//! of the same pixels with different seeds averaged (weighted by their
//! samples), so one frame can be spread over many machines by area and by
//! time.
//!
//! The inputs are EXRs vdbphoton wrote. Inputs are grouped by seed: the
//! tiles of one seed must not overlap and must together cover the frame
//! (or, when every input has the same data window, that window), and the
//! groups are averaged pixel by pixel, each weighted by its samples per
//! pixel. With one group the pixels are copied, so the merged frame is the
//! same bits as a render of the whole frame.
//!
//! Denoising happens here for tiles (never per tile: a tile's denoised
//! edge would not meet its neighbour's): with `--denoise`, or when every
//! input's render asked for it, the merged frame is denoised with the
//! merged `albedo` layer as its guide. A denoised input (a whole frame
//! rendered with `--denoise`) takes part with its raw pixels, its `noisy`
//! layer.

use crate::error::{Error, Result};
use crate::film::Region;
use crate::image::{read_exr, write_exr, write_png_preview, Image, View};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Header settings every input must share whatever the integrator:
/// renders of other scenes, frames or settings cannot be merged. Each
/// integrator adds its own ([`must_agree`]).
pub const MUST_AGREE: &[&str] = &[
    "vdbphoton/version",
    "vdbphoton/scene_hash",
    "vdbphoton/integrator",
    "vdbphoton/max_bounces",
    "vdbphoton/frame",
];

/// Every header key inputs must share: [`MUST_AGREE`] and the registered
/// integrators' keys (`crate::integrator::Registration::header_keys`).
pub fn must_agree() -> Vec<&'static str> {
    let mut keys = MUST_AGREE.to_vec();
    for reg in crate::integrator::REGISTRY {
        for k in reg.header_keys {
            if !keys.contains(k) {
                keys.push(k);
            }
        }
    }
    keys
}

struct Input {
    path: PathBuf,
    image: Image,
    attrs: BTreeMap<String, String>,
    region: Region,
    spp: u64,
}

impl Input {
    fn read(path: &Path) -> Result<Input> {
        let (mut image, attrs) = read_exr(path)?;
        crate::denoise::restore_raw(&mut image);
        let attrs: BTreeMap<String, String> = attrs.into_iter().collect();
        let spp = attrs
            .get("vdbphoton/spp")
            .and_then(|s| s.parse::<u64>().ok())
            .filter(|&s| s > 0)
            .ok_or_else(|| {
                Error::file(
                    path,
                    "has no vdbphoton/spp in its header: not a render vdbphoton wrote",
                )
            })?;
        let (x0, y0) = image.origin();
        let region = Region {
            x0: x0 as u32,
            y0: y0 as u32,
            x1: (x0 + image.width()) as u32,
            y1: (y0 + image.height()) as u32,
        };
        Ok(Input {
            path: path.to_path_buf(),
            image,
            attrs,
            region,
            spp,
        })
    }
    fn seed(&self) -> &str {
        self.attrs.get("vdbphoton/seed").map_or("?", |s| s.as_str())
    }
    fn layers(&self) -> Vec<(String, Vec<String>)> {
        self.image
            .layers()
            .iter()
            .map(|l| (l.name().to_string(), l.channels().to_vec()))
            .collect()
    }
}

/// How a merge writes its result.
#[derive(Debug, Clone, Copy, Default)]
pub struct MergeOptions<'a> {
    /// Also write a PNG preview here.
    pub preview: Option<&'a Path>,
    /// The preview's exposure (default: the inputs').
    pub exposure: Option<f32>,
    /// The preview's view transform (default: the inputs').
    pub view: Option<View>,
    /// Denoise the merged frame (also done when every input asked for it).
    pub denoise: bool,
}

/// What a merge made.
#[derive(Debug, Clone)]
pub struct MergeSummary {
    pub width: u32,
    pub height: u32,
    /// Inputs per seed group, in seed order.
    pub groups: Vec<(String, usize)>,
    /// Samples per pixel of the result (the groups' sum).
    pub spp: u64,
    /// The files written: the EXR, then the preview if any.
    pub outputs: Vec<PathBuf>,
}

/// The bounding box of the pixels `covered` leaves out (`None`: none).
fn uncovered(covered: &[bool], area: Region) -> Option<Region> {
    let w = area.width() as usize;
    let mut out: Option<Region> = None;
    for (i, _) in covered.iter().enumerate().filter(|(_, c)| !**c) {
        let (x, y) = (area.x0 + (i % w) as u32, area.y0 + (i / w) as u32);
        out = Some(match out {
            None => Region {
                x0: x,
                y0: y,
                x1: x + 1,
                y1: y + 1,
            },
            Some(r) => Region {
                x0: r.x0.min(x),
                y0: r.y0.min(y),
                x1: r.x1.max(x + 1),
                y1: r.y1.max(y + 1),
            },
        });
    }
    out
}

/// Tiles of a `--tile I/N` set that are not among `tiles`, with their
/// regions, when the inputs say which tiles they are.
fn missing_tiles(tiles: &[&Input], width: u32, height: u32) -> Option<String> {
    let parse = |t: &Input| -> Option<(u32, u32)> {
        let (i, n) = t.attrs.get("vdbphoton/tile")?.split_once('/')?;
        Some((i.parse().ok()?, n.parse().ok()?))
    };
    let ids: Vec<(u32, u32)> = tiles.iter().map(|t| parse(t)).collect::<Option<_>>()?;
    let n = ids.first()?.1;
    if ids.iter().any(|t| t.1 != n) {
        return None;
    }
    let missing: Vec<String> = (0..n)
        .filter(|i| !ids.iter().any(|t| t.0 == *i))
        .filter_map(|i| Region::tile(i, n, width, height).map(|r| format!("{i}/{n} ({r})")))
        .collect();
    (!missing.is_empty()).then(|| missing.join(", "))
}

/// Reads `inputs`, checks them and writes their merge to `out` (and a PNG
/// preview, by default with the exposure and view transform the inputs
/// were rendered with), atomically. Every problem is one line naming the
/// files.
pub fn merge(out: &Path, inputs: &[PathBuf], options: &MergeOptions) -> Result<MergeSummary> {
    let MergeOptions {
        preview,
        exposure,
        view,
        ..
    } = *options;
    crate::render::prepare_outputs(out, preview)?;
    if inputs.is_empty() {
        return Err(Error::Argument("merge: no input EXR given".into()));
    }
    for p in inputs {
        if p.canonicalize().ok() == out.canonicalize().ok() && out.exists() {
            return Err(Error::file(p, "is also the output of the merge"));
        }
    }
    let mut files: Vec<Input> = inputs
        .iter()
        .map(|p| Input::read(p))
        .collect::<Result<_>>()?;
    // The denoiser's `half` layer is written once every pixel of a render
    // has two samples: kept only when every input has it.
    use crate::denoise::HALF_LAYER;
    if !files.iter().all(|f| f.image.layer(HALF_LAYER).is_some()) {
        for f in &mut files {
            f.image.remove_layer(HALF_LAYER);
        }
    }
    let first = &files[0];
    let (dw, dh) = first.image.display_size();
    // The frame is allocated whole below: a header may claim any size.
    if dw
        .checked_mul(dh)
        .is_none_or(|n| n as u64 > crate::scene::MAX_PIXELS)
    {
        return Err(Error::file(
            &first.path,
            format!(
                "claims a {dw} x {dh} frame, more than the {} pixels a render may have",
                crate::scene::MAX_PIXELS
            ),
        ));
    }
    let layers = first.layers();
    for f in &files[1..] {
        if f.image.display_size() != (dw, dh) {
            let (w, h) = f.image.display_size();
            return Err(Error::file(
                &f.path,
                format!(
                    "is part of a {w} x {h} image but '{}' of a {dw} x {dh} one",
                    first.path.display()
                ),
            ));
        }
        if f.layers() != layers {
            let names = |l: &[(String, Vec<String>)]| {
                let v: Vec<&str> = l.iter().map(|x| x.0.as_str()).collect();
                if v.is_empty() {
                    "none".to_string()
                } else {
                    v.join(", ")
                }
            };
            return Err(Error::file(
                &f.path,
                format!(
                    "has layers {} but '{}' has {} (render all parts with the same --aovs and --denoise)",
                    names(&f.layers()),
                    first.path.display(),
                    names(&layers)
                ),
            ));
        }
        // Parts whose integrators `auto` chose may differ in it (each
        // job runs its own pilots, and near a tie they may choose
        // differently): both estimate the same image, so their pixels
        // merge, and only each integrator's own settings go unchecked.
        let by_auto = |i: &Input| i.attrs.contains_key("vdbphoton/auto");
        let integrator = |i: &Input| i.attrs.get("vdbphoton/integrator").cloned();
        let mixed = by_auto(first) && by_auto(f) && integrator(first) != integrator(f);
        for key in must_agree() {
            if mixed && (!MUST_AGREE.contains(&key) || key == "vdbphoton/integrator") {
                continue;
            }
            let (a, b) = (first.attrs.get(key), f.attrs.get(key));
            if a != b {
                let show = |v: Option<&String>| v.map_or("(none)".to_string(), |s| s.clone());
                return Err(Error::file(
                    &f.path,
                    format!(
                        "was rendered with {key} = {} but '{}' with {}: not parts of one frame",
                        show(b),
                        first.path.display(),
                        show(a)
                    ),
                ));
            }
        }
    }
    // Denoising: asked for, or asked for by every input's render. The
    // library is loaded and the memory checked before anything is merged.
    let denoise = options.denoise
        || files
            .iter()
            .all(|f| f.attrs.contains_key("vdbphoton/denoise"));
    let denoiser = if denoise {
        let pixels = (dw * dh) as u64;
        let need = pixels * (crate::denoise::BYTES_PER_PIXEL + 64);
        if let Some(avail) = crate::memory::available() {
            if need > avail {
                return Err(Error::Argument(format!(
                    "merge: denoising the {dw} x {dh} frame needs about {:.1} GiB but {:.1} GiB is available",
                    need as f64 / (1u64 << 30) as f64,
                    avail as f64 / (1u64 << 30) as f64
                )));
            }
        }
        Some(crate::render::Denoiser::load(0)?)
    } else {
        None
    };
    // The area the merge covers: one shared data window, or the frame.
    let same_window = files.iter().all(|f| f.region == first.region);
    let area = if same_window {
        first.region
    } else {
        Region::full(dw as u32, dh as u32)
    };
    let mut groups: BTreeMap<&str, Vec<&Input>> = BTreeMap::new();
    for f in &files {
        groups.entry(f.seed()).or_default().push(f);
    }
    for (seed, tiles) in &groups {
        for (i, a) in tiles.iter().enumerate() {
            if let Some(b) = tiles[..i].iter().find(|b| b.region.overlaps(&a.region)) {
                return Err(Error::file(
                    &a.path,
                    format!(
                        "overlaps '{}' (regions {} and {}) with the same seed {seed}: the same pixels twice",
                        b.path.display(),
                        a.region,
                        b.region
                    ),
                ));
            }
        }
        let mut covered = vec![false; area.pixels()];
        for t in tiles {
            for y in t.region.y0..t.region.y1 {
                for x in t.region.x0..t.region.x1 {
                    if area.contains(x, y) {
                        let i =
                            (y - area.y0) as usize * area.width() as usize + (x - area.x0) as usize;
                        covered[i] = true;
                    }
                }
            }
        }
        if let Some(gap) = uncovered(&covered, area) {
            let which = missing_tiles(tiles, dw as u32, dh as u32)
                .map(|m| format!(": tile {m} is missing"))
                .unwrap_or_default();
            return Err(Error::Argument(format!(
                "merge: no input of seed {seed} covers pixels {gap} of the {dw} x {dh} frame{which}"
            )));
        }
    }
    // Per group, the pixels of the area; then the weighted mean.
    let (w, h) = (area.width() as usize, area.height() as usize);
    let channels = 4 + layers.iter().map(|l| l.1.len()).sum::<usize>();
    let mut sums = vec![0.0f64; w * h * channels];
    let mut weight = vec![0u64; w * h];
    let mut merged = Image::new(w, h);
    for (name, cs) in &layers {
        let refs: Vec<&str> = cs.iter().map(|c| c.as_str()).collect();
        merged.add_layer(name, &refs)?;
    }
    let single = groups.len() == 1;
    for tiles in groups.values() {
        for t in tiles {
            let (tx, ty) = t.image.origin();
            for y in 0..t.image.height() {
                for x in 0..t.image.width() {
                    let (fx, fy) = ((tx + x) as u32, (ty + y) as u32);
                    if !area.contains(fx, fy) {
                        continue;
                    }
                    let (mx, my) = ((fx - area.x0) as usize, (fy - area.y0) as usize);
                    if single {
                        // Copied, not averaged: the same bits as a full render.
                        merged.set(mx, my, t.image.get(x, y));
                        for (l, m) in t.image.layers().iter().zip(0..) {
                            let v = l.get(x, y).to_vec();
                            merged.layers_mut()[m].set(mx, my, &v);
                        }
                        continue;
                    }
                    let i = my * w + mx;
                    let s = &mut sums[i * channels..(i + 1) * channels];
                    let p = t.image.get(x, y);
                    for c in 0..4 {
                        s[c] += p[c] as f64 * t.spp as f64;
                    }
                    let mut k = 4;
                    for l in t.image.layers() {
                        for v in l.get(x, y) {
                            s[k] += *v as f64 * t.spp as f64;
                            k += 1;
                        }
                    }
                    weight[i] += t.spp;
                }
            }
        }
    }
    if !single {
        for i in 0..w * h {
            let s = &sums[i * channels..(i + 1) * channels];
            let inv = 1.0 / weight[i].max(1) as f64;
            let (x, y) = (i % w, i / w);
            merged.set(
                x,
                y,
                glam::Vec4::new(
                    (s[0] * inv) as f32,
                    (s[1] * inv) as f32,
                    (s[2] * inv) as f32,
                    (s[3] * inv) as f32,
                ),
            );
            let mut k = 4;
            for l in merged.layers_mut() {
                let n = l.num_channels();
                let v: Vec<f32> = (0..n).map(|c| (s[k + c] * inv) as f32).collect();
                l.set(x, y, &v);
                k += n;
            }
        }
    }
    merged.set_window((area.x0 as usize, area.y0 as usize), (dw, dh))?;
    // Samples per pixel of a group: its fewest (tiles rendered to a time
    // budget differ); of the merge: the groups' sum.
    let group_spp: Vec<u64> = groups
        .values()
        .map(|t| t.iter().map(|f| f.spp).min().unwrap_or(0))
        .collect();
    let spp: u64 = group_spp.iter().sum();
    let mut attrs: Vec<(String, String)> = must_agree()
        .iter()
        .filter_map(|k| first.attrs.get(*k).map(|v| (k.to_string(), v.clone())))
        .collect();
    attrs.push(("vdbphoton/spp".into(), spp.to_string()));
    attrs.push((
        "vdbphoton/seed".into(),
        groups.keys().copied().collect::<Vec<_>>().join(","),
    ));
    attrs.push(("vdbphoton/merged_inputs".into(), files.len().to_string()));
    let mut integrators: Vec<&str> = files
        .iter()
        .filter_map(|f| f.attrs.get("vdbphoton/integrator").map(String::as_str))
        .collect();
    integrators.sort_unstable();
    integrators.dedup();
    if integrators.len() > 1 {
        attrs.push((
            "vdbphoton/merged_integrators".into(),
            format!("{} (chosen by auto in each part)", integrators.join(", ")),
        ));
    }
    let mut failed = None;
    if let Some(d) = &denoiser {
        attrs.push(("vdbphoton/denoise".into(), "done".into()));
        match d.apply(&mut merged) {
            Ok(()) => attrs.push(("vdbphoton/denoiser".into(), d.describe(&merged))),
            Err(e) => failed = Some(e),
        }
    }
    if let Some(s) = first.attrs.get("vdbphoton/scene") {
        attrs.push(("vdbphoton/scene".into(), s.clone()));
    }
    let exposure = exposure
        .or_else(|| first.attrs.get("vdbphoton/exposure")?.parse().ok())
        .unwrap_or(0.0);
    let view = view
        .or_else(|| View::parse(first.attrs.get("vdbphoton/view")?).ok())
        .unwrap_or_default();
    for (k, v) in [
        ("vdbphoton/exposure", exposure.to_string()),
        ("vdbphoton/view", view.name().to_string()),
    ] {
        attrs.push((k.into(), v));
    }
    write_exr(out, &merged, &attrs)?;
    let mut outputs = vec![out.to_path_buf()];
    if let Some(p) = preview {
        write_png_preview(p, &merged, exposure, view)?;
        outputs.push(p.to_path_buf());
    }
    if let Some(e) = failed {
        return Err(Error::Argument(format!(
            "{e}; the merged raw frame is written to '{}'",
            out.display()
        )));
    }
    Ok(MergeSummary {
        width: dw as u32,
        height: dh as u32,
        groups: groups
            .iter()
            .map(|(s, t)| (s.to_string(), t.len()))
            .collect(),
        spp,
        outputs,
    })
}
