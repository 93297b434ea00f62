//! Free-flight sampling and transmittance through heterogeneous media, written
//! once and shared by every integrator.
//!
//! - [`sample_t_maj`]: delta (Woodcock) tracking — Woodcock et al. 1965,
//!   "Techniques used in the GEM code"; as a null-collision framework with a
//!   callback per tentative collision, pbrt-v4 §14.2.1 `SampleT_maj`. The
//!   majorant is piecewise constant along the ray (the DDA over the majorant
//!   grid), and the exponential's memorylessness lets sampling restart at
//!   each piece's start.
//! - [`transmittance`]: ratio tracking (Novák, Selle & Jarosz 2014,
//!   "Residual ratio tracking for estimating attenuation in participating
//!   media"), unbiased for RGB extinction with a scalar majorant, with
//!   Russian roulette once the estimate is small.
//! - [`optical_depth`]: deterministic-step quadrature of ∫σt along a segment
//!   with a jittered start (for the ray-marching integrator).

use crate::medium::{Media, MediumPoint};
use crate::sampling::Rng;
use crate::Rgb;
use glam::Vec3;
use std::cell::Cell;

thread_local! {
    static LOOKUPS: Cell<u64> = const { Cell::new(0) };
    static REAL: Cell<u64> = const { Cell::new(0) };
}

/// Counters of the calling thread: tentative collisions (each a lookup of
/// the media) and the real collisions integrators report with
/// [`count_real_collision`]. For benchmarks; reading resets them.
pub fn take_counters() -> (u64, u64) {
    (LOOKUPS.with(|c| c.replace(0)), REAL.with(|c| c.replace(0)))
}

/// Records a real (absorption or scattering) collision.
#[inline]
pub fn count_real_collision() {
    REAL.with(|c| c.set(c.get() + 1));
}

/// What the callback of [`sample_t_maj`] sees at a tentative collision.
#[derive(Debug, Clone, Copy)]
pub struct Collision {
    /// Distance along the ray.
    pub t: f32,
    /// World position.
    pub p: Vec3,
    /// The optics there (summed over volumes).
    pub medium: MediumPoint,
    /// The majorant of sigma_t there, per world unit (≥ every channel of
    /// `medium.sigma_t()`).
    pub sigma_maj: f32,
}

/// Samples tentative collisions along `o + t d` (`d` unit) in `[0, t_max)`
/// with density `sigma_maj`, calling `f` at each; `f` returns false to stop.
/// Returns true when the ray reached `t_max` (or left every volume) without
/// `f` stopping it.
#[inline]
pub fn sample_t_maj(
    media: &Media,
    o: Vec3,
    d: Vec3,
    t_max: f32,
    rng: &mut Rng,
    mut f: impl FnMut(&Collision, &mut Rng) -> bool,
) -> bool {
    let mut reached_end = true;
    media.for_each_segment(o, d, 0.0, t_max, |seg| {
        if seg.max_density <= 0.0 {
            return true;
        }
        let mut t = seg.t0;
        loop {
            // 1 - u is in (0, 1], so the logarithm is finite.
            t -= (1.0 - rng.next_f32()).ln() / seg.max_density;
            if t >= seg.t1 {
                return true;
            }
            let p = o + d * t;
            LOOKUPS.with(|c| c.set(c.get() + 1));
            let c = Collision {
                t,
                p,
                medium: media.eval(p),
                sigma_maj: seg.max_density,
            };
            if !f(&c, rng) {
                reached_end = false;
                return false;
            }
        }
    });
    reached_end
}

/// Transmittance along `o + t d` over `[0, t_max)` by ratio tracking: the
/// product of `1 - sigma_t/sigma_maj` over tentative collisions (per RGB
/// channel). Unbiased; Russian roulette when the estimate falls below 0.1.
pub fn transmittance(media: &Media, o: Vec3, d: Vec3, t_max: f32, rng: &mut Rng) -> Rgb {
    let mut tr = Rgb::ONE;
    sample_t_maj(media, o, d, t_max, rng, |c, rng| {
        let ratio = (Rgb::ONE - c.medium.sigma_t() / c.sigma_maj).max(Rgb::ZERO);
        tr *= ratio;
        let m = tr.max_element();
        if m <= 0.0 {
            return false;
        }
        if m < 0.1 {
            let survive = m / 0.1;
            if rng.next_f32() >= survive {
                tr = Rgb::ZERO;
                return false;
            }
            tr /= survive;
        }
        true
    });
    tr
}

/// Optical depth ∫σt dt over `[t0, t1]` of `o + t d` by the midpoint rule
/// with `steps` equal steps, the sample points shifted by `jitter` ∈ [0, 1)
/// of a step (stratified: unbiased in expectation over the jitter).
pub fn optical_depth(
    media: &Media,
    o: Vec3,
    d: Vec3,
    t0: f32,
    t1: f32,
    steps: u32,
    jitter: f32,
) -> Rgb {
    let steps = steps.max(1);
    let dt = (t1 - t0) / steps as f32;
    let mut tau = Rgb::ZERO;
    for i in 0..steps {
        let t = t0 + (i as f32 + jitter) * dt;
        tau += media.eval(o + d * t).sigma_t();
    }
    tau * dt
}
