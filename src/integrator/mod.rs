//! The integrator interface: a light-transport algorithm as the pass loop
//! (`crate::render::passes`) drives it, and the registry of integrators
//! the renderer knows.
//!
//! To add an integrator: write a module here that implements
//! [`Integrator`] and defines its [`Registration`] (name, constructor,
//! memory estimate, header keys, settings table), and add the module's
//! name to the list in `registry!` below: one new file, one line. Nothing
//! else names it (`auto`'s choice, `crate::render::choose_integrator`,
//! picks between the two it knows).

pub mod catcher;
pub mod guide;
pub mod nee;

/// Declares each integrator's module and lists its `REGISTRATION` in
/// [`REGISTRY`], in this order, so that registering is one line.
macro_rules! registry {
    ($($module:ident,)*) => {
        $(pub mod $module;)*

        /// The integrators the renderer knows (see the module docs to add
        /// one).
        pub const REGISTRY: &[&Registration] = &[$(&$module::REGISTRATION),*];
    };
}

registry! {
    path,
    photon,
    albedo_view,
}

use crate::ray::Ray;
use crate::sampling::{Domain, Rng};
use crate::world::World;

use crate::error::Result;
pub use crate::film::SampleResult;
use crate::scene::{Param, Params, PathSeg, SceneDesc, ValidationError, AUTO_INTEGRATOR};

pub use path::PathIntegrator;
pub use photon::PhotonIntegrator;

/// The key of a camera sample's random streams: (seed, pixel, sample
/// index). An integrator that needs a second stream (the path tracer's
/// alpha) derives it from the same key in another domain.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleKey {
    pub seed: u64,
    pub pixel: u64,
    pub index: u64,
}

impl SampleKey {
    /// The stream of this sample in `domain`.
    pub fn rng(&self, domain: Domain) -> Rng {
        Rng::new(domain, self.seed, self.pixel, self.index)
    }
}

/// A light-transport algorithm, as the pass loop drives it.
pub trait Integrator: Sync {
    /// The name used in scene files and image headers.
    fn name(&self) -> &'static str;
    /// Camera samples per pixel in each pass.
    fn samples_per_pass(&self) -> u32 {
        1
    }
    /// Prepares pass `pass` (0-based) before its camera samples.
    fn begin_pass(&mut self, _world: &World, _pass: u32) {}
    /// Whether this integrator's denoised image is blended with its raw
    /// one by their measured errors (`crate::denoise::blend`, at the cost
    /// of a second run of the denoiser, on half the samples): for an
    /// integrator whose raw image is often smoother than the denoiser
    /// takes it to be, so that its blur costs more than the noise it
    /// removes.
    fn denoise_blended(&self) -> bool {
        false
    }
    /// The time of a camera sample within the camera's shutter (frames
    /// from the frame; 0 without motion blur). By default each sample of a
    /// pixel has its own, stratified over the shutter: the base-2 radical
    /// inverse of the sample's index, rotated by a number of the pixel's
    /// own ([`Domain::Time`], a stream apart, so still frames draw what
    /// they always drew), so that any 2^m samples of a pixel from the
    /// first cover the shutter evenly, as Cycles' low-discrepancy time
    /// does; a moving plume's noise at 256 spp fell by a third against
    /// independent times. An integrator whose pass shares something that
    /// depends on time (a photon map) gives every sample of a pass the
    /// pass's time.
    fn sample_time(&self, world: &World, key: SampleKey) -> f32 {
        world.camera.shutter().map_or(0.0, |s| {
            let offset = SampleKey {
                index: u64::MAX,
                ..key
            }
            .rng(Domain::Time)
            .next_f32();
            let u = crate::sampling::radical_inverse_2(key.index as u32) + offset;
            s.time(u - u.floor())
        })
    }
    /// The radiance along the camera ray (`ray.d` unit, at the sample's
    /// time). `rng` is the sample's camera stream, already used for the
    /// position in the pixel.
    fn li(&self, world: &World, ray: &Ray, rng: &mut Rng, key: SampleKey) -> SampleResult;
    /// Settings and work so far, for the image header (`vdbphoton/...`).
    fn attributes(&self) -> Vec<(String, String)> {
        Vec::new()
    }
    /// What the next pass depends on beyond the pass number (the photon
    /// integrator's storage scale, first radius, measured scattering order
    /// and totals), saved with a checkpoint so that a resumed render
    /// (`crate::render::resume`) goes on exactly as if it had never
    /// stopped. Values as [`state`] writes them (floats by their bits).
    /// Nothing for an integrator whose passes depend only on their number.
    fn state(&self) -> PassState {
        Vec::new()
    }
    /// Takes back what [`Integrator::state`] saved after the same passes of
    /// the same scene; on an error the integrator is as it was.
    fn restore(&mut self, _world: &World, state: &PassState) -> std::result::Result<(), String> {
        match state.first() {
            None => Ok(()),
            Some((k, _)) => Err(format!("the {} integrator keeps no '{k}'", self.name())),
        }
    }
}

