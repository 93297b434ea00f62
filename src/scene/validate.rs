//! Cross-field rules on a [`SceneDesc`]. Error paths use the scene file's key
//! names so the loader can point at the offending line.

use glam::Vec3;

use super::desc::{
    CameraPose, EnvironmentDesc, Lens, LightDesc, MaterialDesc, PhaseDesc, Principled, SceneDesc,
    VolumeBounds,
};
use super::error::{kp, PathSeg, ValidationError};

type Check = Result<(), ValidationError>;

fn err(path: Vec<PathSeg>, message: impl Into<String>) -> Check {
    Err(ValidationError::new(path, message))
}

fn with(path: &[PathSeg], key: &str) -> Vec<PathSeg> {
    let mut p = path.to_vec();
    p.push(PathSeg::Key(key.to_owned()));
    p
}

fn finite(path: &[PathSeg], v: f32) -> Check {
    if v.is_finite() {
        Ok(())
    } else {
        err(path.to_vec(), format!("must be a finite number, got {v}"))
    }
}

fn finite3(path: &[PathSeg], v: Vec3) -> Check {
    if v.is_finite() {
        Ok(())
    } else {
        err(
            path.to_vec(),
            format!("must be finite numbers, got {}", fmt3(v)),
        )
    }
}

fn fmt3(v: Vec3) -> String {
    format!("[{}, {}, {}]", v.x, v.y, v.z)
}

/// Finite and `>= 0` in every component.
fn non_negative3(path: &[PathSeg], v: Vec3) -> Check {
    finite3(path, v)?;
    if v.cmpge(Vec3::ZERO).all() {
        Ok(())
    } else {
        err(path.to_vec(), format!("must be >= 0, got {}", fmt3(v)))
    }
}

fn non_negative(path: &[PathSeg], v: f32) -> Check {
    finite(path, v)?;
    if v >= 0.0 {
        Ok(())
    } else {
        err(path.to_vec(), format!("must be >= 0, got {v}"))
    }
}

/// Finite, within `[lo, hi]` (bounds included or not as flagged).
fn in_range(path: &[PathSeg], v: f32, lo: (f32, bool), hi: (f32, bool)) -> Check {
    finite(path, v)?;
    let above = if lo.1 { v >= lo.0 } else { v > lo.0 };
    let below = if hi.1 { v <= hi.0 } else { v < hi.0 };
    if above && below {
        Ok(())
    } else {
        let open = if lo.1 { '[' } else { '(' };
        let close = if hi.1 { ']' } else { ')' };
        err(
            path.to_vec(),
            format!("must be in {open}{}, {}{close}, got {v}", lo.0, hi.0),
        )
    }
}

fn g_range(path: &[PathSeg], g: f32) -> Check {
    in_range(path, g, (-1.0, true), (1.0, true))
}

fn non_zero_direction(path: &[PathSeg], v: Vec3) -> Check {
    finite3(path, v)?;
    if v.length_squared() > 0.0 {
        Ok(())
    } else {
        err(path.to_vec(), "must not be the zero vector")
    }
}

/// A path's frame and tile placeholders must be well formed.
fn pattern(path: &[PathSeg], p: &std::path::Path) -> Check {
    match crate::sequence::PathPattern::new(p) {
        Ok(_) => Ok(()),
        Err(e) => err(path.to_vec(), e),
    }
}

/// `up` must not be zero or parallel to `view` (named `what`).
fn not_parallel(path: &[PathSeg], up: Vec3, view: Vec3, what: &str) -> Check {
    let sin = view.normalize().cross(up.normalize_or_zero()).length();
    if sin.is_nan() || sin < 1e-4 {
        return err(
            path.to_vec(),
            format!(
                "must not be zero or parallel to the view direction {what} = {}",
                fmt3(view)
            ),
        );
    }
    Ok(())
}

fn grid_name(path: &[PathSeg], name: &str) -> Check {
    if name.trim().is_empty() {
        err(path.to_vec(), "grid name must not be empty")
    } else {
        Ok(())
    }
}

/// The longest shutter, frames: a shutter open for longer blurs a volume
/// over a thousand frames of its motion, a mistake rather than a look.
pub const MAX_SHUTTER: f32 = 1000.0;

