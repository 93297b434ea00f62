//! Light sources: sun (delta or of finite angular diameter), point, spot, and
//! the environment (constant or an equirectangular HDR map, importance
//! sampled).
//!
//! Conventions, as in Blender/Cycles (checked against Cycles 5.0.1 with
//! `scripts/cycles_render.py`; figures in `scripts/README.md`):
//! - a sun's `irradiance` E is W/m² on a surface facing it. With angular
//!   diameter θ > 0 it is a uniform disk of radiance L = E / (π sin²(θ/2)),
//!   which gives exactly E on a surface facing it (∫ L cos dω over the cone);
//! - point and spot `intensity` is W/sr (radiant intensity on the axis);
//!   Blender's light Power P in W is P/(4π) W/sr, for spots too (the power
//!   is not concentrated into the cone);
//! - a spot's cone is its full angle; `blend` softens the edge with
//!   smoothstep over the outer `blend` fraction of (1 − cos(half angle)), as
//!   Cycles' `spot_attenuation`;
//! - a sun is not visible to camera rays (Cycles' default for new lights);
//! - the environment map is equirectangular, Z up, with Blender's mapping
//!   (Cycles' `direction_to_equirectangular`, checked against a Cycles
//!   5.0.1 render of a map whose texels encode their coordinates: +X sees
//!   the map's centre, +Y u = ¼) u = ½ − atan2(y, x)/(2π),
//!   v = atan2(z, hypot(x, y))/π + ½, rotated
//!   about +Z by `rotate_z`.

use crate::sampling::{self, Distribution2D};
use crate::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// A light sample seen from a point.
#[derive(Debug, Clone, Copy)]
pub struct LightSample {
    /// Unit direction from the point towards the light.
    pub wi: Vec3,
    /// Incident radiance (for delta lights: irradiance-like, the value that
    /// multiplies the phase function directly).
    pub li: Rgb,
    /// Solid-angle density of `wi` (1 for delta lights).
    pub pdf: f32,
    /// Distance to the light (infinite for distant lights).
    pub dist: f32,
    pub is_delta: bool,
}

#[derive(Debug, Clone)]
pub enum Light {
    Sun {
        /// Unit, towards the light.
        dir: Vec3,
        /// Irradiance for a delta sun, radiance for a disk.
        value: Rgb,
        /// cos of the half angle (1 for a delta sun).
        cos_max: f32,
        frame: (Vec3, Vec3),
    },
    Point {
        position: Vec3,
        intensity: Rgb,
    },
    Spot {
        position: Vec3,
        /// Unit cone axis, from the light into the scene.
        axis: Vec3,
        intensity: Rgb,
        cos_half: f32,
        /// Width of the smooth edge in cos units.
        smooth: f32,
    },
}

impl Light {
    pub fn sun(direction: Vec3, irradiance: Rgb, angle_deg: f32) -> Self {
        let dir = direction.normalize();
        let half = (angle_deg.to_radians() * 0.5).clamp(0.0, PI * 0.5);
        let frame = sampling::coordinate_system(dir);
        if half <= 0.0 {
            Light::Sun {
                dir,
                value: irradiance,
                cos_max: 1.0,
                frame,
            }
        } else {
            let s = half.sin();
            Light::Sun {
                dir,
                value: irradiance / (PI * s * s),
                cos_max: half.cos(),
                frame,
            }
        }
    }

    pub fn spot(
        position: Vec3,
        direction: Vec3,
        intensity: Rgb,
        cone_deg: f32,
        blend: f32,
    ) -> Self {
        let cos_half = (cone_deg.to_radians() * 0.5).cos();
        Light::Spot {
            position,
            axis: direction.normalize(),
            intensity,
            cos_half,
            smooth: (1.0 - cos_half) * blend.clamp(0.0, 1.0),
        }
    }

    pub fn is_delta(&self) -> bool {
        match self {
            Light::Sun { cos_max, .. } => *cos_max >= 1.0,
            _ => true,
        }
    }

