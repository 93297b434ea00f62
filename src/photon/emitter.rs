//! Where photons come from: every light, the environment and the emissive
//! media, chosen in proportion to their power.
//!
//! Lights at infinity (suns, the environment) emit from a disk of the
//! volumes' bounding sphere per direction, point and spot lights towards it
//! ([`crate::light::Light::sample_le`]). Where surfaces that reflect reach
//! beyond that sphere, the same lights also emit past it, towards the
//! surfaces ([`crate::light::Beyond`]): the light a ground bounces into
//! the smoke from outside the smoke's shadow. Those photons take at most
//! [`BEYOND_SHARE`] of the count (each carries its power divided by the
//! probability of its source, so the split changes noise, not the mean). Emissive media emit from their
//! majorant cells, split into boxes of about a voxel and chosen by emitted
//! power (the emission at a few points of the box times its volume, never
//! less than a small share of the cell's emission bound so that no box
//! that may emit is left out), then a uniform point in the box and an
//! isotropic direction: a photon from point x carries
//! 4π·ε_v(x)·V_box / P(box), ε_v being the radiance emitted per unit length
//! (σa·Le) by the volume v the box belongs to. Photons of fire then carry
//! nearly equal powers, however steeply its emission varies.
//! Each volume's boxes cover that volume's emission only: where volumes
//! overlap, each emits its own photons, and a photon must not carry the
//! others' emission too (the sum over the volumes at x would count the
//! overlap once per volume).

use crate::camera::Shutter;
use crate::light::{Beyond, BoundingSphere, EmittedRay};
use crate::medium::Media;
use crate::sampling::{self, Distribution1D, Rng};
use crate::world::World;
use crate::Rgb;
use glam::{IVec3, Vec3};
use rayon::prelude::*;
use std::f32::consts::PI;

#[derive(Debug, Clone, Copy)]
enum Source {
    Light(usize),
    Environment,
    Media,
    /// A light's photons past the volumes, towards the surfaces.
    LightBeyond(usize),
    EnvironmentBeyond,
}

/// The largest share of the photons that go past the volumes to the
/// surfaces around them. Most of them never reach a volume, and those that
/// do are light the smoke receives second hand (a tenth of its brightness
/// over a grey ground), so they get at most this, whatever their power.
pub const BEYOND_SHARE: f32 = 0.25;

/// A box of an emissive majorant cell, about a voxel.
#[derive(Debug, Clone, Copy)]
struct EmissiveBox {
    volume: usize,
    /// Index-space lower corner and edge.
    lo: Vec3,
    size: f32,
    /// World-space volume.
    volume_world: f32,
}

/// What a photon starts with.
#[derive(Debug, Clone, Copy)]
pub struct Emission {
    pub ray: EmittedRay,
    /// True for photons emitted by the media (their first collision is
    /// already light the march does not compute).
    pub from_media: bool,
    /// True for photons of a light at infinity (a sun, the environment):
    /// they start on a disk at the volumes' bounding sphere, and whatever
    /// lies between there and the light must still be able to stop them.
    pub from_infinity: bool,
}

/// Every photon source of a world, with the distribution that picks one.
#[derive(Debug, Clone)]
pub struct Emitters {
    bounds: BoundingSphere,
    /// The volumes' sphere and the one around them and the surfaces that
    /// reflect, when the latter is larger.
    beyond: Option<Beyond>,
    sources: Vec<Source>,
    pick: Distribution1D,
    boxes: Vec<EmissiveBox>,
    pick_box: Option<Distribution1D>,
    /// Total power per source (W, the estimate used to pick them).
    power: Vec<Rgb>,
}

#[inline]
fn avg(c: Rgb) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

impl Emitters {
    /// The sources of `world`; `None` when nothing emits towards the
    /// volumes.
    pub fn new(world: &World) -> Option<Self> {
        Self::with(world, true)
    }

