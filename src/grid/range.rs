//! Range queries for majorants and checks: the exact [min, max] a
//! trilinear lookup in a block can return, the range over a box of voxels,
//! and the grid's value range, active voxels and bounds.

use super::*;

impl<T: GridValue> Grid<T> {
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

    /// [min, max] of what trilinear lookups at index points in the cell
    /// `[c0, c0 + cell)³` read (the voxels `c0 ..= c0 + cell`): the bounds
    /// of a majorant cell. Exact for a brick-aligned cell of 8
    /// ([`Self::block_lookup_range`]) and for cells of up to 4 voxels
    /// ([`Self::voxel_range`]); larger cells take whole bricks
    /// ([`Self::range_in_box`]), a bound.
    pub fn cell_lookup_range(&self, c0: IVec3, cell: i32) -> [T; 2] {
        if cell == 8 && c0 & 7 == IVec3::ZERO {
            self.block_lookup_range(c0)
        } else if cell <= 4 {
            self.voxel_range(c0, c0 + cell)
        } else {
            self.range_in_box(c0, c0 + cell)
                .unwrap_or([self.background; 2])
        }
    }

    /// [min, max] of the voxels `lo ..= hi` exactly (outside the stored
    /// region, the background): what lookups in a cell of a few voxels
    /// read. [`Self::range_in_box`] answers brick by brick, so for a cell
    /// of 2 voxels it gives the range of the whole 8^3 brick (or two);
    /// this reads the voxels unless that range is a single value.
    pub fn voxel_range(&self, lo: IVec3, hi: IVec3) -> [T; 2] {
        if let Some(r) = self.range_in_box(lo, hi) {
            if r[0] == r[1] {
                return r;
            }
        }
        let mut r = [self.get(lo); 2];
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let v = self.get(IVec3::new(x, y, z));
                    r = [T::min(r[0], v), T::max(r[1], v)];
                }
            }
        }
        r
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

    pub fn brick_range(&self, b: usize) -> [T; 2] {
        self.ranges[b]
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
}
