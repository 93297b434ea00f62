//! Materials: Blender's Principled Volume, evaluated exactly as Cycles'
//! `svm_node_principled_volume` (`kernel/svm/closure.h`), or raw
//! coefficients per unit density.
//!
//! Principled Volume, with D = Density · max(density attribute, 0), C =
//! Color (times the colour attribute when there is one), A = Absorption
//! Color:
//! - σs = D·C, σa = D·max(1 − C, 0)·max(1 − √A, 0) (per channel);
//! - phase: Henyey–Greenstein with g = Anisotropy;
//! - emission (radiance added per unit length, not multiplied by the
//!   density) = Emission Strength · Emission Color, plus blackbody: T =
//!   Temperature · max(temperature attribute, 0), intensity =
//!   (σ_SB · 10⁻⁶ / π) · mix(1, T⁴, Blackbody Intensity), colour = Blackbody
//!   Tint · intensity · [`blackbody_rgb_cycles`](super::blackbody)(T); each
//!   part only when its strength is > 0.
//!
//! Where Cycles evaluates the shader is the volume mesh it builds around the
//! grids' active voxels; constant emission (Emission Strength) therefore
//! glows there even where the density is 0. We apply it where the density
//! attribute is > 0, which is the same region for fog volumes (whose active
//! voxels are those with density > 0) up to the boundary voxels. A
//! `flame_grid`, when given, multiplies the Emission Strength (Blender 2.8's
//! smoke shader drove emission by the flame attribute). Blackbody emission
//! from a temperature grid does not depend on the density at all: flame
//! glows where there is no smoke.
//!
//! Cycles 5 samples volume grids by stochastic one-tap interpolation (one
//! voxel picked with the trilinear weights as probabilities, its
//! `kernel/image.h`), so a term that is nonlinear in an attribute sees voxel
//! values: blackbody emission's mean is Σ wᵢ·Le(Tᵢ), not Le(Σ wᵢ·Tᵢ). With
//! [`BlackbodyFilter::Emission`] (the default) the renderer computes that
//! mean deterministically: it interpolates the radiance computed per voxel
//! ([`Material::blackbody_radiance`]) rather than the temperature.

use super::blackbody::blackbody_rgb_cycles;
use super::MediumPoint;
use crate::phase::PhaseFunction;
pub use crate::scene::{BlackbodyFilter, Principled};
use crate::scene::{MaterialDesc, PhaseDesc};
use crate::Rgb;

/// σ_SB · 10⁻⁶ / π, Cycles' blackbody intensity scale.
const BLACKBODY_SCALE: f32 = 5.670_373e-8 * 1e-6 / std::f32::consts::PI;

/// What the blackbody term sees at a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Temperature {
    /// No temperature grid: the material's Temperature wherever the density
    /// is > 0.
    Uniform,
    /// The interpolated temperature attribute (units of the material's
    /// Temperature, as Blender's).
    Attribute(f32),
    /// Blackbody radiance interpolated from per-voxel values
    /// ([`BlackbodyFilter::Emission`]).
    Radiance(Rgb),
}

#[derive(Debug, Clone, PartialEq)]
pub enum Material {
    Principled(Principled),
    /// Coefficients per unit of the density attribute (per world unit).
    Raw {
        sigma_a: Rgb,
        sigma_s: Rgb,
        emission: Rgb,
        phase: PhaseFunction,
    },
}

impl Material {
    pub fn from_desc(d: &MaterialDesc) -> Self {
        match d {
            MaterialDesc::Principled(p) => Material::Principled(*p),
            MaterialDesc::Raw {
                sigma_a,
                sigma_s,
                emission,
                phase,
            } => Material::Raw {
                sigma_a: *sigma_a,
                sigma_s: *sigma_s,
                emission: *emission,
                phase: match phase {
                    PhaseDesc::Isotropic => PhaseFunction::Isotropic,
                    PhaseDesc::Hg { g } => PhaseFunction::hg(*g),
                    PhaseDesc::Schlick { g } => PhaseFunction::schlick_from_g(*g),
                    // Validated by the scene module (weights ≥ 0, sum > 0).
                    PhaseDesc::HgMix(lobes) => {
                        PhaseFunction::hg_mix(lobes).unwrap_or(PhaseFunction::Isotropic)
                    }
                    PhaseDesc::FournierForand { backscatter, ior } => {
                        PhaseFunction::fournier_forand(*backscatter, *ior)
                    }
                    PhaseDesc::Draine { g, alpha } => PhaseFunction::draine(*g, *alpha),
                    PhaseDesc::Rayleigh => PhaseFunction::Rayleigh,
                    PhaseDesc::Mie { diameter } => PhaseFunction::mie(*diameter),
                },
            },
        }
    }

    pub fn phase(&self) -> PhaseFunction {
        match self {
            Material::Principled(Principled { anisotropy, .. }) => PhaseFunction::hg(*anisotropy),
            Material::Raw { phase, .. } => *phase,
        }
    }

    /// Whether the blackbody term is on (Cycles adds it only when Blackbody
    /// Intensity > 0).
    pub fn has_blackbody(&self) -> bool {
        matches!(self, Material::Principled(Principled { blackbody_intensity, .. }) if *blackbody_intensity > 0.0)
    }

