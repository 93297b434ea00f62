//! Photon tracing and the volume photon map (Jensen & Christensen 1998,
//! "Efficient simulation of light transport in scenes with participating
//! media using photon maps").
//!
//! Photons leave the sources in proportion to their power
//! ([`emitter::Emitters`]) and fly by delta tracking through σt(x) on the
//! shared tracker ([`crate::tracking::sample_t_maj`] and
//! [`crate::tracking::collide`]: spectral tracking, so coloured media stay
//! unbiased, with absorption as a weight). At each real collision the
//! photon's power is multiplied by the collision's weight (σs/σt for grey
//! media) and Russian roulette against its starting power decides whether
//! it goes on ([`crate::sampling::roulette`]): for a grey medium of albedo
//! a it survives with probability a and keeps its power, Jensen's rule. A
//! photon that goes on samples its new direction from the phase function.
//!
//! What is stored, at a collision, is the power after the collision's
//! weight: the density of stored power per unit volume is then
//! σs·∫L dω, so Σ p·Φ / V is the in-scattered radiance σs·L_s already
//! (multiplying by σs again is the classic mistake). Only photons that have
//! scattered at least once before arriving are stored: single scattering
//! is computed exactly by the camera-ray march. Photons emitted by the
//! media are stored from their first collision (the march does not compute
//! scattered emission). Up to `max_bounces` scattering events count, as
//! for paths.
//!
//! Each photon also keeps σs where it was stored. An estimate gathering it
//! at x multiplies by σs(x)/σs(photon): the ratio tends to 1 as radii
//! shrink, and it keeps a kernel that reaches past a volume's edge from
//! lighting the empty space beside it (rays that miss a cloud would
//! otherwise gather its photons unattenuated, a bright halo).
//!
//! A collision is stored with a probability (and its power divided by it):
//! in dense media a photon scatters hundreds of times, and thinning the
//! stored collisions keeps a pass's map to a chosen size without bias. The
//! probability is a scale times the camera's importance at the collision
//! ([`importance::Importance`]), so the map is spent where camera rays
//! gather.
//!
//! Photon `i` of pass `p` draws its numbers from the stream (seed, p, i) in
//! the photon domain, and photons are traced in chunks collected in index
//! order, so the map is the same on any number of threads.

pub mod beam;
pub mod emitter;
pub mod importance;
pub mod map;

use crate::ray::Ray;
use crate::sampling::{roulette, Domain, Rng};
use crate::shape::RayKind;
use crate::tracking::{collide, sample_t_maj};
use crate::world::World;
use crate::Rgb;
use emitter::Emitters;
use glam::Vec3;
use rayon::prelude::*;

/// A stored photon.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Photon {
    pub p: Vec3,
    /// Unit direction towards where it came from (minus its direction of
    /// travel): the `wi` of the phase function.
    pub wi: Vec3,
    /// Power (W) after the collision's weight, over the photons emitted.
    pub power: Rgb,
    /// σs where it was stored (mean over channels): estimates weight a
    /// photon by σs where they gather it over this, so that the kernel
    /// blurs the light, not the medium's edges.
    pub sigma_s: f32,
    /// The volume whose phase function scatters it (bits 0-30) and whether
    /// it was emitted by the media (bit 31).
    tag: u32,
}

const FROM_MEDIA: u32 = 1 << 31;

impl Photon {
    /// The index of the volume whose phase function applies here.
    pub fn volume(&self) -> usize {
        (self.tag & !FROM_MEDIA) as usize
    }
    /// Whether the photon was emitted by the media (its light is emission).
    pub fn from_media(&self) -> bool {
        self.tag & FROM_MEDIA != 0
    }
}

