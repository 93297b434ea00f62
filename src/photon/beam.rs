//! The beam radiance estimate (Jarosz, Zwicker & Jensen 2008, "The beam
//! radiance estimate for volumetric photon mapping"): instead of point
//! queries at every step of a camera ray, one traversal gathers every
//! photon whose sphere the ray crosses.
//!
//! A photon of radius r at perpendicular distance d from the ray and
//! distance t along it adds K(d)·T(t)·p(wo, wi)·Φ, with K the constant 3-D
//! kernel 1/(4/3·π·r³) integrated along the chord: K(d) = 3/(2πr²)·√(1 −
//! d²/r²), which integrates to 1 over the disk, times σs at the ray's point
//! over σs at the photon (see `crate::photon`). The photons' spheres go
//! into a compressed wide BVH (`obvhs`' CWBVH, PLOC-built).
//!
//! In dense media a kernel may be flattened ([`Flat`], [`flatten`]): an
//! ellipsoid of radius r across the gradient of σs and r/s along it. The
//! camera sees a dense cloud's outer mean free path only (a quarter of a
//! voxel on the dense reference cloud, against kernels of several voxels),
//! and a sphere there reaches out of the medium, where no photon is
//! stored, and into its depths: seen at a slant, a sphere's disk across
//! the ray is half outside. Flattened along the gradient the kernel stays
//! in the layer the camera sees.

use super::Photon;
use crate::medium::Media;
use crate::Rgb;
use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray;
use obvhs::BvhBuildParams;
use std::f32::consts::PI;
use std::time::Duration;

/// The largest σs ratio (where gathered over where stored) a photon is
/// weighted by in the first pass: a photon kept in a cloud's thin fringe and
/// gathered where it is dense would otherwise be a firefly (measured on the
/// dense reference cloud: 14 passes, relMSE 6.1e-3 uncapped, 3.9e-3 and
/// 4.1e-3 capped at 4 or 16; capped at 1, the image is 3.5 % too dark).
/// The beam estimate's cap grows over passes (the photon integrator's
/// `ratio_max`), so the light it cuts goes to zero; the point estimate
/// keeps this one.
pub const RATIO_MAX: f32 = 16.0;

/// A photon's kernel flattened along `axis` (unit): radius r across it,
/// r / `squash` along it (`squash` ≥ 1; 1 is the sphere).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Flat {
    pub axis: Vec3,
    pub squash: f32,
}

impl Flat {
    pub const SPHERE: Flat = Flat {
        axis: Vec3::Z,
        squash: 1.0,
    };
}

/// The kernel of a photon at `v` from the ray's origin (radius `r`, shape
/// `flat`), integrated along the ray `t d` (`d` unit): the chord through
/// the ellipsoid over its volume, 4/3·π·r²·(r/s). With the photon's
/// projection on the ray, where the beam estimate takes the transmittance
/// and σs; `None` when the ray misses the kernel. For the sphere this is
/// Jarosz et al.'s K(d) = 3/(2πr²)·√(1 − d²/r²); over the plane across the
/// ray it integrates to 1 whatever the shape and the ray's direction.
#[inline]
pub fn chord_kernel(v: Vec3, d: Vec3, r: f32, flat: Flat) -> Option<(f32, f32)> {
    let t = v.dot(d);
    let r2 = r * r;
    if flat.squash <= 1.0 {
        let d2 = v.length_squared() - t * t;
        if d2 >= r2 {
            return None;
        }
        return Some((t, 3.0 / (2.0 * PI * r2) * (1.0 - d2 / r2).max(0.0).sqrt()));
    }
    // In the space where the ellipsoid is the sphere of radius r (lengths
    // along the axis times `squash`), the ray is `t d'`.
    let stretch = flat.squash - 1.0;
    let ds = d + flat.axis * (stretch * d.dot(flat.axis));
    let vs = v + flat.axis * (stretch * v.dot(flat.axis));
    let dl2 = ds.length_squared();
    let ts = vs.dot(ds) / dl2;
    let d2 = vs.length_squared() - ts * ts * dl2;
    if d2 >= r2 {
        return None;
    }
    // Chord 2·√(r² − d²)/|d'| in t, over the volume 4/3·π·r³/s.
    let chord = 2.0 * (r2 - d2).sqrt() / dl2.sqrt();
    Some((t, chord * 3.0 * flat.squash / (4.0 * PI * r2 * r)))
}

