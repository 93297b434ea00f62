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
mod value;

pub use bricks::BrickValues;
pub use value::GridValue;

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

/// A constant region without voxels: OpenVDB's tiles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tile<T> {
    pub origin: IVec3,
    /// 1: 8^3 voxels, 2: 128^3, 3: 4096^3 (OpenVDB's tree levels).
    pub level: u8,
    pub value: T,
    pub active: bool,
}

impl<T> Tile<T> {
    /// Edge length in voxels of a tile at `level`.
    pub fn dim_of(level: u8) -> i32 {
        match level {
            1 => 8,
            2 => 128,
            _ => 4096,
        }
    }
    pub fn dim(&self) -> i32 {
        Self::dim_of(self.level)
    }
}

/// The pieces a grid is made of, as they come from a file or a generator.
#[derive(Debug, Clone)]
pub struct GridParts<T: GridValue> {
    pub name: String,
    /// OpenVDB's grid class: `fog volume`, `level set`, `staggered`, `unknown`.
    pub class: String,
    pub background: T,
    pub world_from_index: DAffine3,
    /// Origins (multiples of 8) of the bricks.
    pub brick_origins: Vec<IVec3>,
    /// 512 values per brick, in OpenVDB's order.
    pub values: BrickValues<T>,
    /// Active masks, 8 words per brick, bit `x<<6|y<<3|z`.
    pub masks: Vec<[u64; 8]>,
    pub tiles: Vec<Tile<T>>,
}

impl<T: GridValue> GridParts<T> {
    pub fn new(name: &str, background: T, world_from_index: DAffine3) -> Self {
        Self {
            name: name.to_string(),
            class: "fog volume".to_string(),
            background,
            world_from_index,
            brick_origins: Vec::new(),
            values: BrickValues::new(),
            masks: Vec::new(),
            tiles: Vec::new(),
        }
    }

    /// Collapses bricks whose 512 values are equal and uniformly active into
    /// 8^3 tiles, drops inactive background bricks, and merges complete
    /// 16^3 blocks of equal active 8^3 tiles into 128^3 tiles (as
    /// `openvdb::tools::prune` does for constant leaves).
    pub fn prune(&mut self) {
        let mut keep = Vec::with_capacity(self.brick_origins.len());
        let mut new_tiles = Vec::new();
        for b in 0..self.brick_origins.len() {
            let vals = &self.values[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS];
            let v0 = vals[0];
            let uniform = vals.iter().all(|&v| v == v0);
            let mask = self.masks[b];
            let all_on = mask.iter().all(|&w| w == u64::MAX);
            let all_off = mask.iter().all(|&w| w == 0);
            if uniform && all_on {
                new_tiles.push(Tile {
                    origin: self.brick_origins[b],
                    level: 1,
                    value: v0,
                    active: true,
                });
            } else if uniform && all_off && v0 == self.background {
                // Nothing: this brick is background.
            } else {
                keep.push(b);
            }
        }
        if keep.len() != self.brick_origins.len() {
            let mut values = BrickValues::with_brick_capacity(keep.len());
            for &b in &keep {
                values.extend_from_slice(&self.values[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS]);
            }
            self.brick_origins = keep.iter().map(|&b| self.brick_origins[b]).collect();
            self.masks = keep.iter().map(|&b| self.masks[b]).collect();
            self.values = values;
        }
        // Merge 8^3 tiles into 128^3 tiles where a whole block is one value.
        new_tiles.extend(self.tiles.iter().copied());
        let mut by_block: std::collections::HashMap<IVec3, Vec<Tile<T>>> = Default::default();
        let mut others = Vec::new();
        for t in new_tiles {
            if t.level == 1 {
                by_block.entry(t.origin >> 7).or_default().push(t);
            } else {
                others.push(t);
            }
        }
        let brick_blocks: std::collections::HashSet<IVec3> =
            self.brick_origins.iter().map(|o| *o >> 7).collect();
        let mut blocks: Vec<_> = by_block.into_iter().collect();
        blocks.sort_by_key(|(k, _)| (k.x, k.y, k.z));
        for (block, ts) in blocks {
            let v0 = ts[0].value;
            if ts.len() == NODE_SLOTS
                && !brick_blocks.contains(&block)
                && ts.iter().all(|t| t.active && t.value == v0)
            {
                others.push(Tile {
                    origin: block << 7,
                    level: 2,
                    value: v0,
                    active: true,
                });
            } else {
                others.extend(ts);
            }
        }
        self.tiles = others;
    }
}

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

/// Whether `t` is a cell of a dense array of `dims` cells (one unsigned
/// compare per axis also rejects negative coordinates).
#[inline(always)]
fn inside(t: IVec3, dims: IVec3) -> bool {
    (t.x as u32) < dims.x as u32 && (t.y as u32) < dims.y as u32 && (t.z as u32) < dims.z as u32
}

/// The position of cell `t` in a dense array of `dims` cells, x fastest.
#[inline(always)]
fn linear_index(t: IVec3, dims: IVec3) -> usize {
    (t.z as usize * dims.y as usize + t.y as usize) * dims.x as usize + t.x as usize
}

