//! Phase functions: isotropic, Henyey–Greenstein, Schlick, weighted
//! mixtures of Henyey–Greenstein lobes, and the ones Cycles 5's Volume
//! Scatter node adds: Fournier–Forand, Draine, Rayleigh and Mie (an HG and
//! a Draine lobe fitted to the droplet size). Each evaluates, samples
//! exactly, and gives its density (equal to its value: all are sampled by
//! inverting their CDF).
//!
//! # Direction convention (the one place it is written)
//! Both `wo` and `wi` are unit vectors pointing **away** from the scattering
//! point: `wo` towards where the light goes (for a camera path: back towards
//! the camera, minus the camera ray's direction), `wi` towards where it comes
//! from (the light). A phase function depends only on cos = dot(wo, wi).
//! Light travelling along `-wi` goes on along `wo`, so forward scattering
//! (g > 0) means `wo ≈ -wi`, cos ≈ −1: the convention of pbrt-v4 (§11.3)
//! and Mitsuba 3. A photon travelling along `d` and scattered into `d'` has
//! `wi = -d`, `wo = d'`; [`PhaseFunction::sample_travel`] does that mapping.
//!
//! The mean cosine of the scattering angle (between the old and new
//! directions of travel) is `g` for Henyey–Greenstein.
//!
//! Cycles writes its phase functions in μ = dot(direction of travel in,
//! direction of travel out) (`kernel/closure/volume_*.h`: `cos_theta =
//! dot(-sd->wi, wo)`), so forward is μ = +1 there and cos = −μ here; g > 0
//! scatters forward in both. The functions added for Cycles 5 are written
//! in θ, the angle between the directions of travel, through
//! s = sin²(θ/2) = |wo + wi|²/4, which stays exact near the forward peak
//! where 1 + dot(wo, wi) would round to 0.

mod draine;
mod fournier_forand;
mod mie;

pub use draine::Draine;
pub use fournier_forand::FournierForand;
pub use mie::{mie_fit, MieFit};

use crate::sampling::{coordinate_system, spherical_direction};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

const INV_4PI: f32 = 1.0 / (4.0 * PI);

/// Largest |g| (and |k|) used: at ±1 the functions become Dirac deltas, and
/// in f32 their normalisation breaks down well before.
pub const MAX_G: f32 = 0.999;

/// Henyey & Greenstein 1941, "Diffuse radiation in the galaxy", with
/// cos = dot(wo, wi) (so g > 0 peaks at cos = −1, forward).
#[inline]
pub fn henyey_greenstein(cos: f32, g: f32) -> f32 {
    let denom = 1.0 + g * g + 2.0 * g * cos;
    INV_4PI * (1.0 - g * g) / (denom * denom.max(0.0).sqrt()).max(f32::MIN_POSITIVE)
}

/// Schlick's approximation (Blasi, Le Saëc & Schlick 1993):
/// (1 − k²) / (4π (1 + k cos)²), cos = dot(wo, wi).
#[inline]
pub fn schlick(cos: f32, k: f32) -> f32 {
    let d = 1.0 + k * cos;
    INV_4PI * (1.0 - k * k) / (d * d).max(f32::MIN_POSITIVE)
}

/// k of the Schlick function whose shape matches HG(g): k = 1.55 g − 0.55 g³
/// (Pharr, Jakob & Humphreys, pbrt 3rd ed. §15.2.3 note; Blasi et al. 1993
/// fit k ≈ 1.5 g − 0.5 g³, the 1.55/0.55 refinement is the common one).
pub fn schlick_k_from_g(g: f32) -> f32 {
    (1.55 * g - 0.55 * g * g * g).clamp(-MAX_G, MAX_G)
}

/// Up to four HG lobes with weights summing to one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HgMix {
    g: [f32; 4],
    w: [f32; 4],
    n: usize,
}