    /// [`Self::new`], with or without the environment (which the photon
    /// integrator may leave to camera paths).
    pub fn with(world: &World, environment: bool) -> Option<Self> {
        let (lo, hi) = world.media.bounds()?;
        let bounds = BoundingSphere::of_box(lo, hi);
        let mut sources = Vec::new();
        let mut power = Vec::new();
        for (i, l) in world.lights.iter().enumerate() {
            let p = l.power(bounds);
            if avg(p) > 0.0 {
                sources.push(Source::Light(i));
                power.push(p);
            }
        }
        if environment && !world.environment.is_black() {
            let p = world.environment.power(bounds);
            if avg(p) > 0.0 {
                sources.push(Source::Environment);
                power.push(p);
            }
        }
        let (boxes, weights, _) = emissive_boxes(&world.media, world.camera.shutter());
        let pick_box = if weights.iter().any(|&w| w > 0.0) {
            let total: f32 = weights.iter().sum();
            sources.push(Source::Media);
            power.push(Rgb::splat(4.0 * PI * total));
            Some(Distribution1D::new(&weights))
        } else {
            None
        };
        if sources.is_empty() {
            return None;
        }
        let mut weights: Vec<f32> = power.iter().map(|p| avg(*p)).collect();
        let beyond = beyond_volumes(world, lo, hi);
        if let Some(b) = beyond {
            let before = sources.len();
            for (i, l) in world.lights.iter().enumerate() {
                let p = l.power_beyond(b);
                if avg(p) > 0.0 {
                    sources.push(Source::LightBeyond(i));
                    power.push(p);
                }
            }
            if environment && !world.environment.is_black() {
                let p = world.environment.power_beyond(b);
                if avg(p) > 0.0 {
                    sources.push(Source::EnvironmentBeyond);
                    power.push(p);
                }
            }
            // Their weights by power, scaled down to BEYOND_SHARE of the
            // whole at most.
            let inner: f32 = weights.iter().sum();
            let outer: f32 = power[before..].iter().map(|p| avg(*p)).sum();
            let most = inner * BEYOND_SHARE / (1.0 - BEYOND_SHARE);
            let scale = if outer > most { most / outer } else { 1.0 };
            weights.extend(power[before..].iter().map(|p| avg(*p) * scale));
        }
        let pick = Distribution1D::new(&weights);
        Some(Self {
            bounds,
            beyond,
            sources,
            pick,
            boxes,
            pick_box,
            power,
        })
    }

    /// The sphere photons from infinity aim at.
    pub fn bounds(&self) -> BoundingSphere {
        self.bounds
    }

    /// Total power of all sources (W, as estimated for picking them).
    pub fn total_power(&self) -> Rgb {
        self.power.iter().copied().sum()
    }

    /// The shares of the total power (mean over channels) that the media's
    /// emission and the environment emit: (media, environment).
    pub fn shares(&self) -> (f32, f32) {
        let total: f32 = self.power.iter().map(|p| avg(*p)).sum();
        if total <= 0.0 {
            return (0.0, 0.0);
        }
        let of = |want: fn(&Source) -> bool| {
            self.sources
                .iter()
                .zip(&self.power)
                .filter(|(s, _)| want(s))
                .map(|(_, p)| avg(*p))
                .sum::<f32>()
                / total
        };
        (
            of(|s| matches!(s, Source::Media)),
            of(|s| matches!(s, Source::Environment)),
        )
    }

    /// Samples a photon at `time` (frames from the frame: where moving
    /// volumes emit): its ray and its power divided by the probability of
    /// the whole sample (source, position, direction). Divide by the number
    /// of photons emitted for the power each one carries.
    pub fn sample(&self, world: &World, time: f32, rng: &mut Rng) -> Option<Emission> {
        let (_, p_source, k) = self.pick.sample_continuous(rng.next_f32());
        let p_source = p_source / self.pick.count() as f32;
        if p_source <= 0.0 {
            return None;
        }
        let (u, v) = (rng.next_vec2(), rng.next_vec2());
        let (ray, from_media, from_infinity) = match self.sources[k] {
            Source::Light(i) => {
                let light = &world.lights[i];
                let infinite = matches!(light, crate::light::Light::Sun { .. });
                (light.sample_le(self.bounds, u, v)?, false, infinite)
            }
            Source::Environment => (world.environment.sample_le(self.bounds, u, v)?, false, true),
            Source::LightBeyond(i) => {
                let light = &world.lights[i];
                let infinite = matches!(light, crate::light::Light::Sun { .. });
                (light.sample_le_beyond(self.beyond?, u, v)?, false, infinite)
            }
            Source::EnvironmentBeyond => (
                world.environment.sample_le_beyond(self.beyond?, u, v)?,
                false,
                true,
            ),
            Source::Media => (
                self.sample_media(&world.media, time, u, v, rng)?,
                true,
                false,
            ),
        };
        Some(Emission {
            ray: EmittedRay {
                power: ray.power / p_source,
                ..ray
            },
            from_media,
            from_infinity,
        })
    }

