//! Participating media: the optics of the volumes in a scene.
//!
//! Data (the grids, `crate::grid`) stays apart from optics (here): a
//! [`Volume`] pairs a density grid and its optional temperature, flame and
//! colour grids with a material ([`Material`]: Blender's Principled Volume or
//! raw coefficients) and a phase function, and owns the [`MajorantGrid`] that
//! bounds its extinction. [`Media`] is every volume of a scene: overlapping
//! volumes add their coefficients (and mix their phase functions in
//! proportion to their scattering).
//!
//! Units: coefficients are per world unit; `emission` is radiance added per
//! unit length (σa·Le in pbrt's notation, Cycles' volume emission), in
//! W·m⁻³·sr⁻¹ for a scene in metres.

pub mod blackbody;
pub mod majorant;
pub mod principled;

use crate::grid::Grid;
use crate::phase::PhaseFunction;
use crate::Rgb;
use glam::{Affine3A, Vec3};
pub use majorant::{MajorantGrid, Segment};
pub use principled::{Material, Principled};

/// Voxels per majorant cell edge. One brick: tight bounds around the
/// features of smoke, at 1/512 of the voxel count in cells.
pub const MAJORANT_CELL: i32 = 8;

/// The optical properties at a point (summed over overlapping volumes).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MediumPoint {
    pub sigma_a: Rgb,
    pub sigma_s: Rgb,
    /// Radiance added per unit length (σa·Le).
    pub emission: Rgb,
}

impl MediumPoint {
    #[inline]
    pub fn sigma_t(&self) -> Rgb {
        self.sigma_a + self.sigma_s
    }
}

/// A volume placed in the scene.
#[derive(Debug, Clone)]
pub struct Volume {
    /// The file it came from, for messages.
    pub label: String,
    density: Grid<f32>,
    temperature: Option<Grid<f32>>,
    flame: Option<Grid<f32>>,
    color: Option<Grid<Vec3>>,
    /// Whether each secondary grid shares the density grid's index space
    /// (Blender's caches do), so one index point serves all lookups.
    shared_index: [bool; 3],
    material: Material,
    phase: PhaseFunction,
    /// Scene transform times the file's transform.
    world_from_index: Affine3A,
    index_from_world: Affine3A,
    /// Secondary grids' index space from world space.
    secondary_from_world: [Affine3A; 3],
    majorant: MajorantGrid,
    /// sigma_t ≤ `sigma_t_per_density` · density, per world unit.
    sigma_t_per_density: f32,
    /// sigma_t ≥ `sigma_t_min_per_density` · density in every channel (0
    /// with a colour grid).
    sigma_t_min_per_density: f32,
    /// sigma_s / sigma_t wherever the density is > 0, when that is a
    /// constant and the volume does not emit (what decomposition tracking's
    /// control medium needs).
    uniform_albedo: Option<Rgb>,
    world_bounds: (Vec3, Vec3),
}

/// The optional grids of a volume beside its density.
#[derive(Debug, Clone, Default)]
pub struct ExtraGrids {
    pub temperature: Option<Grid<f32>>,
    pub flame: Option<Grid<f32>>,
    pub color: Option<Grid<Vec3>>,
}

fn affine_f32(m: glam::DAffine3) -> Affine3A {
    Affine3A::from_mat3_translation(m.matrix3.as_mat3(), m.translation.as_vec3())
}

impl Volume {
    /// Places `density` (and its companions) in the scene with `transform`
    /// applied after the file's own transform. `None` for an empty grid.
    pub fn new(
        label: &str,
        density: Grid<f32>,
        extra: ExtraGrids,
        material: Material,
        transform: glam::DAffine3,
    ) -> Option<Self> {
        let majorant = MajorantGrid::build(&density, MAJORANT_CELL)?;
        let wfi = transform * density.world_from_index();
        let world_from_index = affine_f32(wfi);
        let index_from_world = affine_f32(wfi.inverse());
        let secondary = |g: Option<glam::DAffine3>| match g {
            Some(m) => (
                m == density.world_from_index(),
                affine_f32((transform * m).inverse()),
            ),
            None => (true, index_from_world),
        };
        let (s0, x0) = secondary(extra.temperature.as_ref().map(|g| g.world_from_index()));
        let (s1, x1) = secondary(extra.flame.as_ref().map(|g| g.world_from_index()));
        let (s2, x2) = secondary(extra.color.as_ref().map(|g| g.world_from_index()));
        let color_max = extra
            .color
            .as_ref()
            .and_then(|g| g.value_range())
            .map(|[_, hi]| hi.max_element().max(0.0));
        let sigma_t_per_density = material.sigma_t_bound_per_density(color_max);
        let (sigma_t_min_per_density, uniform_albedo) = if extra.color.is_some() {
            (0.0, None)
        } else {
            let (s, t) = material.coefficients_per_density();
            let albedo = Rgb::select(t.cmpgt(Rgb::ZERO), s / t, Rgb::ZERO);
            (
                t.min_element().max(0.0),
                (!material.is_emissive()).then_some(albedo),
            )
        };
        // World bounds: the eight corners of the majorant box.
        let (lo, hi) = majorant.bounds();
        let mut wlo = Vec3::splat(f32::INFINITY);
        let mut whi = Vec3::splat(f32::NEG_INFINITY);
        for k in 0..8 {
            let c = Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            let w = world_from_index.transform_point3(c);
            wlo = wlo.min(w);
            whi = whi.max(w);
        }
        let phase = material.phase();
        Some(Self {
            label: label.to_string(),
            density,
            temperature: extra.temperature,
            flame: extra.flame,
            color: extra.color,
            shared_index: [s0, s1, s2],
            material,
            phase,
            world_from_index,
            index_from_world,
            secondary_from_world: [x0, x1, x2],
            majorant,
            sigma_t_per_density,
            sigma_t_min_per_density,
            uniform_albedo,
            world_bounds: (wlo, whi),
        })
    }

