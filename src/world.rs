//! The world a render sees: a scene description (`crate::scene`, the
//! one that parses scene files) turned into loaded volumes, lights and a camera.

use crate::camera::{Camera, Plane, Shutter};
use crate::error::{Error, Result};
use crate::grid::Grid;
use crate::image::texture::{ColorSpace, Texture};
use crate::light::{EnvMap, Environment, Light};
use crate::medium::{ExtraGrids, Material, Media, VelocityField, VelocityGrids, Volume};
use crate::scene::{
    CameraDesc, CameraPose, EnvironmentDesc, Lens, LightDesc, MaterialDesc, MeshDesc,
    MotionBlurDesc, SceneDesc, VelocityUnit, VolumeBounds, VolumeDesc,
};
use crate::scene::{ColorInput, TextureColorSpace};
use crate::shape::{Geometry, Object, ObjectFlags, RayKind, Shapes, Visibility};
use crate::surface::Surface;
use crate::vdb::VdbFile;
use glam::{DAffine3, DVec3, Vec2, Vec3};
use std::sync::Arc;
use std::time::Instant;

pub struct World {
    pub camera: Camera,
    pub lights: Vec<Light>,
    pub environment: Environment,
    pub media: Media,
    /// The meshes' surfaces (empty without `[[mesh]]`).
    pub shapes: Shapes,
    /// Each mesh's material, in the order of `shapes`' objects.
    pub surfaces: Vec<Surface>,
    /// Blender's Film > Transparent: the world seen directly is left out
    /// of the colour.
    pub film_transparent: bool,
    /// Messages worth showing the user (e.g. negative densities clamped).
    pub warnings: Vec<String>,
    /// Seconds spent reading volumes.
    pub load_seconds: f64,
}

fn read_scalar(f: &VdbFile, name: &str) -> Result<Grid<f32>> {
    let g = f.read_float(name)?;
    if !g.all_finite() {
        return Err(Error::grid(
            f.path(),
            name,
            "has NaN or infinite values; fix the simulation or its export",
        ));
    }
    Ok(g)
}

/// A box `[min, max]` in world space.
pub type WorldBox = [DVec3; 2];

/// The axis-aligned box around `t` applied to the box `[lo, hi]`.
fn transform_box(t: &DAffine3, lo: DVec3, hi: DVec3) -> WorldBox {
    let (a, b) = crate::medium::transform_box(*t, lo, hi);
    [a, b]
}

/// The box (in the file's world space, before a scene transform) of a
/// grid's voxels `[lo, hi]` (index, inclusive): voxel centres are the
/// indices, so the box reaches half a voxel beyond them.
pub fn index_box(info: &crate::vdb::GridInfo, lo: DVec3, hi: DVec3) -> WorldBox {
    let m = &info.world_from_index;
    let t = DAffine3::from_cols_array(&[
        m[0], m[4], m[8], m[1], m[5], m[9], m[2], m[6], m[10], m[3], m[7], m[11],
    ]);
    transform_box(&t, lo - 0.5, hi + 0.5)
}

/// The active box of grid `grid` of `f` in the file's world space, from the
/// grid's header (no voxels are read); `None` when it is empty.
fn active_file_box(f: &VdbFile, grid: &str) -> Result<Option<WorldBox>> {
    let info = f.info()?;
    let Some(g) = info.grids.iter().find(|g| g.name == grid) else {
        // A missing grid gets its message from the grid reader.
        f.descriptor(grid)?;
        return Ok(None);
    };
    if g.empty {
        return Ok(None);
    }
    let lo = DVec3::from(g.bbox_min.map(f64::from));
    let hi = DVec3::from(g.bbox_max.map(f64::from));
    Ok(Some(index_box(g, lo, hi)))
}

