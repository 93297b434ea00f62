//! The reference integrator: volumetric path tracing, deliberately simple so
//! that it is obviously right (pbrt-v4's `SimpleVolPathIntegrator` and
//! `VolPathIntegrator`, §14.2). It is the ground truth the photon mapper is
//! measured against.
//!
//! - Free flights by delta tracking against the majorant grid
//!   ([`tracking::sample_t_maj`]); at each tentative collision with
//!   majorant σ̄ the path adds emission β·σa·Le/σ̄ and lets
//!   [`tracking::collide`] choose a real or a null collision: spectral
//!   tracking with history-aware probabilities (Kutz, Habel, Li & Novák
//!   2017), unbiased for RGB coefficients, with decomposition tracking
//!   against the majorant grid's minorant where the albedo is uniform.
//!   Absorption is carried as a weight instead of ending the path (Mitsuba
//!   3's `volpath` does the same): for grey media β falls by the albedo at
//!   each scattering event. Ending paths on absorption is the analog
//!   estimator; on the reference cloud (albedo 0.91) it costs 1.5x the
//!   variance at 256 spp, because most light there has scattered many
//!   times.
//! - Next-event estimation to every light at every real scattering event,
//!   with ratio-tracked transmittance; multiple importance sampling (power
//!   heuristic, Veach 1997) between light and phase sampling for the lights
//!   that rays can hit (the environment and finite suns).
//! - Russian roulette after three scattering events once the throughput is
//!   below [`RR_THRESHOLD`]; `max_bounces` real scattering events at most.
//! - At surfaces, next-event estimation of the lights (MIS against the
//!   BSDF) and, in scenes with glowing media and meshes, of the media's
//!   emission ([`MediaLight`]: the fire lighting the ground), weighted by
//!   the balance heuristic against the emission the BSDF-sampled ray's
//!   collisions find (see `emission_weight`).

use super::nee::{direct_light, direct_light_surface, EnvLight, Sources};
use super::{catcher, Integrator, SampleKey, SampleResult};
use crate::film::CatcherSample;
use crate::light::Light;
use crate::ray::Ray;
use crate::sampling::{power_heuristic, roulette, Rng};
use crate::shape::RayKind;
use crate::bsdf::Frame;
use crate::tracking::{self, sample_t_maj, Collision};
use crate::photon::emitter::MediaLight;
use crate::world::World;
use crate::Rgb;
use glam::Vec3;

/// The reference volumetric path tracer as an [`Integrator`]: one path per
/// camera sample, a pass per sample.
#[derive(Debug, Clone)]
pub struct PathIntegrator {
    /// Real scattering events at most along a path.
    pub max_bounces: u32,
    /// The media's emission as a light for surfaces, in scenes with
    /// meshes and glowing media.
    media_light: Option<MediaLight>,
}

impl PathIntegrator {
    pub fn new(max_bounces: u32) -> Self {
        Self {
            max_bounces,
            media_light: None,
        }
    }

    /// The path tracer for `world`: with next-event estimation of the
    /// media's emission at surfaces when it has meshes and glowing media.
    pub fn for_world(max_bounces: u32, world: &World) -> Self {
        let media_light = (!world.shapes.is_empty() && world.media.is_emissive())
            .then(|| MediaLight::new(&world.media, world.camera.shutter()))
            .flatten();
        Self {
            max_bounces,
            media_light,
        }
    }
}

impl Integrator for PathIntegrator {
    fn name(&self) -> &'static str {
        "path"
    }

    fn li(&self, world: &World, ray: &Ray, rng: &mut Rng, _key: SampleKey) -> SampleResult {
        // Alpha, the camera ray's ratio-tracked transmittance, comes from
        // `trace`, which walks it on its first flight's collisions.
        trace_from(
            world,
            self.max_bounces,
            ray,
            rng,
            Sources::of(world),
            Start::Camera,
            self.media_light.as_ref(),
        )
    }

    fn attributes(&self) -> Vec<(String, String)> {
        vec![("vdbphoton/max_bounces".into(), self.max_bounces.to_string())]
    }
}

