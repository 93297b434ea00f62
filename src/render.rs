//! One render from a scene description to its files: check the outputs,
//! load the world, choose and build the integrator, run passes until a
//! sample count or a time budget, write checkpoints, assemble the AOVs and
//! write the EXR and the PNG preview. The CLI, frame sequences and tiles
//! all go through [`render_scene`]; it reports through a [`Reporter`] and
//! prints nothing itself.

use crate::error::{Error, Result};
use crate::film::{Film, Region};
use crate::integrator::{self, Integrator, PathIntegrator, PhotonIntegrator};
use crate::scene::{Integrator as IntegratorChoice, SceneDesc};
use crate::world::World;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// A duration as the command line takes it: seconds (`90`, `1.5`) or a
/// number with a unit (`90s`, `5m`, `1h`).
pub fn parse_duration(s: &str) -> std::result::Result<Duration, String> {
    let t = s.trim();
    let (num, scale) = if let Some(n) = t.strip_suffix('h') {
        (n, 3600.0)
    } else if let Some(n) = t.strip_suffix('m') {
        (n, 60.0)
    } else if let Some(n) = t.strip_suffix('s') {
        (n, 1.0)
    } else {
        (t, 1.0)
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a duration (e.g. 90, 90s, 5m, 1h)"))?;
    let secs = v * scale;
    if !(secs.is_finite() && secs > 0.0 && secs <= 1e7) {
        return Err(format!(
            "'{s}': a duration must be more than 0 and at most 10^7 seconds"
        ));
    }
    Ok(Duration::from_secs_f64(secs))
}

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
    /// the last complete checkpoint is always a valid image).
    pub checkpoint: Option<Duration>,
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

/// Bytes a stored photon takes at the peak of a pass (the photon, its
/// radius, its box while the BVH is built, the BVH and the reordered copy;
/// `cargo bench --bench photon` measured 128 bytes after the build).
const PHOTON_PEAK_BYTES: u64 = 220;

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
    photon: bool,
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
        + if r.denoise {
            pixels * Film::ALBEDO_BYTES as u64
        } else {
            0
        }
        + if denoise {
            pixels * crate::denoise::BYTES_PER_PIXEL
        } else {
            0
        };
    let photons = if photon {
        r.photon.photons_for(r.width, r.height) as u64 * PHOTON_PEAK_BYTES
    } else {
        0
    };
    let need = film + photons + grids;
    if need > limit {
        return Err(Error::Argument(format!(
            "the render needs about {} (film and images{} {} for {} x {} pixels, photon map {}, grids {}) but {} {}; lower the image size or `photons`, or give --max-memory",
            gib(need),
            if denoise { " and denoising" } else { "" },
            gib(film),
            region.width(),
            region.height(),
            gib(photons),
            gib(grids),
            gib(limit),
            if crate::memory::limit().is_some() { "is the limit" } else { "is available" }
        )));
    }
    Ok(())
}

/// Where a render is.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    /// Share of the work done, 0 to 1.
    pub fraction: f64,
    /// Seconds since the render's first pass started.
    pub elapsed: f64,
    /// Seconds still to go, when it can be told.
    pub eta: Option<f64>,
    /// Passes finished.
    pub passes: u32,
}

/// What a render tells whoever runs it. Called from worker threads.
pub trait Reporter: Sync {
    /// Something the user should know (a grid that has no effect, ...).
    fn warning(&self, _message: &str) {}
    /// Progress within the render, after every tile.
    fn progress(&self, _p: Progress) {}
    /// A checkpoint was written.
    fn checkpoint(&self, _path: &Path, _passes: u32) {}
    /// A finished render wrote this file (the EXR, then the preview).
    fn saved(&self, _path: &Path) {}
    /// Frame `frame`, the `index`-th of `count`, starts.
    fn frame_started(&self, _frame: u32, _index: usize, _count: usize) {}
    /// Frame `frame` ended after `seconds`.
    fn frame_done(&self, _frame: u32, _outcome: &crate::frames::FrameOutcome, _seconds: f64) {}
}

/// A reporter that reports nothing.
pub struct Silent;
impl Reporter for Silent {}

