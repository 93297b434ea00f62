//! One render from a scene description to its files: check the outputs,
//! load the world, choose and build the integrator, run passes until a
//! sample count or a time budget, write checkpoints, assemble the AOVs and
//! write the EXR and the PNG preview. The CLI, frame sequences and tiles
//! all go through [`render_scene`]; it reports through a [`Reporter`] and
//! prints nothing itself.

use crate::error::{Error, Result};
use crate::film::{Film, Region};
use crate::integrator::{self, Integrator};
use crate::scene::{SceneDesc, AUTO_INTEGRATOR};
use crate::world::World;
use std::path::{Path, PathBuf};

pub mod auto;
mod overrides;
pub mod passes;
pub mod report;
pub mod resume;

pub use overrides::Overrides;

pub use passes::{run_passes, run_passes_from, Stop};
pub use report::{FrameOutcome, Progress, Reporter, Silent, Summary, Throttle};
use std::time::{Duration, Instant};

pub use crate::units::parse_duration;

/// How a render runs, beside what the scene says.
#[derive(Debug, Clone, Default)]
pub struct RenderOptions {
    /// Worker threads (`None`: one per core).
    pub threads: Option<usize>,
    /// Run passes until this much wall-clock time has gone (at least one
    /// pass; a pass is started only when the last one's duration still
    /// fits), instead of until the scene's `spp`.
    pub time_limit: Option<Duration>,
    /// Rewrite the outputs this often while rendering (each write atomic, so
    /// the last complete checkpoint is always a valid image), with the
    /// state a resumed render goes on from (`resume`).
    pub checkpoint: Option<Duration>,
    /// Checkpoints without the resume state: previews only (the Blender
    /// add-on's progressive display, which never resumes).
    pub no_resume_state: bool,
    /// More header attributes (e.g. the scene file's name).
    pub attributes: Vec<(String, String)>,
    /// Memory the render may use, bytes (`None`: what the machine has
    /// available). A render that would need more is refused before it
    /// starts.
    pub max_memory: Option<u64>,
    /// Render only these pixels (`--region`); the EXR's data window is the
    /// region inside the whole image.
    pub region: Option<Region>,
    /// Render only tile `I` of `N` (`--tile I/N`, [`Region::tile`]);
    /// `{tile}` in output paths becomes `I`.
    pub tile: Option<(u32, u32)>,
    /// The view transform of the PNG preview.
    pub view: crate::image::View,
}

/// Bytes per pixel beside the film: the image assembled for writing and
/// the encoder's copy (RGBA and, with AOVs, ten channels more, f32).
fn image_bytes_per_pixel(aovs: bool) -> u64 {
    2 * 4 * if aovs { 14 } else { 4 }
}

fn gib(b: u64) -> String {
    format!("{:.1} GiB", b as f64 / (1u64 << 30) as f64)
}

/// Images above this many pixels (16.8 M, eight 1920 x 1080 frames) get a
/// word about their memory and work before they start.
const LARGE_IMAGE_PIXELS: u64 = 1 << 24;