    fn sample_media(
        &self,
        media: &Media,
        time: f32,
        u: glam::Vec2,
        v: glam::Vec2,
        rng: &mut Rng,
    ) -> Option<EmittedRay> {
        let dist = self.pick_box.as_ref()?;
        let (_, pdf, i) = dist.sample_continuous(rng.next_f32());
        let p_box = pdf / dist.count() as f32;
        let c = self.boxes[i];
        let vol = &media.volumes()[c.volume];
        let pi = c.lo + Vec3::new(u.x, u.y, v.x) * c.size;
        let p = vol.world_from_index().transform_point3(pi);
        // This volume's emission only, as the box's weight (see the module
        // docs): `media.eval` would add the overlapping volumes' too. The
        // boxes cover a moving volume's emission over the whole shutter
        // (their bounds are dilated by its motion), so sampling them and
        // weighting by the emission at `time` is unbiased.
        let e = vol.eval(p, time).emission;
        if e.max_element() <= 0.0 || p_box <= 0.0 {
            return None;
        }
        let d = sampling::sample_uniform_sphere(glam::Vec2::new(v.y, rng.next_f32()));
        Some(EmittedRay {
            o: p,
            d,
            power: e * (4.0 * PI * c.volume_world / p_box),
        })
    }
}

/// The volumes' sphere and the sphere around them and every surface that
/// reflects light, when the surfaces reach past the volumes' (by more than
/// a hundredth of its radius); `None` otherwise.
fn beyond_volumes(world: &World, lo: Vec3, hi: Vec3) -> Option<Beyond> {
    let inner = BoundingSphere::of_box(lo, hi);
    let (mut blo, mut bhi) = (lo, hi);
    for (i, surface) in world.surfaces.iter().enumerate() {
        if !surface.reflects() {
            continue;
        }
        if let Some((a, b)) = world.shapes.object_bounds(i) {
            blo = blo.min(a);
            bhi = bhi.max(b);
        }
    }
    let outer = BoundingSphere::of_box(blo, bhi);
    let reaches = (outer.center - inner.center).length() + outer.radius;
    (reaches.is_finite() && reaches > 1.01 * inner.radius).then_some(Beyond { inner, outer })
}

/// Boxes at most over every volume (about 40 bytes each, so 40 MB): a
/// cell of 4 voxels is split into 4^3 boxes of a voxel unless the cells are
/// so many that this would pass it.
const MAX_BOXES: usize = 1 << 20;

/// The least weight of a box, as a fraction of its cell's emission bound.
/// It keeps every point that may emit sampled, so the estimate stays
/// unbiased where the box's points miss its emission (a nonlinear
/// temperature, or a moving volume's advected lookups); small, because
/// whatever the floors add to a cell is spent where little is emitted.
/// With a twentieth, as when whole cells were sampled, the floors took
/// most of a fire's cells: E[Φ²]/E[Φ]² was 1.84 on the test volume of
/// `tests/photon.rs::media_photons_carry_the_emitted_power_evenly`
/// against 1.19 with this, and at 10 s the variance 10 % more on the
/// bench's fire, 4 % on its smoke + fire frame.
const FLOOR: f32 = 0.002;

/// The least weight of a box larger than a voxel (when the cells are too
/// many to split finely, [`MAX_BOXES`]), as cells had before they were
/// split: its nine points can then miss a voxel that emits.
const COARSE_FLOOR: f32 = 0.05;

/// The emissive boxes of every volume and their weights (emitted power
/// estimate × world volume). Each emissive majorant cell is split into
/// boxes of about a voxel ([`MAX_BOXES`] at most), each weighted by its
/// emission at its centre and, on average, its corners, at least
/// [`FLOOR`] × its cell's bound ([`COARSE_FLOOR`] for boxes larger
/// than a voxel). Fire's emission follows the temperature
/// steeply (blackbody), so within a 4-voxel cell it varies by orders of
/// magnitude, and a photon from a uniform point of the cell carried a power
/// that varied with it: over the Blender smoke + fire frame's media photons
/// E[Φ²]/E[Φ]² was 2.6, and the fire's scattered light was two thirds of
/// the photon image's variance (docs/performance.md, "Photons from fire").
/// For trilinear fields of values ≥ 0 (raw emission, per-voxel blackbody
/// radiance, flame) the centre or a corner of a box of a voxel sees every
/// voxel whose lookups reach into the box, so a box estimated dark is dark.
///
/// With a shutter (a moving volume) the points are evaluated at four times
/// spread over the shutter: a moving volume's cells and their bounds are
/// dilated by its motion, so around the emitting cells lies a shell that
/// may emit at some time.
/// Each emissive cell in the order its boxes come: (volume, cell, boxes
/// per edge).
type BoxLayout = Vec<(usize, IVec3, usize)>;