/// An integrator's state between passes ([`Integrator::state`]): named
/// values as text.
pub type PassState = Vec<(String, String)>;

/// Writing and reading [`PassState`] values so that they come back bit for
/// bit: floats as the hexadecimal of their bits, options as `none`.
pub mod state {
    use super::PassState;

    /// An `f32` by its bits.
    pub fn f32(x: f32) -> String {
        format!("{:08x}", x.to_bits())
    }
    /// An `f64` by its bits.
    pub fn f64(x: f64) -> String {
        format!("{:016x}", x.to_bits())
    }
    /// An optional `f32`.
    pub fn opt_f32(x: Option<f32>) -> String {
        x.map_or_else(|| "none".into(), f32)
    }

    /// The value of `key` in `state`.
    pub fn get<'a>(state: &'a PassState, key: &str) -> Result<&'a str, String> {
        state
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
            .ok_or_else(|| format!("no '{key}' in the integrator's state"))
    }
    fn bad(key: &str, v: &str) -> String {
        format!("the integrator's '{key}' is '{v}', not a value it writes")
    }
    pub fn get_f32(state: &PassState, key: &str) -> Result<f32, String> {
        let v = get(state, key)?;
        u32::from_str_radix(v, 16)
            .map(f32::from_bits)
            .map_err(|_| bad(key, v))
    }
    pub fn get_f64(state: &PassState, key: &str) -> Result<f64, String> {
        let v = get(state, key)?;
        u64::from_str_radix(v, 16)
            .map(f64::from_bits)
            .map_err(|_| bad(key, v))
    }
    pub fn get_opt_f32(state: &PassState, key: &str) -> Result<Option<f32>, String> {
        match get(state, key)? {
            "none" => Ok(None),
            _ => get_f32(state, key).map(Some),
        }
    }
    pub fn get_u64(state: &PassState, key: &str) -> Result<u64, String> {
        let v = get(state, key)?;
        v.parse().map_err(|_| bad(key, v))
    }
}

/// Everything the renderer knows of an integrator, in one place: its
/// name, how to build it, what it costs in memory, which header keys two
/// renders must share to be merged, and its settings table. The render,
/// the command line, `merge` and the memory check read it from
/// [`REGISTRY`].
pub struct Registration {
    /// Its name in scene files (`integrator = "..."`), on the command line
    /// and in image headers (`vdbphoton/integrator`).
    pub name: &'static str,
    /// One line for `vdbphoton integrators` and `--help`.
    pub about: &'static str,
    /// The keys of its settings table `[render.NAME]`, each with a line
    /// of documentation; any other key there is refused.
    pub keys: &'static [(&'static str, &'static str)],
    /// Checks its settings table (errors with paths relative to the table).
    pub check: fn(&Params) -> std::result::Result<(), ValidationError>,
    /// Builds it for a scene and its loaded world.
    pub build: fn(&SceneDesc, &crate::world::World) -> Result<Box<dyn Integrator>>,
    /// Bytes it needs at its peak beside the film and the grids (the
    /// photon integrator's map), for the memory check before anything
    /// loads.
    pub peak_bytes: fn(&SceneDesc) -> u64,
    /// Header attributes two renders must share to be merged (its settings
    /// as it used them).
    pub header_keys: &'static [&'static str],
}

/// The registration named `name`.
pub fn find(name: &str) -> Option<&'static Registration> {
    REGISTRY.iter().copied().find(|r| r.name == name)
}

/// Every name `integrator` takes: `auto` and the registered ones.
pub fn names() -> Vec<&'static str> {
    std::iter::once(AUTO_INTEGRATOR)
        .chain(REGISTRY.iter().map(|r| r.name))
        .collect()
}

