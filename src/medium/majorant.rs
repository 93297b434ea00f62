//! Majorant grid and its DDA walk (pbrt-v4 §11.4.3, `MajorantGrid` and
//! `DDAMajorantIterator`; Amanatides & Woo 1987 for the traversal).
//!
//! A coarse grid over a volume's index space whose cells hold an upper bound
//! (majorant) and a lower bound (minorant) of the density that trilinear
//! lookups anywhere in the cell can return. Delta and ratio tracking sample
//! tentative collisions against the majorant, so the tighter it is the fewer
//! lookups they need; the minorant is the homogeneous control medium of
//! residual ratio tracking and decomposition tracking (Novák et al. 2014;
//! Kutz et al. 2017), which need lookups only for the residual between the
//! two. A bound on the wrong side biases every image silently, hence
//! [`MajorantGrid::validate`] and its tests.
//!
//! A lookup at index point `p` reads voxels `floor(p)` and `floor(p) + 1`
//! along each axis, so the cell covering `[c0, c1)` takes the range of the
//! voxels `c0 ..= c1`: padded by one voxel on the upper side.
//!
//! Emissive volumes also keep a bound of the emitted radiance per unit
//! length in each cell (world units, max over channels). Emission does not
//! depend on the extinction (flame glows where there is no smoke), so a
//! cell whose density bound is 0 may still emit: the walk reports such
//! cells, and the grid covers every emitting grid's voxels as well as the
//! density's.

use crate::grid::Grid;
use glam::{IVec3, Vec3};
use rayon::prelude::*;

/// The cells a majorant grid may have: this many (12 bytes each with
/// emission, 48 MiB; cells of 8 voxels over a 1,290³-voxel extent), or two
/// per brick of the density if that is more (a dense 2048³ grid keeps its
/// cells of 8). Beyond it the cells grow.
const MIN_CELL_BUDGET: i64 = 1 << 22;

/// Lower and upper bounds of the density per cell, over an index-space box.
#[derive(Debug, Clone)]
pub struct MajorantGrid {
    /// Index-space position of the corner of cell (0,0,0).
    origin: Vec3,
    /// Lower corner of the region a lookup can see nonzero values in (the
    /// first cells may start before it; walks are clipped to it).
    lower: Vec3,
    /// Upper corner of the region a lookup can see nonzero values in (the
    /// last cells may extend past it; walks are clipped to it).
    upper: Vec3,
    /// Voxels per cell edge.
    cell: i32,
    res: IVec3,
    /// `[min, max]` per cell, x fastest; for a moving volume one such
    /// array per time slab after the first (see [`TIME_SLABS`]).
    range: Vec<[f32; 2]>,
    /// Bound of the emitted radiance per unit length per cell (max over
    /// channels, world units), x fastest, slab after slab as `range`;
    /// empty when nothing emits.
    emission: Vec<f32>,
    /// Time slabs beyond the whole shutter's (0 for a still volume).
    slabs: usize,
}

/// Time slabs of a moving volume's majorant grid: besides the bounds over
/// the whole shutter (slab 0, what [`MajorantGrid::lookup`] and the photon
/// emitter see), bounds for lookups at the times of each of
/// `TIME_SLABS - 1` equal parts of the shutter, each cell widened only as
/// far as its neighbourhood moves over those times. A ray at time τ walks
/// its slab's cells. On the Blender smoke frame (a centred shutter) the
/// trackers met 2.1 times the still frame's tentative collisions with the
/// whole shutter's bounds.
pub const TIME_SLABS: usize = 8;

/// Cells (over all slabs) beyond which a moving volume keeps the whole
/// shutter's bounds only: 12 bytes a cell, 48 MiB.
const SLAB_CELL_BUDGET: usize = 1 << 22;

/// What [`MajorantGrid::build_emissive`] needs to know of a volume's
/// emission: the index box (density index space, inclusive) of the voxels
/// of every grid that emits, and a bound of the emitted radiance per unit
/// length over the lookups in a cell (its lower corner and edge in voxels).
pub struct EmissionBounds<'a> {
    pub voxels: Option<(IVec3, IVec3)>,
    pub bound: &'a dyn Fn(IVec3, i32) -> f32,
}

/// How far (density index units, per axis) a moving volume's lookups may
/// be displaced over the shutter (`crate::medium::motion`).
#[derive(Clone, Copy, Default)]
pub struct MotionReach<'a> {
    /// A bound for every lookup over the whole shutter: the fastest
    /// velocity anywhere (zero for a still volume).
    pub max: Vec3,
    /// When the shutter opens and closes (frames from the frame): the
    /// times of the time slabs.
    pub shutter: (f32, f32),
    /// The displacement per frame, `[min, max]` per axis, of the lookups
    /// whose velocity reads lie in a cell (its lower corner and edge in
    /// voxels): what the velocity there can return. A lookup at `p` reads
    /// the velocity at `p` and at `p` displaced once, both within `max` of
    /// `p`, so its displacement at time τ lies within τ times the union of
    /// these over the cells within `max` of `p`. A smoke plume's velocity
    /// is fast only in its core (on the Blender smoke frame the median
    /// speed is a sixth of the largest) and points one way there (up), so
    /// each cell's window is its own neighbourhood's motion over the slab's
    /// times, shifted along the flow, rather than the fastest motion
    /// anywhere both ways.
    pub local: Option<&'a (dyn Fn(IVec3, i32) -> [Vec3; 2] + Sync)>,
}