/// The kernel shapes of `photons` (radii `radius`) at `time`: each
/// flattened along the gradient of σs, measured by central differences
/// half a radius either side, so that its thickness along it is about the
/// length over which σs changes by its own value, σs / |∇σs|, within
/// [r / `max_squash`, r]. Empty (all spheres, as [`BeamMap::new`] takes
/// them) when `max_squash` is at most 1.
pub fn flatten(
    photons: &[Photon],
    radius: &[f32],
    media: &Media,
    time: f32,
    max_squash: f32,
) -> Vec<Flat> {
    use rayon::prelude::*;
    if max_squash <= 1.0 {
        return Vec::new();
    }
    photons
        .par_iter()
        .zip(radius)
        .map(|(p, &r)| {
            if p.sigma_s <= 0.0 {
                return Flat::SPHERE;
            }
            let h = 0.5 * r;
            let s = |q: Vec3| media.eval(q, time).sigma_s.element_sum() / 3.0;
            let diff = |e: Vec3| s(p.p + e * h) - s(p.p - e * h);
            let g = Vec3::new(diff(Vec3::X), diff(Vec3::Y), diff(Vec3::Z)) / (2.0 * h);
            let len = g.length();
            if len.is_nan() || len <= 0.0 {
                return Flat::SPHERE;
            }
            Flat {
                axis: g / len,
                squash: (r * len / p.sigma_s).clamp(1.0, max_squash),
            }
        })
        .collect()
}

/// A pass's photons with their radii, in BVH order.
pub struct BeamMap {
    photons: Vec<Photon>,
    radius: Vec<f32>,
    /// The kernels' shapes; empty when all are spheres.
    flat: Vec<Flat>,
    /// The cap on the σs ratio in this pass.
    ratio_max: f32,
    /// The mean cosine of the angular kernel that blurs the photons'
    /// directions (1: none; [`crate::phase::PhaseFunction::blurred`]).
    angular: f32,
    bvh: CwBvh,
}

impl BeamMap {
    /// Builds the BVH over the spheres (`radius[i]` around photon `i`,
    /// flattened as `flat[i]` says when `flat` is not empty: the bounds
    /// stay the spheres'); `None` when there are no photons. `ratio_max`
    /// caps the σs ratio a photon is weighted by (see [`RATIO_MAX`]);
    /// `angular` is the mean cosine of the angular kernel over the photons'
    /// directions (1: none).
    pub fn new(
        photons: Vec<Photon>,
        radius: Vec<f32>,
        flat: Vec<Flat>,
        ratio_max: f32,
        angular: f32,
    ) -> Option<Self> {
        debug_assert!(flat.is_empty() || flat.len() == photons.len());
        if photons.is_empty() {
            return None;
        }
        let aabbs: Vec<Aabb> = photons
            .iter()
            .zip(&radius)
            .map(|(p, &r)| {
                let c = Vec3A::from(p.p);
                Aabb::new(c - r, c + r)
            })
            .collect();
        let mut t = Duration::ZERO;
        let bvh = build_cwbvh(&aabbs, BvhBuildParams::very_fast_build(), &mut t);
        // Photons in the BVH's leaf order: a hit's index is the photon's.
        let order = &bvh.primitive_indices;
        let photons = order.iter().map(|&i| photons[i as usize]).collect();
        let radius = order.iter().map(|&i| radius[i as usize]).collect();
        let flat = if flat.is_empty() {
            flat
        } else {
            order.iter().map(|&i| flat[i as usize]).collect()
        };
        Some(Self {
            photons,
            radius,
            flat,
            ratio_max,
            angular,
            bvh,
        })
    }

    pub fn len(&self) -> usize {
        self.photons.len()
    }

    pub fn is_empty(&self) -> bool {
        self.photons.is_empty()
    }

    /// Bytes taken (photons, radii, BVH nodes).
    pub fn memory_bytes(&self) -> usize {
        self.photons.capacity() * std::mem::size_of::<Photon>()
            + self.radius.capacity() * 4
            + self.flat.capacity() * std::mem::size_of::<Flat>()
            + self.bvh.nodes.capacity() * std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>()
            + self.bvh.primitive_indices.capacity() * 4
    }

