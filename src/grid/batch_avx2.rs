//! [`Grid::sample_index_batch`] for `f32` grids on processors with AVX2:
//! eight points per vector lane set.
//!
//! Why: once the scalar batch hides memory latency, its own instruction
//! count limits it (about 45 M lookups/s on one core for a grid in cache).
//! Eight lanes share every instruction of the floor, the index walk and the
//! interpolation, about twice the scalar batch's rate in cache (figures:
//! `cargo bench --bench grid`; the measured ranges and what was tried are
//! in docs/performance.md, "Batched lookups"). On grids larger than the caches
//! the loop waits on memory: its loads and prefetches, not its instruction
//! count, set the rate there. A software pipeline runs the first pass
//! (floor, block slots, prefetches) [`AHEAD`] lane sets before the second
//! (corner loads, interpolation).
//!
//! The corners come in by scalar loads into vectors (`load8`), not AVX2
//! gathers: on this project's Zen 3 machine an eight-lane gather from
//! cache took 3.3 ns against 2.2 ns for eight loads and inserts, and with
//! loads the batch ran 5 % faster in cache and 3 % on pig.vdb. The two
//! flat-index gathers of the first pass stay gathers: as loads they were
//! slower on the cloud, whose index entries miss the cache.
//!
//! The arithmetic is the scalar path's, operation by operation (floor,
//! `p - (float)floor(p)`, then `a + (b - a) * w` in the same order, no
//! fused multiply-add), so the results are the same bits
//! (`tests/sampling.rs` checks every lane against `sample_index`).
//!
//! Two things keep the loop free of per-lane branches:
//! - a lane in a tile or the background reads its constant from the copy
//!   of the constants after the bricks in `values`, with offset 0, so every
//!   corner is one load from one base (two more gathers per lane set, for
//!   the constants, had taken 8 % of the time in cache);
//! - lanes whose corners span more than two blocks (22 of the 512 places
//!   in a block) are collected and redone [`DEFERRED`] at a time, eight
//!   per vector, by `redo_deferred`: every corner's slot and index first,
//!   each prefetched, then the loads. Redone one by one inside the loop,
//!   with the branches of the scalar path and misses on blocks nobody had
//!   prefetched, those 4 % of lanes took a third of the time on the cloud
//!   (45 against 70 M/s with them skipped).
//!
//! Both passes are `#[inline]` functions with one call site each: a helper
//! without the `avx2` feature does not inline the intrinsics (each became a
//! call, 8 M lookups/s), and `#[inline(always)]` cannot be combined with
//! `#[target_feature]`.

use super::{prefetch_line, prefetch_stencil, Grid, CONST_BIT, COORD_LIMIT, EMPTY};
use glam::Vec3;
use std::arch::x86_64::*;

/// Whether this grid can take the vector path: it has the flat index, and
/// every index the vectors compute (into `values`, loaded one lane at a
/// time, or into the flat index, gathered) fits an i32.
pub(super) fn usable(g: &Grid<f32>) -> bool {
    !g.flat.is_empty() && g.values.len() < i32::MAX as usize && g.flat.len() < i32::MAX as usize
}

/// Eight points after the first pass: cell coordinates, weights, which
/// lanes are in range, and the slot codes of the cell's block and of the
/// block across its face (`sn`; the block itself where no face is crossed).
#[derive(Clone, Copy)]
struct Lanes {
    i: [__m256i; 3],
    w: [__m256; 3],
    ok: __m256,
    s: __m256i,
    sn: __m256i,
}

/// Loop-invariant vectors of a grid.
struct Consts {
    origin: [__m256i; 3],
    dims: [__m256i; 3],
    dx: __m256i,
    dxy: __m256i,
    /// Where the constants' copy starts in `values` (see `Grid::constants`).
    tail: __m256i,
}

/// Lane sets between the first and the second pass of a point.
const AHEAD: usize = 8;

/// Lanes across an edge or corner collected before they are redone.
const DEFERRED: usize = 64;