/// The path tracer in the registry: no settings of its own (it takes
/// `max_bounces` from `[render]`, as every integrator does).
pub const REGISTRATION: super::Registration = super::Registration {
    name: "path",
    about: "the reference volumetric path tracer (unbiased; thin media, emission, sky light)",
    keys: &[],
    check: |_| Ok(()),
    build: |desc, world| {
        Ok(Box::new(PathIntegrator::for_world(
            desc.render.max_bounces,
            world,
        )))
    },
    peak_bytes: |_| 0,
    header_keys: &[],
};

/// Scattering events after which Russian roulette starts.
pub const RR_DEPTH: u32 = 3;

/// Throughput below which Russian roulette plays: a path survives with
/// probability β/RR_THRESHOLD and goes on with β = RR_THRESHOLD. pbrt-v4
/// uses 1, which for a grey medium turns the weighted absorption back into
/// the analog one after `RR_DEPTH`. Measured on the reference scene at
/// 256 spp (relMSE × render time, lower is better): 1 → 3.56e-3,
/// 0.5 → 3.00e-3, 0.25 → 3.09e-3, 0.1 → 3.34e-3; 0.25 keeps most of the
/// variance gain of weighting (relMSE 2.17e-4 against 3.30e-4 with 1).
pub const RR_THRESHOLD: f32 = 0.25;

/// Radiance that a phase-sampled ray leaving the volumes receives from the
/// environment and the finite suns, MIS-weighted against light sampling.
fn escaped(world: &World, w: Vec3, phase_pdf: f32, sources: Sources) -> Rgb {
    // A mirror's direction (an infinite density): no light sample finds
    // it, so it takes all of the light.
    let power_heuristic = |nf, f: f32, ng, g| {
        if f.is_infinite() {
            1.0
        } else {
            power_heuristic(nf, f, ng, g)
        }
    };
    let mut l = Rgb::ZERO;
    match sources.environment {
        EnvLight::Off => {}
        EnvLight::Sampled => {
            let pdf = world.environment.pdf(w);
            l += world.environment.le(w) * power_heuristic(1, phase_pdf, 1, pdf);
        }
        EnvLight::Escaped => l += world.environment.le(w),
    }
    for light in sources.lights_of(world) {
        if let Light::Sun { .. } = light {
            let (le, pdf) = light.le_escaped(w);
            if pdf > 0.0 {
                l += le * power_heuristic(1, phase_pdf, 1, pdf);
            }
        }
    }
    l
}

/// Where a path starts, which decides what its first ray sees and what
/// it makes of it (Blender's ray visibility and film semantics).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Start {
    /// A camera ray. It stops at the surfaces camera rays see: a holdout,
    /// and, surfaces not being shaded yet, every other mesh, adds nothing
    /// (alpha is 1 − the transmittance up to it); a shadow catcher gets
    /// the catcher's estimate ([`catcher::estimate`]) when the path takes
    /// the lights. The world it sees directly counts, unless the film is
    /// transparent.
    Camera,
    /// A ray leaving a diffuse surface (the shadow catcher's bounce): it
    /// stops at what diffuse rays see, and the world it reaches
    /// unscattered counts. `leaving`: the surface point and the density of
    /// the ray's direction, when the media's emission is also sampled from
    /// there (the emission its collisions find is then weighted against
    /// that sample).
    Diffuse { leaving: Option<(Vec3, f32)> },
}

impl Start {
    /// The kind of the path's first ray.
    fn kind(self) -> RayKind {
        match self {
            Start::Camera => RayKind::CAMERA,
            Start::Diffuse { .. } => RayKind::DIFFUSE,
        }
    }
}

/// One camera path along `ray` (every segment at its time), with at most
/// `max_bounces` real scattering events. `transmittance` (the film's
/// alpha) and, in emissive media, the emission along the camera ray itself
/// come from a ratio-tracking walk along the whole ray
/// ([`tracking::transmittance_emission`]'s), run on the first flight's
/// collisions ([`tracking::sample_t_maj_camera`]); with the environment
/// alone (no `lights` in `sources`) there is no such walk and
/// `transmittance` is left at 0.
///
/// Every light is sampled at every scattering event, and an environment
/// map too; a constant environment is found by the rays that escape alone
/// ([`Sources::of`]): phase sampling is then already the ideal importance
/// sampling of its light, and a light sample's shadow ray, a transmittance
/// walk to infinity, costs more than it gains. On the equal-time bench at
/// 10 s (2 threads, seed 7; docs/performance.md, "Sky light by paths")
/// relMSE fell from 4.2e-5 to 1.8e-5 on the cloud under sky light alone,
/// from 1.9e-4 to 2.2e-5 on the dense cloud under it, and from 7.0e-5 to
/// 4.8e-5 on the cloud under a sun and a sky.
pub fn trace(world: &World, max_bounces: u32, ray: &Ray, rng: &mut Rng) -> SampleResult {
    trace_from(world, max_bounces, ray, rng, Sources::of(world), Start::Camera, None)
}

