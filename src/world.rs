//! The world a render sees: a scene description (`crate::scene`, the only
//! serde user) turned into loaded volumes, lights and a camera.

use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::grid::Grid;
use crate::light::{EnvMap, Environment, Light};
use crate::medium::{ExtraGrids, Material, Media, Volume};
use crate::scene::{EnvironmentDesc, LightDesc, SceneDesc, VolumeDesc};
use crate::vdb::VdbFile;
use std::time::Instant;

pub struct World {
    pub camera: Camera,
    pub lights: Vec<Light>,
    pub environment: Environment,
    pub media: Media,
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

fn load_volume(v: &VolumeDesc, warnings: &mut Vec<String>) -> Result<Option<Volume>> {
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
            .map(|n| read_scalar(&f, n))
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
    };
    let material = Material::from_desc(&v.material);
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
    Ok(vol)
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
        for v in &desc.volumes {
            if let Some(vol) = load_volume(v, &mut warnings)? {
                volumes.push(vol);
            }
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
        let r = &desc.render;
        let c = &desc.camera;
        Ok(World {
            camera: Camera::new(c.position, c.look_at, c.up, c.vfov_deg, r.width, r.height),
            lights,
            environment,
            media: Media::new(volumes),
            warnings,
            load_seconds: t0.elapsed().as_secs_f64(),
        })
    }
}
