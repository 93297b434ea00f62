//! The GGX (Trowbridge–Reitz) microfacet distribution with Smith's
//! height-correlated masking–shadowing, isotropic, reflection only, in the
//! form Cycles 5.0 evaluates it (`bsdf_microfacet_eval` and
//! `bsdf_microfacet_sample` in `kernel/closure/bsdf_microfacet.h`):
//!
//! f(wo, wi) = F(wo·h) D(h) G₂(wo, wi) / (4 cos θo cos θi),
//! G₂ = 1 / (1 + Λ(wo) + Λ(wi)) (Heitz 2014, "Understanding the
//! Masking-Shadowing Function in Microfacet-Based BRDFs", eq. 99 and 72),
//! sampled from the distribution of visible normals (Heitz 2018,
//! "Sampling the GGX Distribution of Visible Normals", JCGT 7(4)), whose
//! density of wi is D(h) G₁(wo) / (4 cos θo).
//!
//! Local frame, z the normal; `wo` towards the viewer, `wi` towards the
//! light (the module's convention, `super`). D and Λ are computed from the
//! components of h and w (sin² θ = x² + y²) instead of 1 − cos² θ, which
//! keeps f32 precise for lobes much narrower than its epsilon.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Below this α², Cycles treats a microfacet lobe as a perfect mirror
/// (`BSDF_ROUGHNESS_SQ_THRESH`, `kernel/svm/types.h`): it cannot be
/// evaluated, only sampled.
pub const ROUGHNESS_SQ_THRESH: f32 = 2e-10;

/// D(h) for a (not necessarily unit) half vector: α² |h|⁴ / (π (h_x² +
/// h_y² + α² h_z²)²), which is α² / (π (sin² + α² cos²)²) for a unit h.
#[inline]
pub fn d(alpha2: f32, h: Vec3) -> f32 {
    let s2 = h.x * h.x + h.y * h.y;
    let c2 = h.z * h.z;
    let l2 = s2 + c2;
    let den = s2 + alpha2 * c2;
    if den <= 0.0 {
        return 0.0;
    }
    alpha2 * l2 * l2 / (PI * den * den)
}

/// Smith's Λ for GGX: (√(1 + α² tan² θ) − 1) / 2 (Heitz 2014, eq. 72).
#[inline]
pub fn lambda(alpha2: f32, w: Vec3) -> f32 {
    let c2 = w.z * w.z;
    if c2 <= 0.0 {
        return f32::INFINITY;
    }
    let t2 = (w.x * w.x + w.y * w.y) / c2;
    0.5 * ((1.0 + alpha2 * t2).sqrt() - 1.0)
}

/// The geometric part of a reflection lobe at (wo, wi), both above the
/// surface: the unit half vector, D G₂ / (4 cos θo cos θi) (f without
/// Fresnel), and the density of wi under [`sample_vndf`].
#[derive(Debug, Clone, Copy)]
pub struct Reflection {
    pub h: Vec3,
    pub f: f32,
    pub pdf: f32,
}

/// [`Reflection`] for roughness α; `None` when either direction is not
/// above the surface or the lobe is a mirror (α² at or below
/// [`ROUGHNESS_SQ_THRESH`]).
#[inline]
pub fn reflection(alpha: f32, wo: Vec3, wi: Vec3) -> Option<Reflection> {
    let alpha2 = alpha * alpha;
    if wo.z <= 0.0 || wi.z <= 0.0 || alpha2 <= ROUGHNESS_SQ_THRESH {
        return None;
    }
    let hu = wo + wi;
    let len = hu.length();
    if len <= 0.0 {
        return None;
    }
    let h = hu / len;
    let dh = d(alpha2, hu);
    let (lo, li) = (lambda(alpha2, wo), lambda(alpha2, wi));
    let common = dh / (4.0 * wo.z);
    Some(Reflection {
        h,
        f: common / (wi.z * (1.0 + lo + li)),
        pdf: common / (1.0 + lo),
    })
}

