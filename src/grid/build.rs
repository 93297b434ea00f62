//! Building a grid: its parts (bricks, tiles, transform) as a reader or a
//! generator hands them over, checked to fit together, and the indices a
//! lookup walks (the two-level index of 128^3 regions and 16^3-slot nodes,
//! and the flat array of 8^3 blocks when the extent is compact).

use super::*;

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

/// The inverse transform. For a diagonal matrix (OpenVDB's scale and
/// scale-translate maps, what nearly every file uses) it is built from exact
/// reciprocals, as OpenVDB's `ScaleTranslateMap::applyInverseMap` computes
/// `(p - t) * (1/s)`: a generic matrix inverse can put a point that lies on
/// a voxel centre one ulp to the other side of it.
pub(super) fn invert(m: &DAffine3) -> Option<(DAffine3, bool)> {
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
    pub(super) fn top_index(&self, t: IVec3) -> usize {
        linear_index(t, self.top_dims)
    }

    /// The node slot for the brick containing `ijk`, creating the node.
    pub(super) fn node_slot_mut(&mut self, ijk: IVec3) -> std::result::Result<&mut u32, String> {
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
    pub(super) fn build_flat(&mut self) {
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