/// The fluid domain's box in the file's world space: Blender's Mantaflow
/// writes the domain's resolution as `file_base_resolution`, with index
/// (0,0,0) at the domain's corner.
fn domain_file_box(f: &VdbFile, grid: &str) -> Result<WorldBox> {
    let info = f.info()?;
    let g = info.grids.iter().find(|g| g.name == grid);
    let res = g.and_then(|g| {
        let m = g
            .metadata
            .iter()
            .find(|m| m.name == "file_base_resolution")?;
        let v: Vec<f64> = m
            .value
            .trim_matches(|c| c == '[' || c == ']')
            .split(',')
            .map(|x| x.trim().parse().ok())
            .collect::<Option<_>>()?;
        (v.len() == 3 && v.iter().all(|&x| x >= 1.0)).then(|| DVec3::new(v[0], v[1], v[2]))
    });
    match (g, res) {
        (Some(g), Some(res)) => Ok(index_box(g, DVec3::ZERO, res - 1.0)),
        _ => Err(Error::grid(
            f.path(),
            grid,
            "bounds = \"domain\" needs the fluid domain's resolution (the `file_base_resolution` metadata Blender writes), which this grid does not have; give the domain's box as bounds = [[x0, y0, z0], [x1, y1, z1]] instead",
        )),
    }
}

/// The union of the active boxes (file space) of every frame of `v`'s
/// sequence whose file exists, read from the files' headers: the box that
/// keeps automatic framing fixed over the sequence (`bounds =
/// "sequence"`). `None` when no frame has active voxels. A frame that
/// cannot be read is left out here: its own render says what is wrong
/// with it.
pub fn sequence_file_box(pattern: &crate::sequence::PathPattern, grid: &str) -> Option<WorldBox> {
    let mut out: Option<WorldBox> = None;
    for frame in pattern.existing_frames() {
        let Ok(f) = VdbFile::open(pattern.expand(Some(frame), None)) else {
            continue;
        };
        if let Ok(Some([lo, hi])) = active_file_box(&f, grid) {
            out = Some(match out {
                Some([a, b]) => [a.min(lo), b.max(hi)],
                None => [lo, hi],
            });
        }
    }
    out
}

/// Grids a volume names that cannot change its image under its material,
/// each with why (a user who names a grid expects it to matter).
pub fn idle_grids(v: &VolumeDesc) -> Vec<String> {
    let mut out = Vec::new();
    let named = [
        ("temperature_grid", &v.temperature_grid),
        ("flame_grid", &v.flame_grid),
        ("color_grid", &v.color_grid),
    ];
    match &v.material {
        MaterialDesc::Raw { .. } => {
            for (key, grid) in named {
                if let Some(g) = grid {
                    out.push(format!(
                        "{key} '{g}' has no effect: a raw material (sigma_a/sigma_s/emission) uses the density grid only"
                    ));
                }
            }
        }
        MaterialDesc::Principled(p) => {
            if let (Some(g), true) = (&v.temperature_grid, p.blackbody_intensity == 0.0) {
                out.push(format!(
                    "temperature_grid '{g}' has no effect: blackbody_intensity is 0"
                ));
            }
            if let (Some(g), true) = (&v.flame_grid, p.emission_strength == 0.0) {
                out.push(format!(
                    "flame_grid '{g}' has no effect: it scales emission_strength, which is 0 (Blender's Quick Smoke fire glows by temperature_grid and blackbody_intensity instead)"
                ));
            }
        }
    }
    out
}

/// World space is single precision: a transform that places the density's
/// voxels beyond it (a translation of 1e115) would leave every ray missing
/// the volume, and the image black without a word. Checked before the
/// volume's acceleration grids are built.
fn check_world_range(f: &VdbFile, v: &VolumeDesc, density: &Grid<f32>) -> Result<()> {
    let Some((lo, hi)) = density.stored_bounds() else {
        return Ok(());
    };
    let m = v.transform * density.world_from_index();
    let limit = DVec3::splat(f64::from(f32::MAX) / 2.0);
    let [a, b] = transform_box(&m, lo.as_dvec3(), (hi + 1).as_dvec3());
    if a.abs().cmplt(limit).all() && b.abs().cmplt(limit).all() {
        return Ok(());
    }
    let o = m.translation;
    Err(Error::grid(
        f.path(),
        &v.density_grid,
        format!(
            "its transform places the volume beyond single-precision world space (index (0, 0, 0) at {:.3e}, {:.3e}, {:.3e}); check the grid's transform or the scene's",
            o.x, o.y, o.z
        ),
    ))
}

/// The names a velocity grid goes by when a volume names none: Blender's
/// and Mantaflow's `velocity`, Houdini's `vel`.
pub const VELOCITY_NAMES: [&str; 2] = ["velocity", "vel"];

