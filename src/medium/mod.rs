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
pub mod motion;
pub mod principled;

use crate::grid::{Grid, GridValue};
use crate::phase::PhaseFunction;
use crate::Rgb;
use glam::{Affine3A, DAffine3, DVec3, IVec3, Mat3, Vec3};
pub use majorant::{EmissionBounds, MajorantGrid, MotionReach, Segment};
pub use motion::{Motion, VelocityField, VelocityGrids};
pub use principled::{BlackbodyFilter, Material, Principled, Temperature};

/// Voxels per majorant cell edge. One brick: tight bounds around the
/// features of smoke, at 1/512 of the voxel count in cells.
pub const MAJORANT_CELL: i32 = 8;

/// Optical depth at the densest voxel across a cell of [`MAJORANT_CELL`]
/// voxels above which a volume's majorant cells are halved (see
/// [`Volume::new`]).
pub const THICK_CELL_DEPTH: f32 = 2.0;

/// Tentative collisions per voxel length that trackers sample where a
/// volume emits, when the extinction's majorant is lower: emission is
/// collected at tentative collisions (∫T·Le dt ≈ Σ T·Le/σ̄), so it needs a
/// positive rate wherever it is nonzero, also where σt = 0 (flame without
/// smoke). One per voxel resolves the emission's own detail.
pub const EMISSION_RATE_PER_VOXEL: f32 = 1.0;

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
    /// Blackbody radiance per voxel of the temperature grid (same layout
    /// and index space), for [`BlackbodyFilter::Emission`].
    blackbody: Option<Grid<Vec3>>,
    /// Whether each secondary grid (temperature, flame, colour) shares the
    /// density grid's index space (Blender's caches do), so one index point
    /// serves all lookups.
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
    /// Shortest edge of a voxel, world units.
    voxel_length: f32,
    world_bounds: (Vec3, Vec3),
    /// The velocity that blurs it over the shutter, when it moves.
    motion: Option<Motion>,
    /// How far its lookups may move over the shutter, per axis of its
    /// index space (voxels): what the majorant grid is dilated by.
    motion_pad: Vec3,
    /// Whether the velocity grids share the density's index space (as in
    /// Blender's caches), so that the advected index point serves it.
    motion_shares_index: bool,
}

/// The optional grids of a volume beside its density, and how its blackbody
/// emission is filtered.
#[derive(Debug, Clone, Default)]
pub struct ExtraGrids {
    pub temperature: Option<Grid<f32>>,
    pub flame: Option<Grid<f32>>,
    pub color: Option<Grid<Vec3>>,
    pub blackbody_filter: BlackbodyFilter,
    /// The velocity that blurs the volume over the shutter (motion blur).
    pub velocity: Option<VelocityField>,
}

fn affine_f32(m: DAffine3) -> Affine3A {
    Affine3A::from_mat3_translation(m.matrix3.as_mat3(), m.translation.as_vec3())
}

/// The box that bounds the image of the box `[lo, hi]` under `m`.
pub(crate) fn transform_box(m: DAffine3, lo: DVec3, hi: DVec3) -> (DVec3, DVec3) {
    let mut a = DVec3::splat(f64::INFINITY);
    let mut b = DVec3::splat(f64::NEG_INFINITY);
    for k in 0..8 {
        let c = DVec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        let w = m.transform_point3(c);
        a = a.min(w);
        b = b.max(w);
    }
    (a, b)
}

/// The integer box (inclusive, padded by one voxel) that covers the image of
/// the box `[lo, hi]` under `m`.
fn map_box(m: DAffine3, lo: DVec3, hi: DVec3) -> (IVec3, IVec3) {
    let (a, b) = transform_box(m, lo, hi);
    let clamp = |v: DVec3| v.clamp(DVec3::splat(-1e9), DVec3::splat(1e9));
    (
        clamp(a.floor()).as_ivec3() - 1,
        clamp(b.ceil()).as_ivec3() + 1,
    )
}