impl SceneDesc {
    /// Checks every rule the parser cannot express per key: ranges, finite
    /// numbers, camera geometry, something to render. Returns the first
    /// problem found. Call it again after changing fields (CLI overrides).
    pub fn validate(&self) -> Result<(), ValidationError> {
        self.validate_render()?;
        self.validate_camera()?;
        for (i, light) in self.lights.iter().enumerate() {
            validate_light(&kp!["light", i], light)?;
        }
        self.validate_environment()?;
        for (i, volume) in self.volumes.iter().enumerate() {
            let path = kp!["volume", i];
            grid_name(&with(&path, "density_grid"), &volume.density_grid)?;
            for (key, grid) in [
                ("temperature_grid", &volume.temperature_grid),
                ("flame_grid", &volume.flame_grid),
                ("color_grid", &volume.color_grid),
                ("velocity_grid", &volume.velocity_grid),
            ] {
                if let Some(name) = grid {
                    grid_name(&with(&path, key), name)?;
                }
            }
            let t = &volume.transform;
            if !t.is_finite() {
                return err(with(&path, "transform"), "must be finite numbers");
            }
            if t.matrix3.determinant() == 0.0 {
                return err(
                    with(&path, "transform"),
                    "is singular (a zero scale or degenerate matrix)",
                );
            }
            validate_material(&with(&path, "material"), &volume.material)?;
            pattern(&with(&path, "file"), &volume.file)?;
            if let Some([ignition, max]) = volume.temperature_from_flame {
                let p = with(&path, "temperature_from_flame");
                if volume.temperature_grid.is_none() {
                    return err(
                        p,
                        "needs temperature_grid (the flame grid the temperature is made from, \"flame\" in Blender's caches)",
                    );
                }
                non_negative(&p, ignition)?;
                if !(max.is_finite() && max >= ignition) {
                    return err(
                        p,
                        format!("[ignition, max_temp] needs max_temp >= ignition, got [{ignition}, {max}]"),
                    );
                }
            }
            finite3(&with(&path, "velocity_scale"), volume.velocity_scale)?;
            if volume.frame_offset.unsigned_abs() > crate::sequence::MAX_FRAME as u64 {
                return err(
                    with(&path, "frame_offset"),
                    format!(
                        "must be within ±{}, got {}",
                        crate::sequence::MAX_FRAME,
                        volume.frame_offset
                    ),
                );
            }
            if let VolumeBounds::Box([lo, hi]) = volume.bounds {
                if !(lo.is_finite() && hi.is_finite() && lo.cmple(hi).all()) {
                    return err(
                        with(&path, "bounds"),
                        format!("must be finite with min <= max in each axis, got [{lo}, {hi}]"),
                    );
                }
            }
        }
        for (i, mesh) in self.meshes.iter().enumerate() {
            let path = kp!["mesh", i];
            let t = &mesh.transform;
            if !t.is_finite() {
                return err(with(&path, "transform"), "must be finite numbers");
            }
            if t.matrix3.determinant() == 0.0 {
                return err(
                    with(&path, "transform"),
                    "is singular (a zero scale or degenerate matrix)",
                );
            }
            if let Some(m) = &mesh.material {
                validate_surface(&with(&path, "material"), m)?;
            }
        }
        if self.volumes.is_empty() && self.meshes.is_empty() {
            return err(
                vec![],
                "no [[volume]] and no [[mesh]]: a scene needs something to render",
            );
        }
        Ok(())
    }

    fn validate_render(&self) -> Check {
        let r = &self.render;
        let p = |k| kp!["render", k];
        for (key, v) in [("width", r.width), ("height", r.height)] {
            if !(1..=65536).contains(&v) {
                return err(p(key), format!("must be in [1, 65536], got {v}"));
            }
        }
        let pixels = r.width as u64 * r.height as u64;
        if pixels > MAX_PIXELS {
            return err(
                p("width"),
                format!(
                    "{} x {} is {pixels} pixels, more than the {MAX_PIXELS} a render may have \
                     (a render takes about 120 bytes per pixel, 200 with AOV layers)",
                    r.width, r.height
                ),
            );
        }
        if r.spp < 1 {
            return err(p("spp"), format!("must be >= 1, got {}", r.spp));
        }
        if r.output.as_os_str().is_empty() {
            return err(p("output"), "path must not be empty");
        }
        if r.preview.as_ref().is_some_and(|p| p.as_os_str().is_empty()) {
            return err(p("preview"), "path must not be empty");
        }
        pattern(&p("output"), &r.output)?;
        if let Some(preview) = &r.preview {
            pattern(&p("preview"), preview)?;
        }
        let m = &r.motion_blur;
        if !(m.shutter.is_finite() && (0.0..=MAX_SHUTTER).contains(&m.shutter)) {
            return err(
                p("shutter"),
                format!(
                    "must be a number of frames in [0, {MAX_SHUTTER}] (Blender's default is 0.5), got {}",
                    m.shutter
                ),
            );
        }
        if !(m.fps.is_finite() && m.fps > 0.0 && m.fps <= 1e6) {
            return err(
                p("fps"),
                format!(
                    "must be more than 0 frames per second (Blender's fps / fps_base; 24 by default), got {}",
                    m.fps
                ),
            );
        }
        finite(&p("exposure"), r.exposure)
    }