/// The suffixes of split velocity grids, one float grid per component:
/// Houdini's `vel.x` and Cycles' `velocity_x`.
const SPLIT_SUFFIXES: [[&str; 3]; 2] = [[".x", ".y", ".z"], ["_x", "_y", "_z"]];

/// The velocity grid of `v` (`velocity_grid`, or the first of
/// [`VELOCITY_NAMES`] the file has): a `vec3s` grid, or three float
/// grids `NAME.x`/`NAME.y`/`NAME.z` (or `NAME_x`, ...) on one transform.
/// `None` when the volume names none and the file has none; an error when
/// the named one is missing, of another type, or not finite.
fn read_velocity(f: &VdbFile, v: &VolumeDesc) -> Result<Option<(String, VelocityGrids)>> {
    let names = f.grid_names();
    let has = |n: &str| names.contains(&n);
    let candidates: Vec<&str> = match &v.velocity_grid {
        Some(n) => vec![n.as_str()],
        None => VELOCITY_NAMES.to_vec(),
    };
    let finite_vec = |g: Grid<Vec3>, n: &str| {
        if g.all_finite() {
            Ok(g)
        } else {
            Err(Error::grid(
                f.path(),
                n,
                "has NaN or infinite velocities; fix the simulation or its export",
            ))
        }
    };
    for name in candidates {
        if has(name) {
            let d = f.descriptor(name)?;
            return match d.channels() {
                Some(3) => {
                    let g = finite_vec(f.read_vec3(name)?, name)?;
                    Ok(Some((name.to_string(), VelocityGrids::Vector(g))))
                }
                _ => Err(Error::grid(
                    f.path(),
                    name,
                    format!(
                        "is a {} grid, but a velocity grid holds vectors (vec3s), or is three float grids {name}.x, {name}.y, {name}.z",
                        d.value_type()
                    ),
                )),
            };
        }
        for suffixes in SPLIT_SUFFIXES {
            let parts = suffixes.map(|s| format!("{name}{s}"));
            if !parts.iter().all(|p| has(p)) {
                continue;
            }
            let mut grids = Vec::with_capacity(3);
            for p in &parts {
                let d = f.descriptor(p)?;
                if d.channels() != Some(1) {
                    return Err(Error::grid(
                        f.path(),
                        p,
                        format!(
                            "is a {} grid, but a split velocity component is a float grid",
                            d.value_type()
                        ),
                    ));
                }
                let g = f.read_float(p)?;
                if !g.all_finite() {
                    return Err(Error::grid(
                        f.path(),
                        p,
                        "has NaN or infinite velocities; fix the simulation or its export",
                    ));
                }
                grids.push(g);
            }
            let [x, y, z]: [Grid<f32>; 3] = grids
                .try_into()
                .map_err(|_| Error::grid(f.path(), name, "three velocity components expected"))?;
            if y.world_from_index() != x.world_from_index()
                || z.world_from_index() != x.world_from_index()
            {
                return Err(Error::grid(
                    f.path(),
                    name,
                    format!(
                        "the split velocity grids {} have different transforms; they must share one",
                        parts.join(", ")
                    ),
                ));
            }
            return Ok(Some((name.to_string(), VelocityGrids::Split([x, y, z]))));
        }
    }
    match &v.velocity_grid {
        Some(n) => Err(Error::file(
            f.path(),
            format!(
                "no velocity grid '{n}' (neither a vec3s grid '{n}' nor float grids '{n}.x', '{n}.y', '{n}.z'; its grids: {})",
                names.join(", ")
            ),
        )),
        None => Ok(None),
    }
}

/// Displacements over the shutter beyond this many times a volume's
/// largest extent are refused: the majorants, dilated by the motion, would
/// cover that much empty space around the volume, and every ray would pay
/// for it in null collisions (the cost grows with 1 + 2 × this).
pub const MAX_BLUR_EXTENTS: f32 = 4.0;

