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
//! smoke shader drove emission by the flame attribute).

use super::blackbody::blackbody_rgb_cycles;
use super::MediumPoint;
use crate::phase::PhaseFunction;
use crate::scene::{MaterialDesc, PhaseDesc};
use crate::Rgb;

/// σ_SB · 10⁻⁶ / π, Cycles' blackbody intensity scale.
const BLACKBODY_SCALE: f32 = 5.670_373e-8 * 1e-6 / std::f32::consts::PI;

/// The inputs of Blender's Principled Volume node, with its names, units
/// and defaults (the scene description uses this type too).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Principled {
    pub density: f32,
    pub color: Rgb,
    pub absorption_color: Rgb,
    /// Henyey–Greenstein g.
    pub anisotropy: f32,
    pub emission_strength: f32,
    pub emission_color: Rgb,
    pub blackbody_intensity: f32,
    pub blackbody_tint: Rgb,
    /// Kelvin.
    pub temperature: f32,
}

impl Principled {
    /// Blender's defaults.
    pub const DEFAULT: Principled = Principled {
        density: 1.0,
        color: Rgb::splat(0.5),
        absorption_color: Rgb::ZERO,
        anisotropy: 0.0,
        emission_strength: 0.0,
        emission_color: Rgb::ONE,
        blackbody_intensity: 0.0,
        blackbody_tint: Rgb::ONE,
        temperature: 1000.0,
    };
}

impl Default for Principled {
    fn default() -> Self {
        Self::DEFAULT
    }
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
        let m = self.coefficients(1.0, None, None, None);
        (m.sigma_s, m.sigma_t())
    }

    /// The optics at a point, from the grid values there (`density` already
    /// clamped to ≥ 0).
    #[inline]
    pub fn coefficients(
        &self,
        density: f32,
        temperature: Option<f32>,
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
                blackbody_intensity,
                blackbody_tint,
                temperature: t0,
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
                if *blackbody_intensity > 0.0 && (temperature.is_some() || density > 0.0) {
                    let t = (t0 * temperature.map_or(1.0, |x| x.max(0.0))).max(0.0);
                    let t4 = (t * t) * (t * t);
                    let intensity = BLACKBODY_SCALE * (1.0 + (t4 - 1.0) * blackbody_intensity);
                    if intensity > 0.0 {
                        emission += *blackbody_tint * intensity * blackbody_rgb_cycles(t);
                    }
                }
                MediumPoint {
                    sigma_a,
                    sigma_s,
                    emission,
                }
            }
        }
    }
}