fn emissive_boxes(
    media: &Media,
    shutter: Option<Shutter>,
) -> (Vec<EmissiveBox>, Vec<f32>, BoxLayout) {
    let times: Vec<f32> = match shutter {
        Some(s) => (0..4).map(|i| s.time((i as f32 + 0.5) / 4.0)).collect(),
        None => vec![0.0],
    };
    // Every emissive cell first, then how finely they can be split.
    let mut emissive = Vec::new();
    for (vi, v) in media.volumes().iter().enumerate() {
        let g = v.majorant_grid();
        if !g.is_emissive() {
            continue;
        }
        let res = g.resolution();
        for z in 0..res.z {
            for y in 0..res.y {
                for x in 0..res.x {
                    let c = IVec3::new(x, y, z);
                    let bound = g.cell_emission(c);
                    if bound > 0.0 {
                        emissive.push((vi, c, bound));
                    }
                }
            }
        }
    }
    if emissive.is_empty() {
        return (Vec::new(), Vec::new(), Vec::new());
    }
    let budget = (MAX_BOXES / emissive.len()).max(1);
    let most = (budget as f32).cbrt().floor().max(1.0) as usize;
    // Each cell's boxes per edge, in the order the boxes come.
    let layout = emissive
        .iter()
        .map(|&(vi, c, _)| {
            let size = media.volumes()[vi].majorant_grid().cell_box(c).1;
            (vi, c, (size.round().max(1.0) as usize).min(most))
        })
        .collect();
    let (boxes, weights) = emissive
        .par_iter()
        .flat_map_iter(|&(vi, c, bound)| {
            let v = &media.volumes()[vi];
            let (lo, size) = v.majorant_grid().cell_box(c);
            let n = (size.round().max(1.0) as usize).min(most);
            let edge = size / n as f32;
            let det = v.world_from_index().matrix3.determinant().abs();
            let volume_world = det * edge * edge * edge;
            let floor = if edge <= 1.0 { FLOOR } else { COARSE_FLOOR };
            let at = |pi: Vec3| -> f32 {
                let p = v.world_from_index().transform_point3(pi);
                times
                    .iter()
                    .map(|&t| avg(v.eval(p, t).emission.max(Rgb::ZERO)))
                    .sum::<f32>()
                    / times.len() as f32
            };
            // The lattice of the boxes' corners, shared between them.
            let m = n + 1;
            let corner: Vec<f32> = (0..m * m * m)
                .map(|k| {
                    let o = Vec3::new((k % m) as f32, ((k / m) % m) as f32, (k / (m * m)) as f32);
                    at(lo + o * edge)
                })
                .collect();
            (0..n * n * n).map(move |k| {
                let (x, y, z) = (k % n, (k / n) % n, k / (n * n));
                let o = Vec3::new(x as f32, y as f32, z as f32);
                let corners: f32 = (0..8)
                    .map(|j| {
                        corner[(z + (j >> 2)) * m * m + (y + ((j >> 1) & 1)) * m + x + (j & 1)]
                    })
                    .sum::<f32>()
                    / 8.0;
                let mean = 0.5 * (corners + at(lo + (o + 0.5) * edge));
                let b = EmissiveBox {
                    volume: vi,
                    lo: lo + o * edge,
                    size: edge,
                    volume_world,
                };
                (b, mean.max(floor * bound) * volume_world)
            })
        })
        .unzip();
    (boxes, weights, layout)
}

/// The media's emission as a light to sample from a point (next-event
/// estimation from a surface: the fire lighting the ground), over the
/// boxes the photons of the media come from ([`emissive_boxes`]): a box by
/// its weight, a uniform point in it. [`Self::pdf`] gives the density of
/// any point, for multiple importance sampling against the rays that find
/// the emission by flying through it.
#[derive(Debug, Clone)]
pub struct MediaLight {
    boxes: Vec<EmissiveBox>,
    /// Each box's probability.
    prob: Vec<f32>,
    pick: Distribution1D,
    /// Per volume: the first box of each emissive majorant cell (by the
    /// cell's linear index) and the boxes per cell edge.
    cells: Vec<(std::collections::HashMap<u32, u32>, usize)>,
}

