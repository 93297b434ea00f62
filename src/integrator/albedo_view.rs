//! A diagnostic integrator: the image is the denoising albedo
//! ([`super::guide::along`]), what the denoiser is guided by, as Cycles'
//! Denoising Albedo pass shows it. For checking a guide against the beauty
//! image (`--integrator albedo`), and the smallest example of an
//! integrator: this file and one line in `registry!` (`super`) are all it
//! takes (ARCHITECTURE.md, "How to add an integrator").
//!
//! Not light transport: it ignores the lights. Its closed forms are those
//! of the albedo itself (an absorbing slab in front of a sky of radiance
//! 1 gives the slab's transmittance; a non-absorbing one gives 1), which
//! `tests/registry.rs` holds every registered integrator to.

use super::{Integrator, Registration, SampleKey, SampleResult};
use crate::ray::Ray;
use crate::sampling::{Domain, Rng};
use crate::world::World;

/// The albedo view in the registry: no settings of its own.
pub const REGISTRATION: Registration = Registration {
    name: "albedo",
    about:
        "diagnostic: the denoising albedo (the denoiser's guide) as the image, not light transport",
    keys: &[],
    check: |_| Ok(()),
    build: |_, world| Ok(Box::new(AlbedoView::new(world))),
    peak_bytes: |_| 0,
    header_keys: &[],
};

/// The denoising albedo of each camera ray as its radiance.
pub struct AlbedoView {
    step: f32,
}

impl AlbedoView {
    pub fn new(world: &World) -> Self {
        Self {
            step: super::guide::step(world),
        }
    }
}

impl Integrator for AlbedoView {
    fn name(&self) -> &'static str {
        REGISTRATION.name
    }

    fn li(&self, world: &World, ray: &Ray, _rng: &mut Rng, key: SampleKey) -> SampleResult {
        SampleResult {
            l: super::guide::along(world, ray, self.step, &mut key.rng(Domain::Guide)),
            transmittance: 0.0,
            ..Default::default()
        }
    }
}
