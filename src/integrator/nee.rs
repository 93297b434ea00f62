//! Next-event estimation: light arriving at a scattering point straight
//! from the lights and the environment, through the media (pbrt-v4
//! §14.2.3, `SampleLd`). Shared by the path tracer (with multiple
//! importance sampling against phase sampling, Veach 1997) and the photon
//! integrator's marcher (single scattering, without MIS: it samples no
//! direction).

use crate::bsdf::BsdfValue;
use crate::light::{Environment, Light};
use crate::ray::Ray;
use crate::sampling::{power_heuristic, Rng};
use crate::shape::RayKind;
use crate::tracking;
use crate::world::World;
use crate::Rgb;
use glam::Vec3;

/// Which of a world's sources a path or a light sample takes, and how.
/// The photon integrator may leave the environment's light to camera paths
/// (`super::photon::Sky::Paths`): its march and photons then take the
/// lights without it, and those paths the environment alone.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sources {
    /// The lights (suns, spots, points).
    pub lights: bool,
    /// The environment.
    pub environment: EnvLight,
}

/// How a path takes the environment's light.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EnvLight {
    /// Not at all.
    Off,
    /// Sampled at each scattering event and found by the rays that escape,
    /// weighted by multiple importance sampling (an environment map, whose
    /// bright spots only light samples find well).
    Sampled,
    /// Found only by the rays that escape: no light samples. For a constant
    /// environment a light sample's shadow ray costs more than it gains
    /// (docs/performance.md, "Sky light by paths").
    Escaped,
}

impl Sources {
    /// The lights and the environment.
    pub const ALL: Sources = Sources {
        lights: true,
        environment: EnvLight::Sampled,
    };

    /// The lights and `world`'s environment as a path takes it best: a
    /// constant one by escaping rays alone, a map also sampled.
    pub fn of(world: &World) -> Sources {
        Sources {
            lights: true,
            environment: EnvLight::of(world),
        }
    }

    /// `world`'s environment alone, as [`Self::of`] takes it.
    pub fn environment_of(world: &World) -> Sources {
        Sources {
            lights: false,
            environment: EnvLight::of(world),
        }
    }

    /// The lights alone.
    pub const LIGHTS: Sources = Sources {
        lights: true,
        environment: EnvLight::Off,
    };

    /// `world`'s lights, if these sources take them.
    pub fn lights_of(self, world: &World) -> &[Light] {
        if self.lights {
            &world.lights
        } else {
            &[]
        }
    }
}

impl EnvLight {
    /// How a path takes `world`'s environment best.
    pub fn of(world: &World) -> EnvLight {
        match &world.environment {
            e if e.is_black() => EnvLight::Off,
            Environment::Constant(_) => EnvLight::Escaped,
            Environment::Map(_) => EnvLight::Sampled,
        }
    }
}

/// Light arriving at `p` (at `time`) from `sources` along each one's sample, times the
/// phase function and the transmittance, for NEE from a scattering event.
/// A surface that casts shadows (Blender's shadow ray visibility) blocks a
/// sample before its transmittance is walked.
/// With
/// `mis`, lights a phase-sampled ray can also hit are weighted by the power
/// heuristic against phase sampling (the path tracer); without, the light
/// sample is the whole estimate (the photon integrator's marcher, which
/// samples no direction).
#[allow(clippy::too_many_arguments)]
pub fn direct_light(
    world: &World,
    p: Vec3,
    time: f32,
    wo: Vec3,
    phase: &crate::phase::PhaseFunction,
    mis: bool,
    sources: Sources,
    rng: &mut Rng,
) -> Rgb {
    let media = &world.media;
    let mut l = Rgb::ZERO;
    for light in sources.lights_of(world) {
        let u = rng.next_vec2();
        let Some(ls) = light.sample_li(p, u) else {
            continue;
        };
        if ls.li.max_element() <= 0.0 {
            continue;
        }
        let f = phase.eval(wo, ls.wi);
        if f <= 0.0 {
            continue;
        }
        if world.shapes.occluded(p, ls.wi, ls.dist, RayKind::SHADOW) {
            continue;
        }
        let tr = tracking::transmittance(media, &Ray::at_time(p, ls.wi, time), ls.dist, rng);
        if tr.max_element() <= 0.0 {
            continue;
        }
        let w = if ls.is_delta || !mis {
            1.0
        } else {
            power_heuristic(1, ls.pdf, 1, phase.pdf(wo, ls.wi))
        };
        l += ls.li * tr * (f * w / ls.pdf);
    }
    if sources.environment == EnvLight::Sampled && !world.environment.is_black() {
        if let Some((wi, le, pdf)) = world.environment.sample(rng.next_vec2()) {
            if pdf > 0.0 && le.max_element() > 0.0 {
                let f = phase.eval(wo, wi);
                if f > 0.0 && !world.shapes.occluded(p, wi, f32::INFINITY, RayKind::SHADOW) {
                    let tr = tracking::transmittance(
                        media,
                        &Ray::at_time(p, wi, time),
                        f32::INFINITY,
                        rng,
                    );
                    let w = if mis {
                        power_heuristic(1, pdf, 1, phase.pdf(wo, wi))
                    } else {
                        1.0
                    };
                    l += le * tr * (f * w / pdf);
                }
            }
        }
    }
    l
}

