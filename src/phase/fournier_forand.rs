//! The Fournier–Forand phase function of Cycles' Volume Scatter node.
//!
//! Fournier & Forand 1994, "Analytic phase function for ocean water"
//! (Proc. SPIE 2258), in the form of Fournier & Jonasz 1999, "Computer-based
//! underwater imaging analysis" (Proc. SPIE 3761, doi:10.1117/12.366488),
//! which Cycles 5.0 cites: particles with a Junge size distribution of
//! slope μ_J and relative refractive index n scatter, at angle θ between
//! the old and new directions of travel, with s = sin²(θ/2),
//! δ = 4s / (3(n − 1)²), v = (3 − μ_J)/2 < 0,
//!
//! p(θ) = [v(1 − δ) − (1 − δᵛ) + (δ(1 − δᵛ) − v(1 − δ))/s] / (4π(1 − δ)²δᵛ)
//!        + (1 − δ₁₈₀ᵛ)/(16π(δ₁₈₀ − 1)δ₁₈₀ᵛ) · (3cos²θ − 1).
//!
//! Cycles (`kernel/closure/volume_util.h`: `phase_fournier_forand_coeffs`,
//! `phase_fournier_forand`, `phase_fournier_forand_newton`; set up in
//! `kernel/closure/volume_fournier_forand.h`) takes the node's Backscatter B
//! and IOR n, clamps B to at most 0.5 − 10⁻³ and n to at least 1 + 10⁻³,
//! and finds v from B through the backscatter fraction's closed form,
//! B = (1 − δ₉₀⁻ᵛ) / (2(1 − δ₉₀)), i.e. v = −ln(1 + 2B(δ₉₀ − 1)) / ln δ₉₀.
//! It samples θ by Newton's method on the CDF. We evaluate the same
//! function, in f64 and in forms without cancellation (below), and invert
//! the same CDF with a bracketed Newton iteration, so sampling is exact to
//! rounding.
//!
//! With c = −v ∈ (0, 1), k = δ₁₈₀ = 4 / (3(n − 1)²) and L = ln δ = ln(ks),
//! the probability of scattering by less than θ is
//!
//! F(s) = 1 − (1 − s)·R(L) + (c₃/2)·s(1 − s)(1 − 2s),
//! R(L) = (e^{cL} − 1)/(e^L − 1),  c₃ = R(ln k),
//!
//! (F(0) = 0, F(1) = 1) and p = F′(s)/(4π). R is a ratio of two `exp_m1`s,
//! exact also where δ crosses 1 (the 0/0 of the formula above, which
//! Cycles handles by a Taylor expansion). Near θ = 0, F ≈ (ks)^c: the
//! density has an integrable singularity in the forward direction, so
//! [`S_MIN`] bounds how close to it `eval` looks.

use std::f64::consts::PI;

/// The smallest sin²(θ/2) the density is evaluated at: directions closer
/// to straight on than that (θ < 2·10⁻¹⁸, below what f32 directions
/// resolve) get its value, which stays finite in f32 for every parameter.
pub const S_MIN: f64 = 1e-36;

/// Cycles' clamps (`volume_fournier_forand_setup`).
const B_MAX: f32 = 0.5 - 1e-3;
const IOR_MIN: f32 = 1.0 + 1e-3;
/// Below Cycles' range: at B = 0 the function is a Dirac delta forward
/// (v = 0), for which Cycles' formula gives 0 everywhere (its scattered
/// light is lost). We keep B ≥ 10⁻⁵, where the lobe is already that
/// delta for any renderer's purpose (at IOR 1.33, 99.96 % of the light is
/// deflected by less than 1°) and every value is finite.
const B_MIN: f32 = 1e-5;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FournierForand {
    /// Backscatter fraction B and relative IOR n as clamped.
    backscatter: f32,
    ior: f32,
    /// c = −v ∈ (0, 1).
    c: f64,
    /// ln k, k = δ at θ = π.
    ln_k: f64,
    /// Weight of the (3cos²θ − 1) term, Cycles' `coeffs.z`.
    c3: f64,
}

/// (e^{cL} − 1)/(e^L − 1), its limit c at L = 0.
#[inline]
fn ratio(c: f64, l: f64) -> f64 {
    if l == 0.0 {
        c
    } else {
        (c * l).exp_m1() / l.exp_m1()
    }
}

/// e^x − 1 − x, without the cancellation near 0.
#[inline]
fn expm1_minus_x(x: f64) -> f64 {
    if x.abs() < 0.5 {
        // x²/2! + x³/3! + … (18 terms: below 10⁻¹⁷ relative at |x| = 0.5).
        let mut term = x * x / 2.0;
        let mut sum = term;
        for n in 3..=20 {
            term *= x / n as f64;
            sum += term;
        }
        sum
    } else {
        x.exp_m1() - x
    }
}

/// dR/dL (≤ 0: R falls from 1 at L → −∞ towards 0).
#[inline]
fn ratio_derivative(c: f64, l: f64) -> f64 {
    if l.abs() < 1e-5 {
        // Taylor series of R about L = 0 (error O(L³)).
        let cm = c * (c - 1.0);
        cm / 2.0 + cm * (2.0 * c - 1.0) * l / 6.0 + cm * cm * l * l / 8.0
    } else if l.abs() < 0.5 {
        // [c·e^{cL}(e^L − 1) − (e^{cL} − 1)e^L] / (e^L − 1)², with its
        // O(L) terms cancelled by hand: c·φ(L) − φ(cL) + (c − 1)·A·B for
        // φ(x) = e^x − 1 − x, A = e^{cL} − 1, B = e^L − 1.
        let (a, b) = ((c * l).exp_m1(), l.exp_m1());
        (c * expm1_minus_x(l) - expm1_minus_x(c * l) + (c - 1.0) * a * b) / (b * b)
    } else {
        let (a, b) = ((c * l).exp_m1(), l.exp_m1());
        (c * (c * l).exp() * b - a * l.exp()) / (b * b)
    }
}

