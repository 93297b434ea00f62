//! The optics of surfaces: a mesh's material (Blender's Principled BSDF,
//! Diffuse BSDF or Emission, `crate::scene::SurfaceDesc`) with its
//! textures loaded, turned at a point of the surface into a BSDF
//! (`crate::bsdf`, in the point's shading frame `crate::bsdf::Frame`) and
//! the radiance it emits (pbrt-v4's split:
//! shapes in `crate::shape`, the BSDF here, what light does in the
//! integrators).

use crate::bsdf::{Bsdf, PrincipledParams};
use crate::image::texture::Texture;
use crate::scene::{ColorInput, SurfaceDesc};
use crate::Rgb;
use glam::Vec2;
use std::sync::Arc;

/// A colour input with its texture loaded.
#[derive(Debug, Clone)]
pub enum Color {
    Value(Rgb),
    Texture(Arc<Texture>),
}

impl Color {
    #[inline]
    fn at(&self, uv: Vec2) -> Rgb {
        match self {
            Color::Value(c) => *c,
            Color::Texture(t) => t.lookup(uv),
        }
    }
}

/// A mesh's material, ready to shade.
#[derive(Debug, Clone)]
pub enum Surface {
    Principled {
        base_color: Color,
        params: PrincipledParams,
        emission: Rgb,
    },
    Diffuse {
        color: Color,
        roughness: f32,
    },
    Emission {
        color: Color,
        strength: f32,
    },
}

/// What a surface is at one point: its BSDF (none for a pure emitter) and
/// the radiance it emits (both sides, as Cycles' Emission).
#[derive(Debug, Clone)]
pub struct SurfacePoint {
    pub bsdf: Option<Bsdf>,
    pub emission: Rgb,
}

impl Surface {
    /// Cycles' default surface, for objects without a material: a Diffuse
    /// BSDF of colour 0.8.
    pub fn default_surface() -> Surface {
        Surface::Diffuse {
            color: Color::Value(Rgb::splat(0.8)),
            roughness: 0.0,
        }
    }

    /// The surface a description gives, `texture` loading its images (by
    /// file and colour space).
    pub fn from_desc(
        desc: &SurfaceDesc,
        mut texture: impl FnMut(&ColorInput) -> crate::Result<Option<Arc<Texture>>>,
    ) -> crate::Result<Surface> {
        let mut color = |c: &ColorInput| -> crate::Result<Color> {
            Ok(match (c, texture(c)?) {
                (ColorInput::Value(v), _) => Color::Value(*v),
                (ColorInput::Texture { .. }, Some(t)) => Color::Texture(t),
                (ColorInput::Texture { .. }, None) => Color::Value(Rgb::ZERO),
            })
        };
        Ok(match desc {
            SurfaceDesc::Principled(p) => Surface::Principled {
                base_color: color(&p.base_color)?,
                params: PrincipledParams {
                    base_color: Rgb::ZERO,
                    roughness: p.roughness,
                    metallic: p.metallic,
                    ior: p.ior,
                    specular_ior_level: p.specular_ior_level,
                    specular_tint: p.specular_tint,
                    ..PrincipledParams::default()
                },
                emission: p.emission_color * p.emission_strength,
            },
            SurfaceDesc::Diffuse {
                color: c,
                roughness,
            } => Surface::Diffuse {
                color: color(c)?,
                roughness: *roughness,
            },
            SurfaceDesc::Emission { color: c, strength } => Surface::Emission {
                color: color(c)?,
                strength: *strength,
            },
        })
    }

    /// The surface at texture coordinates `uv`.
    #[inline]
    pub fn at(&self, uv: Vec2) -> SurfacePoint {
        match self {
            Surface::Principled {
                base_color,
                params,
                emission,
            } => SurfacePoint {
                bsdf: Some(Bsdf::principled(&PrincipledParams {
                    base_color: base_color.at(uv),
                    ..*params
                })),
                emission: *emission,
            },
            Surface::Diffuse { color, roughness } => SurfacePoint {
                bsdf: Some(Bsdf::diffuse(color.at(uv), *roughness)),
                emission: Rgb::ZERO,
            },
            Surface::Emission { color, strength } => SurfacePoint {
                bsdf: None,
                emission: color.at(uv) * *strength,
            },
        }
    }

    /// Whether the surface reflects light (has a BSDF).
    pub fn reflects(&self) -> bool {
        !matches!(self, Surface::Emission { .. })
    }

    /// Whether the surface emits light anywhere.
    pub fn is_emissive(&self) -> bool {
        match self {
            Surface::Principled { emission, .. } => emission.max_element() > 0.0,
            Surface::Diffuse { .. } => false,
            Surface::Emission { strength, .. } => *strength > 0.0,
        }
    }
}