impl MajorantGrid {
    /// Builds the grid over the stored region of `density`, padded by one
    /// voxel (trilinear lookups just outside it still see its values), with
    /// cells of `cell` voxels, or of a power-of-two multiple of it where the
    /// extent would need more than `MIN_CELL_BUDGET` (2^22) cells (or two per
    /// brick). Returns `None` for an empty grid. Densities
    /// below zero count as zero (they are clamped at lookup, as in Cycles).
    /// Cells that reach outside the stored voxels see the background, which
    /// the minorant includes.
    pub fn build(density: &Grid<f32>, cell: i32) -> Option<Self> {
        Self::build_emissive(density, cell, None, MotionReach::default())
    }

    /// [`Self::build`] over the union of the density's stored voxels and the
    /// emitting voxels of `emission`, with an emission bound per cell.
    /// `None` when both are empty.
    ///
    /// `motion` says how far (index units, per axis) a moving volume's
    /// lookups may be displaced over the shutter: a lookup at `p` then
    /// reads the grids anywhere within that box around `p`, so each cell's
    /// bounds are those of its neighbours within it (a max and a min filter
    /// over the cells), and the grid reaches `motion.max` further on every
    /// side. Zero for a still volume.
    pub fn build_emissive(
        density: &Grid<f32>,
        cell: i32,
        emission: Option<EmissionBounds>,
        reach: MotionReach,
    ) -> Option<Self> {
        let motion = reach.max;
        let stored = density.stored_bounds();
        let emitting = emission.as_ref().and_then(|e| e.voxels);
        let (lo, hi) = match (stored, emitting) {
            (Some((a, b)), Some((c, d))) => (a.min(c), b.max(d)),
            (Some(x), None) | (None, Some(x)) => x,
            (None, None) => return None,
        };
        let motion = motion.max(Vec3::ZERO);
        let pad = motion.ceil().min(Vec3::splat(1e9)).as_ivec3();
        let lo = lo - 1 - pad;
        let hi = hi + 1 + pad;
        // A sparse grid (two voxels 20,000 apart) or emitting grids far
        // from the density would need billions of cells of 8 voxels:
        // coarser cells bound the same lookups, with more null collisions
        // where they are loose.
        let budget = MIN_CELL_BUDGET.max(2 * density.brick_count() as i64);
        let mut cell = cell.max(1);
        let (origin, res) = loop {
            let (origin, res) = if cell == 8 {
                // Cells aligned with the bricks, so that each cell's range is
                // the exact 9³ one of `block_lookup_range`. Lookups stay
                // below `hi`.
                let origin = (lo >> 3) << 3;
                (origin, ((hi - 1 - origin) >> 3) + 1)
            } else {
                // ceil((hi - lo + 1) / cell), in 64 bits: the extent may
                // be near 2^31 voxels.
                let c = i64::from(cell);
                let r = (hi.as_i64vec3() - lo.as_i64vec3() + c) / c;
                (
                    lo,
                    r.min(glam::I64Vec3::splat(i64::from(i32::MAX))).as_ivec3(),
                )
            };
            let cells = res.as_i64vec3();
            if cells.x * cells.y * cells.z <= budget || cell >= 1 << 30 {
                break (origin, res);
            }
            cell = cell.saturating_mul(2);
        };
        let n = (res.x as usize) * (res.y as usize) * (res.z as usize);
        let mut slabs = 0;
        let (range, emission) = if motion == Vec3::ZERO {
            cell_bounds(density, emission.as_ref(), origin, res, cell)
        } else {
            // A moving volume: a lookup in a cell may read anything within
            // `motion` of it. The bounds are dilated on cells finer than
            // the grid's, then gathered into its cells: a displacement of
            // 1.4 voxels widens an 8-voxel cell's window to 12 voxels
            // rather than to three cells (24).
            let mut fine = cell;
            for f in [cell / 8, cell / 4, cell / 2] {
                let r = (cell / f.max(1)) as i64;
                if f >= 1 && cell % f == 0 && n as i64 * r * r * r <= budget {
                    fine = f;
                    break;
                }
            }
            let ratio = cell / fine;
            let fres = res * ratio;
            let (fine_range, fine_emission) =
                cell_bounds(density, emission.as_ref(), origin, fres, fine);
            // Each cell's displacement per frame, [min, max] per axis: the
            // union of the local ranges within the reach of its lookups'
            // first velocity read, taken on the fine cells (a reach of 4.6
            // voxels then widens a cell by 5 voxels, not by two cells of
            // 4), then gathered into the cells: the per-slab filters below
            // work on cells, ratio³ times fewer (per fine cell they took
            // most of the load time of a 256³ moving volume).
            let k = (motion / fine as f32)
                .ceil()
                .min(Vec3::splat(1e9))
                .as_ivec3();
            let local = reach.local.map(|f| {
                // Slice by slice in parallel: reading the velocity voxels of
                // every fine cell is the costly part.
                let slices: Vec<Vec<[Vec3; 2]>> = (0..fres.z)
                    .into_par_iter()
                    .map(|z| {
                        let mut out = Vec::with_capacity((fres.x * fres.y) as usize);
                        for y in 0..fres.y {
                            for x in 0..fres.x {
                                out.push(f(origin + IVec3::new(x, y, z) * fine, fine));
                            }
                        }
                        out
                    })
                    .collect();
                let ranges = || slices.iter().flatten();
                let lo = [0, 1, 2].map(|c| ranges().map(|r| r[0][c]).collect::<Vec<f32>>());
                let hi = [0, 1, 2].map(|c| ranges().map(|r| r[1][c]).collect::<Vec<f32>>());
                let lo = lo.map(|mut v| {
                    dilate(&mut v, fres, k, f32::min);
                    gather(&v, fres, ratio, f32::INFINITY, f32::min)
                });
                let hi = hi.map(|mut v| {
                    dilate(&mut v, fres, k, f32::max);
                    gather(&v, fres, ratio, f32::NEG_INFINITY, f32::max)
                });
                (lo, hi)
            });
            // The whole shutter first, then each time slab (see
            // TIME_SLABS), when the cells fit the budget.
            slabs = if n * TIME_SLABS <= SLAB_CELL_BUDGET {
                TIME_SLABS - 1
            } else {
                0
            };
            let (open, close) = reach.shutter;
            let max_time = open.abs().max(close.abs());
            let parts: Vec<(Vec<[f32; 2]>, Vec<f32>)> = (0..=slabs)
                .into_par_iter()
                .map(|j| {
                    let (t0, t1) = if j == 0 {
                        (open, close)
                    } else {
                        let w = (close - open) / slabs as f32;
                        (open + (j - 1) as f32 * w, open + j as f32 * w)
                    };
                    // The share of the whole shutter's reach (1 when the
                    // shutter is unknown: a bound whatever the times).
                    let share = if max_time > 0.0 {
                        (t0.abs().max(t1.abs()) / max_time).min(1.0)
                    } else {
                        1.0
                    };
                    dilated(
                        &fine_range,
                        &fine_emission,
                        fres,
                        ratio,
                        motion * share,
                        local
                            .as_ref()
                            .filter(|_| max_time > 0.0)
                            .map(|(lo, hi)| Local {
                                lo,
                                hi,
                                times: (t0, t1),
                            }),
                        fine,
                    )
                })
                .collect();
            let mut range = Vec::with_capacity(n * (1 + slabs));
            let mut emission = Vec::new();
            for (r, e) in parts {
                range.extend(r);
                emission.extend(e);
            }
            (range, emission)
        };
        Some(Self {
            origin: origin.as_vec3(),
            lower: lo.as_vec3(),
            // Lookups at p read voxels floor(p) and floor(p) + 1: beyond
            // hi + 1 (hi already padded by one) they see only background.
            upper: hi.as_vec3(),
            cell,
            res,
            range,
            emission,
            slabs,
        })
    }