fn load_volume(
    v: &VolumeDesc,
    motion_blur: &MotionBlurDesc,
    warnings: &mut Vec<String>,
) -> Result<(Option<Volume>, Option<WorldBox>)> {
    for w in idle_grids(v) {
        warnings.push(format!("'{}': {w}", v.file.display()));
    }
    if let (Some(g), false) = (&v.velocity_grid, motion_blur.enabled) {
        warnings.push(format!(
            "'{}': velocity_grid '{g}' has no effect: motion blur is off ([render] motion_blur = true turns it on)",
            v.file.display()
        ));
    }
    let f = VdbFile::open(&v.file)?;
    let density = read_scalar(&f, &v.density_grid)?;
    if let Some([lo, _]) = density.value_range() {
        if lo < 0.0 {
            warnings.push(format!(
                "'{}', grid '{}': negative densities (down to {lo}) are treated as 0, as Cycles does",
                v.file.display(),
                v.density_grid
            ));
        }
    }
    let extra = ExtraGrids {
        temperature: v
            .temperature_grid
            .as_deref()
            .map(|n| {
                let g = read_scalar(&f, n)?;
                match v.temperature_from_flame {
                    // Blender's fluid domain temperature attribute
                    // (`rna_FluidModifier_temperature_grid_get`).
                    Some([ignition, max]) => g.map_values(n, |flame: f32| {
                        if flame > 0.01 {
                            ignition + flame * (max - ignition)
                        } else {
                            0.0
                        }
                    }),
                    None => Ok(g),
                }
            })
            .transpose()?,
        flame: v
            .flame_grid
            .as_deref()
            .map(|n| read_scalar(&f, n))
            .transpose()?,
        color: v
            .color_grid
            .as_deref()
            .map(|n| {
                let g = f.read_vec3(n)?;
                if !g.all_finite() {
                    return Err(Error::grid(
                        f.path(),
                        n,
                        "has NaN or infinite values; fix the simulation or its export",
                    ));
                }
                Ok(g)
            })
            .transpose()?,
        blackbody_filter: v.blackbody_filter,
        velocity: None,
    };
    let mut extra = extra;
    if let Some((open, close)) = motion_blur.shutter_interval() {
        if let Some((name, grids)) = read_velocity(&f, v)? {
            let per_frame = v.velocity_scale
                * match v.velocity_unit {
                    VelocityUnit::Second => (1.0 / motion_blur.fps) as f32,
                    VelocityUnit::Frame => 1.0,
                };
            let field = VelocityField {
                grids,
                shutter: (open, close),
                per_frame,
            };
            check_motion(&f, v, &name, &density, &field)?;
            extra.velocity = Some(field);
        }
    }
    let material = Material::from_desc(&v.material);
    check_world_range(&f, v, &density)?;
    let label = v.file.display().to_string();
    let vol = Volume::new(&label, density, extra, material, v.transform);
    if let Some(vol) = &vol {
        check_optical_depth(v, vol)?;
    }
    if vol.is_none() {
        warnings.push(format!(
            "'{}', grid '{}': the grid is empty and nothing else in the volume emits; the volume is skipped",
            v.file.display(),
            v.density_grid
        ));
    }
    let file_box = match v.bounds {
        VolumeBounds::Box([lo, hi]) => Some([lo, hi]),
        VolumeBounds::Domain => Some(domain_file_box(&f, &v.density_grid)?),
        // A sequence's box is found before its frames are rendered
        // (`crate::frames`); a single file has only its own.
        VolumeBounds::Active | VolumeBounds::Sequence => None,
    };
    let world_box = match (file_box, &vol) {
        (Some([lo, hi]), _) => Some(transform_box(&v.transform, lo, hi)),
        (None, Some(vol)) => Some(match vol.density().active_bounds() {
            // The active voxels, half a voxel beyond their centres.
            Some((lo, hi)) => {
                let m = vol.world_from_index();
                let t = DAffine3::from_cols(
                    m.matrix3.x_axis.as_dvec3(),
                    m.matrix3.y_axis.as_dvec3(),
                    m.matrix3.z_axis.as_dvec3(),
                    m.translation.as_dvec3(),
                );
                transform_box(&t, lo.as_dvec3() - 0.5, hi.as_dvec3() + 0.5)
            }
            // Fire without smoke: the box the trackers use.
            None => {
                let (lo, hi) = vol.world_bounds();
                [lo.as_dvec3(), hi.as_dvec3()]
            }
        }),
        (None, None) => None,
    };
    Ok((vol, world_box))
}