/// What a finished render did.
#[derive(Debug, Clone)]
pub struct Summary {
    pub integrator: &'static str,
    pub passes: u32,
    /// Camera samples per pixel.
    pub spp: u32,
    pub width: u32,
    pub height: u32,
    pub threads: usize,
    pub load_seconds: f64,
    pub render_seconds: f64,
    pub write_seconds: f64,
    /// The files written: the EXR, then the preview if any.
    pub outputs: Vec<PathBuf>,
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

/// The integrator `auto` stands for, and why, for a loaded world: the
/// photon integrator, unless every volume is optically thin (where most
/// light scatters once, which the marcher and the path tracer both compute
/// exactly, and a photon map only adds blur) or nothing scatters.
pub fn choose_integrator(world: &World) -> (IntegratorChoice, &'static str) {
    let thick = world.media.volumes().iter().any(|v| {
        let (lo, hi) = v.world_bounds();
        let extent = (hi - lo).max_element();
        v.sigma_t_per_density() * v.density().value_range().map_or(0.0, |r| r[1]) * extent > 2.0
    });
    if thick {
        (
            IntegratorChoice::Photon,
            "optically thick volume: photon mapping",
        )
    } else {
        (
            IntegratorChoice::Path,
            "optically thin volumes: the path tracer",
        )
    }
}

/// Builds the integrator a scene asks for.
pub fn make_integrator(desc: &SceneDesc, world: &World) -> Result<Box<dyn Integrator>> {
    let r = &desc.render;
    let choice = match r.integrator {
        IntegratorChoice::Auto => choose_integrator(world).0,
        c => c,
    };
    Ok(match choice {
        IntegratorChoice::Path | IntegratorChoice::Auto => {
            Box::new(PathIntegrator::new(r.max_bounces))
        }
        IntegratorChoice::Photon => Box::new(PhotonIntegrator::new(
            world,
            r.photon,
            r.max_bounces,
            r.seed,
        )?),
    })
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
    for (k, v) in integrator.attributes() {
        if !a.iter().any(|(x, _)| *x == k) {
            a.push((k, v));
        }
    }
    a.extend(extra.iter().cloned());
    a
}

/// Writes the film's image to the EXR and the preview (each atomically),
/// denoised when `denoiser` is given. Should denoising fail, the raw image
/// is written all the same and the error returned after: a finished
/// render is never lost to it.
fn write_outputs(
    desc: &SceneDesc,
    film: &Film,
    attrs: &[(String, String)],
    view: crate::image::View,
    denoiser: Option<&Denoiser>,
) -> Result<Vec<PathBuf>> {
    let r = &desc.render;
    let mut image = film.to_image()?;
    let mut attrs = attrs.to_vec();
    let mut failed = None;
    if let Some(d) = denoiser {
        match d.apply(&mut image) {
            Ok(()) => attrs.push(("vdbphoton/denoiser".into(), d.describe(&image))),
            Err(e) => failed = Some(e),
        }
    }
    crate::image::write_exr(&r.output, &image, &attrs)?;
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
    /// Loads Open Image Denoise for `threads` threads (0: all cores).
    pub fn load(threads: usize) -> Result<Self> {
        Ok(Self {
            oidn: crate::denoise::Oidn::load(threads).map_err(Error::Argument)?,
            quality: crate::denoise::Quality::High,
        })
    }

    /// Denoises `image` in place (`crate::denoise::denoise_image`).
    pub fn apply(&self, image: &mut crate::image::Image) -> Result<()> {
        crate::denoise::denoise_image(&self.oidn, image, self.quality).map_err(Error::Argument)
    }

    /// The header's description of what was done to `image`.
    pub fn describe(&self, image: &crate::image::Image) -> String {
        crate::denoise::describe(
            &self.oidn,
            self.quality,
            image.layer(crate::denoise::ALBEDO_LAYER).is_some(),
        )
    }
}

/// When a render stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stop {
    /// After this many passes.
    Passes(u32),
    /// Once this much time has gone: a pass starts only while the time so
    /// far plus the last pass's duration is within it (at least one pass).
    Time(Duration),
}

