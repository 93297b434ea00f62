//! The command line's grammar (clap): commands, options and their parsers.
//! Values are parsed by the library's own parsers (`vdbphoton::units`,
//! `vdbphoton::sequence`), so a job script's value means the same.

use clap::{Parser, Subcommand, ValueEnum};
use std::path::PathBuf;
use vdbphoton::image::View;
use vdbphoton::units;

#[derive(Parser)]
#[command(
    name = "vdbphoton",
    version,
    about = "Physically based renderer for OpenVDB volumes"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Render a scene (TOML, or JSON by extension) to an EXR, and optionally
    /// a PNG preview. Command-line values override the scene's. Given a .vdb
    /// file instead of a scene, renders a quick look at it.
    Render(RenderArgs),
    /// A quick look at a .vdb file: a camera framing its grids, a sun and a
    /// sky, Blender's default material; writes FILE.png (and FILE.exr) in
    /// the working directory. Takes the same options as `render`.
    View(RenderArgs),
    /// Assemble the tiles of a frame (`render --tile I/N`), or average renders
    /// of the same pixels with different seeds, into one EXR.
    Merge {
        /// The merged EXR.
        out: PathBuf,
        /// The tiles or renders (EXRs vdbphoton wrote).
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Also write an 8-bit PNG preview here.
        #[arg(long)]
        preview: Option<PathBuf>,
        /// Preview exposure in stops (default: the inputs' own).
        #[arg(long, allow_negative_numbers = true)]
        exposure: Option<f32>,
        /// Preview view transform: standard, agx (Blender 4 and 5's default)
        /// or filmic (Blender 3's) (default: the inputs' own).
        #[arg(long, value_parser = parse_view)]
        view: Option<View>,
        /// Denoise the merged image with Intel Open Image Denoise 2.x (also
        /// without this when every input's render asked for it).
        #[arg(long)]
        denoise: bool,
    },
    /// Show the grids of .vdb files (like `vdb_print -l`): value type, voxel
    /// counts, index and world boxes, transform, value range, the memory
    /// a grid takes when loaded and the load time.
    Info {
        /// The .vdb files.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Only this grid (an unknown name or an unsupported type is an error).
        #[arg(long)]
        grid: Option<String>,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Compare an image with a reference: means, RMSE, relative MSE, PSNR.
    Compare {
        /// The image to judge (EXR).
        image: PathBuf,
        /// The reference (EXR), e.g. a Cycles render of the same scene.
        reference: PathBuf,
        /// Also write a false-colour difference image (PNG; red: image
        /// brighter, blue: darker, full colour at the largest difference).
        #[arg(long)]
        diff: Option<PathBuf>,
        /// Also write a PNG of the image, the reference and their difference
        /// side by side, with the figures written under them.
        #[arg(long)]
        side_by_side: Option<PathBuf>,
        /// Exposure of the side-by-side pictures, in stops.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        exposure: f32,
        /// View transform of the side-by-side pictures.
        #[arg(long, value_parser = parse_view, default_value = "standard")]
        view: View,
    },
    /// Write a grid as a dense Mitsuba `.vol` file (for comparison renders):
    /// the active bounding box padded by one voxel, cell centres on the
    /// voxel centres; the header's box is the world-space box of the cells.
    ExportVol {
        /// The .vdb file.
        file: PathBuf,
        /// Output .vol file.
        out: PathBuf,
        /// The grid to export.
        #[arg(long, default_value = "density")]
        grid: String,
    },
    /// List the integrators, with the keys of their settings tables.
    Integrators,
    /// Write a deterministic procedural volume as a .vdb file.
    Generate {
        /// What to make: a cloud (one `density` grid) or a plume laid out like
        /// Blender's smoke caches (density, flame, temperature, velocity).
        kind: Kind,
        /// Output .vdb file.
        out: PathBuf,
        /// Voxels along the longest edge (8 to 2048).
        #[arg(long, default_value_t = 128)]
        res: u32,
        /// Random seed: the same seed gives the same file.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
}

#[derive(clap::Args)]
pub struct RenderArgs {
    /// The scene file (or a .vdb file for a quick look).
    pub scene: PathBuf,
    /// Output EXR (default: the scene's `output`); may hold {frame:04},
    /// #### or {tile}.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Samples per pixel (at least 1).
    #[arg(long, value_parser = units::parse_count, allow_negative_numbers = true)]
    pub spp: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = units::parse_count, allow_negative_numbers = true)]
    pub threads: Option<u32>,
    /// Random seed.
    #[arg(long, value_parser = units::parse_seed, allow_negative_numbers = true)]
    pub seed: Option<u64>,
    /// Image width in pixels.
    #[arg(long, value_parser = units::parse_count, allow_negative_numbers = true)]
    pub width: Option<u32>,
    /// Image height in pixels.
    #[arg(long, value_parser = units::parse_count, allow_negative_numbers = true)]
    pub height: Option<u32>,
    /// Also write an 8-bit sRGB PNG preview here.
    #[arg(long)]
    pub preview: Option<PathBuf>,
    /// Preview exposure in stops.
    #[arg(long, allow_negative_numbers = true)]
    pub exposure: Option<f32>,
    /// Preview view transform: standard, agx (Blender 4 and 5's default) or
    /// filmic (Blender 3's).
    #[arg(long, value_parser = parse_view)]
    pub view: Option<View>,
    /// Write AOV layers (direct, indirect, emission, transmittance; with meshes also diffuse_direct, diffuse_indirect, glossy_direct, glossy_indirect).
    #[arg(long)]
    pub aovs: bool,
    /// Denoise the image with Intel Open Image Denoise 2.x (the EXR keeps
    /// the raw render as the layer `noisy`; tiles are denoised by `merge`).
    #[arg(long)]
    pub denoise: bool,
    /// The denoiser's quality: high (default), balanced or fast (about 60 %
    /// of high's time and memory, somewhat more error).
    #[arg(long, value_parser = parse_denoise_quality)]
    pub denoise_quality: Option<vdbphoton::scene::DenoiseQuality>,
    /// Write no PNG preview, whatever the scene says.
    #[arg(long, conflicts_with = "preview")]
    pub no_preview: bool,
    /// The integrator (overrides the scene's `integrator`): auto, or one
    /// of `vdbphoton integrators`.
    #[arg(long, value_parser = parse_integrator)]
    pub integrator: Option<String>,
    /// Render passes until this wall-clock time (e.g. 90, 90s, 5m, 1h)
    /// instead of until the sample count.
    #[arg(long, value_parser = units::parse_duration)]
    pub time: Option<std::time::Duration>,
    /// Rewrite the outputs this often during the render (e.g. 60s), with
    /// the state `--resume` goes on from (OUTPUT.vdbstate); a SIGTERM or
    /// SIGINT then finishes the pass in progress and writes a last
    /// checkpoint before the render stops.
    #[arg(long, value_parser = units::parse_duration)]
    pub checkpoint: Option<std::time::Duration>,
    /// Go on from the state the last checkpoint of a killed render left
    /// beside the EXR, when it is this render's (same scene, settings and
    /// build); the image is then the one the render would have made
    /// uninterrupted, and --time counts the time already spent. Without a
    /// state, or with another render's, the render starts afresh (with a
    /// warning for the latter).
    #[arg(long)]
    pub resume: bool,
    /// Checkpoints without the resume state (previews only: the Blender
    /// add-on's display while it renders).
    #[arg(long, requires = "checkpoint")]
    pub no_resume_state: bool,
    /// Memory the render may use (e.g. 8G, 512M; default: what the machine
    /// has available). A render that needs more is refused before it
    /// starts.
    #[arg(long, value_parser = units::parse_bytes)]
    pub max_memory: Option<u64>,
    /// Render these frames of a sequence: 1-40, 1-3,5,7-20:2 (frame patterns
    /// in the scene's paths are filled in; seeds derive from (seed, frame)).
    #[arg(long, value_parser = parse_frame_list, conflicts_with = "frame")]
    pub frames: Option<FrameList>,
    /// Render one frame of a sequence.
    #[arg(long, value_parser = parse_frame)]
    pub frame: Option<u32>,
    /// Leave frames whose EXR already exists (resumes a sequence).
    #[arg(long)]
    pub skip_existing: bool,
    /// Render only these pixels: X0,Y0,X1,Y1 (end exclusive); the EXR's data
    /// window is the region inside the whole image.
    #[arg(long, conflicts_with = "tile")]
    pub region: Option<String>,
    /// Render only tile I of N (0 <= I < N) of a fixed grid; `merge`
    /// assembles the tiles.
    #[arg(long, value_parser = units::parse_tile)]
    pub tile: Option<(u32, u32)>,
    /// No progress output (the summary line is still printed).
    #[arg(short, long)]
    pub quiet: bool,
    /// How progress is shown on stderr: `text` (a bar, or a line every
    /// 10 %) or `json`: one JSON object a line for programs (the Blender
    /// add-on): {"event": "progress", "fraction", "passes", "elapsed",
    /// "eta"}, "checkpoint" {"path", "passes"}, "saved" {"path"},
    /// "warning" {"message"}, "resumed" {"path", "passes", "seconds"},
    /// "frame" {"frame", "index", "count"}; errors stay plain
    /// `vdbphoton: error: ...` lines.
    #[arg(long, value_parser = ["text", "json"], default_value = "text")]
    pub progress: String,
    /// The version of the Blender add-on that runs this render (it passes
    /// its own): a render is refused, before any work, when this binary
    /// does not speak that add-on's progress stream and options.
    #[arg(long, hide = true)]
    pub addon_version: Option<String>,
    /// Real scattering events at most along a path (overrides the scene's
    /// `max_bounces`).
    #[arg(long, value_parser = units::parse_count, allow_negative_numbers = true)]
    pub max_bounces: Option<u32>,
}

