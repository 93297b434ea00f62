//! A pinhole camera with a vertical field of view, as Blender's with sensor
//! fit "vertical".

use glam::{Vec2, Vec3};

#[derive(Debug, Clone, Copy)]
pub struct Camera {
    position: Vec3,
    /// Camera frame: right, up, forward (unit).
    right: Vec3,
    up: Vec3,
    forward: Vec3,
    /// tan(vfov / 2).
    tan_half: f32,
    width: u32,
    height: u32,
}

impl Camera {
    /// `up` need not be orthogonal to the view direction, only not parallel.
    pub fn new(
        position: Vec3,
        look_at: Vec3,
        up: Vec3,
        vfov_deg: f32,
        width: u32,
        height: u32,
    ) -> Self {
        let forward = (look_at - position).normalize();
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        Self {
            position,
            right,
            up,
            forward,
            tan_half: (vfov_deg.to_radians() * 0.5).tan(),
            width,
            height,
        }
    }

    pub fn position(&self) -> Vec3 {
        self.position
    }

    /// The angle one pixel subtends at the image centre, radians (small
    /// angles: 2·tan(vfov/2) / height).
    pub fn pixel_angle(&self) -> f32 {
        2.0 * self.tan_half / self.height as f32
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
        let aspect = self.width as f32 / self.height as f32;
        let sx = (2.0 * film.x / self.width as f32 - 1.0) * self.tan_half * aspect;
        let sy = (1.0 - 2.0 * film.y / self.height as f32) * self.tan_half;
        (self.forward + self.right * sx + self.up * sy).normalize()
    }
}
