//! Integrators and the render loop that drives them.
//!
//! The film is cut into 16x16 tiles rendered in parallel (rayon). Every
//! random number of a camera sample comes from a stream keyed by (seed,
//! pixel, sample index), never by the thread, so an image is identical
//! whatever the thread count. Pixels use a box filter of one pixel (each
//! sample at a uniformly random position in its pixel), as the reference
//! renders do.

pub mod path;

use crate::sampling::{Domain, Rng};
use crate::tracking;
use crate::world::World;
use crate::Rgb;
use glam::Vec2;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// What one camera sample returns.
#[derive(Debug, Clone, Copy, Default)]
pub struct SampleResult {
    /// Radiance along the camera ray.
    pub l: Rgb,
    /// Light that scattered once in the media (lights and environment).
    pub direct: Rgb,
    /// Light that scattered more than once.
    pub indirect: Rgb,
    /// Emission of the media (at any depth).
    pub emission: Rgb,
}

/// Settings of a render (validated by the scene module and the CLI).
#[derive(Debug, Clone)]
pub struct Settings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub seed: u64,
    /// Real scattering events at most along a path.
    pub max_bounces: u32,
}

/// The rendered film: mean per pixel, row-major from the top row.
#[derive(Debug, Clone)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<Rgb>,
    /// Mean transmittance along the camera ray (alpha = 1 − this).
    pub transmittance: Vec<f32>,
    pub direct: Vec<Rgb>,
    pub indirect: Vec<Rgb>,
    pub emission: Vec<Rgb>,
}

const TILE: u32 = 16;

/// A rendered pixel: position, [L, direct, indirect, emission], transmittance.
type PixelOut = (u32, u32, [Rgb; 4], f32);

/// Streams of one render: the stream number of a camera sample.
fn pixel_stream(x: u32, y: u32, width: u32) -> u64 {
    y as u64 * width as u64 + x as u64
}

/// Renders the world with the reference path tracer. `progress(done,
/// total)` is called after each tile (from worker threads).
pub fn render(
    world: &World,
    settings: &Settings,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Film {
    let (w, h) = (settings.width, settings.height);
    let tiles_x = w.div_ceil(TILE);
    let tiles_y = h.div_ceil(TILE);
    let total = (tiles_x * tiles_y) as usize;
    let done = AtomicUsize::new(0);
    let tiles: Vec<Vec<PixelOut>> = (0..total)
        .into_par_iter()
        .map(|t| {
            let tx = (t as u32 % tiles_x) * TILE;
            let ty = (t as u32 / tiles_x) * TILE;
            let mut out = Vec::with_capacity((TILE * TILE) as usize);
            for y in ty..(ty + TILE).min(h) {
                for x in tx..(tx + TILE).min(w) {
                    let (acc, tr) = render_pixel(world, settings, x, y);
                    out.push((x, y, acc, tr));
                }
            }
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress(n, total);
            out
        })
        .collect();
    let n = (w * h) as usize;
    let mut film = Film {
        width: w,
        height: h,
        rgb: vec![Rgb::ZERO; n],
        transmittance: vec![1.0; n],
        direct: vec![Rgb::ZERO; n],
        indirect: vec![Rgb::ZERO; n],
        emission: vec![Rgb::ZERO; n],
    };
    for tile in tiles {
        for (x, y, acc, tr) in tile {
            let i = (y * w + x) as usize;
            film.rgb[i] = acc[0];
            film.direct[i] = acc[1];
            film.indirect[i] = acc[2];
            film.emission[i] = acc[3];
            film.transmittance[i] = tr;
        }
    }
    film
}

/// Mean of `spp` samples of pixel (x, y): [L, direct, indirect, emission]
/// and the transmittance along the camera ray.
pub fn render_pixel(world: &World, settings: &Settings, x: u32, y: u32) -> ([Rgb; 4], f32) {
    let stream = pixel_stream(x, y, settings.width);
    let mut acc = [Rgb::ZERO; 4];
    let mut tr_sum = 0.0f32;
    for s in 0..settings.spp {
        let mut rng = Rng::new(Domain::Camera, settings.seed, stream, s as u64);
        let film = Vec2::new(x as f32, y as f32) + rng.next_vec2();
        let o = world.camera.position();
        let d = world.camera.direction(film);
        let r = path::trace(world, settings, o, d, &mut rng);
        // Alpha: ratio-tracked transmittance of the camera ray, from a
        // stream of its own so it does not perturb the path.
        let mut rng_t = Rng::new(Domain::Alpha, settings.seed, stream, s as u64);
        let tr = tracking::transmittance(&world.media, o, d, f32::INFINITY, &mut rng_t);
        tr_sum += (tr.x + tr.y + tr.z) / 3.0;
        if r.l.is_finite() {
            acc[0] += r.l;
            acc[1] += r.direct;
            acc[2] += r.indirect;
            acc[3] += r.emission;
        }
    }
    let inv = 1.0 / settings.spp as f32;
    (acc.map(|a| a * inv), tr_sum * inv)
}