    /// Blackbody radiance per unit length for temperature attribute `attr`
    /// (Cycles' formula: T = Temperature·max(attr, 0), intensity
    /// (σ_SB·10⁻⁶/π)·mix(1, T⁴, Blackbody Intensity), colour Tint ·
    /// blackbody_rgb(T)); zero without the term.
    pub fn blackbody_radiance(&self, attr: f32) -> Rgb {
        let Material::Principled(Principled {
            blackbody_intensity,
            blackbody_tint,
            temperature: t0,
            ..
        }) = self
        else {
            return Rgb::ZERO;
        };
        if *blackbody_intensity <= 0.0 {
            return Rgb::ZERO;
        }
        let t = (t0 * attr.max(0.0)).max(0.0);
        let t4 = (t * t) * (t * t);
        let intensity = BLACKBODY_SCALE * (1.0 + (t4 - 1.0) * blackbody_intensity);
        if intensity > 0.0 {
            *blackbody_tint * intensity * blackbody_rgb_cycles(t)
        } else {
            Rgb::ZERO
        }
    }

    /// An upper bound of the blackbody radiance's largest channel for
    /// temperature attributes in `[lo, hi]`. Only where the bound is 0 may
    /// a tracker skip emission, so it needs to be positive wherever the
    /// radiance is; its size only sets how densely emission is sampled.
    /// Taken over 65 temperatures spread over the range (the radiance is
    /// smooth in T), with 5 % to spare.
    pub fn blackbody_bound(&self, lo: f32, hi: f32) -> f32 {
        if !self.has_blackbody() {
            return 0.0;
        }
        let (lo, hi) = (lo.max(0.0), hi.max(lo.max(0.0)));
        let m = (0..=64)
            .map(|i| {
                let a = lo + (hi - lo) * i as f32 / 64.0;
                self.blackbody_radiance(a).max_element()
            })
            .fold(0.0f32, f32::max);
        m * 1.05
    }

    /// Largest channel of the emission that does not come from a
    /// temperature (Emission Strength × Color, raw emission), per unit of
    /// the density (raw) or of the flame attribute (Principled, 1 without a
    /// flame grid).
    pub fn plain_emission_max(&self) -> f32 {
        match self {
            Material::Principled(Principled {
                emission_strength,
                emission_color,
                ..
            }) => {
                if *emission_strength > 0.0 {
                    emission_strength * emission_color.max_element().max(0.0)
                } else {
                    0.0
                }
            }
            Material::Raw { emission, .. } => emission.max_element().max(0.0),
        }
    }

    pub fn is_emissive(&self) -> bool {
        match self {
            Material::Principled(Principled {
                emission_strength,
                emission_color,
                blackbody_intensity,
                ..
            }) => {
                (*emission_strength > 0.0 && emission_color.max_element() > 0.0)
                    || *blackbody_intensity > 0.0
            }
            Material::Raw { emission, .. } => emission.max_element() > 0.0,
        }
    }

    /// An upper bound of max-channel σt per unit of the density attribute,
    /// given the largest colour-attribute component (if there is one).
    pub fn sigma_t_bound_per_density(&self, color_max: Option<f32>) -> f32 {
        match self {
            Material::Principled(Principled {
                density,
                color,
                absorption_color,
                ..
            }) => {
                let d = density.max(0.0);
                match color_max {
                    // σt = D(C c + max(1 − C c, 0)·a) with a ≤ 1: at most
                    // D·max(1, C c) per channel.
                    Some(m) => d * (color.max_element() * m).max(1.0),
                    None => {
                        let a = (Rgb::ONE - absorption_color.max(Rgb::ZERO).map(f32::sqrt))
                            .max(Rgb::ZERO);
                        let st = *color + (Rgb::ONE - *color).max(Rgb::ZERO) * a;
                        d * st.max_element()
                    }
                }
            }
            Material::Raw {
                sigma_a, sigma_s, ..
            } => (*sigma_a + *sigma_s).max_element().max(0.0),
        }
    }

    /// Per unit of the density attribute, without a colour attribute:
    /// `(sigma_s, sigma_t)` when the coefficients are proportional to the
    /// density (always, for both kinds), so that the albedo is the same
    /// wherever the density is > 0.
    pub fn coefficients_per_density(&self) -> (Rgb, Rgb) {
        let m = self.coefficients(1.0, Temperature::Uniform, None, None);
        (m.sigma_s, m.sigma_t())
    }

    /// The optics at a point, from the grid values there (`density` already
    /// clamped to ≥ 0).
    #[inline]
    pub fn coefficients(
        &self,
        density: f32,
        temperature: Temperature,
        flame: Option<f32>,
        color_attr: Option<Rgb>,
    ) -> MediumPoint {
        match self {
            Material::Raw {
                sigma_a,
                sigma_s,
                emission,
                ..
            } => MediumPoint {
                sigma_a: *sigma_a * density,
                sigma_s: *sigma_s * density,
                emission: *emission * density,
            },
            Material::Principled(Principled {
                density: d0,
                color,
                absorption_color,
                emission_strength,
                emission_color,
                ..
            }) => {
                let d = (d0 * density).max(0.0);
                let c = match color_attr {
                    Some(a) => *color * a,
                    None => *color,
                };
                let sigma_s = c * d;
                let a = (Rgb::ONE - absorption_color.max(Rgb::ZERO).map(f32::sqrt)).max(Rgb::ZERO);
                let sigma_a = (Rgb::ONE - c).max(Rgb::ZERO) * a * d;
                let mut emission = Rgb::ZERO;
                if *emission_strength > 0.0 && density > 0.0 {
                    let s = emission_strength * flame.map_or(1.0, |f| f.max(0.0));
                    emission += *emission_color * s;
                }
                // Without a temperature grid the blackbody term is uniform
                // and, like Emission Strength, confined to the density.
                emission += match temperature {
                    Temperature::Uniform if density > 0.0 => self.blackbody_radiance(1.0),
                    Temperature::Uniform => Rgb::ZERO,
                    Temperature::Attribute(x) => self.blackbody_radiance(x),
                    Temperature::Radiance(l) => l,
                };
                MediumPoint {
                    sigma_a,
                    sigma_s,
                    emission,
                }
            }
        }
    }
}
