//! Plain description structs produced by the scene parser.
//!
//! Nothing in here touches serde or the file system: these are the types the
//! renderer consumes. Paths are already resolved against the scene file's
//! directory; nothing is normalised beyond that (directions keep the length
//! the user wrote, mix weights are not renormalised).

use std::collections::BTreeMap;
use std::path::PathBuf;

use glam::{DAffine3, DMat3, DVec3, Vec3};

use crate::Rgb;

/// A whole scene: what to render, from where, lit by what.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneDesc {
    pub render: RenderDesc,
    pub camera: CameraDesc,
    pub lights: Vec<LightDesc>,
    pub environment: EnvironmentDesc,
    pub volumes: Vec<VolumeDesc>,
    /// Surfaces (`[[mesh]]`): occluders, holdouts, shadow catchers.
    pub meshes: Vec<MeshDesc>,
    /// What the scene file said that still works but should change
    /// (deprecated keys), for the render to report.
    pub warnings: Vec<String>,
}

/// One value of an integrator's settings table (`[render.NAME]`), as the
/// scene file wrote it. The scene knows no integrator: each integrator
/// reads and checks its own table (`crate::integrator::Registration`), so
/// adding one needs no change here.
#[derive(Debug, Clone, PartialEq)]
pub enum Param {
    Bool(bool),
    Int(i64),
    Float(f64),
    Str(String),
}

impl Param {
    /// The value as a number (an integer or a float).
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            Param::Int(i) => Some(*i as f64),
            Param::Float(f) => Some(*f),
            _ => None,
        }
    }
    /// The value as an integer.
    pub fn as_i64(&self) -> Option<i64> {
        match self {
            Param::Int(i) => Some(*i),
            _ => None,
        }
    }
    /// The value as a string.
    pub fn as_str(&self) -> Option<&str> {
        match self {
            Param::Str(s) => Some(s),
            _ => None,
        }
    }
    /// The value as a boolean.
    pub fn as_bool(&self) -> Option<bool> {
        match self {
            Param::Bool(b) => Some(*b),
            _ => None,
        }
    }
    /// What the value is, for messages ("an integer", ...).
    pub fn kind(&self) -> &'static str {
        match self {
            Param::Bool(_) => "a boolean",
            Param::Int(_) => "an integer",
            Param::Float(_) => "a number",
            Param::Str(_) => "a string",
        }
    }
}

impl std::fmt::Display for Param {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Param::Bool(b) => write!(f, "{b}"),
            Param::Int(i) => write!(f, "{i}"),
            Param::Float(x) => write!(f, "{x}"),
            Param::Str(s) => write!(f, "\"{s}\""),
        }
    }
}

/// Open Image Denoise's quality (Blender's Denoising › Quality): `High`
/// is its best image; `Fast` takes about 60 % of the time and memory and
/// leaves somewhat more error (figures in docs/performance.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DenoiseQuality {
    #[default]
    High,
    Balanced,
    Fast,
}

impl DenoiseQuality {
    /// The spelling used in scene files and headers.
    pub fn name(self) -> &'static str {
        match self {
            DenoiseQuality::High => "high",
            DenoiseQuality::Balanced => "balanced",
            DenoiseQuality::Fast => "fast",
        }
    }

    /// The quality named `s`.
    pub fn parse(s: &str) -> Option<Self> {
        [Self::High, Self::Balanced, Self::Fast]
            .into_iter()
            .find(|q| q.name() == s)
    }
}

/// An integrator's settings table, key by key.
pub type Params = BTreeMap<String, Param>;

/// The integrator name that lets the renderer choose
/// (`crate::render::choose_integrator`).
pub const AUTO_INTEGRATOR: &str = "auto";