/// Runs passes of `integrator` into `film` until `stop`, reporting progress
/// and calling `after_pass(film, integrator, passes so far)` after each
/// pass (checkpoints). Returns the number of passes.
pub fn run_passes(
    world: &World,
    integrator: &mut dyn Integrator,
    film: &mut Film,
    seed: u64,
    stop: Stop,
    reporter: &dyn Reporter,
    mut after_pass: impl FnMut(&Film, &dyn Integrator, u32) -> Result<()>,
) -> Result<u32> {
    let t0 = Instant::now();
    let mut passes = 0u32;
    let mut last_pass = Duration::ZERO;
    loop {
        let done = match stop {
            Stop::Time(limit) => passes > 0 && t0.elapsed() + last_pass > limit,
            Stop::Passes(n) => passes >= n,
        };
        if done {
            return Ok(passes);
        }
        crate::interrupt::check()?;
        let tp = Instant::now();
        integrator.begin_pass(world, passes);
        let done_before = passes;
        let report = |done: usize, total: usize| {
            let in_pass = done as f64 / total.max(1) as f64;
            let elapsed = t0.elapsed().as_secs_f64();
            let (fraction, eta) = match stop {
                Stop::Time(limit) => {
                    let l = limit.as_secs_f64().max(1e-9);
                    ((elapsed / l).min(1.0), Some((l - elapsed).max(0.0)))
                }
                Stop::Passes(n) => {
                    let f = (done_before as f64 + in_pass) / n.max(1) as f64;
                    (f, (f > 0.0).then(|| elapsed / f - elapsed))
                }
            };
            reporter.progress(Progress {
                fraction,
                elapsed,
                eta,
                passes: done_before,
            });
        };
        integrator::render_pass(world, integrator, film, seed, passes, &report);
        // An interrupted pass is incomplete: stop before anything is
        // written from it.
        crate::interrupt::check()?;
        passes += 1;
        last_pass = tp.elapsed();
        after_pass(film, integrator, passes)?;
    }
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
    let wants_photons = r.integrator != IntegratorChoice::Path;
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
    check_memory(
        desc,
        region,
        0,
        wants_photons,
        denoise_here,
        opts.max_memory,
    )?;
    let denoiser = if denoise_here {
        Some(Denoiser::load(opts.threads.unwrap_or(0))?)
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
    let run = || -> Result<Summary> {
        let world = World::load(desc)?;
        let grids: u64 = world
            .media
            .volumes()
            .iter()
            .map(|v| v.memory_bytes() as u64)
            .sum();
        check_memory(
            desc,
            region,
            grids,
            wants_photons,
            denoise_here,
            opts.max_memory,
        )?;
        for w in &world.warnings {
            reporter.warning(w);
        }
        let mut integrator = make_integrator(desc, &world)?;
        let mut film = Film::new(r.width, r.height, region, r.aovs);
        if r.denoise {
            integrator.enable_albedo(&world);
            film = film.with_albedo();
        }
        let per_pass = integrator.samples_per_pass().max(1);
        let stop = match opts.time_limit {
            Some(t) => Stop::Time(t),
            None => Stop::Passes(r.spp.div_ceil(per_pass).max(1)),
        };
        let t0 = Instant::now();
        let mut last_checkpoint = Instant::now();
        let passes = run_passes(
            &world,
            integrator.as_mut(),
            &mut film,
            r.seed,
            stop,
            reporter,
            |film, integrator, passes| {
                let Some(every) = opts.checkpoint else {
                    return Ok(());
                };
                if last_checkpoint.elapsed() < every {
                    return Ok(());
                }
                let attrs = attributes(
                    desc,
                    integrator,
                    passes,
                    passes * per_pass,
                    t0.elapsed().as_secs_f64(),
                    &extra,
                );
                write_outputs(desc, film, &attrs, opts.view, denoiser.as_ref())?;
                reporter.checkpoint(&r.output, passes);
                last_checkpoint = Instant::now();
                Ok(())
            },
        )?;
        let render_seconds = t0.elapsed().as_secs_f64();
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
        let outputs = write_outputs(desc, &film, &attrs, opts.view, denoiser.as_ref())?;
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

/// Keeps the last message of a progress bar from interleaving: a
/// convenience for reporters that print from worker threads.
pub struct Throttle {
    last: Mutex<Option<Instant>>,
    every: Duration,
}

impl Throttle {
    pub fn new(every: Duration) -> Self {
        Self {
            last: Mutex::new(None),
            every,
        }
    }
    /// True at most once per interval (and always when `force`).
    pub fn ready(&self, force: bool) -> bool {
        let mut l = self.last.lock().unwrap_or_else(|e| e.into_inner());
        let now = Instant::now();
        if force || l.is_none_or(|t| now - t >= self.every) {
            *l = Some(now);
            true
        } else {
            false
        }
    }
}