    /// Samples a direction towards the light from `p`.
    pub fn sample_li(&self, p: Vec3, u: Vec2) -> Option<LightSample> {
        match *self {
            Light::Sun {
                dir,
                value,
                cos_max,
                frame,
            } => {
                if cos_max >= 1.0 {
                    return Some(LightSample {
                        wi: dir,
                        li: value,
                        pdf: 1.0,
                        dist: f32::INFINITY,
                        is_delta: true,
                    });
                }
                let local = sampling::sample_uniform_cone(u, cos_max);
                let wi = (frame.0 * local.x + frame.1 * local.y + dir * local.z).normalize();
                Some(LightSample {
                    wi,
                    li: value,
                    pdf: sampling::uniform_cone_pdf(cos_max),
                    dist: f32::INFINITY,
                    is_delta: false,
                })
            }
            Light::Point {
                position,
                intensity,
            } => point_sample(position, p, intensity),
            Light::Spot {
                position,
                axis,
                intensity,
                cos_half,
                smooth,
            } => {
                let mut ls = point_sample(position, p, intensity)?;
                let falloff = spot_falloff((-ls.wi).dot(axis), cos_half, smooth);
                if falloff <= 0.0 {
                    return None;
                }
                ls.li *= falloff;
                Some(ls)
            }
        }
    }

    /// Radiance a ray leaving the scene in direction `w` receives from this
    /// light, and the solid-angle density `sample_li` has for `w` (for MIS).
    /// Zero for delta lights (no ray can hit them).
    pub fn le_escaped(&self, w: Vec3) -> (Rgb, f32) {
        match *self {
            Light::Sun {
                dir,
                value,
                cos_max,
                ..
            } if cos_max < 1.0 && w.dot(dir) >= cos_max => {
                (value, sampling::uniform_cone_pdf(cos_max))
            }
            _ => (Rgb::ZERO, 0.0),
        }
    }
}

/// A sphere around everything that can interact with light (the volumes'
/// bounds): lights at infinity emit photons from a disk of its radius, and
/// point lights aim at it ([`Beyond`] for the surfaces around it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundingSphere {
    pub center: Vec3,
    pub radius: f32,
}

impl BoundingSphere {
    /// The sphere through the corners of the box `[lo, hi]`.
    pub fn of_box(lo: Vec3, hi: Vec3) -> Self {
        Self {
            center: (lo + hi) * 0.5,
            radius: ((hi - lo).length() * 0.5).max(1e-6),
        }
    }

    /// A ray arriving from direction `w` (pointing away from the scene,
    /// towards the source): its origin on the disk of the sphere's radius
    /// perpendicular to `w`, outside the sphere, and the disk's area.
    fn disk_ray(&self, w: Vec3, u: Vec2) -> (Vec3, f32) {
        let (t, b) = sampling::coordinate_system(w);
        let q = sampling::sample_uniform_disk_concentric(u) * self.radius;
        let o = self.center + w * (2.0 * self.radius) + t * q.x + b * q.y;
        (o, PI * self.radius * self.radius)
    }
}

/// The light that misses the volumes but may still reach them by a
/// surface: rays through the sphere `outer` (around the volumes and every
/// surface that reflects) that miss `inner` (around the volumes), which
/// [`Light::sample_le`] leaves out. A ground far wider than the smoke
/// reflects light into it from everywhere under it; photons aimed at the
/// volumes alone never carry that light (it was 6 % of the smoke's
/// brightness over issue 50's grey ground).
///
/// Lights at infinity emit into the annulus around `inner`'s disk that
/// covers `outer`'s, with a radius ρ log-uniform between the two (density
/// ∝ 1/ρ² over the annulus): the share of a ground point's reflection
/// that reaches the volumes falls as 1/ρ², so each photon carries about as
/// much of that light wherever it lands, and a ground a hundred times the
/// smoke's size costs no more photons than one twice its size. Point
/// lights emit into the zone of directions between the cone around
/// `inner` and the one around `outer`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Beyond {
    pub inner: BoundingSphere,
    pub outer: BoundingSphere,
}

impl Beyond {
    /// The annulus' outer radius around the inner sphere's centre: enough
    /// to cover the outer sphere's disk from any direction.
    fn reach(&self) -> f32 {
        self.outer.radius + (self.outer.center - self.inner.center).length()
    }

