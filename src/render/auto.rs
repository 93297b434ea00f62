//! `auto`: the integrator that renders a frame best, found by measuring
//! both on the frame itself rather than by thresholds fitted to a set of
//! scenes.
//!
//! Both integrators render a short pilot, their passes alternating, on a
//! lattice of one pixel in [`PILOT_STRIDE`] spread evenly over the frame
//! ([`pilot_pixels`]), at the frame's own resolution: the photon integrator's kernels, the camera's footprint and
//! the photon count of a pass are the render's. Each pilot's error is
//! estimated from its two halves, the even and the odd passes, as the
//! denoiser's blend does (`crate::denoise::blend`): for independent passes
//! E[(a − b)²] / 4 is the variance of their mean m, so
//! mean((a − b)² / 4 / (m² + 0.01)) estimates the relative MSE of the
//! pilot's image (the benchmarks' formula) without a reference. The same
//! estimate halfway through gives how fast the error falls with passes
//! ([`EXPONENT_RANGE`]): 1/n for independent, unbiased passes once their
//! rare bright paths are sampled, slower for progressive photon mapping,
//! whose kernels shrink from pass to pass, and slower too for a path
//! tracer whose halves have not yet met the rare paths that carry much of
//! the light (a small fire seen through smoke): its error then grows with
//! the samples that meet them, and the measured fall says so.
//! A pass of the whole frame costs the photon trace of the pilot's pass
//! plus its camera samples scaled by the frame's pixels over the pilot's.
//!
//! The integrator whose predicted error at the render's horizon (its time
//! budget, or for a sample count the time the path tracer needs for it) is
//! lower renders the frame; the header says what was measured and why.
//!
//! What the halves cannot see is the photon estimate's bias (the blur of
//! its kernels, which shrinks with the passes): the prediction is of its
//! variance. The bench `cargo bench --bench equal_time` measures both
//! against converged references.

use super::passes::camera_sample_guided;
use crate::integrator::Integrator;
use crate::world::World;
use crate::Rgb;
use rayon::prelude::*;
use std::time::Instant;

/// One pixel in this many renders the pilot.
pub const PILOT_STRIDE: u32 = 8;

/// The pixels of the pilots: in row y, those whose x + 3y is a multiple of
/// [`PILOT_STRIDE`] (3 is prime to 8, so the columns cycle row by row), an
/// even lattice over the frame: its mean error and cost are the frame's,
/// wherever the volumes are. (The first tiles of the frame's shuffled
/// order were not: ten 16 x 16 tiles of the benchmark's reference cloud at
/// 160 x 120 held almost none of it, and estimated the path tracer's error
/// a hundredth of the frame's.)
pub fn pilot_pixels(width: u32, height: u32) -> Vec<(u32, u32)> {
    let mut p = Vec::new();
    for y in 0..height {
        let first = (PILOT_STRIDE - (3 * y) % PILOT_STRIDE) % PILOT_STRIDE;
        p.extend(
            (first..width)
                .step_by(PILOT_STRIDE as usize)
                .map(|x| (x, y)),
        );
    }
    p
}

/// Pilot pixels a job of the thread pool takes at a time.
const PILOT_CHUNK: usize = 64;

/// The share of the render's horizon the pilots spend together.
pub const PILOT_SHARE: f64 = 0.04;

/// The longest the pilots measure (a long render's 4 % would be minutes
/// without a word of progress, and the estimates are steady long before).
pub const MAX_PILOT_SECONDS: f64 = 20.0;

/// The share of a short render's horizon after which the pilots stop at
/// two passes each (a frame of few passes whose photon passes are dear).
pub const MAX_PILOT_SHARE: f64 = 0.15;

/// Passes each pilot runs at least (two per half, so that the error
/// halfway is measured; two in a short render, [`MAX_PILOT_SHARE`]) and at
/// most.
pub const MIN_PILOT_PASSES: u32 = 4;
pub const MAX_PILOT_PASSES: u32 = 64;

/// The range the measured fall of the error with passes (the exponent of
/// n) is clamped to: no faster than the 1/n of independent passes, and no
/// slower than not at all. An error that does not fall over the pilot is
/// one whose rare bright paths the pilot has only begun to meet: a path
/// tracer's light from a small fire through smoke grew from 5.2e-3 to
/// 1.1e-2 over 6 pilot passes, and its true error after 2,900 passes
/// was still 2e-2 (tests/auto.rs).
pub const EXPONENT_RANGE: (f64, f64) = (0.0, 1.0);

/// How long the render will run: a time budget, or a number of passes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Horizon {
    Seconds(f64),
    Passes(u32),
}

