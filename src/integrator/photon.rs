//! The photon integrator: volumetric photon mapping (Jensen & Christensen
//! 1998) with a ray marcher, progressive over passes (Knaus & Zwicker 2011).
//!
//! Each pass traces a fresh photon map (`crate::photon`), then every
//! camera ray marches the volumes:
//! - steps of at most `step` (the finest voxel by default) and at most half
//!   an optical depth of the majorant, with one jitter per ray (stratified
//!   midpoints); stretches the majorant grid marks empty of both extinction
//!   and emission are skipped;
//! - each step i of length Δ with σt at its point contributes its source S
//!   (per unit length) as T_i·S·(1 − e^{−σtΔ})/σt, T_i the transmittance to
//!   the step: emission, single scattering, multiple scattering;
//! - single scattering σs·∫p·L_light is computed at one or two steps
//!   chosen (stratified) in proportion to T·σs·(1 − e^{−σtΔ})/σt, by
//!   next-event estimation to every light with ratio-tracked transmittance:
//!   unbiased for the march's sum at the cost of a shadow ray per light and
//!   sample instead of one per step;
//! - multiple scattering comes from the photons, which carry only light that
//!   has scattered at least once: with the beam estimate one BVH traversal
//!   along the marched part of the ray, with the point estimate a k-nearest
//!   query at every step;
//! - a constant environment's light, by default ([`Sky::Auto`]), comes from a
//!   camera path instead (`super::path::trace_from`, the environment
//!   alone, from the camera ray's first scattering on), at every sample or
//!   at a share of them ([`Tuning::sky_paths`]); photons then come from the
//!   lights and the glowing media only, and the march's single scattering
//!   samples the lights only. Under a diffuse sky a path escapes to it as
//!   soon as it leaves the volumes, a near-furnace case where its variance
//!   is small, while a photon map's estimate keeps its kernels' noise: the
//!   estimators split the light by source, each taking what it is good at;
//! - the march ends with Russian roulette once the transmittance is small.
//!
//! Progressive: pass i (from 1) shrinks the photons' radii by
//! i^((α−1)/2) (beams, a 2-D kernel) or the search radius by i^((α−1)/3)
//! (points), so the image, the mean over passes, converges to the
//! path-traced answer; memory is that of one pass. `k`, α and the light
//! samples suit dense and thin media differently and, unless the scene
//! gives them, come from the pilot's scattering order ([`Tuning`]).
//!
//! Photons per pass are kept to about `photons` stored ones: in dense media
//! a photon scatters hundreds of times, and the probability of storing a
//! collision (its power divided by it) comes from the previous pass's count
//! (from a pilot of 1/32 of the photons before the first pass), so the map
//! stays the same size and the image stays deterministic.

use super::nee::{direct_light, EnvLight, Sources};
use super::{param, Integrator, SampleKey, SampleResult};
use crate::photon::beam::{flatten, BeamMap, RATIO_MAX};
use crate::photon::emitter::Emitters;
use crate::photon::importance::Importance;
use crate::photon::map::{density_radii, median, PointMap};
use crate::photon::{self, Photon};
use crate::ray::Ray;
use crate::sampling::{radical_inverse_2, roulette, Domain, Rng};
use crate::shape::{Hit, RayKind};
use crate::scene::{Params, SceneDesc, ValidationError};
use crate::world::World;
use crate::Rgb;
use glam::Vec3;
use std::cell::RefCell;

/// Which photon estimate the camera rays use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Estimate {
    /// The beam radiance estimate (Jarosz, Zwicker & Jensen 2008): every
    /// photon's sphere the camera ray crosses, found by one BVH traversal.
    #[default]
    Beam,
    /// The point estimate at each step of the march: the k nearest photons,
    /// Σ p·Φ / (4/3·π·r³) (Jensen & Christensen 1998).
    Point,
}

impl Estimate {
    /// The spelling used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Estimate::Beam => "beam",
            Estimate::Point => "point",
        }
    }
}

/// Settings of the photon integrator (its table `[render.photon]`), with
/// their defaults.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhotonSettings {
    /// Photons emitted per pass (`photons`); `None`: [`auto_photons`] of
    /// the frame.
    pub photons: Option<u32>,
    /// Neighbours that set a photon's radius (`k`); `None`: chosen from the
    /// pilot ([`Tuning::automatic`]).
    pub k: Option<u32>,
    /// Largest radius in the first pass, world units (`radius`); `None`:
    /// automatic from the photon density.
    pub radius: Option<f32>,
    /// Knaus & Zwicker's α in (0, 1] (`alpha`): radii shrink as
    /// i^((α − 1)/3) for points and i^((α − 1)/2) for beams over passes i;
    /// `None`: chosen from the pilot ([`Tuning::automatic`]).
    pub alpha: Option<f32>,
    /// Length of a step of the camera-ray march, world units (`step`);
    /// `None`: the finest voxel of the volumes.
    pub step: Option<f32>,
    /// The photon estimate (`estimate`).
    pub estimate: Estimate,
    /// Who carries the environment's light (`sky`).
    pub sky: Sky,
}

/// Who carries the environment's light in the photon integrator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sky {
    /// [`Sky::Paths`] for a constant environment, [`Sky::Photons`] for a
    /// map: a map's bright spots are small lights, which photons carry well
    /// (measured only for constant skies: docs/performance.md, "Sky light
    /// by paths").
    Auto,
    /// Camera paths, as the path tracer traces them but taking the
    /// environment's light alone (`path::trace_from`), at a share of the
    /// camera samples ([`Tuning::sky_paths`]); photons come from the lights
    /// and the media only.
    Paths,
    /// Photons, as every other source.
    Photons,
}

impl Default for PhotonSettings {
    fn default() -> Self {
        Self {
            photons: None,
            k: None,
            radius: None,
            alpha: None,
            step: None,
            estimate: Estimate::Beam,
            sky: Sky::Auto,
        }
    }
}

/// Most photons a pass may emit: 2^28 (a pass's photon map then takes tens
/// of GiB; the render checks what the machine has before it starts).
pub const MAX_PHOTONS: u32 = 1 << 28;

/// Bytes a stored photon takes at the peak of a pass (the photon, its
/// radius, its box while the BVH is built, the BVH and the reordered copy;
/// `cargo bench --bench photon` measured 128 bytes after the build).
pub const PHOTON_PEAK_BYTES: u64 = 220;

