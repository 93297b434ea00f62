//! Serde mirror of the file format, and its conversion into [`SceneDesc`].
//!
//! Every struct denies unknown fields and deserialises in a streaming way
//! (no untagged/internally-tagged enums), so TOML spans and JSON positions
//! point at the offending key. Optional keys are `Option`s; defaults live in
//! one place, the conversion below.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Component, Path, PathBuf};

use glam::{DAffine3, DVec3, Vec3};
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::Deserialize;

use super::desc::{
    affine_from_rows, compose_trs, BlackbodyFilter, CameraDesc, ColorInput, DenoiseQuality,
    EnvironmentDesc, LightDesc, MaterialDesc, MeshDesc, MotionBlurDesc, Param, Params, PhaseDesc,
    Principled, PrincipledBsdf, RayVisibility, RenderDesc, SceneDesc, ShutterPosition, SurfaceDesc,
    TextureColorSpace, VelocityUnit, VolumeDesc,
};
use super::desc::{CameraPose, Lens, SensorFit, VolumeBounds, AUTO_VIEW_DIRECTION};
use super::error::{kp, PathSeg, ValidationError};
use crate::Rgb;

/// Three numbers `[x, y, z]`, or one number meaning `[v, v, v]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Splat3(pub [f64; 3]);

impl<'de> Deserialize<'de> for Splat3 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Splat3;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("an array of 3 numbers or a single number")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Splat3, E> {
                Ok(Splat3([v; 3]))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Splat3, E> {
                Ok(Splat3([v as f64; 3]))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Splat3, E> {
                Ok(Splat3([v as f64; 3]))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Splat3, A::Error> {
                read_exact(seq, &self).map(Splat3)
            }
        }
        d.deserialize_any(V)
    }
}

/// `[T; N]` that refuses an array of any other length. serde's own impl
/// for arrays stops after N elements and leaves the check for more to the
/// format: serde_json makes it, the TOML deserializer does not, so
/// `position = [0, -3, 1, 99, "x"]` would have passed as three numbers.
pub(crate) struct Exact<T, const N: usize>(pub [T; N]);

impl<'de, T: Deserialize<'de>, const N: usize> Deserialize<'de> for Exact<T, N> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<T, const N: usize>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>, const N: usize> Visitor<'de> for V<T, N> {
            type Value = Exact<T, N>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "an array of length {N}")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Exact<T, N>, A::Error> {
                read_exact(seq, &self).map(Exact)
            }
        }
        d.deserialize_seq(V(std::marker::PhantomData))
    }
}

/// Exactly `N` elements of `seq`, or an "invalid length" error against
/// `expected` that counts them all.
fn read_exact<'de, A: SeqAccess<'de>, T: Deserialize<'de>, const N: usize>(
    mut seq: A,
    expected: &dyn de::Expected,
) -> Result<[T; N], A::Error> {
    let mut items = Vec::with_capacity(N);
    while items.len() < N {
        match seq.next_element()? {
            Some(v) => items.push(v),
            None => return Err(de::Error::invalid_length(items.len(), expected)),
        }
    }
    let mut n = N;
    while seq.next_element::<de::IgnoredAny>()?.is_some() {
        n += 1;
    }
    if n != N {
        return Err(de::Error::invalid_length(n, expected));
    }
    items
        .try_into()
        .map_err(|_| de::Error::invalid_length(n, expected))
}

/// `Option<[f64; N]>` through [`Exact`] (for `deserialize_with`).
fn exact<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<Option<[f64; N]>, D::Error> {
    Ok(Option::<Exact<f64, N>>::deserialize(d)?.map(|e| e.0))
}