/// Refuses a render that will not fit in `limit` bytes: film and images
/// (with the denoiser's own memory when `denoise`), the photon map of a
/// pass, and the grids (when loaded).
fn check_memory(
    desc: &SceneDesc,
    region: Region,
    grids: u64,
    denoise: bool,
    limit: Option<u64>,
) -> Result<()> {
    let Some(limit) = limit.or_else(crate::memory::available) else {
        return Ok(());
    };
    let r = &desc.render;
    let pixels = region.pixels() as u64;
    let film = Film::bytes_for(pixels as usize, r.aovs) as u64
        + pixels * image_bytes_per_pixel(r.aovs)
        + if desc.meshes.iter().any(|m| m.shadow_catcher) {
            pixels * Film::CATCHER_BYTES as u64
        } else {
            0
        }
        + if r.aovs && !desc.meshes.is_empty() {
            pixels * Film::SURFACE_AOV_BYTES as u64
        } else {
            0
        }
        + if r.denoise {
            pixels * Film::DENOISE_BYTES as u64
        } else {
            0
        }
        + if denoise {
            pixels * crate::denoise::BYTES_PER_PIXEL
        } else {
            0
        };
    // `auto` may choose any integrator: count the one that needs most.
    let photons = match integrator::find(&r.integrator) {
        Some(reg) => (reg.peak_bytes)(desc),
        None => integrator::REGISTRY
            .iter()
            .map(|reg| (reg.peak_bytes)(desc))
            .max()
            .unwrap_or(0),
    };
    let meshes = mesh_bytes(desc);
    let mesh_total: u64 = meshes.iter().map(|m| m.1).sum();
    let need = film + photons + grids + mesh_total;
    if need > limit {
        let is = if crate::memory::limit().is_some() {
            "is the limit"
        } else {
            "is available"
        };
        // A mesh that does not fit on its own is what to name.
        if let Some((i, bytes, size)) = meshes.iter().copied().max_by_key(|m| m.1) {
            if bytes > limit / 2 {
                let m = &desc.meshes[i];
                return Err(Error::file(
                    &m.file,
                    format!(
                        "{} triangles and {} vertices need about {} of memory to render, but {} {is}; decimate the mesh or give --max-memory",
                        size.triangles,
                        size.vertices,
                        gib(bytes),
                        gib(limit),
                    ),
                )
                .context(format!("[[mesh]] {} {}", i + 1, m.label())));
            }
        }
        return Err(Error::Argument(format!(
            "the render needs about {} (film and images{} {} for {} x {} pixels, photon map {}, grids {}, meshes {}) but {} {is}; lower the image size or [render.photon] photons, or give --max-memory",
            gib(need),
            if denoise { " and denoising" } else { "" },
            gib(film),
            region.width(),
            region.height(),
            gib(photons),
            gib(grids),
            gib(mesh_total),
            gib(limit),
        )));
    }
    Ok(())
}

/// What each `[[mesh]]` will take in memory once loaded, from its file's
/// header (PLY) or lines (OBJ): its index, bytes and size. A file that
/// cannot be read counts nothing here; loading it says what is wrong.
fn mesh_bytes(desc: &SceneDesc) -> Vec<(usize, u64, crate::mesh::MeshSize)> {
    desc.meshes
        .iter()
        .enumerate()
        .filter_map(|(i, m)| {
            let size = crate::mesh::size_of_file(&m.file).ok()?;
            let bytes = size
                .triangles
                .saturating_mul(crate::shape::BYTES_PER_TRIANGLE)
                .saturating_add(size.vertices.saturating_mul(2 * 12));
            Some((i, bytes, size))
        })
        .collect()
}

/// Checks before any work that the outputs can be written: the EXR must end
/// in `.exr` and the preview in `.png` (so that one format never lands
/// under the other's name), and their folders are created when missing, so
/// a finished render is never lost to a missing folder.
pub fn prepare_outputs(exr: &Path, preview: Option<&Path>) -> Result<()> {
    let ext_is = |p: &Path, e: &str| {
        p.extension()
            .and_then(|x| x.to_str())
            .is_some_and(|x| x.eq_ignore_ascii_case(e))
    };
    if !ext_is(exr, "exr") {
        return Err(Error::Argument(format!(
            "output '{}': the image is written as OpenEXR, so its name must end in .exr",
            exr.display()
        )));
    }
    if let Some(p) = preview {
        if !ext_is(p, "png") {
            return Err(Error::Argument(format!(
                "preview '{}': the preview is a PNG, so its name must end in .png",
                p.display()
            )));
        }
    }
    for p in std::iter::once(exr).chain(preview) {
        if p.is_dir() {
            return Err(Error::Argument(format!(
                "output '{}' is a directory",
                p.display()
            )));
        }
        let dir = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        std::fs::create_dir_all(dir).map_err(|e| {
            Error::Argument(format!(
                "cannot create the folder '{}' for '{}': {e}",
                dir.display(),
                p.display()
            ))
        })?;
        // Can a file be made there? (A read-only folder fails here, not
        // after the render.)
        let probe = dir.join(format!(".vdbphoton-probe-{}", std::process::id()));
        std::fs::write(&probe, b"").map_err(|e| {
            Error::Argument(format!(
                "cannot write into '{}' (for '{}'): {e}",
                dir.display(),
                p.display()
            ))
        })?;
        let _ = std::fs::remove_file(&probe);
    }
    Ok(())
}

