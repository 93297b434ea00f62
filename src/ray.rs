//! A ray with a time, as pbrt-v4's `Ray`: where it starts, where it goes
//! and when. Time is in frames from the frame being rendered (0 for a
//! still frame); moving volumes are looked up at it
//! (`crate::medium::motion`), so every flight, shadow ray and lookup of one
//! camera sample happens at the sample's time.

use glam::Vec3;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    pub o: Vec3,
    /// Direction (unit wherever distances along the ray are world units).
    pub d: Vec3,
    /// Frames from the frame being rendered.
    pub time: f32,
}

impl Ray {
    /// A ray at the frame's own time.
    #[inline]
    pub fn new(o: Vec3, d: Vec3) -> Self {
        Self { o, d, time: 0.0 }
    }

    /// A ray at `time`.
    #[inline]
    pub fn at_time(o: Vec3, d: Vec3, time: f32) -> Self {
        Self { o, d, time }
    }

    /// The point at distance `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }

    /// A ray from `o` towards `d` at this ray's time.
    #[inline]
    pub fn spawn(&self, o: Vec3, d: Vec3) -> Self {
        Self {
            o,
            d,
            time: self.time,
        }
    }
}