/// `[render]`. All fields are plain so the CLI can override them and call
/// [`SceneDesc::validate`] again.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderDesc {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    pub seed: u64,
    pub max_bounces: u32,
    /// The integrator's name (`integrator`): [`AUTO_INTEGRATOR`] or one of
    /// `crate::integrator::REGISTRY`, checked there.
    pub integrator: String,
    /// The integrators' own settings, `[render.NAME]` tables by name
    /// (today's flat photon keys in `[render]` land in `photon`).
    pub settings: BTreeMap<String, Params>,
    /// EXR output, resolved against the scene file's directory.
    pub output: PathBuf,
    /// Optional PNG preview, resolved against the scene file's directory.
    pub preview: Option<PathBuf>,
    /// Preview exposure in stops.
    pub exposure: f32,
    /// Write AOV layers (direct, indirect, emission, transmittance; with meshes also diffuse_direct, diffuse_indirect, glossy_direct, glossy_indirect).
    pub aovs: bool,
    /// The frames rendered when the command line names none (`frames`,
    /// ascending, e.g. the frame range a Blender export wrote).
    pub frames: Option<Vec<u32>>,
    /// Velocity motion blur (`motion_blur`, `shutter`, `shutter_position`,
    /// `fps`).
    pub motion_blur: MotionBlurDesc,
    /// Denoise the finished image with Intel Open Image Denoise (`denoise`);
    /// tiles are denoised when merged.
    pub denoise: bool,
    /// How hard the denoiser works on the finished image
    /// (`denoise_quality`, Blender's Denoising › Quality).
    pub denoise_quality: DenoiseQuality,
    /// Go on from the state a killed render's last checkpoint left beside
    /// the EXR (`resume`, `--resume`; `crate::render::resume`).
    pub resume: bool,
    /// Blender's Film > Transparent (`film_transparent`): the world seen
    /// directly is left out of the colour, so RGBA is premultiplied and
    /// composites with a plain "over".
    pub film_transparent: bool,
}

/// Blender's Motion Blur panel (Render Properties): whether moving
/// volumes blur, for how long the shutter is open and where it sits around
/// the frame, and the frame rate that turns velocities per second into
/// displacements.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionBlurDesc {
    /// `motion_blur` (Blender's `use_motion_blur`; off by default).
    pub enabled: bool,
    /// `shutter`: how long the shutter is open, in frames (Blender's
    /// `motion_blur_shutter`, 0.5 by default).
    pub shutter: f32,
    /// `shutter_position` (Blender's Position).
    pub position: ShutterPosition,
    /// `fps`: frames per second (Blender's `fps / fps_base`, 24 by
    /// default).
    pub fps: f64,
}

impl Default for MotionBlurDesc {
    fn default() -> Self {
        Self {
            enabled: false,
            shutter: 0.5,
            position: ShutterPosition::Center,
            fps: 24.0,
        }
    }
}

impl MotionBlurDesc {
    /// When the shutter is open, in frames from the frame: `(open, close)`
    /// (`None` when motion blur is off).
    pub fn shutter_interval(&self) -> Option<(f32, f32)> {
        if !self.enabled {
            return None;
        }
        let s = self.shutter;
        Some(match self.position {
            ShutterPosition::Start => (0.0, s),
            ShutterPosition::Center => (-0.5 * s, 0.5 * s),
            ShutterPosition::End => (-s, 0.0),
        })
    }
}

/// Where the shutter sits around the frame (Blender's
/// `motion_blur_position`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ShutterPosition {
    /// Opens at the frame.
    Start,
    /// Centred on the frame.
    #[default]
    Center,
    /// Closes at the frame.
    End,
}

impl ShutterPosition {
    /// The spelling used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            ShutterPosition::Start => "start",
            ShutterPosition::Center => "center",
            ShutterPosition::End => "end",
        }
    }
}

/// What a velocity grid's vectors measure (Blender's Volume data
/// `velocity_unit`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum VelocityUnit {
    /// World units per second (Blender's default; Houdini's `vel`).
    #[default]
    Second,
    /// World units per frame.
    Frame,
}

impl VelocityUnit {
    /// The spelling used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            VelocityUnit::Second => "second",
            VelocityUnit::Frame => "frame",
        }
    }
}

impl Default for RenderDesc {
    /// Defaults as documented; `output` is the unresolved `out.exr`.
    fn default() -> Self {
        RenderDesc {
            width: 320,
            height: 240,
            spp: 64,
            seed: 0,
            max_bounces: 256,
            integrator: AUTO_INTEGRATOR.to_string(),
            settings: BTreeMap::new(),
            output: PathBuf::from("out.exr"),
            preview: None,
            exposure: 0.0,
            aovs: false,
            frames: None,
            motion_blur: MotionBlurDesc::default(),
            denoise: false,
            denoise_quality: DenoiseQuality::High,
            resume: false,
            film_transparent: false,
        }
    }
}