/// The integrator `auto` stands for, and why, for a loaded world and a
/// render of `horizon`:
/// - nothing scatters light: the path tracer at once; photons would carry
///   nothing (a frame of pure emission, an empty volume);
/// - no light reaches the volumes (a pilot of photons,
///   [`integrator::photon::pilot`]): the path tracer at once;
/// - a denoised image: the path tracer, whose noise is what the denoiser
///   removes (the photon estimate's error is blotches the size of its
///   kernels, which it leaves), unless the volumes glow and their light
///   scatters ([`GLOW_SHARE`], [`GLOW_SCATTERING`]): photons carry the
///   fire's light scattered by the smoke from every emitting voxel, which
///   the path tracer finds only by chance (docs/performance.md,
///   "Denoising");
/// - otherwise both integrators render a pilot on the frame itself and the
///   one with the lower predicted error at the horizon renders
///   ([`auto::measure`], [`auto::decide`]).
pub fn choose_integrator(
    desc: &SceneDesc,
    world: &World,
    horizon: auto::Horizon,
) -> Result<(&'static str, String)> {
    let r = &desc.render;
    let path = integrator::path::REGISTRATION.name;
    let photon = integrator::photon::REGISTRATION.name;
    if !world.media.scatters() {
        return Ok((
            path,
            "nothing scatters light (absorption or emission only, or no density): the path tracer at once; photons would carry nothing".into(),
        ));
    }
    let Some(p) = integrator::photon::pilot(world, r.max_bounces, r.seed) else {
        return Ok((
            path,
            "no light reaches the volumes: the path tracer at once".into(),
        ));
    };
    if r.denoise {
        let measured = format!(
            "the volumes emit {:.0} % of the light; {:.0} % of their photons scatter",
            100.0 * p.media_share.max(0.0),
            100.0 * p.media_scattering
        );
        return Ok(
            if p.media_share >= GLOW_SHARE && p.media_scattering >= GLOW_SCATTERING {
                (
                    photon,
                    format!("denoised; {measured}: photon mapping, whose photons carry the volumes' glow scattered by the smoke (the path tracer finds it by chance)"),
                )
            } else {
                (
                    path,
                    format!(
                        "denoised; {measured}: the path tracer, whose noise the denoiser removes"
                    ),
                )
            },
        );
    }
    let mut candidates = Vec::new();
    for name in [path, photon] {
        let reg = integrator::find(name)
            .ok_or_else(|| Error::Scene(format!("there is no integrator '{name}'")))?;
        // An integrator that cannot render this world is no candidate.
        if let Ok(i) = (reg.build)(desc, world) {
            candidates.push((name, i));
        }
    }
    if candidates.len() < 2 {
        return Ok((
            path,
            "the photon integrator cannot render this scene: the path tracer".into(),
        ));
    }
    let measured = auto::measure(
        world,
        candidates
            .iter_mut()
            .map(|(n, i)| (*n, i.as_mut() as &mut dyn Integrator))
            .collect(),
        r.seed,
        horizon,
    );
    Ok(auto::decide(&measured, horizon))
}

/// The share of the light the volumes must emit themselves for `auto` to
/// count them as glowing.
pub const GLOW_SHARE: f32 = 0.1;

/// The share of the photons the volumes emit that must scatter for `auto`
/// to take photon mapping for their glow.
pub const GLOW_SCATTERING: f64 = 0.2;

/// Builds the integrator a scene asks for (`auto`: [`choose_integrator`],
/// for a render of the scene's samples).
pub fn make_integrator(desc: &SceneDesc, world: &World) -> Result<Box<dyn Integrator>> {
    let horizon = auto::Horizon::Passes(desc.render.spp.max(1));
    Ok(build_integrator(desc, world, horizon)?.0)
}