impl PhotonSettings {
    /// The settings of a `[render.photon]` table, checked.
    pub fn from_params(p: &Params) -> Result<Self, ValidationError> {
        let d = PhotonSettings::default();
        Ok(PhotonSettings {
            photons: param::int(p, "photons", 1, MAX_PHOTONS as i64)
                .map_err(|mut e| {
                    e.message = format!(
                        "{} (photons per pass; each takes about 100 bytes)",
                        e.message
                    );
                    e
                })?
                .map(|n| n as u32),
            k: param::int(p, "k", 1, 1024)?.map(|k| k as u32),
            radius: param::number(p, "radius", 0.0, f32::MAX as f64)?.map(|r| r as f32),
            alpha: param::number(p, "alpha", 0.0, 1.0)?.map(|a| a as f32),
            step: param::number(p, "step", 0.0, f32::MAX as f64)?.map(|s| s as f32),
            estimate: match param::choice(p, "estimate", &["beam", "point"])? {
                None => d.estimate,
                Some("point") => Estimate::Point,
                Some(_) => Estimate::Beam,
            },
            sky: match param::choice(p, "sky", &["auto", "paths", "photons"])? {
                None => d.sky,
                Some("photons") => Sky::Photons,
                Some("paths") => Sky::Paths,
                Some(_) => Sky::Auto,
            },
        })
    }

    /// The photon settings of a scene (defaults where it gives none).
    /// Call on a checked scene (`super::check_settings`).
    pub fn of(desc: &SceneDesc) -> crate::error::Result<Self> {
        Self::from_params(&super::settings(desc, REGISTRATION.name))
            .map_err(|e| crate::error::Error::Scene(format!("[render.photon] {e}")))
    }
}

/// The photon integrator in the registry.
pub const REGISTRATION: super::Registration = super::Registration {
    name: "photon",
    about: "volumetric photon mapping with a ray marcher, progressive over passes (dense, bright media)",
    keys: &[
        ("photons", "photons emitted per pass (default: half a photon per pixel, at least 10,000)"),
        ("k", "neighbours that set a photon's radius (default: from the pilot)"),
        ("radius", "largest radius in the first pass, world units (default: from the photon density)"),
        ("alpha", "progressive radius reduction, in (0, 1] (default: from the pilot)"),
        ("step", "march step, world units (default: the finest voxel)"),
        ("estimate", "\"beam\" (default) or \"point\""),
        ("sky", "who carries the environment's light: \"auto\" (default: paths for a constant sky, photons for a map), \"paths\" (camera paths; photons from the lights and fire only) or \"photons\""),
    ],
    check: |p| PhotonSettings::from_params(p).map(|_| ()),
    build: |desc, world| {
        let r = &desc.render;
        Ok(Box::new(PhotonIntegrator::new(
            world,
            PhotonSettings::of(desc)?,
            r.max_bounces,
            r.seed,
        )?))
    },
    peak_bytes: |desc| {
        let r = &desc.render;
        PhotonSettings::of(desc).map_or(0, |s| {
            let n = match s.photons {
                Some(n) => n,
                // The count the passes may grow to (the tuning that grows
                // it is chosen later, by the pilot).
                None => max_photons_in_pass(auto_photons(r.width, r.height)),
            };
            n as u64 * PHOTON_PEAK_BYTES
        })
    },
    header_keys: &[
        "vdbphoton/photons_per_pass",
        "vdbphoton/k",
        "vdbphoton/alpha",
        "vdbphoton/estimate",
        "vdbphoton/step",
        "vdbphoton/sky_paths",
    ],
};

/// Photons per pass for a `width` x `height` frame when the scene gives
/// none: half a photon per pixel of the whole frame (also for a tile, so
/// that a tile's pixels are those of the full render), at least 10,000.
///
/// A pass costs camera rays in proportion to the pixels and photon
/// tracing in proportion to the photons; the error at equal time is
/// lowest when both grow together. Measured at 30 s on two threads
/// (relMSE against the ground truths of `cargo bench --bench
/// equal_time`; docs/performance.md): at 256 x 192 the dense cloud gave
/// 1.49e-3 with 25,000 photons a pass and 1.68e-3 with 50,000, the
/// reference cloud 7.0e-5 with 25,000 and 6.7e-5 with 100,000; at 512 x
/// 384 (box-filtered to 256 x 192 for the comparison) 100,000 beat 25,000
/// on both, 1.92e-3 against 2.25e-3 and 7.6e-5 against 1.06e-4.
pub fn auto_photons(width: u32, height: u32) -> u32 {
    ((width as u64 * height as u64).div_ceil(2).max(10_000)).min(MAX_AUTO_PHOTONS as u64) as u32
}

/// The most photons a pass gets without asking (a 4K frame's half a
/// photon per pixel).
const MAX_AUTO_PHOTONS: u32 = 1 << 22;

/// Photons per pass for a `width` x `height` frame: the settings' `photons`,
/// or [`auto_photons`].
pub fn photons_for(settings: &PhotonSettings, width: u32, height: u32) -> u32 {
    settings
        .photons
        .unwrap_or_else(|| auto_photons(width, height))
}

/// Photons emitted in pass `pass` (0-based) when the count is automatic:
/// `base` for the first [`GROW_FROM`] passes, then `base` times
/// ((pass + 1) / GROW_FROM)^`growth`, at most [`max_photons_in_pass`].
///
/// Why grow: a pass's beam estimate gathers about the same number of
/// photons along a ray whatever their count (the radii are set by the
/// k nearest), so its variance hardly depends on the count, while its
/// bias falls with the radius, r² ∝ N^(−2/3). The mean of P passes has a
/// variance ∝ 1/P and keeps the bias, so past a few hundred passes the
/// bias is what is left, and more photons a pass lower it where shrinking
/// the radii (`alpha`) would raise each pass's variance instead. The bias
/// and the variance of the mean fall together for N ∝ P^(3/4); √P grows
/// more gently and measured as well. On the dense cloud under a sun
/// (`benches/scenes/dense_sun.toml`, 160 x 120, 2 threads, `cargo bench
/// --bench equal_time`, seeds 7 and 8; docs/performance.md) at 120 s:
/// 10,000 photons in every pass 5.36e-4, growing as √P 4.51e-4 and
/// 4.28e-4, as P^(3/4) 4.47e-4 and 4.53e-4, 25,000 in every pass 4.21e-4
/// and 4.37e-4, the path tracer 4.31e-4 and 4.42e-4; α = 0.8 instead of
/// 0.9 5.51e-4. At 10 s (about 250 passes) the count does not grow, so
/// short renders keep their passes. On the Blender smoke + fire frame
/// (`smoke_fire.toml`, thin: 1,300 passes in 30 s, where photons are
/// cheap beside the camera rays), seed 7, fixed against growing as √P:
/// 1.20e-5 and 1.14e-5 at 10 s, 7.64e-6 and 5.70e-6 at 30 s, 4.55e-6 and
/// 3.56e-6 at 120 s (the path tracer 2.90e-5, 1.11e-5, 4.19e-6).
pub fn photons_in_pass(base: u32, pass: u32, growth: f32) -> u32 {
    let f = ((pass as f32 + 1.0) / GROW_FROM as f32).max(1.0).powf(growth);
    // (A float-to-integer cast saturates.)
    ((base as f64 * f as f64) as u32).clamp(base, max_photons_in_pass(base))
}