/// What a pass of photon tracing did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TraceStats {
    /// Photons emitted.
    pub emitted: u64,
    /// Collisions at which a photon could have been stored.
    pub eligible: u64,
    /// The sum of the importance at those collisions: the photons a scale
    /// of 1 would store (before capping each probability at 1).
    pub eligible_weight: f64,
    /// Photons stored.
    pub stored: u64,
    /// Photons that scattered at least once, and the scattering events of
    /// them all: their ratio is the media's mean scattering order.
    pub scattered: u64,
    pub collisions: u64,
    /// Photons the media emitted, and those of them that scattered.
    pub media_emitted: u64,
    pub media_scattered: u64,
}

impl TraceStats {
    /// Mean scattering events of a photon that scattered (0 when none did).
    pub fn order(&self) -> f64 {
        self.collisions as f64 / self.scattered.max(1) as f64
    }
}

/// How collisions are kept: with probability `scale` times the importance
/// there (1 without an importance grid), at most 1.
#[derive(Debug, Clone, Copy)]
pub struct Store<'a> {
    pub scale: f32,
    pub importance: Option<&'a importance::Importance>,
}

impl Store<'_> {
    /// Keep every collision.
    pub const ALL: Store<'static> = Store {
        scale: 1.0,
        importance: None,
    };

    #[inline]
    fn weight(&self, p: Vec3) -> f32 {
        self.importance.map_or(1.0, |i| i.at(p))
    }
}

/// Photons emitted per chunk of work (the unit of parallelism).
const CHUNK: u32 = 1024;

/// Traces `n` photons of pass `pass` at `time` (frames from the frame:
/// where moving volumes are), keeping eligible collisions as `store` says.
#[allow(clippy::too_many_arguments)]
pub fn trace(
    world: &World,
    emitters: &Emitters,
    n: u32,
    seed: u64,
    pass: u32,
    time: f32,
    max_bounces: u32,
    store: Store,
) -> (Vec<Photon>, TraceStats) {
    let chunks = n.div_ceil(CHUNK);
    let parts: Vec<(Vec<Photon>, Flights)> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let mut out = Vec::new();
            let mut sum = Flights::default();
            if crate::interrupt::abandon() {
                return (out, sum);
            }
            for i in c * CHUNK..((c + 1) * CHUNK).min(n) {
                let mut rng = Rng::new(Domain::Photon, seed, pass as u64, i as u64);
                sum.add(trace_one(
                    world,
                    emitters,
                    n,
                    time,
                    max_bounces,
                    store,
                    &mut rng,
                    &mut out,
                ));
            }
            (out, sum)
        })
        .collect();
    let stored = parts.iter().map(|p| p.0.len() as u64).sum();
    let mut all = Flights::default();
    for p in &parts {
        all.add(p.1);
    }
    let mut photons = Vec::with_capacity(stored as usize);
    for (p, _) in parts {
        photons.extend(p);
    }
    (
        photons,
        TraceStats {
            emitted: n as u64,
            eligible: all.eligible,
            eligible_weight: all.weight,
            stored,
            scattered: all.scattered,
            collisions: all.collisions,
            media_emitted: all.media_emitted,
            media_scattered: all.media_scattered,
        },
    )
}

/// What some photons' flights met.
#[derive(Debug, Clone, Copy, Default)]
struct Flights {
    /// Collisions at which a photon could have been stored.
    eligible: u64,
    /// The importance summed over them.
    weight: f64,
    /// Photons that scattered at least once.
    scattered: u64,
    /// Scattering events.
    collisions: u64,
    /// Photons the media emitted, and those of them that scattered.
    media_emitted: u64,
    media_scattered: u64,
}

impl Flights {
    fn add(&mut self, o: Flights) {
        self.eligible += o.eligible;
        self.weight += o.weight;
        self.scattered += o.scattered;
        self.collisions += o.collisions;
        self.media_emitted += o.media_emitted;
        self.media_scattered += o.media_scattered;
    }
}