/// The light a ray leaving shadow catcher `hit` towards `ray.d` receives
/// (`pdf`: the density of that direction; the catcher is white and
/// Lambertian): a path from [`Start::Diffuse`], all sources as
/// [`Sources::of`] takes them, and with `media_light`, on
/// [`MEDIA_LIGHT_SHARE`] of the calls, a sample of the media's emission
/// weighted against the path's by multiple importance sampling, as at any
/// surface: the catcher's bounce.
pub fn bounce(
    world: &World,
    max_bounces: u32,
    hit: &crate::shape::Hit,
    ray: &Ray,
    pdf: f32,
    media_light: Option<&MediaLight>,
    rng: &mut Rng,
) -> Rgb {
    let mut l = Rgb::ZERO;
    if let Some(ml) = media_light.filter(|_| rng.next_f32() < MEDIA_LIGHT_SHARE) {
        let frame = Frame::from_normal(hit.n);
        let white = crate::bsdf::Bsdf::diffuse(Rgb::ONE, 0.0);
        l += media_light_surface(world, ml, hit, &frame, &white, Vec3::Z, ray.time, rng).total();
    }
    let leaving = media_light.map(|_| (hit.p, pdf));
    l + trace_from(
        world,
        max_bounces,
        ray,
        rng,
        Sources::of(world),
        Start::Diffuse { leaving },
        media_light,
    )
    .l
}