/// Samples `points` into `out`.
///
/// # Safety
/// The processor must support AVX2, `usable(g)` must hold, and `out` must
/// be as long as `points` (its stores are unchecked).
#[target_feature(enable = "avx2")]
pub(super) unsafe fn sample(g: &Grid<f32>, points: &[Vec3], out: &mut [f32]) {
    debug_assert!(usable(g) && points.len() == out.len());
    let c = Consts {
        origin: [g.flat_origin.x, g.flat_origin.y, g.flat_origin.z].map(|o| _mm256_set1_epi32(o)),
        dims: [g.flat_dims.x, g.flat_dims.y, g.flat_dims.z].map(|d| _mm256_set1_epi32(d)),
        dx: _mm256_set1_epi32(g.flat_dims.x),
        dxy: _mm256_set1_epi32(g.flat_dims.x * g.flat_dims.y),
        tail: _mm256_set1_epi32(g.brick_slice().len() as i32),
    };
    // A software pipeline: the first pass runs AHEAD lane sets before the
    // second, so each set's corners were asked for that long before.
    let sets = points.len() / 8;
    let zero = Lanes {
        i: [_mm256_setzero_si256(); 3],
        w: [_mm256_setzero_ps(); 3],
        ok: _mm256_setzero_ps(),
        s: _mm256_setzero_si256(),
        sn: _mm256_setzero_si256(),
    };
    let mut ring = [zero; AHEAD];
    // Lanes whose corners span more than two blocks, redone by
    // `redo_deferred` a chunk at a time (room for one more lane set past
    // DEFERRED: the appends below do not branch).
    let mut deferred = [0usize; DEFERRED + 8];
    let mut n = 0;
    // One call site each, so both passes inline into this loop.
    for j in 0..sets + AHEAD {
        let r = &mut ring[j % AHEAD];
        if j >= AHEAD {
            let k = 8 * (j - AHEAD);
            let multi = second_pass(g, &c, r, &mut out[k..]);
            for lane in 0..8 {
                deferred[n] = k + lane;
                n += (multi >> lane) as usize & 1;
            }
            if n >= DEFERRED {
                redo_deferred(g, &c, points, &deferred[..n], out);
                n = 0;
            }
        }
        if j < sets {
            // The points 16 lane sets ahead (96 bytes a set): the hardware
            // prefetcher alone let their loads miss while the memory was
            // busy with corners (cloud: 8 % faster with these two hints).
            let ahead = points.as_ptr().wrapping_add(8 * (j + 16)) as *const u8;
            prefetch_line(ahead);
            prefetch_line(ahead.wrapping_add(64));
            *r = first_pass(g, &c, &points[8 * j..]);
        }
    }
    redo_deferred(g, &c, points, &deferred[..n], out);
    let k = 8 * sets;
    for j in k..points.len() {
        out[j] = g.sample_index(points[j]);
    }
}