    /// The in-scattered light the camera ray `o + t d` (`d` unit) gathers
    /// over `[0, t_max)`, each photon weighted by `along(t)` at its closest
    /// point on the ray: (the transmittance from the camera there, σs there
    /// as the mean over channels), and by the phase function blurred by the
    /// map's angular kernel. Returns (from light photons, from media
    /// photons).
    pub fn gather(
        &self,
        media: &Media,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        along: impl Fn(f32) -> (Rgb, f32),
    ) -> (Rgb, Rgb) {
        let (mut light, mut emitted) = (Rgb::ZERO, Rgb::ZERO);
        if t_max.is_nan() || t_max <= 0.0 {
            return (light, emitted);
        }
        let wo = -d;
        let ray = Ray::new(Vec3A::from(o), Vec3A::from(d), 0.0, t_max);
        self.bvh.ray_traverse_anyhit(ray, |_, id| {
            let p = &self.photons[id];
            let r = self.radius[id];
            let flat = self.flat.get(id).copied().unwrap_or(Flat::SPHERE);
            let Some((t, k)) = chord_kernel(p.p - o, d, r, flat) else {
                return;
            };
            if t < 0.0 || t >= t_max {
                return;
            }
            let (tr, sigma_s) = along(t);
            if sigma_s <= 0.0 || p.sigma_s <= 0.0 {
                return;
            }
            let c = p.power
                * (k * (sigma_s / p.sigma_s).min(self.ratio_max)
                    * media
                        .phase_of(p.volume())
                        .blurred(self.angular)
                        .eval(wo, p.wi))
                * tr;
            if p.from_media() {
                emitted += c;
            } else {
                light += c;
            }
        });
        (light, emitted)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Over a grid of parallel rays across it, a kernel integrates to 1,
    /// sphere or flattened, whatever its axis and the rays' direction: the
    /// estimate neither makes nor loses light (a wrong volume, or the chord
    /// measured in the stretched space, fails this by the squash).
    #[test]
    fn a_kernel_integrates_to_one_over_the_rays_across_it() {
        let r = 0.3;
        for (axis, squash, d) in [
            (Vec3::Z, 1.0, Vec3::X),
            (Vec3::Z, 2.0, Vec3::Z),
            (Vec3::Z, 2.0, Vec3::X),
            (
                Vec3::new(1.0, 2.0, -0.5).normalize(),
                3.0,
                Vec3::new(0.3, -0.8, 0.5).normalize(),
            ),
            (Vec3::Y, 8.0, Vec3::new(0.0, 0.1, 1.0).normalize()),
        ] {
            let flat = Flat { axis, squash };
            let (u, w) = d.any_orthonormal_pair();
            let n = 400;
            let cell = 2.0 * r / n as f32;
            let mut sum = 0.0f64;
            for i in 0..n {
                for j in 0..n {
                    let a = -r + (i as f32 + 0.5) * cell;
                    let b = -r + (j as f32 + 0.5) * cell;
                    // The ray starts well before the kernel.
                    let o = u * a + w * b - d * 2.0;
                    if let Some((t, k)) = chord_kernel(-o, d, r, flat) {
                        assert!((t - 2.0).abs() < r, "projection {t}");
                        sum += (k * cell * cell) as f64;
                    }
                }
            }
            assert!(
                (sum - 1.0).abs() < 2e-3,
                "axis {axis}, squash {squash}, ray {d}: integrates to {sum}"
            );
        }
    }

    /// A photon's light reaches the camera ray weighted by the phase
    /// function blurred by the map's angular kernel, HG(g·s) for an HG
    /// medium (the kernel the photon integrator shrinks over passes), and
    /// unblurred with s = 1: a gather that ignored the kernel, or blurred
    /// twice, fails.
    #[test]
    fn the_gather_weighs_a_photon_by_the_blurred_phase_function() {
        use crate::medium::{ExtraGrids, Material, Volume};
        use crate::phase::{henyey_greenstein, PhaseFunction};
        let volume = Volume::new(
            "cloud",
            crate::generate::cloud(8, 1).unwrap(),
            ExtraGrids::default(),
            Material::Raw {
                sigma_a: Rgb::splat(0.1),
                sigma_s: Rgb::splat(2.0),
                emission: Rgb::ZERO,
                phase: PhaseFunction::hg(0.8),
            },
            glam::DAffine3::IDENTITY,
        )
        .unwrap();
        let media = Media::new(vec![volume]);
        let wi = Vec3::new(0.9, 0.2, -0.3).normalize();
        let photon = Photon {
            p: Vec3::new(0.1, 0.0, 0.0),
            wi,
            power: Rgb::new(1.0, 2.0, 3.0),
            sigma_s: 2.0,
            tag: 0,
        };
        let (o, d, r) = (Vec3::new(-1.0, 0.03, 0.02), Vec3::X, 0.1);
        let (_, k) = chord_kernel(photon.p - o, d, r, Flat::SPHERE).unwrap();
        for s in [1.0, 0.75, 0.5] {
            let map = BeamMap::new(vec![photon], vec![r], Vec::new(), RATIO_MAX, s).unwrap();
            // σs where gathered equals σs where stored: a ratio of 1.
            let (light, emitted) = map.gather(&media, o, d, 10.0, |_| (Rgb::ONE, 2.0));
            let want = photon.power * (k * henyey_greenstein((-d).dot(wi), 0.8 * s));
            assert!(
                (light - want).abs().max_element() < 1e-5 * want.max_element(),
                "s = {s}: {light} against {want}"
            );
            assert_eq!(emitted, Rgb::ZERO);
        }
    }
}