/// The most photons [`photons_in_pass`] gives a pass of `base` photons,
/// whatever the growth: [`MAX_GROWTH`] times `base`, but no more than
/// [`MAX_AUTO_PHOTONS`] (a 4K frame's half a photon per pixel, which does
/// not grow), since a pass's memory is its photons.
pub fn max_photons_in_pass(base: u32) -> u32 {
    (base as u64 * MAX_GROWTH as u64).min(MAX_AUTO_PHOTONS.max(base) as u64) as u32
}

/// The exponent with which the automatic photon count grows with the
/// passes ([`photons_in_pass`]), in dense and thin media alike.
const PHOTON_GROWTH: f32 = 0.5;

/// Passes before the automatic photon count grows ([`photons_in_pass`]).
const GROW_FROM: u32 = 256;

/// The most an automatic photon count grows.
const MAX_GROWTH: u32 = 8;

/// Settings a render uses that suit dense and thin media differently:
/// `k` and `alpha` as the scene gives them or, when absent, as
/// [`Tuning::automatic`] chooses; the light samples a camera ray takes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tuning {
    pub k: u32,
    pub alpha: f32,
    /// Steps of a camera ray that get next-event estimation, stratified
    /// over the march's single-scattering weights.
    pub light_samples: u32,
    /// How far the beam estimate flattens a kernel along the gradient of
    /// σs at most (`crate::photon::beam::flatten`; 1: spheres).
    pub max_squash: f32,
    /// The share of camera samples that trace a path for the environment's
    /// light ([`Sky::Paths`]), each weighted by its inverse. Below 1 the
    /// choice itself adds variance (a one-sample estimate of a part of the
    /// image that a path gives with little noise), so it pays only where
    /// paths are long and photons cheap by comparison.
    pub sky_paths: f32,
    /// The mean cosine of the first pass's angular kernel over the photons'
    /// directions ([`angular_kernel`]; 1: none).
    pub angular: f32,
}

impl Tuning {
    /// Optically thin or dark media: the photon map's error is mostly its
    /// bias, so radii start small and shrink fast. Two light samples: more
    /// cut a pass's single-scattering variance (on the reference cloud
    /// 5.7e-5 with one, 4.6e-6 with eight), but a shadow ray is not cheap
    /// and more passes lower the error more (at 30 s two samples gave
    /// relMSE 7.0e-5 there, eight 8.0e-5).
    pub const THIN: Tuning = Tuning {
        k: 32,
        alpha: 2.0 / 3.0,
        light_samples: 2,
        max_squash: 1.0,
        // Half the samples: relMSE 2-3 times as high at 10 s on the
        // equal-time bench's thin clouds under a sun and a sky.
        sky_paths: 1.0,
        // The error there is the bias; a blur over directions would add
        // to it.
        angular: 1.0,
    };
    /// Dense, bright media, where a photon scatters many times: the map's
    /// error is mostly its noise (the phase function weighs the few photons
    /// travelling towards the camera far above the rest), so fewer
    /// neighbours set the first radii and they shrink slowly; and single
    /// scattering is a small, quiet part of the image (on the dense
    /// reference cloud its variance is a sixtieth of the photons'), so one
    /// light sample.
    ///
    /// Kernels flattened to half their radius along the gradient of σs:
    /// the camera sees only the outer mean free path of such a cloud, and
    /// spheres there reach out of it. On the dense cloud under a sun
    /// (benches/scenes/dense_sun.toml, 2 threads, seeds 7 and 8; the bias
    /// and variance split as in docs/performance.md) the multiple
    /// scattering came out 4 % dark with spheres; at 30 s relMSE 1.43e-3
    /// (its bias² 6.3e-4), image mean 0.988; flattened at most 2x: 1.18e-3
    /// (bias² 2.4e-4), mean 0.997; at most 4x or 8x: 1.35e-3 and 1.36e-3,
    /// too bright at the silhouette. At 120 s, 7.5e-4 against 5.6e-4.
    pub const DENSE: Tuning = Tuning {
        k: 16,
        alpha: 0.9,
        light_samples: 1,
        max_squash: 2.0,
        // dense_sun at 10 s (2 threads, seeds 7 and 8): relMSE 1.35e-3
        // with every sample, 1.16e-3 with half, 1.28e-3 and 1.41e-3 with
        // 0.35 and 0.25 (photons carrying the sky: 2.30e-3).
        sky_paths: 0.5,
        // See `angular_kernel`.
        angular: 0.75,
    };

    /// The tuning for media where a photon that scatters scatters on
    /// average `order` times (measured by the pilot): [`Self::DENSE`] from
    /// [`DENSE_ORDER`] on, [`Self::THIN`] below.
    ///
    /// Measured on the equal-time bench's clouds (docs/performance.md): on
    /// the dense one (albedo 0.999, g = 0.8; order 61) k = 16, α = 0.9 gave
    /// a relMSE of 1.21e-3 after 200 passes against 1.56e-3 with k = 32,
    /// α = 2/3, at about the same image mean after 65 passes (0.991), and
    /// one light sample instead of two cut the 30 s error by 4.5 % more; on
    /// the reference cloud (albedo 0.91; order 4.4) k = 16, α = 0.9 gave
    /// 8.8e-5 after 2,223 passes against 4.6e-5, the error there being the
    /// bias.
    pub fn automatic(order: f64) -> Tuning {
        if order >= DENSE_ORDER {
            Self::DENSE
        } else {
            Self::THIN
        }
    }

    /// The settings' `k` and `alpha`, each automatic when absent.
    pub fn of(settings: &PhotonSettings, order: f64) -> Tuning {
        let auto = Self::automatic(order);
        Tuning {
            k: settings.k.unwrap_or(auto.k),
            alpha: settings.alpha.unwrap_or(auto.alpha),
            ..auto
        }
    }
}

/// Mean scattering events per scattered photon from which media count as
/// dense for [`Tuning::automatic`].
pub const DENSE_ORDER: f64 = 10.0;

/// Largest optical depth of the majorant over one march step.
const MAX_STEP_TAU: f32 = 0.5;