/// [`trace`] for the light of `sources` only, taken as they say. With the
/// environment alone (no `lights`) the path
/// gathers nothing the photon integrator's photons and march carry: no
/// emission, and no light along the camera ray before its first scattering
/// (the march adds the background it sees): only the environment's light
/// scattered once or more.
///
/// Surfaces stop every flight: the first at what `start`'s rays see,
/// later ones (scattered in a volume) at what volume-scatter rays see; a
/// flight that reaches a surface ends the path there (surfaces are not
/// shaded yet), having gathered what the media gave it on the way.
pub fn trace_from(
    world: &World,
    max_bounces: u32,
    ray: &Ray,
    rng: &mut Rng,
    sources: Sources,
    start: Start,
    media_light: Option<&MediaLight>,
) -> SampleResult {
    // The media's emission is sampled from surfaces when the path takes
    // the lights.
    let media_light = media_light.filter(|_| sources.lights);
    let media = &world.media;
    let env_only = !sources.lights;
    // Light samples at scattering events: none when nothing is sampled.
    let sampled = sources.lights || sources.environment == EnvLight::Sampled;
    let time = ray.time;
    let mut res = SampleResult::default();
    // The camera ray's emission, seen through everything in front of it
    // by every sample: the path's own collisions would count it only up to
    // where the path first scatters (see `transmittance_emission`). The
    // path's collisions then add emission from its first scattering on.
    // The walk that gives it, and alpha, shares the first flight's lookups
    // (`sample_t_maj_camera`).
    // (A bounce whose collisions weigh the emission against the media
    // light's sample finds it by its collisions from the start.)
    let weighted_start = matches!(start, Start::Diffuse { leaving: Some(_) });
    let camera_emission = media.is_emissive() && !env_only && !weighted_start;
    let mut beta = Rgb::ONE;
    let mut ray_o = ray.o;
    let mut ray_d = ray.d;
    let mut depth = 0u32; // real scattering events (volume or surface) so far
    let mut last_phase_pdf = 0.0f32;
    // The kind of the next ray: the start's, then what scattered it.
    let mut kind = start.kind();
    // When the path first scattered on a surface, the lobe that sent it on
    // (glossy or not): its light then goes to Blender's Diffuse or Glossy
    // passes instead of `direct`, `indirect` and `emission`.
    let mut first_lobe: Option<bool> = None;
    // Where the current flight left a surface, with the BSDF's density of
    // its direction, when the media's emission is also sampled from there.
    let mut from_surface: Option<(Vec3, f32)> = match start {
        Start::Diffuse { leaving } => leaving,
        Start::Camera => None,
    };
    loop {
        let lobe = first_lobe;
        let leaving = from_surface;
        let mut scattered = false;
        let mut terminated = false;
        let mut new_dir = ray_d;
        let mut new_o = ray_o;
        let mut new_pdf = 0.0;
        let segment = Ray::at_time(ray_o, ray_d, time);
        let first_flight = depth == 0;
        let hit = world.shapes.intersect(ray_o, ray_d, f32::INFINITY, kind);
        let t_max = hit.map_or(f32::INFINITY, |h| h.t);
        let on_collision = |c: &Collision, rng: &mut Rng| {
            let Some(step) = tracking::collide(c, beta, rng) else {
                terminated = true;
                return false;
            };
            if let Some(m) = step
                .medium
                .as_ref()
                .filter(|_| !env_only && (depth > 0 || !camera_emission))
            {
                if m.emission.max_element() > 0.0 {
                    let w = match (leaving, media_light) {
                        (Some((o, pdf)), Some(ml)) => emission_weight(
                            pdf,
                            (c.p - o).length_squared(),
                            avg(m.sigma_t()),
                            MEDIA_LIGHT_SHARE * ml.pdf(media, c.p),
                        ),
                        _ => 1.0,
                    };
                    let e = beta * m.emission * (w / c.sigma_maj);
                    res.l += e;
                    match lobe {
                        Some(g) => res.surface.add_to(g, depth == 1, e),
                        None => res.emission += e,
                    }
                }
            }
            beta *= step.weight;
            if !step.scatter {
                return true;
            }
            depth += 1;
            if depth > max_bounces || beta.max_element() <= 0.0 {
                terminated = true;
                return false;
            }
            let wo = -ray_d;
            let phase = step.phase;
            let ld = if sampled {
                beta * direct_light(world, c.p, time, wo, &phase, true, sources, rng)
            } else {
                Rgb::ZERO
            };
            res.l += ld;
            match lobe {
                Some(g) => res.surface.add_to(g, false, ld),
                None if depth == 1 => res.direct += ld,
                None => res.indirect += ld,
            }
            match phase.sample(wo, rng.next_vec2()) {
                Some(ps) if ps.pdf > 0.0 => {
                    beta *= ps.p / ps.pdf;
                    new_dir = ps.wi;
                    new_o = c.p;
                    new_pdf = ps.pdf;
                    scattered = true;
                }
                _ => terminated = true,
            }
            false
        };
        let left = if !env_only && first_flight && !weighted_start {
            let (left, tr, e) =
                tracking::sample_t_maj_camera(media, &segment, t_max, rng, on_collision);
            res.l += e;
            res.emission += e;
            res.transmittance = (tr.x + tr.y + tr.z) / 3.0;
            left
        } else {
            sample_t_maj(media, &segment, t_max, rng, on_collision)
        };
        // A camera ray whose surface is a shadow catcher gets the catcher's
        // estimate, weighted as alpha is by the transmittance up to it
        // (the camera walk's, over the whole ray: the pixel sees the
        // catcher also where this path scatters or is absorbed first).
        if let (true, Start::Camera, true, Some(h)) = (first_flight, start, sources.lights, hit) {
            let flags = world.shapes.object(h.object).flags;
            if flags.shadow_catcher && !flags.holdout {
                res.catcher = Some(if res.transmittance > 0.0 {
                    catcher::estimate(world, &h, time, rng, catcher::BOUNCE_SHARE, |r, pdf, rng| {
                        bounce(world, max_bounces, &h, r, pdf, media_light, rng)
                    })
                    .scaled(res.transmittance)
                } else {
                    CatcherSample::default()
                });
            }
        }
        // A flight that neither scattered nor left the volumes used up its
        // tentative collisions (tracking::MAX_TENTATIVE): it ends.
        if terminated || (!scattered && !left) {
            break;
        }
        if let (false, Some(h)) = (scattered, hit) {
            // The flight reached a surface. A camera ray's holdout or
            // shadow catcher is a hole in the image; any other surface
            // is shaded.
            let flags = world.shapes.object(h.object).flags;
            if first_flight && start == Start::Camera {
                if flags.holdout || flags.shadow_catcher {
                    break;
                }
                // An opaque surface: the camera sees nothing through it.
                res.transmittance = 0.0;
            }
            let sh = world.shapes.shading(&h);
            let sp = world.surfaces[h.object as usize].at(sh.uv);
            if !env_only && sp.emission.max_element() > 0.0 {
                let e = beta * sp.emission;
                res.l += e;
                match first_lobe {
                    Some(g) => res.surface.add_to(g, depth == 1, e),
                    None => res.emission += e,
                }
            }
            let Some(bsdf) = sp.bsdf else {
                break;
            };
            depth += 1;
            if depth > max_bounces {
                break;
            }
            let frame = Frame::from_normal(sh.n);
            let wo = frame.to_local(-ray_d);
            if sampled {
                let by_lobe =
                    direct_light_surface(world, &h, &frame, &bsdf, wo, time, sources, rng);
                add_surface_light(&mut res, first_lobe, depth, beta, by_lobe);
            }
            if let Some(ml) = media_light.filter(|_| rng.next_f32() < MEDIA_LIGHT_SHARE) {
                let by_lobe = media_light_surface(world, ml, &h, &frame, &bsdf, wo, time, rng);
                add_surface_light(&mut res, first_lobe, depth, beta, by_lobe);
            }
            let Some(bs) = bsdf.sample(wo, rng.next_f32(), rng.next_vec2()) else {
                break;
            };
            let wi = frame.to_world(bs.wi);
            // Reflection only, to the side the ray came from.
            if bs.pdf <= 0.0 || wi.dot(h.n) <= 0.0 {
                break;
            }
            beta *= bs.f.total() * (bs.wi.z.abs() / bs.pdf);
            if depth == 1 {
                first_lobe = Some(bs.glossy);
            }
            // A mirror's direction the light sample cannot draw: its
            // emission is the ray's alone.
            from_surface = (!bs.singular).then_some((h.p, bs.pdf));
            ray_o = h.spawn(wi);
            ray_d = wi;
            last_phase_pdf = if bs.singular { f32::INFINITY } else { bs.pdf };
            kind = if bs.glossy {
                RayKind::GLOSSY
            } else {
                RayKind::DIFFUSE
            };
            if depth >= RR_DEPTH && !roulette(&mut beta, RR_THRESHOLD, rng) {
                break;
            }
            if !beta.is_finite() {
                break;
            }
            continue;
        }
        if !scattered {
            // The path left every volume.
            if depth == 0 {
                // (A transparent film leaves out the world the camera sees.)
                let transparent = start == Start::Camera && world.film_transparent;
                if !env_only && !transparent {
                    res.l += beta * world.environment.le(ray_d);
                }
            } else {
                let e = beta * escaped(world, ray_d, last_phase_pdf, sources);
                res.l += e;
                match first_lobe {
                    Some(g) => res.surface.add_to(g, depth == 1, e),
                    None if depth == 1 => res.direct += e,
                    None => res.indirect += e,
                }
            }
            break;
        }
        ray_o = new_o;
        ray_d = new_dir;
        last_phase_pdf = new_pdf;
        kind = RayKind::VOLUME_SCATTER;
        from_surface = None;
        // Russian roulette on the throughput itself: survivors go on with
        // β = RR_THRESHOLD, so weights stay bounded (a floor on the
        // termination probability would let them grow without bound).
        if depth >= RR_DEPTH && !roulette(&mut beta, RR_THRESHOLD, rng) {
            break;
        }
        if !beta.is_finite() {
            break;
        }
    }
    res
}

