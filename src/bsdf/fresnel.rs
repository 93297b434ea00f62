//! Fresnel reflectance as Cycles' Principled BSDF uses it
//! (`kernel/closure/bsdf_util.h` and `microfacet_fresnel` in
//! `kernel/closure/bsdf_microfacet.h`, Cycles 5.0): the exact dielectric
//! term, the "generalized Schlick" remapping the Principled BSDF's
//! specular layer applies to it, and the F82-tint conductor model of its
//! metallic lobe.

use crate::Rgb;

/// Unpolarised Fresnel reflectance of a dielectric interface of relative
/// index `eta` (outside over inside) at incidence cosine `cos_i` (Born &
/// Wolf §1.5; Walter et al. 2007 eq. 22 form, without the refracted
/// direction). 1 under total internal reflection (`eta` < 1).
#[inline]
pub fn dielectric(cos_i: f32, eta: f32) -> f32 {
    let c = cos_i.abs();
    let g2 = eta * eta - 1.0 + c * c;
    if g2 <= 0.0 {
        return 1.0;
    }
    let g = g2.sqrt();
    let a = (g - c) / (g + c);
    let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    0.5 * a * a * (1.0 + b * b)
}

/// Reflectance at normal incidence of a dielectric of index `ior`:
/// ((n − 1)/(n + 1))² (Cycles' `F0_from_ior`).
#[inline]
pub fn f0_from_ior(ior: f32) -> f32 {
    let r = (ior - 1.0) / (ior + 1.0);
    r * r
}

/// The index whose normal-incidence reflectance is `f0`, with `f0` held
/// in [0, 0.99] as Cycles' `ior_from_F0` does.
#[inline]
pub fn ior_from_f0(f0: f32) -> f32 {
    let s = f0.clamp(0.0, 0.99).sqrt();
    (1.0 + s) / (1.0 - s)
}

/// Kulla & Conty's fit (2017, "Revisiting Physically Based Shading at
/// Imageworks", appendix) of the hemispherical average of the dielectric
/// Fresnel term, ∫₀¹ 2μ F(μ, η) dμ, as Cycles' `fresnel_dielectric_Fss`.
#[inline]
pub fn dielectric_fss(eta: f32) -> f32 {
    if eta < 1.0 {
        0.997118 + eta * (0.1014 - eta * (0.965241 + eta * 0.130607))
    } else {
        (eta - 1.0) / (4.08567 + 1.00071 * eta)
    }
}

/// The Principled BSDF's dielectric specular Fresnel (Cycles'
/// `MicrofacetFresnel::GENERALIZED_SCHLICK` with a negative exponent): the
/// exact dielectric curve of `eta`, remapped from its own normal-incidence
/// value to [`f0`, 1], so that Specular IOR Level and Specular Tint move
/// F0 while the curve keeps its shape towards grazing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpecularFresnel {
    /// Reflectance at normal incidence, tinted, each channel in [0, 1].
    pub f0: Rgb,
    /// Relative index of the curve's shape (the IOR adjusted by Specular
    /// IOR Level).
    pub eta: f32,
    /// F0 of `eta` itself.
    pub f0_real: f32,
}

impl SpecularFresnel {
    pub fn new(f0: Rgb, eta: f32) -> Self {
        SpecularFresnel {
            f0: f0.clamp(Rgb::ZERO, Rgb::ONE),
            eta,
            f0_real: f0_from_ior(eta),
        }
    }

    /// Where the exact curve lies between its F0 and 1, in [0, 1].
    #[inline]
    pub fn s(&self, cos_i: f32) -> f32 {
        inverse_lerp_01(self.f0_real, dielectric(cos_i, self.eta))
    }

    #[inline]
    pub fn eval(&self, cos_i: f32) -> Rgb {
        self.f0.lerp(Rgb::ONE, self.s(cos_i))
    }

    /// The hemispherical average used by the energy compensation (Cycles'
    /// `bsdf_microfacet_setup_fresnel_generalized_schlick`): the remapping
    /// applied to the average of the exact curve (linear, so exact up to
    /// the clamp).
    pub fn average(&self) -> Rgb {
        let s = inverse_lerp_01(self.f0_real, dielectric_fss(self.eta));
        self.f0.lerp(Rgb::ONE, s)
    }
}

/// (x − a)/(1 − a) held in [0, 1] (0 when a = 1).
#[inline]
fn inverse_lerp_01(a: f32, x: f32) -> f32 {
    let d = 1.0 - a;
    if d <= 0.0 {
        return 0.0;
    }
    ((x - a) / d).clamp(0.0, 1.0)
}

/// Kutz, Hasan & Edmondson's F82-tint conductor model ("Novel aspects of
/// the Adobe Standard Material", 2023), as Cycles' Principled BSDF gives
/// its metallic lobe: Schlick's F0 → 1 curve minus b·μ(1 − μ)⁶, with b set
/// so that the curve at μ = 1/7 (about 82°) is Schlick's value times the
/// tint (`fresnel_f82tint_B`, `fresnel_f82` in Cycles' `bsdf_util.h`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct F82Tint {
    pub f0: Rgb,
    pub b: Rgb,
}

