//! Velocity motion blur: where a moving volume's lookups go at a time
//! within the shutter.
//!
//! A volume is stored at the frame's time; at time τ (frames from the
//! frame, negative before it) its contents are found by one first-order
//! semi-Lagrangian step back along the velocity u (world units per frame):
//!
//! φ(x, τ) = φ(x − τ·u(x, τ), 0), with u(x, τ) = u(x − τ·u(x, 0), 0),
//!
//! the self-advected velocity itself estimated by one step (Kim & Ko 2007,
//! "Eulerian motion blur"; Wreninge 2012, "Production Volume Rendering").
//! That is Cycles' `volume_shader_motion_blur` exactly: two velocity
//! lookups, then every grid (density, temperature, flame, colour) read at
//! the advected point, so that images compare. Outside the velocity grid's
//! voxels its background (zero) leaves lookups where they are.
//!
//! The velocity grid is read as Cycles reads it: one vector per voxel,
//! interpolated trilinearly at the voxel centres, also for OpenVDB's
//! `staggered` class (Mantaflow's MAC grids), whose components really sit
//! on the faces; as a `vec3s` grid or three float grids (Houdini's `vel.x`,
//! `vel.y`, `vel.z`) on one transform.

use crate::grid::Grid;
use glam::{Affine3A, DAffine3, IVec3, Mat3, Vec3};

/// |M|·v with |M| the matrix of |entries|: per component, the bound of
/// M·w over every w with |w_j| ≤ v_j.
fn abs_mul(m: Mat3, v: Vec3) -> Vec3 {
    Mat3::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs()) * v
}

/// Frames a shutter open over `(open, close)` reaches from the frame,
/// either way.
fn reach((open, close): (f32, f32)) -> f32 {
    open.abs().max(close.abs())
}

/// A volume's velocity: one vector grid, or three float grids, one per
/// component, with the same transform.
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)] // one per volume
pub enum VelocityGrids {
    Vector(Grid<Vec3>),
    Split([Grid<f32>; 3]),
}

impl VelocityGrids {
    /// The grids' own index-to-world transform (the file's).
    pub fn world_from_index(&self) -> DAffine3 {
        match self {
            VelocityGrids::Vector(g) => g.world_from_index(),
            VelocityGrids::Split(g) => g[0].world_from_index(),
        }
    }

    /// The largest magnitude of each component over every voxel and tile
    /// (and the background), in the grid's own units: a bound of every
    /// trilinear lookup, which is a convex combination of voxels.
    pub fn max_components(&self) -> Vec3 {
        match self {
            VelocityGrids::Vector(g) => {
                let r = g
                    .value_range()
                    .map_or(Vec3::ZERO, |[lo, hi]| lo.abs().max(hi.abs()));
                r.max(g.background().abs())
            }
            VelocityGrids::Split(gs) => Vec3::from(gs.each_ref().map(|g| {
                g.value_range()
                    .map_or(0.0, |[lo, hi]| lo.abs().max(hi.abs()))
                    .max(g.background().abs())
            })),
        }
    }

    /// Bytes the grids take.
    pub fn memory_bytes(&self) -> usize {
        match self {
            VelocityGrids::Vector(g) => g.memory_bytes(),
            VelocityGrids::Split(gs) => gs.iter().map(|g| g.memory_bytes()).sum(),
        }
    }

    /// [min, max] of each component that lookups in the index cell
    /// `[c0, c0 + cell)³` read ([`Grid::cell_lookup_range`]).
    pub fn cell_range(&self, c0: IVec3, cell: i32) -> [Vec3; 2] {
        match self {
            VelocityGrids::Vector(g) => g.cell_lookup_range(c0, cell),
            VelocityGrids::Split(gs) => {
                let r = gs.each_ref().map(|g| g.cell_lookup_range(c0, cell));
                [Vec3::from(r.map(|r| r[0])), Vec3::from(r.map(|r| r[1]))]
            }
        }
    }

    /// [`Self::cell_range`] for lookups in the inclusive index box
    /// `lo..=hi` (whole bricks: a bound).
    pub fn box_range(&self, lo: IVec3, hi: IVec3) -> [Vec3; 2] {
        match self {
            VelocityGrids::Vector(g) => g.range_in_box(lo, hi).unwrap_or([g.background(); 2]),
            VelocityGrids::Split(gs) => {
                let r = gs
                    .each_ref()
                    .map(|g| g.range_in_box(lo, hi).unwrap_or([g.background(); 2]));
                [Vec3::from(r.map(|r| r[0])), Vec3::from(r.map(|r| r[1]))]
            }
        }
    }

    #[inline(always)]
    fn sample_index(&self, q: Vec3) -> Vec3 {
        match self {
            VelocityGrids::Vector(g) => g.sample_index(q),
            VelocityGrids::Split(g) => {
                let [x, y, z] = g;
                Vec3::new(x.sample_index(q), y.sample_index(q), z.sample_index(q))
            }
        }
    }
}

/// A velocity field as the scene gives it: its grids and the world
/// displacement per frame that a unit vector of them stands for before the
/// volume's transform (`velocity_scale`, divided by the frame rate for
/// grids in units per second).
#[derive(Debug, Clone)]
pub struct VelocityField {
    pub grids: VelocityGrids,
    /// When the shutter opens and closes, in frames from the frame
    /// (`(-0.25, 0.25)` for Blender's default, centred on the frame): the
    /// times lookups may be advected to.
    pub shutter: (f32, f32),
    /// Displacement per frame of a unit grid vector along each of the
    /// grid's axes, in the file's world units (`velocity_scale`, divided
    /// by the frame rate for velocities per second).
    pub per_frame: Vec3,
}

