//! Next-event estimation: light arriving at a scattering point straight
//! from the lights and the environment, through the media (pbrt-v4
//! §14.2.3, `SampleLd`). Shared by the path tracer (with multiple
//! importance sampling against phase sampling, Veach 1997) and the photon
//! integrator's marcher (single scattering, without MIS: it samples no
//! direction).

use crate::ray::Ray;
use crate::sampling::{power_heuristic, Rng};
use crate::tracking;
use crate::world::World;
use crate::Rgb;
use glam::Vec3;

/// Light arriving at `p` (at `time`) along each light's sample, times the
/// phase function and the transmittance, for NEE from a scattering event.
/// With
/// `mis`, lights a phase-sampled ray can also hit are weighted by the power
/// heuristic against phase sampling (the path tracer); without, the light
/// sample is the whole estimate (the photon integrator's marcher, which
/// samples no direction).
pub fn direct_light(
    world: &World,
    p: Vec3,
    time: f32,
    wo: Vec3,
    phase: &crate::phase::PhaseFunction,
    mis: bool,
    rng: &mut Rng,
) -> Rgb {
    let media = &world.media;
    let mut l = Rgb::ZERO;
    for light in &world.lights {
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
    if !world.environment.is_black() {
        if let Some((wi, le, pdf)) = world.environment.sample(rng.next_vec2()) {
            if pdf > 0.0 && le.max_element() > 0.0 {
                let f = phase.eval(wo, wi);
                if f > 0.0 {
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