    pub fn world_bounds(&self) -> (Vec3, Vec3) {
        self.world_bounds
    }

    /// Rebuilds the majorant grid with cells of `cell` voxels (a cell larger
    /// than the grid gives one global majorant), without its minorant if
    /// `minorant` is false. For benchmarks.
    pub fn set_majorant_cell(&mut self, cell: i32, minorant: bool) {
        if let Some(mut m) = MajorantGrid::build(&self.density, cell.max(1)) {
            if !minorant {
                m.clear_minorant();
            }
            self.majorant = m;
        }
    }
    pub fn density(&self) -> &Grid<f32> {
        &self.density
    }
    pub fn majorant_grid(&self) -> &MajorantGrid {
        &self.majorant
    }
    pub fn phase(&self) -> PhaseFunction {
        self.phase
    }
    pub fn world_from_index(&self) -> Affine3A {
        self.world_from_index
    }
    /// Upper bound of sigma_t per unit density (max over channels).
    pub fn sigma_t_per_density(&self) -> f32 {
        self.sigma_t_per_density
    }

    #[inline]
    fn secondary(&self, g: &Option<Grid<f32>>, k: usize, pi: Vec3, p: Vec3) -> Option<f32> {
        g.as_ref().map(|g| {
            let q = if self.shared_index[k] {
                pi
            } else {
                self.secondary_from_world[k].transform_point3(p)
            };
            g.sample_index(q)
        })
    }

    /// Optics at world point `p`.
    #[inline]
    pub fn eval(&self, p: Vec3) -> MediumPoint {
        let pi = self.index_from_world.transform_point3(p);
        let density = self.density.sample_index(pi).max(0.0);
        let temperature = self.secondary(&self.temperature, 0, pi, p);
        let flame = self.secondary(&self.flame, 1, pi, p);
        let color = self.color.as_ref().map(|g| {
            let q = if self.shared_index[2] {
                pi
            } else {
                self.secondary_from_world[2].transform_point3(p)
            };
            g.sample_index(q)
        });
        self.material
            .coefficients(density, temperature, flame, color)
    }

    /// Whether the material emits light anywhere.
    pub fn is_emissive(&self) -> bool {
        self.material.is_emissive()
    }
}

/// Every volume of a scene.
#[derive(Debug, Clone, Default)]
pub struct Media {
    volumes: Vec<Volume>,
    /// The albedo and phase function shared by every volume, when they do
    /// (and none emits): then the minorant of the majorant grid is a
    /// homogeneous control medium whose collisions need no lookup.
    control: Option<(Rgb, PhaseFunction)>,
}

/// A ray in each volume's index space, with its clipped extent.
#[derive(Debug, Clone, Copy)]
struct IndexRay {
    o: Vec3,
    d: Vec3,
}

impl Media {
    pub fn new(volumes: Vec<Volume>) -> Self {
        let first = volumes
            .first()
            .and_then(|v| Some((v.uniform_albedo?, v.phase)));
        let control = first.filter(|&(a, ph)| {
            volumes
                .iter()
                .all(|v| v.uniform_albedo == Some(a) && v.phase == ph)
        });
        Self { volumes, control }
    }

