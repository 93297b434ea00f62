//! Free-flight sampling and transmittance through heterogeneous media, written
//! once and shared by every integrator.
//!
//! - [`sample_t_maj`]: delta (Woodcock) tracking — Woodcock et al. 1965,
//!   "Techniques used in the GEM code"; as a null-collision framework with a
//!   callback per tentative collision, pbrt-v4 §14.2.1 `SampleT_maj`. The
//!   majorant is piecewise constant along the ray (the DDA over the majorant
//!   grid), and the exponential's memorylessness lets sampling restart at
//!   each piece's start.
//! - [`collide`]: what a path does at a tentative collision (spectral and
//!   decomposition tracking, Kutz et al. 2017), shared by the integrators.
//! - [`transmittance`]: residual ratio tracking (Novák, Selle & Jarosz 2014,
//!   "Residual ratio tracking for estimating attenuation in participating
//!   media") with the majorant grid's minorant as the control, unbiased for
//!   RGB extinction, with Russian roulette once the estimate is small.
//! - [`optical_depth`]: deterministic-step quadrature of ∫σt along a segment
//!   with a jittered start (for the ray-marching integrator).

use crate::medium::{Media, MediumPoint};
use crate::sampling::Rng;
use crate::Rgb;
use glam::Vec3;
use std::cell::Cell;

thread_local! {
    static TENTATIVE: Cell<u64> = const { Cell::new(0) };
    static LOOKUPS: Cell<u64> = const { Cell::new(0) };
    static REAL: Cell<u64> = const { Cell::new(0) };
}

/// Tracking statistics of one thread, for benchmarks.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// Tentative collisions sampled (delta and ratio tracking).
    pub tentative: u64,
    /// Evaluations of the media (each reads every grid of the volumes).
    pub lookups: u64,
    /// Real collisions (scattering events, weighted absorption included).
    pub real: u64,
}

/// The counters of the calling thread; reading resets them.
pub fn take_counters() -> Counters {
    Counters {
        tentative: TENTATIVE.with(|c| c.replace(0)),
        lookups: LOOKUPS.with(|c| c.replace(0)),
        real: REAL.with(|c| c.replace(0)),
    }
}

#[inline]
fn bump(c: &'static std::thread::LocalKey<Cell<u64>>) {
    c.with(|c| c.set(c.get() + 1));
}

/// Records a real collision.
#[inline]
fn count_real_collision() {
    bump(&REAL);
}

/// What the callback of [`sample_t_maj`] sees at a tentative collision. The
/// optics are looked up only on demand ([`Collision::medium`]): with a
/// control medium, many collisions are decided without them.
#[derive(Debug, Clone, Copy)]
pub struct Collision<'a> {
    /// Distance along the ray.
    pub t: f32,
    /// World position.
    pub p: Vec3,
    /// The majorant of sigma_t here, per world unit (≥ every channel of
    /// sigma_t).
    pub sigma_maj: f32,
    /// A minorant of sigma_t here (≤ every channel; 0 where none is known):
    /// the extinction of the homogeneous control medium of decomposition
    /// tracking.
    pub sigma_c: f32,
    media: &'a Media,
}

impl Collision<'_> {
    /// The optics here (summed over volumes): one lookup, counted.
    #[inline]
    pub fn medium(&self) -> MediumPoint {
        bump(&LOOKUPS);
        self.media.eval(self.p)
    }
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
            bump(&TENTATIVE);
            let c = Collision {
                t,
                p: o + d * t,
                sigma_maj: seg.max_density,
                sigma_c: seg.min_density.min(seg.max_density),
                media,
            };
            if !f(&c, rng) {
                reached_end = false;
                return false;
            }
        }
    });
    reached_end
}

/// The outcome of a tentative collision for a path, from [`collide`].
#[derive(Debug, Clone, Copy)]
pub struct Step {
    /// True for a real collision: the path scatters here (absorption is in
    /// `weight`); false for a null collision: it flies on.
    pub scatter: bool,
    /// Factor for the path throughput β.
    pub weight: Rgb,
    /// The optics, when they were looked up (always without a control
    /// medium; emissive media never have one).
    pub medium: Option<MediumPoint>,
}

#[inline]
fn avg(c: Rgb) -> f32 {
    (c.x + c.y + c.z) * (1.0 / 3.0)
}