/// A moving volume's velocity, placed in the scene.
#[derive(Debug, Clone)]
pub struct Motion {
    grids: VelocityGrids,
    /// The velocity grids' index space from world space.
    index_from_world: Affine3A,
    /// World displacement per frame of a grid vector: the volume's scene
    /// transform (its linear part: grid vectors are in the file's world
    /// space) times `per_frame`.
    world_per_frame: Mat3,
    /// The same in the velocity grids' index units.
    index_per_frame: Mat3,
    /// The largest magnitude of each grid component.
    max_components: Vec3,
    /// When the shutter opens and closes, in frames from the frame.
    shutter: (f32, f32),
}

impl Motion {
    /// The motion of a volume placed by `transform`; `None` when nothing
    /// moves (a zero velocity grid, a zero scale or a zero shutter), so that
    /// such a volume renders exactly as a still one.
    pub fn new(field: VelocityField, transform: DAffine3) -> Option<Self> {
        let world_per_frame = transform.matrix3.as_mat3() * Mat3::from_diagonal(field.per_frame);
        let max_components = field.grids.max_components();
        let speed = abs_mul(world_per_frame, max_components).length();
        if !(speed > 0.0 && reach(field.shutter) > 0.0) {
            return None;
        }
        let wfi = transform * field.grids.world_from_index();
        let ifw = wfi.inverse();
        Some(Self {
            grids: field.grids,
            index_from_world: Affine3A::from_mat3_translation(
                ifw.matrix3.as_mat3(),
                ifw.translation.as_vec3(),
            ),
            index_per_frame: ifw.matrix3.as_mat3() * world_per_frame,
            world_per_frame,
            max_components,
            shutter: field.shutter,
        })
    }

    /// The velocity at world point `p`: world units per frame.
    pub fn velocity(&self, p: Vec3) -> Vec3 {
        let q = self.index_from_world.transform_point3(p);
        self.world_per_frame * self.grids.sample_index(q)
    }

    /// Where the stored volume holds what is at `p` at `time` (frames from
    /// the frame): `p − τ·u(p − τ·u(p))`, as the module docs derive.
    #[inline]
    pub fn advect(&self, p: Vec3, time: f32) -> Vec3 {
        p - self.displacement(p, time).1
    }

    /// The velocity grids' index space from world space.
    pub fn index_from_world(&self) -> Affine3A {
        self.index_from_world
    }

    /// [`Self::advect`] for the world point whose velocity-grid index point
    /// is `q`: the advected point in that index space, and the world
    /// displacement `τ·u` to subtract from the world point. The work is
    /// done in index space (one transform for the caller, none here), and
    /// where the velocity is zero (outside the grid's voxels) the second
    /// lookup is skipped: it would read the same point.
    #[inline(always)]
    pub fn displacement(&self, p: Vec3, time: f32) -> (Vec3, Vec3) {
        let q = self.index_from_world.transform_point3(p);
        let v = self.grids.sample_index(q);
        if v == Vec3::ZERO {
            return (q, Vec3::ZERO);
        }
        let v = self
            .grids
            .sample_index(q - time * (self.index_per_frame * v));
        (
            q - time * (self.index_per_frame * v),
            time * (self.world_per_frame * v),
        )
    }

    /// Frames the shutter reaches from the frame, at most, either way.
    pub fn max_time(&self) -> f32 {
        reach(self.shutter)
    }

    /// When the shutter opens and closes, in frames from the frame.
    pub fn shutter(&self) -> (f32, f32) {
        self.shutter
    }

    /// How far (world units) a lookup may be displaced over the shutter.
    pub fn max_displacement(&self) -> f32 {
        abs_mul(self.world_per_frame, self.max_components).length() * self.max_time()
    }

    /// How far a lookup may be displaced over the shutter along each axis
    /// of the index space `index_from_world` maps world vectors into: the
    /// displacement is τ·A·W·v, so its component a is at most
    /// max|τ| · Σ_j |(A·W)_aj| · max|v_j|.
    pub fn index_displacement(&self, index_from_world: Mat3) -> Vec3 {
        abs_mul(index_from_world * self.world_per_frame, self.max_components) * self.max_time()
    }

    /// The displacement per frame, `[min, max]` along each axis of the
    /// index space `index_from_world` maps world vectors into, of lookups
    /// whose velocity reads return components within `[lo, hi]`: interval
    /// arithmetic on A·W·v.
    pub fn index_velocity_range(&self, index_from_world: Mat3, [lo, hi]: [Vec3; 2]) -> [Vec3; 2] {
        let m = (index_from_world * self.world_per_frame).transpose();
        let row = |r: Vec3| {
            let (a, b) = (r * lo, r * hi);
            (a.min(b).element_sum(), a.max(b).element_sum())
        };
        let (x, y, z) = (row(m.x_axis), row(m.y_axis), row(m.z_axis));
        [Vec3::new(x.0, y.0, z.0), Vec3::new(x.1, y.1, z.1)]
    }

    /// The velocity grids.
    pub fn grids(&self) -> &VelocityGrids {
        &self.grids
    }

    /// Bytes the velocity grids take.
    pub fn memory_bytes(&self) -> usize {
        self.grids.memory_bytes()
    }
}
