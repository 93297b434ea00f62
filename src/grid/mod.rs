//! A sparse voxel grid of our own, built for the renderer's hot paths.
//!
//! Layout (see ARCHITECTURE.md for why):
//! - voxel values live in 8^3 *bricks* (OpenVDB's leaf size and voxel order,
//!   `offset = (x&7)<<6 | (y&7)<<3 | (z&7)`), so a whole leaf copies from
//!   OpenVDB with one `memcpy`, stored aligned to 2048 bytes
//!   ([`BrickValues`]) so a lookup's eight corners span as few cache lines
//!   as the layout allows;
//! - a dense *top index* covers the grid's extent in 128^3-voxel regions; each
//!   entry is a constant (background, or a 128^3/4096^3 tile) or a *node* of
//!   16^3 slots; a slot is a constant (background or an 8^3 tile) or a brick;
//! - when the extent is compact (every simulation cache we have seen), a
//!   *flat index* holds the same slots as one dense array of 8^3 blocks, so
//!   a lookup takes one dependent read before the values instead of two.
//!   Its size is capped near that of the top index and nodes, so a grid
//!   with far-apart parts keeps the two-level walk instead of a huge array.
//!
//! A lookup is one or two array reads and a bounds check, with no hashing,
//! so the per-sample cost is O(1). Per-brick min/max ranges serve the
//! majorants of the renderer (`range_in_box`).
//!
//! Lookups come one at a time (`sample_index`, what tracking along a ray
//! does) or in batches of independent points (`sample_index_batch`), which
//! prefetch the corners ahead of the interpolation and, for `f32` grids on
//! processors with AVX2, run eight points per instruction
//! (`batch_avx2`): in grids larger than the caches that is 2-4 times the
//! single lookups' rate.
//!
//! Sampling is trilinear between voxel centres, exactly as OpenVDB's
//! `tools::BoxSampler`: index (i,j,k) is a voxel centre and world =
//! `world_from_index` · index.

#[cfg(target_arch = "x86_64")]
mod batch_avx2;
mod bricks;
mod build;
mod lookup;
mod range;
mod value;

pub use bricks::BrickValues;
pub use build::{GridParts, Tile};
pub use value::GridValue;

// Helpers the submodules share (each reaches them through `super::*`).
use lookup::{linear_index, prefetch_line, prefetch_stencil, slot_offset};

use crate::error::{Error, Result};
use glam::{BVec3, DAffine3, DVec3, IVec3, Vec3};
use rayon::prelude::*;

/// Voxels along an edge of a brick (OpenVDB's leaf node).
pub const BRICK_DIM: i32 = 8;
/// Voxels in a brick.
pub const BRICK_VOXELS: usize = 512;
const LOG2_NODE_VOXELS: i32 = 7; // a node covers 128^3 voxels = 16^3 bricks
const NODE_SLOTS: usize = 4096;
/// Slot and top-index codes with this bit set are constants.
const CONST_BIT: u32 = 1 << 31;
/// `constants[0]` is the background, so "empty" is constant 0.
const EMPTY: u32 = CONST_BIT;
/// Index coordinates are inside ±2^30 (OpenVDB's are 32-bit): points
/// beyond, and NaN, lie outside every grid, and the integer casts of the
/// lookups never overflow.
const COORD_LIMIT: f32 = (1u32 << 30) as f32;
/// The largest top index we allocate (entries of 4 bytes): 2^24 regions of
/// 128^3 voxels, i.e. an extent of about 32768^3 voxels.
const MAX_TOP_ENTRIES: i64 = 1 << 24;