/// `out[j] = sample_index(points[j])` for the lanes `which` whose corners
/// span four or eight blocks, eight lanes per vector: first every corner's
/// slot (one flat-index gather per corner) and value index, with a
/// prefetch of each, then the value loads and interpolation.
///
/// # Safety
/// As for [`sample`]; each of `which` is below `points.len()`, and there
/// are at most `DEFERRED + 8` of them.
#[target_feature(enable = "avx2")]
unsafe fn redo_deferred(
    g: &Grid<f32>,
    c: &Consts,
    points: &[Vec3],
    which: &[usize],
    out: &mut [f32],
) {
    const GROUPS: usize = DEFERRED / 8 + 1;
    debug_assert!(which.len() <= 8 * GROUPS);
    if which.is_empty() {
        return;
    }
    if points.len() > (i32::MAX / 3) as usize {
        // Point indices as gather offsets would overflow.
        for &j in which {
            out[j] = g.sample_index(points[j]);
        }
        return;
    }
    let groups = which.len().div_ceil(8);
    let mut lanes = [[0i32; 8]; GROUPS];
    let mut corners = [[_mm256_setzero_si256(); 8]; GROUPS];
    let mut weights = [[_mm256_setzero_ps(); 3]; GROUPS];
    let one = _mm256_set1_epi32(1);
    let seven = _mm256_set1_epi32(7);
    let empty = _mm256_set1_epi32(EMPTY as i32);
    let scale = [one, c.dx, c.dxy];
    let flat = g.flat.as_ptr() as *const i32;
    let values = g.values.as_ptr();
    for q in 0..groups {
        // The last group is padded with its last lane (written twice).
        for (l, lane) in lanes[q].iter_mut().enumerate() {
            *lane = which[(8 * q + l).min(which.len() - 1)] as i32;
        }
        let i3 = _mm256_mullo_epi32(
            _mm256_loadu_si256(lanes[q].as_ptr() as *const __m256i),
            _mm256_set1_epi32(3),
        );
        // SAFETY: each lane's three floats are those of a point.
        let p = points.as_ptr() as *const f32;
        let pv = [0, 1, 2]
            .map(|a| _mm256_i32gather_ps::<4>(p, _mm256_add_epi32(i3, _mm256_set1_epi32(a))));
        // As in `first_pass` (these lanes passed its range check).
        let i = pv.map(|v| _mm256_cvttps_epi32(_mm256_floor_ps(v)));
        weights[q] = [0, 1, 2].map(|a| _mm256_sub_ps(pv[a], _mm256_cvtepi32_ps(i[a])));
        // Per axis, the flat-index term, whether it is inside the index,
        // and the voxel offset, for the low and the high corner.
        let mut term = [[_mm256_setzero_si256(); 2]; 3];
        let mut inside = [[_mm256_setzero_si256(); 2]; 3];
        let mut voxel = [[_mm256_setzero_si256(); 2]; 3];
        for a in 0..3 {
            for (h, v) in [i[a], _mm256_add_epi32(i[a], one)].into_iter().enumerate() {
                let t = _mm256_sub_epi32(_mm256_srai_epi32::<3>(v), c.origin[a]);
                term[a][h] = _mm256_mullo_epi32(t, scale[a]);
                inside[a][h] = inside_axis(t, c.dims[a]);
                voxel[a][h] = _mm256_sllv_epi32(
                    _mm256_and_si256(v, seven),
                    _mm256_set1_epi32(6 - 3 * a as i32),
                );
            }
        }
        for (k, corner) in corners[q].iter_mut().enumerate() {
            let (x, y, z) = (k >> 2, (k >> 1) & 1, k & 1);
            let lin = _mm256_add_epi32(_mm256_add_epi32(term[0][x], term[1][y]), term[2][z]);
            let m = _mm256_and_si256(_mm256_and_si256(inside[0][x], inside[1][y]), inside[2][z]);
            // SAFETY: masked to entries inside `flat_dims`.
            let s = _mm256_mask_i32gather_epi32::<4>(empty, flat, lin, m);
            let off = _mm256_add_epi32(_mm256_add_epi32(voxel[0][x], voxel[1][y]), voxel[2][z]);
            *corner = _mm256_blendv_epi8(
                _mm256_add_epi32(_mm256_slli_epi32::<9>(index(s)), off),
                _mm256_add_epi32(c.tail, index(s)),
                is_const(s),
            );
            let mut o = [0i32; 8];
            _mm256_storeu_si256(o.as_mut_ptr() as *mut __m256i, *corner);
            for o in o {
                prefetch_line(values.wrapping_add(o as usize));
            }
        }
    }
    for q in 0..groups {
        // SAFETY: each index is a value of `values`, as in `second_pass`.
        let d = load8(values, &corners[q]);
        let mut r = [0f32; 8];
        _mm256_storeu_ps(r.as_mut_ptr(), interpolate(d, weights[q]));
        for (l, &j) in lanes[q].iter().enumerate() {
            out[j as usize] = r[l];
        }
    }
}