/// For a moving volume, the displacement per frame (density index units,
/// `[min, max]` per axis) of lookups whose velocity reads lie in a
/// density-index cell: what the velocity there can return
/// ([`MotionReach::local`]).
fn local_displacement(
    m: &Motion,
    index_from_world: Affine3A,
) -> impl Fn(IVec3, i32) -> [Vec3; 2] + Sync + '_ {
    let to_index = Mat3::from(index_from_world.matrix3);
    // The velocity grids' index space from the density's, when they differ.
    let from_density = (m.index_from_world() != index_from_world).then(|| {
        let a = m.index_from_world() * index_from_world.inverse();
        DAffine3::from_mat3_translation(
            Mat3::from(a.matrix3).as_dmat3(),
            Vec3::from(a.translation).as_dvec3(),
        )
    });
    move |c0: IVec3, cell: i32| {
        let v = match from_density {
            None => m.grids().cell_range(c0, cell),
            Some(f) => {
                let (lo, hi) = map_box(f, c0.as_dvec3(), (c0 + cell).as_dvec3());
                m.grids().box_range(lo, hi)
            }
        };
        m.index_velocity_range(to_index, v)
    }
}

/// The [`MotionReach`] of a volume (`pad`: its bound anywhere over the
/// whole shutter).
fn motion_reach<'a>(
    motion: Option<&Motion>,
    pad: Vec3,
    local: &'a Option<impl Fn(IVec3, i32) -> [Vec3; 2] + Sync + 'a>,
) -> MotionReach<'a> {
    MotionReach {
        max: pad,
        shutter: motion.map_or((0.0, 0.0), |m| m.shutter()),
        local: local
            .as_ref()
            .map(|f| f as &(dyn Fn(IVec3, i32) -> [Vec3; 2] + Sync)),
    }
}

/// A secondary grid seen from the density's index space: the range of its
/// lookups over a density-index cell.
struct Secondary<'a, T: GridValue> {
    grid: &'a Grid<T>,
    /// Its index space from the density's (None when shared).
    from_density: Option<DAffine3>,
}

impl<T: GridValue> Secondary<'_, T> {
    fn range(&self, c0: IVec3, cell: i32) -> [T; 2] {
        match self.from_density {
            None => self.grid.cell_lookup_range(c0, cell),
            Some(m) => {
                let (lo, hi) = map_box(m, c0.as_dvec3(), (c0 + cell).as_dvec3());
                self.grid
                    .range_in_box(lo, hi)
                    .unwrap_or([self.grid.background(); 2])
            }
        }
    }
}