/// Decides a tentative collision for a path with throughput `beta`.
///
/// Spectral tracking with history-aware probabilities (Kutz, Habel, Li &
/// Novák 2017, §5): with σn = σ̄ − σt, the collision is real with
/// probability ∝ avg(β·σt) and null with probability ∝ avg(β·σn), and the
/// weight σs/(σ̄·P) or σn/(σ̄·P) keeps the estimator unbiased for RGB
/// coefficients. Absorption is carried in the weight (σs instead of σt in
/// the numerator) rather than ending the path.
///
/// With a control medium (the media's albedo the same everywhere, and no
/// emission: [`Media::control_albedo`]) the real part splits into the control's σc and the
/// residual σt − σc (decomposition tracking, Kutz et al. 2017 §4). The
/// control part has probability σc/σ̄ and weight σs/σt = the albedo: it
/// needs no lookup. Only the rest, a fraction 1 − σc/σ̄, reads the grids.
#[inline]
pub fn collide(c: &Collision, beta: Rgb, rng: &mut Rng) -> Option<Step> {
    let u = rng.next_f32();
    let mut p_c = 0.0;
    if let Some(albedo) = c.media.control_albedo() {
        p_c = c.sigma_c / c.sigma_maj;
        if u < p_c {
            count_real_collision();
            return Some(Step {
                scatter: true,
                weight: albedo,
                medium: None,
            });
        }
    }
    let m = c.medium();
    let sigma_t = m.sigma_t();
    let sigma_n = (Rgb::splat(c.sigma_maj) - sigma_t).max(Rgb::ZERO);
    let sigma_r = (sigma_t - Rgb::splat(c.sigma_c)).max(Rgb::ZERO);
    let (wr, wn) = (avg(beta * sigma_r), avg(beta * sigma_n));
    let rest = wr + wn;
    if rest <= 0.0 {
        return None;
    }
    // u is uniform on [p_c, 1) here: rescale it to the rest.
    let v = (u - p_c) / (1.0 - p_c) * rest;
    let p_rest = (1.0 - p_c) / rest;
    if v < wr || wn <= 0.0 {
        count_real_collision();
        // σs·(σr/σt): the residual's share of the scattering.
        let share = Rgb::select(sigma_t.cmpgt(Rgb::ZERO), sigma_r / sigma_t, Rgb::ZERO);
        Some(Step {
            scatter: true,
            weight: m.sigma_s * share / (c.sigma_maj * wr * p_rest),
            medium: Some(m),
        })
    } else {
        Some(Step {
            scatter: false,
            weight: sigma_n / (c.sigma_maj * wn * p_rest),
            medium: Some(m),
        })
    }
}

/// Transmittance along `o + t d` over `[0, t_max)` by residual ratio
/// tracking (Novák, Selle & Jarosz 2014, §4): on each stretch of constant
/// bounds the control medium σc (the minorant) attenuates analytically by
/// exp(−σc·len), and tentative collisions at the residual rate σ̄ − σc each
/// multiply by `1 − (sigma_t − σc)/(σ̄ − σc)` (per RGB channel). Without a
/// minorant it is plain ratio tracking. Unbiased; Russian roulette when the
/// estimate falls below 0.1.
pub fn transmittance(media: &Media, o: Vec3, d: Vec3, t_max: f32, rng: &mut Rng) -> Rgb {
    let mut tr = Rgb::ONE;
    // Russian roulette on a small estimate; false when it ends at zero.
    let roulette = |tr: &mut Rgb, rng: &mut Rng| {
        let m = tr.max_element();
        if m <= 0.0 {
            *tr = Rgb::ZERO;
            return false;
        }
        if m < 0.1 {
            let survive = m / 0.1;
            if rng.next_f32() >= survive {
                *tr = Rgb::ZERO;
                return false;
            }
            *tr /= survive;
        }
        true
    };
    media.for_each_segment(o, d, 0.0, t_max, |seg| {
        let sigma_c = seg.min_density.min(seg.max_density);
        if sigma_c > 0.0 {
            tr *= (-sigma_c * (seg.t1 - seg.t0)).exp();
            if !roulette(&mut tr, rng) {
                return false;
            }
        }
        let rate = seg.max_density - sigma_c;
        if rate <= 0.0 {
            return true;
        }
        let mut t = seg.t0;
        loop {
            t -= (1.0 - rng.next_f32()).ln() / rate;
            if t >= seg.t1 {
                return true;
            }
            bump(&TENTATIVE);
            bump(&LOOKUPS);
            let m = media.eval(o + d * t);
            let ratio = Rgb::ONE - (m.sigma_t() - Rgb::splat(sigma_c)) / rate;
            tr *= ratio.clamp(Rgb::ZERO, Rgb::ONE);
            if !roulette(&mut tr, rng) {
                return false;
            }
        }
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