/// `[camera]`: a pinhole camera: where it is ([`CameraPose`]), its lens
/// ([`Lens`]) and Blender's lens shift.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraDesc {
    pub pose: CameraPose,
    pub lens: Lens,
    /// Blender's `shift_x`, `shift_y`: the image plane moved by these
    /// fractions of its fitted side.
    pub shift: [f32; 2],
}

impl Default for CameraDesc {
    fn default() -> Self {
        CameraDesc {
            pose: CameraPose::LookAt {
                position: Vec3::new(0.0, -4.5, 0.6),
                look_at: Vec3::ZERO,
                up: Vec3::Z,
            },
            lens: Lens::Vfov(40.0),
            shift: [0.0, 0.0],
        }
    }
}

/// Where the camera is and where it looks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CameraPose {
    /// `position`, `look_at`, `up` (need not be orthogonal to the view).
    LookAt {
        position: Vec3,
        look_at: Vec3,
        up: Vec3,
    },
    /// Blender's camera-to-world matrix (`matrix_world`, or `location` and
    /// `rotation`): the camera looks down its local −Z with local +Y up;
    /// scale is ignored.
    Matrix(DAffine3),
    /// `framing = "auto"`: aimed at the centre of the volumes' boxes (each
    /// volume's `bounds`) from `direction` (from the target towards the
    /// camera), far enough that the boxes' bounding sphere fills the view.
    Auto { direction: Vec3, up: Vec3 },
}

/// The direction an automatically framed camera sees the volumes from
/// (from the target towards the camera): a three-quarter view from the
/// front right and a little above, with Z up.
pub const AUTO_VIEW_DIRECTION: Vec3 = Vec3::new(1.0, -1.6, 0.7);

/// How wide the camera sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lens {
    /// Vertical field of view, degrees, in (0, 180).
    Vfov(f32),
    /// Blender's lens: focal length and sensor size in millimetres, and
    /// which image side the sensor spans.
    Sensor {
        focal_length: f32,
        sensor_width: f32,
        sensor_height: f32,
        fit: SensorFit,
    },
}

/// One `[[light]]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LightDesc {
    /// Distant light. `direction` points towards the light (not normalised);
    /// `irradiance` in W/m² on a surface facing the sun; `angle_deg` is the
    /// angular diameter (0 = delta light).
    Sun {
        direction: Vec3,
        irradiance: Rgb,
        angle_deg: f32,
    },
    /// Isotropic point light; `intensity` in W/sr.
    Point { position: Vec3, intensity: Rgb },
    /// Spot light. `direction` is the cone axis, pointing from the light into
    /// the scene (not normalised); `intensity` in W/sr on the axis;
    /// `cone_angle_deg` is the full cone angle; `blend` in [0, 1] is Blender's
    /// `spot_blend`.
    Spot {
        position: Vec3,
        direction: Vec3,
        intensity: Rgb,
        cone_angle_deg: f32,
        blend: f32,
    },
}

/// `[environment]`: what a ray that leaves every volume sees.
#[derive(Debug, Clone, PartialEq)]
pub enum EnvironmentDesc {
    /// Constant radiance (W·m⁻²·sr⁻¹).
    Constant(Rgb),
    /// Equirectangular HDR map, resolved path; radiance = texel × `strength`,
    /// map rotated by `rotate_z_deg` about +Z.
    Map {
        path: PathBuf,
        strength: f32,
        rotate_z_deg: f32,
    },
}

impl Default for EnvironmentDesc {
    fn default() -> Self {
        EnvironmentDesc::Constant(Rgb::ZERO)
    }
}

