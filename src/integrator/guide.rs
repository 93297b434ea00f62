//! The denoiser's guide for a camera ray (`crate::denoise`): the denoising
//! albedo, the scattering colour seen along the ray, ∫ T(s)·σs(s) ds, plus
//! the transmittance times what it sees of the environment (at most 1), as
//! Cycles' Denoising Albedo pass holds for volumes.
//!
//! A march: steps of at most `step`, one jitter per ray, each adding
//! T·(1 − e^{−σtΔ})·σs/σt at its midpoint (exact for optics constant over
//! the step), until the transmittance is below 10^-3.
//!
//! A guide needs little noise, not many samples: the pass loop computes it
//! for the first [`GUIDE_SAMPLES`] samples of each pixel only (the film
//! averages it over those), whatever the integrator: every sample's march
//! cost the path tracer a few percent of its samples on the dense cloud.

use crate::ray::Ray;
use crate::sampling::Rng;
use crate::shape::RayKind;
use crate::world::World;
use crate::Rgb;

/// The march stops once every channel's transmittance is below this: what
/// lies behind adds at most this much.
const T_MIN: f32 = 1e-3;

/// Samples of each pixel that carry the guide (the first ones): enough for
/// a guide antialiased over the pixel and nearly noise-free.
pub const GUIDE_SAMPLES: u64 = 16;

/// The denoising albedo along `ray` (`ray.d` unit), marched in steps of at
/// most `step` world units.
pub fn along(world: &World, ray: &Ray, step: f32, rng: &mut Rng) -> Rgb {
    let media = &world.media;
    let jitter = rng.next_f32();
    let mut tr = Rgb::ONE;
    let mut albedo = Rgb::ZERO;
    let mut ended = false;
    // Up to the surface the camera sees (a hole: nothing beyond counts).
    let hit = world
        .shapes
        .intersect(ray.o, ray.d, f32::INFINITY, RayKind::CAMERA);
    let t_max = hit.map_or(f32::INFINITY, |h| h.t);
    media.for_each_segment_at(ray.o, ray.d, 0.0, t_max, ray.time, |seg| {
        if seg.max_density <= 0.0 {
            return true;
        }
        let len = seg.t1 - seg.t0;
        let n = (len / step).ceil().clamp(1.0, 1e6) as u32;
        let dt = len / n as f32;
        for i in 0..n {
            let t = seg.t0 + (i as f32 + jitter) * dt;
            let m = media.eval(ray.at(t), ray.time);
            let (att, w) = crate::medium::Media::step_weights(m.sigma_t(), dt);
            albedo += tr * w * m.sigma_s;
            tr *= att;
            if tr.max_element() < T_MIN {
                ended = true;
                return false;
            }
        }
        true
    });
    if !ended {
        match hit {
            None if !world.film_transparent => {
                albedo += tr * world.environment.le(ray.d).min(Rgb::ONE);
            }
            // A shaded surface: its BSDF's albedo, as Cycles' Denoising
            // Albedo takes it (a mostly mirror-like one: the mirror's
            // colour, where Cycles would go on to what it reflects).
            Some(h) => {
                let flags = world.shapes.object(h.object).flags;
                if !flags.holdout && !flags.shadow_catcher {
                    let sh = world.shapes.shading(&h);
                    let sp = world.surfaces[h.object as usize].at(sh.uv);
                    if let Some(bsdf) = sp.bsdf {
                        let frame = crate::bsdf::Frame::from_normal(sh.n);
                        let c = match bsdf.albedo(frame.to_local(-ray.d)) {
                            crate::bsdf::AlbedoGuide::Albedo(c)
                            | crate::bsdf::AlbedoGuide::Continue(c) => c,
                        };
                        albedo += tr * c;
                    }
                }
            }
            None => {}
        }
    }
    albedo
}

/// The march step for `world`: its finest voxel.
pub fn step(world: &World) -> f32 {
    world.media.finest_voxel().unwrap_or(1.0)
}