/// The settings table of integrator `name` in a scene (empty when the
/// scene has none).
pub fn settings<'a>(desc: &'a SceneDesc, name: &str) -> std::borrow::Cow<'a, Params> {
    match desc.render.settings.get(name) {
        Some(p) => std::borrow::Cow::Borrowed(p),
        None => std::borrow::Cow::Owned(Params::new()),
    }
}

/// Checks a scene's integrator and the integrators' settings tables:
/// the name is `auto` or registered, every `[render.NAME]` table belongs
/// to a registered integrator, holds only its keys, and passes its check.
/// Error paths are the scene file's (`render.photon.k`), so the scene
/// loader points at the line ([`crate::scene::SceneDesc::load_with`]).
pub fn check_settings(desc: &SceneDesc) -> std::result::Result<(), ValidationError> {
    let r = &desc.render;
    let key = |k: &str| PathSeg::Key(k.to_owned());
    if r.integrator != AUTO_INTEGRATOR && find(&r.integrator).is_none() {
        return Err(ValidationError::new(
            vec![key("render"), key("integrator")],
            format!(
                "there is no integrator '{}'; it is one of {}",
                r.integrator,
                names().join(", ")
            ),
        ));
    }
    for (name, params) in &r.settings {
        let table = vec![key("render"), key(name)];
        let Some(reg) = find(name) else {
            return Err(ValidationError::new(
                table,
                format!(
                    "there is no integrator '{name}': a table in [render] holds an integrator's settings ({})",
                    REGISTRY
                        .iter()
                        .map(|r| format!("[render.{}]", r.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        };
        for k in params.keys() {
            if !reg.keys.iter().any(|(known, _)| known == k) {
                let mut path = table.clone();
                path.push(key(k));
                return Err(ValidationError::new(
                    path,
                    if reg.keys.is_empty() {
                        format!("unknown key: the {name} integrator has no settings")
                    } else {
                        format!(
                            "unknown key; [render.{name}] takes {}",
                            reg.keys.iter().map(|k| k.0).collect::<Vec<_>>().join(", ")
                        )
                    },
                ));
            }
        }
        (reg.check)(params).map_err(|mut e| {
            let mut path = table.clone();
            path.append(&mut e.path);
            e.path = path;
            e
        })?;
    }
    Ok(())
}

/// Readers of a settings table's values, with the scene's wording for
/// what is wrong (for integrators' [`Registration::check`]).
pub mod param {
    use super::{Param, Params, PathSeg, ValidationError};

    type Result<T> = std::result::Result<T, ValidationError>;

    fn error(key: &str, message: String) -> ValidationError {
        ValidationError::new(vec![PathSeg::Key(key.to_owned())], message)
    }

    /// An integer in `lo..=hi`, when given.
    pub fn int(p: &Params, key: &str, lo: i64, hi: i64) -> Result<Option<i64>> {
        let Some(v) = p.get(key) else { return Ok(None) };
        let i = v
            .as_i64()
            .ok_or_else(|| error(key, format!("must be an integer, got {}", v.kind())))?;
        if !(lo..=hi).contains(&i) {
            return Err(error(key, format!("must be in [{lo}, {hi}], got {i}")));
        }
        Ok(Some(i))
    }

    /// A finite number above `lo` (excluded) and at most `hi`, when given.
    pub fn number(p: &Params, key: &str, lo: f64, hi: f64) -> Result<Option<f64>> {
        let Some(v) = p.get(key) else { return Ok(None) };
        let x = v
            .as_f64()
            .ok_or_else(|| error(key, format!("must be a number, got {}", v.kind())))?;
        if !(x.is_finite() && x > lo && x <= hi) {
            return Err(error(key, format!("must be in ({lo}, {hi}], got {x}")));
        }
        Ok(Some(x))
    }

    /// One of `choices`, when given.
    pub fn choice(p: &Params, key: &str, choices: &[&'static str]) -> Result<Option<&'static str>> {
        let Some(v) = p.get(key) else { return Ok(None) };
        let s = match v {
            Param::Str(s) => s.as_str(),
            other => {
                return Err(error(
                    key,
                    format!(
                        "must be one of {}, got {}",
                        choices.join(", "),
                        other.kind()
                    ),
                ))
            }
        };
        choices
            .iter()
            .copied()
            .find(|c| *c == s)
            .map(Some)
            .ok_or_else(|| {
                error(
                    key,
                    format!("must be one of {}, got \"{s}\"", choices.join(", ")),
                )
            })
    }
}