/// What a pilot measured of one integrator.
#[derive(Debug, Clone, PartialEq)]
pub struct Measured {
    pub name: &'static str,
    /// Passes the pilot ran.
    pub passes: u32,
    /// The estimated relative MSE of the pilot's image after them.
    pub rel_mse: f64,
    /// The same after (about) half of them.
    pub rel_mse_half: f64,
    /// How the error falls with passes: relative MSE ∝ n^(−exponent).
    pub exponent: f64,
    /// The seconds a pass of the whole frame takes.
    pub seconds_per_pass: f64,
    /// The seconds the pilot took.
    pub seconds: f64,
}

impl Measured {
    /// The relative MSE predicted after `seconds` of passes of the whole
    /// frame (at least one pass).
    pub fn predicted(&self, seconds: f64) -> f64 {
        let n = (seconds / self.seconds_per_pass.max(1e-12)).max(1.0);
        self.rel_mse * (self.passes as f64 / n).powf(self.exponent)
    }
}

/// A pilot's running sums over its pixels, by half.
struct Pilot<'a> {
    name: &'static str,
    integrator: &'a mut dyn Integrator,
    halves: [Vec<Rgb>; 2],
    passes: u32,
    /// The estimated relative MSE after each even number of passes
    /// (index k: after 2k passes).
    errors: Vec<f64>,
    begin_seconds: f64,
    camera_seconds: f64,
}

impl Pilot<'_> {
    /// The seconds a pass of the whole frame takes: the pass's own work
    /// (the photon trace) and its camera samples times `scale`, the
    /// frame's pixels over the pilot's.
    fn seconds_per_pass(&self, scale: f64) -> f64 {
        (self.begin_seconds + self.camera_seconds * scale) / self.passes.max(1) as f64
    }

    /// The estimated relative MSE of the mean of the passes so far, from
    /// its halves (an even number of passes).
    fn rel_mse(&self) -> f64 {
        let per_half = (self.passes / 2).max(1) as f64;
        let [a, b] = &self.halves;
        let mut sum = 0.0f64;
        for (a, b) in a.iter().zip(b) {
            for c in 0..3 {
                let (x, y) = (a[c] as f64 / per_half, b[c] as f64 / per_half);
                // The mean's variance, and the reference's square as m²
                // less that variance (E[m²] = μ² + Var m): with m² itself
                // the noisier early passes divide by more, so the error
                // seemed to fall slower than it does (as n^-0.86 for the
                // path tracer on the reference cloud).
                let var = (x - y) * (x - y) / 4.0;
                let m = 0.5 * (x + y);
                sum += var / ((m * m - var).max(0.0) + 0.01);
            }
        }
        sum / (3 * a.len()).max(1) as f64
    }
}