/// Steps per voxel at most, whatever the majorant: where the majorant is
/// huge but the density falls away (a cloud's fringe), half an optical
/// depth of the majorant per step would cost millions of steps in space
/// the light crosses freely; with σ = 4·10^5 per unit on the reference
/// cloud a 16 x 12 pass took 84 s. Steps this short are exact enough
/// wherever the light gets through.
const MAX_STEPS_PER_VOXEL: f32 = 16.0;

/// The cap on the σs ratio of the beam estimate in pass `pass` (0-based):
/// [`RATIO_MAX`] times √(pass + 1).
///
/// The cap keeps a photon stored in a cloud's thin fringe from becoming a
/// firefly where its kernel reaches a dense core, but the light it cuts is
/// lost: with a constant cap of 16 the Houdini pyro under a sun
/// (benches/scenes/pyro_sun.toml) came out 0.8 % dark at 10 s and 0.6 %
/// at 30 s, the Blender smoke + fire frame 0.3 %. Growing as √(pass + 1),
/// a firefly of pass i weighs at most 16/√N in the mean of N passes, so
/// the image still converges, and the cut light goes to zero. Measured
/// with `cargo bench --bench equal_time` (relMSE at 10 s and 30 s on two
/// threads; docs/performance.md): the pyro 3.2e-4 and 1.6e-4 with the
/// constant cap, 2.5e-4 and 1.1e-4 growing as √(pass + 1), 3.2e-4 and
/// 1.1e-4 as (pass + 1), 4.3e-4 and 1.4e-4 with no cap (the fireflies);
/// the smoke + fire frame within noise of the constant cap (1.7e-5 and
/// 1.0e-5, against 1.6e-5 and 9.2e-6), its mean 0.2 % from the
/// reference instead of 0.3 %.
fn ratio_max(pass: u32) -> f32 {
    RATIO_MAX * ((pass + 1) as f32).sqrt()
}

/// The mean cosine of the angular kernel that blurs the photons' directions
/// in pass `pass` (0-based), starting from `first`: 1 − (1 − first)·(pass +
/// 1)^(−1/4), rising to 1 (no blur), so that the estimate stays consistent
/// as the radii's shrinking keeps it.
///
/// Why blur directions: in a dense cloud of forward-scattering particles
/// (HG g = 0.8) the phase function weighs the few photons travelling
/// towards the camera far above the rest (a factor of 729 across HG(0.8)),
/// and that, more than their number, makes a pass's estimate noisy
/// (docs/performance.md, "Where the dense cloud's error comes from" and
/// "The dense target against a quieter reference"). Blurring each photon's
/// direction by an HG kernel of mean cosine s is, for HG media, evaluating
/// HG(g·s) instead of HG(g) ([`crate::phase::PhaseFunction::blurred`]): an angular
/// kernel density estimate beside the spatial one. Measured on the
/// equal-time bench's dense cloud under a sun (2 threads, 30 s, seeds 7
/// and 8, against 16,384-spp path-traced halves; relMSE less the
/// reference's noise, then the variance and bias² of one render): without
/// the blur 3.66e-4 (2.90e-4, 7.8e-5); from 0.75, 3.16e-4 (2.24e-4,
/// 9.3e-5); from 0.5, 3.15e-4 (1.78e-4, 1.37e-4), more of it bias. Only
/// dense media blur ([`Tuning::DENSE`]): where the error is the bias, a
/// blur would add to it.
pub fn angular_kernel(first: f32, pass: u32) -> f32 {
    if first >= 1.0 {
        return 1.0;
    }
    1.0 - (1.0 - first) * ((pass + 1) as f32).powf(-0.25)
}

/// The march plays Russian roulette once the transmittance is below this.
const MARCH_RR: f32 = 0.02;

/// Photons stored per photon emitted, on average, in a pass.
const STORED_PER_EMITTED: f32 = 1.0;

/// A pass's photon map, for the estimate in use.
enum Map {
    Beam(BeamMap),
    Point(PointMap),
}

/// One step of a camera ray's march.
#[derive(Debug, Clone, Copy)]
struct MarchStep {
    /// Start of the step along the ray, and its length.
    t0: f32,
    dt: f32,
    /// Transmittance from the camera to the step's start.
    tr: Rgb,
    sigma_t: Rgb,
    sigma_s: Rgb,
    /// ∫ transmittance over the step: T·(1 − e^{−σtΔ})/σt per channel.
    w: Rgb,
    /// Where the optics were looked up.
    p: Vec3,
}

thread_local! {
    static STEPS: RefCell<Vec<MarchStep>> = const { RefCell::new(Vec::new()) };
}

#[inline]
fn luminance(c: Rgb) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// What the passes so far did.
#[derive(Debug, Clone, Copy, Default)]
pub struct PhotonTotals {
    pub passes: u32,
    pub emitted: u64,
    pub stored: u64,
    /// Photons in the last pass's map.
    pub last_stored: u64,
    /// Largest photon radius of the first pass (world units).
    pub r_max: f32,
}

/// Volumetric photon mapping with a ray marcher; see the module docs.
pub struct PhotonIntegrator {
    settings: PhotonSettings,
    /// Photons emitted per pass (the setting, or half a photon per pixel).
    photons: u32,
    max_bounces: u32,
    seed: u64,
    emitters: Option<Emitters>,
    /// What camera paths take of the environment's light when they carry
    /// it ([`Sky::Paths`] with an environment that shines): a constant one
    /// found by escaping rays alone, a map also sampled.
    sky_paths: Option<Sources>,
    step: f32,
    /// The shortest step (the finest voxel over MAX_STEPS_PER_VOXEL).
    min_step: f32,
    /// The first pass's largest radius (automatic or `radius`).
    r_max: Option<f32>,
    /// Scale of the probability of storing a collision in the next pass.
    store: Option<f32>,
    /// Where the camera sees (scales the storage probability).
    importance: Option<Importance>,
    map: Option<Map>,
    /// The point estimate's search radius in this pass.
    search_radius: f32,
    /// The media's mean scattering order, from the pilot.
    order: f64,
    /// `k`, `alpha` and light samples in use (automatic ones chosen after
    /// the pilot).
    tuning: Tuning,
    totals: PhotonTotals,
    /// The time of this pass's photons and camera rays (motion blur; 0 for
    /// a still frame): see [`pass_time`].
    time: f32,
}

/// What a short photon trace measures of a world's light and media, for
/// `auto` (`crate::render::choose_integrator`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pilot {
    /// Mean scattering events of a photon that scatters at least once.
    pub order: f64,
    /// The share of the emitted power that comes from the media (fire).
    pub media_share: f32,
    /// The share that comes from the environment (sky light).
    pub environment_share: f32,
    /// The share of the photons that scatter at least once.
    pub scattering: f64,
    /// The share of the photons the media emit that scatter at least once.
    pub media_scattering: f64,
}