/// Floors eight points, finds their blocks' slot codes, and prefetches the
/// cache lines of their corners.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn first_pass(g: &Grid<f32>, c: &Consts, points: &[Vec3]) -> Lanes {
    debug_assert!(points.len() >= 8);
    let empty = _mm256_set1_epi32(EMPTY as i32);
    // SAFETY: 24 floats from here (8 points); the flat-index gathers are
    // masked to entries inside `flat_dims`.
    let p = points.as_ptr() as *const f32;
    let pv = load_xyz(p);
    // Range check as in `floor_split`: NaN and |p| >= 2^30 read the
    // background; such lanes continue at 0 so every address is valid.
    let abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX));
    let limit = _mm256_set1_ps(COORD_LIMIT);
    let ok = pv
        .iter()
        .map(|&v| _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_and_ps(v, abs_mask), limit))
        .fold(_mm256_castsi256_ps(_mm256_set1_epi32(-1)), |a, b| {
            _mm256_and_ps(a, b)
        });
    let pv = pv.map(|v| _mm256_and_ps(v, ok));
    // `p - (float)floor(p)` as the scalar path computes it (the same bits,
    // down to the sign of a zero weight at p = -0).
    let i = pv.map(|v| _mm256_cvttps_epi32(_mm256_floor_ps(v)));
    let w = [0, 1, 2].map(|a| _mm256_sub_ps(pv[a], _mm256_cvtepi32_ps(i[a])));
    // Block coordinates in the flat index, and the block across the face
    // where the cell's last voxel is 7 (edge lanes are -1: t + 1 there).
    let edge = block_edges(i);
    let t = [0, 1, 2].map(|a| _mm256_sub_epi32(_mm256_srai_epi32::<3>(i[a]), c.origin[a]));
    let tn = [0, 1, 2].map(|a| _mm256_sub_epi32(t[a], edge[a]));
    let lin = |t: [__m256i; 3]| {
        _mm256_add_epi32(
            _mm256_add_epi32(t[0], _mm256_mullo_epi32(t[1], c.dx)),
            _mm256_mullo_epi32(t[2], c.dxy),
        )
    };
    let flat = g.flat.as_ptr() as *const i32;
    let s = _mm256_mask_i32gather_epi32::<4>(empty, flat, lin(t), inside_lanes(t, c.dims));
    let sn = _mm256_mask_i32gather_epi32::<4>(empty, flat, lin(tn), inside_lanes(tn, c.dims));
    // Prefetch: the corners' lines in both blocks (brick lanes only).
    let v = voxel_offsets(i);
    let vn = _mm256_andnot_si256(
        _mm256_or_si256(
            _mm256_or_si256(
                _mm256_and_si256(edge[0], _mm256_set1_epi32(0o700)),
                _mm256_and_si256(edge[1], _mm256_set1_epi32(0o070)),
            ),
            _mm256_and_si256(edge[2], _mm256_set1_epi32(0o007)),
        ),
        v,
    );
    let at = |s: __m256i, v: __m256i| {
        _mm256_andnot_si256(
            is_const(s),
            _mm256_add_epi32(_mm256_slli_epi32::<9>(index(s)), v),
        )
    };
    // Each lane's lines in its own block: the near and far corner of the
    // low x slab (`a`, `a + 9`) and of the high one (`b`, `b + 9`). Where
    // the cell crosses a y or z face, `a` steps back one voxel along that
    // axis, so `a + 9` stays in the rows the cell uses instead of wrapping
    // into the next row; where it crosses the x face, the high slab is the
    // neighbour's. A fixed stencil (+0, +9, +64, +73) asked for lines no
    // corner uses in a third of the lanes: the cloud's batched lookups
    // ran 3-8 % slower, more where memory was slow.
    let back = _mm256_or_si256(
        _mm256_and_si256(edge[1], _mm256_set1_epi32(8)),
        _mm256_and_si256(edge[2], _mm256_set1_epi32(1)),
    );
    let a = at(s, _mm256_sub_epi32(v, back));
    let across = at(sn, vn);
    let b = _mm256_blendv_epi8(_mm256_add_epi32(a, _mm256_set1_epi32(64)), across, edge[0]);
    let mut offsets = [0i32; 24];
    _mm256_storeu_si256(offsets.as_mut_ptr() as *mut __m256i, a);
    _mm256_storeu_si256(offsets.as_mut_ptr().add(8) as *mut __m256i, b);
    _mm256_storeu_si256(offsets.as_mut_ptr().add(16) as *mut __m256i, across);
    let values = g.values.as_ptr();
    let pair = |o: i32| {
        let p = values.wrapping_add(o as usize);
        prefetch_line(p);
        prefetch_line(p.wrapping_add(9));
    };
    for lane in 0..8 {
        pair(offsets[lane]);
        pair(offsets[8 + lane]);
    }
    // The block across a y or z face where the cell crosses one (a
    // quarter of the lanes): both its slabs.
    let crossing = _mm256_or_si256(edge[1], edge[2]);
    let mut bits = _mm256_movemask_ps(_mm256_castsi256_ps(crossing)) as u32;
    while bits != 0 {
        prefetch_stencil(
            values.wrapping_add(offsets[16 + bits.trailing_zeros() as usize] as usize),
        );
        bits &= bits - 1;
    }
    Lanes { i, w, ok, s, sn }
}

