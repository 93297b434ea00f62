//! Draine's phase function, and Rayleigh's, its special case.
//!
//! Draine 2003, "Scattering by interstellar dust grains. I. Optical and
//! ultraviolet" (ApJ 598, doi:10.1086/379118), eq. 4: with μ the cosine
//! between the old and new directions of travel,
//!
//! p(μ) = (1 − g²)(1 + αμ²) / (4π (1 + α(1 + 2g²)/3) (1 + g² − 2gμ)^{3/2}),
//!
//! Henyey–Greenstein times (1 + αμ²), normalised (HG's ⟨μ²⟩ is
//! (1 + 2g²)/3). α = 0 is HG, g = 0 and α = 1 Rayleigh, α = 1
//! Cornette–Shanks. g > 0 scatters forward, as HG's g. Cycles 5.0
//! (`kernel/closure/volume_util.h`, `phase_draine`; set up in
//! `kernel/closure/volume_draine.h`) evaluates exactly this, clamps |g| to
//! 0.999, and takes |g| < 10⁻³ with α > 0.999 as Rayleigh and α < 10⁻³ as
//! HG; [`Draine::new`] does the same.
//!
//! Sampling inverts the CDF. Cycles uses the closed-form root of a quartic
//! from Jendersie & d'Eon 2023's supplemental code, and for |g| < 10⁻² the
//! g = 0 root (so there it samples a slightly different lobe than it
//! evaluates). We instead solve F(μ) = u exactly by Newton's method in the
//! variable v = F_HG(μ), HG's own CDF: there the density of Draine's CDF
//! is (1 + αμ²)/Z, between 1/Z and (1 + α)/Z, so the iteration is well
//! conditioned however peaked the lobe, and HG's closed-form inverse gives
//! μ, 1 ± μ and (1 + g² − 2gμ)^{1/2} from v without cancellation.
//!
//! Rayleigh 1871: p(μ) = 3(1 + μ²)/(16π), sampled by Cardano's root of
//! its cubic CDF (Frisvad 2011, "Importance sampling the Rayleigh phase
//! function", JOSA A 28, doi:10.1364/JOSAA.28.002436, which Cycles cites).

use super::Deflection;
use std::f64::consts::PI;

/// Cycles' clamp on |g| (`volume_draine_setup`).
const G_MAX: f32 = 1.0 - 1e-3;
/// Our bound on α (Blender's node offers 0 to 500; Cycles does not clamp).
const ALPHA_MAX: f32 = 1e6;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Draine {
    g: f32,
    alpha: f32,
}

impl Draine {
    /// Draine(g, α) with Cycles' clamps and special cases: |g| ≤ 0.999;
    /// |g| < 10⁻³ with α > 0.999 is Rayleigh (g = 0, α = 1: Cycles'
    /// `phase_draine` switches to `phase_rayleigh` there, also for α far
    /// above 1); α < 10⁻³ is HG (α = 0). α < 0 (below Blender's socket
    /// range; α < −1 would make the density negative) is taken as 0.
    pub fn new(g: f32, alpha: f32) -> Self {
        let g = if g.is_nan() {
            0.0
        } else {
            g.clamp(-G_MAX, G_MAX)
        };
        let alpha = if alpha.is_nan() {
            0.0
        } else {
            alpha.clamp(0.0, ALPHA_MAX)
        };
        if g.abs() < 1e-3 && alpha > 0.999 {
            Self { g: 0.0, alpha: 1.0 }
        } else if alpha < 1e-3 {
            Self { g, alpha: 0.0 }
        } else {
            Self { g, alpha }
        }
    }

    /// Draine(g, α) as given (|g| < 1, α ≥ 0), without Cycles' special
    /// cases: for exact results such as a blurred Rayleigh lobe.
    pub(crate) fn exact(g: f32, alpha: f32) -> Self {
        Self { g, alpha }
    }

    pub fn g(&self) -> f32 {
        self.g
    }
    pub fn alpha(&self) -> f32 {
        self.alpha
    }

    fn norm(&self) -> f64 {
        let g = self.g as f64;
        1.0 + self.alpha as f64 * (1.0 + 2.0 * g * g) / 3.0
    }

    /// Density per steradian at sin²(θ/2) = `s` (θ from the direction of
    /// travel). 1 + g² − 2gμ is written (1 − g)² + 4gs, exact near the
    /// forward peak.
    #[inline]
    pub fn density(&self, s: f64) -> f64 {
        let s = s.clamp(0.0, 1.0);
        let (g, a) = (self.g as f64, self.alpha as f64);
        let mu = 1.0 - 2.0 * s;
        let x = (1.0 - g) * (1.0 - g) + 4.0 * g * s;
        (1.0 - g * g) * (1.0 + a * mu * mu) / (4.0 * PI * self.norm() * x * x.sqrt())
    }

    /// μ, 1 + μ, 1 − μ and (1 + g² − 2gμ)^{1/2} where HG's CDF (from
    /// μ = −1) is `v`: the inverse of v = (1 − g²)/(2g)·(1/y − 1/(1 + g)),
    /// y = (1 + g² − 2gμ)^{1/2}, with the factors of g cancelled by hand.
    fn hg_inverse(g: f64, v: f64) -> (f64, f64, f64, f64) {
        let q = 1.0 - g + 2.0 * g * v;
        let q2 = q * q;
        let mu = (2.0 * v * (1.0 + g * g) * (1.0 - g + g * v) - (1.0 - g) * (1.0 - g)) / q2;
        let one_plus = 2.0 * v * (1.0 + g) * (1.0 + g) * (1.0 - g + g * v) / q2;
        let one_minus = 2.0 * (1.0 - v) * (1.0 - g) * (1.0 - g) * (1.0 + g * v) / q2;
        (mu, one_plus, one_minus, (1.0 - g * g) / q)
    }

