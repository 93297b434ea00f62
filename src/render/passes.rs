//! The pass loop: a render is a sequence of passes (pbrt-v4's
//! `Integrator::Render`, cut into passes as progressive photon mapping
//! needs). Before a pass the integrator prepares what the whole pass shares
//! ([`Integrator::begin_pass`]: the photon integrator traces a fresh photon
//! map), then every pixel gets [`Integrator::samples_per_pass`] camera
//! samples ([`Integrator::li`]), added to the film's sums. A sample count or
//! a time budget ([`Stop`]) decides how many passes run.
//!
//! The film is cut into 16x16 tiles rendered in parallel (rayon), in a
//! fixed shuffled order so that the share of tiles done is a fair measure
//! of the work done (empty sky rows do not all come first). Every random
//! number of a camera sample comes from a stream keyed by (seed, pixel,
//! sample index) in the camera domain, never by the thread, so an image is
//! identical whatever the thread count. Pixels use a box filter of one
//! pixel (each sample at a uniformly random position in its pixel), as the
//! reference renders do.

use super::report::{Progress, Reporter};
use super::resume::Position;
use crate::error::Result;
use crate::film::{Film, Region, SampleResult};
use crate::integrator::{guide, Integrator, PathIntegrator, SampleKey};
use crate::ray::Ray;
use crate::sampling::{mix64, Domain};
use crate::world::World;
use crate::Rgb;
use glam::Vec2;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Settings of a render with the reference path tracer (tests and
/// benchmarks; the renderer proper is set up by `crate::render`).
#[derive(Debug, Clone)]
pub struct Settings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub seed: u64,
    /// Real scattering events at most along a path.
    pub max_bounces: u32,
}

const TILE: u32 = 16;

/// The stream number of pixel (x, y) of an image `width` wide.
pub fn pixel_stream(x: u32, y: u32, width: u32) -> u64 {
    y as u64 * width as u64 + x as u64
}

/// One camera sample of pixel (x, y), sample `index`.
pub fn camera_sample(
    world: &World,
    integrator: &dyn Integrator,
    seed: u64,
    x: u32,
    y: u32,
    index: u64,
) -> SampleResult {
    camera_sample_guided(world, integrator, seed, (x, y), index, None)
}

/// [`camera_sample`] with the denoiser's guide (the albedo) along its
/// camera ray when it is one of the pixel's first [`guide::GUIDE_SAMPLES`]
/// samples (`guide_step`: the guide's march step; `None` when no guide is
/// kept). The guide draws from a stream of its own, so the radiance is the
/// same bits with or without it.
pub fn camera_sample_guided(
    world: &World,
    integrator: &dyn Integrator,
    seed: u64,
    (x, y): (u32, u32),
    index: u64,
    guide_step: Option<f32>,
) -> SampleResult {
    let key = SampleKey {
        seed,
        pixel: pixel_stream(x, y, world.camera.width()),
        index,
    };
    // Stratified first dimensions where surfaces are: the pixel, the first
    // light and BSDF samples on a surface converge faster (a smooth ground
    // or sphere: half the error at equal samples); on volumes alone, whose
    // first numbers delta tracking spends, they gained 3 % for 5 % more
    // work (docs/performance.md, "Stratified camera samples"), so those
    // scenes keep independent numbers (and their images' bits).
    let rng = key.rng(Domain::Camera);
    let mut rng = if world.shapes.is_empty() {
        rng
    } else {
        rng.stratified(seed, key.pixel, index)
    };
    let film = Vec2::new(x as f32, y as f32) + rng.next_vec2();
    let ray = Ray::at_time(
        world.camera.position(),
        world.camera.direction(film),
        integrator.sample_time(world, key),
    );
    let mut r = integrator.li(world, &ray, &mut rng, key);
    if let Some(step) = guide_step.filter(|_| index < guide::GUIDE_SAMPLES) {
        r.albedo = Some(guide::along(world, &ray, step, &mut key.rng(Domain::Guide)));
    }
    r
}

/// The tiles of `region`, in a fixed shuffled order: the share of tiles
/// done is then a fair measure of the work done (rows of empty sky do not
/// all come first), which the progress and its ETA rely on.
pub fn tiles(region: Region) -> Vec<Region> {
    let mut t = Vec::new();
    let mut y = region.y0;
    while y < region.y1 {
        let mut x = region.x0;
        while x < region.x1 {
            t.push(Region {
                x0: x,
                y0: y,
                x1: (x + TILE).min(region.x1),
                y1: (y + TILE).min(region.y1),
            });
            x += TILE;
        }
        y += TILE;
    }
    t.sort_by_key(|r| mix64(((r.y0 as u64) << 32) | r.x0 as u64));
    t
}

/// Runs pass `pass` of `integrator` over the film's region: every pixel
/// gets the integrator's samples per pass, numbered on from the samples of
/// the passes before. `progress(done, total)` is called after each tile
/// (from worker threads). Call [`Integrator::begin_pass`] first.
pub fn render_pass(
    world: &World,
    integrator: &dyn Integrator,
    film: &mut Film,
    seed: u64,
    pass: u32,
    progress: &(dyn Fn(usize, usize) + Sync),
) {
    let spp = integrator.samples_per_pass();
    let first = pass as u64 * spp as u64;
    let tiles = tiles(film.region);
    let total = tiles.len();
    let guide_step = film.has_guides().then(|| guide::step(world));
    let done = AtomicUsize::new(0);
    // Each pixel lies in one tile, so its sums see its samples in order
    // whichever thread adds a tile when: the film is the same bits on any
    // number of threads.
    let film = Mutex::new(film);
    tiles.into_par_iter().for_each(|t| {
        // A signal asked to stop: leave the rest (the caller sees it).
        if crate::interrupt::abandon() {
            return;
        }
        let mut out = Vec::with_capacity(t.pixels() * spp as usize);
        for y in t.y0..t.y1 {
            for x in t.x0..t.x1 {
                for s in 0..spp {
                    out.push(camera_sample_guided(
                        world,
                        integrator,
                        seed,
                        (x, y),
                        first + s as u64,
                        guide_step,
                    ));
                }
            }
        }
        {
            let mut f = film.lock().unwrap_or_else(|e| e.into_inner());
            let mut k = 0;
            for y in t.y0..t.y1 {
                for x in t.x0..t.x1 {
                    for _ in 0..spp {
                        f.add(x, y, &out[k]);
                        k += 1;
                    }
                }
            }
        }
        progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
    });
}

