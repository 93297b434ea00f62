//! vdbphoton: a physically based renderer for OpenVDB volumes.
//!
//! See ARCHITECTURE.md for how the crate is cut: `vdb` (the OpenVDB bridge)
//! feeds `grid` (our sparse grid); `generate` makes procedural volumes.

pub mod error;
pub mod generate;
pub mod grid;
pub mod vdb;

pub use error::{Error, Result};