/// Refuses a velocity so fast that the volume would move more than
/// [`MAX_BLUR_EXTENTS`] times its own extent over the shutter (bounded
/// cost: see there).
fn check_motion(
    f: &VdbFile,
    v: &VolumeDesc,
    name: &str,
    density: &Grid<f32>,
    field: &VelocityField,
) -> Result<()> {
    let Some(m) = crate::medium::Motion::new(field.clone(), v.transform) else {
        return Ok(());
    };
    let Some((lo, hi)) = density.stored_bounds() else {
        return Ok(());
    };
    let w = v.transform * density.world_from_index();
    let [a, b] = transform_box(&w, lo.as_dvec3(), (hi + 1).as_dvec3());
    let extent = (b - a).max_element() as f32;
    let moved = m.max_displacement();
    if moved.is_finite() && moved <= MAX_BLUR_EXTENTS * extent {
        return Ok(());
    }
    Err(Error::grid(
        f.path(),
        name,
        format!(
            "the fastest velocity moves the volume {moved:.3e} world units over the shutter, {:.3e} times its {extent:.3e}-unit extent (at most {MAX_BLUR_EXTENTS}: the majorants, dilated by the motion, would cover that much empty space); check velocity_scale, velocity_unit and fps",
            moved / extent
        ),
    ))
}

/// The flags of a `[[mesh]]`.
fn mesh_flags(m: &MeshDesc) -> ObjectFlags {
    let v = &m.visibility;
    ObjectFlags {
        holdout: m.holdout,
        shadow_catcher: m.shadow_catcher,
        visibility: Visibility::NONE
            .with(RayKind::CAMERA, v.camera)
            .with(RayKind::SHADOW, v.shadow)
            .with(RayKind::DIFFUSE, v.diffuse)
            .with(RayKind::GLOSSY, v.glossy)
            .with(RayKind::TRANSMISSION, v.transmission)
            .with(RayKind::VOLUME_SCATTER, v.volume_scatter),
    }
}

/// Reads a `[[mesh]]` and places it in world space (normals by the
/// transform's inverse transpose); refuses a transform that puts a vertex
/// beyond single-precision world space.
fn load_mesh(m: &MeshDesc) -> Result<(Object, Geometry)> {
    let mesh = crate::mesh::read(&m.file)?;
    let t = m.transform;
    let world: Vec<Vec3> = mesh
        .positions
        .iter()
        .map(|p| t.transform_point3(p.as_dvec3()).as_vec3())
        .collect();
    let limit = f32::MAX / 2.0;
    if let Some(p) = world
        .iter()
        .find(|p| !(p.is_finite() && p.abs().max_element() < limit))
    {
        return Err(Error::file(
            &m.file,
            format!(
                "its transform places a vertex beyond single-precision world space ({:.3e}, {:.3e}, {:.3e}); check the mesh's transform",
                p.x, p.y, p.z
            ),
        ));
    }
    let normal_matrix = t.matrix3.inverse().transpose();
    let normals = mesh
        .normals
        .iter()
        .map(|n| (normal_matrix * n.as_dvec3()).normalize_or_zero().as_vec3())
        .collect();
    let name = m.name.clone().unwrap_or_else(|| {
        m.file
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
    });
    Ok((
        Object {
            name,
            flags: mesh_flags(m),
            triangles: mesh.triangles.len(),
        },
        Geometry {
            positions: world,
            triangles: mesh.triangles,
            normals,
            uvs: mesh.uvs,
        },
    ))
}

/// A `[[mesh]]`'s material with its textures read (each file and colour
/// space once, in `cache`); Cycles' default surface when it has none.
fn load_surface(
    m: &MeshDesc,
    cache: &mut Vec<((std::path::PathBuf, ColorSpace), Arc<Texture>)>,
) -> Result<Surface> {
    let Some(desc) = &m.material else {
        return Ok(Surface::default_surface());
    };
    Surface::from_desc(desc, |c| {
        let ColorInput::Texture { file, colorspace } = c else {
            return Ok(None);
        };
        let space = match colorspace {
            TextureColorSpace::Srgb => ColorSpace::Srgb,
            TextureColorSpace::Linear => ColorSpace::Linear,
        };
        let key = (file.clone(), space);
        if let Some((_, t)) = cache.iter().find(|(k, _)| *k == key) {
            return Ok(Some(t.clone()));
        }
        let t = Arc::new(
            Texture::read(file, space)
                .map_err(|e| Error::Argument(format!("[mesh.material] texture: {e}")))?,
        );
        cache.push((key, t.clone()));
        Ok(Some(t))
    })
}