    fn validate_camera(&self) -> Check {
        let c = &self.camera;
        let p = |k| kp!["camera", k];
        match c.pose {
            CameraPose::LookAt {
                position,
                look_at,
                up,
            } => {
                finite3(&p("position"), position)?;
                finite3(&p("look_at"), look_at)?;
                finite3(&p("up"), up)?;
                let view = look_at - position;
                if view.length_squared() == 0.0 {
                    return err(
                        p("look_at"),
                        format!("must differ from 'position' (both are {})", fmt3(position)),
                    );
                }
                not_parallel(&p("up"), up, view, "look_at - position")?;
            }
            CameraPose::Matrix(m) => {
                if !m.is_finite() {
                    return err(p("matrix"), "must be finite numbers");
                }
                let (x, y, z) = (m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis);
                let unit = |v: glam::DVec3| v.normalize_or_zero();
                if m.matrix3.determinant().abs() < 1e-12
                    || unit(x).dot(unit(y)).abs() > 1e-3
                    || unit(y).dot(unit(z)).abs() > 1e-3
                    || unit(z).dot(unit(x)).abs() > 1e-3
                {
                    return err(
                        p("matrix"),
                        "must be a rotation (with translation and scale): its first three columns must be orthogonal and not zero",
                    );
                }
            }
            CameraPose::Auto { direction, up } => {
                non_zero_direction(&p("direction"), direction)?;
                finite3(&p("up"), up)?;
                not_parallel(&p("up"), up, direction, "direction")?;
            }
        }
        match c.lens {
            Lens::Vfov(v) => in_range(&p("vfov"), v, (0.0, false), (180.0, false))?,
            Lens::Sensor {
                focal_length,
                sensor_width,
                sensor_height,
                fit: _,
            } => {
                in_range(&p("focal_length"), focal_length, (0.0, false), (1e6, true))?;
                in_range(&p("sensor_width"), sensor_width, (0.0, false), (1e6, true))?;
                in_range(
                    &p("sensor_height"),
                    sensor_height,
                    (0.0, false),
                    (1e6, true),
                )?;
            }
        }
        in_range(&p("shift_x"), c.shift[0], (-100.0, true), (100.0, true))?;
        in_range(&p("shift_y"), c.shift[1], (-100.0, true), (100.0, true))
    }

    fn validate_environment(&self) -> Check {
        let p = |k| kp!["environment", k];
        match &self.environment {
            EnvironmentDesc::Constant(radiance) => non_negative3(&p("radiance"), *radiance),
            EnvironmentDesc::Map {
                path,
                strength,
                rotate_z_deg,
            } => {
                if path.as_os_str().is_empty() {
                    return err(p("map"), "path must not be empty");
                }
                non_negative(&p("strength"), *strength)?;
                finite(&p("rotate_z"), *rotate_z_deg)
            }
        }
    }
}

fn validate_light(path: &[PathSeg], light: &LightDesc) -> Check {
    let k = |key| with(path, key);
    match *light {
        LightDesc::Sun {
            direction,
            irradiance,
            angle_deg,
        } => {
            non_zero_direction(&k("direction"), direction)?;
            non_negative3(&k("irradiance"), irradiance)?;
            in_range(&k("angle"), angle_deg, (0.0, true), (180.0, false))
        }
        LightDesc::Point {
            position,
            intensity,
        } => {
            finite3(&k("position"), position)?;
            non_negative3(&k("intensity"), intensity)
        }
        LightDesc::Spot {
            position,
            direction,
            intensity,
            cone_angle_deg,
            blend,
        } => {
            finite3(&k("position"), position)?;
            non_zero_direction(&k("direction"), direction)?;
            non_negative3(&k("intensity"), intensity)?;
            in_range(
                &k("cone_angle"),
                cone_angle_deg,
                (0.0, false),
                (180.0, true),
            )?;
            in_range(&k("blend"), blend, (0.0, true), (1.0, true))
        }
    }
}

/// The most pixels a render may have: 2^27 (e.g. 16384 x 8192). A render
/// takes about 120 bytes per pixel at its peak, 200 with AOV layers
/// (measured at 2048 x 2048), so 15 to 25 GiB at this size; far larger
/// sizes would fail to allocate, and an allocation failure aborts the
/// process instead of reporting an error.
pub const MAX_PIXELS: u64 = 1 << 27;