/// Photons of [`pilot`]: enough for the mean scattering order to within a
/// few per cent, a few milliseconds in thin media, 0.1 s in the dense
/// cloud (where a photon scatters 60 times).
pub const PILOT_PHOTONS: u32 = 4096;

/// Traces [`PILOT_PHOTONS`] photons of `world` (their own stream of the
/// seed, at the first pass's time) and measures what `auto` decides by;
/// `None` when nothing emits towards the volumes.
pub fn pilot(world: &World, max_bounces: u32, seed: u64) -> Option<Pilot> {
    let emitters = Emitters::new(world)?;
    let time = pass_time(world, seed, 0);
    let st = measure(
        world,
        &emitters,
        PILOT_PHOTONS,
        (seed, u32::MAX - 1),
        time,
        max_bounces,
        None,
    );
    let (media_share, environment_share) = emitters.shares();
    Some(Pilot {
        order: st.order(),
        media_share,
        environment_share,
        scattering: st.scattered as f64 / st.emitted.max(1) as f64,
        media_scattering: st.media_scattered as f64 / st.media_emitted.max(1) as f64,
    })
}

/// Traces `n` photons in the stream `(seed, stream)` at `time` and keeps
/// none: what their flights met (what storing every collision would keep,
/// weighted by `importance`; the scattering order). Both pilots use it:
/// the integrator's before its first pass and `auto`'s ([`pilot`]).
fn measure(
    world: &World,
    emitters: &Emitters,
    n: u32,
    (seed, stream): (u64, u32),
    time: f32,
    max_bounces: u32,
    importance: Option<&Importance>,
) -> photon::TraceStats {
    let none = photon::Store {
        scale: 0.0,
        importance,
    };
    photon::trace(world, emitters, n, seed, stream, time, max_bounces, none).1
}

/// The time within `world`'s shutter at which pass `pass` renders
/// everything: its photons and every camera ray. A photon map is the light
/// of one instant, so a camera ray must gather from a map of its own time
/// (else the moving medium's σs and the map's light disagree: a biased
/// estimate); the mean over passes converges to the blurred image.
/// Passes are stratified over the shutter by the base-2 radical inverse
/// of the pass, rotated by the seed (Cranley–Patterson), so any 2^m
/// passes from the first cover it evenly.
pub fn pass_time(world: &World, seed: u64, pass: u32) -> f32 {
    let Some(shutter) = world.camera.shutter() else {
        return 0.0;
    };
    let offset = Rng::new(Domain::Time, seed, u64::MAX, 0).next_f32();
    let u = radical_inverse_2(pass) + offset;
    shutter.time(u - u.floor())
}

impl PhotonIntegrator {
    pub fn new(
        world: &World,
        settings: PhotonSettings,
        max_bounces: u32,
        seed: u64,
    ) -> crate::error::Result<Self> {
        let finest = super::guide::step(world);
        let step = settings.step.unwrap_or(finest);
        // `auto`: paths where a path finds the sky by escaping alone (a
        // constant one), photons for a map.
        let env = EnvLight::of(world);
        let paths = match settings.sky {
            Sky::Auto => env == EnvLight::Escaped,
            Sky::Paths => env != EnvLight::Off,
            Sky::Photons => false,
        };
        let sky_paths = paths.then(|| Sources::environment_of(world));
        Ok(Self {
            settings,
            photons: photons_for(&settings, world.camera.width(), world.camera.height()),
            max_bounces,
            seed,
            emitters: Emitters::with(world, sky_paths.is_none()),
            sky_paths,
            min_step: finest / MAX_STEPS_PER_VOXEL,
            importance: Importance::from_camera(world, step),
            step,
            r_max: settings.radius,
            store: None,
            map: None,
            search_radius: 0.0,
            order: 0.0,
            tuning: Tuning::of(&settings, 0.0),
            totals: PhotonTotals::default(),
            time: 0.0,
        })
    }

    /// What the passes so far did.
    pub fn totals(&self) -> PhotonTotals {
        self.totals
    }

    /// The share of camera samples that trace a path for the environment's
    /// light: 0 when photons carry it, every sample when no photons are
    /// traced at all (nothing else to spend the time on).
    pub fn sky_share(&self) -> f32 {
        match (self.sky_paths, &self.emitters) {
            (None, _) => 0.0,
            (Some(_), None) => 1.0,
            (Some(_), Some(_)) => self.tuning.sky_paths,
        }
    }

    /// The scale of the storage probability that keeps about
    /// `STORED_PER_EMITTED` stored photons per emitted one, given what a
    /// trace of `st.emitted` photons met.
    fn store_scale(&self, st: &photon::TraceStats) -> f32 {
        let target = STORED_PER_EMITTED as f64 * self.photons as f64;
        let expected = st.eligible_weight * self.photons as f64 / st.emitted.max(1) as f64;
        if expected <= 0.0 {
            1.0
        } else {
            (target / expected).clamp(1e-9, 1e9) as f32
        }
    }

    /// The radii of a pass's photons: the density radius, at most the first
    /// pass's largest radius, shrunk for pass `pass` (0-based).
    fn radii(&mut self, photons: &[Photon], world: &World, pass: u32) -> Vec<f32> {
        let k = self.tuning.k;
        // A first guess of the density radius from the photons' spread in
        // the volumes' bounds, then one refinement on cells of about the
        // radius itself.
        let (lo, hi) = world.media.bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
        let volume = (hi - lo).max(Vec3::splat(1e-6)).element_product();
        let rho = photons.len().max(1) as f32 / volume;
        let guess = (3.0 * k as f32 / (4.0 * std::f32::consts::PI * rho)).cbrt();
        // (One photon in 16 has a sixteenth of the density: its radii are
        // 16^(1/3) times larger.)
        let sample: Vec<Photon> = photons.iter().step_by(16).copied().collect();
        let first = median(&density_radii(&sample, k, guess, f32::INFINITY)) / 16f32.cbrt();
        let cell = (first / 1.5).max(1e-6);
        let r_max = *self.r_max.get_or_insert(4.0 * first);
        self.totals.r_max = r_max;
        let shrink = ((pass + 1) as f32).powf((self.tuning.alpha - 1.0) / 2.0);
        let mut r = density_radii(photons, k, cell, r_max);
        for x in &mut r {
            *x *= shrink;
        }
        r
    }
}