impl FournierForand {
    /// From Cycles' node inputs: Backscatter `b` (the fraction of light
    /// scattered by more than 90°) and the particles' relative IOR, clamped
    /// as Cycles clamps them (B to [10⁻⁵, 0.499], n ≥ 1.001; see [`B_MIN`]).
    pub fn new(backscatter: f32, ior: f32) -> Self {
        let b = if backscatter.is_nan() {
            B_MIN
        } else {
            backscatter.abs().clamp(B_MIN, B_MAX)
        };
        let n = if ior.is_nan() {
            IOR_MIN
        } else {
            ior.max(IOR_MIN)
        };
        let nm1 = n as f64 - 1.0;
        let k = 4.0 / (3.0 * nm1 * nm1);
        // v = −ln(1 + 2B(δ₉₀ − 1))/ln δ₉₀, written with ln_1p so that it
        // stays exact near δ₉₀ = 1 (n ≈ 1.8165), where it tends to −2B.
        let d90m1 = 0.5 * k - 1.0;
        let c = if d90m1 == 0.0 {
            2.0 * b as f64
        } else {
            (2.0 * b as f64 * d90m1).ln_1p() / d90m1.ln_1p()
        };
        let ln_k = k.ln();
        Self {
            backscatter: b,
            ior: n,
            c,
            ln_k,
            c3: ratio(c, ln_k),
        }
    }

    pub fn backscatter(&self) -> f32 {
        self.backscatter
    }
    pub fn ior(&self) -> f32 {
        self.ior
    }

    /// Density per steradian at sin²(θ/2) = `s` (θ from the direction of
    /// travel), for `s` in [0, 1].
    #[inline]
    pub fn density(&self, s: f64) -> f64 {
        let s = s.clamp(S_MIN, 1.0);
        let l = self.ln_k + s.ln();
        // dF/ds = R − (1 − s)·R′/s, two terms ≥ 0; then the (3cos²θ − 1)
        // term, written in s.
        let main = ratio(self.c, l) - (1.0 - s) * ratio_derivative(self.c, l) / s;
        (main + 0.5 * self.c3 * (1.0 - 6.0 * s + 6.0 * s * s)) / (4.0 * PI)
    }

    /// The probability of scattering by less than θ, for sin²(θ/2) = `s`.
    pub fn cdf(&self, s: f64) -> f64 {
        if s <= 0.0 {
            return 0.0;
        }
        let s = s.min(1.0);
        let c = self.c;
        let l = self.ln_k + s.ln();
        // 1 − (1 − s)·R = (e^L − e^{cL} + s(e^{cL} − 1))/(e^L − 1), with
        // e^L − e^{cL} = e^{cL}·(e^{(1−c)L} − 1): both terms of the sum
        // share the denominator's sign, so nothing cancels as F → 0.
        let f = if l == 0.0 {
            1.0 - c + s * c
        } else {
            ((c * l).exp() * ((1.0 - c) * l).exp_m1() + s * (c * l).exp_m1()) / l.exp_m1()
        };
        f + 0.5 * self.c3 * s * (1.0 - s) * (1.0 - 2.0 * s)
    }

    /// sin²(θ/2) with F = `u`: Newton's method on ln F over z = ln s,
    /// bracketed (z in [ln 10⁻³⁰⁰, 0], where F rises from about 0 to 1).
    /// Where F ≈ (ks)^c, ln F is linear in z and Newton converges at once.
    pub fn sample_s(&self, u: f64) -> f64 {
        const Z_MIN: f64 = -690.0;
        if u.is_nan() || u <= 0.0 {
            return 0.0;
        }
        if u >= 1.0 {
            return 1.0;
        }
        let target = u.ln();
        let h = |z: f64| self.cdf(z.exp()).ln() - target;
        if h(Z_MIN) >= 0.0 {
            // The rest of the lobe lies within 10⁻¹⁵⁰ rad of straight on.
            return 0.0;
        }
        let (mut lo, mut hi) = (Z_MIN, 0.0f64);
        // The start that F ≈ (ks)^c gives.
        let mut z = (target / self.c - self.ln_k).clamp(Z_MIN, 0.0);
        if z <= lo || z >= hi {
            z = 0.5 * (lo + hi);
        }
        for _ in 0..200 {
            let s = z.exp();
            let f = self.cdf(s);
            let g = f.ln() - target;
            if g < 0.0 {
                lo = z;
            } else {
                hi = z;
            }
            // d ln F/dz = s·F′(s)/F = 4π·s·p/F.
            let slope = 4.0 * PI * s * self.density(s) / f;
            let mut next = z - g / slope;
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            if (next - z).abs() <= 1e-14 * z.abs().max(1.0) || hi - lo <= 1e-14 * lo.abs() {
                return next.exp().min(1.0);
            }
            z = next;
        }
        z.exp().min(1.0)
    }

    /// Mean cosine of the scattering angle: ⟨cos θ⟩ = 1 − 2⟨s⟩ =
    /// 2∫₀¹F(s)ds − 1 (by parts), by Simpson's rule over s = t⁴, which
    /// takes F's (ks)^c rise at 0 smoothly. No closed form known to us.
    pub fn mean_cosine(&self) -> f64 {
        let n = 4000;
        let mut sum = 0.0;
        for i in 0..=n {
            let t = i as f64 / n as f64;
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            sum += w * self.cdf(t.powi(4)) * 4.0 * t.powi(3);
        }
        2.0 * sum / (3.0 * n as f64) - 1.0
    }
}