/// Renders the whole image with the reference path tracer at
/// `settings.spp` samples per pixel (tests and benchmarks).
/// `progress(done, total)` counts tiles over all passes.
pub fn render(
    world: &World,
    settings: &Settings,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Film {
    let integrator = PathIntegrator::new(settings.max_bounces);
    let region = Region::full(settings.width, settings.height);
    let mut film = Film::new(settings.width, settings.height, region, true);
    let per_pass = tiles(region).len();
    let total = per_pass * settings.spp as usize;
    for pass in 0..settings.spp {
        let before = pass as usize * per_pass;
        render_pass(
            world,
            &integrator,
            &mut film,
            settings.seed,
            pass,
            &|d, _| progress(before + d, total),
        );
    }
    film
}

/// Mean of `spp` path-traced samples of pixel (x, y): [L, direct, indirect,
/// emission] and the transmittance along the camera ray (tests).
pub fn render_pixel(world: &World, settings: &Settings, x: u32, y: u32) -> ([Rgb; 4], f32) {
    let integrator = PathIntegrator::new(settings.max_bounces);
    let mut acc = [Rgb::ZERO; 4];
    let mut tr = 0.0f32;
    for s in 0..settings.spp {
        let r = camera_sample(world, &integrator, settings.seed, x, y, s as u64);
        if r.l.is_finite() {
            acc[0] += r.l;
            acc[1] += r.direct;
            acc[2] += r.indirect;
            acc[3] += r.emission;
        }
        tr += r.transmittance;
    }
    let inv = 1.0 / settings.spp as f32;
    (acc.map(|a| a * inv), tr * inv)
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
    run_passes_from(
        world,
        integrator,
        film,
        seed,
        stop,
        Position::default(),
        reporter,
        |f, i, at, _| after_pass(f, i, at.passes),
    )
    .map(|at| at.passes)
}

/// [`run_passes`] going on from `start` (a resumed render: the film and the
/// integrator hold its first `start.passes` passes; a time budget counts
/// `start.seconds`). `after_pass(film, integrator, position, last)` is
/// called after each pass, and with `last` set once a stop was asked
/// (SIGINT, SIGTERM): within [`crate::interrupt::finish_passes`] the pass
/// in progress finishes first, so that a last checkpoint keeps it.
#[allow(clippy::too_many_arguments)]
pub fn run_passes_from(
    world: &World,
    integrator: &mut dyn Integrator,
    film: &mut Film,
    seed: u64,
    stop: Stop,
    start: Position,
    reporter: &dyn Reporter,
    mut after_pass: impl FnMut(&Film, &dyn Integrator, Position, bool) -> Result<()>,
) -> Result<Position> {
    let t0 = Instant::now();
    let mut at = start;
    let elapsed = |t0: Instant| start.seconds + t0.elapsed().as_secs_f64();
    loop {
        let done = match stop {
            Stop::Time(limit) => at.passes > 0 && elapsed(t0) + at.last_pass > limit.as_secs_f64(),
            Stop::Passes(n) => at.passes >= n,
        };
        if done {
            return Ok(at);
        }
        if let Err(e) = crate::interrupt::check() {
            after_pass(film, integrator, at, true)?;
            return Err(e);
        }
        let tp = Instant::now();
        integrator.begin_pass(world, at.passes);
        let done_before = at.passes;
        let report = |done: usize, total: usize| {
            let in_pass = done as f64 / total.max(1) as f64;
            let elapsed = elapsed(t0);
            let (fraction, eta) = match stop {
                Stop::Time(limit) => {
                    let l = limit.as_secs_f64().max(1e-9);
                    ((elapsed / l).min(1.0), Some((l - elapsed).max(0.0)))
                }
                Stop::Passes(n) => {
                    // The ETA from this run's rate (a resumed render's
                    // earlier passes ran elsewhere, perhaps slower).
                    let f = (done_before as f64 + in_pass) / n.max(1) as f64;
                    let f0 = start.passes as f64 / n.max(1) as f64;
                    let run = t0.elapsed().as_secs_f64();
                    (f, (f > f0).then(|| run * (1.0 - f) / (f - f0)))
                }
            };
            reporter.progress(Progress {
                fraction,
                elapsed,
                eta,
                passes: done_before,
            });
        };
        render_pass(world, integrator, film, seed, at.passes, &report);
        // An abandoned pass is incomplete: stop before anything is
        // written from it.
        if crate::interrupt::abandon() {
            crate::interrupt::check()?;
        }
        at.passes += 1;
        at.last_pass = tp.elapsed().as_secs_f64();
        at.seconds = elapsed(t0);
        after_pass(
            film,
            integrator,
            at,
            crate::interrupt::requested().is_some(),
        )?;
    }
}
