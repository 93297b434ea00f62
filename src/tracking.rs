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
//! - [`transmittance_emission`]: the same walk also estimating the
//!   emission that reaches the ray's origin (for camera rays through fire).
//! - [`sample_t_maj_camera`]: a camera ray's first flight and its
//!   transmittance (and emission) walk on the same collisions until the
//!   flight scatters.
//! - [`optical_depth`]: deterministic-step quadrature of ∫σt along a segment
//!   with a jittered start (for the ray-marching integrator).

use crate::medium::{Media, MediumPoint, Segment};
use crate::phase::PhaseFunction;
use crate::ray::Ray;
use crate::sampling::{roulette, Rng};
use crate::stats::{count_real, count_tentative};
use crate::Rgb;
use glam::Vec3;

pub use crate::stats::{take_counters, Counters};

/// What the callback of [`sample_t_maj`] sees at a tentative collision. The
/// optics are looked up only on demand ([`Collision::medium`]): with a
/// control medium, many collisions are decided without them.
#[derive(Debug, Clone, Copy)]
pub struct Collision<'a> {
    /// Distance along the ray.
    pub t: f32,
    /// World position.
    pub p: Vec3,
    /// The ray's time (frames from the frame): where moving volumes are.
    pub time: f32,
    /// The rate tentative collisions are sampled at here, per world unit:
    /// the majorant of sigma_t (≥ every channel), raised to the media's
    /// emission rate where something may emit.
    pub sigma_maj: f32,
    /// The extinction of the homogeneous control medium of decomposition
    /// tracking here: the minorant of sigma_t when the media have a control
    /// ([`Media::control_albedo`]), and exactly 0 wherever they have none
    /// (emissive media, volumes that differ in albedo or phase, a colour
    /// grid). Never a bound alone: collisions of the control are decided
    /// without looking the optics up, so they must carry the control's
    /// albedo.
    pub sigma_c: f32,
    media: &'a Media,
    /// The optics here and the volume chosen for a scattering event
    /// ([`Media::eval_scatter`]) when the walk that sampled this collision
    /// has looked them up already ([`sample_t_maj_camera`]).
    looked_up: Option<(MediumPoint, usize)>,
    /// The uniform number that decides the collision ([`collide`]) when
    /// the walk has drawn it (to take the control's collisions out of its
    /// own estimate).
    u: Option<f32>,
}

impl Collision<'_> {
    /// The optics here (summed over volumes): one lookup, counted, unless
    /// the walk has made it.
    #[inline]
    pub fn medium(&self) -> MediumPoint {
        match self.looked_up {
            Some((m, _)) => m,
            None => self.media.eval(self.p, self.time),
        }
    }
}

/// Tentative collisions one flight may take: a safety net that bounds the
/// cost of a sample whatever the coefficients (the scene loader refuses
/// extinction beyond `world::MAX_VOXEL_OPTICAL_DEPTH`, within which a
/// flight meets about a thousand per voxel at worst). A flight that uses
/// them up ends as if absorbed.
pub const MAX_TENTATIVE: u32 = 1 << 20;