/// A 4 x 4 matrix whose rows are each exactly 4 numbers.
fn exact_matrix<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[[f64; 4]; 4]>, D::Error> {
    Ok(Option::<Exact<Exact<f64, 4>, 4>>::deserialize(d)?.map(|m| m.0.map(|r| r.0)))
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
pub(crate) struct SceneIn {
    #[serde(default)]
    pub(crate) render: RenderIn,
    #[serde(default)]
    camera: CameraIn,
    #[serde(default)]
    light: Vec<LightIn>,
    #[serde(default)]
    environment: EnvironmentIn,
    #[serde(default)]
    volume: Vec<VolumeIn>,
    #[serde(default)]
    mesh: Vec<MeshIn>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
pub(crate) struct RenderIn {
    width: Option<u32>,
    height: Option<u32>,
    spp: Option<u32>,
    seed: Option<u64>,
    max_bounces: Option<u32>,
    integrator: Option<String>,
    // Deprecated: the photon integrator's settings, now `[render.photon]`.
    photons: Option<ParamIn>,
    k: Option<ParamIn>,
    radius: Option<ParamIn>,
    alpha: Option<ParamIn>,
    step: Option<ParamIn>,
    estimate: Option<ParamIn>,
    output: Option<String>,
    preview: Option<String>,
    exposure: Option<f64>,
    aovs: Option<bool>,
    frames: Option<String>,
    motion_blur: Option<bool>,
    shutter: Option<f64>,
    shutter_position: Option<ShutterPositionIn>,
    fps: Option<f64>,
    denoise: Option<bool>,
    denoise_quality: Option<DenoiseQualityIn>,
    resume: Option<bool>,
    film_transparent: Option<bool>,
    /// The integrators' tables `[render.NAME]`, taken out of `[render]`
    /// before serde reads it (`super::parse_toml`): their names are not
    /// known here.
    #[serde(skip)]
    pub(crate) tables: BTreeMap<String, ParamsIn>,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum ShutterPositionIn {
    Start,
    Center,
    End,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum DenoiseQualityIn {
    High,
    Balanced,
    Fast,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum VelocityUnitIn {
    Second,
    Frame,
}

/// A value of an integrator's settings table: a number, a string or a
/// boolean (the integrator checks which it wants).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ParamIn(pub Param);

impl<'de> Deserialize<'de> for ParamIn {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = ParamIn;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number, a string or a boolean")
            }
            fn visit_bool<E: de::Error>(self, v: bool) -> Result<ParamIn, E> {
                Ok(ParamIn(Param::Bool(v)))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<ParamIn, E> {
                Ok(ParamIn(Param::Int(v)))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<ParamIn, E> {
                i64::try_from(v)
                    .map(|v| ParamIn(Param::Int(v)))
                    .map_err(|_| E::custom(format!("{v} is too large")))
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<ParamIn, E> {
                Ok(ParamIn(Param::Float(v)))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<ParamIn, E> {
                Ok(ParamIn(Param::Str(v.to_owned())))
            }
        }
        d.deserialize_any(V)
    }
}

/// An integrator's settings table `[render.NAME]` as read.
pub(crate) type ParamsIn = BTreeMap<String, ParamIn>;

/// The photon integrator's keys that `[render]` held before integrators
/// had tables of their own: still read, into `[render.photon]`, with a
/// deprecation warning.
pub(crate) const FLAT_PHOTON_KEYS: [&str; 6] =
    ["photons", "k", "radius", "alpha", "step", "estimate"];

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
struct CameraIn {
    #[serde(default, deserialize_with = "exact")]
    position: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exact")]
    look_at: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exact")]
    up: Option<[f64; 3]>,
    vfov: Option<f64>,
    focal_length: Option<f64>,
    sensor_width: Option<f64>,
    sensor_height: Option<f64>,
    sensor_fit: Option<SensorFitIn>,
    shift_x: Option<f64>,
    shift_y: Option<f64>,
    #[serde(default, deserialize_with = "exact_matrix")]
    matrix: Option<[[f64; 4]; 4]>,
    #[serde(default, deserialize_with = "exact")]
    location: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exact")]
    rotation: Option<[f64; 3]>,
    framing: Option<FramingIn>,
    #[serde(default, deserialize_with = "exact")]
    direction: Option<[f64; 3]>,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum SensorFitIn {
    Auto,
    Horizontal,
    Vertical,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum FramingIn {
    Auto,
}

/// `bounds = "active" | "sequence" | "domain"` or `[[x0, y0, z0], [x1, y1, z1]]`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct BoundsIn(VolumeBounds);

impl<'de> Deserialize<'de> for BoundsIn {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = BoundsIn;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str(
                    "\"active\", \"sequence\", \"domain\" or a box [[x0, y0, z0], [x1, y1, z1]]",
                )
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<BoundsIn, E> {
                Ok(BoundsIn(match v {
                    "active" => VolumeBounds::Active,
                    "sequence" => VolumeBounds::Sequence,
                    "domain" => VolumeBounds::Domain,
                    _ => return Err(de::Error::invalid_value(de::Unexpected::Str(v), &self)),
                }))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<BoundsIn, A::Error> {
                let Exact(lo) = seq
                    .next_element::<Exact<f64, 3>>()?
                    .ok_or_else(|| de::Error::invalid_length(0, &self))?;
                let Exact(hi) = seq
                    .next_element::<Exact<f64, 3>>()?
                    .ok_or_else(|| de::Error::invalid_length(1, &self))?;
                if seq.next_element::<de::IgnoredAny>()?.is_some() {
                    return Err(de::Error::invalid_length(3, &self));
                }
                Ok(BoundsIn(VolumeBounds::Box([
                    DVec3::from(lo),
                    DVec3::from(hi),
                ])))
            }
        }
        d.deserialize_any(V)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum LightKind {
    Sun,
    Point,
    Spot,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
struct LightIn {
    #[serde(rename = "type")]
    kind: LightKind,
    #[serde(default, deserialize_with = "exact")]
    direction: Option<[f64; 3]>,
    irradiance: Option<Splat3>,
    angle: Option<f64>,
    #[serde(default, deserialize_with = "exact")]
    position: Option<[f64; 3]>,
    intensity: Option<Splat3>,
    cone_angle: Option<f64>,
    cone_falloff: Option<f64>,
    blend: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
struct EnvironmentIn {
    radiance: Option<Splat3>,
    map: Option<String>,
    strength: Option<f64>,
    rotate_z: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
struct VolumeIn {
    file: String,
    density_grid: Option<String>,
    temperature_grid: Option<String>,
    flame_grid: Option<String>,
    color_grid: Option<String>,
    blackbody_interpolation: Option<BlackbodyFilterIn>,
    transform: Option<TransformIn>,
    material: Option<MaterialIn>,
    bounds: Option<BoundsIn>,
    frame_offset: Option<i64>,
    #[serde(default, deserialize_with = "exact")]
    temperature_from_flame: Option<[f64; 2]>,
    velocity_grid: Option<String>,
    velocity_scale: Option<Splat3>,
    velocity_unit: Option<VelocityUnitIn>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
struct MeshIn {
    file: String,
    name: Option<String>,
    transform: Option<TransformIn>,
    holdout: Option<bool>,
    shadow_catcher: Option<bool>,
    visibility: Option<VisibilityIn>,
    material: Option<SurfaceIn>,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum SurfaceKind {
    Principled,
    Diffuse,
    Emission,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
struct SurfaceIn {
    #[serde(rename = "type")]
    kind: Option<SurfaceKind>,
    base_color: Option<Splat3>,
    base_color_texture: Option<TextureIn>,
    roughness: Option<f64>,
    metallic: Option<f64>,
    ior: Option<f64>,
    specular_ior_level: Option<f64>,
    specular_tint: Option<Splat3>,
    emission_color: Option<Splat3>,
    emission_strength: Option<f64>,
    color: Option<Splat3>,
    color_texture: Option<TextureIn>,
    strength: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
struct TextureIn {
    file: String,
    colorspace: Option<ColorSpaceIn>,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum ColorSpaceIn {
    Srgb,
    Linear,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
struct VisibilityIn {
    camera: Option<bool>,
    shadow: Option<bool>,
    diffuse: Option<bool>,
    glossy: Option<bool>,
    transmission: Option<bool>,
    volume_scatter: Option<bool>,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum BlackbodyFilterIn {
    Emission,
    Temperature,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
struct TransformIn {
    #[serde(default, deserialize_with = "exact")]
    translate: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exact")]
    rotate: Option<[f64; 3]>,
    scale: Option<Splat3>,
    #[serde(default, deserialize_with = "exact_matrix")]
    matrix: Option<[[f64; 4]; 4]>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
struct MaterialIn {
    density: Option<f64>,
    color: Option<Splat3>,
    absorption_color: Option<Splat3>,
    anisotropy: Option<f64>,
    emission_strength: Option<f64>,
    emission_color: Option<Splat3>,
    blackbody_intensity: Option<f64>,
    blackbody_tint: Option<Splat3>,
    temperature: Option<f64>,
    sigma_s: Option<Splat3>,
    sigma_a: Option<Splat3>,
    emission: Option<Splat3>,
    phase: Option<PhaseIn>,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case")]
enum PhaseKind {
    Isotropic,
    Hg,
    Schlick,
    HgMix,
    FournierForand,
    Draine,
    Rayleigh,
    Mie,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
struct PhaseIn {
    #[serde(rename = "type")]
    kind: PhaseKind,
    g: Option<f64>,
    lobes: Option<Vec<LobeIn>>,
    backscatter: Option<f64>,
    ior: Option<f64>,
    alpha: Option<f64>,
    diameter: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, expecting = "a table")]
struct LobeIn {
    g: f64,
    weight: f64,
}

type Conv<T> = Result<T, ValidationError>;

fn v3(a: [f64; 3]) -> Vec3 {
    Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32)
}

fn rgb(s: Splat3) -> Rgb {
    v3(s.0)
}

fn with(path: &[PathSeg], key: &str) -> Vec<PathSeg> {
    let mut p = path.to_vec();
    p.push(PathSeg::Key(key.to_owned()));
    p
}

/// Lexically removes `.` and `..` (no file-system access).
fn normalize(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => match out.components().next_back() {
                Some(Component::Normal(_)) => {
                    out.pop();
                }
                Some(Component::RootDir | Component::Prefix(_)) => {}
                _ => out.push(".."),
            },
            other => out.push(other.as_os_str()),
        }
    }
    if out.as_os_str().is_empty() {
        out.push(".");
    }
    out
}

/// Resolves a path from the scene file against `base` (absolute paths are
/// kept), rejecting empty strings.
fn resolve(base: &Path, p: &str, path: Vec<PathSeg>) -> Conv<PathBuf> {
    if p.trim().is_empty() {
        return Err(ValidationError::new(path, "path must not be empty"));
    }
    Ok(normalize(&base.join(p)))
}

fn require<T>(v: Option<T>, path: &[PathSeg], key: &str, what: &str) -> Conv<T> {
    v.ok_or_else(|| ValidationError::new(with(path, key), format!("missing (required {what})")))
}

impl SceneIn {
    pub(crate) fn into_desc(self, base: &Path) -> Conv<SceneDesc> {
        let lights = self
            .light
            .into_iter()
            .enumerate()
            .map(|(i, l)| l.into_desc(&kp!["light", i]))
            .collect::<Conv<Vec<_>>>()?;
        let volumes = self
            .volume
            .into_iter()
            .enumerate()
            .map(|(i, v)| v.into_desc(base, &kp!["volume", i]))
            .collect::<Conv<Vec<_>>>()?;
        let meshes = self
            .mesh
            .into_iter()
            .enumerate()
            .map(|(i, m)| m.into_desc(base, &kp!["mesh", i]))
            .collect::<Conv<Vec<_>>>()?;
        let mut warnings = Vec::new();
        Ok(SceneDesc {
            render: self.render.into_desc(base, &mut warnings)?,
            camera: self.camera.into_desc()?,
            lights,
            environment: self.environment.into_desc(base)?,
            volumes,
            meshes,
            warnings,
        })
    }
}

impl RenderIn {
    /// The flat photon keys this `[render]` gives (deprecated).
    pub(crate) fn flat_photon_keys(&self) -> Vec<&'static str> {
        let given = [
            self.photons.is_some(),
            self.k.is_some(),
            self.radius.is_some(),
            self.alpha.is_some(),
            self.step.is_some(),
            self.estimate.is_some(),
        ];
        FLAT_PHOTON_KEYS
            .iter()
            .zip(given)
            .filter(|(_, g)| *g)
            .map(|(k, _)| *k)
            .collect()
    }

    fn into_desc(self, base: &Path, warnings: &mut Vec<String>) -> Conv<RenderDesc> {
        let d = RenderDesc::default();
        let output = self.output.as_deref().unwrap_or("out.exr");
        let flat = self.flat_photon_keys();
        let mut settings: BTreeMap<String, Params> = self
            .tables
            .into_iter()
            .map(|(name, t)| (name, t.into_iter().map(|(k, v)| (k, v.0)).collect()))
            .collect();
        if !flat.is_empty() {
            let photon = settings.entry("photon".to_owned()).or_default();
            let values = [
                self.photons,
                self.k,
                self.radius,
                self.alpha,
                self.step,
                self.estimate,
            ];
            for (key, value) in FLAT_PHOTON_KEYS.iter().zip(values) {
                let Some(value) = value else { continue };
                if photon.contains_key(*key) {
                    return Err(ValidationError::new(
                        kp!["render", *key],
                        "given twice: here and in [render.photon]; keep the one in [render.photon]",
                    ));
                }
                photon.insert((*key).to_owned(), value.0);
            }
            warnings.push(format!(
                "[render] {}: the photon integrator's settings now have a table of their own; move {} to [render.photon] (keys in [render] are deprecated and will stop working)",
                flat.join(", "),
                if flat.len() == 1 { "it" } else { "them" }
            ));
        }
        Ok(RenderDesc {
            width: self.width.unwrap_or(d.width),
            height: self.height.unwrap_or(d.height),
            spp: self.spp.unwrap_or(d.spp),
            seed: self.seed.unwrap_or(d.seed),
            max_bounces: self.max_bounces.unwrap_or(d.max_bounces),
            integrator: self.integrator.unwrap_or(d.integrator),
            settings,
            output: resolve(base, output, kp!["render", "output"])?,
            preview: match self.preview {
                Some(p) => Some(resolve(base, &p, kp!["render", "preview"])?),
                None => None,
            },
            exposure: self.exposure.map_or(d.exposure, |e| e as f32),
            aovs: self.aovs.unwrap_or(d.aovs),
            frames: match self.frames {
                Some(f) => Some(
                    crate::sequence::parse_frames(&f)
                        .map_err(|e| ValidationError::new(kp!["render", "frames"], e))?,
                ),
                None => None,
            },
            motion_blur: {
                let m = d.motion_blur;
                MotionBlurDesc {
                    enabled: self.motion_blur.unwrap_or(m.enabled),
                    shutter: self.shutter.map_or(m.shutter, |s| s as f32),
                    position: match self.shutter_position {
                        None => m.position,
                        Some(ShutterPositionIn::Start) => ShutterPosition::Start,
                        Some(ShutterPositionIn::Center) => ShutterPosition::Center,
                        Some(ShutterPositionIn::End) => ShutterPosition::End,
                    },
                    fps: self.fps.unwrap_or(m.fps),
                }
            },
            denoise: self.denoise.unwrap_or(d.denoise),
            denoise_quality: match self.denoise_quality {
                None => d.denoise_quality,
                Some(DenoiseQualityIn::High) => DenoiseQuality::High,
                Some(DenoiseQualityIn::Balanced) => DenoiseQuality::Balanced,
                Some(DenoiseQualityIn::Fast) => DenoiseQuality::Fast,
            },
            resume: self.resume.unwrap_or(d.resume),
            film_transparent: self.film_transparent.unwrap_or(d.film_transparent),
        })
    }
}

impl CameraIn {
    fn into_desc(self) -> Conv<CameraDesc> {
        let pose = self.pose()?;
        if self.direction.is_some() && !matches!(pose, CameraPose::Auto { .. }) {
            return Err(ValidationError::new(
                with(&kp!["camera"], "direction"),
                "only used with framing = \"auto\"",
            ));
        }
        Ok(CameraDesc {
            pose,
            lens: self.lens()?,
            shift: [
                self.shift_x.unwrap_or(0.0) as f32,
                self.shift_y.unwrap_or(0.0) as f32,
            ],
        })
    }

    /// Where the camera is: one of four forms (look-at, a matrix,
    /// Blender's location and rotation, automatic framing), never two.
    fn pose(&self) -> Conv<CameraPose> {
        let d = CameraDesc::default();
        let path = kp!["camera"];
        // Keys that say where the camera is, by the form they belong to.
        let look_at_keys = [
            (self.position.is_some(), "position"),
            (self.look_at.is_some(), "look_at"),
        ];
        let blender_keys = [
            (self.location.is_some(), "location"),
            (self.rotation.is_some(), "rotation"),
        ];
        let first = |keys: &[(bool, &'static str)]| keys.iter().find(|k| k.0).map(|k| k.1);
        let clash = |a: &str, b: &str| {
            Err(ValidationError::new(
                with(&path, b),
                format!("cannot be combined with '{a}' (the camera is placed by one of: position/look_at/up, matrix, location/rotation, framing = \"auto\")"),
            ))
        };
        Ok(if let Some(m) = self.matrix {
            if let Some(k) = first(&look_at_keys).or(first(&blender_keys)) {
                return clash("matrix", k);
            }
            for (present, k) in [
                (self.up.is_some(), "up"),
                (self.framing.is_some(), "framing"),
            ] {
                if present {
                    return clash("matrix", k);
                }
            }
            if m[3] != [0.0, 0.0, 0.0, 1.0] {
                return Err(ValidationError::new(
                    with(&path, "matrix"),
                    format!("last row must be [0, 0, 0, 1], got {:?}", m[3]),
                ));
            }
            CameraPose::Matrix(affine_from_rows(m))
        } else if self.location.is_some() || self.rotation.is_some() {
            if let Some(k) = first(&look_at_keys) {
                return clash("location", k);
            }
            for (present, k) in [
                (self.up.is_some(), "up"),
                (self.framing.is_some(), "framing"),
            ] {
                if present {
                    return clash("location", k);
                }
            }
            let location = require(self.location, &path, "location", "with 'rotation'")?;
            CameraPose::Matrix(compose_trs(
                DVec3::from(location),
                self.rotation.map_or(DVec3::ZERO, DVec3::from),
                DVec3::ONE,
            ))
        } else if self.framing.is_some() {
            if let Some(k) = first(&look_at_keys) {
                return clash("framing", k);
            }
            CameraPose::Auto {
                direction: self.direction.map_or(AUTO_VIEW_DIRECTION, v3),
                up: self.up.map_or(Vec3::Z, v3),
            }
        } else {
            let CameraPose::LookAt {
                position,
                look_at,
                up,
            } = d.pose
            else {
                unreachable!("the default camera is a look-at camera")
            };
            CameraPose::LookAt {
                position: self.position.map_or(position, v3),
                look_at: self.look_at.map_or(look_at, v3),
                up: self.up.map_or(up, v3),
            }
        })
    }

    /// The lens: a vertical field of view, or Blender's focal length and
    /// sensor (not both).
    fn lens(&self) -> Conv<Lens> {
        let d = CameraDesc::default();
        let path = kp!["camera"];
        let first = |keys: &[(bool, &'static str)]| keys.iter().find(|k| k.0).map(|k| k.1);
        let sensor_keys = [
            (self.focal_length.is_some(), "focal_length"),
            (self.sensor_width.is_some(), "sensor_width"),
            (self.sensor_height.is_some(), "sensor_height"),
            (self.sensor_fit.is_some(), "sensor_fit"),
        ];
        Ok(match (self.vfov, first(&sensor_keys)) {
            (Some(_), Some(k)) => {
                return Err(ValidationError::new(
                    with(&path, k),
                    "cannot be combined with 'vfov' (give either vfov or Blender's focal_length and sensor)",
                ))
            }
            (Some(v), None) => Lens::Vfov(v as f32),
            (None, Some(_)) => Lens::Sensor {
                focal_length: self.focal_length.unwrap_or(50.0) as f32,
                sensor_width: self.sensor_width.unwrap_or(36.0) as f32,
                sensor_height: self.sensor_height.unwrap_or(24.0) as f32,
                fit: match self.sensor_fit {
                    None | Some(SensorFitIn::Auto) => SensorFit::Auto,
                    Some(SensorFitIn::Horizontal) => SensorFit::Horizontal,
                    Some(SensorFitIn::Vertical) => SensorFit::Vertical,
                },
            },
            (None, None) => d.lens,
        })
    }
}

impl LightIn {
    fn present_keys(&self) -> Vec<&'static str> {
        let mut keys = Vec::new();
        let mut add = |present: bool, key| {
            if present {
                keys.push(key)
            }
        };
        add(self.direction.is_some(), "direction");
        add(self.irradiance.is_some(), "irradiance");
        add(self.angle.is_some(), "angle");
        add(self.position.is_some(), "position");
        add(self.intensity.is_some(), "intensity");
        add(self.cone_angle.is_some(), "cone_angle");
        add(self.cone_falloff.is_some(), "cone_falloff");
        add(self.blend.is_some(), "blend");
        keys
    }

    fn into_desc(self, path: &[PathSeg]) -> Conv<LightDesc> {
        let (name, allowed): (&str, &[&str]) = match self.kind {
            LightKind::Sun => ("sun", &["direction", "irradiance", "angle"]),
            LightKind::Point => ("point", &["position", "intensity"]),
            LightKind::Spot => (
                "spot",
                &[
                    "position",
                    "direction",
                    "intensity",
                    "cone_angle",
                    "cone_falloff",
                    "blend",
                ],
            ),
        };
        if let Some(bad) = self
            .present_keys()
            .into_iter()
            .find(|k| !allowed.contains(k))
        {
            return Err(ValidationError::new(
                with(path, bad),
                format!(
                    "not a key of a \"{name}\" light (expected one of: type, {})",
                    allowed.join(", ")
                ),
            ));
        }
        let what = format!("for a \"{name}\" light");
        Ok(match self.kind {
            LightKind::Sun => LightDesc::Sun {
                direction: v3(require(self.direction, path, "direction", &what)?),
                irradiance: rgb(require(self.irradiance, path, "irradiance", &what)?),
                angle_deg: self.angle.unwrap_or(0.0) as f32,
            },
            LightKind::Point => LightDesc::Point {
                position: v3(require(self.position, path, "position", &what)?),
                intensity: rgb(require(self.intensity, path, "intensity", &what)?),
            },
            LightKind::Spot => {
                if self.cone_falloff.is_some() && self.blend.is_some() {
                    return Err(ValidationError::new(
                        with(path, "blend"),
                        "'blend' and 'cone_falloff' are the same setting: give only one",
                    ));
                }
                LightDesc::Spot {
                    position: v3(require(self.position, path, "position", &what)?),
                    direction: v3(require(self.direction, path, "direction", &what)?),
                    intensity: rgb(require(self.intensity, path, "intensity", &what)?),
                    cone_angle_deg: self.cone_angle.unwrap_or(45.0) as f32,
                    blend: self.blend.or(self.cone_falloff).unwrap_or(0.15) as f32,
                }
            }
        })
    }
}

impl EnvironmentIn {
    fn into_desc(self, base: &Path) -> Conv<EnvironmentDesc> {
        let path = kp!["environment"];
        match self.map {
            Some(map) => {
                if self.radiance.is_some() {
                    return Err(ValidationError::new(
                        with(&path, "radiance"),
                        "give either 'radiance' or 'map', not both",
                    ));
                }
                Ok(EnvironmentDesc::Map {
                    path: resolve(base, &map, with(&path, "map"))?,
                    strength: self.strength.unwrap_or(1.0) as f32,
                    rotate_z_deg: self.rotate_z.unwrap_or(0.0) as f32,
                })
            }
            None => {
                for (present, key) in [(self.strength, "strength"), (self.rotate_z, "rotate_z")] {
                    if present.is_some() {
                        return Err(ValidationError::new(
                            with(&path, key),
                            "only used with 'map' (an environment map)",
                        ));
                    }
                }
                Ok(EnvironmentDesc::Constant(
                    self.radiance.map_or(Rgb::ZERO, rgb),
                ))
            }
        }
    }
}

impl VolumeIn {
    fn into_desc(self, base: &Path, path: &[PathSeg]) -> Conv<VolumeDesc> {
        // A volume that names fire grids gets Blender's Quick Smoke look
        // where its material leaves a value open.
        let fire = self.temperature_grid.is_some() || self.flame_grid.is_some();
        Ok(VolumeDesc {
            file: resolve(base, &self.file, with(path, "file"))?,
            density_grid: self.density_grid.unwrap_or_else(|| "density".to_owned()),
            temperature_grid: self.temperature_grid,
            flame_grid: self.flame_grid,
            color_grid: self.color_grid,
            blackbody_filter: match self.blackbody_interpolation {
                None | Some(BlackbodyFilterIn::Emission) => BlackbodyFilter::Emission,
                Some(BlackbodyFilterIn::Temperature) => BlackbodyFilter::Temperature,
            },
            transform: match self.transform {
                Some(t) => t.into_desc(&with(path, "transform"))?,
                None => DAffine3::IDENTITY,
            },
            material: self
                .material
                .unwrap_or_default()
                .into_desc(&with(path, "material"), fire)?,
            bounds: self.bounds.map_or(VolumeBounds::Active, |b| b.0),
            frame_offset: self.frame_offset.unwrap_or(0),
            temperature_from_flame: self
                .temperature_from_flame
                .map(|[a, b]| [a as f32, b as f32]),
            velocity_grid: self.velocity_grid,
            velocity_scale: self.velocity_scale.map_or(Vec3::ONE, |s| v3(s.0)),
            velocity_unit: match self.velocity_unit {
                None | Some(VelocityUnitIn::Second) => VelocityUnit::Second,
                Some(VelocityUnitIn::Frame) => VelocityUnit::Frame,
            },
        })
    }
}

impl MeshIn {
    fn into_desc(self, base: &Path, path: &[PathSeg]) -> Conv<MeshDesc> {
        let d = RayVisibility::default();
        let v = self.visibility.unwrap_or_default();
        Ok(MeshDesc {
            name: self.name,
            file: resolve(base, &self.file, with(path, "file"))?,
            transform: match self.transform {
                Some(t) => t.into_desc(&with(path, "transform"))?,
                None => DAffine3::IDENTITY,
            },
            holdout: self.holdout.unwrap_or(false),
            shadow_catcher: self.shadow_catcher.unwrap_or(false),
            visibility: RayVisibility {
                camera: v.camera.unwrap_or(d.camera),
                shadow: v.shadow.unwrap_or(d.shadow),
                diffuse: v.diffuse.unwrap_or(d.diffuse),
                glossy: v.glossy.unwrap_or(d.glossy),
                transmission: v.transmission.unwrap_or(d.transmission),
                volume_scatter: v.volume_scatter.unwrap_or(d.volume_scatter),
            },
            material: match self.material {
                Some(m) => Some(m.into_desc(base, &with(path, "material"))?),
                None => None,
            },
        })
    }
}

impl TextureIn {
    fn into_desc(self, base: &Path, path: &[PathSeg]) -> Conv<ColorInput> {
        Ok(ColorInput::Texture {
            file: resolve(base, &self.file, with(path, "file"))?,
            colorspace: match self.colorspace {
                None | Some(ColorSpaceIn::Srgb) => TextureColorSpace::Srgb,
                Some(ColorSpaceIn::Linear) => TextureColorSpace::Linear,
            },
        })
    }
}

impl SurfaceIn {
    fn present_keys(&self) -> Vec<&'static str> {
        let mut keys = Vec::new();
        let mut add = |present: bool, key| {
            if present {
                keys.push(key)
            }
        };
        add(self.base_color.is_some(), "base_color");
        add(self.base_color_texture.is_some(), "base_color_texture");
        add(self.roughness.is_some(), "roughness");
        add(self.metallic.is_some(), "metallic");
        add(self.ior.is_some(), "ior");
        add(self.specular_ior_level.is_some(), "specular_ior_level");
        add(self.specular_tint.is_some(), "specular_tint");
        add(self.emission_color.is_some(), "emission_color");
        add(self.emission_strength.is_some(), "emission_strength");
        add(self.color.is_some(), "color");
        add(self.color_texture.is_some(), "color_texture");
        add(self.strength.is_some(), "strength");
        keys
    }

    fn into_desc(self, base: &Path, path: &[PathSeg]) -> Conv<SurfaceDesc> {
        let kind = self.kind.unwrap_or(SurfaceKind::Principled);
        let (name, allowed): (&str, &[&str]) = match kind {
            SurfaceKind::Principled => (
                "principled",
                &[
                    "base_color",
                    "base_color_texture",
                    "roughness",
                    "metallic",
                    "ior",
                    "specular_ior_level",
                    "specular_tint",
                    "emission_color",
                    "emission_strength",
                ],
            ),
            SurfaceKind::Diffuse => ("diffuse", &["color", "color_texture", "roughness"]),
            SurfaceKind::Emission => ("emission", &["color", "color_texture", "strength"]),
        };
        if let Some(bad) = self
            .present_keys()
            .into_iter()
            .find(|k| !allowed.contains(k))
        {
            return Err(ValidationError::new(
                with(path, bad),
                format!(
                    "not a key of a \"{name}\" surface (expected one of: type, {})",
                    allowed.join(", ")
                ),
            ));
        }
        let color = |value: Option<Splat3>,
                     texture: Option<TextureIn>,
                     key: &str,
                     default: Rgb|
         -> Conv<ColorInput> {
            match (value, texture) {
                (Some(_), Some(_)) => Err(ValidationError::new(
                    with(path, &format!("{key}_texture")),
                    format!("give either '{key}' or '{key}_texture', not both"),
                )),
                (_, Some(t)) => t.into_desc(base, &with(path, &format!("{key}_texture"))),
                (v, None) => Ok(ColorInput::Value(v.map_or(default, rgb))),
            }
        };
        let f = |v: Option<f64>, d: f32| v.map_or(d, |v| v as f32);
        Ok(match kind {
            SurfaceKind::Principled => {
                let d = PrincipledBsdf::default();
                let ColorInput::Value(base_default) = d.base_color else {
                    unreachable!("the default base colour is a value")
                };
                SurfaceDesc::Principled(PrincipledBsdf {
                    base_color: color(
                        self.base_color,
                        self.base_color_texture,
                        "base_color",
                        base_default,
                    )?,
                    roughness: f(self.roughness, d.roughness),
                    metallic: f(self.metallic, d.metallic),
                    ior: f(self.ior, d.ior),
                    specular_ior_level: f(self.specular_ior_level, d.specular_ior_level),
                    specular_tint: self.specular_tint.map_or(d.specular_tint, rgb),
                    emission_color: self.emission_color.map_or(d.emission_color, rgb),
                    emission_strength: f(self.emission_strength, d.emission_strength),
                })
            }
            SurfaceKind::Diffuse => SurfaceDesc::Diffuse {
                color: color(self.color, self.color_texture, "color", Rgb::splat(0.8))?,
                roughness: f(self.roughness, 0.0),
            },
            SurfaceKind::Emission => SurfaceDesc::Emission {
                color: color(self.color, self.color_texture, "color", Rgb::ONE)?,
                strength: f(self.strength, 1.0),
            },
        })
    }
}

impl TransformIn {
    fn into_desc(self, path: &[PathSeg]) -> Conv<DAffine3> {
        let Some(m) = self.matrix else {
            return Ok(compose_trs(
                self.translate.map_or(DVec3::ZERO, DVec3::from),
                self.rotate.map_or(DVec3::ZERO, DVec3::from),
                self.scale.map_or(DVec3::ONE, |s| DVec3::from(s.0)),
            ));
        };
        let trs = [
            (self.translate.is_some(), "translate"),
            (self.rotate.is_some(), "rotate"),
            (self.scale.is_some(), "scale"),
        ];
        if let Some((_, key)) = trs.iter().find(|(present, _)| *present) {
            return Err(ValidationError::new(
                with(path, key),
                "cannot be combined with 'matrix' (give either translate/rotate/scale or matrix)",
            ));
        }
        if m[3] != [0.0, 0.0, 0.0, 1.0] {
            return Err(ValidationError::new(
                with(path, "matrix"),
                format!("last row must be [0, 0, 0, 1], got {:?}", m[3]),
            ));
        }
        Ok(affine_from_rows(m))
    }
}

impl MaterialIn {
    /// `fire`: the volume names a temperature or flame grid, so open
    /// Principled values take Blender's Quick Smoke (fire) material's
    /// values ([`Principled::QUICK_SMOKE_FIRE`]) instead of the node's
    /// defaults.
    fn into_desc(self, path: &[PathSeg], fire: bool) -> Conv<MaterialDesc> {
        let principled = [
            (self.density.is_some(), "density"),
            (self.color.is_some(), "color"),
            (self.absorption_color.is_some(), "absorption_color"),
            (self.anisotropy.is_some(), "anisotropy"),
            (self.emission_strength.is_some(), "emission_strength"),
            (self.emission_color.is_some(), "emission_color"),
            (self.blackbody_intensity.is_some(), "blackbody_intensity"),
            (self.blackbody_tint.is_some(), "blackbody_tint"),
            (self.temperature.is_some(), "temperature"),
        ];
        let raw = [
            (self.sigma_s.is_some(), "sigma_s"),
            (self.sigma_a.is_some(), "sigma_a"),
            (self.emission.is_some(), "emission"),
            (self.phase.is_some(), "phase"),
        ];
        let first = |keys: &[(bool, &'static str)]| keys.iter().find(|k| k.0).map(|k| k.1);
        match (first(&principled), first(&raw)) {
            (Some(p), Some(r)) => Err(ValidationError::new(
                with(path, r),
                format!(
                    "cannot be mixed with Principled Volume key '{p}' (use either the \
                     Principled keys or the raw sigma_s/sigma_a/emission/phase keys)"
                ),
            )),
            (_, Some(_)) => Ok(MaterialDesc::Raw {
                sigma_a: self.sigma_a.map_or(Rgb::ZERO, rgb),
                sigma_s: self.sigma_s.map_or(Rgb::ZERO, rgb),
                emission: self.emission.map_or(Rgb::ZERO, rgb),
                phase: match self.phase {
                    Some(p) => p.into_desc(&with(path, "phase"))?,
                    None => PhaseDesc::Isotropic,
                },
            }),
            _ => {
                let d = if fire {
                    Principled::QUICK_SMOKE_FIRE
                } else {
                    Principled::DEFAULT
                };
                let f = |v: Option<f64>, d: f32| v.map_or(d, |v| v as f32);
                let c = |v: Option<Splat3>, d: Rgb| v.map_or(d, rgb);
                Ok(MaterialDesc::Principled(Principled {
                    density: f(self.density, d.density),
                    color: c(self.color, d.color),
                    absorption_color: c(self.absorption_color, d.absorption_color),
                    anisotropy: f(self.anisotropy, d.anisotropy),
                    emission_strength: f(self.emission_strength, d.emission_strength),
                    emission_color: c(self.emission_color, d.emission_color),
                    blackbody_intensity: f(self.blackbody_intensity, d.blackbody_intensity),
                    blackbody_tint: c(self.blackbody_tint, d.blackbody_tint),
                    temperature: f(self.temperature, d.temperature),
                }))
            }
        }
    }
}

impl PhaseIn {
    fn into_desc(self, path: &[PathSeg]) -> Conv<PhaseDesc> {
        let (name, keys): (&str, &[&str]) = match self.kind {
            PhaseKind::Isotropic => ("isotropic", &[]),
            PhaseKind::Hg => ("hg", &["g"]),
            PhaseKind::Schlick => ("schlick", &["g"]),
            PhaseKind::HgMix => ("hg_mix", &["lobes"]),
            PhaseKind::FournierForand => ("fournier_forand", &["backscatter", "ior"]),
            PhaseKind::Draine => ("draine", &["g", "alpha"]),
            PhaseKind::Rayleigh => ("rayleigh", &[]),
            PhaseKind::Mie => ("mie", &["diameter"]),
        };
        let what = format!("for phase type \"{name}\"");
        let given = [
            ("g", self.g.is_some()),
            ("lobes", self.lobes.is_some()),
            ("backscatter", self.backscatter.is_some()),
            ("ior", self.ior.is_some()),
            ("alpha", self.alpha.is_some()),
            ("diameter", self.diameter.is_some()),
        ];
        if let Some((key, _)) = given.iter().find(|(k, set)| *set && !keys.contains(k)) {
            return Err(ValidationError::new(
                with(path, key),
                format!("not used by phase type \"{name}\""),
            ));
        }
        let num = |v: Option<f64>, key: &str| require(v, path, key, &what).map(|v| v as f32);
        Ok(match self.kind {
            PhaseKind::Isotropic => PhaseDesc::Isotropic,
            PhaseKind::Hg => PhaseDesc::Hg {
                g: num(self.g, "g")?,
            },
            PhaseKind::Schlick => PhaseDesc::Schlick {
                g: num(self.g, "g")?,
            },
            PhaseKind::HgMix => PhaseDesc::HgMix(
                require(self.lobes, path, "lobes", &what)?
                    .into_iter()
                    .map(|l| (l.g as f32, l.weight as f32))
                    .collect(),
            ),
            PhaseKind::FournierForand => PhaseDesc::FournierForand {
                backscatter: num(self.backscatter, "backscatter")?,
                ior: num(self.ior, "ior")?,
            },
            PhaseKind::Draine => PhaseDesc::Draine {
                g: num(self.g, "g")?,
                alpha: num(self.alpha, "alpha")?,
            },
            PhaseKind::Rayleigh => PhaseDesc::Rayleigh,
            PhaseKind::Mie => PhaseDesc::Mie {
                diameter: num(self.diameter, "diameter")?,
            },
        })
    }
}