/// A sparse grid of `f32` or `Vec3` values; see the module documentation.
#[derive(Debug, Clone)]
pub struct Grid<T: GridValue> {
    name: String,
    class: String,
    background: T,
    world_from_index: DAffine3,
    /// For a diagonal map this holds 1/s and -t (see `world_to_index`).
    index_from_world: DAffine3,
    diagonal: bool,
    values: BrickValues<T>,
    brick_origins: Vec<IVec3>,
    masks: Vec<[u64; 8]>,
    /// Per brick: [min, max] over all 512 values (active or not: trilinear
    /// interpolation reads them all).
    ranges: Vec<[T; 2]>,
    tiles: Vec<Tile<T>>,
    /// `constants[0]` is the background, then one entry per tile. They are
    /// also the tail of `values`, after the bricks (from `brick_count() *
    /// 512` on), so that the AVX2 batch reads a brick value or a constant
    /// by one load from one base (`batch_avx2`).
    constants: Vec<T>,
    /// Top index origin and size in units of 128 voxels.
    top_origin: IVec3,
    top_dims: IVec3,
    top: Vec<u32>,
    /// 4096 slots per node.
    nodes: Vec<u32>,
    /// The slots again as one dense array over the stored extent, one entry
    /// per 8^3 block, x fastest; empty when the extent is too sparse for it
    /// (`build_flat`). `top` and `nodes` stay: they build it, and
    /// `range_in_box` walks them a node at a time.
    flat: Vec<u32>,
    /// First block of `flat` (voxel coordinates / 8) and blocks per axis.
    flat_origin: IVec3,
    flat_dims: IVec3,
    /// Inclusive voxel bounds of everything stored (bricks and tiles).
    bounds: Option<(IVec3, IVec3)>,
    all_finite: bool,
}

/// Points per pass of the scalar [`Grid::sample_index_batch`]: enough
/// lookups in flight to cover memory latency, few enough that the first
/// pass's cache lines are still there for the second.
pub const BATCH_LANES: usize = 16;

impl<T: GridValue> Grid<T> {
    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn class(&self) -> &str {
        &self.class
    }

    pub fn background(&self) -> T {
        self.background
    }

    pub fn world_from_index(&self) -> DAffine3 {
        self.world_from_index
    }

    /// The inverse of `world_from_index` as an affine map.
    pub fn index_from_world(&self) -> DAffine3 {
        if self.diagonal {
            let d = self.index_from_world.matrix3;
            DAffine3 {
                matrix3: d,
                translation: d * self.index_from_world.translation,
            }
        } else {
            self.index_from_world
        }
    }

    /// Lengths of the index axes in world units.
    pub fn voxel_size(&self) -> DVec3 {
        let m = self.world_from_index.matrix3;
        DVec3::new(m.x_axis.length(), m.y_axis.length(), m.z_axis.length())
    }

    /// Inclusive voxel bounds of everything stored (bricks and tiles), or
    /// `None` for an empty grid. Outside it every value is the background.
    pub fn stored_bounds(&self) -> Option<(IVec3, IVec3)> {
        self.bounds
    }

    pub fn brick_count(&self) -> usize {
        self.brick_origins.len()
    }

    pub fn brick_origins(&self) -> &[IVec3] {
        &self.brick_origins
    }

    /// The values of all bricks, brick `b` at `b * 512` (without the
    /// constants' copy that follows them).
    pub(super) fn brick_slice(&self) -> &[T] {
        &self.values[..self.brick_origins.len() * BRICK_VOXELS]
    }

    /// The 512 values of brick `b`.
    pub fn brick_values(&self, b: usize) -> &[T] {
        &self.values[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS]
    }

    pub fn brick_mask(&self, b: usize) -> &[u64; 8] {
        &self.masks[b]
    }

    pub fn tiles(&self) -> &[Tile<T>] {
        &self.tiles
    }

    /// Heap and inline memory taken by the grid, in bytes.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        size_of::<Self>()
            + self.values.capacity_bytes()
            + self.brick_origins.capacity() * size_of::<IVec3>()
            + self.masks.capacity() * size_of::<[u64; 8]>()
            + self.ranges.capacity() * size_of::<[T; 2]>()
            + self.tiles.capacity() * size_of::<Tile<T>>()
            + self.constants.capacity() * size_of::<T>()
            + self.top.capacity() * 4
            + self.nodes.capacity() * 4
            + self.flat.capacity() * 4
            + self.name.capacity()
            + self.class.capacity()
    }
}

#[cfg(test)]
mod tests {
    use super::lookup::floor_split;
    use super::*;