    /// The slab of a moving volume's lookups at `time` (frames from the
    /// frame) for a shutter open over `(open, close)`: slab `j` ≥ 1 bounds
    /// lookups at times within the `j`-th of the [`TIME_SLABS`] − 1 equal
    /// parts of the shutter, slab 0 the whole shutter (also for a time that
    /// is not finite, or outside the shutter).
    pub fn slab(&self, time: f32, (open, close): (f32, f32)) -> usize {
        let w = close - open;
        if self.slabs == 0 || w.is_nan() || w <= 0.0 {
            return 0;
        }
        let x = (time - open) / w * self.slabs as f32;
        if (0.0..=self.slabs as f32).contains(&x) {
            (x as usize).min(self.slabs - 1) + 1
        } else {
            0
        }
    }

    /// Whether any cell may emit.
    pub fn is_emissive(&self) -> bool {
        !self.emission.is_empty()
    }

    /// The emission bound of cell `c` (0 outside, or where nothing emits).
    pub fn cell_emission(&self, c: IVec3) -> f32 {
        if self.emission.is_empty() || c.cmplt(IVec3::ZERO).any() || c.cmpge(self.res).any() {
            return 0.0;
        }
        self.emission[((c.z * self.res.y + c.y) * self.res.x + c.x) as usize]
    }

    /// The index-space box of cell `c`: its lower corner and edge (voxels).
    pub fn cell_box(&self, c: IVec3) -> (Vec3, f32) {
        (self.origin + (c * self.cell).as_vec3(), self.cell as f32)
    }