fn validate_material(path: &[PathSeg], material: &MaterialDesc) -> Check {
    let k = |key| with(path, key);
    match material {
        MaterialDesc::Principled(Principled {
            density,
            color,
            absorption_color,
            anisotropy,
            emission_strength,
            emission_color,
            blackbody_intensity,
            blackbody_tint,
            temperature,
        }) => {
            non_negative(&k("density"), *density)?;
            non_negative3(&k("color"), *color)?;
            non_negative3(&k("absorption_color"), *absorption_color)?;
            g_range(&k("anisotropy"), *anisotropy)?;
            non_negative(&k("emission_strength"), *emission_strength)?;
            non_negative3(&k("emission_color"), *emission_color)?;
            non_negative(&k("blackbody_intensity"), *blackbody_intensity)?;
            non_negative3(&k("blackbody_tint"), *blackbody_tint)?;
            non_negative(&k("temperature"), *temperature)
        }
        MaterialDesc::Raw {
            sigma_a,
            sigma_s,
            emission,
            phase,
        } => {
            non_negative3(&k("sigma_s"), *sigma_s)?;
            non_negative3(&k("sigma_a"), *sigma_a)?;
            non_negative3(&k("emission"), *emission)?;
            let p = k("phase");
            match phase {
                PhaseDesc::Isotropic | PhaseDesc::Rayleigh => Ok(()),
                PhaseDesc::Hg { g } | PhaseDesc::Schlick { g } => g_range(&with(&p, "g"), *g),
                // The ranges of Blender 5's Volume Scatter node's sockets.
                PhaseDesc::FournierForand { backscatter, ior } => {
                    in_range(
                        &with(&p, "backscatter"),
                        *backscatter,
                        (0.0, true),
                        (0.5, true),
                    )?;
                    in_range(&with(&p, "ior"), *ior, (1.0, true), (2.0, true))
                }
                PhaseDesc::Draine { g, alpha } => {
                    g_range(&with(&p, "g"), *g)?;
                    in_range(&with(&p, "alpha"), *alpha, (0.0, true), (500.0, true))
                }
                PhaseDesc::Mie { diameter } => {
                    in_range(&with(&p, "diameter"), *diameter, (0.0, true), (50.0, true))
                }
                PhaseDesc::HgMix(lobes) => {
                    let lobes_path = with(&p, "lobes");
                    let mut sum = 0.0;
                    for (i, &(g, weight)) in lobes.iter().enumerate() {
                        let mut lobe = lobes_path.clone();
                        lobe.push(PathSeg::Index(i));
                        g_range(&with(&lobe, "g"), g)?;
                        non_negative(&with(&lobe, "weight"), weight)?;
                        sum += weight;
                    }
                    if sum > 0.0 && sum.is_finite() {
                        Ok(())
                    } else {
                        err(
                            lobes_path,
                            format!("weights must have a positive sum, got {sum}"),
                        )
                    }
                }
            }
        }
    }
}

fn validate_color(path: &[PathSeg], key: &str, c: &super::desc::ColorInput) -> Check {
    match c {
        super::desc::ColorInput::Value(v) => non_negative3(&with(path, key), *v),
        super::desc::ColorInput::Texture { .. } => Ok(()),
    }
}

/// Ranges as Blender's sockets have them.
fn validate_surface(path: &[PathSeg], m: &super::desc::SurfaceDesc) -> Check {
    use super::desc::SurfaceDesc;
    match m {
        SurfaceDesc::Principled(p) => {
            validate_color(path, "base_color", &p.base_color)?;
            in_range(
                &with(path, "roughness"),
                p.roughness,
                (0.0, true),
                (1.0, true),
            )?;
            in_range(
                &with(path, "metallic"),
                p.metallic,
                (0.0, true),
                (1.0, true),
            )?;
            in_range(&with(path, "ior"), p.ior, (1.0, true), (1000.0, true))?;
            in_range(
                &with(path, "specular_ior_level"),
                p.specular_ior_level,
                (0.0, true),
                (1.0, true),
            )?;
            non_negative3(&with(path, "specular_tint"), p.specular_tint)?;
            non_negative3(&with(path, "emission_color"), p.emission_color)?;
            non_negative(&with(path, "emission_strength"), p.emission_strength)
        }
        SurfaceDesc::Diffuse { color, roughness } => {
            validate_color(path, "color", color)?;
            in_range(
                &with(path, "roughness"),
                *roughness,
                (0.0, true),
                (1.0, true),
            )
        }
        SurfaceDesc::Emission { color, strength } => {
            validate_color(path, "color", color)?;
            non_negative(&with(path, "strength"), *strength)
        }
    }
}