    /// The albedo every real collision has, when the volumes share one and
    /// none emits; see [`crate::tracking::collide`].
    #[inline]
    pub fn control_albedo(&self) -> Option<Rgb> {
        self.control.map(|(a, _)| a)
    }
    pub fn volumes(&self) -> &[Volume] {
        &self.volumes
    }
    pub fn volumes_mut(&mut self) -> &mut [Volume] {
        &mut self.volumes
    }
    pub fn is_empty(&self) -> bool {
        self.volumes.is_empty()
    }

    /// World-space bounding box of all volumes.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        self.volumes
            .iter()
            .map(|v| v.world_bounds())
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
    }

    /// Summed optics at world point `p`.
    #[inline]
    pub fn eval(&self, p: Vec3) -> MediumPoint {
        match self.volumes.as_slice() {
            [v] => v.eval(p),
            vs => vs.iter().fold(MediumPoint::default(), |acc, v| {
                let m = v.eval(p);
                MediumPoint {
                    sigma_a: acc.sigma_a + m.sigma_a,
                    sigma_s: acc.sigma_s + m.sigma_s,
                    emission: acc.emission + m.emission,
                }
            }),
        }
    }

    /// The phase function at `p`: with overlapping volumes, one of theirs
    /// chosen with probability proportional to its scattering there (a
    /// one-sample estimate of the σs-weighted mixture), using `u`.
    pub fn phase_at(&self, p: Vec3, u: f32) -> PhaseFunction {
        if let Some((_, phase)) = self.control {
            return phase;
        }
        match self.volumes.as_slice() {
            [v] => v.phase(),
            vs => {
                let w: Vec<f32> = vs.iter().map(|v| v.eval(p).sigma_s.element_sum()).collect();
                let total: f32 = w.iter().sum();
                let mut x = u * total;
                for (v, wi) in vs.iter().zip(&w) {
                    if x < *wi {
                        return v.phase();
                    }
                    x -= wi;
                }
                vs.iter()
                    .zip(&w)
                    .rev()
                    .find(|(_, w)| **w > 0.0)
                    .map(|(v, _)| v.phase())
                    .unwrap_or(PhaseFunction::Isotropic)
            }
        }
    }

    /// Calls `f` for each stretch of the ray `o + t d` (`d` a unit world
    /// direction) within `[t0, t1)` that has a constant majorant of
    /// sigma_t (per world unit, max over channels) and minorant (min over
    /// channels), in order of `t`.
    /// Stretches where no volume is present are skipped; where volumes
    /// overlap, their bounds add. `f` returns false to stop.
    #[inline]
    pub fn for_each_segment(
        &self,
        o: Vec3,
        d: Vec3,
        t0: f32,
        t1: f32,
        mut f: impl FnMut(Segment) -> bool,
    ) {
        match self.volumes.as_slice() {
            [] => {}
            [v] => {
                let r = IndexRay {
                    o: v.index_from_world.transform_point3(o),
                    d: v.index_from_world.transform_vector3(d),
                };
                for s in v.majorant.walk(r.o, r.d, t0, t1) {
                    let seg = Segment {
                        max_density: s.max_density * v.sigma_t_per_density,
                        min_density: s.min_density * v.sigma_t_min_per_density,
                        ..s
                    };
                    if !f(seg) {
                        return;
                    }
                }
            }
            vs => {
                // Merge the walks: between consecutive boundaries of any of
                // them the summed majorant is constant.
                let mut walks: Vec<_> = vs
                    .iter()
                    .map(|v| {
                        let io = v.index_from_world.transform_point3(o);
                        let id = v.index_from_world.transform_vector3(d);
                        let mut w = v.majorant.walk(io, id, t0, t1);
                        let cur = w.next();
                        (w, cur, (v.sigma_t_per_density, v.sigma_t_min_per_density))
                    })
                    .collect();
                let mut t = t0;
                loop {
                    let mut next_t = f32::INFINITY;
                    let mut maj = 0.0;
                    let mut min = 0.0;
                    let mut any = false;
                    for (_, cur, (k_max, k_min)) in walks.iter() {
                        if let Some(s) = cur {
                            any = true;
                            if s.t0 > t {
                                next_t = next_t.min(s.t0);
                            } else {
                                next_t = next_t.min(s.t1);
                                maj += s.max_density * k_max;
                                min += s.min_density * k_min;
                            }
                        }
                    }
                    if !any || !next_t.is_finite() {
                        return;
                    }
                    if next_t > t
                        && maj > 0.0
                        && !f(Segment {
                            t0: t,
                            t1: next_t,
                            max_density: maj,
                            min_density: min,
                        })
                    {
                        return;
                    }
                    t = next_t;
                    for (w, cur, _) in walks.iter_mut() {
                        while let Some(s) = cur {
                            if s.t1 <= t {
                                *cur = w.next();
                            } else {
                                break;
                            }
                        }
                    }
                }
            }
        }
    }
}