    /// The index-space box outside which every lookup is background: the
    /// stored voxels' bounds widened by one voxel on each side.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.lower, self.upper)
    }

    pub fn resolution(&self) -> IVec3 {
        self.res
    }

    /// Voxels per cell edge.
    pub fn cell(&self) -> i32 {
        self.cell
    }

    /// The `[min, max]` bounds of the cell holding index point `p` (zeros
    /// outside).
    pub fn lookup(&self, p: Vec3) -> [f32; 2] {
        let c = ((p - self.origin) / self.cell as f32).floor().as_ivec3();
        if c.cmplt(IVec3::ZERO).any() || c.cmpge(self.res).any() {
            return [0.0; 2];
        }
        self.range[((c.z * self.res.y + c.y) * self.res.x + c.x) as usize]
    }

    /// Sets every lower bound to 0 (no minorant). For benchmarks and tests.
    pub fn clear_minorant(&mut self) {
        for r in &mut self.range {
            r[0] = 0.0;
        }
    }

    /// Largest bound anywhere.
    pub fn max(&self) -> f32 {
        self.range.iter().map(|r| r[1]).fold(0.0, f32::max)
    }

    /// Checks that every cell bounds the trilinear lookups inside it from
    /// above and below, at
    /// `samples_per_cell` random points per cell plus its corners. For tests.
    pub fn validate(&self, density: &Grid<f32>, samples_per_cell: u32) -> Result<(), String> {
        let mut state = 0x853c_49e6_748f_ea9bu64;
        let mut rnd = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 40) as f32) / (1u64 << 24) as f32
        };
        for z in 0..self.res.z {
            for y in 0..self.res.y {
                for x in 0..self.res.x {
                    let c = IVec3::new(x, y, z);
                    let [lower, bound] =
                        self.range[((z * self.res.y + y) * self.res.x + x) as usize];
                    let c0 = self.origin + (c * self.cell).as_vec3();
                    let size = self.cell as f32;
                    let check = |p: Vec3| {
                        let v = density.sample_index(p).max(0.0);
                        if v > bound {
                            return Err(format!(
                                "cell {c}: lookup {v} at {p} above its bound {bound}"
                            ));
                        }
                        if v < lower {
                            return Err(format!(
                                "cell {c}: lookup {v} at {p} below its lower bound {lower}"
                            ));
                        }
                        Ok(())
                    };
                    for k in 0..8 {
                        let corner =
                            Vec3::new((k & 1) as f32, ((k >> 1) & 1) as f32, (k >> 2) as f32);
                        check(c0 + corner * (size - 1e-3))?;
                    }
                    for _ in 0..samples_per_cell {
                        check(c0 + Vec3::new(rnd(), rnd(), rnd()) * size)?;
                    }
                }
            }
        }
        Ok(())
    }

    /// Walks the cells a ray crosses between `t0` and `t1`. The ray is in
    /// index space (`o + t d`); `t` keeps whatever unit the caller's `d`
    /// implies (world distance for a unit world direction mapped to index
    /// space).
    pub fn walk(&self, o: Vec3, d: Vec3, t0: f32, t1: f32) -> Dda<'_> {
        self.walk_slab(o, d, t0, t1, 0)
    }

    /// [`Self::walk`] through the bounds of time slab `slab` ([`Self::slab`]).
    pub fn walk_slab(&self, o: Vec3, d: Vec3, t0: f32, t1: f32, slab: usize) -> Dda<'_> {
        let n = (self.res.x as usize) * (self.res.y as usize) * (self.res.z as usize);
        let (lo, hi) = self.bounds();
        // Clip to the grid's box (slab test; ±0 directions handled by the
        // IEEE infinities of 1/d).
        let inv = d.recip();
        let ta = (lo - o) * inv;
        let tb = (hi - o) * inv;
        let tmin = ta.min(tb);
        let tmax = ta.max(tb);
        let mut t_enter = t0.max(tmin.max_element());
        let t_exit = t1.min(tmax.min_element());
        if t_enter.is_nan() || t_exit.is_nan() {
            t_enter = f32::INFINITY;
        }
        let mut dda = Dda {
            grid: self,
            base: n * slab.min(self.slabs),
            cell: IVec3::ZERO,
            step: IVec3::ZERO,
            next_t: Vec3::ZERO,
            delta_t: Vec3::ZERO,
            t: t_enter,
            t_end: t_exit,
        };
        if t_enter.partial_cmp(&t_exit) != Some(std::cmp::Ordering::Less) {
            dda.t = f32::INFINITY;
            return dda;
        }
        let cs = self.cell as f32;
        let p = (o + d * t_enter - self.origin) / cs;
        // p is inside the clipped box, so above −1: truncating p + 1 is the
        // floor, without libm's floorf (a call per axis, per flight).
        let cell = ((p + Vec3::ONE).as_ivec3() - IVec3::ONE).clamp(IVec3::ZERO, self.res - 1);
        let mut step = IVec3::ZERO;
        let mut next_t = Vec3::splat(f32::INFINITY);
        let mut delta_t = Vec3::splat(f32::INFINITY);
        for a in 0..3 {
            if d[a] == 0.0 {
                continue;
            }
            // Distance in t for one cell along this axis.
            delta_t[a] = (cs / d[a]).abs();
            if d[a] > 0.0 {
                step[a] = 1;
                let boundary = self.origin[a] + (cell[a] + 1) as f32 * cs;
                next_t[a] = t_enter + (boundary - (o[a] + d[a] * t_enter)) / d[a];
            } else {
                step[a] = -1;
                let boundary = self.origin[a] + cell[a] as f32 * cs;
                next_t[a] = t_enter + (boundary - (o[a] + d[a] * t_enter)) / d[a];
            }
        }
        dda.cell = cell;
        dda.step = step;
        dda.next_t = next_t;
        dda.delta_t = delta_t;
        dda
    }
}

/// The `[min, max]` density bounds of each cell of a `res` grid of cells of
/// `cell` voxels from `origin` (x fastest), and the emission bounds when
/// `emission` is given (empty when nothing emits).
fn cell_bounds(
    density: &Grid<f32>,
    emission: Option<&EmissionBounds>,
    origin: IVec3,
    res: IVec3,
    cell: i32,
) -> (Vec<[f32; 2]>, Vec<f32>) {
    let n = (res.x as usize) * (res.y as usize) * (res.z as usize);
    let mut range = Vec::with_capacity(n);
    let mut bound = Vec::with_capacity(if emission.is_some() { n } else { 0 });
    for z in 0..res.z {
        for y in 0..res.y {
            for x in 0..res.x {
                let c0 = origin + IVec3::new(x, y, z) * cell;
                let [a, b] = density.cell_lookup_range(c0, cell);
                range.push([a.max(0.0), b.max(0.0)]);
                if let Some(e) = emission {
                    bound.push((e.bound)(c0, cell).max(0.0));
                }
            }
        }
    }
    if bound.iter().all(|&b| b <= 0.0) {
        bound.clear();
    }
    (range, bound)
}