impl F82Tint {
    /// `f0` (the base colour) and `tint` (Specular Tint) each held in
    /// [0, 1], as Cycles does.
    pub fn new(f0: Rgb, tint: Rgb) -> Self {
        let f0 = f0.clamp(Rgb::ZERO, Rgb::ONE);
        let tint = tint.clamp(Rgb::ZERO, Rgb::ONE);
        let b = if tint == Rgb::ONE {
            Rgb::ZERO
        } else {
            // At μ = 1/7: 1 − μ = 6/7; Schlick(μ) − b μ (1 − μ)⁶ = Schlick(μ)·tint.
            let f = 6.0f32 / 7.0;
            let f5 = f.powi(5);
            let schlick = f0.lerp(Rgb::ONE, f5);
            schlick * (7.0 / (f5 * f)) * (Rgb::ONE - tint)
        };
        F82Tint { f0, b }
    }

    #[inline]
    pub fn eval(&self, cos_i: f32) -> Rgb {
        let s = (1.0 - cos_i).clamp(0.0, 1.0);
        let s5 = s * s * s * s * s;
        let schlick = self.f0.lerp(Rgb::ONE, s5);
        (schlick - self.b * (cos_i * s5 * s)).clamp(Rgb::ZERO, Rgb::ONE)
    }

    /// Its hemispherical average ∫₀¹ 2μ F(μ) dμ in closed form (Cycles'
    /// `fresnel_f82_Fss`): F0 + (1 − F0)/21 − b/126.
    pub fn average(&self) -> Rgb {
        self.f0.lerp(Rgb::ONE, 1.0 / 21.0) - self.b * (1.0 / 126.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_limits() {
        assert!((dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert!((dielectric(0.0, 1.5) - 1.0).abs() < 1e-6);
        assert_eq!(dielectric(0.3, 1.0), 0.0);
        // Total internal reflection inside glass beyond the critical angle.
        assert_eq!(dielectric(0.5, 1.0 / 1.5), 1.0);
        assert!((ior_from_f0(f0_from_ior(1.5)) - 1.5).abs() < 1e-5);
    }

    /// The closed-form averages equal ∫ 2μ F dμ by quadrature; for the
    /// dielectric, Kulla & Conty's fit (Cycles' too) is within 3 % from
    /// IOR 1.5 to 3 and low below: by 2.5 % at 1.5, 3.7 % at 1.45, 8 % at
    /// 1.33, 23 % at 1.1 (0.0193 for 0.0252). It only sets how much energy the
    /// compensation returns, so its error there is a fraction of 1 − E.
    #[test]
    fn averages_match_quadrature() {
        let avg = |f: &dyn Fn(f32) -> f32| {
            let n = 20_000;
            (0..n)
                .map(|i| {
                    let mu = (i as f32 + 0.5) / n as f32;
                    2.0 * mu * f(mu)
                })
                .sum::<f32>()
                / n as f32
        };
        for eta in [1.5f32, 1.6, 2.0, 2.5, 3.0] {
            let q = avg(&|mu| dielectric(mu, eta));
            assert!(
                (dielectric_fss(eta) / q - 1.0).abs() < 0.03,
                "eta {eta}: {q}"
            );
        }
        let q = avg(&|mu| dielectric(mu, 1.5));
        assert!((q - 0.09178).abs() < 1e-4, "{q}");
        // (A strong tint on a dark F0 drives the curve below 0 near 82°,
        // where Cycles clamps it and its closed form, which does not, is
        // off: for F0 0.1 and tint 0.2, 0.08498 against 0.08540.)
        let f = F82Tint::new(Rgb::new(0.9, 0.5, 0.2), Rgb::new(1.0, 0.7, 0.5));
        for c in 0..3 {
            let q = avg(&|mu| f.eval(mu)[c]);
            assert!((q - f.average()[c]).abs() < 1e-4, "{c}: {q}");
        }
    }

    /// F82-tint: F0 at normal incidence, 1 at grazing, Schlick × tint at
    /// μ = 1/7.
    #[test]
    fn f82_tint_hits_its_anchors() {
        let f0 = Rgb::new(0.95, 0.64, 0.54);
        let tint = Rgb::new(0.5, 0.8, 1.0);
        let f = F82Tint::new(f0, tint);
        assert!((f.eval(1.0) - f0).abs().max_element() < 1e-6);
        assert!((f.eval(0.0) - Rgb::ONE).abs().max_element() < 1e-6);
        let mu = 1.0f32 / 7.0;
        let schlick = f0.lerp(Rgb::ONE, (1.0 - mu).powi(5));
        assert!((f.eval(mu) - schlick * tint).abs().max_element() < 1e-5);
    }
}