    #[test]
    fn flat_index_agrees_with_the_two_level_one() {
        let g = crate::generate::cloud(128, 3).unwrap();
        assert!(!g.flat.is_empty(), "a generated cloud is dense enough");
        assert!(!g.tiles().is_empty() && g.brick_count() > 0);
        let mut two = g.clone();
        two.flat = Vec::new();
        // Every block of the extent and a margin of empty space around it.
        let (lo, hi) = g.stored_bounds().unwrap();
        let mut blocks = 0;
        for z in (lo.z - 16..=hi.z + 16).step_by(8) {
            for y in (lo.y - 16..=hi.y + 16).step_by(8) {
                for x in (lo.x - 16..=hi.x + 16).step_by(8) {
                    let i = IVec3::new(x, y, z);
                    assert_eq!(g.slot(i), two.slot(i), "at {i}");
                    blocks += 1;
                }
            }
        }
        assert!(blocks > 200);
        // And the samples, bit for bit, at points spread over the extent.
        let size = (hi - lo + 9).as_vec3();
        let mut rng = crate::sampling::Rng::new(crate::sampling::Domain::Test, 1, 0, 0);
        for _ in 0..20_000 {
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let p = (lo - 4).as_vec3() + u * size;
            assert_eq!(g.sample_index(p).to_bits(), two.sample_index(p).to_bits());
        }
    }

    #[test]
    fn sparse_extent_keeps_the_two_level_index() {
        // Two bricks 2^20 voxels apart: a dense index of 8^3 blocks over
        // that extent would hold 2^17 entries for two bricks.
        let mut parts = GridParts::new("density", 0.0, DAffine3::IDENTITY);
        for (k, o) in [IVec3::ZERO, IVec3::new(1 << 20, 0, 0)].iter().enumerate() {
            parts.brick_origins.push(*o);
            parts.masks.push([u64::MAX; 8]);
            parts.values.extend((0..512).map(|v| (k * 512 + v) as f32));
        }
        let g = Grid::from_parts(parts).unwrap();
        assert!(g.flat.is_empty());
        // Two nodes and a top index of 8193 entries, not 512 KiB of blocks.
        assert!(g.memory_bytes() < 128 * 1024, "{}", g.memory_bytes());
        assert_eq!(g.get(IVec3::new(1, 2, 3)), (64 + 16 + 3) as f32);
        assert_eq!(g.get(IVec3::new((1 << 20) + 7, 7, 7)), 1023.0);
        assert_eq!(g.get(IVec3::new(1 << 19, 0, 0)), 0.0);
        assert_eq!(
            g.sample_index(Vec3::new(1.5, 2.0, 3.0)),
            (96 + 16 + 3) as f32
        );
    }

    #[test]
    fn floor_split_is_floor() {
        let mut vals = vec![0.0f32, -0.0, 0.5, -0.5, 1.0, -1.0, 7.0, -7.0, 8.0, -8.0];
        vals.extend([1e-30, -1e-30, 0.99999994, -0.99999994, 123456.7, -123456.7]);
        vals.extend([(1 << 29) as f32 + 0.5, -((1 << 29) as f32) - 0.5]);
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..10_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            vals.push(f32::from_bits((x >> 32) as u32) % 4096.0);
        }
        for (k, &v) in vals.iter().enumerate() {
            if !v.is_finite() {
                continue;
            }
            let p = Vec3::new(v, vals[(k + 1) % vals.len()], -v);
            let p = Vec3::select(p.is_finite_mask(), p, Vec3::ZERO);
            let (i, w) = floor_split(p).unwrap();
            let f = p.floor();
            assert_eq!(i.as_vec3(), f, "{p}");
            assert_eq!(w, p - f, "{p}");
        }
        let far = COORD_LIMIT;
        for p in [
            Vec3::new(far, 0.0, 0.0),
            Vec3::new(0.0, -far, 0.0),
            Vec3::new(0.0, 0.0, f32::NAN),
            Vec3::new(f32::INFINITY, 0.0, 0.0),
        ] {
            assert_eq!(floor_split(p), None, "{p}");
        }
    }
}
