//! Point estimates from a pass's photons, and the radii photons get for the
//! beam estimate.
//!
//! [`PointMap`] is a k-d tree (kiddo's immutable tree) over the photons:
//! the in-scattered radiance at x towards wo is Σ p(wo, wi)·Φ / (4/3·π·r³)
//! over the k nearest photons within the pass's radius, r the distance of
//! the farthest one used (or the search radius when fewer are found).
//! Photons store power after σs/σt, so this is σs·L_s already (each
//! photon's power scaled by σs at x over σs where it was stored).
//!
//! [`density_radii`] gives each photon the radius of the ball that holds k
//! photons at the photon density around it, counted in a grid of cells:
//! the distance of its k-th neighbour in expectation, in O(1) per photon.
//! An exact k-NN query per photon (kiddo, k = 32) measured 2.4 s for a
//! million photons on two cores, more than a whole pass should take.

use super::beam::RATIO_MAX;
use super::Photon;
use crate::medium::Media;
use crate::Rgb;
use glam::{IVec3, Vec3};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::num::NonZero;

/// The photons of a pass in a k-d tree, for point estimates.
pub struct PointMap {
    photons: Vec<Photon>,
    tree: ImmutableKdTree<f32, 3>,
}

impl PointMap {
    pub fn new(photons: Vec<Photon>) -> Option<Self> {
        if photons.is_empty() {
            return None;
        }
        let pts: Vec<[f32; 3]> = photons.iter().map(|p| p.p.to_array()).collect();
        let tree = ImmutableKdTree::new_from_slice(&pts).ok()?;
        Some(Self { photons, tree })
    }

    pub fn len(&self) -> usize {
        self.photons.len()
    }

    pub fn is_empty(&self) -> bool {
        self.photons.is_empty()
    }

    /// In-scattered radiance σs·L_s at `x` (where the mean of σs over
    /// channels is `sigma_s`) towards `wo` (unit, pointing away from x),
    /// from at most `k` photons within `radius`: the parts from light
    /// photons and from photons the media emitted.
    pub fn estimate(
        &self,
        media: &Media,
        x: Vec3,
        sigma_s: f32,
        wo: Vec3,
        k: u32,
        radius: f32,
    ) -> (Rgb, Rgb) {
        let k = NonZero::new(k.max(1) as usize).unwrap_or(NonZero::<usize>::MIN);
        let found = self
            .tree
            .query(&x.to_array())
            .nearest_n::<SquaredEuclidean<f32>>(k)
            .within(radius * radius)
            .unsorted()
            .execute();
        if found.is_empty() {
            return (Rgb::ZERO, Rgb::ZERO);
        }
        let r2 = if found.len() >= k.get() {
            found.iter().map(|f| f.distance).fold(0.0f32, f32::max)
        } else {
            radius * radius
        };
        let r2 = r2.max(1e-12);
        let volume = 4.0 / 3.0 * std::f32::consts::PI * r2 * r2.sqrt();
        let (mut light, mut emitted) = (Rgb::ZERO, Rgb::ZERO);
        for f in &found {
            let p = &self.photons[f.item as usize];
            if p.sigma_s <= 0.0 {
                continue;
            }
            let contribution = p.power
                * ((sigma_s / p.sigma_s).min(RATIO_MAX)
                    * media.phase_of(p.volume()).eval(wo, p.wi));
            if p.from_media() {
                emitted += contribution;
            } else {
                light += contribution;
            }
        }
        (light / volume, emitted / volume)
    }
}

/// For each photon, the radius of the ball that holds `k` photons at the
/// photon density around it (counted over the 3x3x3 cells of edge `cell`
/// around its own), at most `r_max`. The neighbourhood sums come from one
/// separable box filter over the count grid, so a photon costs one lookup.
pub fn density_radii(photons: &[Photon], k: u32, cell: f32, r_max: f32) -> Vec<f32> {
    if photons.is_empty() {
        return Vec::new();
    }
    let (lo, hi) = photons.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(a, b), p| (a.min(p.p), b.max(p.p)),
    );
    // At most 2^24 cells: coarser cells over a wide spread.
    let mut cell = cell.max(1e-6);
    let dims = |cell: f32| ((hi - lo) / cell).floor().as_ivec3() + 1;
    while dims(cell).as_i64vec3().element_product() > 1 << 24 {
        cell *= 2.0;
    }
    let n = dims(cell);
    let (nx, ny, nz) = (n.x as usize, n.y as usize, n.z as usize);
    let cell_of = |p: Vec3| {
        let c = ((p - lo) / cell)
            .floor()
            .as_ivec3()
            .clamp(IVec3::ZERO, n - 1);
        (c.z as usize * ny + c.y as usize) * nx + c.x as usize
    };
    let mut counts = vec![0u32; nx * ny * nz];
    for p in photons {
        counts[cell_of(p.p)] += 1;
    }
    // Box sums of width 3 along x, then y, then z.
    let mut tmp = vec![0u32; counts.len()];
    for (stride, len) in [(1, nx), (nx, ny), (nx * ny, nz)] {
        for (i, t) in tmp.iter_mut().enumerate() {
            let c = (i / stride) % len;
            let mut s = counts[i];
            if c > 0 {
                s += counts[i - stride];
            }
            if c + 1 < len {
                s += counts[i + stride];
            }
            *t = s;
        }
        std::mem::swap(&mut counts, &mut tmp);
    }
    let k = k.max(1) as f32;
    let scale = 3.0 * k * 27.0 * cell * cell * cell / (4.0 * std::f32::consts::PI);
    photons
        .par_iter()
        .map(|p| {
            let total = counts[cell_of(p.p)].max(1) as f32;
            (scale / total).cbrt().min(r_max)
        })
        .collect()
}

/// The median of `v` (0 for an empty slice).
pub fn median(v: &[f32]) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    let m = s.len() / 2;
    s.select_nth_unstable_by(m, |a, b| a.total_cmp(b));
    s[m]
}