/// [`make_integrator`] for a render of `horizon`, with `auto`'s reason for
/// its choice (`None` for an integrator the scene names).
pub fn build_integrator(
    desc: &SceneDesc,
    world: &World,
    horizon: auto::Horizon,
) -> Result<(Box<dyn Integrator>, Option<String>)> {
    check_integrator(desc)?;
    let (name, why) = match desc.render.integrator.as_str() {
        AUTO_INTEGRATOR => {
            let (name, why) = choose_integrator(desc, world, horizon)?;
            (name, Some(why))
        }
        name => (name, None),
    };
    let reg = integrator::find(name)
        .ok_or_else(|| Error::Scene(format!("there is no integrator '{name}'")))?;
    Ok(((reg.build)(desc, world)?, why))
}

/// Checks the scene's integrator and its settings table
/// ([`integrator::check_settings`]) as an error of the crate (a scene
/// loaded with [`load_scene`] was checked already, with line numbers).
pub fn check_integrator(desc: &SceneDesc) -> Result<()> {
    integrator::check_settings(desc).map_err(|e| Error::Scene(e.to_string()))
}

/// Loads a scene file with everything the renderer checks: the scene's
/// own rules and the integrators' settings tables, each error pointing at
/// its line.
pub fn load_scene(path: impl AsRef<Path>) -> Result<SceneDesc> {
    Ok(SceneDesc::load_with(path, &integrator::check_settings)?)
}