/// Each cell's displacement per frame, `[min, max]` per axis
/// (`lo[axis][cell]`, `hi[axis][cell]`, index units), on the grid of cells
/// `ratio` fine cells wide, and the times `(t0, t1)` of a time slab.
struct Local<'a> {
    lo: &'a [Vec<f32>; 3],
    hi: &'a [Vec<f32>; 3],
    times: (f32, f32),
}

/// The bounds of cells `ratio` fine cells wide from fine-cell bounds
/// (`fres` of them, `fine` voxels each), dilated by `motion` voxels per
/// axis: each cell then bounds every lookup displaced that far from it.
/// With `local`, each fine cell's window is its own: the lookup at `p` and
/// time τ reads `p − τ·s` with `s` within the cell's range, so over the
/// slab's times the window is the cell shifted by `−τ·[min, max]`, within
/// `motion` of it.
fn dilated(
    fine_range: &[[f32; 2]],
    fine_emission: &[f32],
    fres: IVec3,
    ratio: i32,
    motion: Vec3,
    local: Option<Local>,
    fine: i32,
) -> (Vec<[f32; 2]>, Vec<f32>) {
    // Within `k` fine cells: a displaced point lies in
    // (c0 − motion, c0 + fine + motion), and motion ≤ k·fine.
    let cells = |m: f32| (m / fine as f32).ceil().clamp(-1e9, 1e9) as i32;
    let k = IVec3::new(cells(motion.x), cells(motion.y), cells(motion.z));
    let mut upper: Vec<f32> = fine_range.iter().map(|r| r[1]).collect();
    let mut lower: Vec<f32> = fine_range.iter().map(|r| r[0]).collect();
    let mut emission = fine_emission.to_vec();
    // Beyond the grid every lookup is background: 0 (densities below 0
    // count as 0).
    match local {
        None => {
            dilate(&mut upper, fres, k, f32::max);
            dilate(&mut lower, fres, k, f32::min);
            if !emission.is_empty() {
                dilate(&mut emission, fres, k, f32::max);
            }
        }
        Some(Local {
            lo,
            hi,
            times: (t0, t1),
        }) => {
            // Window offsets in fine cells per axis: a point of a fine
            // cell [c0, c0 + fine) displaced by d in [d0, d1] lies in
            // [c0 − d1, c0 + fine − d0), the cells floor(−d1 / fine) to
            // ceil(−d0 / fine) from it; never beyond k. Each fine cell
            // takes its cell's range.
            let res = fres / ratio;
            let n = lo[0].len();
            let mut first = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
            let mut last = first.clone();
            for a in 0..3 {
                for i in 0..n {
                    let (s0, s1) = (lo[a][i], hi[a][i]);
                    let p = [t0 * s0, t0 * s1, t1 * s0, t1 * s1];
                    let d0 = p.into_iter().fold(f32::INFINITY, f32::min);
                    let d1 = p.into_iter().fold(f32::NEG_INFINITY, f32::max);
                    let f = ((-d1 / fine as f32).floor().clamp(-1e9, 1e9) as i32).max(-k[a]);
                    let l = cells(-d0).min(k[a]);
                    first[a][i] = f.min(l) as f32;
                    last[a][i] = l.max(f) as f32;
                }
            }
            // A separable filter whose window varies: the x pass at a cell
            // q serves every output cell p whose y and z windows hold q,
            // all within k.y, k.z fine cells of it (so within
            // ceil(k / ratio) cells), so it takes the widest x window over
            // those (and the y pass the widest y window within k.z); the z
            // pass takes p's own.
            let kc = IVec3::new(
                (k.x + ratio - 1) / ratio,
                (k.y + ratio - 1) / ratio,
                (k.z + ratio - 1) / ratio,
            );
            dilate(&mut first[0], res, IVec3::new(0, kc.y, kc.z), f32::min);
            dilate(&mut last[0], res, IVec3::new(0, kc.y, kc.z), f32::max);
            dilate(&mut first[1], res, IVec3::new(0, 0, kc.z), f32::min);
            dilate(&mut last[1], res, IVec3::new(0, 0, kc.z), f32::max);
            let fine_of = |v: &Vec<f32>| -> Vec<f32> {
                if ratio == 1 {
                    return v.clone();
                }
                let r = ratio as usize;
                let mut out = Vec::with_capacity(fine_range.len());
                for z in 0..fres.z as usize {
                    for y in 0..fres.y as usize {
                        let row = ((z / r) * res.y as usize + y / r) * res.x as usize;
                        let cells = &v[row..row + res.x as usize];
                        out.extend(cells.iter().flat_map(|&c| std::iter::repeat_n(c, r)));
                    }
                }
                out
            };
            let first = first.each_ref().map(fine_of);
            let last = last.each_ref().map(fine_of);
            for axis in 0..3 {
                let (f, l) = (&first[axis], &last[axis]);
                filter_axis_varying(&mut upper, fres, axis, f, l, f32::max);
                filter_axis_varying(&mut lower, fres, axis, f, l, f32::min);
                if !emission.is_empty() {
                    filter_axis_varying(&mut emission, fres, axis, f, l, f32::max);
                }
            }
        }
    }
    let mut range: Vec<[f32; 2]> = lower.into_iter().zip(upper).map(|(a, b)| [a, b]).collect();
    if ratio > 1 {
        range = gather(&range, fres, ratio, [f32::INFINITY, 0.0], |a, b| {
            [a[0].min(b[0]), a[1].max(b[1])]
        });
        if !emission.is_empty() {
            emission = gather(&emission, fres, ratio, 0.0, f32::max);
        }
    }
    (range, emission)
}