/// Loads the eight corners of each lane and interpolates; returns the
/// lanes whose corners span more than two blocks (a bit each), which the
/// caller must redo.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn second_pass(g: &Grid<f32>, c: &Consts, l: &Lanes, out: &mut [f32]) -> u32 {
    debug_assert!(out.len() >= 8);
    let edge = block_edges(l.i);
    let v = voxel_offsets(l.i);
    // SAFETY: every corner index is a value of `values`: for a brick lane,
    // an offset below 512 of the brick its slot code names (each corner's
    // offset stays inside its block, as in `Grid::fetch_general`); for a
    // constant, its copy after the bricks (see `Grid::constants`).
    let (ks, kn) = (is_const(l.s), is_const(l.sn));
    // Where a block's values start: its brick, or its constant's copy.
    let start = |s: __m256i, k: __m256i| {
        _mm256_blendv_epi8(
            _mm256_slli_epi32::<9>(index(s)),
            _mm256_add_epi32(c.tail, index(s)),
            k,
        )
    };
    let (bs, bn) = (start(l.s, ks), start(l.sn, kn));
    // Per axis, the step to the high corner: +1 voxel, or back 7 into the
    // next block where the cell crosses the face.
    let step = |a: usize, shift: i32| {
        _mm256_blendv_epi8(
            _mm256_set1_epi32(1 << shift),
            _mm256_set1_epi32(-(7 << shift)),
            edge[a],
        )
    };
    let st = [step(0, 6), step(1, 3), step(2, 0)];
    let values = g.values.as_ptr();
    let corner = |cx: bool, cy: bool, cz: bool| {
        let mut off = v;
        let mut cross = _mm256_setzero_si256();
        for (a, on) in [cx, cy, cz].into_iter().enumerate() {
            if on {
                off = _mm256_add_epi32(off, st[a]);
                cross = _mm256_or_si256(cross, edge[a]);
            }
        }
        // A constant's offset is 0.
        let base = _mm256_blendv_epi8(bs, bn, cross);
        let konst = _mm256_blendv_epi8(ks, kn, cross);
        _mm256_add_epi32(base, _mm256_andnot_si256(konst, off))
    };
    let ix = [
        corner(false, false, false),
        corner(false, false, true),
        corner(false, true, false),
        corner(false, true, true),
        corner(true, false, false),
        corner(true, false, true),
        corner(true, true, false),
        corner(true, true, true),
    ];
    let d = load8(values, &ix);
    let r = _mm256_blendv_ps(_mm256_set1_ps(g.background), interpolate(d, l.w), l.ok);
    _mm256_storeu_ps(out.as_mut_ptr(), r);
    // Lanes across an edge or a corner (two or three axes at 7): their
    // results are wrong here, and the caller redoes them.
    let n_edges = _mm256_sub_epi32(
        _mm256_setzero_si256(),
        _mm256_add_epi32(_mm256_add_epi32(edge[0], edge[1]), edge[2]),
    );
    let multi = _mm256_and_si256(
        _mm256_cmpgt_epi32(n_edges, _mm256_set1_epi32(1)),
        _mm256_castps_si256(l.ok),
    );
    _mm256_movemask_ps(_mm256_castsi256_ps(multi)) as u32
}

/// The values at eight index vectors, by scalar loads (see the module
/// docs for why not gathers).
///
/// # Safety
/// Every lane of `ix` must index a value of `values`.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn load8(values: *const f32, ix: &[__m256i; 8]) -> [__m256; 8] {
    let mut o = [[0u32; 8]; 8];
    for k in 0..8 {
        _mm256_storeu_si256(o[k].as_mut_ptr() as *mut __m256i, ix[k]);
    }
    let at = |i: u32| *values.add(i as usize);
    let row = |o: &[u32; 8]| {
        _mm256_set_m128(
            _mm_setr_ps(at(o[4]), at(o[5]), at(o[6]), at(o[7])),
            _mm_setr_ps(at(o[0]), at(o[1]), at(o[2]), at(o[3])),
        )
    };
    [
        row(&o[0]),
        row(&o[1]),
        row(&o[2]),
        row(&o[3]),
        row(&o[4]),
        row(&o[5]),
        row(&o[6]),
        row(&o[7]),
    ]
}