/// Light arriving at surface point `hit` from `sources` along each one's
/// sample, times the BSDF and |cos θ| with the shading normal, the
/// media's transmittance and the shadows of the meshes: next-event
/// estimation at a surface (pbrt-v4's `SampleLd` for a `SurfaceInteraction`).
/// `wo` is in `frame` (the shading frame). Lights a BSDF-sampled ray can
/// also hit (finite suns, an environment map) are weighted by the power
/// heuristic against BSDF sampling. Only light from the side the ray came
/// from counts: the BSDFs reflect and do not transmit. Split by the BSDF's
/// lobes (diffuse and glossy), for Blender's Diffuse and Glossy passes.
#[allow(clippy::too_many_arguments)]
pub fn direct_light_surface(
    world: &World,
    hit: &crate::shape::Hit,
    frame: &crate::bsdf::Frame,
    bsdf: &crate::bsdf::Bsdf,
    wo: Vec3,
    time: f32,
    sources: Sources,
    rng: &mut Rng,
) -> BsdfValue {
    let media = &world.media;
    let p = hit.spawn(hit.n);
    let mut l = BsdfValue::ZERO;
    // The BSDF times |cos| for a world direction, and its pdf.
    let eval = |wi: Vec3| -> Option<(BsdfValue, f32)> {
        if wi.dot(hit.n) <= 0.0 {
            return None;
        }
        let wl = frame.to_local(wi);
        let f = bsdf.f(wo, wl).scaled(wl.z.abs());
        (f.total().max_element() > 0.0).then(|| (f, bsdf.pdf(wo, wl)))
    };
    let add = |l: &mut BsdfValue, f: BsdfValue, li: Rgb| {
        l.diffuse += f.diffuse * li;
        l.glossy += f.glossy * li;
    };
    for light in sources.lights_of(world) {
        let u = rng.next_vec2();
        let Some(ls) = light.sample_li(p, u) else {
            continue;
        };
        if ls.li.max_element() <= 0.0 {
            continue;
        }
        let Some((f, bsdf_pdf)) = eval(ls.wi) else {
            continue;
        };
        if world.shapes.occluded(p, ls.wi, ls.dist, RayKind::SHADOW) {
            continue;
        }
        let tr = tracking::transmittance(media, &Ray::at_time(p, ls.wi, time), ls.dist, rng);
        if tr.max_element() <= 0.0 {
            continue;
        }
        let w = if ls.is_delta {
            1.0
        } else {
            power_heuristic(1, ls.pdf, 1, bsdf_pdf)
        };
        add(&mut l, f, ls.li * tr * (w / ls.pdf));
    }
    if sources.environment == EnvLight::Sampled && !world.environment.is_black() {
        if let Some((wi, le, pdf)) = world.environment.sample(rng.next_vec2()) {
            if pdf > 0.0 && le.max_element() > 0.0 {
                if let Some((f, bsdf_pdf)) = eval(wi) {
                    if !world.shapes.occluded(p, wi, f32::INFINITY, RayKind::SHADOW) {
                        let tr = tracking::transmittance(
                            media,
                            &Ray::at_time(p, wi, time),
                            f32::INFINITY,
                            rng,
                        );
                        let w = power_heuristic(1, pdf, 1, bsdf_pdf);
                        add(&mut l, f, le * tr * (w / pdf));
                    }
                }
            }
        }
    }
    l
}