/// The surfaces of a scene's `[[mesh]]`es and their materials (by object,
/// in the order of `Shapes::objects`).
pub fn load_shapes(
    meshes: &[MeshDesc],
    warnings: &mut Vec<String>,
) -> Result<(Shapes, Vec<Surface>)> {
    use crate::scene::{ColorInput, SurfaceDesc};
    let mut parts = Vec::with_capacity(meshes.len());
    let mut surfaces = Vec::with_capacity(meshes.len());
    let mut cache = Vec::new();
    for (i, m) in meshes.iter().enumerate() {
        let context = |e: Error| e.context(format!("[[mesh]] {} {}", i + 1, m.label()));
        let part = load_mesh(m).map_err(context)?;
        let textured = match &m.material {
            Some(SurfaceDesc::Principled(p)) => matches!(p.base_color, ColorInput::Texture { .. }),
            Some(SurfaceDesc::Diffuse { color, .. } | SurfaceDesc::Emission { color, .. }) => {
                matches!(color, ColorInput::Texture { .. })
            }
            None => false,
        };
        if textured && part.1.uvs.is_empty() && !part.1.triangles.is_empty() {
            warnings.push(format!(
                "[[mesh]] {} {}: its material has an image texture but '{}' has no UV map: the texture is read at (0, 0) everywhere",
                i + 1,
                m.label(),
                m.file.display()
            ));
        }
        parts.push(part);
        surfaces.push(load_surface(m, &mut cache).map_err(context)?);
    }
    Ok((Shapes::new(parts), surfaces))
}

/// The camera a scene describes; `boxes` are the volumes' world boxes
/// for automatic framing.
pub fn make_camera(c: &CameraDesc, width: u32, height: u32, boxes: &[WorldBox]) -> Result<Camera> {
    let shift = Vec2::from(c.shift);
    let plane = match c.lens {
        // A vertical field of view fits the height: shift is a fraction of
        // it.
        Lens::Vfov(v) => {
            let p = Plane::vfov(v, width, height);
            Plane {
                shift_x: shift.x * 2.0 * p.tan_half_y,
                shift_y: shift.y * 2.0 * p.tan_half_y,
                ..p
            }
        }
        Lens::Sensor {
            focal_length,
            sensor_width,
            sensor_height,
            fit,
        } => Plane::sensor(
            focal_length,
            Vec2::new(sensor_width, sensor_height),
            fit,
            shift,
            width,
            height,
        ),
    };
    Ok(match c.pose {
        CameraPose::LookAt {
            position,
            look_at,
            up,
        } => Camera::with_frame(position, look_at - position, up, plane, width, height),
        CameraPose::Matrix(m) => Camera::with_frame(
            m.translation.as_vec3(),
            -m.matrix3.z_axis.as_vec3(),
            m.matrix3.y_axis.as_vec3(),
            plane,
            width,
            height,
        ),
        CameraPose::Auto { direction, up } => {
            let Some([lo, hi]) = boxes
                .iter()
                .copied()
                .reduce(|[a, b], [c, d]| [a.min(c), b.max(d)])
            else {
                return Err(Error::Argument(
                    "[camera] framing = \"auto\": no volume has voxels to frame".into(),
                ));
            };
            // Aim at the boxes' centre, from far enough that every corner
            // is inside the view with 5 % to spare on the tighter side.
            let centre = (lo + hi) * 0.5;
            let dir = direction.as_dvec3().normalize();
            let forward = -dir;
            let right = forward.cross(up.as_dvec3()).normalize();
            let cam_up = right.cross(forward);
            let (tx, ty) = (
                0.95 * plane.tan_half_x as f64,
                0.95 * plane.tan_half_y as f64,
            );
            let mut distance: f64 = 1e-6;
            for i in 0..8 {
                let corner = DVec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                );
                let q = corner - centre;
                let (u, v, w) = (q.dot(right), q.dot(cam_up), q.dot(forward));
                // Depth of the corner is distance + w.
                distance = distance
                    .max(u.abs() / tx - w)
                    .max(v.abs() / ty - w)
                    .max(1e-3 - w);
            }
            let position = centre + dir * distance;
            Camera::with_frame(
                position.as_vec3(),
                (-dir).as_vec3(),
                up,
                plane,
                width,
                height,
            )
        }
    })
}