/// One photon's flight: what it met.
#[allow(clippy::too_many_arguments)]
fn trace_one(
    world: &World,
    emitters: &Emitters,
    n: u32,
    time: f32,
    max_bounces: u32,
    store: Store,
    rng: &mut Rng,
    out: &mut Vec<Photon>,
) -> Flights {
    let mut flight = Flights::default();
    let Some(e) = emitters.sample(world, time, rng) else {
        return flight;
    };
    let media = &world.media;
    let mut power = e.ray.power / n as f32;
    // Russian roulette keeps the power near what the photon started with.
    let mut threshold = power.max_element();
    if threshold.is_nan() || threshold <= 0.0 {
        return flight;
    }
    let media_bit = if e.from_media { FROM_MEDIA } else { 0 };
    flight.media_emitted = e.from_media as u64;
    let (mut o, mut d) = (e.ray.o, e.ray.d);
    // Light from infinity starts at the volumes' bounding sphere: a surface
    // beyond it, towards the light, still shadows it.
    if e.from_infinity && world.shapes.occluded(o, -d, f32::INFINITY, RayKind::SHADOW) {
        return flight;
    }
    let mut collisions = 0u32;
    // Surface bounces so far: light that reflected off a surface is no
    // longer what the march's single scattering computes, so it is stored
    // from its first collision in a volume on.
    let mut bounces = 0u32;
    // Light on its way from a light is what shadow rays carry; once
    // scattered in a volume, or emitted by the media, volume-scatter rays;
    // once reflected, diffuse or glossy rays (Blender's ray visibility).
    let mut kind = if e.from_media {
        RayKind::VOLUME_SCATTER
    } else {
        RayKind::SHADOW
    };
    loop {
        let mut next: Option<(Vec3, Vec3)> = None;
        let hit = world.shapes.intersect(o, d, f32::INFINITY, kind);
        let t_max = hit.map_or(f32::INFINITY, |h| h.t);
        let reached = sample_t_maj(media, &Ray::at_time(o, d, time), t_max, rng, |c, rng| {
            let Some(step) = collide(c, power, rng) else {
                return false;
            };
            power *= step.weight;
            if !step.scatter {
                return true;
            }
            collisions += 1;
            if collisions > max_bounces {
                return false;
            }
            flight.collisions += 1;
            flight.scattered = 1;
            flight.media_scattered = e.from_media as u64;
            if collisions >= 2 || bounces > 0 || e.from_media {
                flight.eligible += 1;
                let w = store.weight(c.p);
                flight.weight += w as f64;
                let q = (store.scale * w).min(1.0);
                if q > 0.0 && (q >= 1.0 || rng.next_f32() < q) {
                    let sigma_s = step.medium.unwrap_or_else(|| media.eval(c.p, time)).sigma_s;
                    out.push(Photon {
                        p: c.p,
                        wi: -d,
                        power: power / q,
                        sigma_s: sigma_s.element_sum() / 3.0,
                        tag: step.volume as u32 | media_bit,
                    });
                }
            }
            if !roulette(&mut power, threshold, rng) {
                return false;
            }
            if let Some((nd, _)) = step.phase.sample_travel(d, rng.next_vec2()) {
                next = Some((c.p, nd));
            }
            false
        });
        match (next, hit) {
            (Some((p, nd)), _) if power.is_finite() => {
                o = p;
                d = nd;
                kind = RayKind::VOLUME_SCATTER;
            }
            // The flight reached a surface: the photon reflects, its power
            // times the BSDF's weight, and goes on with Russian roulette
            // against its starting power, as at a collision.
            (None, Some(h)) if reached && power.is_finite() => {
                bounces += 1;
                if collisions + bounces > max_bounces {
                    return flight;
                }
                let sh = world.shapes.shading(&h);
                let Some(bsdf) = world.surfaces[h.object as usize].at(sh.uv).bsdf else {
                    return flight;
                };
                let frame = crate::bsdf::Frame::from_normal(sh.n);
                let wo = frame.to_local(-d);
                let toward = cone_toward(h.p, emitters.bounds());
                let Some((wi, weight, glossy)) = reflect(&bsdf, &frame, wo, h.n, toward, rng)
                else {
                    return flight;
                };
                power *= weight;
                // The first reflection sets the level Russian roulette
                // keeps: photons past the volumes start with powers that
                // differ by their distance and leave the surface with
                // about equal ones (see `reflect`); against their
                // starting power, roulette would make them unequal again.
                if bounces == 1 {
                    threshold = threshold.min(power.max_element());
                }
                if !roulette(&mut power, threshold, rng) {
                    return flight;
                }
                o = h.spawn(wi);
                d = wi;
                kind = if glossy {
                    RayKind::GLOSSY
                } else {
                    RayKind::DIFFUSE
                };
            }
            _ => return flight,
        }
    }
}