/// The `res / ratio` grid whose each value is `op` over the `ratio`³ values
/// of the `res` grid `v` it covers (x fastest).
fn gather<T: Copy>(v: &[T], res: IVec3, ratio: i32, init: T, op: impl Fn(T, T) -> T) -> Vec<T> {
    let c = res / ratio;
    let mut out = vec![init; (c.x as usize) * (c.y as usize) * (c.z as usize)];
    let (nx, r) = (res.x as usize, ratio as usize);
    let cells = nx * res.y as usize * res.z as usize;
    for (row, src) in v[..cells].chunks_exact(nx).enumerate() {
        let (y, z) = (row % res.y as usize, row / res.y as usize);
        let base = ((z / r) * c.y as usize + y / r) * c.x as usize;
        let dst = &mut out[base..base + c.x as usize];
        for (x, &s) in src.iter().enumerate() {
            let o = &mut dst[x / r];
            *o = op(*o, s);
        }
    }
    out
}

/// Replaces each value of the `res` grid `v` (x fastest) by `op` over the
/// values within `k` cells along each axis, counting cells beyond the grid
/// as 0: a separable max (or min) filter, each line by van Herk and
/// Gil-Werman's algorithm (three `op`s a cell whatever `k`).
fn dilate(v: &mut [f32], res: IVec3, k: IVec3, op: impl Fn(f32, f32) -> f32 + Copy) {
    let dims = [res.x as usize, res.y as usize, res.z as usize];
    let strides = [1, dims[0], dims[0] * dims[1]];
    for axis in 0..3 {
        let r = k[axis].max(0) as usize;
        if r == 0 {
            continue;
        }
        let n = dims[axis];
        let stride = strides[axis];
        let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut line = vec![0.0f32; n];
        let mut out = vec![0.0f32; n];
        let mut g = vec![0.0f32; n + 2 * r];
        let mut h = vec![0.0f32; n + 2 * r];
        for j in 0..dims[b] {
            for i in 0..dims[a] {
                let base = i * strides[a] + j * strides[b];
                for (t, x) in line.iter_mut().enumerate() {
                    *x = v[base + t * stride];
                }
                filter_line(&line, r, op, &mut g, &mut h, &mut out);
                for (t, x) in out.iter().enumerate() {
                    v[base + t * stride] = *x;
                }
            }
        }
    }
}

/// Replaces each value of the `res` grid `v` (x fastest) by `op` over the
/// values from `first` to `last` cells (its own, whole numbers, `first` ≤
/// `last`) from it along `axis`, counting cells beyond the grid as 0. Each
/// line through a sparse table (the op over each run of 2^l cells), so any
/// window costs one query.
fn filter_axis_varying(
    v: &mut [f32],
    res: IVec3,
    axis: usize,
    first: &[f32],
    last: &[f32],
    op: impl Fn(f32, f32) -> f32 + Copy,
) {
    let dims = [res.x as usize, res.y as usize, res.z as usize];
    let strides = [1, dims[0], dims[0] * dims[1]];
    let n = dims[axis];
    let stride = strides[axis];
    let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
    // table[l][j]: op over line[j ..= j + 2^l − 1] of the line padded by
    // `pad` zeros on each side, as far as its windows reach (at most n: a
    // window beyond n cells sees the whole line anyway).
    let ni = n as i64;
    let mut table: Vec<Vec<f32>> = Vec::new();
    let mut offsets = vec![(0i64, 0i64); n];
    let mut win = vec![(0usize, 0usize); n];
    for j in 0..dims[b] {
        for i in 0..dims[a] {
            let base = i * strides[a] + j * strides[b];
            let mut pad = 0;
            for (t, o) in offsets.iter_mut().enumerate() {
                let c = base + t * stride;
                let f = (first[c] as i64).clamp(-ni, ni);
                let l = (last[c] as i64).clamp(-ni, ni).max(f);
                *o = (f, l);
                pad = pad.max(f.abs()).max(l.abs());
            }
            if pad == 0 {
                continue;
            }
            let m = n + 2 * pad as usize;
            let mut widest = 1;
            for (t, (w, &(f, l))) in win.iter_mut().zip(&offsets).enumerate() {
                let lo = (pad + t as i64 + f) as usize;
                let hi = (pad + t as i64 + l) as usize;
                *w = (lo, hi);
                widest = widest.max(hi - lo + 1);
            }
            let levels = (usize::BITS - widest.leading_zeros()) as usize;
            table.resize_with(levels.max(table.len()), Vec::new);
            let t0 = &mut table[0];
            t0.clear();
            t0.resize(m, 0.0);
            for t in 0..n {
                t0[pad as usize + t] = v[base + t * stride];
            }
            for l in 1..levels {
                let (done, rest) = table.split_at_mut(l);
                let (prev, cur) = (&done[l - 1], &mut rest[0]);
                let h = 1 << (l - 1);
                cur.clear();
                cur.extend((0..m).map(|j| {
                    if j + h < m {
                        op(prev[j], prev[j + h])
                    } else {
                        prev[j]
                    }
                }));
            }
            for (t, &(lo, hi)) in win.iter().enumerate() {
                let l = (usize::BITS - 1 - (hi - lo + 1).leading_zeros()) as usize;
                let row = &table[l];
                v[base + t * stride] = op(row[lo], row[hi + 1 - (1 << l)]);
            }
        }
    }
}