    /// The annulus' area.
    fn area(&self) -> f32 {
        let (r0, r1) = (self.inner.radius, self.reach());
        PI * (r1 * r1 - r0 * r0).max(0.0)
    }

    /// A ray arriving from direction `w` through the annulus (log-uniform
    /// radius, uniform angle), its origin beyond everything in `outer`, and
    /// the inverse of its density per unit area.
    fn annulus_ray(&self, w: Vec3, u: Vec2) -> (Vec3, f32) {
        let (r0, r1) = (self.inner.radius, self.reach());
        let l = (r1 / r0).ln();
        let rho = r0 * (l * u.x).exp();
        let phi = 2.0 * PI * u.y;
        let (t, b) = sampling::coordinate_system(w);
        let o = self.inner.center + w * (2.0 * r1) + t * (rho * phi.cos()) + b * (rho * phi.sin());
        (o, 2.0 * PI * rho * rho * l)
    }

    /// The zone of directions from `position` between the cone around
    /// `inner` and the one around `outer`, as (cos of its inner edge, cos
    /// of its outer edge, axis); `None` when it is empty (the point inside
    /// `inner`).
    fn zone(&self, position: Vec3) -> Option<(f32, f32, Vec3)> {
        let cos_in = point_cone(position, self.inner)?;
        let axis = (self.inner.center - position).normalize();
        let cos_out = match point_cone(position, self.outer) {
            None => -1.0,
            Some(c) => {
                let to = (self.outer.center - position).normalize();
                let angle = axis.dot(to).clamp(-1.0, 1.0).acos() + c.clamp(-1.0, 1.0).acos();
                angle.min(PI).cos()
            }
        };
        (cos_out < cos_in).then_some((cos_in, cos_out, axis))
    }
}

/// A photon leaving a light (pbrt-v4's `SampleLe`): where it starts, its
/// unit direction of travel, and its power divided by the density of the
/// sample (the estimate of the light's power this one sample makes).
#[derive(Debug, Clone, Copy)]
pub struct EmittedRay {
    pub o: Vec3,
    pub d: Vec3,
    pub power: Rgb,
}

impl Light {
    /// The power (W) the light sends towards `bounds` as [`Self::sample_le`]
    /// samples it (pbrt-v4's `Phi`): a sun through a disk of the sphere's
    /// radius, a point light into the cone around the sphere (everywhere
    /// when it is inside), a spot into its cone.
    pub fn power(&self, bounds: BoundingSphere) -> Rgb {
        let area = PI * bounds.radius * bounds.radius;
        match *self {
            Light::Sun { value, cos_max, .. } => {
                if cos_max >= 1.0 {
                    value * area
                } else {
                    value * (area * 2.0 * PI * (1.0 - cos_max))
                }
            }
            Light::Point {
                position,
                intensity,
            } => {
                intensity * point_cone(position, bounds).map_or(4.0 * PI, |c| 2.0 * PI * (1.0 - c))
            }
            Light::Spot {
                intensity,
                cos_half,
                smooth,
                ..
            } => {
                // ∫ falloff dω: full inside the inner cone, the smoothstep
                // (mean ½ over its width) across the edge.
                intensity * (2.0 * PI * ((1.0 - cos_half) - 0.5 * smooth))
            }
        }
    }

