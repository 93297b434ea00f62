//! The shadow catcher: what a camera sample that sees a shadow-catcher
//! surface gives Cycles' Shadow Catcher pass (Blender's Object >
//! Visibility > Mask > Shadow Catcher), shared by every integrator.
//!
//! Cycles splits a camera path where it first meets a catcher
//! (`kernel/integrator/shadow_catcher.h`): one half goes on through the
//! whole scene, the other sees only the catchers, the lights and the
//! world; the pass is the ratio of what the two gather at the catcher,
//! summed over the pixel's samples (`film_calculate_shadow_catcher` in
//! `kernel/film/read.h`), and 1 where no catcher is seen. A plate times
//! the pass then darkens where the scene's volumes and meshes shadow the
//! catcher, and brightens where they send it light (fire, light scattered
//! by smoke).
//!
//! Here the catcher is a white Lambertian surface (its material cancels
//! in the ratio; surfaces are not shaded yet). Both estimates share their
//! samples, so their ratio is steady where nothing shadows:
//! - every light is sampled once: unshadowed, its light times cos/π
//!   (blocked only by other catchers that cast shadows); shadowed, the
//!   same times the media's transmittance and the shadows of every mesh;
//! - one cosine-weighted direction takes the world and what the scene
//!   sends: unshadowed, the world's radiance there (unless a catcher is in
//!   the way); shadowed, a path from the catcher through the scene
//!   (`bounce`, the path tracer from a diffuse surface, with the media's
//!   emission also sampled from the catcher), which gathers the world
//!   through the media, light the media scatter and the media's own
//!   emission. Where the lights reach the catcher unshadowed that path is
//!   a small part of its light and is traced on a share of the samples
//!   only (Russian roulette around the unshadowed world).

use crate::film::CatcherSample;
use crate::ray::Ray;
use crate::sampling::{coordinate_system, sample_cosine_hemisphere, Rng};
use crate::shape::{Hit, ObjectFlags, RayKind};
use crate::tracking;
use crate::world::World;
use crate::Rgb;
use std::f32::consts::FRAC_1_PI;

/// The catcher's two estimates at `hit` (a camera ray's, at `time`);
/// `bounce` is the light a ray leaving the surface receives through the
/// scene.
pub fn estimate(
    world: &World,
    hit: &Hit,
    time: f32,
    rng: &mut Rng,
    share: f32,
    bounce: impl FnOnce(&Ray, f32, &mut Rng) -> Rgb,
) -> CatcherSample {
    let n = hit.n;
    let mut out = CatcherSample::default();
    let catcher = |f: &ObjectFlags| f.shadow_catcher;
    for light in &world.lights {
        let u = rng.next_vec2();
        let p = hit.spawn(n);
        let Some(ls) = light.sample_li(p, u) else {
            continue;
        };
        let cos = ls.wi.dot(n);
        if cos <= 0.0 || ls.pdf <= 0.0 || ls.li.max_element() <= 0.0 {
            continue;
        }
        let e = ls.li * (cos * FRAC_1_PI / ls.pdf);
        // Unshadowed, only other catchers block the light: asked only
        // when something does.
        let shapes = &world.shapes;
        if shapes.occluded(p, ls.wi, ls.dist, RayKind::SHADOW) {
            if !shapes.occluded_where(p, ls.wi, ls.dist, RayKind::SHADOW, catcher) {
                out.unshadowed += e;
            }
            continue;
        }
        out.unshadowed += e;
        let tr = tracking::transmittance(&world.media, &Ray::at_time(p, ls.wi, time), ls.dist, rng);
        out.shadowed += e * tr;
    }
    let local = sample_cosine_hemisphere(rng.next_vec2());
    let (t, b) = coordinate_system(n);
    let w = t * local.x + b * local.y + n * local.z;
    let p = hit.spawn(w);
    let sky = if world
        .shapes
        .occluded_where(p, w, f32::INFINITY, RayKind::DIFFUSE, catcher)
    {
        Rgb::ZERO
    } else {
        world.environment.le(w)
    };
    out.unshadowed += sky;
    // The bounce by Russian roulette around the unshadowed sky (a control
    // variate): `sky + (bounce − sky)/q` with probability q, else `sky`,
    // whose mean is the bounce's for any q. Where the lights reach the
    // catcher unshadowed the bounce is a small part of what it receives
    // and is traced on BOUNCE_SHARE of the samples; in the volumes' shadow
    // it is most of it, and always traced.
    let lit = if out.unshadowed.max_element() > 0.0 {
        (out.shadowed.element_sum() / out.unshadowed.element_sum()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let q = 1.0 - (1.0 - share.clamp(0.0, 1.0)) * lit;
    out.shadowed += sky;
    if q >= 1.0 || rng.next_f32() < q {
        out.shadowed += (bounce(&Ray::at_time(p, w, time), local.z * FRAC_1_PI, rng) - sky) / q;
    }
    out
}

/// The share of samples that trace the catcher's bounce where the lights
/// reach it unshadowed (more in the volumes' shadow, all in full shadow).
pub const BOUNCE_SHARE: f32 = 0.125;