impl Volume {
    /// Places `density` (and its companions) in the scene with `transform`
    /// applied after the file's own transform. `None` when nothing is
    /// stored: an empty density grid and no emitting grid.
    pub fn new(
        label: &str,
        density: Grid<f32>,
        extra: ExtraGrids,
        material: Material,
        transform: DAffine3,
    ) -> Option<Self> {
        let dwfi = density.world_from_index();
        let wfi = transform * dwfi;
        let world_from_index = affine_f32(wfi);
        let index_from_world = affine_f32(wfi.inverse());
        let motion = extra.velocity.and_then(|v| Motion::new(v, transform));
        let motion_pad = motion.as_ref().map_or(Vec3::ZERO, |m| {
            m.index_displacement(glam::Mat3::from(index_from_world.matrix3))
        });
        let secondary = |g: Option<DAffine3>| match g {
            Some(m) => (m == dwfi, affine_f32((transform * m).inverse())),
            None => (true, index_from_world),
        };
        let (s0, x0) = secondary(extra.temperature.as_ref().map(|g| g.world_from_index()));
        let (s1, x1) = secondary(extra.flame.as_ref().map(|g| g.world_from_index()));
        let (s2, x2) = secondary(extra.color.as_ref().map(|g| g.world_from_index()));
        let blackbody = match (&extra.temperature, extra.blackbody_filter) {
            (Some(t), BlackbodyFilter::Emission) if material.has_blackbody() => t
                .map_values("blackbody", |x| material.blackbody_radiance(x))
                .ok(),
            _ => None,
        };
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
        // Moving and emissive volumes: cells of 4 voxels. A moving
        // volume's bounds are dilated by the motion of each time slab on
        // 1-voxel cells with exact voxel ranges (`Grid::voxel_range`), so a
        // cell bounds only what can move into it; cells of a whole brick
        // would add up to 7 voxels of margin to every side. An emissive
        // volume's trackers meet one tentative collision per voxel wherever
        // a cell may emit (`EMISSION_RATE_PER_VOXEL`), over less of the ray
        // with smaller cells. Measured on the Blender smoke frame (64 spp,
        // path tracer): blurred 4.2 s with cells of 8, 3.0 s with cells of
        // 4; still 2.35 s and 1.54 s. Clouds that do not glow render no
        // faster with cells of 4 (docs/performance.md, "Motion blur").
        //
        // Optically thick volumes: cells of 4 too. Where a cell of 8 voxels
        // holds many mean free paths at its densest, its bound is far above
        // most of its voxels, and every collision the trackers meet there
        // costs a lookup. Measured (2 threads, 96 or 64 spp, cells of 8 →
        // 4; docs/performance.md, "Majorant cells for thick clouds"): the
        // dense cloud (33 mean free paths per 8 voxels) path 3.1 → 2.5 s,
        // photon 3.4 → 2.7 s; the pyro (8.8) path 1.55 → 1.38 s; the
        // reference cloud (3.7) path 1.11 → 1.03 s; but the wispy cloud
        // (0.83) path 0.60 → 0.66 s, its DDA's extra steps costing more
        // than the few collisions saved.
        let thick = {
            let voxel = wfi.matrix3.determinant().abs().cbrt() as f32;
            let densest = density.value_range().map_or(0.0, |[_, hi]| hi.max(0.0));
            sigma_t_per_density * densest * voxel * MAJORANT_CELL as f32 > THICK_CELL_DEPTH
        };
        let cell = if motion.is_some() || material.is_emissive() || thick {
            MAJORANT_CELL / 2
        } else {
            MAJORANT_CELL
        };
        let local = motion
            .as_ref()
            .map(|m| local_displacement(m, index_from_world));
        let majorant = if material.is_emissive() {
            fn view(g: &Option<Grid<f32>>, dwfi: DAffine3) -> Option<Secondary<'_, f32>> {
                g.as_ref().map(|g| Secondary {
                    grid: g,
                    from_density: (g.world_from_index() != dwfi)
                        .then(|| g.world_from_index().inverse() * dwfi),
                })
            }
            let temperature = view(&extra.temperature, dwfi);
            let flame = view(&extra.flame, dwfi);
            let bb = blackbody.as_ref().map(|g| Secondary {
                grid: g,
                from_density: temperature.as_ref().and_then(|t| t.from_density),
            });
            // Blackbody emission from a temperature grid reaches as far as
            // that grid's voxels, whatever the density there.
            let voxels = match (&extra.temperature, material.has_blackbody()) {
                (Some(t), true) => t.stored_bounds().map(|(lo, hi)| {
                    if t.world_from_index() == dwfi {
                        (lo, hi)
                    } else {
                        map_box(
                            dwfi.inverse() * t.world_from_index(),
                            lo.as_dvec3(),
                            hi.as_dvec3(),
                        )
                    }
                }),
                _ => None,
            };
            let plain = material.plain_emission_max();
            let density_ref = &density;
            let material_ref = &material;
            let bound = move |c0: IVec3, cell: i32| -> f32 {
                let dens_hi = density_ref.cell_lookup_range(c0, cell)[1].max(0.0);
                let mut b = 0.0;
                match material_ref {
                    Material::Raw { .. } => b += plain * dens_hi,
                    Material::Principled(_) => {
                        if plain > 0.0 && dens_hi > 0.0 {
                            b += plain
                                * flame
                                    .as_ref()
                                    .map_or(1.0, |f| f.range(c0, cell)[1].max(0.0));
                        }
                        if material_ref.has_blackbody() {
                            b += match (&bb, &temperature) {
                                (Some(g), _) => g.range(c0, cell)[1].max_element().max(0.0),
                                (None, Some(t)) => {
                                    let [lo, hi] = t.range(c0, cell);
                                    material_ref.blackbody_bound(lo, hi)
                                }
                                (None, None) if dens_hi > 0.0 => {
                                    material_ref.blackbody_radiance(1.0).max_element().max(0.0)
                                }
                                (None, None) => 0.0,
                            };
                        }
                    }
                }
                b
            };
            MajorantGrid::build_emissive(
                &density,
                cell,
                Some(EmissionBounds {
                    voxels,
                    bound: &bound,
                }),
                motion_reach(motion.as_ref(), motion_pad, &local),
            )?
        } else {
            MajorantGrid::build_emissive(
                &density,
                cell,
                None,
                motion_reach(motion.as_ref(), motion_pad, &local),
            )?
        };
        drop(local);
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
        let m = wfi.matrix3;
        let voxel_length = m
            .x_axis
            .length()
            .min(m.y_axis.length())
            .min(m.z_axis.length()) as f32;
        let phase = material.phase();
        Some(Self {
            label: label.to_string(),
            density,
            temperature: extra.temperature,
            flame: extra.flame,
            color: extra.color,
            blackbody,
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
            voxel_length,
            world_bounds: (wlo, whi),
            motion_shares_index: motion
                .as_ref()
                .is_some_and(|m| m.index_from_world() == index_from_world),
            motion,
            motion_pad,
        })
    }

    /// The volume's velocity, when it moves over the shutter.
    pub fn motion(&self) -> Option<&Motion> {
        self.motion.as_ref()
    }

    /// The majorant grid's time slab for lookups at `time`
    /// ([`MajorantGrid::slab`]; 0, the whole shutter, for a still volume).
    #[inline]
    fn slab(&self, time: f32) -> usize {
        match &self.motion {
            Some(m) => self.majorant.slab(time, m.shutter()),
            None => 0,
        }
    }

    pub fn world_bounds(&self) -> (Vec3, Vec3) {
        self.world_bounds
    }

    /// Rebuilds the majorant grid with cells of `cell` voxels (a cell larger
    /// than the grid gives one global majorant), without its minorant if
    /// `minorant` is false. For benchmarks and tests of non-emissive
    /// volumes (the emission bounds are dropped).
    pub fn set_majorant_cell(&mut self, cell: i32, minorant: bool) {
        let local = self
            .motion
            .as_ref()
            .map(|m| local_displacement(m, self.index_from_world));
        let reach = motion_reach(self.motion.as_ref(), self.motion_pad, &local);
        if let Some(mut m) = MajorantGrid::build_emissive(&self.density, cell.max(1), None, reach) {
            if !minorant {
                m.clear_minorant();
            }
            self.majorant = m;
        }
    }
    /// Bytes the volume's grids take.
    pub fn memory_bytes(&self) -> usize {
        self.density.memory_bytes()
            + self.temperature.as_ref().map_or(0, |g| g.memory_bytes())
            + self.flame.as_ref().map_or(0, |g| g.memory_bytes())
            + self.color.as_ref().map_or(0, |g| g.memory_bytes())
            + self.blackbody.as_ref().map_or(0, |g| g.memory_bytes())
            + self.motion.as_ref().map_or(0, |m| m.memory_bytes())
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
    pub fn material(&self) -> &Material {
        &self.material
    }
    pub fn world_from_index(&self) -> Affine3A {
        self.world_from_index
    }
    pub fn index_from_world(&self) -> Affine3A {
        self.index_from_world
    }
    /// Upper bound of sigma_t per unit density (max over channels).
    pub fn sigma_t_per_density(&self) -> f32 {
        self.sigma_t_per_density
    }
    /// Shortest voxel edge in world units.
    pub fn voxel_length(&self) -> f32 {
        self.voxel_length
    }

    #[inline]
    fn secondary<T: GridValue>(
        &self,
        g: &Option<Grid<T>>,
        k: usize,
        pi: Vec3,
        p: Vec3,
    ) -> Option<T> {
        g.as_ref().map(|g| {
            let q = if self.shared_index[k] {
                pi
            } else {
                self.secondary_from_world[k].transform_point3(p)
            };
            g.sample_index(q)
        })
    }

    /// Optics at world point `p` at `time` (frames from the frame; 0 for a
    /// still frame): a moving volume is looked up where its contents were
    /// at the frame ([`Motion::advect`]).
    #[inline]
    pub fn eval(&self, p: Vec3, time: f32) -> MediumPoint {
        let (p, pi) = match &self.motion {
            Some(m) if time != 0.0 => {
                let (q, d) = m.displacement(p, time);
                let p = p - d;
                if self.motion_shares_index {
                    (p, q)
                } else {
                    (p, self.index_from_world.transform_point3(p))
                }
            }
            _ => (p, self.index_from_world.transform_point3(p)),
        };
        let density = self.density.sample_index(pi).max(0.0);
        let temperature = match self.secondary(&self.blackbody, 0, pi, p) {
            Some(l) => Temperature::Radiance(l),
            None => match self.secondary(&self.temperature, 0, pi, p) {
                Some(t) => Temperature::Attribute(t),
                None => Temperature::Uniform,
            },
        };
        let flame = self.secondary(&self.flame, 1, pi, p);
        let color = self.secondary(&self.color, 2, pi, p);
        self.material
            .coefficients(density, temperature, flame, color)
    }

    /// Whether the material emits light anywhere.
    pub fn is_emissive(&self) -> bool {
        self.material.is_emissive()
    }

    /// Whether light can scatter anywhere in it: some density, and a
    /// material that scatters per unit of it (or a colour grid, which may
    /// give it a scattering colour). An absorbing or only glowing volume
    /// does not: nothing a photon map could store.
    pub fn scatters(&self) -> bool {
        let dense = self.density.value_range().is_some_and(|r| r[1] > 0.0);
        let sigma_s = self.material.coefficients_per_density().0.max_element() > 0.0;
        dense && (sigma_s || self.color.is_some())
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
    /// Tentative collisions per unit length where some volume emits
    /// ([`EMISSION_RATE_PER_VOXEL`] per voxel of the finest emissive
    /// volume); 0 when nothing emits.
    emission_rate: f32,
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
        let emission_rate = volumes
            .iter()
            .filter(|v| v.majorant.is_emissive())
            .map(|v| EMISSION_RATE_PER_VOXEL / v.voxel_length)
            .fold(0.0, f32::max);
        Self {
            volumes,
            control,
            emission_rate,
        }
    }

    /// The albedo every real collision has, when the volumes share one and
    /// none emits; see [`crate::tracking::collide`].
    #[inline]
    pub fn control_albedo(&self) -> Option<Rgb> {
        self.control.map(|(a, _)| a)
    }
    /// The phase function of the control medium (see [`Self::control_albedo`]).
    #[inline]
    pub fn control_phase(&self) -> Option<PhaseFunction> {
        self.control.map(|(_, p)| p)
    }
    /// Tentative collisions per unit length that trackers need where
    /// something emits (0 when nothing does).
    #[inline]
    pub fn emission_rate(&self) -> f32 {
        self.emission_rate
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
    /// Whether any volume emits.
    pub fn is_emissive(&self) -> bool {
        self.emission_rate > 0.0
    }
    /// Whether light scatters in any volume ([`Volume::scatters`]).
    pub fn scatters(&self) -> bool {
        self.volumes.iter().any(Volume::scatters)
    }
    /// Whether any volume moves over the shutter.
    pub fn is_moving(&self) -> bool {
        self.volumes.iter().any(|v| v.motion.is_some())
    }

    /// The shortest voxel edge of all volumes, world units (`None` without
    /// volumes): what the marchers step by by default.
    pub fn finest_voxel(&self) -> Option<f32> {
        self.volumes
            .iter()
            .map(|v| v.voxel_length())
            .reduce(f32::min)
    }

    /// The weights of a march step of length `dt` through extinction
    /// `sigma_t` (constant over the step): its transmittance e^(−σt·dt),
    /// and ∫₀^dt e^(−σt·s) ds = (1 − e^(−σt·dt))/σt (dt where σt is
    /// about 0), the factor that turns a source per unit length into what
    /// the step adds.
    #[inline]
    pub fn step_weights(sigma_t: Rgb, dt: f32) -> (Rgb, Rgb) {
        let att = (-sigma_t * dt).map(f32::exp);
        let w = Rgb::select(
            sigma_t.cmpgt(Rgb::splat(1e-6)),
            (Rgb::ONE - att) / sigma_t.max(Rgb::splat(1e-6)),
            Rgb::splat(dt),
        );
        (att, w)
    }

    /// World-space bounding box of all volumes.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        self.volumes
            .iter()
            .map(|v| v.world_bounds())
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
    }

    /// Summed optics at world point `p` at `time` (frames from the frame;
    /// one lookup, counted).
    #[inline]
    pub fn eval(&self, p: Vec3, time: f32) -> MediumPoint {
        crate::stats::count_lookup();
        match self.volumes.as_slice() {
            [v] => v.eval(p, time),
            vs => vs.iter().fold(MediumPoint::default(), |acc, v| {
                let m = v.eval(p, time);
                MediumPoint {
                    sigma_a: acc.sigma_a + m.sigma_a,
                    sigma_s: acc.sigma_s + m.sigma_s,
                    emission: acc.emission + m.emission,
                }
            }),
        }
    }

    /// Summed optics at `p` and the phase function of a scattering event
    /// there: with overlapping volumes, one of theirs chosen with
    /// probability proportional to its scattering (a one-sample estimate of
    /// the σs-weighted mixture), using `u`. One lookup (counted), no
    /// allocation: the choice is made while the volumes are summed
    /// (weighted reservoir sampling with one uniform number, rescaled at
    /// each step).
    /// Returns the optics and the index of the chosen volume (its phase
    /// function is [`Self::phase_of`]; 0 when none scatters).
    #[inline]
    pub fn eval_scatter(&self, p: Vec3, time: f32, u: f32) -> (MediumPoint, usize) {
        crate::stats::count_lookup();
        match self.volumes.as_slice() {
            [v] => (v.eval(p, time), 0),
            vs => {
                let mut acc = MediumPoint::default();
                let mut chosen = 0;
                let mut total = 0.0f32;
                let mut u = u;
                for (i, v) in vs.iter().enumerate() {
                    let m = v.eval(p, time);
                    acc.sigma_a += m.sigma_a;
                    acc.sigma_s += m.sigma_s;
                    acc.emission += m.emission;
                    let w = m.sigma_s.element_sum();
                    if w <= 0.0 {
                        continue;
                    }
                    total += w;
                    let q = w / total;
                    if u < q {
                        chosen = i;
                        u /= q;
                    } else {
                        u = (u - q) / (1.0 - q);
                    }
                    u = u.clamp(0.0, 1.0 - f32::EPSILON);
                }
                (acc, chosen)
            }
        }
    }

    /// The phase function of volume `i` (isotropic for an index past the
    /// end, which no caller passes).
    #[inline]
    pub fn phase_of(&self, i: usize) -> PhaseFunction {
        self.volumes
            .get(i)
            .map_or(PhaseFunction::Isotropic, |v| v.phase)
    }

    /// The phase function of a scattering event at `p` (see
    /// [`Self::eval_scatter`]): no lookup with a control medium or a single
    /// volume, one (counted) otherwise.
    pub fn phase_at(&self, p: Vec3, time: f32, u: f32) -> PhaseFunction {
        if let Some((_, phase)) = self.control {
            return phase;
        }
        match self.volumes.as_slice() {
            [v] => v.phase(),
            _ => self.phase_of(self.eval_scatter(p, time, u).1),
        }
    }

    /// Calls `f` for each stretch of the ray `o + t d` (`d` a unit world
    /// direction) within `[t0, t1)` that has a constant majorant of
    /// sigma_t (per world unit, max over channels), minorant (min over
    /// channels) and emission bound, in order of `t`.
    /// Stretches where no volume is present are skipped; where volumes
    /// overlap, their bounds add. `f` returns false to stop.
    #[inline]
    pub fn for_each_segment(
        &self,
        o: Vec3,
        d: Vec3,
        t0: f32,
        t1: f32,
        f: impl FnMut(Segment) -> bool,
    ) {
        self.for_each_segment_at(o, d, t0, t1, f32::INFINITY, f)
    }

    /// [`Self::for_each_segment`] for a ray at `time` (frames from the
    /// frame): moving volumes give the bounds of that time's slab
    /// ([`MajorantGrid::slab`]), tighter than the whole shutter's. A time
    /// that is not finite means the whole shutter.
    #[inline]
    pub fn for_each_segment_at(
        &self,
        o: Vec3,
        d: Vec3,
        t0: f32,
        t1: f32,
        time: f32,
        mut f: impl FnMut(Segment) -> bool,
    ) {
        match self.volumes.as_slice() {
            [] => {}
            [v] => {
                let io = v.index_from_world.transform_point3(o);
                let id = v.index_from_world.transform_vector3(d);
                for s in v.majorant.walk_slab(io, id, t0, t1, v.slab(time)) {
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
                // them the summed bounds are constant.
                let mut walks: Vec<_> = vs
                    .iter()
                    .map(|v| {
                        let io = v.index_from_world.transform_point3(o);
                        let id = v.index_from_world.transform_vector3(d);
                        let mut w = v.majorant.walk_slab(io, id, t0, t1, v.slab(time));
                        let cur = w.next();
                        (w, cur, (v.sigma_t_per_density, v.sigma_t_min_per_density))
                    })
                    .collect();
                let mut t = t0;
                loop {
                    let mut next_t = f32::INFINITY;
                    let mut maj = 0.0;
                    let mut min = 0.0;
                    let mut emission = 0.0;
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
                                emission += s.emission;
                            }
                        }
                    }
                    if !any || !next_t.is_finite() {
                        return;
                    }
                    if next_t > t
                        && (maj > 0.0 || emission > 0.0)
                        && !f(Segment {
                            t0: t,
                            t1: next_t,
                            max_density: maj,
                            min_density: min,
                            emission,
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
