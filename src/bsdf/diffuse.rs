//! Diffuse reflection as Cycles 5.0 has it: Lambert (`bsdf_diffuse.h`)
//! below a roughness of 10⁻⁵, otherwise the Oren–Nayar model of
//! `bsdf_oren_nayar.h`, which since Blender 4.3 is Fujii's "improved"
//! Oren–Nayar (Y. Fujii, "A tiny improvement of Oren-Nayar reflectance
//! model", 2013, the variant Cycles 4.2 already used) plus the
//! energy-preserving multiple-scattering term of the OpenPBR Surface
//! specification (its "EON" diffuse, after Portsmouth et al. 2025,
//! "EON: A practical energy-preserving rough diffuse BRDF"). Sampled by
//! the cosine (as Cycles does for both).
//!
//! For roughness σ ∈ [0, 1], A = 1/(π + (π/2 − 2/3) σ), B = σ A and, with
//! s = wi·wo − cos θi cos θo divided by max(cos θi, cos θo) where it is
//! positive,
//!
//! f = C (A + B s) + C E_ms (1 − E(θo)) (1 − E(θi)),
//!
//! where E(θ) = π A + B G(θ) is the single-scattering albedo (Fujii's
//! closed form G), E_avg = π A + (2π − 5.6)/3 · B its average, and
//! E_ms = ρ² E_avg / (π (1 − E_avg) (1 − ρ (1 − E_avg))) with ρ = C held
//! in [0, 1]. Reciprocal. C is the closure's colour (weight); for the
//! Diffuse BSDF node Cycles holds ρ in [0, 1] but not C.

use crate::Rgb;
use glam::Vec3;
use std::f32::consts::{FRAC_PI_2, PI};

/// Below this roughness the Diffuse BSDF node is Lambert in Cycles
/// (`svm_node_closure_bsdf`, `CLOSURE_BSDF_DIFFUSE_ID`).
pub const LAMBERT_BELOW: f32 = 1e-5;

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Diffuse {
    /// f = 1/π (times the lobe's colour).
    Lambert,
    OrenNayar(OrenNayar),
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrenNayar {
    a: f32,
    b: f32,
    /// E_ms: the multiple-scattering term without its two (1 − E) factors.
    e_ms: Rgb,
}

impl Diffuse {
    /// `roughness` below [`LAMBERT_BELOW`] gives Lambert; `albedo` is the
    /// colour the multiple-scattering term is computed for.
    pub fn new(roughness: f32, albedo: Rgb) -> Self {
        if roughness.is_nan() || roughness < LAMBERT_BELOW {
            Diffuse::Lambert
        } else {
            Diffuse::OrenNayar(OrenNayar::new(roughness, albedo))
        }
    }

    /// f without the colour, both directions above the surface (wi.z > 0
    /// is checked by the caller; wo.z ≤ 0 is evaluated as Cycles does,
    /// with cos θo taken as 0).
    #[inline]
    pub fn f(&self, wo: Vec3, wi: Vec3) -> Rgb {
        match self {
            Diffuse::Lambert => Rgb::splat(1.0 / PI),
            Diffuse::OrenNayar(on) => on.f(wo, wi),
        }
    }
}

/// Fujii's G(θ) = sin θ (θ − 2/3 − sin θ cos θ) + (2/3) tan θ (1 − sin³ θ),
/// with its Taylor expansion near grazing where tan θ loses precision
/// (`bsdf_oren_nayar_G`).
#[inline]
fn g(cos: f32) -> f32 {
    if cos < 1e-6 {
        return (FRAC_PI_2 - 2.0 / 3.0) - cos;
    }
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let theta = cos.clamp(-1.0, 1.0).acos();
    sin * (theta - 2.0 / 3.0 - sin * cos) + 2.0 / 3.0 * (sin / cos) * (1.0 - sin * sin * sin)
}

impl OrenNayar {
    pub fn new(roughness: f32, albedo: Rgb) -> Self {
        let sigma = roughness.clamp(0.0, 1.0);
        let a = 1.0 / (PI + sigma * (FRAC_PI_2 - 2.0 / 3.0));
        let b = sigma * a;
        let rho = albedo.clamp(Rgb::ZERO, Rgb::ONE);
        let e_avg = a * PI + (2.0 * PI - 5.6) / 3.0 * b;
        let e_ms = rho * rho * (e_avg / (PI * (1.0 - e_avg))) / (Rgb::ONE - rho * (1.0 - e_avg));
        OrenNayar { a, b, e_ms }
    }

    /// Single-scattering directional albedo E(θ).
    #[inline]
    fn e(&self, cos: f32) -> f32 {
        self.a * PI + self.b * g(cos)
    }

    #[inline]
    pub fn f(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let nl = wi.z.max(0.0);
        let nv = wo.z.max(0.0);
        let mut s = wi.dot(wo) - nl * nv;
        if s > 0.0 {
            s /= nl.max(nv) + f32::MIN_POSITIVE;
        }
        let single = self.a + self.b * s;
        let multi = self.e_ms * ((1.0 - self.e(nv)) * (1.0 - self.e(nl)));
        Rgb::splat(single) + multi
    }
}