/// One `[[volume]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeDesc {
    /// The `.vdb` file, resolved against the scene file's directory.
    pub file: PathBuf,
    pub density_grid: String,
    pub temperature_grid: Option<String>,
    pub flame_grid: Option<String>,
    pub color_grid: Option<String>,
    /// How blackbody emission from the temperature grid is filtered between
    /// voxels (`blackbody_interpolation`).
    pub blackbody_filter: BlackbodyFilter,
    /// Scene transform, applied after the file's own index-to-world
    /// transform: `world = transform · file_transform · index`.
    pub transform: DAffine3,
    pub material: MaterialDesc,
    /// The box automatic camera framing uses for this volume.
    pub bounds: VolumeBounds,
    /// Frame `f` of a render reads frame `f + frame_offset` of this
    /// volume's sequence (Blender's Start Frame and Offset, or a fluid
    /// cache's offset).
    pub frame_offset: i64,
    /// `[ignition, max_temp]`: the temperature grid is made from the flame
    /// grid named by `temperature_grid` as Blender makes a fluid domain's
    /// temperature attribute (`ignition + flame · (max_temp − ignition)`
    /// where flame > 0.01, else 0), instead of read as it is.
    pub temperature_from_flame: Option<[f32; 2]>,
    /// The velocity grid that blurs the volume when motion blur is on
    /// (`velocity_grid`): a `vec3s` grid, or float grids `NAME.x`, `NAME.y`,
    /// `NAME.z`. `None`: `velocity`, else `vel` (Houdini), else none.
    pub velocity_grid: Option<String>,
    /// Multiplies the velocities (`velocity_scale`, Blender's Velocity
    /// Scale): per component of the grid's vectors, before `transform`
    /// (one number for all three, as Blender's; three reproduce how Cycles
    /// reads a fluid domain's velocity, in the domain object's space).
    pub velocity_scale: Vec3,
    /// What the velocities measure (`velocity_unit`).
    pub velocity_unit: VelocityUnit,
}

/// One `[[mesh]]`: a triangle mesh placed in the scene, with Blender's
/// object visibility.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshDesc {
    /// The object's name (`name`, Blender's), for messages; `None`: none
    /// given.
    pub name: Option<String>,
    /// The mesh file (`.ply` or `.obj`), resolved against the scene file's
    /// directory.
    pub file: PathBuf,
    /// Object to world (`transform`).
    pub transform: DAffine3,
    /// Blender's Object > Visibility > Mask > Holdout (`holdout`).
    pub holdout: bool,
    /// Blender's Object > Visibility > Mask > Shadow Catcher
    /// (`shadow_catcher`).
    pub shadow_catcher: bool,
    /// Blender's Object > Visibility > Ray Visibility (`visibility`).
    pub visibility: RayVisibility,
    /// Its material's surface shader (`[mesh.material]`); `None`: no
    /// material, which Cycles renders as its default surface (a Diffuse
    /// BSDF of colour 0.8).
    pub material: Option<SurfaceDesc>,
}

/// `[mesh.material]`: a surface shader of Blender's, with its names and
/// defaults.
#[derive(Debug, Clone, PartialEq)]
pub enum SurfaceDesc {
    /// The Principled BSDF as artists leave it for grounds and props.
    Principled(PrincipledBsdf),
    /// The Diffuse BSDF: Lambert, or Oren–Nayar when `roughness` > 0.
    Diffuse { color: ColorInput, roughness: f32 },
    /// The Emission shader: radiance `color` × `strength`, both sides.
    Emission { color: ColorInput, strength: f32 },
}

/// A colour input: a constant, or an Image Texture through the mesh's UV
/// map.
#[derive(Debug, Clone, PartialEq)]
pub enum ColorInput {
    Value(Rgb),
    Texture {
        /// Resolved against the scene file's directory.
        file: PathBuf,
        colorspace: TextureColorSpace,
    },
}

/// How an image's stored values become linear (Blender's Image › Color
/// Space).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TextureColorSpace {
    /// Blender's sRGB.
    #[default]
    Srgb,
    /// Blender's Linear Rec.709 and Non-Color: values as stored.
    Linear,
}

/// The Principled BSDF's inputs that vdbphoton shades (Blender 4/5 names
/// and defaults).
#[derive(Debug, Clone, PartialEq)]
pub struct PrincipledBsdf {
    pub base_color: ColorInput,
    pub roughness: f32,
    pub metallic: f32,
    pub ior: f32,
    pub specular_ior_level: f32,
    pub specular_tint: Rgb,
    pub emission_color: Rgb,
    pub emission_strength: f32,
}