/// A microfacet normal drawn from the visible normals seen from `wo`
/// (wo.z > 0), by Heitz 2018 (stretch to the hemisphere configuration,
/// sample its projected area, lift, unstretch), as Cycles'
/// `microfacet_ggx_sample_vndf` does.
pub fn sample_vndf(wo: Vec3, alpha: f32, u: Vec2) -> Vec3 {
    let v = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let lensq = v.x * v.x + v.y * v.y;
    let (t1, t2) = if lensq > 1e-7 {
        let t1 = Vec3::new(-v.y, v.x, 0.0) / lensq.sqrt();
        (t1, v.cross(t1))
    } else {
        (Vec3::X, Vec3::Y)
    };
    let mut p = crate::sampling::sample_uniform_disk_concentric(u);
    let s = 0.5 * (1.0 + v.z);
    p.y = (1.0 - s) * (1.0 - p.x * p.x).max(0.0).sqrt() + s * p.y;
    let pz = (1.0 - p.length_squared()).max(0.0).sqrt();
    let nh = t1 * p.x + t2 * p.y + v * pz;
    Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(0.0)).normalize()
}

/// The mirror image of `wo` about `h`.
#[inline]
pub fn reflect(wo: Vec3, h: Vec3) -> Vec3 {
    2.0 * wo.dot(h) * h - wo
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ D(h) cos θh dωh = 1 (the projected microfacet area is the
    /// macro-surface's), by quadrature in θ with the substitution tan θ =
    /// α tan(πt/2), which follows the lobe at any α.
    #[test]
    fn d_is_normalised() {
        for alpha in [1e-3f32, 0.05, 0.3, 1.0] {
            let n = 4000;
            let mut sum = 0.0f64;
            for i in 0..n {
                let t = (i as f64 + 0.5) / n as f64;
                let tt = (std::f64::consts::FRAC_PI_2 * t).tan();
                let theta = (alpha as f64 * tt).atan();
                let dtheta = alpha as f64 * std::f64::consts::FRAC_PI_2 * (1.0 + tt * tt)
                    / (1.0 + (alpha as f64 * tt).powi(2));
                let h = Vec3::new(theta.sin() as f32, 0.0, theta.cos() as f32);
                sum += d(alpha * alpha, h) as f64
                    * theta.cos()
                    * theta.sin()
                    * dtheta
                    * 2.0
                    * std::f64::consts::PI
                    / n as f64;
            }
            assert!((sum - 1.0).abs() < 2e-3, "alpha {alpha}: {sum}");
        }
    }

    /// The masking function's normalisation: ∫ G₁(wo) max(0, wo·h) D(h)
    /// dωh = cos θo (Heitz 2014, eq. 2), i.e. the visible normals' density
    /// integrates to 1.
    #[test]
    fn visible_normals_are_normalised() {
        for alpha in [0.05f32, 0.5, 1.0] {
            for cos_o in [0.05f32, 0.5, 1.0] {
                let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
                let g1 = 1.0 / (1.0 + lambda(alpha * alpha, wo)) as f64;
                let (nt, np) = (1500, 400);
                let mut sum = 0.0f64;
                for i in 0..nt {
                    let t = (i as f64 + 0.5) / nt as f64;
                    let tt = (std::f64::consts::FRAC_PI_2 * t).tan();
                    let theta = (alpha as f64 * tt).atan();
                    // D cos θh dω in t: sin(πt)/4 dt dφ (tests/bsdf_tables.rs).
                    let w = (std::f64::consts::PI * t).sin() / (4.0 * theta.cos());
                    for j in 0..np {
                        let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / np as f64;
                        let h = Vec3::new(
                            (theta.sin() * phi.cos()) as f32,
                            (theta.sin() * phi.sin()) as f32,
                            theta.cos() as f32,
                        );
                        sum += w * (wo.dot(h).max(0.0) as f64) / (nt * np) as f64
                            * 2.0
                            * std::f64::consts::PI;
                    }
                }
                let got = g1 * sum / cos_o as f64;
                assert!((got - 1.0).abs() < 3e-3, "alpha {alpha} cos {cos_o}: {got}");
            }
        }
    }

    #[test]
    fn vndf_normals_face_the_viewer() {
        let wo = Vec3::new(0.8, 0.0, 0.6);
        for i in 0..1000 {
            let u = Vec2::new((i as f32 + 0.5) / 1000.0, ((i * 7) % 1000) as f32 / 1000.0);
            let h = sample_vndf(wo, 0.4, u);
            assert!((h.length() - 1.0).abs() < 1e-5 && h.z >= 0.0 && wo.dot(h) >= -1e-6);
        }
    }
}
