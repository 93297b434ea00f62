//! vdbphoton: a physically based renderer for OpenVDB volumes.
//!
//! See ARCHITECTURE.md for how the crate is cut and the layer order its
//! modules keep (checked by `tests/layers.rs`); the `vdbphoton` binary
//! (`src/bin/vdbphoton`) only parses and prints.

pub mod atomic;
pub mod bsdf;
pub mod camera;
pub mod denoise;
pub mod error;
pub mod export;
pub mod film;
pub mod frames;
pub mod generate;
pub mod grid;
pub mod image;
pub mod inspect;
pub mod integrator;
pub mod interrupt;
pub mod light;
pub mod medium;
pub mod memory;
pub mod merge;
pub mod mesh;
pub mod phase;
pub mod photon;
pub mod quicklook;
pub mod ray;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod sequence;
pub mod shape;
pub mod stats;
pub mod tracking;
pub mod units;
pub mod vdb;
pub mod world;

pub use error::{Error, Result};

/// Linear RGB radiometric quantities (radiance, coefficients, colours).
pub type Rgb = glam::Vec3;