impl Integrator for PhotonIntegrator {
    fn name(&self) -> &'static str {
        "photon"
    }

    /// A photon map's error is blotches the size of its kernels, which the
    /// denoiser leaves, and after many passes little pixel noise is left
    /// for it to remove: on the Blender smoke + fire frame at 840 passes
    /// the raw image was 4.8e-6 from the truth, denoised 6.5e-6, blended
    /// 4.8e-6 (docs/performance.md, "Denoising").
    fn denoise_blended(&self) -> bool {
        true
    }

    fn begin_pass(&mut self, world: &World, pass: u32) {
        self.map = None;
        self.time = pass_time(world, self.seed, pass);
        let time = self.time;
        let Some(emitters) = &self.emitters else {
            return;
        };
        let importance = self.importance.as_ref();
        let scale = match self.store {
            Some(s) => s,
            None => {
                // A pilot, in a stream of its own, measures what storing
                // every collision would keep.
                let n = self.photons;
                let pilot = (n / 32).max(256).min(n);
                let st = measure(
                    world,
                    emitters,
                    pilot,
                    (self.seed, u32::MAX),
                    time,
                    self.max_bounces,
                    importance,
                );
                self.order = st.order();
                self.tuning = Tuning::of(&self.settings, self.order);
                self.store_scale(&st)
            }
        };
        let store = photon::Store { scale, importance };
        let n = match self.settings.photons {
            Some(n) => n,
            None => photons_in_pass(self.photons, pass, PHOTON_GROWTH),
        };
        let (photons, st) = photon::trace(
            world,
            emitters,
            n,
            self.seed,
            pass,
            time,
            self.max_bounces,
            store,
        );
        self.store = Some(self.store_scale(&st));
        self.totals.passes += 1;
        self.totals.emitted += st.emitted;
        self.totals.stored += st.stored;
        self.totals.last_stored = st.stored;
        if photons.is_empty() {
            return;
        }
        self.map = match self.settings.estimate {
            Estimate::Beam => {
                let radius = self.radii(&photons, world, pass);
                let flat = flatten(
                    &photons,
                    &radius,
                    &world.media,
                    time,
                    self.tuning.max_squash,
                );
                let angular = angular_kernel(self.tuning.angular, pass);
                BeamMap::new(photons, radius, flat, ratio_max(pass), angular).map(Map::Beam)
            }
            Estimate::Point => {
                if self.r_max.is_none() {
                    self.radii(&photons, world, 0);
                }
                let r_max = self.r_max.unwrap_or(1.0);
                self.search_radius =
                    r_max * ((pass + 1) as f32).powf((self.tuning.alpha - 1.0) / 3.0);
                PointMap::new(photons).map(Map::Point)
            }
        };
    }

    /// Every camera ray of a pass at the pass's time ([`pass_time`]).
    fn sample_time(&self, _world: &World, _key: SampleKey) -> f32 {
        self.time
    }

    fn li(&self, world: &World, ray: &Ray, rng: &mut Rng, _key: SampleKey) -> SampleResult {
        let (mut res, hit, tr) = STEPS.with(|s| {
            let mut steps = s.borrow_mut();
            steps.clear();
            self.march(world, ray, RayKind::CAMERA, rng, &mut steps)
        });
        if let Some(sources) = self.sky_paths {
            // The environment's light, from a path at a share of the
            // samples (a one-sample estimate: weighted by its inverse);
            // every sample when no photons are traced at all.
            let share = self.sky_share();
            if share >= 1.0 || rng.next_f32() < share {
                let p = super::path::trace_from(
                    world,
                    self.max_bounces,
                    ray,
                    rng,
                    sources,
                    super::path::Start::Camera,
                    None,
                );
                let w = 1.0 / share;
                res.l += p.l * w;
                res.direct += p.direct * w;
                res.indirect += p.indirect * w;
                res.surface.add(&p.surface.times(Rgb::splat(w)));
            }
        }
        if let Some(h) = hit {
            // A shadow catcher: its estimate, weighted as alpha is by the
            // transmittance up to it (0 where the march ended first).
            let flags = world.shapes.object(h.object).flags;
            if !flags.holdout && !flags.shadow_catcher {
                // Any other surface is shaded, and opaque.
                res.transmittance = 0.0;
                if tr.max_element() > 0.0 {
                    let (emission, passes) = self.surface_light(world, &h, ray.d, ray.time, rng);
                    let (e, passes) = (tr * emission, passes.times(tr));
                    res.l += e + passes.total();
                    res.emission += e;
                    res.surface.add(&passes);
                }
            }
            if flags.shadow_catcher && !flags.holdout {
                res.catcher = Some(if res.transmittance > 0.0 {
                    super::catcher::estimate(world, &h, ray.time, rng, 1.0, |r, pdf, rng| {
                        super::path::bounce(world, self.max_bounces, &h, r, pdf, None, rng)
                    })
                    .scaled(res.transmittance)
                } else {
                    crate::film::CatcherSample::default()
                });
            }
        }
        res
    }

    fn attributes(&self) -> Vec<(String, String)> {
        let s = &self.settings;
        let t = &self.totals;
        let mut a = vec![
            (
                "vdbphoton/photons_per_pass".into(),
                self.photons.to_string(),
            ),
            ("vdbphoton/photons_emitted".into(), t.emitted.to_string()),
            ("vdbphoton/photons_stored".into(), t.stored.to_string()),
            ("vdbphoton/k".into(), self.tuning.k.to_string()),
            ("vdbphoton/alpha".into(), format!("{}", self.tuning.alpha)),
            (
                "vdbphoton/max_squash".into(),
                format!("{}", self.tuning.max_squash),
            ),
            (
                // The first pass's angular kernel (its mean cosine; 1: no
                // blur), rising to 1 as angular_kernel says.
                "vdbphoton/angular_kernel".into(),
                format!("{}", self.tuning.angular),
            ),
            (
                // The exponent of photons_in_pass (0 when `photons` is set).
                "vdbphoton/photon_growth".into(),
                format!(
                    "{}",
                    if s.photons.is_some() { 0.0 } else { PHOTON_GROWTH }
                ),
            ),
            (
                "vdbphoton/scattering_order".into(),
                format!("{:.2}", self.order),
            ),
            ("vdbphoton/step".into(), format!("{}", self.step)),
            ("vdbphoton/estimate".into(), s.estimate.name().into()),
            (
                // The share of camera samples that trace the environment's
                // light (0: photons carry it).
                "vdbphoton/sky_paths".into(),
                format!("{}", self.sky_share()),
            ),
            ("vdbphoton/radius".into(), format!("{}", t.r_max)),
        ];
        if let Some(p) = self.store {
            a.push(("vdbphoton/store_scale".into(), format!("{p}")));
        }
        a
    }

    /// The pilot's measurements and the radius chosen by the first pass
    /// (everything a pass takes from those before it), and the totals.
    fn state(&self) -> super::PassState {
        use super::state::{f32, f64, opt_f32};
        let t = &self.totals;
        [
            ("store", opt_f32(self.store)),
            ("r_max", opt_f32(self.r_max)),
            ("order", f64(self.order)),
            ("passes", t.passes.to_string()),
            ("emitted", t.emitted.to_string()),
            ("stored", t.stored.to_string()),
            ("last_stored", t.last_stored.to_string()),
            ("first_r_max", f32(t.r_max)),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }

    fn restore(&mut self, _world: &World, s: &super::PassState) -> Result<(), String> {
        use super::state::{get_f32, get_f64, get_opt_f32, get_u64};
        let store = get_opt_f32(s, "store")?;
        let r_max = get_opt_f32(s, "r_max")?;
        let order = get_f64(s, "order")?;
        let passes = u32::try_from(get_u64(s, "passes")?).map_err(|e| e.to_string())?;
        let totals = PhotonTotals {
            passes,
            emitted: get_u64(s, "emitted")?,
            stored: get_u64(s, "stored")?,
            last_stored: get_u64(s, "last_stored")?,
            r_max: get_f32(s, "first_r_max")?,
        };
        self.store = store;
        self.r_max = r_max;
        self.order = order;
        // The tuning the pilot chose (the first pass runs it).
        if store.is_some() {
            self.tuning = Tuning::of(&self.settings, order);
        }
        self.totals = totals;
        Ok(())
    }
}