/// The share of surface points that sample the media's emission: the
/// sample costs a transmittance walk through the smoke, and where the
/// fire is large and near (Blender's smoke + fire frame over a ground)
/// a sample at every point cost 40 % more time for 2 % less error per
/// sample; the share enters the MIS weights as a factor of the light's
/// density, so the estimate stays unbiased.
pub const MEDIA_LIGHT_SHARE: f32 = 0.25;

/// Adds a surface point's light sample (split by lobe, before `beta`) to
/// the image and its pass: the Diffuse or Glossy Direct pass at the path's
/// first scattering (`depth` 1), later the pass of the first lobe, or
/// `indirect` when the path first scattered in a volume.
#[inline]
fn add_surface_light(
    res: &mut SampleResult,
    first_lobe: Option<bool>,
    depth: u32,
    beta: Rgb,
    by_lobe: crate::bsdf::BsdfValue,
) {
    let ld = beta * by_lobe.total();
    res.l += ld;
    match first_lobe {
        Some(g) => res.surface.add_to(g, false, ld),
        None if depth == 1 => {
            res.surface.diffuse_direct += beta * by_lobe.diffuse;
            res.surface.glossy_direct += beta * by_lobe.glossy;
        }
        None => res.indirect += ld,
    }
}

#[inline]
fn avg(c: Rgb) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