/// `out[i] = op(src[i − r ..= i + r])`, values beyond `src` being 0; `g`
/// and `h` are scratch of `src.len() + 2r`.
fn filter_line(
    src: &[f32],
    r: usize,
    op: impl Fn(f32, f32) -> f32,
    g: &mut [f32],
    h: &mut [f32],
    out: &mut [f32],
) {
    let n = src.len();
    let w = 2 * r + 1;
    let m = n + 2 * r;
    let at = |j: usize| if j >= r && j < r + n { src[j - r] } else { 0.0 };
    // g: running op from the start of each block of w; h: from its end.
    for j in 0..m {
        g[j] = if j % w == 0 {
            at(j)
        } else {
            op(g[j - 1], at(j))
        };
    }
    for j in (0..m).rev() {
        h[j] = if j == m - 1 || (j + 1) % w == 0 {
            at(j)
        } else {
            op(h[j + 1], at(j))
        };
    }
    // The window [i, i + w − 1] of the padded line spans at most two
    // blocks: the end of i's and the start of the next.
    for (i, o) in out.iter_mut().enumerate() {
        *o = op(h[i], g[i + w - 1]);
    }
}

/// One stretch of a ray with constant bounds of the density (of σt, once
/// `Media` has scaled them) and of the emission.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    pub t0: f32,
    pub t1: f32,
    /// Upper bound along `[t0, t1)`.
    pub max_density: f32,
    /// Lower bound along `[t0, t1)` (≥ 0).
    pub min_density: f32,
    /// Upper bound of the emitted radiance per unit length along
    /// `[t0, t1)` (max over channels, world units; 0 where nothing emits).
    pub emission: f32,
}

/// Iterator over the cells of a [`MajorantGrid`] along a ray.
#[derive(Debug, Clone)]
pub struct Dda<'a> {
    grid: &'a MajorantGrid,
    /// Where the walked slab's cells start in `range` and `emission`.
    base: usize,
    cell: IVec3,
    step: IVec3,
    next_t: Vec3,
    delta_t: Vec3,
    t: f32,
    t_end: f32,
}