    /// Samples a photon leaving the light towards `bounds` from four
    /// uniform numbers.
    pub fn sample_le(&self, bounds: BoundingSphere, u: Vec2, v: Vec2) -> Option<EmittedRay> {
        match *self {
            Light::Sun {
                dir,
                value,
                cos_max,
                frame,
            } => {
                let (w, power_per_area) = sun_direction(dir, value, cos_max, frame, v);
                let (o, area) = bounds.disk_ray(w, u);
                Some(EmittedRay {
                    o,
                    d: -w,
                    power: power_per_area * area,
                })
            }
            Light::Point {
                position,
                intensity,
            } => {
                let (d, pdf) = match point_cone(position, bounds) {
                    Some(cos_max) => {
                        let axis = (bounds.center - position).normalize();
                        let (t, b) = sampling::coordinate_system(axis);
                        let l = sampling::sample_uniform_cone(u, cos_max);
                        (
                            (t * l.x + b * l.y + axis * l.z).normalize(),
                            sampling::uniform_cone_pdf(cos_max),
                        )
                    }
                    None => (
                        sampling::sample_uniform_sphere(u),
                        sampling::uniform_sphere_pdf(),
                    ),
                };
                Some(EmittedRay {
                    o: position,
                    d,
                    power: intensity / pdf,
                })
            }
            Light::Spot {
                position,
                axis,
                intensity,
                cos_half,
                smooth,
            } => {
                let (t, b) = sampling::coordinate_system(axis);
                let l = sampling::sample_uniform_cone(u, cos_half);
                let d = (t * l.x + b * l.y + axis * l.z).normalize();
                let falloff = spot_falloff(l.z, cos_half, smooth);
                (falloff > 0.0).then(|| EmittedRay {
                    o: position,
                    d,
                    power: intensity * (falloff / sampling::uniform_cone_pdf(cos_half)),
                })
            }
        }
    }
}

impl Light {
    /// The power (W) the light sends into `beyond` as
    /// [`Self::sample_le_beyond`] samples it: a sun through the whole
    /// annulus, a point light into the zone; a spot's photons already fill
    /// its cone ([`Self::sample_le`]), so none.
    pub fn power_beyond(&self, beyond: Beyond) -> Rgb {
        match *self {
            Light::Sun { value, cos_max, .. } => {
                let area = beyond.area();
                if cos_max >= 1.0 {
                    value * area
                } else {
                    value * (area * 2.0 * PI * (1.0 - cos_max))
                }
            }
            Light::Point {
                position,
                intensity,
            } => beyond
                .zone(position)
                .map_or(Rgb::ZERO, |(ci, co, _)| intensity * (2.0 * PI * (ci - co))),
            Light::Spot { .. } => Rgb::ZERO,
        }
    }

    /// Samples a photon leaving the light into `beyond` from four uniform
    /// numbers (see [`Beyond`]).
    pub fn sample_le_beyond(&self, beyond: Beyond, u: Vec2, v: Vec2) -> Option<EmittedRay> {
        match *self {
            Light::Sun {
                dir,
                value,
                cos_max,
                frame,
            } => {
                let (w, power_per_area) = sun_direction(dir, value, cos_max, frame, v);
                let (o, inv_pdf) = beyond.annulus_ray(w, u);
                Some(EmittedRay {
                    o,
                    d: -w,
                    power: power_per_area * inv_pdf,
                })
            }
            Light::Point {
                position,
                intensity,
            } => {
                let (cos_in, cos_out, axis) = beyond.zone(position)?;
                let z = cos_in + (cos_out - cos_in) * u.x;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                let (t, b) = sampling::coordinate_system(axis);
                let d = (t * (r * phi.cos()) + b * (r * phi.sin()) + axis * z).normalize();
                Some(EmittedRay {
                    o: position,
                    d,
                    power: intensity * (2.0 * PI * (cos_in - cos_out)),
                })
            }
            Light::Spot { .. } => None,
        }
    }
}

/// A sun photon's direction towards the light (uniform in the sun's cone
/// from `v`, or its direction for a delta sun) and its power per unit area
/// of the disk it crosses: the irradiance over the direction's density.
fn sun_direction(dir: Vec3, value: Rgb, cos_max: f32, frame: (Vec3, Vec3), v: Vec2) -> (Vec3, Rgb) {
    if cos_max >= 1.0 {
        (dir, value)
    } else {
        let l = sampling::sample_uniform_cone(v, cos_max);
        let w = (frame.0 * l.x + frame.1 * l.y + dir * l.z).normalize();
        (w, value / sampling::uniform_cone_pdf(cos_max))
    }
}

/// cos of the half angle of the cone from `position` around `bounds`, or
/// `None` when the point is inside the sphere.
fn point_cone(position: Vec3, bounds: BoundingSphere) -> Option<f32> {
    let d2 = (bounds.center - position).length_squared();
    let r2 = bounds.radius * bounds.radius;
    (d2 > r2).then(|| (1.0 - r2 / d2).max(0.0).sqrt())
}