/// Trilinear interpolation of eight corners (ordered `[x][y][z]`) with
/// weights `w`, as `Grid::interpolate` computes it: `a + (b - a) * w` in
/// the same order, no fused multiply-add, so the same bits.
#[inline]
#[target_feature(enable = "avx2")]
fn interpolate(d: [__m256; 8], w: [__m256; 3]) -> __m256 {
    let lerp =
        |a: __m256, b: __m256, w: __m256| _mm256_add_ps(a, _mm256_mul_ps(_mm256_sub_ps(b, a), w));
    let y0 = lerp(lerp(d[0], d[1], w[2]), lerp(d[2], d[3], w[2]), w[1]);
    let y1 = lerp(lerp(d[4], d[5], w[2]), lerp(d[6], d[7], w[2]), w[1]);
    lerp(y0, y1, w[0])
}

/// Eight points of three floats (x y z x y z ...) as x, y and z vectors.
/// Plain loads and shuffles rather than three strided gathers: with
/// gathers, the reads of a long array of points were the hottest
/// instruction of the loop (21 % of samples in `perf`), as if they missed
/// the cache at every line, and the 512^3 cloud ran at 25 M/s against 40
/// with loads.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn load_xyz(p: *const f32) -> [__m256; 3] {
    // SAFETY: the caller passes 24 readable floats.
    let half = |k: usize| _mm_loadu_ps(p.add(k));
    // Low 128-bit halves hold points 0-3, high halves points 4-7.
    let m03 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(half(0)), half(12));
    let m14 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(half(4)), half(16));
    let m25 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(half(8)), half(20));
    // m03 = x0 y0 z0 x1, m14 = y1 z1 x2 y2, m25 = z2 x3 y3 z3 (per half).
    let xy = _mm256_shuffle_ps::<0b10_01_11_10>(m14, m25); // x2 y2 x3 y3
    let yz = _mm256_shuffle_ps::<0b01_00_10_01>(m03, m14); // y0 z0 y1 z1
    [
        _mm256_shuffle_ps::<0b10_00_11_00>(m03, xy), // x0 x1 x2 x3
        _mm256_shuffle_ps::<0b11_01_10_00>(yz, xy),  // y0 y1 y2 y3
        _mm256_shuffle_ps::<0b11_00_11_01>(yz, m25), // z0 z1 z2 z3
    ]
}

/// `(x&7)<<6 | (y&7)<<3 | (z&7)` per lane.
#[inline]
#[target_feature(enable = "avx2")]
fn voxel_offsets(i: [__m256i; 3]) -> __m256i {
    let seven = _mm256_set1_epi32(7);
    let low = i.map(|v| _mm256_and_si256(v, seven));
    _mm256_or_si256(
        _mm256_or_si256(
            _mm256_slli_epi32::<6>(low[0]),
            _mm256_slli_epi32::<3>(low[1]),
        ),
        low[2],
    )
}

/// All-ones lanes where the slot code is a constant.
#[inline]
#[target_feature(enable = "avx2")]
fn is_const(s: __m256i) -> __m256i {
    _mm256_srai_epi32::<31>(s)
}

/// The brick or constant index of a slot code.
#[inline]
#[target_feature(enable = "avx2")]
fn index(s: __m256i) -> __m256i {
    _mm256_and_si256(s, _mm256_set1_epi32(!CONST_BIT as i32))
}

/// Lanes where `t` is a cell of a dense array of `dims` cells.
#[inline]
#[target_feature(enable = "avx2")]
fn inside_lanes(t: [__m256i; 3], dims: [__m256i; 3]) -> __m256i {
    _mm256_and_si256(
        _mm256_and_si256(inside_axis(t[0], dims[0]), inside_axis(t[1], dims[1])),
        inside_axis(t[2], dims[2]),
    )
}

/// Lanes where `0 <= t < dim` (one axis of [`inside_lanes`]).
#[inline]
#[target_feature(enable = "avx2")]
fn inside_axis(t: __m256i, dim: __m256i) -> __m256i {
    _mm256_andnot_si256(
        _mm256_cmpgt_epi32(_mm256_setzero_si256(), t),
        _mm256_cmpgt_epi32(dim, t),
    )
}

/// Per axis, the lanes where the cell crosses a face of its 8^3 block:
/// where its low corner is the block's last voxel (`Grid`'s `block_edge`).
#[inline]
#[target_feature(enable = "avx2")]
fn block_edges(i: [__m256i; 3]) -> [__m256i; 3] {
    let seven = _mm256_set1_epi32(7);
    i.map(|v| _mm256_cmpeq_epi32(_mm256_and_si256(v, seven), seven))
}