/// Samples tentative collisions along `ray` (`ray.d` unit) in `[0, t_max)`
/// and calls `f` at each; `f` returns false to stop. The rate is the
/// majorant of σt, and at least the media's emission rate where the
/// majorant grid says something may emit, so that emission is met also
/// where σt = 0. Returns true when the ray reached `t_max` (or left every
/// volume) without `f` stopping it (nor [`MAX_TENTATIVE`]).
#[inline]
pub fn sample_t_maj(
    media: &Media,
    ray: &Ray,
    t_max: f32,
    rng: &mut Rng,
    mut f: impl FnMut(&Collision, &mut Rng) -> bool,
) -> bool {
    let Ray { o, d, time } = *ray;
    let mut reached_end = true;
    let mut budget = MAX_TENTATIVE;
    let control = media.control_albedo().is_some();
    let emission_rate = media.emission_rate();
    media.for_each_segment_at(o, d, 0.0, t_max, time, |seg| {
        let rate = if seg.emission > 0.0 {
            seg.max_density.max(emission_rate)
        } else {
            seg.max_density
        };
        if rate <= 0.0 {
            return true;
        }
        let sigma_c = if control {
            seg.min_density.min(rate)
        } else {
            0.0
        };
        let mut t = seg.t0;
        loop {
            // 1 - u is in (0, 1], so the logarithm is finite.
            t -= (1.0 - rng.next_f32()).ln() / rate;
            if t >= seg.t1 {
                return true;
            }
            budget -= 1;
            if budget == 0 {
                reached_end = false;
                return false;
            }
            count_tentative();
            let c = Collision {
                t,
                p: o + d * t,
                time,
                sigma_maj: rate,
                sigma_c,
                media,
                looked_up: None,
                u: None,
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
    /// The phase function of the scattering event (meaningful when
    /// `scatter`): with overlapping volumes one of theirs, chosen in
    /// proportion to its scattering ([`Media::eval_scatter`]).
    pub phase: PhaseFunction,
    /// The index of the volume whose phase function that is.
    pub volume: usize,
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
/// With a control medium (`c.sigma_c > 0`: the media's albedo the same
/// everywhere, and no emission) the real part splits into the control's σc
/// and the residual σt − σc (decomposition tracking, Kutz et al. 2017 §4).
/// The control part has probability σc/σ̄ and weight σs/σt = the albedo: it
/// needs no lookup. Only the rest, a fraction 1 − σc/σ̄, reads the grids.
/// Without a control σc is 0 and every collision is decided on the looked-up
/// optics, so none of the scattering is lost.
#[inline]
pub fn collide(c: &Collision, beta: Rgb, rng: &mut Rng) -> Option<Step> {
    let u = match c.u {
        Some(u) => u,
        None => rng.next_f32(),
    };
    let u_phase = rng.next_f32();
    let mut p_c = 0.0;
    if c.sigma_c > 0.0 {
        if let (Some(albedo), Some(phase)) = (c.media.control_albedo(), c.media.control_phase()) {
            p_c = c.sigma_c / c.sigma_maj;
            if u < p_c {
                count_real();
                return Some(Step {
                    scatter: true,
                    weight: albedo,
                    medium: None,
                    phase,
                    volume: 0,
                });
            }
        }
    }
    let (m, volume) = match c.looked_up {
        Some(l) => l,
        None => c.media.eval_scatter(c.p, c.time, u_phase),
    };
    let phase = c.media.phase_of(volume);
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
        count_real();
        // σs·(σr/σt): the residual's share of the scattering (all of it
        // without a control).
        let share = Rgb::select(sigma_t.cmpgt(Rgb::ZERO), sigma_r / sigma_t, Rgb::ZERO);
        Some(Step {
            scatter: true,
            weight: m.sigma_s * share / (c.sigma_maj * wr * p_rest),
            medium: Some(m),
            phase,
            volume,
        })
    } else {
        Some(Step {
            scatter: false,
            weight: sigma_n / (c.sigma_maj * wn * p_rest),
            medium: Some(m),
            phase,
            volume,
        })
    }
}

/// Transmittance estimates below this play Russian roulette (survivors
/// are scaled back up to it), so that a shadow ray deep in a dense medium
/// stops after a few lookups instead of running to its end.
pub const TRANSMITTANCE_RR: f32 = 0.1;

/// Transmittance along `ray` over `[0, t_max)` by residual ratio
/// tracking (Novák, Selle & Jarosz 2014, §4): on each stretch of constant
/// bounds the control medium σc (the minorant) attenuates analytically by
/// exp(−σc·len), and tentative collisions at the residual rate σ̄ − σc each
/// multiply by `1 − (sigma_t − σc)/(σ̄ − σc)` (per RGB channel). Without a
/// minorant it is plain ratio tracking. Unbiased; Russian roulette when the
/// estimate falls below 0.1.
pub fn transmittance(media: &Media, ray: &Ray, t_max: f32, rng: &mut Rng) -> Rgb {
    ratio_walk(media, ray, t_max, rng, false).0
}

/// Transmittance along `ray` over `[0, t_max)` and the emitted radiance
/// that reaches its origin, ∫ T(t)·σa·Le(t) dt, in one walk.
///
/// The transmittance is [`transmittance`]'s estimator. The emission is a
/// ratio-tracking (next-flight) estimate: tentative collisions sampled at
/// the rate λ (the majorant, raised to the media's emission rate where
/// something may emit) each add T̂(t)·σa·Le(t)/λ with T̂ the running
/// transmittance estimate, which is the Monte Carlo estimate of the
/// integral with points at density λ (ratio tracking, Novák, Selle &
/// Jarosz 2014, applied to the emission integral). A path's own
/// collisions estimate the same integral but stop at its first real
/// collision, so the fire behind a wisp of smoke is seen or not per sample;
/// here every sample sees all of it, attenuated: on Blender's smoke + fire
/// frame the emission was nearly all of the path tracer's variance.
/// Segments where nothing may emit keep [`transmittance`]'s residual
/// control; emissive ones use plain ratio tracking, so that T̂ is known at
/// each collision.
pub fn transmittance_emission(media: &Media, ray: &Ray, t_max: f32, rng: &mut Rng) -> (Rgb, Rgb) {
    ratio_walk(media, ray, t_max, rng, true)
}

/// The walk of [`transmittance`] (`emission` false: every segment keeps
/// the residual control) and of [`transmittance_emission`] (emissive
/// segments also sum the emission, without a control).
#[inline(always)]
fn ratio_walk(media: &Media, ray: &Ray, t_max: f32, rng: &mut Rng, emission: bool) -> (Rgb, Rgb) {
    let mut walk = RatioWalk::new(media, ray, emission);
    media.for_each_segment_at(ray.o, ray.d, 0.0, t_max, ray.time, |seg| {
        walk.segment(&seg, seg.t0, rng)
    });
    (walk.tr, walk.emitted)
}

/// The state of a ratio-tracking walk ([`ratio_walk`]), which
/// [`sample_t_maj_camera`] also runs from wherever its flight ends.
struct RatioWalk<'a> {
    media: &'a Media,
    ray: Ray,
    /// Whether emissive segments sum the emission.
    emission: bool,
    /// The transmittance estimate so far.
    tr: Rgb,
    /// The emission that reaches the ray's origin so far.
    emitted: Rgb,
    budget: u32,
}

impl<'a> RatioWalk<'a> {
    fn new(media: &'a Media, ray: &Ray, emission: bool) -> Self {
        Self {
            media,
            ray: *ray,
            emission,
            tr: Rgb::ONE,
            emitted: Rgb::ZERO,
            budget: MAX_TENTATIVE,
        }
    }

    /// Whether `seg` is walked without a control, summing emission.
    #[inline(always)]
    fn emissive(&self, seg: &Segment) -> bool {
        self.emission && seg.emission > 0.0
    }

    /// The rate of tentative collisions in `seg` when it is walked without
    /// a control (emission needs every collision's optics).
    #[inline(always)]
    fn plain_rate(&self, seg: &Segment) -> f32 {
        if self.emissive(seg) {
            seg.max_density.max(self.media.emission_rate())
        } else {
            seg.max_density
        }
    }

    /// The control σc the walk takes analytically in `seg`: the minorant,
    /// valid for transmittance whatever the albedo or emission (only
    /// extinction matters here); none where it sums emission, which needs
    /// every collision's optics.
    #[inline(always)]
    fn control(&self, seg: &Segment) -> f32 {
        if self.emissive(seg) {
            0.0
        } else {
            seg.min_density.min(seg.max_density)
        }
    }

    /// One tentative collision at the residual rate `rate` with optics `m`
    /// and control `sigma_c` (0 where emissive): false when the walk ends
    /// (Russian roulette, or out of tentative collisions: opaque).
    #[inline(always)]
    fn collision(
        &mut self,
        m: &MediumPoint,
        sigma_c: f32,
        rate: f32,
        emissive: bool,
        rng: &mut Rng,
    ) -> bool {
        // Out of tentative collisions (see MAX_TENTATIVE): opaque.
        self.budget -= 1;
        if self.budget == 0 {
            self.tr = Rgb::ZERO;
            return false;
        }
        if emissive {
            self.emitted += self.tr * m.emission / rate;
        }
        let ratio = Rgb::ONE - (m.sigma_t() - Rgb::splat(sigma_c)) / rate;
        self.tr *= ratio.clamp(Rgb::ZERO, Rgb::ONE);
        roulette(&mut self.tr, TRANSMITTANCE_RR, rng)
    }

    /// Walks `seg` from `t0` on (the exponential's memorylessness lets a
    /// walk start anywhere): false when the walk ends.
    #[inline(always)]
    fn segment(&mut self, seg: &Segment, t0: f32, rng: &mut Rng) -> bool {
        let Ray { o, d, time } = self.ray;
        let emissive = self.emissive(seg);
        let sigma_c = self.control(seg);
        let rate = self.plain_rate(seg) - sigma_c;
        if sigma_c > 0.0 {
            self.tr *= (-sigma_c * (seg.t1 - t0)).exp();
            if !roulette(&mut self.tr, TRANSMITTANCE_RR, rng) {
                return false;
            }
        }
        if rate <= 0.0 {
            return true;
        }
        let mut t = t0;
        loop {
            t -= (1.0 - rng.next_f32()).ln() / rate;
            if t >= seg.t1 {
                return true;
            }
            count_tentative();
            let m = self.media.eval(o + d * t, time);
            if !self.collision(&m, sigma_c, rate, emissive, rng) {
                return false;
            }
        }
    }
}

/// [`sample_t_maj`] along a camera ray from its origin over `[0, t_max)`
/// (up to the surface it meets), together with the camera ray's own walk
/// over that whole stretch ([`transmittance`], or
/// [`transmittance_emission`] where the media glow), sharing their
/// lookups: returns what `sample_t_maj` returns, the transmittance (the
/// film's alpha) and the emission that reaches the origin.
///
/// Until the flight's first real collision one set of tentative
/// collisions serves both. Where the media may emit, the two sample at
/// the same rate (the majorant raised to the emission rate) and need the
/// same optics: each collision adds its emission and ratio to the walk and
/// is then decided for the flight. Where nothing emits the flight samples
/// at the majorant σ̄ and the walk keeps its residual control σc: it takes
/// each of the flight's collisions with probability (σ̄ − σc)/σ̄ (a
/// Poisson process at the residual rate), deciding by the number that
/// decides the flight's collision where the media have a control (whose
/// collisions, taken without a lookup, are then exactly the ones the walk
/// leaves out), and attenuates the stretch walked by exp(−σc·len). From
/// where the flight ends the walk goes on alone. Its collisions and their
/// numbers are then a marked Poisson process of the walk's rates over the
/// whole ray, the flight's end being a stopping time (the strong Markov
/// property), so both estimates keep their expectations; they are only no
/// longer independent. A camera ray in thin media often leaves them
/// before it scatters, so a separate walk was mostly the flight's lookups
/// over again: on Blender's smoke + fire frame it was 43 % of the path
/// tracer's time, on the bench's thin clouds 13-21 % (docs/performance.md,
/// "The camera ray's emission").
pub fn sample_t_maj_camera(
    media: &Media,
    ray: &Ray,
    t_max: f32,
    rng: &mut Rng,
    mut f: impl FnMut(&Collision, &mut Rng) -> bool,
) -> (bool, Rgb, Rgb) {
    let Ray { o, d, time } = *ray;
    let mut walk = RatioWalk::new(media, ray, media.is_emissive());
    let control = media.control_albedo().is_some();
    let (mut flying, mut walking) = (true, true);
    let mut reached_end = true;
    let mut budget = MAX_TENTATIVE;
    media.for_each_segment_at(o, d, 0.0, t_max, time, |seg| {
        let mut shared_end = seg.t0;
        if flying {
            let rate = walk.plain_rate(&seg);
            let emissive = walk.emissive(&seg);
            // The walk's control, and the flight's (the same, where the
            // media have one: they never emit).
            let sigma_c = walk.control(&seg);
            let flight_c = if control { sigma_c } else { 0.0 };
            shared_end = seg.t1;
            let mut t = seg.t0;
            loop {
                // (A rate of 0: nothing for either here.)
                if rate <= 0.0 {
                    break;
                }
                t -= (1.0 - rng.next_f32()).ln() / rate;
                if t >= seg.t1 {
                    break;
                }
                // Out of tentative collisions: the flight ends as in
                // `sample_t_maj`, and the walk is opaque as in `ratio_walk`.
                budget -= 1;
                if budget == 0 {
                    reached_end = false;
                    walk.tr = Rgb::ZERO;
                    return false;
                }
                count_tentative();
                let p = o + d * t;
                let u = rng.next_f32();
                // A collision of the flight's control needs no lookup, and
                // is one the walk leaves out (decided as `collide` decides).
                let of_control = flight_c > 0.0 && u < flight_c / rate;
                let looked_up = (!of_control).then(|| media.eval_scatter(p, time, rng.next_f32()));
                if let Some((m, _)) = &looked_up {
                    let kept = control || sigma_c <= 0.0 || rng.next_f32() * rate >= sigma_c;
                    if walking && kept {
                        walking = walk.collision(m, sigma_c, rate - sigma_c, emissive, rng);
                    }
                }
                let c = Collision {
                    t,
                    p,
                    time,
                    sigma_maj: rate,
                    sigma_c: flight_c,
                    media,
                    looked_up,
                    u: Some(u),
                };
                if !f(&c, rng) {
                    flying = false;
                    reached_end = false;
                    shared_end = t;
                    break;
                }
            }
            if walking && sigma_c > 0.0 {
                walk.tr *= (-sigma_c * (shared_end - seg.t0)).exp();
                walking = roulette(&mut walk.tr, TRANSMITTANCE_RR, rng);
            }
        }
        if !walking {
            return flying;
        }
        // The flight has ended (here or before): the walk alone from there.
        flying || walk.segment(&seg, shared_end, rng)
    });
    (reached_end, walk.tr, walk.emitted)
}

/// Optical depth ∫σt dt over `[t0, t1]` of `ray` by the midpoint rule
/// with `steps` equal steps, the sample points shifted by `jitter` ∈ [0, 1)
/// of a step (stratified: unbiased in expectation over the jitter).
pub fn optical_depth(media: &Media, ray: &Ray, t0: f32, t1: f32, steps: u32, jitter: f32) -> Rgb {
    let steps = steps.max(1);
    let dt = (t1 - t0) / steps as f32;
    let mut tau = Rgb::ZERO;
    for i in 0..steps {
        let t = t0 + (i as f32 + jitter) * dt;
        tau += media.eval(ray.at(t), ray.time).sigma_t();
    }
    tau * dt
}
