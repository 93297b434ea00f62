//! Surface scattering: Blender's Principled BSDF and Diffuse BSDF as
//! Cycles 4.x/5.0 evaluates them, for opaque grounds and props. Optics
//! only: which surface, which material and how its light is gathered are
//! the integrators'.
//!
//! # Conventions (the one place they are written)
//! Every direction is a unit vector in the local [`Frame`] of the shading
//! point, whose z is the shading normal, and both point **away** from the
//! surface: `wo` towards the viewer (for a camera path, minus the ray's
//! direction), `wi` towards the light. This is pbrt-v4's convention
//! (§9.1). Cycles names them the other way round: its `sd->wi` is our
//! `wo` and the `wo` of its `bsdf_eval` our `wi`.
//!
//! [`Bsdf::f`] is the BSDF itself, **without** cos θi (pbrt's `f`);
//! Cycles' `bsdf_eval` returns f·cos θi. A light of irradiance E arriving
//! along wi is reflected as L = f(wo, wi) · cos θi · E.
//!
//! Reflection only: f and the density are 0 for wi.z ≤ 0, and sampling
//! never returns such a direction.
//!
//! # Back faces and shading normals
//! Cycles turns the normals of a surface seen from behind to face the
//! viewer for every closure that does not transmit (`SD_BACKFACING`:
//! `sd->N` and `sd->Ng` are negated), so both sides of a mesh shade
//! alike. Build the frame with [`Frame::facing`], which does the same from
//! the geometric normal. A shading (smooth or bumped) normal can still put
//! `wo` below the frame's horizon; then we do as Cycles does: the glossy
//! lobes give nothing and cannot be sampled (`bsdf_microfacet_eval`
//! refuses cos θo ≤ 0), the diffuse lobe still reflects (Lambert ignores
//! wo; Oren–Nayar takes cos θo as 0). Cycles also drops sampled
//! directions below the *geometric* surface (`bsdf_*_sample` check
//! `dot(Ng, wo)`): the caller, which knows Ng, should drop those too.
//!
//! # What is evaluated (Cycles 5.0, `kernel/svm/closure.h`,
//! `svm_node_closure_bsdf`, `CLOSURE_BSDF_PRINCIPLED_ID`)
//! With m = Metallic, r = Roughness and α = r² (Cycles squares the
//! roughness), the Principled BSDF is the sum of
//! 1. a metallic GGX lobe, weight m, with the F82-tint Fresnel of
//!    [`fresnel::F82Tint`] (F0 = Base Color, tint = Specular Tint);
//! 2. a dielectric GGX specular layer, weight 1 − m, with the Fresnel of
//!    [`fresnel::SpecularFresnel`]: F0 = F0(IOR) · 2 · Specular IOR Level ·
//!    Specular Tint, the curve of the IOR whose F0 that is (level 0 removes
//!    the layer);
//! 3. a diffuse base, weight (1 − m) · Base Color, Lambert (Oren–Nayar
//!    with Blender 4.3's Diffuse Roughness), attenuated by the specular
//!    layer's estimated albedo seen from wo: the base's weight is
//!    multiplied by 1 − maxc(albedo_c) (Cycles' `closure_layering_weight`,
//!    its "albedo scaling"; the estimate is `bsdf_microfacet_estimate_albedo`,
//!    F0 + (1 − F0)·s from [`tables::ggx_ior_s`], times the energy
//!    compensation's darkening below).
//!
//! With Multiscatter GGX (Blender's default), each GGX lobe is multiplied
//! by 1 + F_ms (1 − E)/E, E = E(r, cos θo) its directional albedo without
//! Fresnel ([`tables::ggx_e`]) and F_ms = F_avg E_avg / (1 − F_avg (1 −
//! E_avg)) the Fresnel of the light that scatters more than once (Kulla &
//! Conty 2017, "Revisiting Physically Based Shading at Imageworks", with
//! one F_avg cancelled: Cycles' `microfacet_ggx_preserve_energy`; F_avg the
//! Fresnel model's hemispherical average). Since that factor and the
//! layering depend on wo alone, the Principled BSDF is not reciprocal, in
//! Cycles as here; its lobes without them are.
//!
//! Lobes are sampled in proportion to Cycles' sample weights (a closure's
//! weight times its estimated albedo), and the density of a direction is
//! the mixture's, Σ wₖ pdfₖ / Σ wₖ (`surface_shader_bsdf_eval_pdfs`).
//! Below α² = 2·10⁻¹⁰ (r ≈ 0.0038) a GGX lobe is a mirror, as in Cycles:
//! it adds nothing to [`Bsdf::f`] or [`Bsdf::pdf`] and is sampled as a
//! Dirac delta ([`BsdfSample::singular`]).
//!
//! Not modelled (callers warn): transmission, coat, sheen, subsurface,
//! anisotropy, thin film, alpha, emission through the BSDF (see
//! [`emission`]), the bump-map corrections of the normal.

