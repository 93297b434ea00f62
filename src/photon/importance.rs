//! Where the camera can see: a coarse grid over the volumes holding the
//! largest transmittance from the camera that any pixel's ray reaches in
//! each cell, dilated by one cell. Photon tracing stores a collision with a
//! probability proportional to it (and divides the stored power by that
//! probability), so a pass's map is spent where camera rays gather:
//! deep inside a dense cloud, where no camera ray gets, photons are rarely
//! kept. Unbiased, since every place keeps a probability above zero
//! ([`FLOOR`]); only the variance moves.

use crate::shape::RayKind;
use crate::world::World;
use glam::{IVec3, Vec2, Vec3};
use rayon::prelude::*;

/// The least importance any cell has: keeps the storage probability
/// positive everywhere (so the estimate stays unbiased) and the weight of a
/// photon kept where the camera hardly sees bounded.
pub const FLOOR: f32 = 1e-3;

/// Camera rays stop once their transmittance is below this.
const T_MIN: f32 = 1e-4;

/// Largest cells per axis.
const MAX_RES: i32 = 256;

/// The camera's view of the volumes, cell by cell.
#[derive(Debug, Clone)]
pub struct Importance {
    lo: Vec3,
    cell: f32,
    res: IVec3,
    value: Vec<f32>,
}

impl Importance {
    /// Marches the ray through every pixel's centre with steps of at most
    /// `step` (and half an optical depth of the majorant), recording the
    /// transmittance at each step's cell. `None` without volumes.
    pub fn from_camera(world: &World, step: f32) -> Option<Self> {
        let (lo, hi) = world.media.bounds()?;
        let finest = world.media.finest_voxel()?;
        let extent = (hi - lo).max(Vec3::splat(1e-6));
        // Cells no smaller than a voxel, nor than two pixels' footprint at
        // the volumes' near side (pixel-centre rays must reach every cell a
        // camera ray can cross), nor than the extent over MAX_RES.
        let cam = &world.camera;
        let near = ((lo + hi) * 0.5 - cam.position()).length() - (hi - lo).length() * 0.5;
        let footprint = 2.0 * near.max(0.0) * cam.pixel_angle();
        let cell = finest
            .max(footprint)
            .max(extent.max_element() / MAX_RES as f32);
        let res = (extent / cell).ceil().as_ivec3().max(IVec3::ONE);
        let n = (res.x * res.y * res.z) as usize;
        let index = |p: Vec3| {
            let c = ((p - lo) / cell).floor().as_ivec3();
            if c.cmplt(IVec3::ZERO).any() || c.cmpge(res).any() {
                None
            } else {
                Some(((c.z * res.y + c.y) * res.x + c.x) as usize)
            }
        };
        let media = &world.media;
        // A moving volume is seen where it is at each time of the shutter:
        // the camera's view at four times spread over it.
        let times: Vec<f32> = match cam.shutter() {
            Some(s) => (0..4).map(|i| s.time((i as f32 + 0.5) / 4.0)).collect(),
            None => vec![0.0],
        };
        let grid = (0..cam.height())
            .into_par_iter()
            .fold(
                || vec![0.0f32; n],
                |mut g, y| {
                    for (x, &time) in
                        (0..cam.width()).flat_map(|x| times.iter().map(move |t| (x, t)))
                    {
                        let d = cam.direction(Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
                        let o = cam.position();
                        let mut tr = 1.0f32;
                        // Up to the surface the camera sees there.
                        let t_max = world
                            .shapes
                            .intersect(o, d, f32::INFINITY, RayKind::CAMERA)
                            .map_or(f32::INFINITY, |h| h.t);
                        media.for_each_segment(o, d, 0.0, t_max, |seg| {
                            if seg.max_density <= 0.0 && seg.emission <= 0.0 {
                                return true;
                            }
                            let mut target = step;
                            if seg.max_density > 0.0 {
                                target = target.min(0.5 / seg.max_density).max(finest / 16.0);
                            }
                            let k = ((seg.t1 - seg.t0) / target).ceil().clamp(1.0, 1e6) as u32;
                            let dt = (seg.t1 - seg.t0) / k as f32;
                            for i in 0..k {
                                let p = o + d * (seg.t0 + (i as f32 + 0.5) * dt);
                                if let Some(j) = index(p) {
                                    g[j] = g[j].max(tr);
                                }
                                let st = media.eval(p, time).sigma_t();
                                tr *= (-(st.x + st.y + st.z) / 3.0 * dt).exp();
                                if tr < T_MIN {
                                    return false;
                                }
                            }
                            true
                        });
                    }
                    g
                },
            )
            .reduce(
                || vec![0.0f32; n],
                |mut a, b| {
                    for (x, y) in a.iter_mut().zip(&b) {
                        *x = x.max(*y);
                    }
                    a
                },
            );
        // Dilate by one cell: a photon's kernel reaches rays in the next
        // cell.
        let mut value = grid.clone();
        for z in 0..res.z {
            for y in 0..res.y {
                for x in 0..res.x {
                    let mut m = 0.0f32;
                    for dz in -1..=1 {
                        for dy in -1..=1 {
                            for dx in -1..=1 {
                                let q = IVec3::new(x + dx, y + dy, z + dz);
                                if q.cmpge(IVec3::ZERO).all() && q.cmplt(res).all() {
                                    m = m.max(grid[((q.z * res.y + q.y) * res.x + q.x) as usize]);
                                }
                            }
                        }
                    }
                    value[((z * res.y + y) * res.x + x) as usize] = m;
                }
            }
        }
        Some(Self {
            lo,
            cell,
            res,
            value,
        })
    }

    /// The importance at `p`, at least [`FLOOR`].
    #[inline]
    pub fn at(&self, p: Vec3) -> f32 {
        let c = ((p - self.lo) / self.cell).floor().as_ivec3();
        if c.cmplt(IVec3::ZERO).any() || c.cmpge(self.res).any() {
            return FLOOR;
        }
        self.value[((c.z * self.res.y + c.y) * self.res.x + c.x) as usize].max(FLOOR)
    }
}