/// The frames of `--frames` (a type of its own: clap takes a bare `Vec` for
/// an option given several times).
#[derive(Debug, Clone)]
pub struct FrameList(pub Vec<u32>);

fn parse_frame_list(s: &str) -> std::result::Result<FrameList, String> {
    vdbphoton::sequence::parse_frames(s).map(FrameList)
}

fn parse_frame(s: &str) -> std::result::Result<u32, String> {
    match vdbphoton::sequence::parse_frames(s) {
        Ok(f) if f.len() == 1 => Ok(f[0]),
        _ => Err(format!(
            "must be one frame number from 0 to {} (use --frames for several)",
            vdbphoton::sequence::MAX_FRAME
        )),
    }
}

/// A denoising quality: high, balanced or fast.
fn parse_denoise_quality(s: &str) -> std::result::Result<vdbphoton::scene::DenoiseQuality, String> {
    vdbphoton::scene::DenoiseQuality::parse(s)
        .ok_or_else(|| format!("'{s}' is not a denoising quality: high, balanced or fast"))
}

/// An integrator's name: `auto` or a registered one.
fn parse_integrator(s: &str) -> std::result::Result<String, String> {
    let names = vdbphoton::integrator::names();
    if names.contains(&s) {
        Ok(s.to_string())
    } else {
        Err(format!(
            "'{s}' is not an integrator: one of {}",
            names.join(", ")
        ))
    }
}

pub fn parse_view(s: &str) -> std::result::Result<View, String> {
    View::parse(s)
}

#[derive(Clone, Copy, ValueEnum)]
pub enum Kind {
    Cloud,
    Plume,
}