/// Runs the pilots of `candidates` (name, integrator) over the frame's
/// [`pilot_pixels`],
/// camera seed `seed`, for about [`PILOT_SHARE`] of `horizon`, and returns
/// what each measured. The integrators are left after their pilot passes
/// (build fresh ones to render).
pub fn measure(
    world: &World,
    candidates: Vec<(&'static str, &mut dyn Integrator)>,
    seed: u64,
    horizon: Horizon,
) -> Vec<Measured> {
    let (w, h) = (world.camera.width(), world.camera.height());
    let pixels = pilot_pixels(w, h);
    let pilot_pixels = pixels.len();
    let scale = (w as f64 * h as f64) / pilot_pixels.max(1) as f64;
    // Samples of their own: the render's first samples stay independent.
    let seed = seed ^ 0xA076_1D64_78BD_642F;
    let mut pilots: Vec<Pilot> = candidates
        .into_iter()
        .map(|(name, integrator)| Pilot {
            name,
            integrator,
            halves: [vec![Rgb::ZERO; pilot_pixels], vec![Rgb::ZERO; pilot_pixels]],
            passes: 0,
            errors: vec![f64::NAN],
            begin_seconds: 0.0,
            camera_seconds: 0.0,
        })
        .collect();
    let t0 = Instant::now();
    loop {
        for p in pilots.iter_mut() {
            let pass = p.passes;
            let tb = Instant::now();
            p.integrator.begin_pass(world, pass);
            p.begin_seconds += tb.elapsed().as_secs_f64();
            let tc = Instant::now();
            let integrator: &dyn Integrator = &*p.integrator;
            let spp = integrator.samples_per_pass().max(1);
            let first = pass as u64 * spp as u64;
            let values: Vec<Vec<Rgb>> = pixels
                .par_chunks(PILOT_CHUNK)
                .map(|chunk| {
                    chunk
                        .iter()
                        .map(|&(x, y)| {
                            let mut l = Rgb::ZERO;
                            for s in 0..spp {
                                let r = camera_sample_guided(
                                    world,
                                    integrator,
                                    seed,
                                    (x, y),
                                    first + s as u64,
                                    None,
                                );
                                // As the film: a sample that is not a
                                // number is left out.
                                if r.l.is_finite() {
                                    l += r.l;
                                }
                            }
                            l / spp as f32
                        })
                        .collect()
                })
                .collect();
            p.camera_seconds += tc.elapsed().as_secs_f64();
            let half = &mut p.halves[(pass % 2) as usize];
            for (sum, v) in half.iter_mut().zip(values.into_iter().flatten()) {
                *sum += v;
            }
            p.passes += 1;
            if p.passes % 2 == 0 {
                let e = p.rel_mse();
                p.errors.push(e);
            }
        }
        let passes = pilots.iter().map(|p| p.passes).min().unwrap_or(0);
        if passes >= MAX_PILOT_PASSES {
            break;
        }
        if passes % 2 == 1 {
            continue;
        }
        let horizon_seconds = match horizon {
            Horizon::Seconds(s) => s,
            Horizon::Passes(n) => {
                n as f64
                    * pilots
                        .iter()
                        .map(|p| p.seconds_per_pass(scale))
                        .fold(f64::INFINITY, f64::min)
            }
        };
        let spent = t0.elapsed().as_secs_f64();
        // Enough measured; or a short render whose pilots would cost too
        // large a share of it (two passes each then: the error, without
        // its fall, taken as 1/n); or a stop asked (the render that
        // follows stops at once).
        let share = PILOT_SHARE * horizon_seconds;
        if passes >= MIN_PILOT_PASSES && spent >= share.min(MAX_PILOT_SECONDS)
            || spent >= MAX_PILOT_SHARE * horizon_seconds
            || crate::interrupt::abandon()
        {
            break;
        }
    }
    pilots
        .iter()
        .map(|p| {
            let k = p.errors.len() - 1;
            let rel_mse = p.errors[k];
            let half = p.errors[(k / 2).max(1)];
            // The fall by least squares over log error against log passes,
            // every even count from 2 (more stable than two points).
            let points: Vec<(f64, f64)> = (1..=k)
                .filter(|&i| p.errors[i] > 0.0)
                .map(|i| ((2.0 * i as f64).ln(), p.errors[i].ln()))
                .collect();
            let measured_exponent = if points.len() >= 2 {
                let n = points.len() as f64;
                let (mx, my) = points
                    .iter()
                    .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
                let sxy: f64 = points.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
                let sxx: f64 = points.iter().map(|(x, _)| (x - mx) * (x - mx)).sum();
                -sxy / sxx
            } else {
                EXPONENT_RANGE.1
            };
            let exponent = if measured_exponent.is_finite() {
                measured_exponent.clamp(EXPONENT_RANGE.0, EXPONENT_RANGE.1)
            } else {
                EXPONENT_RANGE.1
            };
            Measured {
                name: p.name,
                passes: p.passes,
                rel_mse,
                rel_mse_half: half,
                exponent,
                seconds_per_pass: p.seconds_per_pass(scale),
                seconds: p.begin_seconds + p.camera_seconds,
            }
        })
        .collect()
}

/// The time the render of `horizon` is predicted at, from what the pilots
/// measured: its budget less the pilots' time, or its passes at the
/// fastest integrator's pace.
pub fn horizon_seconds(measured: &[Measured], horizon: Horizon) -> f64 {
    match horizon {
        Horizon::Seconds(s) => {
            let spent: f64 = measured.iter().map(|m| m.seconds).sum();
            (s - spent).max(s * 0.5)
        }
        Horizon::Passes(n) => {
            n as f64
                * measured
                    .iter()
                    .map(|m| m.seconds_per_pass)
                    .fold(f64::INFINITY, f64::min)
        }
    }
}

/// The integrator with the lowest predicted error at `horizon`, and the
/// header's line on why (ties to the first).
pub fn decide(measured: &[Measured], horizon: Horizon) -> (&'static str, String) {
    let t = horizon_seconds(measured, horizon);
    let mut best = 0;
    for (i, m) in measured.iter().enumerate() {
        if m.predicted(t) < measured[best].predicted(t) {
            best = i;
        }
    }
    let parts: Vec<String> = measured
        .iter()
        .map(|m| {
            format!(
                "{}: {} pilot passes, relative MSE {:.2e} (after half {:.2e}, falling as n^-{:.2}), {:.3} s a pass of the frame, predicted {:.2e}",
                m.name,
                m.passes,
                m.rel_mse,
                m.rel_mse_half,
                m.exponent,
                m.seconds_per_pass,
                m.predicted(t)
            )
        })
        .collect();
    let name = measured.get(best).map_or("path", |m| m.name);
    (
        name,
        format!(
            "measured on pilots ({}) for a render of {t:.1} s: {}, the lower predicted error",
            parts.join("; "),
            name
        ),
    )
}
