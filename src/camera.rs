//! A pinhole camera, as Blender's perspective camera: a frame (right, up,
//! forward), the half-extents of the image plane at unit distance, and
//! Blender's lens shift.
//!
//! Blender's sensor fit decides which image side the sensor size spans
//! (`BKE_camera_params_compute_viewplane`): `horizontal` makes
//! `sensor_width` span the image width, `vertical` makes `sensor_height`
//! span the height, and `auto` makes `sensor_width` span the longer side.
//! Shift moves the image plane by a fraction of that fitted side. Pixels
//! are square.

use glam::{Vec2, Vec3};

pub use crate::scene::SensorFit;

/// The image plane at unit distance: half-extents and the shift of its
/// centre, in units of distance (tangents).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    pub tan_half_x: f32,
    pub tan_half_y: f32,
    pub shift_x: f32,
    pub shift_y: f32,
}

impl Plane {
    /// A vertical field of view in degrees (no shift).
    pub fn vfov(vfov_deg: f32, width: u32, height: u32) -> Self {
        let t = (vfov_deg.to_radians() * 0.5).tan();
        Self {
            tan_half_x: t * width as f32 / height as f32,
            tan_half_y: t,
            shift_x: 0.0,
            shift_y: 0.0,
        }
    }

    /// Blender's lens: focal length and sensor size in millimetres, sensor
    /// fit, and shift (a fraction of the fitted side).
    pub fn sensor(
        focal_length: f32,
        sensor: Vec2,
        fit: SensorFit,
        shift: Vec2,
        width: u32,
        height: u32,
    ) -> Self {
        let (w, h) = (width as f32, height as f32);
        let horizontal = match fit {
            SensorFit::Auto => w >= h,
            SensorFit::Horizontal => true,
            SensorFit::Vertical => false,
        };
        // Auto and horizontal fits use the sensor width, vertical the
        // height; `t` is half the fitted side at unit distance.
        let size = if fit == SensorFit::Vertical {
            sensor.y
        } else {
            sensor.x
        };
        let t = 0.5 * size / focal_length;
        let (tan_half_x, tan_half_y) = if horizontal {
            (t, t * h / w)
        } else {
            (t * w / h, t)
        };
        let fitted = 2.0 * t;
        Self {
            tan_half_x,
            tan_half_y,
            shift_x: shift.x * fitted,
            shift_y: shift.y * fitted,
        }
    }
}

/// When the shutter is open, in frames from the frame being rendered
/// (pbrt-v4's `shutterOpen`, `shutterClose`; Blender's motion blur
/// Shutter and Position). Camera samples are spread uniformly over it, as
/// Blender's default shutter curve does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shutter {
    pub open: f32,
    pub close: f32,
}

impl Shutter {
    /// The time at `u` ∈ [0, 1) of the way through the shutter.
    #[inline]
    pub fn time(&self, u: f32) -> f32 {
        self.open + u * (self.close - self.open)
    }

    /// The largest time from the frame the shutter reaches, either way.
    pub fn max_time(&self) -> f32 {
        self.open.abs().max(self.close.abs())
    }
}

#[derive(Debug, Clone, Copy)]
pub struct Camera {
    position: Vec3,
    /// Camera frame: right, up, forward (unit, orthogonal).
    right: Vec3,
    up: Vec3,
    forward: Vec3,
    plane: Plane,
    width: u32,
    height: u32,
    /// Open over these times (motion blur); `None`: the frame's instant.
    shutter: Option<Shutter>,
}

impl Camera {
    /// A camera at `position` looking at `look_at` with a vertical field of
    /// view. `up` need not be orthogonal to the view direction, only not
    /// parallel.
    pub fn new(
        position: Vec3,
        look_at: Vec3,
        up: Vec3,
        vfov_deg: f32,
        width: u32,
        height: u32,
    ) -> Self {
        let forward = (look_at - position).normalize();
        Self::with_frame(
            position,
            forward,
            up,
            Plane::vfov(vfov_deg, width, height),
            width,
            height,
        )
    }

    /// A camera looking along `forward` with `up` (not parallel to it)
    /// giving the image's upward direction, and image plane `plane`.
    pub fn with_frame(
        position: Vec3,
        forward: Vec3,
        up: Vec3,
        plane: Plane,
        width: u32,
        height: u32,
    ) -> Self {
        let forward = forward.normalize();
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        Self {
            position,
            right,
            up,
            forward,
            plane,
            width,
            height,
            shutter: None,
        }
    }