/// A point of the media's emission drawn by [`MediaLight::sample`].
#[derive(Debug, Clone, Copy)]
pub struct MediaLightSample {
    pub p: Vec3,
    /// The media's emission (radiance per unit length) at `p`.
    pub emission: Rgb,
    /// The media's σt at `p` (mean over channels).
    pub sigma_t: f32,
    /// The density of `p` (per unit volume) over every volume's boxes.
    pub pdf: f32,
}

impl MediaLight {
    /// The emissive media of `media` (`None` when nothing emits).
    pub fn new(media: &Media, shutter: Option<Shutter>) -> Option<Self> {
        let (boxes, weights, layout) = emissive_boxes(media, shutter);
        let total: f32 = weights.iter().sum();
        if boxes.is_empty() || total.is_nan() || total <= 0.0 {
            return None;
        }
        let prob = weights.iter().map(|w| w / total).collect();
        let mut cells: Vec<(std::collections::HashMap<u32, u32>, usize)> = media
            .volumes()
            .iter()
            .map(|_| (std::collections::HashMap::new(), 1))
            .collect();
        let mut first = 0u32;
        for (vi, c, n) in layout {
            let res = media.volumes()[vi].majorant_grid().resolution();
            let linear = ((c.z * res.y + c.y) * res.x + c.x) as u32;
            cells[vi].0.insert(linear, first);
            cells[vi].1 = n;
            first += (n * n * n) as u32;
        }
        debug_assert_eq!(first as usize, boxes.len());
        Some(Self {
            boxes,
            prob,
            pick: Distribution1D::new(&weights),
            cells,
        })
    }

    /// A point of the media's emission at `time`, or `None` where the box
    /// drawn does not emit there.
    pub fn sample(&self, media: &Media, time: f32, rng: &mut Rng) -> Option<MediaLightSample> {
        let (_, _, i) = self.pick.sample_continuous(rng.next_f32());
        let c = self.boxes[i];
        let vol = &media.volumes()[c.volume];
        let u = rng.next_vec2();
        let pi = c.lo + Vec3::new(u.x, u.y, rng.next_f32()) * c.size;
        let p = vol.world_from_index().transform_point3(pi);
        // Every volume's emission at p over the density of p through
        // every volume's boxes (a mixture): where volumes overlap, each
        // one's boxes cover its own emission, and together they cover all.
        let m = media.eval(p, time);
        if m.emission.max_element() <= 0.0 {
            return None;
        }
        let pdf = self.pdf(media, p);
        (pdf > 0.0).then_some(MediaLightSample {
            p,
            emission: m.emission,
            sigma_t: avg(m.sigma_t()),
            pdf,
        })
    }

    /// The density with which [`Self::sample`] draws world point `p` (per
    /// unit volume), summed over the volumes whose boxes hold it.
    pub fn pdf(&self, media: &Media, p: Vec3) -> f32 {
        let mut pdf = 0.0;
        for (vi, (cells, n)) in self.cells.iter().enumerate() {
            if cells.is_empty() {
                continue;
            }
            let vol = &media.volumes()[vi];
            let g = vol.majorant_grid();
            let pi = vol.index_from_world().transform_point3(p);
            let (origin, edge) = g.cell_box(IVec3::ZERO);
            let c = ((pi - origin) / edge).floor().as_ivec3();
            let res = g.resolution();
            if c.cmplt(IVec3::ZERO).any() || c.cmpge(res).any() {
                continue;
            }
            let linear = ((c.z * res.y + c.y) * res.x + c.x) as u32;
            let Some(&first) = cells.get(&linear) else {
                continue;
            };
            let lo = origin + (c * g.cell()).as_vec3();
            let sub = edge / *n as f32;
            let k = ((pi - lo) / sub)
                .floor()
                .as_ivec3()
                .clamp(IVec3::ZERO, IVec3::splat(*n as i32 - 1));
            let b = first as usize + ((k.z as usize * n + k.y as usize) * n + k.x as usize);
            let bx = &self.boxes[b];
            pdf += self.prob[b] / bx.volume_world;
        }
        pdf
    }
}
