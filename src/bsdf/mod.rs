//! PLACEHOLDER until the bsdf branch lands: Lambert only, with the API
//! the integrators use.

use crate::sampling::sample_cosine_hemisphere;
use crate::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrincipledParams {
    pub base_color: Rgb,
    pub roughness: f32,
    pub metallic: f32,
    pub ior: f32,
    pub specular_ior_level: f32,
    pub specular_tint: Rgb,
}

#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BsdfValue {
    pub diffuse: Rgb,
    pub glossy: Rgb,
}

impl BsdfValue {
    pub fn sum(&self) -> Rgb {
        self.diffuse + self.glossy
    }
}

#[derive(Debug, Clone, Copy)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub f: BsdfValue,
    pub pdf: f32,
    pub glossy: bool,
}

#[derive(Debug, Clone, Copy)]
pub struct Bsdf {
    color: Rgb,
}

impl Bsdf {
    pub fn principled(p: &PrincipledParams) -> Bsdf {
        Bsdf {
            color: p.base_color,
        }
    }
    pub fn diffuse(color: Rgb, _roughness: f32) -> Bsdf {
        Bsdf { color }
    }
    pub fn f(&self, wo: Vec3, wi: Vec3) -> BsdfValue {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return BsdfValue::default();
        }
        BsdfValue {
            diffuse: self.color * FRAC_1_PI,
            glossy: Rgb::ZERO,
        }
    }
    pub fn sample(&self, wo: Vec3, _uc: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = sample_cosine_hemisphere(u);
        if wi.z <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            f: self.f(wo, wi),
            pdf: wi.z * FRAC_1_PI,
            glossy: false,
        })
    }
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            0.0
        } else {
            wi.z * FRAC_1_PI
        }
    }
    pub fn albedo(&self) -> Rgb {
        self.color
    }
}