/// The largest optical depth a single voxel may have. Light does not cross
/// even one voxel long before this (its transmittance is e^-1000), and
/// beyond it the trackers' cost, which grows with the majorant over the
/// stretches where the density falls away, is no longer bounded by anything
/// a render can afford: σ = 10^12 made a 16 x 12 render run for minutes,
/// and on the reference cloud at 4·10^5 per unit (10^4 per voxel) the
/// photons of one pass took 84 s, at 4·10^4 (830 per voxel) 9 s.
pub const MAX_VOXEL_OPTICAL_DEPTH: f32 = 1e3;

/// Refuses extinction so high that a single voxel is opaque beyond any
/// meaning (see [`MAX_VOXEL_OPTICAL_DEPTH`]).
fn check_optical_depth(v: &VolumeDesc, vol: &Volume) -> Result<()> {
    let dmax = vol.density().value_range().map_or(0.0, |r| r[1].max(0.0));
    let sigma = vol.sigma_t_per_density() * dmax;
    let depth = sigma * vol.voxel_length();
    if !depth.is_finite() || depth > MAX_VOXEL_OPTICAL_DEPTH {
        return Err(Error::grid(
            &v.file,
            &v.density_grid,
            format!(
                "the material makes the extinction reach {sigma:e} per unit length, an optical depth of {depth:e} across one voxel (at most {MAX_VOXEL_OPTICAL_DEPTH:e}: light could not cross a voxel); lower the material's density or sigma_a/sigma_s"
            ),
        ));
    }
    Ok(())
}

impl World {
    /// Loads every volume (and the environment map) of a validated scene.
    pub fn load(desc: &SceneDesc) -> Result<World> {
        let t0 = Instant::now();
        let mut warnings = Vec::new();
        let mut volumes = Vec::new();
        let mut boxes = Vec::new();
        for (i, v) in desc.volumes.iter().enumerate() {
            let (vol, world_box) = load_volume(v, &desc.render.motion_blur, &mut warnings)
                .map_err(|e| e.context(format!("[[volume]] {}", i + 1)))?;
            volumes.extend(vol);
            boxes.extend(world_box);
        }
        let lights = desc
            .lights
            .iter()
            .map(|l| match *l {
                LightDesc::Sun {
                    direction,
                    irradiance,
                    angle_deg,
                } => Light::sun(direction, irradiance, angle_deg),
                LightDesc::Point {
                    position,
                    intensity,
                } => Light::Point {
                    position,
                    intensity,
                },
                LightDesc::Spot {
                    position,
                    direction,
                    intensity,
                    cone_angle_deg,
                    blend,
                } => Light::spot(position, direction, intensity, cone_angle_deg, blend),
            })
            .collect();
        let environment = match &desc.environment {
            EnvironmentDesc::Constant(c) => Environment::Constant(*c),
            EnvironmentDesc::Map {
                path,
                strength,
                rotate_z_deg,
            } => {
                let img = crate::image::read_exr_rgb(path)?;
                let texels = img.pixels.iter().map(|p| *p * *strength).collect();
                Environment::Map(Box::new(EnvMap::new(
                    img.width,
                    img.height,
                    texels,
                    *rotate_z_deg,
                )))
            }
        };
        let (shapes, surfaces) = load_shapes(&desc.meshes, &mut warnings)?;
        let r = &desc.render;
        let c = &desc.camera;
        let media = Media::new(volumes);
        // The shutter opens only where something moves: a frame without
        // motion renders exactly as a still one.
        let shutter = match r.motion_blur.shutter_interval() {
            Some((open, close)) if media.is_moving() => Some(Shutter { open, close }),
            Some(_) => {
                warnings.push(
                    "motion_blur is on, but no volume moves (no velocity grid, or a zero one): the frame renders still".into(),
                );
                None
            }
            None => None,
        };
        Ok(World {
            camera: make_camera(c, r.width, r.height, &boxes)?.with_shutter(shutter),
            lights,
            environment,
            media,
            shapes,
            surfaces,
            film_transparent: r.film_transparent,
            warnings,
            load_seconds: t0.elapsed().as_secs_f64(),
        })
    }
}