impl HgMix {
    /// `lobes` as (g, weight); weights ≥ 0 with a positive sum, normalised
    /// here.
    pub fn new(lobes: &[(f32, f32)]) -> Result<Self, String> {
        if lobes.is_empty() || lobes.len() > 4 {
            return Err(format!("an HG mix needs 1 to 4 lobes, not {}", lobes.len()));
        }
        let sum: f32 = lobes.iter().map(|l| l.1).sum();
        if lobes
            .iter()
            .any(|l| l.1.is_nan() || l.1 < 0.0 || !l.0.is_finite() || l.0.abs() > 1.0)
            || sum.is_nan()
            || sum <= 0.0
        {
            return Err("HG mix lobes need |g| ≤ 1 and weights ≥ 0 with a positive sum".into());
        }
        let mut m = HgMix {
            g: [0.0; 4],
            w: [0.0; 4],
            n: lobes.len(),
        };
        for (i, (g, w)) in lobes.iter().enumerate() {
            m.g[i] = g.clamp(-MAX_G, MAX_G);
            m.w[i] = w / sum;
        }
        Ok(m)
    }
    pub fn lobes(&self) -> impl Iterator<Item = (f32, f32)> + '_ {
        (0..self.n).map(|i| (self.g[i], self.w[i]))
    }
}

/// Cycles' Mie lobes (see [`PhaseFunction::mie`]): (1 − w_D)·HG(g_HG) +
/// w_D·Draine; blurring (see [`PhaseFunction::blurred`]) changes g_HG. The
/// HG lobe is evaluated and sampled in f64 through sin²(θ/2), as the
/// Draine one is: at Mie's g_HG of up to 0.998 the f32 HG of cos θ is off
/// by a percent at the peak.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HgDraine {
    pub g_hg: f32,
    pub draine: Draine,
    /// The Draine lobe's weight, in [0, 1].
    pub w_d: f32,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PhaseFunction {
    Isotropic,
    HenyeyGreenstein {
        g: f32,
    },
    Schlick {
        k: f32,
    },
    HgMix(HgMix),
    /// Fournier–Forand, from Backscatter and IOR as Cycles' node has them.
    FournierForand(FournierForand),
    /// Draine (2003), HG times (1 + αμ²).
    Draine(Draine),
    /// Rayleigh: 3(1 + cos²θ)/(16π).
    Rayleigh,
    /// Cycles' Mie approximation: an HG and a Draine lobe.
    HgDraine(HgDraine),
}

/// A scattering angle θ between the old and new directions of travel, as
/// cos θ (Cycles' μ: 1 is straight on) and sin θ, each computed without
/// cancellation so that small deflections keep their precision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Deflection {
    pub cos: f64,
    pub sin: f64,
}

impl Deflection {
    /// From s = sin²(θ/2).
    fn from_half_angle(s: f64) -> Self {
        let s = s.clamp(0.0, 1.0);
        Self {
            cos: 1.0 - 2.0 * s,
            sin: 2.0 * (s * (1.0 - s)).sqrt(),
        }
    }
}

/// s = sin²(θ/2) for θ the scattering angle between the direction of
/// travel −`wi` and `wo`: (1 − cos θ)/2 = (1 + dot(wo, wi))/2 =
/// |wo + wi|²/4 for unit vectors, the last exact near θ = 0.
#[inline]
fn half_angle_sin2(wo: Vec3, wi: Vec3) -> f64 {
    ((wo + wi).length_squared() as f64 * 0.25).min(1.0)
}

/// A sampled direction.
#[derive(Debug, Clone, Copy)]
pub struct PhaseSample {
    pub wi: Vec3,
    /// Value of the phase function.
    pub p: f32,
    /// Solid-angle density (equal to `p`).
    pub pdf: f32,
}

/// cos θ between `wo` and the sampled `wi` for an HG lobe, by inverting its
/// CDF (pbrt-v4 `SampleHenyeyGreenstein`).
#[inline]
fn sample_hg_cos(g: f32, u: f32) -> f32 {
    if g.abs() < 1e-3 {
        return 1.0 - 2.0 * u;
    }
    let s = (1.0 - g * g) / (1.0 + g - 2.0 * g * u);
    (-1.0 / (2.0 * g) * (1.0 + g * g - s * s)).clamp(-1.0, 1.0)
}

#[inline]
fn sample_schlick_cos(k: f32, u: f32) -> f32 {
    if k.abs() < 1e-4 {
        return 2.0 * u - 1.0;
    }
    // Inverse of F(c) = (1 − k²)/(2k) [1/(1 − k) − 1/(1 + k c)].
    let s = (1.0 - k * k) / (1.0 + k - 2.0 * k * u);
    ((s - 1.0) / k).clamp(-1.0, 1.0)
}

