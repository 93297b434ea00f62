//! Lookups: a voxel's value, and trilinear samples between voxel centres
//! exactly as OpenVDB's `tools::BoxSampler`, one point at a time (what
//! tracking along a ray does) or in batches that prefetch their corners;
//! the world/index transforms.

use super::*;

/// Whether `t` is a cell of a dense array of `dims` cells (one unsigned
/// compare per axis also rejects negative coordinates).
#[inline(always)]
pub(super) fn inside(t: IVec3, dims: IVec3) -> bool {
    (t.x as u32) < dims.x as u32 && (t.y as u32) < dims.y as u32 && (t.z as u32) < dims.z as u32
}

/// The position of cell `t` in a dense array of `dims` cells, x fastest.
#[inline(always)]
pub(super) fn linear_index(t: IVec3, dims: IVec3) -> usize {
    (t.z as usize * dims.y as usize + t.y as usize) * dims.x as usize + t.x as usize
}

/// The axes on which the cell at `i0` (corners `i0` to `i0 + 1`) crosses
/// a face of its 8^3 block: those where `i0` is the block's last voxel.
#[inline(always)]
pub(super) fn block_edge(i0: IVec3) -> BVec3 {
    (i0 & 7).cmpeq(IVec3::splat(7))
}

/// The voxel one step from `i0` along the crossing axes `edge`: for a cell
/// across one face, a voxel of the block beyond it.
#[inline(always)]
pub(super) fn across(i0: IVec3, edge: BVec3) -> IVec3 {
    i0 + IVec3::select(edge, IVec3::ONE, IVec3::ZERO)
}

/// Asks for the cache lines of a lookup's corners in an 8^3 block, given a
/// pointer to its first corner: the two x planes (+0, +64) and the next
/// row in each (+9, +73), which starts a new line for odd y. A hint only.
#[inline(always)]
pub(super) fn prefetch_stencil<T>(first: *const T) {
    for o in [0usize, 9, 64, 73] {
        prefetch_line(first.wrapping_add(o));
    }
}

/// Asks for the cache line holding `*p`. A hint only.
#[inline(always)]
pub(super) fn prefetch_line<T>(p: *const T) {
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
pub(super) fn voxel_offset(ijk: IVec3) -> usize {
    (((ijk.x & 7) << 6) | ((ijk.y & 7) << 3) | (ijk.z & 7)) as usize
}

#[inline(always)]
pub(super) fn slot_offset(ijk: IVec3) -> usize {
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
pub(super) fn floor_split(p: Vec3) -> Option<(IVec3, Vec3)> {
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

impl<T: GridValue> Grid<T> {
    /// The slot code of the 8^3 block that holds voxel `ijk`.
    #[inline(always)]
    pub(super) fn slot(&self, ijk: IVec3) -> u32 {
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
    pub(super) fn slot_two_level(&self, ijk: IVec3) -> u32 {
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
    pub(super) fn value_in(&self, s: u32, v: usize) -> T {
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
    pub(super) fn block_base(&self, s: u32, v: usize) -> (*const T, usize) {
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
    pub(super) fn fetch8(&self, i0: IVec3) -> [T; 8] {
        self.fetch8_from(i0, self.slot(i0), |next| self.slot(next))
    }

    /// [`Self::fetch8`] given the slot `s` of the block of `i0`;
    /// `slot_across(next)` gives the slot of the block across the one face
    /// a cell may cross (`next` is a voxel of it), asked only then.
    #[inline(always)]
    pub(super) fn fetch8_from(
        &self,
        i0: IVec3,
        s: u32,
        slot_across: impl FnOnce(IVec3) -> u32,
    ) -> [T; 8] {
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
    pub(super) fn fetch_one_block(&self, i0: IVec3, s: u32) -> [T; 8] {
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
    pub(super) fn fetch_two_blocks(&self, i0: IVec3, edge: BVec3, s: u32, sn: u32) -> [T; 8] {
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
    pub(super) fn fetch_general(&self, i0: IVec3, edge: BVec3, s: u32) -> [T; 8] {
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
    pub(super) fn interpolate(d: [T; 8], w: Vec3) -> T {
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
    /// times on the larger ones (the figures are in docs/performance.md). Meant for
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
    pub(super) fn prefetch_corners(&self, s: u32, v: usize) {
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
}