impl Default for PrincipledBsdf {
    fn default() -> Self {
        Self {
            base_color: ColorInput::Value(Rgb::splat(0.8)),
            roughness: 0.5,
            metallic: 0.0,
            ior: 1.5,
            specular_ior_level: 0.5,
            specular_tint: Rgb::ONE,
            emission_color: Rgb::ONE,
            emission_strength: 0.0,
        }
    }
}

/// Which kinds of rays see an object (Blender's ray visibility; all of
/// them by default).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RayVisibility {
    pub camera: bool,
    pub shadow: bool,
    pub diffuse: bool,
    pub glossy: bool,
    pub transmission: bool,
    pub volume_scatter: bool,
}

impl Default for RayVisibility {
    fn default() -> Self {
        Self {
            camera: true,
            shadow: true,
            diffuse: true,
            glossy: true,
            transmission: true,
            volume_scatter: true,
        }
    }
}

impl MeshDesc {
    /// How messages name it: its `name`, else its file's name.
    pub fn label(&self) -> String {
        match &self.name {
            Some(n) => format!("'{n}'"),
            None => format!("'{}'", self.file.display()),
        }
    }
}

/// `[[volume]] bounds`: the box of a volume that automatic framing
/// (`[camera] framing = "auto"`) fits into the view.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum VolumeBounds {
    /// The active voxels of the frame being rendered.
    #[default]
    Active,
    /// The union of the active voxels of every frame of the sequence whose
    /// file exists: the framing stays fixed over the sequence.
    Sequence,
    /// The fluid domain the file was simulated in (Blender's Mantaflow
    /// writes its resolution as `file_base_resolution`; index (0,0,0) is
    /// the domain's corner): fixed over a sequence.
    Domain,
    /// A box `[min, max]` in the file's own world space (before the
    /// volume's `transform`), e.g. a fluid domain's box.
    Box([DVec3; 2]),
}

/// `[volume.material]`.
#[derive(Debug, Clone, PartialEq)]
pub enum MaterialDesc {
    /// Blender's Principled Volume; same names, same defaults.
    Principled(Principled),
    /// Raw coefficients per unit grid density, in world units⁻¹.
    Raw {
        sigma_a: Rgb,
        sigma_s: Rgb,
        /// Radiance added per unit length per unit density.
        emission: Rgb,
        phase: PhaseDesc,
    },
}

impl MaterialDesc {
    /// Blender's Principled Volume defaults.
    pub const PRINCIPLED_DEFAULT: MaterialDesc = MaterialDesc::Principled(Principled::DEFAULT);
}

impl Default for MaterialDesc {
    fn default() -> Self {
        MaterialDesc::PRINCIPLED_DEFAULT
    }
}

/// Phase function of a raw material.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum PhaseDesc {
    #[default]
    Isotropic,
    /// Henyey–Greenstein.
    Hg { g: f32 },
    /// Schlick's approximation of Henyey–Greenstein.
    Schlick { g: f32 },
    /// Weighted mix of HG lobes, `(g, weight)`; weights are not normalised
    /// (the renderer divides by their sum).
    HgMix(Vec<(f32, f32)>),
    /// Fournier–Forand as Cycles' Volume Scatter node has it: the fraction
    /// of light scattered backwards (by more than 90°), in [0, 0.5], and the
    /// particles' relative index of refraction, in [1, 2].
    FournierForand { backscatter: f32, ior: f32 },
    /// Draine: anisotropy `g` in [−1, 1] and `alpha` in [0, 500].
    Draine { g: f32, alpha: f32 },
    /// Rayleigh.
    Rayleigh,
    /// Cycles' Mie approximation for water droplets of `diameter`
    /// micrometres, in [0, 50].
    Mie { diameter: f32 },
}

/// `(sin, cos)` of an angle in degrees, exact for multiples of 90°.
fn sin_cos_deg(deg: f64) -> (f64, f64) {
    let r = deg.rem_euclid(360.0);
    if r == 0.0 {
        (0.0, 1.0)
    } else if r == 90.0 {
        (1.0, 0.0)
    } else if r == 180.0 {
        (0.0, -1.0)
    } else if r == 270.0 {
        (-1.0, 0.0)
    } else {
        deg.to_radians().sin_cos()
    }
}