    /// ∫₋₁^μ 2π·HG(t)·t² dt, from the antiderivative with its 1/g³
    /// cancelled analytically (Y = 1 + g, y as in [`Self::hg_inverse`]):
    /// (1 − g)(1 + μ)/(3y(Y + y)) · [y(1 + μ)²(3y + Y)/(Y + y)²
    /// − 6μy(1 + μ)/(Y + y) + 3μ²]. At g = 0 it is (1 + μ³)/6.
    fn hg_second_moment_cdf(g: f64, mu: f64, one_plus: f64, y: f64) -> f64 {
        let big = 1.0 + g;
        let sum = big + y;
        let bracket = y * one_plus * one_plus * (3.0 * y + big) / (sum * sum)
            - 6.0 * mu * y * one_plus / sum
            + 3.0 * mu * mu;
        (1.0 - g) * one_plus / (3.0 * y * sum) * bracket
    }

    /// Draine's CDF (from μ = −1) at the μ whose HG CDF is `v`, and μ,
    /// 1 + μ, 1 − μ there.
    fn cdf_at(&self, v: f64) -> (f64, f64, f64, f64) {
        let g = self.g as f64;
        let (mu, one_plus, one_minus, y) = Self::hg_inverse(g, v);
        let f2 = Self::hg_second_moment_cdf(g, mu, one_plus, y);
        (
            (v + self.alpha as f64 * f2) / self.norm(),
            mu,
            one_plus,
            one_minus,
        )
    }

    /// The scattering angle whose CDF is `u`.
    pub fn sample(&self, u: f64) -> Deflection {
        let (a, z) = (self.alpha as f64, self.norm());
        let u = u.clamp(0.0, 1.0);
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        let mut v = u;
        let mut at = self.cdf_at(v);
        for _ in 0..100 {
            let (f, mu, ..) = at;
            let r = f - u;
            if r == 0.0 {
                break;
            }
            if r < 0.0 {
                lo = v;
            } else {
                hi = v;
            }
            // dF/dv = (1 + αμ²)/Z.
            let mut next = v - r * z / (1.0 + a * mu * mu);
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            let done = (next - v).abs() <= 1e-15 || hi - lo <= 1e-15;
            v = next;
            at = self.cdf_at(v);
            if done {
                break;
            }
        }
        let (_, mu, one_plus, one_minus) = at;
        Deflection {
            cos: mu.clamp(-1.0, 1.0),
            sin: (one_plus * one_minus).max(0.0).sqrt(),
        }
    }

    /// ⟨μ⟩ = g(1 + α(3 + 2g²)/5) / (1 + α(1 + 2g²)/3), from HG's moments
    /// ⟨μ⟩ = g and ⟨μ³⟩ = g(3 + 2g²)/5 (μ³ = (2P₃ + 3P₁)/5, and HG's
    /// ⟨P_l⟩ = g^l).
    pub fn mean_cosine(&self) -> f64 {
        let (g, a) = (self.g as f64, self.alpha as f64);
        g * (1.0 + a * (3.0 + 2.0 * g * g) / 5.0) / self.norm()
    }
}

/// Henyey–Greenstein's density at sin²(θ/2) = `s`, in f64 and with
/// 1 + g² − 2gμ as (1 − g)² + 4gs: exact at the peak for g near 1, where
/// the f32 [`super::henyey_greenstein`] of cos loses two digits (Mie's HG
/// lobe has g up to 0.998).
#[inline]
pub fn hg_density(g: f64, s: f64) -> f64 {
    let s = s.clamp(0.0, 1.0);
    let x = (1.0 - g) * (1.0 - g) + 4.0 * g * s;
    (1.0 - g * g) / (4.0 * PI * x * x.sqrt())
}

/// The scattering angle where HG's CDF is `u`, by its closed-form inverse
/// in f64 (see [`Draine::hg_inverse`]).
pub fn hg_sample(g: f64, u: f64) -> Deflection {
    let (mu, one_plus, one_minus, _) = Draine::hg_inverse(g, u.clamp(0.0, 1.0));
    Deflection {
        cos: mu.clamp(-1.0, 1.0),
        sin: (one_plus * one_minus).max(0.0).sqrt(),
    }
}

/// Rayleigh's density per steradian at sin²(θ/2) = `s`.
#[inline]
pub fn rayleigh_density(s: f64) -> f64 {
    let mu = 1.0 - 2.0 * s.clamp(0.0, 1.0);
    3.0 / (16.0 * PI) * (1.0 + mu * mu)
}

/// The scattering angle where Rayleigh's CDF, (μ³ + 3μ + 4)/8, is `u`:
/// μ³ + 3μ − 2b = 0 for b = 4u − 2, whose one real root is w − 1/w with
/// w = ∛(b + √(b² + 1)) (Cardano); taken for |b| and given b's sign, so
/// the sum under the root never cancels.
pub fn rayleigh_sample(u: f64) -> Deflection {
    let b = 4.0 * u.clamp(0.0, 1.0) - 2.0;
    let w = (b.abs() + (b * b + 1.0).sqrt()).cbrt();
    let mu = ((w - 1.0 / w) * b.signum()).clamp(-1.0, 1.0);
    Deflection {
        cos: mu,
        sin: ((1.0 - mu) * (1.0 + mu)).max(0.0).sqrt(),
    }
}