mod diffuse;
pub mod fresnel;
mod microfacet;
pub mod tables;

use crate::sampling::{coordinate_system, sample_cosine_hemisphere};
use crate::Rgb;
use diffuse::Diffuse;
use fresnel::{F82Tint, SpecularFresnel};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Cycles drops a closure whose sample weight is below this
/// (`CLOSURE_WEIGHT_CUTOFF`, `kernel/svm/types.h`).
const WEIGHT_CUTOFF: f32 = 1e-5;

/// A glossy lobe with α² above this counts as diffuse for the denoiser's
/// albedo (0.075², `film_write_denoising_features_surface`).
const DENOISE_ROUGH_SQ: f32 = 0.075 * 0.075;

/// An orthonormal frame whose z is the shading normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub t: Vec3,
    pub b: Vec3,
    pub n: Vec3,
}

impl Frame {
    /// A frame around the unit normal `n` (the tangents are arbitrary;
    /// every lobe here is isotropic).
    pub fn from_normal(n: Vec3) -> Self {
        let (t, b) = coordinate_system(n);
        Frame { t, b, n }
    }

    /// The frame Cycles shades in: around the shading normal `ns`, turned
    /// to the viewer's side when the geometric normal `ng` faces away from
    /// `wo` (world space, pointing away from the surface).
    pub fn facing(ns: Vec3, ng: Vec3, wo: Vec3) -> Self {
        if ng.dot(wo) < 0.0 {
            Frame::from_normal(-ns)
        } else {
            Frame::from_normal(ns)
        }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
}

/// The BSDF at a pair of directions, split as Blender's passes split it:
/// `diffuse` (Diffuse Direct/Indirect) and `glossy` (Glossy). Without
/// cos θi. Units: 1/sr.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BsdfValue {
    pub diffuse: Rgb,
    pub glossy: Rgb,
}

impl BsdfValue {
    pub const ZERO: BsdfValue = BsdfValue {
        diffuse: Rgb::ZERO,
        glossy: Rgb::ZERO,
    };

    #[inline]
    pub fn total(&self) -> Rgb {
        self.diffuse + self.glossy
    }

    #[inline]
    pub fn scaled(&self, s: f32) -> BsdfValue {
        BsdfValue {
            diffuse: self.diffuse * s,
            glossy: self.glossy * s,
        }
    }
}

/// A direction drawn by [`Bsdf::sample`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BsdfSample {
    /// Towards where the light comes from, wi.z > 0.
    pub wi: Vec3,
    /// The whole BSDF at (wo, wi), every lobe (as [`Bsdf::f`]), unless
    /// `singular`.
    pub f: BsdfValue,
    /// The mixture's solid-angle density of `wi` (as [`Bsdf::pdf`]),
    /// unless `singular`.
    pub pdf: f32,
    /// Whether a glossy lobe drew it (else the diffuse one): which pass
    /// the path's later light belongs to.
    pub glossy: bool,
    /// A mirror lobe (roughness below ≈ 0.0038) drew it: `f` is that
    /// lobe's weight over cos θi and `pdf` the probability of having picked
    /// it, so f·cos θi/pdf is the path's weight as for any sample, but the
    /// direction is a Dirac delta: no light sampling can find it (MIS
    /// weight 1 for this sample).
    pub singular: bool,
}