/// Rotation from XYZ Euler angles in degrees, Blender's default order:
/// `Rz · Ry · Rx` (X is applied first).
pub fn euler_xyz_deg(rotate_deg: DVec3) -> DMat3 {
    let (sx, cx) = sin_cos_deg(rotate_deg.x);
    let (sy, cy) = sin_cos_deg(rotate_deg.y);
    let (sz, cz) = sin_cos_deg(rotate_deg.z);
    let rx = DMat3::from_cols(DVec3::X, DVec3::new(0.0, cx, sx), DVec3::new(0.0, -sx, cx));
    let ry = DMat3::from_cols(DVec3::new(cy, 0.0, -sy), DVec3::Y, DVec3::new(sy, 0.0, cy));
    let rz = DMat3::from_cols(DVec3::new(cz, sz, 0.0), DVec3::new(-sz, cz, 0.0), DVec3::Z);
    rz * ry * rx
}

/// `translate · Rz · Ry · Rx · scale` (angles in degrees): scale first, then
/// rotate about X, Y, Z, then translate — Blender's object transform.
pub fn compose_trs(translate: DVec3, rotate_deg: DVec3, scale: DVec3) -> DAffine3 {
    DAffine3::from_mat3_translation(
        euler_xyz_deg(rotate_deg) * DMat3::from_diagonal(scale),
        translate,
    )
}

/// Affine transform from a row-major 4×4 matrix; the last row is ignored
/// (the parser checks it is `0 0 0 1`).
pub fn affine_from_rows(m: [[f64; 4]; 4]) -> DAffine3 {
    DAffine3::from_cols(
        DVec3::new(m[0][0], m[1][0], m[2][0]),
        DVec3::new(m[0][1], m[1][1], m[2][1]),
        DVec3::new(m[0][2], m[1][2], m[2][2]),
        DVec3::new(m[0][3], m[1][3], m[2][3]),
    )
}

/// The inputs of Blender's Principled Volume node, with its names, units
/// and defaults (the optics in `crate::medium` compute with it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Principled {
    pub density: f32,
    pub color: Rgb,
    pub absorption_color: Rgb,
    /// Henyey–Greenstein g.
    pub anisotropy: f32,
    pub emission_strength: f32,
    pub emission_color: Rgb,
    pub blackbody_intensity: f32,
    pub blackbody_tint: Rgb,
    /// Kelvin.
    pub temperature: f32,
}

impl Principled {
    /// Blender's defaults.
    pub const DEFAULT: Principled = Principled {
        density: 1.0,
        color: Rgb::splat(0.5),
        absorption_color: Rgb::ZERO,
        anisotropy: 0.0,
        emission_strength: 0.0,
        emission_color: Rgb::ONE,
        blackbody_intensity: 0.0,
        blackbody_tint: Rgb::ONE,
        temperature: 1000.0,
    };

    /// The domain material of Blender's Quick Smoke with fire (Object >
    /// Quick Effects > Quick Smoke, "Fire + Smoke"): Density 5, Blackbody
    /// Intensity 1, the rest the node's defaults. Open values of a volume
    /// that names a temperature or flame grid take these.
    pub const QUICK_SMOKE_FIRE: Principled = Principled {
        density: 5.0,
        blackbody_intensity: 1.0,
        ..Self::DEFAULT
    };
}

impl Default for Principled {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// How blackbody emission from a temperature grid is filtered between
/// voxels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BlackbodyFilter {
    /// Interpolate the emitted radiance computed at each voxel: the mean of
    /// Cycles' stochastic one-tap lookups, so images match Blender.
    #[default]
    Emission,
    /// Interpolate the temperature, then compute its radiance: smoother
    /// (and, since T⁴ is convex, dimmer) between hot and cold voxels.
    Temperature,
}

impl BlackbodyFilter {
    /// The spelling used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            BlackbodyFilter::Emission => "emission",
            BlackbodyFilter::Temperature => "temperature",
        }
    }
}

/// Which image side the sensor spans (Blender's `sensor_fit`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SensorFit {
    /// `sensor_width` spans the longer side (Blender's default).
    #[default]
    Auto,
    /// `sensor_width` spans the width.
    Horizontal,
    /// `sensor_height` spans the height.
    Vertical,
}