impl Iterator for Dda<'_> {
    type Item = Segment;

    #[inline]
    fn next(&mut self) -> Option<Segment> {
        if self.t.partial_cmp(&self.t_end) != Some(std::cmp::Ordering::Less) {
            return None;
        }
        let g = self.grid;
        let c = self.cell;
        let i = self.base + ((c.z * g.res.y + c.y) * g.res.x + c.x) as usize;
        let [lo, hi] = g.range[i];
        let emission = g.emission.get(i).copied().unwrap_or(0.0);
        // The axis whose boundary comes first.
        let a = if self.next_t.x < self.next_t.y {
            if self.next_t.x < self.next_t.z {
                0
            } else {
                2
            }
        } else if self.next_t.y < self.next_t.z {
            1
        } else {
            2
        };
        let t1 = self.next_t[a].min(self.t_end);
        let seg = Segment {
            t0: self.t,
            t1,
            max_density: hi,
            min_density: lo,
            emission,
        };
        self.t = t1;
        self.cell[a] += self.step[a];
        self.next_t[a] += self.delta_t[a];
        if self.cell[a] < 0 || self.cell[a] >= g.res[a] {
            self.t = f32::INFINITY;
        }
        Some(seg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn local_dilation_covers_each_cells_own_window() {
        // Random bounds and random displacement ranges per cell: each
        // cell's result must bound every cell its own lookups can reach
        // over the slab's times (the cell displaced by −τ·s, τ in the slab,
        // s in its range, within the global reach). The passes take the
        // widest window of the cells they serve; with each cell's own
        // window in every pass this fails.
        // On fine cells (the bounds) of cells `ratio` fine cells wide (the
        // displacement ranges), as `build_emissive` calls it.
        for seed in 1..40 {
            for ratio in [1, 2] {
                local_dilation_case(IVec3::new(10, 8, 6), ratio, seed);
            }
        }
    }

    fn local_dilation_case(res: IVec3, ratio: i32, seed: u64) {
        let n = (res.x * res.y * res.z) as usize;
        let cres = res / ratio;
        let nc = (cres.x * cres.y * cres.z) as usize;
        let mut state = seed;
        let mut rnd = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 40) as f32) / (1u64 << 24) as f32
        };
        let range: Vec<[f32; 2]> = (0..n)
            .map(|_| {
                let a = rnd();
                [a, a + rnd()]
            })
            .collect();
        let emission: Vec<f32> = (0..n).map(|_| rnd()).collect();
        // Displacement per frame, index units: up to 12 along each axis
        // (3 fine cells over the shutter's reach of 0.25 frames, not a
        // multiple of the ratio 2), one way along z.
        let per_frame = Vec3::new(12.0, 12.0, 12.0);
        let (mut lo, mut hi) = ([vec![], vec![], vec![]], [vec![], vec![], vec![]]);
        for a in 0..3 {
            for _ in 0..nc {
                let (u, w) = (rnd() * 2.0 - 1.0, rnd() * 2.0 - 1.0);
                let (u, w) = if a == 2 { (u.abs(), w.abs()) } else { (u, w) };
                lo[a].push(u.min(w) * per_frame[a]);
                hi[a].push(u.max(w) * per_frame[a]);
            }
        }
        let max_time = 0.25;
        let motion = per_frame * max_time;
        let idx = |p: IVec3| ((p.z * res.y + p.y) * res.x + p.x) as usize;
        let cidx = |p: IVec3| {
            let c = p / ratio;
            ((c.z * cres.y + c.y) * cres.x + c.x) as usize
        };
        for (t0, t1) in [(-0.25, 0.25), (-0.25, -0.1), (0.05, 0.15), (0.0, 0.25)] {
            let share = f32::max(f32::abs(t0), f32::abs(t1)) / max_time;
            let local = Local {
                lo: &lo,
                hi: &hi,
                times: (t0, t1),
            };
            let (r, e) = dilated(
                &range,
                &emission,
                res,
                ratio,
                motion * share,
                Some(local),
                1,
            );
            assert_eq!(r.len(), nc);
            for z in 0..res.z {
                for y in 0..res.y {
                    for x in 0..res.x {
                        let p = IVec3::new(x, y, z);
                        let ci = cidx(p);
                        // The reachable cells: [p − d1, p + 1 − d0) over d
                        // in τ·[lo, hi] of p's cell, clipped to the global
                        // reach.
                        let (mut f, mut l) = (IVec3::ZERO, IVec3::ZERO);
                        for a in 0..3 {
                            let ds = [
                                t0 * lo[a][ci],
                                t0 * hi[a][ci],
                                t1 * lo[a][ci],
                                t1 * hi[a][ci],
                            ];
                            let d0 = ds.iter().copied().fold(f32::INFINITY, f32::min);
                            let d1 = ds.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                            let k = (motion[a] * share).ceil() as i32;
                            f[a] = ((-d1).floor() as i32).max(-k);
                            l[a] = ((-d0).ceil() as i32).min(k);
                        }
                        let (mut want_lo, mut want_hi, mut want_e) =
                            (f32::INFINITY, 0.0f32, 0.0f32);
                        for dz in f.z..=l.z {
                            for dy in f.y..=l.y {
                                for dx in f.x..=l.x {
                                    let q = p + IVec3::new(dx, dy, dz);
                                    if q.cmplt(IVec3::ZERO).any() || q.cmpge(res).any() {
                                        want_lo = want_lo.min(0.0);
                                        continue;
                                    }
                                    want_lo = want_lo.min(range[idx(q)][0]);
                                    want_hi = want_hi.max(range[idx(q)][1]);
                                    want_e = want_e.max(emission[idx(q)]);
                                }
                            }
                        }
                        assert!(
                            r[ci][1] >= want_hi && r[ci][0] <= want_lo && e[ci] >= want_e,
                            "{p} ratio {ratio} times {t0}..{t1} seed {seed}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn dilation_is_the_max_and_min_over_the_window() {
        let res = IVec3::new(7, 5, 4);
        let n = (res.x * res.y * res.z) as usize;
        let v: Vec<f32> = (0..n).map(|i| ((i * 37 % 23) as f32) - 5.0).collect();
        let at = |p: IVec3| {
            if p.cmplt(IVec3::ZERO).any() || p.cmpge(res).any() {
                0.0
            } else {
                v[((p.z * res.y + p.y) * res.x + p.x) as usize]
            }
        };
        for k in [
            IVec3::new(1, 2, 0),
            IVec3::new(3, 1, 1),
            IVec3::new(9, 0, 2),
        ] {
            for (op, name) in [(f32::max as fn(f32, f32) -> f32, "max"), (f32::min, "min")] {
                let mut d = v.clone();
                dilate(&mut d, res, k, op);
                for z in 0..res.z {
                    for y in 0..res.y {
                        for x in 0..res.x {
                            let p = IVec3::new(x, y, z);
                            let mut want = at(p);
                            for dz in -k.z..=k.z {
                                for dy in -k.y..=k.y {
                                    for dx in -k.x..=k.x {
                                        want = op(want, at(p + IVec3::new(dx, dy, dz)));
                                    }
                                }
                            }
                            let got = d[((z * res.y + y) * res.x + x) as usize];
                            assert_eq!(got, want, "{name} k {k} at {p}");
                        }
                    }
                }
            }
        }
        let g = gather(&v, IVec3::new(6, 4, 4), 2, f32::NEG_INFINITY, f32::max);
        assert_eq!(g.len(), 3 * 2 * 2);
        assert_eq!(
            g[0],
            [0, 1, 6, 7, 24, 25, 30, 31]
                .map(|i| v[i])
                .into_iter()
                .fold(f32::NEG_INFINITY, f32::max)
        );
    }
}