/// A spot's falloff at `cos` from its axis: smoothstep over the outer
/// `smooth` (in cos units) of the cone, as Cycles' `spot_attenuation`.
fn spot_falloff(cos: f32, cos_half: f32, smooth: f32) -> f32 {
    if cos <= cos_half {
        return 0.0;
    }
    let t = cos - cos_half;
    if smooth > 0.0 && t < smooth {
        let x = t / smooth;
        x * x * (3.0 - 2.0 * x)
    } else {
        1.0
    }
}

/// The sample of an isotropic point source of `intensity` at `position`
/// seen from `p` (inverse-square falloff).
fn point_sample(position: Vec3, p: Vec3, intensity: Rgb) -> Option<LightSample> {
    let v = position - p;
    let d2 = v.length_squared();
    if d2 <= 0.0 {
        return None;
    }
    let dist = d2.sqrt();
    Some(LightSample {
        wi: v / dist,
        li: intensity / d2,
        pdf: 1.0,
        dist,
        is_delta: true,
    })
}

/// What rays that leave every volume see.
#[derive(Debug, Clone)]
pub enum Environment {
    Constant(Rgb),
    Map(Box<EnvMap>),
}

/// An equirectangular HDR environment, importance sampled by luminance times
/// sin θ (the Jacobian of the lat-long mapping; pbrt-v4 §12.5.2).
#[derive(Debug, Clone)]
pub struct EnvMap {
    width: usize,
    height: usize,
    texels: Vec<Rgb>,
    distribution: Distribution2D,
    /// Radians, about +Z.
    rotate_z: f32,
    /// ∫ Le dω over the sphere.
    integral: Rgb,
}

fn luminance(c: Rgb) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

impl EnvMap {
    /// `texels` row-major, top row first (v = 1 at the top, +Z up), already
    /// multiplied by the strength.
    pub fn new(width: usize, height: usize, texels: Vec<Rgb>, rotate_z_deg: f32) -> Self {
        let mut f = Vec::with_capacity(width * height);
        for y in 0..height {
            // Row y covers polar angle θ from y/h·π to (y+1)/h·π (top = +Z).
            let sin_theta = ((y as f32 + 0.5) / height as f32 * PI).sin();
            for x in 0..width {
                f.push(luminance(texels[y * width + x]).max(0.0) * sin_theta);
            }
        }
        let distribution = Distribution2D::new(&f, width, height);
        // Each texel covers (2π / w) in φ and the band of its row in θ:
        // solid angle (2π / w)·(cos θ0 − cos θ1).
        let mut integral = Rgb::ZERO;
        for y in 0..height {
            let c0 = (y as f32 / height as f32 * PI).cos();
            let c1 = ((y + 1) as f32 / height as f32 * PI).cos();
            let omega = 2.0 * PI / width as f32 * (c0 - c1);
            for x in 0..width {
                integral += texels[y * width + x] * omega;
            }
        }
        Self {
            width,
            height,
            texels,
            distribution,
            rotate_z: rotate_z_deg.to_radians(),
            integral,
        }
    }

    /// Map coordinates (u right, v down from the top) of a world direction.
    fn uv(&self, w: Vec3) -> Vec2 {
        let (s, c) = (-self.rotate_z).sin_cos();
        let x = c * w.x - s * w.y;
        let y = s * w.x + c * w.y;
        let u = 0.5 - y.atan2(x) / (2.0 * PI);
        let v = w.z.atan2(x.hypot(y)) / PI + 0.5;
        Vec2::new(u.rem_euclid(1.0), (1.0 - v).clamp(0.0, 1.0))
    }

    fn direction(&self, uv: Vec2) -> Vec3 {
        let phi = (0.5 - uv.x) * 2.0 * PI;
        let elevation = (0.5 - uv.y) * PI;
        // Inverse of uv(): atan2(y, x) = phi.
        let (sp, cp) = phi.sin_cos();
        let (se, ce) = elevation.sin_cos();
        let x = cp * ce;
        let y = sp * ce;
        let (s, c) = self.rotate_z.sin_cos();
        Vec3::new(c * x - s * y, s * x + c * y, se)
    }