/// The balance-heuristic weight (Veach 1997) of the media's emission at a
/// point found by the collisions of a BSDF-sampled ray, against
/// [`MediaLight`]'s sampling of that point: the ray's density there is
/// taken as the BSDF's density of the direction times the point's σt
/// (where collisions fall) over the squared distance (to a density per
/// unit volume, as the light's), and the light's as [`MediaLight::pdf`].
/// Any weights that add to one for each point keep the sum unbiased: this
/// one gives the emission near the surface to the ray (whose density grows
/// as 1/t² there, where the light sample's estimate would) and the far,
/// small fire to the light sample.
#[inline]
fn emission_weight(bsdf_pdf: f32, dist2: f32, sigma_t: f32, light_pdf: f32) -> f32 {
    let ray = bsdf_pdf * sigma_t / dist2.max(1e-12);
    if ray.is_nan() || ray <= 0.0 {
        return 0.0;
    }
    if !ray.is_finite() {
        return 1.0;
    }
    ray / (ray + light_pdf)
}

/// Next-event estimation of the media's emission from surface point `hit`
/// (BSDF in `frame`, `wo` local): a point of the emission drawn by `light`,
/// its emission times the BSDF, |cos θ|, the meshes' shadow and the media's
/// transmittance, over its density per solid angle, weighted against the
/// BSDF-sampled ray by [`emission_weight`]. Split by lobe.
#[allow(clippy::too_many_arguments)]
fn media_light_surface(
    world: &World,
    light: &MediaLight,
    hit: &crate::shape::Hit,
    frame: &Frame,
    bsdf: &crate::bsdf::Bsdf,
    wo: Vec3,
    time: f32,
    rng: &mut Rng,
) -> crate::bsdf::BsdfValue {
    let none = crate::bsdf::BsdfValue::ZERO;
    let media = &world.media;
    let Some(s) = light.sample(media, time, rng) else {
        return none;
    };
    let to = s.p - hit.p;
    let dist2 = to.length_squared();
    if dist2.is_nan() || dist2 <= 0.0 {
        return none;
    }
    let dist = dist2.sqrt();
    let wi = to / dist;
    if wi.dot(hit.n) <= 0.0 {
        return none;
    }
    let wl = frame.to_local(wi);
    let f = bsdf.f(wo, wl).scaled(wl.z.abs());
    if f.total().max_element() <= 0.0 {
        return none;
    }
    let o = hit.spawn(hit.n);
    let d = (s.p - o).length();
    if world.shapes.occluded(o, wi, d, RayKind::SHADOW) {
        return none;
    }
    let tr = tracking::transmittance(media, &Ray::at_time(o, wi, time), d, rng);
    if tr.max_element() <= 0.0 {
        return none;
    }
    // Drawn at a share of the surface points: its density is that share
    // of the light's.
    let pdf = MEDIA_LIGHT_SHARE * s.pdf;
    let w = 1.0 - emission_weight(bsdf.pdf(wo, wl), dist2, s.sigma_t, pdf);
    let li = s.emission * tr * (w / (pdf * dist2));
    crate::bsdf::BsdfValue {
        diffuse: f.diffuse * li,
        glossy: f.glossy * li,
    }
}