/// What the denoiser's albedo guide takes from a surface, as Cycles
/// writes its Denoising Albedo pass (`film_write_denoising_features_surface`,
/// `kernel/film/denoising_passes.h`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AlbedoGuide {
    /// The guide's value here: the estimated albedo of the diffuse-like
    /// lobes (diffuse, and glossy ones rougher than α = 0.075), times the
    /// path's guide throughput.
    Albedo(Rgb),
    /// Mostly sharp reflection (at least 75 % of the sample weight in
    /// lobes with α ≤ 0.075): multiply the guide's throughput by this (the
    /// sharp lobes' albedo) and take the guide from what the reflected ray
    /// sees.
    Continue(Rgb),
}

/// Blender's GGX distributions for the Principled BSDF.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Distribution {
    /// Single scattering only: loses energy at high roughness.
    Ggx,
    /// GGX with Cycles' energy compensation (Blender's default).
    #[default]
    MultiGgx,
}

/// The Principled BSDF's inputs that shape an opaque surface, with Blender
/// 4+/5's names and defaults (checked in bpy 5.0.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrincipledParams {
    /// Base Color, linear RGB; default 0.8 grey.
    pub base_color: Rgb,
    /// Roughness in [0, 1] (α = r²); default 0.5.
    pub roughness: f32,
    /// Metallic in [0, 1]; default 0.
    pub metallic: f32,
    /// IOR; default 1.5 (Blender 4.0 on).
    pub ior: f32,
    /// Specular IOR Level, scaling F0 by twice its value (0.5 keeps the
    /// IOR's F0, 0 removes the specular layer); default 0.5.
    pub specular_ior_level: f32,
    /// Specular Tint: F0's colour for dielectrics, the colour at grazing
    /// (82°) for metals; default white.
    pub specular_tint: Rgb,
    /// Diffuse Roughness (Blender 4.3 on): Oren–Nayar above 0; default 0.
    pub diffuse_roughness: f32,
    /// Default Multiscatter GGX.
    pub distribution: Distribution,
}

impl Default for PrincipledParams {
    fn default() -> Self {
        PrincipledParams {
            base_color: Rgb::splat(0.8),
            roughness: 0.5,
            metallic: 0.0,
            ior: 1.5,
            specular_ior_level: 0.5,
            specular_tint: Rgb::ONE,
            diffuse_roughness: 0.0,
            distribution: Distribution::MultiGgx,
        }
    }
}

impl PrincipledParams {
    /// Refuses inputs that are not finite, naming the input as Blender
    /// does. ([`Bsdf::principled`] takes any values: it clamps as Cycles
    /// does and replaces what is not finite by Blender's default.)
    pub fn validate(&self) -> Result<(), String> {
        let colors = [
            ("Base Color", self.base_color),
            ("Specular Tint", self.specular_tint),
        ];
        for (name, c) in colors {
            if !c.is_finite() {
                return Err(format!("{name} is not a finite colour ({c})"));
            }
        }
        let floats = [
            ("Roughness", self.roughness),
            ("Metallic", self.metallic),
            ("IOR", self.ior),
            ("Specular IOR Level", self.specular_ior_level),
            ("Diffuse Roughness", self.diffuse_roughness),
        ];
        for (name, v) in floats {
            if !v.is_finite() {
                return Err(format!("{name} is not a finite number ({v})"));
            }
        }
        Ok(())
    }