impl PhotonIntegrator {
    /// The march of one ray of `kind` (a camera ray, or a gather ray from
    /// a surface); see the module docs. It stops at the first surface the
    /// ray sees, which it returns with the transmittance up to there. What
    /// lies beyond the media (the world) counts for a camera ray unless
    /// the film is transparent, and for a gather ray unless camera paths
    /// carry the world's light (`sky_paths`).
    fn march(
        &self,
        world: &World,
        ray: &Ray,
        kind: RayKind,
        rng: &mut Rng,
        steps: &mut Vec<MarchStep>,
    ) -> (SampleResult, Option<Hit>, Rgb) {
        let Ray { o, d, time } = *ray;
        let media = &world.media;
        let mut res = SampleResult::default();
        let mut tr = Rgb::ONE;
        let mut ended = false;
        let jitter = rng.next_f32();
        let hit = world.shapes.intersect(o, d, f32::INFINITY, kind);
        let t_hit = hit.map_or(f32::INFINITY, |h| h.t);
        media.for_each_segment_at(o, d, 0.0, t_hit, time, |seg| {
            if seg.max_density <= 0.0 && seg.emission <= 0.0 {
                return true;
            }
            let len = seg.t1 - seg.t0;
            let mut target = self.step;
            if seg.max_density > 0.0 {
                target = target
                    .min(MAX_STEP_TAU / seg.max_density)
                    .max(self.min_step);
            }
            let n = (len / target).ceil().clamp(1.0, 1e6) as u32;
            let dt = len / n as f32;
            for i in 0..n {
                let t0 = seg.t0 + i as f32 * dt;
                let p = o + d * (t0 + jitter * dt);
                let m = media.eval(p, time);
                let st = m.sigma_t();
                let (att, w) = crate::medium::Media::step_weights(st, dt);
                let w = w * tr;
                let e = w * m.emission;
                res.emission += e;
                steps.push(MarchStep {
                    t0,
                    dt,
                    tr,
                    sigma_t: st,
                    sigma_s: m.sigma_s,
                    w,
                    p,
                });
                tr *= att;
                if tr.max_element() < MARCH_RR && !roulette(&mut tr, MARCH_RR, rng) {
                    ended = true;
                    return false;
                }
            }
            true
        });
        let t_end = if ended {
            steps.last().map_or(0.0, |s| s.t0 + s.dt)
        } else {
            t_hit
        };
        let wo = -d;
        // Single scattering at `light_samples` steps chosen by
        // T·σs·(1 − e^{−σtΔ})/σt, stratified over its cumulative sum.
        let total: f32 = steps.iter().map(|s| luminance(s.w * s.sigma_s)).sum();
        // The march's light samples take the environment unless paths do.
        let sources = if self.sky_paths.is_some() {
            Sources::LIGHTS
        } else {
            Sources::ALL
        };
        let any_source = !world.lights.is_empty()
            || (sources.environment != EnvLight::Off && !world.environment.is_black());
        if total > 0.0 && any_source {
            let m = self.tuning.light_samples;
            let u0 = rng.next_f32();
            let mut acc = 0.0f32;
            let mut k = 0u32;
            for s in steps.iter() {
                let c = luminance(s.w * s.sigma_s);
                acc += c;
                while k < m && (k as f32 + u0) / m as f32 * total < acc {
                    k += 1;
                    let prob = c / total;
                    if prob > 0.0 {
                        let phase = media.phase_at(s.p, time, rng.next_f32());
                        let ls = direct_light(world, s.p, time, wo, &phase, false, sources, rng);
                        res.direct += s.w * s.sigma_s * ls / (prob * m as f32);
                    }
                }
            }
        }
        // Multiple scattering from the photon map.
        match &self.map {
            Some(Map::Beam(map)) => {
                // Transmittance and σs at t, from the march: σs is 0 outside
                // the steps (where the march skipped empty space).
                let along = |t: f32| {
                    let i = steps.partition_point(|s| s.t0 <= t);
                    if i == 0 {
                        return (Rgb::ONE, 0.0);
                    }
                    let s = &steps[i - 1];
                    let tr = s.tr * (-s.sigma_t * (t - s.t0).min(s.dt)).map(f32::exp);
                    let inside = t < s.t0 + s.dt;
                    (
                        tr,
                        if inside {
                            s.sigma_s.element_sum() / 3.0
                        } else {
                            0.0
                        },
                    )
                };
                let (light, emitted) = map.gather(media, o, d, t_end, along);
                res.indirect = light;
                res.emission += emitted;
            }
            Some(Map::Point(map)) => {
                for s in steps.iter() {
                    if s.sigma_s.max_element() <= 0.0 {
                        continue;
                    }
                    let (light, emitted) = map.estimate(
                        media,
                        s.p,
                        s.sigma_s.element_sum() / 3.0,
                        wo,
                        self.tuning.k,
                        self.search_radius,
                    );
                    res.indirect += s.w * light;
                    res.emission += s.w * emitted;
                }
            }
            None => {}
        }
        res.l = res.direct + res.indirect + res.emission;
        if ended {
            tr = Rgb::ZERO;
        } else {
            // What the ray sees beyond the media: the world, unless a
            // surface stops it.
            let world_seen = if kind == RayKind::CAMERA {
                !world.film_transparent
            } else {
                self.sky_paths.is_none()
            };
            if hit.is_none() && world_seen {
                let le = world.environment.le(d);
                res.l += tr * le;
            }
            res.transmittance = (tr.x + tr.y + tr.z) / 3.0;
        }
        (res, hit, tr)
    }

