//! vdbphoton: a physically based renderer for OpenVDB volumes.
//!
//! See ARCHITECTURE.md for how the crate is cut: `vdb` (the OpenVDB bridge)
//! feeds `grid` (our sparse grid); `generate` makes procedural volumes.

pub mod atomic;
pub mod camera;
pub mod denoise;
pub mod error;
pub mod film;
pub mod frames;
pub mod generate;
pub mod grid;
pub mod image;
pub mod integrator;
pub mod interrupt;
pub mod light;
pub mod medium;
pub mod memory;
pub mod merge;
pub mod phase;
pub mod photon;
pub mod quicklook;
pub mod ray;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod sequence;
pub mod stats;
pub mod tracking;
pub mod vdb;
pub mod world;

pub use error::{Error, Result};

/// Linear RGB radiometric quantities (radiance, coefficients, colours).
pub type Rgb = glam::Vec3;