    /// The inputs as Cycles reads them: clamped to their ranges, and what
    /// is not finite replaced by the default.
    fn sanitized(&self) -> PrincipledParams {
        let d = PrincipledParams::default();
        let color = |c: Rgb, d: Rgb| {
            Rgb::from_array([0, 1, 2].map(|i| {
                if c[i].is_finite() {
                    c[i].max(0.0)
                } else {
                    d[i]
                }
            }))
        };
        let num = |v: f32, d: f32| if v.is_finite() { v } else { d };
        PrincipledParams {
            base_color: color(self.base_color, d.base_color),
            roughness: num(self.roughness, d.roughness).clamp(0.0, 1.0),
            metallic: num(self.metallic, d.metallic).clamp(0.0, 1.0),
            ior: num(self.ior, d.ior).max(1e-5),
            specular_ior_level: num(self.specular_ior_level, d.specular_ior_level).max(0.0),
            specular_tint: color(self.specular_tint, d.specular_tint),
            diffuse_roughness: num(self.diffuse_roughness, d.diffuse_roughness).clamp(0.0, 1.0),
            distribution: self.distribution,
        }
    }
}

/// The radiance of Blender's Emission shader (and the Principled BSDF's
/// Emission) on a surface: Color × Strength, the same on both sides
/// (Cycles' `emission_setup`, `emissive_simple_eval`), W/(m² sr) for
/// Strength in W/m². Strength 1 makes the surface show its colour.
#[inline]
pub fn emission(color: Rgb, strength: f32) -> Rgb {
    color * strength
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum LobeFresnel {
    Specular(SpecularFresnel),
    Metal(F82Tint),
}

/// A GGX reflection lobe with its Fresnel model and energy compensation.
#[derive(Debug, Clone, Copy, PartialEq)]
struct GgxLobe {
    /// The closure's weight (Metallic, or 1 − Metallic).
    weight: f32,
    alpha: f32,
    fresnel: LobeFresnel,
    /// The Fresnel model's hemispherical average, for F_ms.
    f_avg: Rgb,
    multiscatter: bool,
}

/// What a GGX lobe is worth seen from one wo.
#[derive(Debug, Clone, Copy)]
struct GgxAt {
    /// Multiplies F·D·G₂/(4 cos cos): weight × (1 + F_ms (1 − E)/E).
    scale: Rgb,
    /// Cycles' albedo estimate of the closure (`bsdf_albedo`): weight ×
    /// darkening × (F0 + (1 − F0) s).
    albedo: Rgb,
    sample_weight: f32,
}

impl GgxLobe {
    #[inline]
    fn singular(&self) -> bool {
        self.alpha * self.alpha <= microfacet::ROUGHNESS_SQ_THRESH
    }

    /// The roughness the tables are read at (Cycles' √√(αx αy)).
    #[inline]
    fn rough(&self) -> f32 {
        self.alpha.sqrt()
    }

    #[inline]
    fn fresnel(&self, cos: f32) -> Rgb {
        match &self.fresnel {
            LobeFresnel::Specular(f) => f.eval(cos),
            LobeFresnel::Metal(f) => f.eval(cos),
        }
    }

    /// Cycles' `bsdf_microfacet_estimate_albedo` at μ = cos θo: F0 + (1 −
    /// F0)·s with s from the tables (the F82 term's b left out, as
    /// Cycles does), 0 when the Fresnel term at μ itself is 0.
    fn albedo_estimate(&self, mu: f32) -> Rgb {
        if self.fresnel(mu) == Rgb::ZERO {
            return Rgb::ZERO;
        }
        match &self.fresnel {
            LobeFresnel::Specular(f) => {
                f.f0.lerp(Rgb::ONE, tables::ggx_ior_s(self.rough(), mu, f.eta))
            }
            LobeFresnel::Metal(f) => {
                f.f0.lerp(Rgb::ONE, tables::ggx_schlick5_s(self.rough(), mu))
            }
        }
    }

    /// Energy compensation at μ: (1 + F_ms (1 − E)/E, E + F_ms (1 − E)),
    /// the factor on the lobe and Cycles' "darkening" on its weight
    /// (`microfacet_ggx_preserve_energy`); both 1 without compensation.
    fn compensation(&self, mu: f32) -> (Rgb, Rgb) {
        if !self.multiscatter {
            return (Rgb::ONE, Rgb::ONE);
        }
        let e = tables::ggx_e(self.rough(), mu);
        let e_avg = tables::ggx_e_avg(self.rough());
        let f_ms = self.f_avg * e_avg / (Rgb::ONE - self.f_avg * (1.0 - e_avg));
        let missing = (1.0 - e) / e;
        let scale = Rgb::ONE + f_ms * missing;
        (scale, scale * e)
    }

    fn at(&self, mu: f32) -> GgxAt {
        let (scale, darkening) = self.compensation(mu);
        let est = self.albedo_estimate(mu);
        GgxAt {
            scale: scale * self.weight,
            albedo: darkening * est * self.weight,
            sample_weight: self.weight * mean(est) * mean(darkening),
        }
    }
}

#[inline]
fn mean(c: Rgb) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

/// The diffuse lobe: a colour (the closure's weight) and its model.
#[derive(Debug, Clone, Copy, PartialEq)]
struct DiffuseLobe {
    color: Rgb,
    model: Diffuse,
}

/// A surface's BSDF: Blender's Principled BSDF or Diffuse BSDF. Cheap to
/// copy; the per-direction parts are computed at each call.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bsdf {
    diffuse: Option<DiffuseLobe>,
    /// Under the specular layer: attenuated by its albedo.
    layered: bool,
    specular: Option<GgxLobe>,
    metal: Option<GgxLobe>,
}