/// The axes on which the cell at `i0` (corners `i0` to `i0 + 1`) crosses
/// a face of its 8^3 block: those where `i0` is the block's last voxel.
#[inline(always)]
fn block_edge(i0: IVec3) -> BVec3 {
    (i0 & 7).cmpeq(IVec3::splat(7))
}

/// The voxel one step from `i0` along the crossing axes `edge`: for a cell
/// across one face, a voxel of the block beyond it.
#[inline(always)]
fn across(i0: IVec3, edge: BVec3) -> IVec3 {
    i0 + IVec3::select(edge, IVec3::ONE, IVec3::ZERO)
}

/// Asks for the cache lines of a lookup's corners in an 8^3 block, given a
/// pointer to its first corner: the two x planes (+0, +64) and the next
/// row in each (+9, +73), which starts a new line for odd y. A hint only.
#[inline(always)]
fn prefetch_stencil<T>(first: *const T) {
    for o in [0usize, 9, 64, 73] {
        prefetch_line(first.wrapping_add(o));
    }
}

/// Asks for the cache line holding `*p`. A hint only.
#[inline(always)]
fn prefetch_line<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: a prefetch is a hint; it does not access memory in the
        // language's sense, so any address is sound (callers form pointers
        // with wrapping arithmetic).
        unsafe { _mm_prefetch(p as *const i8, _MM_HINT_T0) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

#[inline(always)]
fn voxel_offset(ijk: IVec3) -> usize {
    (((ijk.x & 7) << 6) | ((ijk.y & 7) << 3) | (ijk.z & 7)) as usize
}

#[inline(always)]
fn slot_offset(ijk: IVec3) -> usize {
    ((((ijk.x >> 3) & 15) << 8) | (((ijk.y >> 3) & 15) << 4) | ((ijk.z >> 3) & 15)) as usize
}

/// `floor(p)` as integers and `p - floor(p)`, without a libm call (baseline
/// x86-64 has no SSE4.1 `roundps`) and without Rust's saturating float to
/// int casts (a compare and two conditional moves each): truncate, then
/// step down where truncation rounded up. Points beyond ±2^30 (outside any
/// grid: OpenVDB's coordinates are 32-bit) and NaN give `None`.
///
/// On x86-64 the three axes go through one SSE2 register (part of the
/// baseline, so no feature detection): glam's `Vec3` is three scalars, and
/// the compiler split this into scalar and vector halves, 35 instructions
/// where the register version needs about 15.
#[inline(always)]
fn floor_split(p: Vec3) -> Option<(IVec3, Vec3)> {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of every x86-64 target; the stores write
        // four lanes into four-element arrays.
        unsafe {
            let v = _mm_set_ps(0.0, p.z, p.y, p.x);
            let a = _mm_andnot_ps(_mm_set1_ps(-0.0), v);
            // NaN compares false, so it fails the range check too.
            let ok = _mm_movemask_ps(_mm_cmplt_ps(a, _mm_set1_ps(COORD_LIMIT)));
            if ok & 7 != 7 {
                return None;
            }
            let t = _mm_cvttps_epi32(v);
            // Truncation rounded up where t > p: step down there (the
            // comparison's all-ones lanes are -1).
            let i = _mm_add_epi32(t, _mm_castps_si128(_mm_cmplt_ps(v, _mm_cvtepi32_ps(t))));
            let w = _mm_sub_ps(v, _mm_cvtepi32_ps(i));
            let mut iv = [0i32; 4];
            let mut wv = [0f32; 4];
            _mm_storeu_si128(iv.as_mut_ptr() as *mut __m128i, i);
            _mm_storeu_ps(wv.as_mut_ptr(), w);
            Some((
                IVec3::new(iv[0], iv[1], iv[2]),
                Vec3::new(wv[0], wv[1], wv[2]),
            ))
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        // A per-component test: `max_element` would skip a NaN.
        if !p.abs().cmplt(Vec3::splat(COORD_LIMIT)).all() {
            return None;
        }
        // SAFETY: every component is finite and below 2^30 in magnitude.
        let t = unsafe {
            IVec3::new(
                p.x.to_int_unchecked::<i32>(),
                p.y.to_int_unchecked::<i32>(),
                p.z.to_int_unchecked::<i32>(),
            )
        };
        let tf = t.as_vec3();
        let i = t - IVec3::select(tf.cmpgt(p), IVec3::ONE, IVec3::ZERO);
        Some((i, p - i.as_vec3()))
    }
}

/// The inverse transform. For a diagonal matrix (OpenVDB's scale and
/// scale-translate maps, what nearly every file uses) it is built from exact
/// reciprocals, as OpenVDB's `ScaleTranslateMap::applyInverseMap` computes
/// `(p - t) * (1/s)`: a generic matrix inverse can put a point that lies on
/// a voxel centre one ulp to the other side of it.
fn invert(m: &DAffine3) -> Option<(DAffine3, bool)> {
    let det = m.matrix3.determinant();
    if !det.is_finite() || det.abs() < 1e-300 || !m.translation.is_finite() {
        return None;
    }
    let a = m.matrix3;
    let diagonal = a.x_axis.y == 0.0
        && a.x_axis.z == 0.0
        && a.y_axis.x == 0.0
        && a.y_axis.z == 0.0
        && a.z_axis.x == 0.0
        && a.z_axis.y == 0.0;
    if diagonal {
        let inv = DVec3::ONE / DVec3::new(a.x_axis.x, a.y_axis.y, a.z_axis.z);
        let inverse = DAffine3 {
            matrix3: glam::DMat3::from_diagonal(inv),
            translation: -m.translation,
        };
        return Some((inverse, true));
    }
    Some((m.inverse(), false))
}

impl<T: GridValue> Grid<T> {
    /// Builds a grid from its parts, checking that they fit together.
    pub fn from_parts(parts: GridParts<T>) -> Result<Self> {
        let GridParts {
            name,
            class,
            background,
            world_from_index,
            brick_origins,
            values,
            masks,
            tiles,
        } = parts;
        let label = name.clone();
        let bad = |m: String| Error::InvalidGrid(format!("grid '{label}': {m}"));
        let n = brick_origins.len();
        if values.len() != n * BRICK_VOXELS || masks.len() != n {
            return Err(bad(format!(
                "{n} bricks but {} values and {} masks",
                values.len(),
                masks.len()
            )));
        }
        let (index_from_world, diagonal) = invert(&world_from_index)
            .ok_or_else(|| bad("its transform is singular or not finite".into()))?;
        for o in &brick_origins {
            if *o & 7 != IVec3::ZERO {
                return Err(bad(format!("brick origin {o} is not a multiple of 8")));
            }
        }
        for t in &tiles {
            if !(1..=3).contains(&t.level) {
                return Err(bad(format!("tile at {} has level {}", t.origin, t.level)));
            }
            if t.origin & (t.dim() - 1) != IVec3::ZERO {
                return Err(bad(format!(
                    "tile origin {} is not aligned to its size {}",
                    t.origin,
                    t.dim()
                )));
            }
        }

        // Extent in voxels, then in 128-voxel regions.
        let mut lo = IVec3::MAX;
        let mut hi = IVec3::MIN;
        for o in &brick_origins {
            lo = lo.min(*o);
            hi = hi.max(*o + 7);
        }
        for t in &tiles {
            lo = lo.min(t.origin);
            hi = hi.max(t.origin + (t.dim() - 1));
        }
        let bounds = (lo.cmple(hi).all()).then_some((lo, hi));
        let (top_origin, top_dims) = match bounds {
            Some((lo, hi)) => {
                let a = lo >> LOG2_NODE_VOXELS;
                let b = hi >> LOG2_NODE_VOXELS;
                let d = (b - a).as_i64vec3() + 1;
                if d.x * d.y * d.z > MAX_TOP_ENTRIES {
                    return Err(bad(format!(
                        "its extent {lo}..{hi} is too large ({} x {} x {} voxels)",
                        hi.x as i64 - lo.x as i64 + 1,
                        hi.y as i64 - lo.y as i64 + 1,
                        hi.z as i64 - lo.z as i64 + 1
                    )));
                }
                (a, (b - a) + 1)
            }
            None => (IVec3::ZERO, IVec3::ZERO),
        };
        let top_len = (top_dims.x as usize) * (top_dims.y as usize) * (top_dims.z as usize);
        let mut grid = Grid {
            name,
            class,
            background,
            world_from_index,
            index_from_world,
            diagonal,
            values,
            brick_origins,
            masks,
            ranges: Vec::new(),
            tiles: Vec::new(),
            constants: vec![background],
            top_origin,
            top_dims,
            top: vec![EMPTY; top_len],
            nodes: Vec::new(),
            flat: Vec::new(),
            flat_origin: IVec3::ZERO,
            flat_dims: IVec3::ZERO,
            bounds,
            all_finite: true,
        };

        // Large tiles go straight into the top index; order by level so that
        // an overlap is always detected on the smaller piece.
        let mut tiles = tiles;
        tiles.sort_by_key(|t| std::cmp::Reverse(t.level));
        for t in &tiles {
            let code = CONST_BIT | grid.constants.len() as u32;
            grid.constants.push(t.value);
            if t.level >= 2 {
                let a = (t.origin >> LOG2_NODE_VOXELS) - top_origin;
                let k = t.dim() >> LOG2_NODE_VOXELS;
                for z in 0..k {
                    for y in 0..k {
                        for x in 0..k {
                            let i = grid.top_index(a + IVec3::new(x, y, z));
                            if grid.top[i] != EMPTY {
                                return Err(bad(format!("tile at {} overlaps another", t.origin)));
                            }
                            grid.top[i] = code;
                        }
                    }
                }
            } else {
                let s = grid.node_slot_mut(t.origin).map_err(bad)?;
                if *s != EMPTY {
                    return Err(bad(format!("tile at {} overlaps another", t.origin)));
                }
                *s = code;
            }
        }
        grid.tiles = tiles;
        // The constants' copy after the bricks (see the field); the loader
        // reserves room for it, so this does not move the bricks.
        grid.values.reserve_exact(grid.constants.len());
        grid.values.extend_from_slice(&grid.constants);
        for b in 0..grid.brick_origins.len() {
            let o = grid.brick_origins[b];
            let s = grid.node_slot_mut(o).map_err(bad)?;
            if *s != EMPTY {
                return Err(bad(format!(
                    "brick at {o} overlaps another brick or a tile"
                )));
            }
            *s = b as u32;
        }
        if grid.brick_origins.len() >= CONST_BIT as usize {
            return Err(bad("too many bricks".into()));
        }
        grid.build_flat();

        let (ranges, finite): (Vec<[T; 2]>, Vec<bool>) = grid
            .brick_slice()
            .par_chunks(BRICK_VOXELS)
            .with_min_len(64)
            .map(T::range_of)
            .unzip();
        grid.ranges = ranges;
        grid.all_finite = background.is_finite()
            && finite.iter().all(|&f| f)
            && grid.tiles.iter().all(|t| t.value.is_finite());
        Ok(grid)
    }

    #[inline(always)]
    fn top_index(&self, t: IVec3) -> usize {
        linear_index(t, self.top_dims)
    }

    /// The node slot for the brick containing `ijk`, creating the node.
    fn node_slot_mut(&mut self, ijk: IVec3) -> std::result::Result<&mut u32, String> {
        let i = self.top_index((ijk >> LOG2_NODE_VOXELS) - self.top_origin);
        let e = self.top[i];
        let node = if e == EMPTY {
            let node = (self.nodes.len() / NODE_SLOTS) as u32;
            self.nodes.resize(self.nodes.len() + NODE_SLOTS, EMPTY);
            self.top[i] = node;
            node
        } else if e & CONST_BIT != 0 {
            return Err(format!("the 8^3 block at {ijk} overlaps a larger tile"));
        } else {
            e
        };
        Ok(&mut self.nodes[node as usize * NODE_SLOTS + slot_offset(ijk)])
    }

    /// Fills `flat` unless it would take more entries than the top index
    /// and nodes plus one per 16 voxel values (so it adds at most the
    /// two-level index's own size and 6 % of the values): for the generated
    /// 512^3 cloud it is 0.15 MiB of 22, while a grid of two bricks 2^20
    /// voxels apart keeps the two-level walk rather than 2^17 entries.
    fn build_flat(&mut self) {
        let Some((lo, hi)) = self.bounds else {
            return;
        };
        let (a, b) = (lo >> 3_i32, hi >> 3_i32);
        let d = (b - a).as_i64vec3() + 1;
        let len = d.x * d.y * d.z;
        let budget = (self.top.len() + self.nodes.len() + self.brick_slice().len() / 16) as i64;
        if len > budget {
            return;
        }
        let mut flat = Vec::with_capacity(len as usize);
        for z in a.z..=b.z {
            for y in a.y..=b.y {
                for x in a.x..=b.x {
                    flat.push(self.slot_two_level(IVec3::new(x, y, z) << 3_i32));
                }
            }
        }
        self.flat = flat;
        self.flat_origin = a;
        self.flat_dims = d.as_ivec3();
    }

    /// The slot code of the 8^3 block that holds voxel `ijk`.
    #[inline(always)]
    fn slot(&self, ijk: IVec3) -> u32 {
        if self.flat.is_empty() {
            return self.slot_two_level(ijk);
        }
        let t = (ijk >> 3_i32) - self.flat_origin;
        if !inside(t, self.flat_dims) {
            return EMPTY;
        }
        let i = linear_index(t, self.flat_dims);
        debug_assert!(i < self.flat.len());
        // SAFETY: 0 <= t < flat_dims by the check above, and `flat` has
        // flat_dims.x * flat_dims.y * flat_dims.z entries (`build_flat`).
        unsafe { *self.flat.get_unchecked(i) }
    }

    /// [`Self::slot`] through the top index and its nodes.
    #[inline(always)]
    fn slot_two_level(&self, ijk: IVec3) -> u32 {
        let t = (ijk >> LOG2_NODE_VOXELS) - self.top_origin;
        if !inside(t, self.top_dims) {
            return EMPTY;
        }
        let i = self.top_index(t);
        debug_assert!(i < self.top.len());
        // SAFETY: 0 <= t < top_dims by the check above, and `top` has
        // top_dims.x * top_dims.y * top_dims.z entries (`from_parts`).
        let e = unsafe { *self.top.get_unchecked(i) };
        if e & CONST_BIT != 0 {
            return e;
        }
        let j = e as usize * NODE_SLOTS + slot_offset(ijk);
        debug_assert!(j < self.nodes.len());
        // SAFETY: a top entry without CONST_BIT is the index of a node of
        // NODE_SLOTS slots in `nodes` (`node_slot_mut`); slot_offset < 4096.
        unsafe { *self.nodes.get_unchecked(j) }
    }

    /// The value of voxel `ijk` (background outside what is stored).
    #[inline(always)]
    pub fn get(&self, ijk: IVec3) -> T {
        let s = self.slot(ijk);
        if s & CONST_BIT != 0 {
            self.constants[(s & !CONST_BIT) as usize]
        } else {
            self.values[s as usize * BRICK_VOXELS + voxel_offset(ijk)]
        }
    }

    /// Whether voxel `ijk` is active.
    pub fn is_active(&self, ijk: IVec3) -> bool {
        let s = self.slot(ijk);
        if s & CONST_BIT != 0 {
            let c = (s & !CONST_BIT) as usize;
            c > 0 && self.tiles[c - 1].active
        } else {
            let bit = voxel_offset(ijk);
            self.masks[s as usize][bit >> 6] >> (bit & 63) & 1 == 1
        }
    }

    /// The value at voxel offset `v` of the 8^3 block with slot code `s`.
    #[inline(always)]
    fn value_in(&self, s: u32, v: usize) -> T {
        if s & CONST_BIT != 0 {
            self.constants[(s & !CONST_BIT) as usize]
        } else {
            self.values[s as usize * BRICK_VOXELS + v]
        }
    }

    /// Base pointer and offset mask of the 8^3 block with slot code `s`, at
    /// voxel offset `v`: a brick's values from `v` on, or its constant with
    /// every offset masked to 0. A conditional move, not a branch: which of
    /// the two a scattered lookup meets is unpredictable, and known only
    /// after the index walk's loads.
    #[inline(always)]
    fn block_base(&self, s: u32, v: usize) -> (*const T, usize) {
        let is_const = s & CONST_BIT != 0;
        let k = (s & !CONST_BIT) as usize;
        debug_assert!(if is_const {
            k < self.constants.len()
        } else {
            (k + 1) * BRICK_VOXELS <= self.values.len()
        });
        let base = std::hint::select_unpredictable(
            is_const,
            self.constants.as_ptr().wrapping_add(k),
            self.values.as_ptr().wrapping_add(k * BRICK_VOXELS + v),
        );
        (
            base,
            std::hint::select_unpredictable(is_const, 0, usize::MAX),
        )
    }

    /// The eight values around `i0`, ordered `[x][y][z]` as in `BoxSampler`.
    ///
    /// Of the 512 places of `i0` in its 8^3 block, 343 have all eight
    /// corners in the block, 147 straddle one face (two blocks), 21 an edge
    /// (four) and 1 a corner (eight). The first two cases, 96 % of scattered
    /// lookups, are straight-line code with no branch on brick or constant
    /// ([`Self::block_base`]); the rest take the general loop.
    #[inline(always)]
    fn fetch8(&self, i0: IVec3) -> [T; 8] {
        self.fetch8_from(i0, self.slot(i0), |next| self.slot(next))
    }

    /// [`Self::fetch8`] given the slot `s` of the block of `i0`;
    /// `slot_across(next)` gives the slot of the block across the one face
    /// a cell may cross (`next` is a voxel of it), asked only then.
    #[inline(always)]
    fn fetch8_from(&self, i0: IVec3, s: u32, slot_across: impl FnOnce(IVec3) -> u32) -> [T; 8] {
        let edge = block_edge(i0);
        if !edge.any() {
            return self.fetch_one_block(i0, s);
        }
        if edge.bitmask().count_ones() == 1 {
            return self.fetch_two_blocks(i0, edge, s, slot_across(across(i0, edge)));
        }
        self.fetch_general(i0, edge, s)
    }

    /// [`Self::fetch8`] with all eight corners in the block of slot `s`.
    #[inline(always)]
    fn fetch_one_block(&self, i0: IVec3, s: u32) -> [T; 8] {
        let (base, m) = self.block_base(s, voxel_offset(i0));
        // SAFETY: for a constant every offset is masked to 0; for a brick,
        // with no coordinate at 7 in the block, the offset plus 73 is still
        // inside its 512 values.
        [0usize, 1, 8, 9, 64, 65, 72, 73].map(|o| unsafe { *base.add(o & m) })
    }

    /// [`Self::fetch8`] across the one face `edge` of the block of slot `s`:
    /// the four corners low along the crossing axis are in this block, the
    /// four high ones at the start of the next (slot `sn`).
    #[inline(always)]
    fn fetch_two_blocks(&self, i0: IVec3, edge: BVec3, s: u32, sn: u32) -> [T; 8] {
        let (bl, ml) = self.block_base(s, voxel_offset(i0));
        let (bh, mh) = self.block_base(sn, voxel_offset(across(i0, edge)));
        // SAFETY: as in the one-block case; in each block the offsets stay
        // on the axes that do not cross, where the coordinate is below 7.
        let l = |o: usize| unsafe { *bl.add(o & ml) };
        let h = |o: usize| unsafe { *bh.add(o & mh) };
        if edge.x {
            [l(0), l(1), l(8), l(9), h(0), h(1), h(8), h(9)]
        } else if edge.y {
            [l(0), l(1), h(0), h(1), l(64), l(65), h(64), h(65)]
        } else {
            [l(0), h(0), l(8), h(8), l(64), h(64), l(72), h(72)]
        }
    }

    /// [`Self::fetch8`] across an edge or corner: each block looked up once.
    #[inline(always)]
    fn fetch_general(&self, i0: IVec3, edge: BVec3, s: u32) -> [T; 8] {
        let step = IVec3::select(edge, IVec3::splat(8), IVec3::ZERO);
        let mut slots = [s; 8];
        for (c, slot) in slots.iter_mut().enumerate().skip(1) {
            let d = IVec3::new((c >> 2) as i32, ((c >> 1) & 1) as i32, (c & 1) as i32) * step;
            if d != IVec3::ZERO {
                *slot = self.slot(i0 + d);
            }
        }
        let o = |d: i32, e: bool| if e { -(7 << d) } else { 1 << d };
        let base = voxel_offset(i0) as i32;
        let (dx, dy, dz) = (o(6, edge.x), o(3, edge.y), o(0, edge.z));
        std::array::from_fn(|c| {
            let (cx, cy, cz) = ((c >> 2) as i32, ((c >> 1) & 1) as i32, (c & 1) as i32);
            self.value_in(slots[c], (base + cx * dx + cy * dy + cz * dz) as usize)
        })
    }

    /// Trilinear interpolation of the eight corners, in `BoxSampler`'s order.
    #[inline(always)]
    fn interpolate(d: [T; 8], w: Vec3) -> T {
        let l = T::lerp_f32;
        let y0 = l(l(d[0], d[1], w.z), l(d[2], d[3], w.z), w.y);
        let y1 = l(l(d[4], d[5], w.z), l(d[6], d[7], w.z), w.y);
        l(y0, y1, w.x)
    }

    /// Trilinear sample at a point in index space (single precision: the
    /// renderer's path, which transforms rays into index space once).
    #[inline(always)]
    pub fn sample_index(&self, p: Vec3) -> T {
        let Some((i0, w)) = floor_split(p) else {
            return self.background;
        };
        Self::interpolate(self.fetch8(i0), w)
    }

    /// [`Self::sample_index`] at many independent points: `out[i]` is
    /// `sample_index(points[i])`, bit for bit (where the grid stores NaN
    /// values and a lookup meets two different NaNs, both results are NaN
    /// but may carry different payloads: x86 keeps the first operand's NaN
    /// and the compiler may order an addition's operands either way).
    ///
    /// Why a batch: in a grid larger than the caches each lookup waits on
    /// memory for its values, and one point at a time the processor
    /// overlaps only the few lookups its reorder window holds. A batch
    /// finds the blocks of points well ahead of interpolating them and
    /// prefetches their corners' cache lines in between. For `f32` grids
    /// with the flat index on processors with AVX2 this runs eight points
    /// per instruction (`batch_avx2`); otherwise [`BATCH_LANES`] points at
    /// a time through two scalar passes. On the grids of `benches/grid.rs` it
    /// runs about 1.6 times as fast as one lookup at a time in cache and 2-5
    /// times on the larger ones (the figures are in ARCHITECTURE.md). Meant for
    /// callers with many independent points at once, such as photons or rays
    /// traced in lockstep.
    ///
    /// # Panics
    /// If `points` and `out` differ in length.
    pub fn sample_index_batch(&self, points: &[Vec3], out: &mut [T]) {
        assert_eq!(points.len(), out.len(), "one output per point");
        #[cfg(target_arch = "x86_64")]
        if std::any::TypeId::of::<T>() == std::any::TypeId::of::<f32>()
            && std::arch::is_x86_feature_detected!("avx2")
        {
            // SAFETY: T is f32, so this is the same grid type.
            let g = unsafe { &*(self as *const Self as *const Grid<f32>) };
            if batch_avx2::usable(g) {
                // SAFETY: AVX2 is present (checked above); `usable` holds;
                // `out` is `points.len()` f32 values (one channel).
                unsafe { batch_avx2::sample(g, points, T::as_floats_mut(out)) };
                return;
            }
        }
        self.sample_index_batch_scalar(points, out);
    }

    /// Whether lookups go through the flat index (for tests).
    #[doc(hidden)]
    pub fn has_flat_index(&self) -> bool {
        !self.flat.is_empty()
    }

    /// [`Self::sample_index_batch`] without the vector path (for tests and
    /// for processors without AVX2).
    #[doc(hidden)]
    pub fn sample_index_batch_scalar(&self, points: &[Vec3], out: &mut [T]) {
        assert_eq!(points.len(), out.len(), "one output per point");
        const N: usize = BATCH_LANES;
        for (pc, oc) in points.chunks(N).zip(out.chunks_mut(N)) {
            let mut i0s = [IVec3::ZERO; N];
            let mut ws = [Vec3::ZERO; N];
            let mut slots = [(EMPTY, EMPTY); N];
            let mut inside = [false; N];
            for (j, p) in pc.iter().enumerate() {
                let Some((i0, w)) = floor_split(*p) else {
                    continue;
                };
                let s = self.slot(i0);
                self.prefetch_corners(s, voxel_offset(i0));
                let edge = block_edge(i0);
                let mut sn = s;
                // `any` first: it is cheaper than a popcount without the
                // POPCNT instruction, and two thirds of cells cross nothing.
                if edge.any() && edge.bitmask().count_ones() == 1 {
                    let next = across(i0, edge);
                    sn = self.slot(next);
                    self.prefetch_corners(sn, voxel_offset(next));
                }
                (i0s[j], ws[j], slots[j], inside[j]) = (i0, w, (s, sn), true);
            }
            for (j, o) in oc.iter_mut().enumerate() {
                if !inside[j] {
                    *o = self.background;
                    continue;
                }
                let (s, sn) = slots[j];
                *o = Self::interpolate(self.fetch8_from(i0s[j], s, |_| sn), ws[j]);
            }
        }
    }

    /// Asks for the cache lines holding the corners of a lookup at voxel
    /// offset `v` of the block with slot code `s` ([`prefetch_stencil`]).
    #[inline(always)]
    fn prefetch_corners(&self, s: u32, v: usize) {
        prefetch_stencil(self.block_base(s, v).0);
    }

    /// Trilinear sample at a point in index space, in double precision,
    /// matching `openvdb::tools::BoxSampler::sample` operation by operation.
    pub fn sample_index_f64(&self, p: DVec3) -> T {
        let f = p.floor();
        // As in `floor_split`: beyond ±2^30 (and NaN) is outside any grid,
        // and the integer cast below would saturate.
        if !f.abs().cmplt(DVec3::splat(COORD_LIMIT as f64)).all() {
            return self.background;
        }
        let w = p - f;
        let d = self.fetch8(f.as_ivec3());
        let l = T::lerp_f64;
        let y0 = l(l(d[0], d[1], w.z), l(d[2], d[3], w.z), w.y);
        let y1 = l(l(d[4], d[5], w.z), l(d[6], d[7], w.z), w.y);
        l(y0, y1, w.x)
    }

    /// World to index space, in double precision, computed as OpenVDB does.
    pub fn world_to_index(&self, p: DVec3) -> DVec3 {
        let m = &self.index_from_world;
        if self.diagonal {
            // (p - t) * (1/s): `translation` holds -t for diagonal maps.
            (p + m.translation)
                * DVec3::new(m.matrix3.x_axis.x, m.matrix3.y_axis.y, m.matrix3.z_axis.z)
        } else {
            m.transform_point3(p)
        }
    }

    /// Index to world space.
    pub fn index_to_world(&self, p: DVec3) -> DVec3 {
        self.world_from_index.transform_point3(p)
    }

    /// Trilinear sample at a world-space point (OpenVDB's `wsSample`).
    pub fn sample_world(&self, p: DVec3) -> T {
        self.sample_index_f64(self.world_to_index(p))
    }

    /// [min, max] of the voxels `o ..= o + 8` along each axis, `o` a multiple
    /// of 8: exactly the values that trilinear lookups at index points in
    /// `[o, o + 8)³` read. Built from the block's own range and the faces,
    /// edges and corner of its +x, +y and +z neighbours, so a majorant cell
    /// of one block is as tight as a 9³ box allows (a box query through
    /// [`Self::range_in_box`] would take whole neighbouring bricks, 16³).
    pub fn block_lookup_range(&self, o: IVec3) -> [T; 2] {
        debug_assert!(o & 7 == IVec3::ZERO);
        let range_of = |k: i32| {
            let off = IVec3::new(k & 1, (k >> 1) & 1, k >> 2);
            let s = self.slot(o + off * 8);
            if s & CONST_BIT != 0 {
                let c = self.constants[(s & !CONST_BIT) as usize];
                return [c, c];
            }
            if k == 0 {
                return self.ranges[s as usize];
            }
            // Only the layer of this neighbour next to the block: one voxel
            // thick along each axis it is offset on.
            let n = |a: i32| if a == 1 { 1 } else { 8 };
            let vals = self.brick_values(s as usize);
            let mut r = [vals[0], vals[0]];
            for x in 0..n(off.x) {
                for y in 0..n(off.y) {
                    for z in 0..n(off.z) {
                        let v = vals[((x << 6) | (y << 3) | z) as usize];
                        r = [T::min(r[0], v), T::max(r[1], v)];
                    }
                }
            }
            r
        };
        (1..8).fold(range_of(0), |[lo, hi], k| {
            let r = range_of(k);
            [T::min(lo, r[0]), T::max(hi, r[1])]
        })
    }

    /// [min, max] of every value that a lookup in the inclusive voxel box
    /// `lo..=hi` can read, or `None` when the box is empty. Values outside
    /// the stored region count as the background. Used to build majorants.
    pub fn range_in_box(&self, lo: IVec3, hi: IVec3) -> Option<[T; 2]> {
        if lo.cmpgt(hi).any() {
            return None;
        }
        let mut acc: Option<[T; 2]> = None;
        let mut add = |r: [T; 2]| {
            acc = Some(match acc {
                None => r,
                Some([a, b]) => [T::min(a, r[0]), T::max(b, r[1])],
            })
        };
        let bg = [self.background; 2];
        // Regions of the box outside the top index hold the background.
        let t_lo = lo >> LOG2_NODE_VOXELS;
        let t_hi = hi >> LOG2_NODE_VOXELS;
        let top_hi = self.top_origin + self.top_dims - 1;
        if t_lo.cmplt(self.top_origin).any() || t_hi.cmpgt(top_hi).any() {
            add(bg);
        }
        let a = t_lo.max(self.top_origin);
        let b = t_hi.min(top_hi);
        for tz in a.z..=b.z {
            for ty in a.y..=b.y {
                for tx in a.x..=b.x {
                    let t = IVec3::new(tx, ty, tz);
                    let e = self.top[self.top_index(t - self.top_origin)];
                    if e & CONST_BIT != 0 {
                        add([self.constants[(e & !CONST_BIT) as usize]; 2]);
                        continue;
                    }
                    let node = &self.nodes[e as usize * NODE_SLOTS..][..NODE_SLOTS];
                    let r0: IVec3 = t << LOG2_NODE_VOXELS;
                    let blo: IVec3 = (lo.max(r0) - r0) >> 3;
                    let bhi: IVec3 = (hi.min(r0 + 127) - r0) >> 3;
                    for bx in blo.x..=bhi.x {
                        for by in blo.y..=bhi.y {
                            for bz in blo.z..=bhi.z {
                                let s = node[((bx << 8) | (by << 4) | bz) as usize];
                                if s & CONST_BIT != 0 {
                                    add([self.constants[(s & !CONST_BIT) as usize]; 2]);
                                } else {
                                    add(self.ranges[s as usize]);
                                }
                            }
                        }
                    }
                }
            }
        }
        acc
    }

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
    fn brick_slice(&self) -> &[T] {
        &self.values[..self.brick_origins.len() * BRICK_VOXELS]
    }

    /// The 512 values of brick `b`.
    pub fn brick_values(&self, b: usize) -> &[T] {
        &self.values[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS]
    }
    pub fn brick_mask(&self, b: usize) -> &[u64; 8] {
        &self.masks[b]
    }
    pub fn brick_range(&self, b: usize) -> [T; 2] {
        self.ranges[b]
    }
    pub fn tiles(&self) -> &[Tile<T>] {
        &self.tiles
    }
    /// False when any stored value is NaN or infinite.
    pub fn all_finite(&self) -> bool {
        self.all_finite
    }
    /// [min, max] over every stored value, or `None` for an empty grid.
    pub fn value_range(&self) -> Option<[T; 2]> {
        let (lo, hi) = self.bounds?;
        self.range_in_box(lo, hi)
    }

    /// Number of active voxels (in bricks and in active tiles).
    pub fn active_voxel_count(&self) -> u64 {
        let bricks: u64 = self
            .masks
            .iter()
            .map(|m| m.iter().map(|w| w.count_ones() as u64).sum::<u64>())
            .sum();
        let tiles: u64 = self
            .tiles
            .iter()
            .filter(|t| t.active)
            .map(|t| (t.dim() as u64).pow(3))
            .sum();
        bricks + tiles
    }

    /// Inclusive bounding box of the active voxels.
    pub fn active_bounds(&self) -> Option<(IVec3, IVec3)> {
        let mut lo = IVec3::MAX;
        let mut hi = IVec3::MIN;
        for (o, m) in self.brick_origins.iter().zip(&self.masks) {
            for (w, &word) in m.iter().enumerate() {
                let mut bits = word;
                while bits != 0 {
                    let n = w * 64 + bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let p = *o + IVec3::new((n >> 6) as i32, ((n >> 3) & 7) as i32, (n & 7) as i32);
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            }
        }
        for t in self.tiles.iter().filter(|t| t.active) {
            lo = lo.min(t.origin);
            hi = hi.max(t.origin + (t.dim() - 1));
        }
        lo.cmple(hi).all().then_some((lo, hi))
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

    /// A grid of the same layout (bricks, masks, tiles, transform) whose
    /// every value, background included, is `f(value)`. The renderer builds
    /// per-voxel emitted radiance from a temperature grid this way, so that
    /// trilinear lookups interpolate radiance rather than temperature.
    pub fn map_values<U: GridValue>(&self, name: &str, f: impl Fn(T) -> U) -> Result<Grid<U>> {
        let mut values = BrickValues::with_brick_capacity(self.brick_origins.len());
        for &v in self.brick_slice() {
            values.push(f(v));
        }
        Grid::from_parts(GridParts {
            name: name.to_string(),
            class: self.class.clone(),
            background: f(self.background),
            world_from_index: self.world_from_index,
            brick_origins: self.brick_origins.clone(),
            values,
            masks: self.masks.clone(),
            tiles: self
                .tiles
                .iter()
                .map(|t| Tile {
                    origin: t.origin,
                    level: t.level,
                    value: f(t.value),
                    active: t.active,
                })
                .collect(),
        })
    }

    /// Takes the grid apart again (for writing).
    pub fn to_parts(&self) -> GridParts<T> {
        GridParts {
            name: self.name.clone(),
            class: self.class.clone(),
            background: self.background,
            world_from_index: self.world_from_index,
            brick_origins: self.brick_origins.clone(),
            values: {
                let mut v = BrickValues::with_brick_capacity(self.brick_origins.len());
                v.extend_from_slice(self.brick_slice());
                v
            },
            masks: self.masks.clone(),
            tiles: self.tiles.clone(),
        }
    }

    /// Checks the internal invariants: every brick reachable through the
    /// index at its origin, every range bounding its brick's values. For
    /// tests; O(size of the grid).
    pub fn validate(&self) -> std::result::Result<(), String> {
        let bits = |v: &[T]| {
            T::to_flat(v)
                .iter()
                .map(|f| f.to_bits())
                .collect::<Vec<_>>()
        };
        if bits(&self.values[self.brick_slice().len()..]) != bits(&self.constants) {
            return Err("the values' tail is not the constants".into());
        }
        for (b, o) in self.brick_origins.iter().enumerate() {
            if self.slot(*o) != b as u32 {
                return Err(format!("brick {b} at {o} is not reachable"));
            }
            let [lo, hi] = self.ranges[b];
            for &v in self.brick_values(b) {
                if T::min(lo, v) != lo || T::max(hi, v) != hi {
                    return Err(format!("brick {b}: value {v:?} outside its range"));
                }
            }
        }
        for (i, t) in self.tiles.iter().enumerate() {
            if self.get(t.origin) != t.value || self.get(t.origin + (t.dim() - 1)) != t.value {
                return Err(format!("tile {i} at {} does not read back", t.origin));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
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