impl PhaseFunction {
    pub fn hg(g: f32) -> Self {
        PhaseFunction::HenyeyGreenstein {
            g: g.clamp(-MAX_G, MAX_G),
        }
    }
    pub fn schlick_from_g(g: f32) -> Self {
        PhaseFunction::Schlick {
            k: schlick_k_from_g(g),
        }
    }
    pub fn hg_mix(lobes: &[(f32, f32)]) -> Result<Self, String> {
        HgMix::new(lobes).map(PhaseFunction::HgMix)
    }
    /// Cycles' Fournier–Forand from the Volume Scatter node's Backscatter
    /// (fraction of light scattered by more than 90°) and IOR, with Cycles'
    /// clamps ([`FournierForand::new`]).
    pub fn fournier_forand(backscatter: f32, ior: f32) -> Self {
        PhaseFunction::FournierForand(FournierForand::new(backscatter, ior))
    }
    /// Cycles' Draine from the node's Anisotropy `g` and Alpha, with its
    /// clamps and special cases ([`Draine::new`]).
    pub fn draine(g: f32, alpha: f32) -> Self {
        PhaseFunction::Draine(Draine::new(g, alpha))
    }
    /// Cycles' Mie approximation for water droplets of `diameter` µm
    /// ([`mie_fit`]): the HG lobe clamped to |g| ≤ [`MAX_G`] and the Draine
    /// lobe set up as Cycles sets up each.
    pub fn mie(diameter: f32) -> Self {
        let fit = mie_fit(diameter);
        PhaseFunction::HgDraine(HgDraine {
            g_hg: fit.g_hg.clamp(-MAX_G, MAX_G),
            draine: Draine::new(fit.g_d, fit.alpha),
            w_d: fit.w_d.clamp(0.0, 1.0),
        })
    }