/// The lobes' weights seen from one wo.
#[derive(Debug, Clone, Copy)]
struct Lobes {
    diffuse: Rgb,
    diffuse_sample: f32,
    specular: Option<GgxAt>,
    metal: Option<GgxAt>,
}

impl Lobes {
    fn sample_total(&self) -> f32 {
        self.diffuse_sample
            + self.specular.map_or(0.0, |s| s.sample_weight)
            + self.metal.map_or(0.0, |s| s.sample_weight)
    }
}

impl Bsdf {
    /// Blender's Diffuse BSDF: `color` (any non-negative value; Cycles
    /// holds only the Oren–Nayar albedo in [0, 1]) and `roughness` (Lambert
    /// below 10⁻⁵, Oren–Nayar above, clamped to 1).
    pub fn diffuse(color: Rgb, roughness: f32) -> Self {
        let color =
            Rgb::from_array(
                color
                    .to_array()
                    .map(|c| if c.is_finite() { c.max(0.0) } else { 0.8 }),
            );
        Bsdf {
            diffuse: Some(DiffuseLobe {
                color,
                model: Diffuse::new(roughness, color),
            }),
            layered: false,
            specular: None,
            metal: None,
        }
    }

    /// Blender's Principled BSDF (the module's documentation says what of
    /// it), from its inputs as Cycles clamps them.
    pub fn principled(p: &PrincipledParams) -> Self {
        let p = p.sanitized();
        let multiscatter = p.distribution == Distribution::MultiGgx;
        let alpha = p.roughness * p.roughness;
        let metal = (p.metallic > WEIGHT_CUTOFF).then(|| {
            let f = F82Tint::new(p.base_color, p.specular_tint);
            GgxLobe {
                weight: p.metallic,
                alpha,
                fresnel: LobeFresnel::Metal(f),
                f_avg: f.average(),
                multiscatter,
            }
        });
        let w = 1.0 - p.metallic;
        // Specular IOR Level scales F0; the curve is that of the IOR with
        // the scaled F0 (`svm_node_closure_bsdf`: "Apply IOR adjustment").
        let mut eta = p.ior;
        let mut f0 = fresnel::f0_from_ior(eta);
        if p.specular_ior_level != 0.5 {
            f0 *= 2.0 * p.specular_ior_level;
            eta = fresnel::ior_from_f0(f0);
            if p.ior < 1.0 {
                eta = 1.0 / eta;
            }
        }
        let specular = (eta != 1.0 && w >= WEIGHT_CUTOFF).then(|| {
            let f = SpecularFresnel::new(p.specular_tint * f0, eta);
            GgxLobe {
                weight: w,
                alpha,
                fresnel: LobeFresnel::Specular(f),
                f_avg: f.average(),
                multiscatter,
            }
        });
        Bsdf {
            diffuse: Some(DiffuseLobe {
                color: p.base_color * w,
                model: Diffuse::new(p.diffuse_roughness, p.base_color),
            }),
            layered: true,
            specular,
            metal,
        }
    }