    /// The camera with its shutter open over `shutter` (motion blur).
    pub fn with_shutter(self, shutter: Option<Shutter>) -> Self {
        Self { shutter, ..self }
    }

    /// The shutter, when the camera blurs motion.
    pub fn shutter(&self) -> Option<Shutter> {
        self.shutter
    }

    pub fn position(&self) -> Vec3 {
        self.position
    }

    /// The unit view direction (through the image centre without shift).
    pub fn forward(&self) -> Vec3 {
        self.forward
    }

    /// The image plane.
    pub fn plane(&self) -> Plane {
        self.plane
    }

    /// The angle one pixel subtends at the image centre, radians (small
    /// angles; pixels are square).
    pub fn pixel_angle(&self) -> f32 {
        2.0 * self.plane.tan_half_y / self.height as f32
    }

    /// Image width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The unit direction through film position `film` in pixels (x right,
    /// y down, (0,0) the top-left corner of the top-left pixel).
    pub fn direction(&self, film: Vec2) -> Vec3 {
        let p = &self.plane;
        let sx = (2.0 * film.x / self.width as f32 - 1.0) * p.tan_half_x + p.shift_x;
        let sy = (1.0 - 2.0 * film.y / self.height as f32) * p.tan_half_y + p.shift_y;
        (self.forward + self.right * sx + self.up * sy).normalize()
    }

    /// The film position (pixels) where the point `p` appears, if it is in
    /// front of the camera: the inverse of [`Camera::direction`].
    pub fn project(&self, p: Vec3) -> Option<Vec2> {
        let d = p - self.position;
        let z = d.dot(self.forward);
        if z <= 0.0 {
            return None;
        }
        let pl = &self.plane;
        let sx = d.dot(self.right) / z;
        let sy = d.dot(self.up) / z;
        Some(Vec2::new(
            ((sx - pl.shift_x) / pl.tan_half_x + 1.0) * 0.5 * self.width as f32,
            (1.0 - (sy - pl.shift_y) / pl.tan_half_y) * 0.5 * self.height as f32,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sensor_fit_spans_the_side_blender_says() {
        let s = Vec2::new(36.0, 24.0);
        // Landscape, auto = horizontal: 36 mm across the width.
        let p = Plane::sensor(50.0, s, SensorFit::Auto, Vec2::ZERO, 160, 90);
        assert!((p.tan_half_x - 0.36).abs() < 1e-6);
        assert!((p.tan_half_y - 0.36 * 90.0 / 160.0).abs() < 1e-6);
        // Portrait, auto: the sensor width spans the height.
        let p = Plane::sensor(50.0, s, SensorFit::Auto, Vec2::ZERO, 90, 160);
        assert!((p.tan_half_y - 0.36).abs() < 1e-6);
        // Vertical: the sensor height spans the height.
        let p = Plane::sensor(50.0, s, SensorFit::Vertical, Vec2::ZERO, 160, 90);
        assert!((p.tan_half_y - 0.24).abs() < 1e-6);
        // Horizontal on a portrait image: the width still gets 36 mm.
        let p = Plane::sensor(50.0, s, SensorFit::Horizontal, Vec2::new(0.1, 0.0), 90, 160);
        assert!((p.tan_half_x - 0.36).abs() < 1e-6);
        assert!((p.shift_x - 0.1 * 0.72).abs() < 1e-6);
    }

    #[test]
    fn project_inverts_direction() {
        let plane = Plane::sensor(
            35.0,
            Vec2::new(36.0, 24.0),
            SensorFit::Auto,
            Vec2::new(0.1, -0.05),
            64,
            48,
        );
        let c = Camera::with_frame(
            Vec3::new(1.0, -4.0, 0.5),
            Vec3::new(-0.2, 1.0, -0.1),
            Vec3::Z,
            plane,
            64,
            48,
        );
        for f in [
            Vec2::new(0.0, 0.0),
            Vec2::new(31.5, 20.25),
            Vec2::new(64.0, 48.0),
        ] {
            let p = c.position() + c.direction(f) * 3.0;
            assert!((c.project(p).unwrap() - f).length() < 1e-3);
        }
    }
}