/// The cone of directions from `p` towards `sphere` (axis, cos of its half
/// angle), when `p` is outside it.
fn cone_toward(p: Vec3, sphere: crate::light::BoundingSphere) -> Option<(Vec3, f32)> {
    let to = sphere.center - p;
    let d2 = to.length_squared();
    let r2 = sphere.radius * sphere.radius;
    (d2 > r2).then(|| (to / d2.sqrt(), (1.0 - r2 / d2).max(0.0).sqrt()))
}

/// A photon's reflection off a surface: the direction it leaves in (world
/// space), the weight f·|cos θi|/pdf its power takes, and whether a glossy
/// lobe carries it. Outside the volumes' sphere, half the photons are sent
/// into the cone towards it and half by the BSDF, weighted by the balance
/// heuristic over both densities (one-sample MIS, Veach 1997, §9.2.4):
/// what a ground reflects into the smoke is then carried by many photons
/// of about equal power, instead of the few that the BSDF happens to send
/// there, with a power that grows with the square of their distance
/// ([`crate::light::Beyond`]). No direction is left out (the BSDF's
/// half reaches everywhere else), so the estimate stays unbiased.
fn reflect(
    bsdf: &crate::bsdf::Bsdf,
    frame: &crate::bsdf::Frame,
    wo: Vec3,
    ng: Vec3,
    toward: Option<(Vec3, f32)>,
    rng: &mut Rng,
) -> Option<(Vec3, Rgb, bool)> {
    let Some((axis, cos_max)) = toward else {
        let bs = bsdf.sample(wo, rng.next_f32(), rng.next_vec2())?;
        let wi = frame.to_world(bs.wi);
        if bs.pdf <= 0.0 || wi.dot(ng) <= 0.0 {
            return None;
        }
        return Some((wi, bs.f.total() * (bs.wi.z.abs() / bs.pdf), bs.glossy));
    };
    let pdf_cone = crate::sampling::uniform_cone_pdf(cos_max);
    let in_cone = |w: Vec3| w.dot(axis) > cos_max;
    let (uc, u) = (rng.next_f32(), rng.next_vec2());
    let (wi, wi_local) = if uc < 0.5 {
        let bs = bsdf.sample(wo, 2.0 * uc, u)?;
        let wi = frame.to_world(bs.wi);
        if bs.pdf <= 0.0 || wi.dot(ng) <= 0.0 {
            return None;
        }
        if bs.singular {
            // A mirror's direction: the cone never draws it.
            return Some((wi, bs.f.total() * (bs.wi.z.abs() / (0.5 * bs.pdf)), true));
        }
        (wi, bs.wi)
    } else {
        let l = crate::sampling::sample_uniform_cone(u, cos_max);
        let (t, b) = crate::sampling::coordinate_system(axis);
        let wi = (t * l.x + b * l.y + axis * l.z).normalize();
        (wi, frame.to_local(wi))
    };
    if wi_local.z <= 0.0 || wi.dot(ng) <= 0.0 {
        return None;
    }
    let f = bsdf.f(wo, wi_local);
    let pdf = 0.5 * bsdf.pdf(wo, wi_local) + if in_cone(wi) { 0.5 * pdf_cone } else { 0.0 };
    if pdf <= 0.0 || !pdf.is_finite() {
        return None;
    }
    let glossy = f.glossy.element_sum() > f.diffuse.element_sum();
    Some((wi, f.total() * (wi_local.z / pdf), glossy))
}