    fn lobes(&self, wo: Vec3) -> Lobes {
        let mu = wo.z;
        let specular = self.specular.map(|l| l.at(mu));
        let metal = self.metal.map(|l| l.at(mu));
        let mut diffuse = self.diffuse.map_or(Rgb::ZERO, |d| d.color);
        if self.layered {
            if let (Some(s), Some(l)) = (specular, self.specular) {
                // Cycles' closure_layering_weight: the base loses the
                // largest channel of the layer's albedo over its weight.
                diffuse *= (1.0 - (s.albedo / l.weight).max_element()).clamp(0.0, 1.0);
            }
        }
        let mut diffuse_sample = mean(diffuse).abs();
        if diffuse_sample < WEIGHT_CUTOFF {
            diffuse = Rgb::ZERO;
            diffuse_sample = 0.0;
        }
        Lobes {
            diffuse,
            diffuse_sample,
            specular,
            metal,
        }
    }

    fn glossy_lobes<'a>(&'a self, l: &'a Lobes) -> impl Iterator<Item = (&'a GgxLobe, &'a GgxAt)> {
        self.specular
            .iter()
            .zip(l.specular.iter())
            .chain(self.metal.iter().zip(l.metal.iter()))
    }

    fn f_with(&self, l: &Lobes, wo: Vec3, wi: Vec3) -> BsdfValue {
        if wi.z <= 0.0 {
            return BsdfValue::ZERO;
        }
        let diffuse = match &self.diffuse {
            Some(d) if l.diffuse_sample > 0.0 => l.diffuse * d.model.f(wo, wi),
            _ => Rgb::ZERO,
        };
        let mut glossy = Rgb::ZERO;
        for (lobe, at) in self.glossy_lobes(l) {
            if let Some(r) = microfacet::reflection(lobe.alpha, wo, wi) {
                glossy += at.scale * lobe.fresnel(wo.dot(r.h)) * r.f;
            }
        }
        BsdfValue { diffuse, glossy }
    }

    fn pdf_with(&self, l: &Lobes, wo: Vec3, wi: Vec3) -> f32 {
        let total = l.sample_total();
        if wi.z <= 0.0 || total <= 0.0 {
            return 0.0;
        }
        let mut p = l.diffuse_sample * wi.z / PI;
        for (lobe, at) in self.glossy_lobes(l) {
            if let Some(r) = microfacet::reflection(lobe.alpha, wo, wi) {
                p += at.sample_weight * r.pdf;
            }
        }
        p / total
    }

    /// The BSDF at (wo, wi), without cos θi.
    pub fn f(&self, wo: Vec3, wi: Vec3) -> BsdfValue {
        self.f_with(&self.lobes(wo), wo, wi)
    }

    /// The solid-angle density with which [`Bsdf::sample`] draws `wi`
    /// (mirror lobes left out).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.pdf_with(&self.lobes(wo), wo, wi)
    }

    /// Draws wi: a lobe chosen by `uc` in proportion to Cycles' sample
    /// weights, a direction from it by `u` (the cosine for the diffuse
    /// lobe, the visible normals for a glossy one). `None` when the chosen
    /// lobe gives no direction above the surface (Cycles' `LABEL_NONE`: the
    /// path ends), or nothing reflects.
    pub fn sample(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<BsdfSample> {
        let l = self.lobes(wo);
        let total = l.sample_total();
        if total <= 0.0 {
            return None;
        }
        let mut pick = uc * total;
        let mut chosen = None;
        for (lobe, at) in self.glossy_lobes(&l) {
            if pick < at.sample_weight {
                chosen = Some((lobe, at));
                break;
            }
            pick -= at.sample_weight;
        }
        let wi = match chosen {
            None => {
                if l.diffuse_sample <= 0.0 {
                    return None;
                }
                sample_cosine_hemisphere(u)
            }
            Some((lobe, at)) => {
                if wo.z <= 0.0 {
                    return None;
                }
                if lobe.singular() {
                    let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                    let f = at.scale * lobe.fresnel(wo.z) / wi.z;
                    return Some(BsdfSample {
                        wi,
                        f: BsdfValue {
                            diffuse: Rgb::ZERO,
                            glossy: f,
                        },
                        pdf: at.sample_weight / total,
                        glossy: true,
                        singular: true,
                    });
                }
                microfacet::reflect(wo, microfacet::sample_vndf(wo, lobe.alpha, u))
            }
        };
        if wi.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf_with(&l, wo, wi);
        if pdf <= 0.0 || !pdf.is_finite() {
            return None;
        }
        Some(BsdfSample {
            wi,
            f: self.f_with(&l, wo, wi),
            pdf,
            glossy: chosen.is_some(),
            singular: false,
        })
    }

    /// The denoiser's albedo guide at this surface seen from `wo`.
    pub fn albedo(&self, wo: Vec3) -> AlbedoGuide {
        let l = self.lobes(wo);
        let (mut diffuse_like, mut sharp) = (l.diffuse, Rgb::ZERO);
        let (mut total, mut rough) = (l.diffuse_sample, l.diffuse_sample);
        for (lobe, at) in self.glossy_lobes(&l) {
            total += at.sample_weight;
            if lobe.alpha * lobe.alpha > DENOISE_ROUGH_SQ {
                diffuse_like += at.albedo;
                rough += at.sample_weight;
            } else {
                sharp += at.albedo;
            }
        }
        if total == 0.0 || rough * 4.0 > total {
            AlbedoGuide::Albedo(diffuse_like)
        } else {
            AlbedoGuide::Continue(sharp)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_round_trips_and_faces_the_viewer() {
        let n = Vec3::new(0.3, -0.5, 0.81).normalize();
        let f = Frame::from_normal(n);
        let v = Vec3::new(0.2, 0.7, -0.4);
        assert!((f.to_world(f.to_local(v)) - v).length() < 1e-6);
        assert!((f.to_local(n) - Vec3::Z).length() < 1e-6);
        let wo = -n;
        assert!(Frame::facing(n, n, wo).to_local(wo).z > 0.99);
        assert!(Frame::facing(n, n, -wo).to_local(-wo).z > 0.99);
    }

    #[test]
    fn validate_names_the_input() {
        let p = PrincipledParams {
            roughness: f32::NAN,
            ..Default::default()
        };
        assert!(p.validate().unwrap_err().contains("Roughness"));
        assert!(PrincipledParams::default().validate().is_ok());
        // Not finite becomes the default, not black.
        let b = Bsdf::principled(&p);
        assert_eq!(b, Bsdf::principled(&PrincipledParams::default()));
    }

    /// Specular IOR Level 0 removes the specular layer; metallic 0 has no
    /// metal; metallic 1 has nothing else.
    #[test]
    fn lobes_present_as_cycles_allocates_them() {
        let p = PrincipledParams::default();
        let b = Bsdf::principled(&p);
        assert!(b.specular.is_some() && b.metal.is_none() && b.diffuse.is_some());
        let b = Bsdf::principled(&PrincipledParams {
            specular_ior_level: 0.0,
            ..p
        });
        assert!(b.specular.is_none());
        let b = Bsdf::principled(&PrincipledParams { metallic: 1.0, ..p });
        assert!(b.specular.is_none() && b.metal.is_some());
        let l = b.lobes(Vec3::Z);
        assert_eq!(l.diffuse_sample, 0.0);
    }
}