    fn lookup(&self, uv: Vec2) -> Rgb {
        let x = ((uv.x * self.width as f32) as usize).min(self.width - 1);
        let y = ((uv.y * self.height as f32) as usize).min(self.height - 1);
        self.texels[y * self.width + x]
    }
}

impl Environment {
    pub fn is_black(&self) -> bool {
        match self {
            Environment::Constant(c) => c.max_element() <= 0.0,
            Environment::Map(_) => false,
        }
    }

    /// Radiance arriving from direction `w` (pointing away from the scene).
    pub fn le(&self, w: Vec3) -> Rgb {
        match self {
            Environment::Constant(c) => *c,
            Environment::Map(m) => m.lookup(m.uv(w)),
        }
    }

    /// Samples a direction; returns (w, radiance, solid-angle pdf).
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, Rgb, f32)> {
        match self {
            Environment::Constant(c) => Some((
                sampling::sample_uniform_sphere(u),
                *c,
                sampling::uniform_sphere_pdf(),
            )),
            Environment::Map(m) => {
                let (uv, pdf_uv) = m.distribution.sample(u);
                if pdf_uv <= 0.0 {
                    return None;
                }
                let theta = uv.y * PI;
                let sin_theta = theta.sin();
                if sin_theta <= 0.0 {
                    return None;
                }
                let w = m.direction(uv);
                Some((w, m.lookup(uv), pdf_uv / (2.0 * PI * PI * sin_theta)))
            }
        }
    }

    /// ∫ Le dω over the sphere (W·m⁻² on a surface facing every
    /// direction at once): what a disk of unit area receives.
    pub fn radiance_integral(&self) -> Rgb {
        match self {
            Environment::Constant(c) => *c * (4.0 * PI),
            Environment::Map(m) => m.integral,
        }
    }

    /// The power the environment sends through a disk of `bounds`' radius
    /// per direction (what [`Self::sample_le`] samples).
    pub fn power(&self, bounds: BoundingSphere) -> Rgb {
        self.radiance_integral() * (PI * bounds.radius * bounds.radius)
    }

    /// Samples a photon arriving from the environment: a direction by
    /// [`Self::sample`], then a point on the disk perpendicular to it.
    pub fn sample_le(&self, bounds: BoundingSphere, u: Vec2, v: Vec2) -> Option<EmittedRay> {
        let (w, le, pdf) = self.sample(v)?;
        if pdf <= 0.0 {
            return None;
        }
        let (o, area) = bounds.disk_ray(w, u);
        Some(EmittedRay {
            o,
            d: -w,
            power: le * (area / pdf),
        })
    }

    /// The power the environment sends through the annulus of `beyond`
    /// per direction (what [`Self::sample_le_beyond`] samples).
    pub fn power_beyond(&self, beyond: Beyond) -> Rgb {
        self.radiance_integral() * beyond.area()
    }

    /// Samples a photon arriving from the environment into `beyond`: a
    /// direction by [`Self::sample`], then a point of the annulus.
    pub fn sample_le_beyond(&self, beyond: Beyond, u: Vec2, v: Vec2) -> Option<EmittedRay> {
        let (w, le, pdf) = self.sample(v)?;
        if pdf <= 0.0 {
            return None;
        }
        let (o, inv_pdf) = beyond.annulus_ray(w, u);
        Some(EmittedRay {
            o,
            d: -w,
            power: le * (inv_pdf / pdf),
        })
    }

    /// Solid-angle density of `sample` for direction `w`.
    pub fn pdf(&self, w: Vec3) -> f32 {
        match self {
            Environment::Constant(_) => sampling::uniform_sphere_pdf(),
            Environment::Map(m) => {
                let uv = m.uv(w);
                let sin_theta = (uv.y * PI).sin();
                if sin_theta <= 0.0 {
                    return 0.0;
                }
                m.distribution.pdf(uv) / (2.0 * PI * PI * sin_theta)
            }
        }
    }
}