    /// The light leaving surface point `hit` towards `-d`, the camera's
    /// ray: its emission (returned apart, the camera sees it), and by
    /// Blender's Diffuse and Glossy passes next-event estimation of the
    /// lights (and an environment map the photons carry) and a
    /// BSDF-sampled gather ray, marched as a camera ray is (single
    /// scattering, the photon map, emission) and shaded again where it
    /// meets another surface (Russian roulette after `RR_DEPTH` bounces,
    /// `max_bounces` at most). The world's light when camera paths carry it
    /// (`sky_paths`) is theirs, not this.
    fn surface_light(
        &self,
        world: &World,
        hit: &Hit,
        d: Vec3,
        time: f32,
        rng: &mut Rng,
    ) -> (Rgb, crate::film::SurfaceAovs) {
        let mut seen = Rgb::ZERO;
        let mut passes = crate::film::SurfaceAovs::default();
        let mut beta = Rgb::ONE;
        let (mut hit, mut d, mut depth) = (*hit, d, 0u32);
        // The lobe the first reflection took.
        let mut lobe = false;
        let sources = if self.sky_paths.is_some() {
            Sources::LIGHTS
        } else {
            Sources::ALL
        };
        loop {
            let sh = world.shapes.shading(&hit);
            let sp = world.surfaces[hit.object as usize].at(sh.uv);
            if depth == 0 {
                seen += sp.emission;
            } else {
                passes.add_to(lobe, depth == 1, beta * sp.emission);
            }
            let Some(bsdf) = sp.bsdf else {
                return (seen, passes);
            };
            depth += 1;
            if depth > self.max_bounces {
                return (seen, passes);
            }
            let frame = crate::bsdf::Frame::from_normal(sh.n);
            let wo = frame.to_local(-d);
            let ld = super::nee::direct_light_surface(
                world, &hit, &frame, &bsdf, wo, time, sources, rng,
            );
            if depth == 1 {
                passes.diffuse_direct += ld.diffuse;
                passes.glossy_direct += ld.glossy;
            } else {
                passes.add_to(lobe, false, beta * ld.total());
            }
            let Some(bs) = bsdf.sample(wo, rng.next_f32(), rng.next_vec2()) else {
                return (seen, passes);
            };
            let wi = frame.to_world(bs.wi);
            if bs.pdf <= 0.0 || wi.dot(hit.n) <= 0.0 {
                return (seen, passes);
            }
            if depth == 1 {
                lobe = bs.glossy;
            }
            beta *= bs.f.total() * (bs.wi.z.abs() / bs.pdf);
            if depth >= super::path::RR_DEPTH && !roulette(&mut beta, super::path::RR_THRESHOLD, rng) {
                return (seen, passes);
            }
            let kind = if bs.glossy {
                RayKind::GLOSSY
            } else {
                RayKind::DIFFUSE
            };
            let gather = Ray::at_time(hit.spawn(wi), wi, time);
            let (r, next, tr) = STEPS.with(|s| {
                let mut steps = s.borrow_mut();
                steps.clear();
                self.march(world, &gather, kind, rng, &mut steps)
            });
            // What the gather ray finds straight (the media's emission, the
            // world) is this point's direct light; what the media scatter
            // to it, its indirect.
            let scattered = r.direct + r.indirect;
            passes.add_to(lobe, depth == 1, beta * (r.l - scattered));
            passes.add_to(lobe, false, beta * scattered);
            match next {
                Some(h) if tr.max_element() > 0.0 => {
                    beta *= tr;
                    hit = h;
                    d = wi;
                }
                _ => return (seen, passes),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_automatic_photon_count_grows_as_its_schedule_says() {
        // The same count for the first GROW_FROM passes, and always
        // without growth.
        for pass in [0, 1, GROW_FROM - 1] {
            assert_eq!(photons_in_pass(10_000, pass, 0.5), 10_000);
        }
        assert_eq!(photons_in_pass(10_000, 100_000, 0.0), 10_000);
        // Then base · ((pass + 1) / GROW_FROM)^growth: 4x the passes, 2x
        // the photons at √P, 16x the passes, 8x at P^(3/4).
        assert_eq!(photons_in_pass(10_000, 4 * GROW_FROM - 1, 0.5), 20_000);
        assert_eq!(photons_in_pass(10_000, 16 * GROW_FROM - 1, 0.75), 80_000);
        // At most MAX_GROWTH times the base, and never past a 4K frame's
        // automatic count: such a frame does not grow.
        assert_eq!(photons_in_pass(10_000, u32::MAX, 1.0), 80_000);
        let big = auto_photons(4096, 2160);
        assert_eq!(big, MAX_AUTO_PHOTONS);
        assert_eq!(photons_in_pass(big, u32::MAX, 1.0), big);
        assert_eq!(photons_in_pass(1 << 21, u32::MAX, 1.0), MAX_AUTO_PHOTONS);
        assert_eq!(max_photons_in_pass(10_000), 80_000);
    }

    /// The angular kernel starts at the tuning's mean cosine and rises to
    /// 1 (no blur) as (pass + 1)^(−1/4): the estimate stays consistent.
    /// Without a blur it is exactly 1 in every pass, so that thin media
    /// render as before.
    #[test]
    fn the_angular_kernel_narrows_to_none() {
        for pass in [0, 1, 1000, u32::MAX] {
            assert_eq!(angular_kernel(1.0, pass), 1.0);
        }
        assert_eq!(angular_kernel(0.75, 0), 0.75);
        // 1 − 0.25 / 16^(1/4) after 16 passes, 1 − 0.25 / 10 after 10^4.
        assert!((angular_kernel(0.75, 15) - 0.875).abs() < 1e-6);
        assert!((angular_kernel(0.75, 9999) - 0.975).abs() < 1e-5);
        let mut last = 0.0;
        for pass in (0..1_000_000).step_by(997) {
            let s = angular_kernel(0.75, pass);
            assert!(s > last && s < 1.0, "pass {pass}: {s} after {last}");
            last = s;
        }
    }
}