    /// p(wo, wi) in sr⁻¹.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        let cos = wo.dot(wi);
        match *self {
            PhaseFunction::Isotropic => INV_4PI,
            PhaseFunction::HenyeyGreenstein { g } => henyey_greenstein(cos, g),
            PhaseFunction::Schlick { k } => schlick(cos, k),
            PhaseFunction::HgMix(m) => m.lobes().map(|(g, w)| w * henyey_greenstein(cos, g)).sum(),
            PhaseFunction::FournierForand(f) => f.density(half_angle_sin2(wo, wi)) as f32,
            PhaseFunction::Draine(d) => d.density(half_angle_sin2(wo, wi)) as f32,
            PhaseFunction::Rayleigh => draine::rayleigh_density(half_angle_sin2(wo, wi)) as f32,
            PhaseFunction::HgDraine(m) => {
                let s = half_angle_sin2(wo, wi);
                let w = m.w_d as f64;
                ((1.0 - w) * draine::hg_density(m.g_hg as f64, s) + w * m.draine.density(s)) as f32
            }
        }
    }

    /// Density of [`sample`](Self::sample) for `wi`: equal to `eval`.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval(wo, wi)
    }

    /// Samples `wi` given `wo` from two uniform numbers.
    #[inline]
    pub fn sample(&self, wo: Vec3, u: Vec2) -> Option<PhaseSample> {
        let phi = 2.0 * PI * u.y;
        // Sampled in cos = dot(wo, wi), sin from it, for the functions that
        // had it so; the others give their deflection (Cycles' μ = −cos).
        let with_sin = |cos: f32| (cos, (1.0 - cos * cos).max(0.0).sqrt());
        let ours = |d: Deflection| (-d.cos as f32, d.sin as f32);
        let (cos, sin) = match *self {
            PhaseFunction::Isotropic => with_sin(1.0 - 2.0 * u.x),
            PhaseFunction::HenyeyGreenstein { g } => with_sin(sample_hg_cos(g, u.x)),
            PhaseFunction::Schlick { k } => with_sin(sample_schlick_cos(k, u.x)),
            PhaseFunction::HgMix(m) => {
                // Choose the lobe with u.x, then reuse the remainder.
                let mut x = u.x;
                let mut g = m.g[m.n - 1];
                for i in 0..m.n {
                    if x < m.w[i] || i == m.n - 1 {
                        g = m.g[i];
                        x = if m.w[i] > 0.0 {
                            (x / m.w[i]).min(1.0 - f32::EPSILON)
                        } else {
                            0.5
                        };
                        break;
                    }
                    x -= m.w[i];
                }
                with_sin(sample_hg_cos(g, x))
            }
            PhaseFunction::FournierForand(f) => {
                ours(Deflection::from_half_angle(f.sample_s(u.x as f64)))
            }
            PhaseFunction::Draine(d) => ours(d.sample(u.x as f64)),
            PhaseFunction::Rayleigh => ours(draine::rayleigh_sample(u.x as f64)),
            PhaseFunction::HgDraine(m) => {
                // The lobe by u.x (Draine below w_D), the remainder reused.
                let x = u.x as f64;
                let w = m.w_d as f64;
                if x < w {
                    ours(m.draine.sample(x / w))
                } else {
                    ours(draine::hg_sample(m.g_hg as f64, (x - w) / (1.0 - w)))
                }
            }
        };
        let (t, b) = coordinate_system(wo);
        let wi = spherical_direction(sin, cos, phi, (t, b, wo));
        let p = self.eval(wo, wi);
        (p > 0.0).then_some(PhaseSample { wi, p, pdf: p })
    }

    /// For a particle travelling along `d`: samples its new direction of
    /// travel, with the phase value (= density).
    #[inline]
    pub fn sample_travel(&self, d: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        // wi = -d and the new direction is wo. These functions depend on
        // dot(wo, wi) only, so sampling wo given wi is sampling with the
        // roles swapped: the sample's `wi` is the new direction of travel.
        self.sample(-d, u).map(|s| (s.wi, s.p))
    }

    /// This phase function blurred over directions by a Henyey–Greenstein
    /// kernel of mean cosine `s` (1: unchanged, 0: isotropic): the
    /// convolution ∫ p(wo, w) K_s(w, wi) dw. By the Funk–Hecke theorem a
    /// zonal convolution multiplies the Legendre coefficients, and HG(g)'s
    /// are g^l (Henyey & Greenstein 1941), so HG(g) blurred by HG(s) is
    /// exactly HG(g·s), lobe by lobe for a mixture, and for the HG lobe of
    /// Cycles' Mie.
    ///
    /// Rayleigh's coefficients are 1 and 1/2 (at l = 0, 2), so blurred it
    /// is exactly 1 + (s²/2)·P₂ over 4π: Draine(0, α) with
    /// 2α/(3 + α) = s²/2, α = 3s²/(4 − s²).
    ///
    /// The others are returned unblurred, which is the conservative answer:
    /// the kernel only trades bias for variance, so leaving a lobe sharp
    /// keeps that lobe's estimate as it is without the kernel (unbiased in
    /// angle, and as noisy). Schlick's function, Fournier–Forand's and
    /// Draine's have no blurred closed form of their own kind (Draine's
    /// factor μ² couples each Legendre order to its neighbours, so its
    /// blur is no Draine), so a Draine lobe, also Mie's, stays sharp.
    ///
    /// The photon estimate uses it as an angular kernel over the photons'
    /// directions (`crate::integrator::photon::angular_kernel`).
    pub fn blurred(&self, s: f32) -> PhaseFunction {
        match *self {
            PhaseFunction::HenyeyGreenstein { g } => PhaseFunction::HenyeyGreenstein { g: g * s },
            PhaseFunction::HgMix(mut m) => {
                for g in &mut m.g[..m.n] {
                    *g *= s;
                }
                PhaseFunction::HgMix(m)
            }
            PhaseFunction::HgDraine(mut m) => {
                m.g_hg *= s;
                PhaseFunction::HgDraine(m)
            }
            PhaseFunction::Rayleigh if s != 1.0 => {
                PhaseFunction::Draine(Draine::exact(0.0, 3.0 * s * s / (4.0 - s * s)))
            }
            other => other,
        }
    }

    /// Mean cosine of the scattering angle (old vs new direction of travel).
    pub fn mean_cosine(&self) -> f32 {
        match *self {
            PhaseFunction::Isotropic => 0.0,
            PhaseFunction::HenyeyGreenstein { g } => g,
            PhaseFunction::Schlick { k } => {
                if k.abs() < 1e-3 {
                    2.0 * k / 3.0
                } else {
                    let k = k as f64;
                    (1.0 / k - (1.0 - k * k) / (2.0 * k * k) * ((1.0 + k) / (1.0 - k)).ln()) as f32
                }
            }
            PhaseFunction::HgMix(m) => m.lobes().map(|(g, w)| g * w).sum(),
            PhaseFunction::FournierForand(f) => f.mean_cosine() as f32,
            PhaseFunction::Draine(d) => d.mean_cosine() as f32,
            PhaseFunction::Rayleigh => 0.0,
            PhaseFunction::HgDraine(m) => {
                (1.0 - m.w_d) * m.g_hg + m.w_d * m.draine.mean_cosine() as f32
            }
        }
    }
}