/// A fingerprint of what a render shows: the scene with its seed, sample
/// count and output names left out, so that tiles and renders with other
/// seeds of one frame share it and `merge` can refuse parts of other
/// scenes (FNV-1a over the description's debug text).
pub fn scene_hash(desc: &SceneDesc) -> String {
    let mut d = desc.clone();
    d.render.seed = 0;
    d.render.spp = 0;
    d.render.output = PathBuf::new();
    d.render.preview = None;
    d.render.frames = None;
    d.render.resume = false;
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in format!("{d:?}").bytes() {
        h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// Header attributes of a render.
fn attributes(
    desc: &SceneDesc,
    integrator: &dyn Integrator,
    passes: u32,
    spp: u32,
    seconds: f64,
    extra: &[(String, String)],
) -> Vec<(String, String)> {
    let r = &desc.render;
    let mut a = vec![
        (
            "vdbphoton/version".to_string(),
            env!("CARGO_PKG_VERSION").to_string(),
        ),
        ("vdbphoton/scene_hash".to_string(), scene_hash(desc)),
        (
            "vdbphoton/integrator".to_string(),
            integrator.name().to_string(),
        ),
        ("vdbphoton/spp".to_string(), spp.to_string()),
        ("vdbphoton/passes".to_string(), passes.to_string()),
        ("vdbphoton/seed".to_string(), r.seed.to_string()),
        (
            "vdbphoton/max_bounces".to_string(),
            r.max_bounces.to_string(),
        ),
        (
            "vdbphoton/render_seconds".to_string(),
            format!("{seconds:.3}"),
        ),
    ];
    let m = &r.motion_blur;
    if m.enabled {
        a.push((
            "vdbphoton/motion_blur".to_string(),
            format!(
                "shutter {} frames, {}, {} fps",
                m.shutter,
                m.position.name(),
                m.fps
            ),
        ));
    }
    if r.film_transparent {
        a.push(("vdbphoton/film_transparent".to_string(), "true".to_string()));
    }
    if !desc.meshes.is_empty() {
        a.push((
            "vdbphoton/meshes".to_string(),
            desc.meshes
                .iter()
                .map(|m| {
                    let mut s = m.label();
                    if m.holdout {
                        s.push_str(" holdout");
                    } else if m.shadow_catcher {
                        s.push_str(" shadow_catcher");
                    }
                    s
                })
                .collect::<Vec<_>>()
                .join(", "),
        ));
    }
    for (k, v) in integrator.attributes() {
        if !a.iter().any(|(x, _)| *x == k) {
            a.push((k, v));
        }
    }
    a.extend(extra.iter().cloned());
    a
}

/// Writes the film's image to the EXR and the preview (each atomically),
/// denoised when `denoiser` is given; `exr_written` runs once the EXR is
/// in place. Should denoising fail, the raw image
/// is written all the same and the error returned after: a finished
/// render is never lost to it.
fn write_outputs(
    desc: &SceneDesc,
    film: &Film,
    attrs: &[(String, String)],
    view: crate::image::View,
    denoiser: Option<&Denoiser>,
    checkpoint: bool,
    exr_written: impl FnOnce(),
) -> Result<Vec<PathBuf>> {
    let r = &desc.render;
    let mut image = film.to_image()?;
    let mut attrs = attrs.to_vec();
    let mut failed = None;
    if let Some(d) = denoiser {
        // A checkpoint is a preview: its denoising takes the fast quality
        // (about 60 % of the time), the finished frame the one asked for.
        let quality = if checkpoint {
            crate::denoise::Quality::Fast
        } else {
            d.quality
        };
        match d.apply_at(&mut image, quality) {
            Ok(()) => attrs.push(("vdbphoton/denoiser".into(), d.describe_at(&image, quality))),
            Err(e) => failed = Some(e),
        }
    }
    crate::image::write_exr(&r.output, &image, &attrs)?;
    exr_written();
    let mut out = vec![r.output.clone()];
    if let Some(p) = &r.preview {
        crate::image::write_png_preview(p, &image, r.exposure, view)?;
        out.push(p.clone());
    }
    match failed {
        None => Ok(out),
        Some(e) => Err(Error::Argument(format!(
            "{e}; the raw render is written to '{}'",
            r.output.display()
        ))),
    }
}

/// The denoiser of a render (Open Image Denoise, loaded when the render
/// starts, so that a missing library stops it before any work).
pub struct Denoiser {
    oidn: crate::denoise::Oidn,
    quality: crate::denoise::Quality,
}

impl Denoiser {
    /// Loads Open Image Denoise for `threads` threads (0: all cores), at
    /// its highest quality.
    pub fn load(threads: usize) -> Result<Self> {
        Ok(Self {
            oidn: crate::denoise::Oidn::load(threads).map_err(Error::Argument)?,
            quality: crate::denoise::Quality::High,
        })
    }

    /// The same denoiser at another quality.
    pub fn with_quality(self, quality: crate::denoise::Quality) -> Self {
        Self { quality, ..self }
    }

    /// Denoises `image` in place (`crate::denoise::denoise_image`).
    pub fn apply(&self, image: &mut crate::image::Image) -> Result<()> {
        self.apply_at(image, self.quality)
    }

    /// Denoises `image` in place at `quality`.
    pub fn apply_at(
        &self,
        image: &mut crate::image::Image,
        quality: crate::denoise::Quality,
    ) -> Result<()> {
        crate::denoise::denoise_image(&self.oidn, image, quality).map_err(Error::Argument)
    }

    /// The header's description of what was done to `image`.
    pub fn describe(&self, image: &crate::image::Image) -> String {
        self.describe_at(image, self.quality)
    }

    fn describe_at(&self, image: &crate::image::Image, quality: crate::denoise::Quality) -> String {
        crate::denoise::describe(
            &self.oidn,
            quality,
            image.layer(crate::denoise::ALBEDO_LAYER).is_some(),
            image.layer(crate::denoise::HALF_LAYER).is_some(),
        )
    }
}

/// Takes up a killed render's state at `path` when it is this render's
/// (`id`) and within `stop`: the film and the integrator then hold its
/// passes, and the position returned is where it was. Otherwise (none, or
/// another render's, or damaged: reported) the render starts afresh and
/// `path` stays until its first checkpoint replaces it.
fn resume_from(
    path: &Path,
    id: &resume::Identity,
    stop: Stop,
    world: &World,
    integrator: &mut dyn Integrator,
    film: &mut Film,
    reporter: &dyn Reporter,
) -> resume::Position {
    let refuse = |why: String| {
        reporter.warning(&format!(
            "not resuming from '{}': {why}; the render starts from its first pass",
            path.display()
        ));
        resume::Position::default()
    };
    let state = match resume::read(path, id, film) {
        Ok(None) => return resume::Position::default(),
        Ok(Some(s)) => s,
        Err(why) => return refuse(why),
    };
    if let Stop::Passes(n) = stop {
        if state.at.passes > n {
            return refuse(format!(
                "it holds {} passes, more than the {n} this render makes",
                state.at.passes
            ));
        }
    }
    if let Err(why) = integrator.restore(world, &state.integrator) {
        return refuse(why);
    }
    *film = state.film;
    reporter.resumed(path, state.at.passes, state.at.seconds);
    state.at
}

/// The summary of the finished render of `desc` at its output, when the
/// EXR there has no resume state and its header says it is this render:
/// the same scene, seed, tile and (for a sample count) samples.
fn finished_already(desc: &SceneDesc, opts: &RenderOptions) -> Option<Summary> {
    let r = &desc.render;
    let attrs = crate::image::read_exr_attributes(&r.output)?;
    let get = |k: &str| attrs.iter().find(|(x, _)| x == k).map(|(_, v)| v.as_str());
    let tile = opts.tile.map(|(i, n)| format!("{i}/{n}"));
    let spp: u32 = get("vdbphoton/spp")?.parse().ok()?;
    let same = get("vdbphoton/scene_hash") == Some(scene_hash(desc).as_str())
        && get("vdbphoton/seed") == Some(r.seed.to_string().as_str())
        && get("vdbphoton/tile") == tile.as_deref()
        && opts.region.is_none()
        && (opts.time_limit.is_some() || spp >= r.spp);
    if !same {
        return None;
    }
    let integrator = integrator::find(get("vdbphoton/integrator")?)?.name;
    Some(Summary {
        integrator,
        passes: get("vdbphoton/passes")?.parse().ok()?,
        spp,
        width: r.width,
        height: r.height,
        threads: 0,
        load_seconds: 0.0,
        render_seconds: get("vdbphoton/render_seconds")?.parse().ok()?,
        write_seconds: 0.0,
        outputs: vec![r.output.clone()],
    })
}

/// The pixels a render covers: the whole image, `--region` or `--tile`.
pub fn region_of(desc: &SceneDesc, opts: &RenderOptions) -> Result<Region> {
    let (w, h) = (desc.render.width, desc.render.height);
    match (opts.region, opts.tile) {
        (Some(_), Some(_)) => Err(Error::Argument(
            "give either --region or --tile, not both".into(),
        )),
        (Some(r), None) => {
            if r.x0 >= r.x1 || r.y0 >= r.y1 || r.x1 > w || r.y1 > h {
                return Err(Error::Argument(format!(
                    "--region {r} is empty or reaches outside the {w} x {h} image"
                )));
            }
            Ok(r)
        }
        (None, Some((i, n))) => Region::tile(i, n, w, h).ok_or_else(|| {
            Error::Argument(if n == 0 || i >= n {
                format!("--tile {i}/{n}: the tile must be 0 to {}", n.max(1) - 1)
            } else {
                format!("--tile {i}/{n}: a {w} x {h} image has too few pixels for {n} tiles")
            })
        }),
        (None, None) => Ok(Region::full(w, h)),
    }
}

/// Renders a validated scene to its outputs.
pub fn render_scene(
    desc: &SceneDesc,
    opts: &RenderOptions,
    reporter: &dyn Reporter,
) -> Result<Summary> {
    let r = &desc.render;
    let region = region_of(desc, opts)?;
    prepare_outputs(&r.output, r.preview.as_deref())?;
    if opts.threads == Some(0) {
        return Err(Error::Argument("--threads must be at least 1".into()));
    }
    check_integrator(desc)?;
    for w in &desc.warnings {
        reporter.warning(w);
    }
    // Grids check what is left of the limit before they load.
    crate::memory::set_limit(opts.max_memory);
    if region.pixels() as u64 > LARGE_IMAGE_PIXELS {
        let film = Film::bytes_for(region.pixels(), r.aovs) as u64
            + region.pixels() as u64 * image_bytes_per_pixel(r.aovs);
        reporter.warning(&format!(
            "a large image: {} x {} pixels ({:.0} M), about {} for the film and images, and {:.0} times the work of a 1920 x 1080 frame",
            region.width(),
            region.height(),
            region.pixels() as f64 / 1e6,
            gib(film),
            region.pixels() as f64 / (1920.0 * 1080.0)
        ));
    }
    // Tiles and regions are denoised when merged (`merge`), never alone: a
    // tile's denoised edge would not meet its neighbour's.
    let part = opts.tile.is_some() || opts.region.is_some();
    let denoise_here = r.denoise && !part;
    check_memory(desc, region, 0, denoise_here, opts.max_memory)?;
    let denoiser = if denoise_here {
        Some(Denoiser::load(opts.threads.unwrap_or(0))?.with_quality(r.denoise_quality.into()))
    } else {
        None
    };
    // The preview's settings travel with the image, so that `merge` shows
    // merged tiles as the render would have.
    let mut extra = opts.attributes.clone();
    extra.push(("vdbphoton/exposure".into(), format!("{}", r.exposure)));
    extra.push(("vdbphoton/view".into(), opts.view.name().into()));
    if let Some((i, n)) = opts.tile {
        extra.push(("vdbphoton/tile".into(), format!("{i}/{n}")));
    }
    if r.denoise {
        // The request travels with the image: `merge` denoises tiles, and
        // renders of other seeds averaged, when every input asked for it.
        extra.push((
            "vdbphoton/denoise".into(),
            if part { "at merge" } else { "done" }.into(),
        ));
    }
    // One render at a time writes an output and its state; the lock also
    // clears what a killed render left half-written.
    let stateful = r.resume || opts.checkpoint.is_some();
    let _lock = resume::lock(&r.output, stateful)?;
    let state_path = resume::state_path(&r.output);
    // A render asked to resume whose output is already this render,
    // finished (a farm task run again after it ended): nothing to do, and
    // a checkpoint of a fresh start must not replace the finished image.
    if r.resume && !state_path.exists() {
        if let Some(done) = finished_already(desc, opts) {
            reporter.warning(&format!(
                "'{}' is this render, finished ({} passes); nothing to resume",
                r.output.display(),
                done.passes
            ));
            return Ok(done);
        }
    }
    // A stop request (a farm's SIGTERM) lets a checkpointing render finish
    // its pass and write a last checkpoint.
    let _finish = opts.checkpoint.map(|_| crate::interrupt::finish_passes());
    let run = || -> Result<Summary> {
        let world = World::load(desc)?;
        let grids: u64 = world
            .media
            .volumes()
            .iter()
            .map(|v| v.memory_bytes() as u64)
            .sum();
        check_memory(desc, region, grids, denoise_here, opts.max_memory)?;
        for w in &world.warnings {
            reporter.warning(w);
        }
        // Why `auto` chose what it chose, in the header.
        let mut extra = extra.clone();
        // A render that resumes goes on with the integrator its state
        // was made with (`auto` measures again only for a fresh start).
        let resumed_with = (r.resume && r.integrator == AUTO_INTEGRATOR)
            .then(|| resume::integrator_of(&state_path))
            .flatten()
            .and_then(|name| integrator::find(&name));
        let choosing = Instant::now();
        let (mut integrator, why) = match resumed_with {
            Some(reg) => (
                (reg.build)(desc, &world)?,
                Some(format!(
                    "{}, as chosen when this render started (resumed)",
                    reg.name
                )),
            ),
            None => {
                let horizon = match opts.time_limit {
                    Some(t) => auto::Horizon::Seconds(t.as_secs_f64()),
                    None => auto::Horizon::Passes(r.spp.max(1)),
                };
                build_integrator(desc, &world, horizon)?
            }
        };
        let chose = why.is_some() && resumed_with.is_none();
        if let Some(why) = why {
            extra.push(("vdbphoton/auto".into(), why));
        }
        if integrator.name() == integrator::photon::REGISTRATION.name && !world.media.scatters() {
            reporter.warning(
                "the photon integrator gains nothing here: no volume scatters light (absorption or emission only, or no density), so every photon would be traced only to be absorbed; integrator = \"path\" (or \"auto\") renders the same image without that work",
            );
        }
        let mut film = Film::new(r.width, r.height, region, r.aovs);
        if world.shapes.has_catcher() {
            film = film.with_catcher();
        }
        if !world.shapes.is_empty() {
            film = film.with_surface_aovs();
        }
        if r.denoise {
            film = film.with_guides();
            if integrator.denoise_blended() {
                film = film.with_half();
            }
        }
        let per_pass = integrator.samples_per_pass().max(1);
        // `auto`'s pilots spend part of a time budget.
        let stop = match opts.time_limit {
            Some(t) if chose => Stop::Time(t.saturating_sub(choosing.elapsed())),
            Some(t) => Stop::Time(t),
            None => Stop::Passes(r.spp.div_ceil(per_pass).max(1)),
        };
        // (The identity hashes the executable: only when a state is in play.)
        let writes_state = opts.checkpoint.is_some() && !opts.no_resume_state;
        let id = (r.resume || writes_state)
            .then(|| resume::Identity::of(desc, integrator.name(), &film));
        let start = match &id {
            Some(id) if r.resume => resume_from(
                &state_path,
                id,
                stop,
                &world,
                integrator.as_mut(),
                &mut film,
                reporter,
            ),
            _ => resume::Position::default(),
        };
        let mut last_checkpoint = Instant::now();
        let mut saved = start.passes;
        let at = run_passes_from(
            &world,
            integrator.as_mut(),
            &mut film,
            r.seed,
            stop,
            start,
            reporter,
            |film, integrator, at, last| {
                let Some(every) = opts.checkpoint else {
                    return Ok(());
                };
                if at.passes == saved || (!last && last_checkpoint.elapsed() < every) {
                    return Ok(());
                }
                // The state first: an EXR with a state beside it is a
                // checkpoint (`resume::is_finished`).
                if let (true, Some(id)) = (writes_state, &id) {
                    resume::write(&state_path, id, at, &integrator.state(), film)?;
                }
                let attrs = attributes(
                    desc,
                    integrator,
                    at.passes,
                    at.passes * per_pass,
                    at.seconds,
                    &extra,
                );
                write_outputs(
                    desc,
                    film,
                    &attrs,
                    opts.view,
                    denoiser.as_ref(),
                    true,
                    || {},
                )?;
                reporter.checkpoint(&r.output, at.passes);
                saved = at.passes;
                last_checkpoint = Instant::now();
                Ok(())
            },
        )
        .map_err(|e| match e {
            // The state written or resumed from keeps `saved` passes.
            Error::Interrupted { signal, kept: None } => Error::Interrupted {
                signal,
                kept: (saved > 0 && (writes_state || r.resume)).then(|| {
                    format!(
                        "the checkpoint '{}' keeps {saved} passes; --resume goes on from them",
                        r.output.display()
                    )
                }),
            },
            e => e,
        })?;
        let render_seconds = at.seconds;
        let passes = at.passes;
        let tw = Instant::now();
        let spp = passes * per_pass;
        let attrs = attributes(
            desc,
            integrator.as_ref(),
            passes,
            spp,
            render_seconds,
            &extra,
        );
        // The render is finished once its EXR is on disk: its state goes
        // then (also when only the denoising failed: the raw image is
        // written), never when the EXR could not be written.
        let outputs = write_outputs(
            desc,
            &film,
            &attrs,
            opts.view,
            denoiser.as_ref(),
            false,
            || {
                if state_path.exists() {
                    if let Err(e) = resume::finish(&r.output, &state_path) {
                        reporter.warning(&e);
                    }
                }
            },
        )?;
        for p in &outputs {
            reporter.saved(p);
        }
        Ok(Summary {
            integrator: integrator.name(),
            passes,
            spp,
            width: r.width,
            height: r.height,
            threads: rayon::current_num_threads(),
            load_seconds: world.load_seconds,
            render_seconds,
            write_seconds: tw.elapsed().as_secs_f64(),
            outputs,
        })
    };
    match opts.threads {
        Some(t) => rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .map_err(|e| Error::Argument(format!("cannot start {t} threads: {e}")))?
            .install(run),
        None => run(),
    }
}
