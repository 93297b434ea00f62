//! The `vdbphoton` command line. Parsing and printing only: the work is in
//! the library.

use clap::{Parser, Subcommand, ValueEnum};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;
use vdbphoton::image::View;
use vdbphoton::vdb::{self, AnyGrid, VdbFile};
use vdbphoton::{generate, Error, Result};

#[derive(Parser)]
#[command(
    name = "vdbphoton",
    version,
    about = "Physically based renderer for OpenVDB volumes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
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
struct RenderArgs {
    /// The scene file (or a .vdb file for a quick look).
    scene: PathBuf,
    /// Output EXR (default: the scene's `output`); may hold {frame:04},
    /// #### or {tile}.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Samples per pixel (at least 1).
    #[arg(long, value_parser = parse_count, allow_negative_numbers = true)]
    spp: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = parse_count, allow_negative_numbers = true)]
    threads: Option<u32>,
    /// Random seed.
    #[arg(long, value_parser = parse_seed, allow_negative_numbers = true)]
    seed: Option<u64>,
    /// Image width in pixels.
    #[arg(long, value_parser = parse_count, allow_negative_numbers = true)]
    width: Option<u32>,
    /// Image height in pixels.
    #[arg(long, value_parser = parse_count, allow_negative_numbers = true)]
    height: Option<u32>,
    /// Also write an 8-bit sRGB PNG preview here.
    #[arg(long)]
    preview: Option<PathBuf>,
    /// Preview exposure in stops.
    #[arg(long, allow_negative_numbers = true)]
    exposure: Option<f32>,
    /// Preview view transform: standard, agx (Blender 4 and 5's default) or
    /// filmic (Blender 3's).
    #[arg(long, value_parser = parse_view)]
    view: Option<View>,
    /// Write AOV layers (direct, indirect, emission, transmittance).
    #[arg(long)]
    aovs: bool,
    /// Denoise the image with Intel Open Image Denoise 2.x (the EXR keeps
    /// the raw render as the layer `noisy`; tiles are denoised by `merge`).
    #[arg(long)]
    denoise: bool,
    /// Write no PNG preview, whatever the scene says.
    #[arg(long, conflicts_with = "preview")]
    no_preview: bool,
    /// The integrator (overrides the scene's `integrator`).
    #[arg(long, value_enum)]
    integrator: Option<IntegratorArg>,
    /// Render passes until this wall-clock time (e.g. 90, 90s, 5m, 1h)
    /// instead of until the sample count.
    #[arg(long, value_parser = parse_duration)]
    time: Option<std::time::Duration>,
    /// Rewrite the outputs this often during the render (e.g. 60s).
    #[arg(long, value_parser = parse_duration)]
    checkpoint: Option<std::time::Duration>,
    /// Memory the render may use (e.g. 8G, 512M; default: what the machine
    /// has available). A render that needs more is refused before it
    /// starts.
    #[arg(long, value_parser = parse_bytes)]
    max_memory: Option<u64>,
    /// Render these frames of a sequence: 1-40, 1-3,5,7-20:2 (frame patterns
    /// in the scene's paths are filled in; seeds derive from (seed, frame)).
    #[arg(long, value_parser = parse_frame_list, conflicts_with = "frame")]
    frames: Option<FrameList>,
    /// Render one frame of a sequence.
    #[arg(long, value_parser = parse_frame)]
    frame: Option<u32>,
    /// Leave frames whose EXR already exists (resumes a sequence).
    #[arg(long)]
    skip_existing: bool,
    /// Render only these pixels: X0,Y0,X1,Y1 (end exclusive); the EXR's data
    /// window is the region inside the whole image.
    #[arg(long, conflicts_with = "tile")]
    region: Option<String>,
    /// Render only tile I of N (0 <= I < N) of a fixed grid; `merge`
    /// assembles the tiles.
    #[arg(long, value_parser = parse_tile)]
    tile: Option<(u32, u32)>,
    /// No progress output (the summary line is still printed).
    #[arg(short, long)]
    quiet: bool,
}

/// A count given on the command line: a whole number, at least 1.
fn parse_count(s: &str) -> std::result::Result<u32, String> {
    match s.trim().parse::<i64>() {
        Ok(v) if (1..=u32::MAX as i64).contains(&v) => Ok(v as u32),
        Ok(_) => Err(format!("must be a whole number from 1 to {}", u32::MAX)),
        Err(_) => Err("must be a whole number, at least 1".to_string()),
    }
}

fn parse_seed(s: &str) -> std::result::Result<u64, String> {
    s.trim()
        .parse::<u64>()
        .map_err(|_| format!("must be a whole number from 0 to {}", u64::MAX))
}

/// The frames of `--frames` (a type of its own: clap takes a bare `Vec` for
/// an option given several times).
#[derive(Debug, Clone)]
struct FrameList(Vec<u32>);

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

fn parse_tile(s: &str) -> std::result::Result<(u32, u32), String> {
    let bad = || format!("'{s}' is not a tile: write I/N, tile I (from 0) of N, e.g. 3/16");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n): (u32, u32) = (
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || i >= n {
        return Err(format!("'{s}': the tile I of I/N must be 0 to N-1"));
    }
    Ok((i, n))
}

fn parse_view(s: &str) -> std::result::Result<View, String> {
    View::parse(s)
}

#[derive(Clone, Copy, ValueEnum)]
enum IntegratorArg {
    Path,
    Photon,
    Auto,
}

impl From<IntegratorArg> for vdbphoton::scene::Integrator {
    fn from(a: IntegratorArg) -> Self {
        match a {
            IntegratorArg::Path => Self::Path,
            IntegratorArg::Photon => Self::Photon,
            IntegratorArg::Auto => Self::Auto,
        }
    }
}

fn parse_bytes(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let (num, scale) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let scale: u64 = match c.to_ascii_uppercase() {
                'K' => 1 << 10,
                'M' => 1 << 20,
                'G' => 1 << 30,
                'T' => 1 << 40,
                _ => {
                    return Err(format!(
                        "'{s}' is not an amount of memory: use a number of bytes or K, M, G, T (e.g. 8G)"
                    ))
                }
            };
            (&t[..i], scale)
        }
        _ => (t, 1),
    };
    let v: f64 = num
        .parse()
        .map_err(|_| format!("'{s}' is not an amount of memory (e.g. 8G, 512M)"))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("'{s}': the memory must be more than 0"));
    }
    Ok((v * scale as f64) as u64)
}

fn parse_duration(s: &str) -> std::result::Result<std::time::Duration, String> {
    vdbphoton::render::parse_duration(s)
}

#[derive(Clone, Copy, ValueEnum)]
enum Kind {
    Cloud,
    Plume,
}

fn human_bytes(b: u64) -> String {
    const U: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < U.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.1} {}", U[u])
    }
}

struct Loaded {
    grid: AnyGrid,
    seconds: f64,
}

/// Prints the grids of `file` (as text), or returns them as JSON.
fn info(file: &std::path::Path, only: Option<String>, json: bool) -> Result<serde_json::Value> {
    let vdb = VdbFile::open(file)?;
    let names: Vec<String> = match &only {
        Some(g) => vec![vdb.descriptor(g)?.name.clone()],
        None => vdb.grid_names().iter().map(|s| s.to_string()).collect(),
    };
    // Load each supported grid into the Rust grid (an explicitly named grid
    // must load; in a listing, unsupported grids are shown, not loaded).
    let mut loaded = Vec::new();
    for n in &names {
        let d = vdb.descriptor(n)?;
        if d.channels().is_none() && only.is_none() {
            loaded.push(None);
            continue;
        }
        let t0 = Instant::now();
        let grid = vdb.read_any(n)?;
        loaded.push(Some(Loaded {
            grid,
            seconds: t0.elapsed().as_secs_f64(),
        }));
    }
    let finfo = vdb.info()?;
    let h = vdb.header();
    if json {
        let grids: Vec<serde_json::Value> = names
            .iter()
            .zip(&loaded)
            .map(|(n, l)| {
                let gi = finfo.grids.iter().find(|g| &g.name == n);
                let d = vdb.descriptor(n).ok();
                let mut o = serde_json::json!({
                    "name": n,
                    "value_type": d.map(|d| d.value_type().to_string()),
                    "supported": l.is_some(),
                });
                if let Some(gi) = gi {
                    o["grid_class"] = gi.grid_class.clone().into();
                    o["voxel_size"] = serde_json::json!(gi.voxel_size);
                    o["map_type"] = gi.map_type.clone().into();
                    o["world_from_index"] = serde_json::json!(gi.world_from_index);
                    o["metadata"] = gi
                        .metadata
                        .iter()
                        .map(|m| (m.name.clone(), serde_json::Value::from(m.value.clone())))
                        .collect::<serde_json::Map<_, _>>()
                        .into();
                }
                if let Some(l) = l {
                    o["active_voxels"] = l.grid.active_voxel_count().into();
                    o["memory_bytes"] = (l.grid.memory_bytes() as u64).into();
                    o["load_seconds"] = l.seconds.into();
                    let (bounds, bricks, tiles) = grid_summary(&l.grid);
                    o["index_bbox"] = serde_json::json!(bounds);
                    if let (Some(b), Some(gi)) = (bounds, gi) {
                        let [lo, hi] = world_box(gi, b);
                        o["world_bbox"] = serde_json::json!([lo, hi]);
                    }
                    o["bricks"] = bricks.into();
                    o["tiles"] = serde_json::json!(tiles);
                }
                o
            })
            .collect();
        let out = serde_json::json!({
            "file": file.display().to_string(),
            "file_bytes": h.file_size,
            "file_version": h.file_version,
            "library_version": format!("{}.{}", h.library_version.0, h.library_version.1),
            "metadata": finfo.metadata.iter().map(|m| (m.name.clone(), serde_json::Value::from(m.value.clone()))).collect::<serde_json::Map<_, _>>(),
            "grids": grids,
        });
        return Ok(out);
    }
    println!(
        "{}: {} ({} grid{}, VDB format {}, written by OpenVDB {}.{})",
        file.display(),
        human_bytes(h.file_size),
        h.grids.len(),
        if h.grids.len() == 1 { "" } else { "s" },
        h.file_version,
        h.library_version.0,
        h.library_version.1
    );
    for m in &finfo.metadata {
        println!("  {}: {}", m.name, m.value);
    }
    for (n, l) in names.iter().zip(&loaded) {
        let d = vdb.descriptor(n)?;
        let gi = finfo.grids.iter().find(|g| &g.name == n);
        let class = gi.map(|g| g.grid_class.as_str()).unwrap_or("?");
        println!("{n}  {}  {class}", d.value_type());
        let Some(l) = l else {
            println!(
                "  (value type {} is not supported by vdbphoton: not loaded)",
                d.value_type()
            );
            continue;
        };
        let (bounds, bricks, tiles) = grid_summary(&l.grid);
        if let (Some(b), Some(gi)) = (bounds, gi) {
            let [lo, hi] = world_box(gi, b);
            println!(
                "  world box [{:.4}, {:.4}, {:.4}] -> [{:.4}, {:.4}, {:.4}]  (size {:.4} x {:.4} x {:.4}; voxels reach half a voxel past their centres)",
                lo[0],
                lo[1],
                lo[2],
                hi[0],
                hi[1],
                hi[2],
                hi[0] - lo[0],
                hi[1] - lo[1],
                hi[2] - lo[2]
            );
        }
        match bounds {
            Some([lo, hi]) => println!(
                "  active voxels {}   index bbox [{},{},{}] -> [{},{},{}]  ({} x {} x {})",
                l.grid.active_voxel_count(),
                lo[0],
                lo[1],
                lo[2],
                hi[0],
                hi[1],
                hi[2],
                hi[0] - lo[0] + 1,
                hi[1] - lo[1] + 1,
                hi[2] - lo[2] + 1
            ),
            None => println!("  empty (no active voxels)"),
        }
        if let Some(gi) = gi {
            let v = gi.voxel_size;
            println!(
                "  voxel size {} x {} x {}   transform {} (linear)",
                v[0], v[1], v[2], gi.map_type
            );
            let m = gi.world_from_index;
            println!(
                "  world_from_index [{} {} {} {}; {} {} {} {}; {} {} {} {}]",
                m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9], m[10], m[11]
            );
        }
        println!(
            "  bricks {}   tiles 8^3: {}  128^3: {}  4096^3: {}",
            bricks, tiles[0], tiles[1], tiles[2]
        );
        match &l.grid {
            AnyGrid::Float(g) => {
                if let Some([a, b]) = g.value_range() {
                    println!("  values {a} .. {b}   background {}", g.background());
                }
            }
            AnyGrid::Vec3(g) => println!("  background {}", g.background()),
        }
        println!(
            "  memory when rendered {}   load {:.1} ms",
            human_bytes(l.grid.memory_bytes() as u64),
            l.seconds * 1e3
        );
    }
    Ok(serde_json::Value::Null)
}

/// The world-space box of the voxels `[lo, hi]` (index, inclusive) of a
/// grid.
fn world_box(gi: &vdb::GridInfo, [lo, hi]: [[i32; 3]; 2]) -> [[f64; 3]; 2] {
    let d = |v: [i32; 3]| glam::DVec3::from(v.map(f64::from));
    vdbphoton::world::index_box(gi, d(lo), d(hi)).map(|v| v.to_array())
}

type Summary = (Option<[[i32; 3]; 2]>, usize, [usize; 3]);

fn grid_summary(g: &AnyGrid) -> Summary {
    fn s<T: vdbphoton::grid::GridValue>(g: &vdbphoton::grid::Grid<T>) -> Summary {
        let mut tiles = [0; 3];
        for t in g.tiles() {
            tiles[(t.level as usize).clamp(1, 3) - 1] += 1;
        }
        (
            g.active_bounds().map(|(a, b)| [a.to_array(), b.to_array()]),
            g.brick_count(),
            tiles,
        )
    }
    match g {
        AnyGrid::Float(g) => s(g),
        AnyGrid::Vec3(g) => s(g),
    }
}

/// The command line's reporter: progress on stderr (a bar on a terminal, a
/// line every 10 % otherwise, for farm logs), `Saved: 'PATH'` on stdout
/// for every file a finished render writes (the line Flamenco reads).
struct CliReporter {
    quiet: bool,
    tty: bool,
    last_decile: std::sync::atomic::AtomicUsize,
    throttle: vdbphoton::render::Throttle,
    /// "frame N: " while a sequence renders.
    frame: std::sync::Mutex<String>,
}

impl vdbphoton::render::Reporter for CliReporter {
    fn warning(&self, m: &str) {
        self.end_bar();
        eprintln!("vdbphoton: warning: {m}");
    }
    fn progress(&self, p: vdbphoton::render::Progress) {
        if self.quiet {
            return;
        }
        let eta = p.eta.map_or("?".to_string(), |e| format!("{e:.0}s"));
        let frame = self.frame.lock().map(|f| f.clone()).unwrap_or_default();
        if self.tty {
            if !self.throttle.ready(p.fraction >= 1.0) {
                return;
            }
            let n = ((p.fraction * 30.0) as usize).min(30);
            eprint!(
                "\r{frame}rendering [{}{}] {:5.1}%  pass {}  {:.0}s elapsed, ETA {eta} ",
                "#".repeat(n),
                " ".repeat(30 - n),
                p.fraction * 100.0,
                p.passes + 1,
                p.elapsed
            );
        } else {
            let decile = (p.fraction * 10.0) as usize;
            if decile
                > self
                    .last_decile
                    .fetch_max(decile, std::sync::atomic::Ordering::Relaxed)
            {
                eprintln!(
                    "{frame}rendering: {:3.0}% ({:.1} s elapsed, ETA {eta})",
                    decile as f64 * 10.0,
                    p.elapsed
                );
            }
        }
    }
    fn checkpoint(&self, path: &std::path::Path, passes: u32) {
        if !self.quiet {
            self.end_bar();
            eprintln!("checkpoint: {} after {passes} passes", path.display());
        }
    }
    fn saved(&self, path: &std::path::Path) {
        self.end_bar();
        println!("Saved: '{}'", path.display());
        let _ = std::io::Write::flush(&mut std::io::stdout());
    }
    fn frame_started(&self, frame: u32, index: usize, count: usize) {
        self.last_decile
            .store(0, std::sync::atomic::Ordering::Relaxed);
        if let Ok(mut f) = self.frame.lock() {
            *f = format!("frame {frame} ({}/{count}): ", index + 1);
        }
    }
    fn frame_done(&self, frame: u32, outcome: &vdbphoton::frames::FrameOutcome, seconds: f64) {
        use vdbphoton::frames::FrameOutcome;
        self.end_bar();
        match outcome {
            FrameOutcome::Written(s) => {
                eprintln!("frame {frame}: {} ({seconds:.2} s)", summary_line(s))
            }
            FrameOutcome::Skipped(p) => {
                eprintln!("frame {frame}: skipped, '{}' exists", p.display())
            }
            FrameOutcome::Failed(e) => {
                eprintln!("vdbphoton: error: frame {frame}: {}", one_line(e))
            }
        }
    }
}

impl CliReporter {
    /// Ends a progress bar's line before other output.
    fn end_bar(&self) {
        if self.tty && !self.quiet {
            eprint!("\r\x1b[K");
        }
    }
}

fn summary_line(s: &vdbphoton::render::Summary) -> String {
    format!(
        "rendered {} x {} with {} ({} passes, {} spp) in {:.2} s  (load {:.2} s, write {:.2} s, {} threads)",
        s.width,
        s.height,
        s.integrator,
        s.passes,
        s.spp,
        s.render_seconds,
        s.load_seconds,
        s.write_seconds,
        s.threads
    )
}

fn render(a: RenderArgs, quick_look: bool) -> Result<()> {
    use std::io::IsTerminal;
    use vdbphoton::frames::{render_job, FrameJob, FrameOutcome};
    use vdbphoton::render::RenderOptions;
    use vdbphoton::scene::SceneDesc;
    let t_start = Instant::now();
    let reporter = CliReporter {
        quiet: a.quiet,
        tty: std::io::stderr().is_terminal(),
        last_decile: std::sync::atomic::AtomicUsize::new(0),
        throttle: vdbphoton::render::Throttle::new(std::time::Duration::from_millis(200)),
        frame: std::sync::Mutex::new(String::new()),
    };
    let quick_look = quick_look || vdbphoton::quicklook::is_vdb(&a.scene);
    let mut desc = if quick_look {
        let (desc, notes) = vdbphoton::quicklook::scene_for(&a.scene)?;
        if !a.quiet {
            for n in notes {
                eprintln!("quick look: {n}");
            }
        }
        desc
    } else {
        SceneDesc::load(&a.scene)?
    };
    let r = &mut desc.render;
    // Command-line paths are relative to the working directory.
    if let Some(o) = a.output {
        // A preview the scene asks for follows the output the user chose,
        // instead of overwriting the scene's own preview file.
        if a.preview.is_none() && r.preview.is_some() {
            r.preview = Some(o.with_extension("png"));
        }
        r.output = o;
    }
    if let Some(p) = a.preview {
        r.preview = Some(p);
    }
    if a.no_preview {
        r.preview = None;
    }
    if let Some(v) = a.spp {
        r.spp = v;
    }
    if let Some(v) = a.seed {
        r.seed = v;
    }
    if let Some(v) = a.width {
        r.width = v;
    }
    if let Some(v) = a.height {
        r.height = v;
    }
    if let Some(v) = a.exposure {
        r.exposure = v;
    }
    if let Some(i) = a.integrator {
        r.integrator = i.into();
    }
    r.aovs |= a.aovs;
    r.denoise |= a.denoise;
    desc.validate().map_err(|e| {
        Error::Argument(format!(
            "{}: after the command-line options: {e}",
            a.scene.display()
        ))
    })?;
    let region = a
        .region
        .as_deref()
        .map(|s| {
            vdbphoton::film::Region::parse(s, desc.render.width, desc.render.height)
                .map_err(Error::Argument)
        })
        .transpose()?;
    let opts = RenderOptions {
        threads: a.threads.map(|t| t as usize),
        time_limit: a.time,
        checkpoint: a.checkpoint,
        max_memory: a.max_memory,
        attributes: vec![("vdbphoton/scene".to_string(), a.scene.display().to_string())],
        region,
        tile: a.tile,
        view: a.view.unwrap_or_default(),
    };
    let job = FrameJob {
        frames: a.frames.map(|f| f.0).or(a.frame.map(|f| vec![f])),
        skip_existing: a.skip_existing,
    };
    let report = render_job(&desc, &job, &opts, &reporter).map_err(|e| {
        // Errors about the scene's inputs say which scene.
        match e {
            e @ (Error::Scene(_) | Error::Interrupted { .. } | Error::Argument(_)) => e,
            e if quick_look => e,
            e => e.context(a.scene.display().to_string()),
        }
    })?;
    // The summary is printed even with --quiet: it is the line a farm log
    // wants.
    let total = t_start.elapsed().as_secs_f64();
    match report.frames.as_slice() {
        [(None, FrameOutcome::Written(s))] => {
            eprintln!("{} (total {total:.2} s)", summary_line(s))
        }
        [(None, FrameOutcome::Skipped(p))] => {
            eprintln!("skipped: '{}' exists", p.display())
        }
        frames => {
            let count = |f: fn(&FrameOutcome) -> bool| frames.iter().filter(|(_, o)| f(o)).count();
            let written = count(|o| matches!(o, FrameOutcome::Written(_)));
            let skipped = count(|o| matches!(o, FrameOutcome::Skipped(_)));
            let failed = report.failed();
            eprintln!(
                "frames: {written} written, {skipped} skipped, {} failed{} in {total:.2} s",
                failed.len(),
                if failed.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", vdbphoton::sequence::format_frames(&failed))
                }
            );
        }
    }
    if !report.ok() {
        let failed = report.failed();
        return Err(Error::Argument(format!(
            "{} of {} frames failed: {}",
            failed.len(),
            report.frames.len(),
            vdbphoton::sequence::format_frames(&failed)
        )));
    }
    Ok(())
}

/// Mitsuba's binary volume format: "VOL", version 3, encoding 1 (float32),
/// x/y/z resolution, channels, bounding box (6 floats), then the values with
/// x varying fastest.
fn export_vol(file: &std::path::Path, out: &std::path::Path, grid: &str) -> Result<()> {
    let g = VdbFile::open(file)?.read_float(grid)?;
    let m = g.world_from_index().matrix3;
    if m.x_axis.y != 0.0
        || m.x_axis.z != 0.0
        || m.y_axis.x != 0.0
        || m.y_axis.z != 0.0
        || m.z_axis.x != 0.0
        || m.z_axis.y != 0.0
    {
        return Err(Error::grid(
            file,
            grid,
            "export-vol needs an axis-aligned (scale and translate) transform",
        ));
    }
    let (lo, hi) = g
        .active_bounds()
        .ok_or_else(|| Error::grid(file, grid, "the grid has no active voxels"))?;
    let (lo, hi) = (lo - 1, hi + 1);
    let res = hi - lo + 1;
    let mut bytes: Vec<u8> = b"VOL".to_vec();
    bytes.push(3);
    for v in [1i32, res.x, res.y, res.z, 1] {
        bytes.extend(v.to_le_bytes());
    }
    let wlo = g.index_to_world(lo.as_dvec3() - 0.5);
    let whi = g.index_to_world(hi.as_dvec3() + 0.5);
    for v in [wlo.x, wlo.y, wlo.z, whi.x, whi.y, whi.z] {
        bytes.extend((v as f32).to_le_bytes());
    }
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                bytes.extend(g.get(glam::IVec3::new(x, y, z)).to_le_bytes());
            }
        }
    }
    vdbphoton::atomic::replace_with(
        out,
        |tmp| std::fs::write(tmp, &bytes).map_err(|e| Error::io(out, e)),
        |e| Error::io(out, e),
    )?;
    eprintln!(
        "wrote {} ({} x {} x {} voxels, world box {:?} .. {:?})",
        out.display(),
        res.x,
        res.y,
        res.z,
        wlo.to_array(),
        whi.to_array()
    );
    Ok(())
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(a) => render(a, false),
        Command::View(a) => render(a, true),
        Command::Merge {
            out,
            inputs,
            preview,
            exposure,
            view,
            denoise,
        } => {
            let m = vdbphoton::merge::merge(
                &out,
                &inputs,
                &vdbphoton::merge::MergeOptions {
                    preview: preview.as_deref(),
                    exposure,
                    view,
                    denoise,
                },
            )?;
            for p in &m.outputs {
                println!("Saved: '{}'", p.display());
            }
            let groups: Vec<String> = m
                .groups
                .iter()
                .map(|(seed, n)| format!("{n} with seed {seed}"))
                .collect();
            eprintln!(
                "merged {} inputs ({}) into {} x {}, {} spp",
                inputs.len(),
                groups.join(", "),
                m.width,
                m.height,
                m.spp
            );
            Ok(())
        }
        Command::ExportVol { file, out, grid } => export_vol(&file, &out, &grid),
        Command::Compare {
            image,
            reference,
            diff,
            side_by_side,
            exposure,
            view,
        } => {
            let a = vdbphoton::image::read_exr_rgb(&image)?;
            let b = vdbphoton::image::read_exr_rgb(&reference)?;
            let m = vdbphoton::image::compare(&a, &b)?;
            println!(
                "mean {:.6}  reference mean {:.6}  ratio {:.5}  RMSE {:.6}  relMSE {:.3e}  PSNR {:.2} dB",
                m.mean_a, m.mean_b, m.mean_ratio, m.rmse, m.rel_mse, m.psnr
            );
            if let Some(d) = diff {
                let scale = vdbphoton::image::write_diff_png(&d, &a, &b)?;
                eprintln!(
                    "wrote {} (full colour at |difference| = {scale:.4})",
                    d.display()
                );
            }
            if let Some(p) = side_by_side {
                let name = |p: &std::path::Path| {
                    p.file_name()
                        .map_or(String::new(), |n| n.to_string_lossy().into_owned())
                };
                vdbphoton::image::write_side_by_side(
                    &p,
                    &a,
                    &b,
                    &name(&image),
                    &name(&reference),
                    &m,
                    exposure,
                    view,
                )?;
                eprintln!("wrote {}", p.display());
            }
            Ok(())
        }
        Command::Info { files, grid, json } => {
            // Every file is shown; one that cannot be read is an error
            // line, the others still print, and the exit code says so.
            let mut failed = 0;
            let mut out = Vec::new();
            for f in &files {
                match info(f, grid.clone(), json) {
                    Ok(v) => out.push(v),
                    Err(e) if files.len() > 1 => {
                        eprintln!("vdbphoton: error: {}", one_line(&e));
                        failed += 1;
                    }
                    Err(e) => return Err(e),
                }
            }
            if json {
                let v = if files.len() == 1 {
                    out.pop().unwrap_or_default()
                } else {
                    serde_json::Value::Array(out)
                };
                println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
            }
            if failed > 0 {
                return Err(Error::Argument(format!(
                    "{failed} of {} files could not be read",
                    files.len()
                )));
            }
            Ok(())
        }
        Command::Generate {
            kind,
            out,
            res,
            seed,
        } => {
            let t0 = Instant::now();
            let grids = match kind {
                Kind::Cloud => vec![AnyGrid::Float(generate::cloud(res, seed)?)],
                Kind::Plume => generate::plume(res, seed)?,
            };
            vdb::write_vdb(&out, &grids)?;
            let voxels: u64 = grids.iter().map(|g| g.active_voxel_count()).sum();
            eprintln!(
                "wrote {} ({} grid{}, {} active voxels) in {:.2} s",
                out.display(),
                grids.len(),
                if grids.len() == 1 { "" } else { "s" },
                voxels,
                t0.elapsed().as_secs_f64()
            );
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(
                e.kind(),
                ErrorKind::DisplayHelp
                    | ErrorKind::DisplayVersion
                    | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ) {
                let _ = e.print();
                return ExitCode::SUCCESS;
            }
            // One line, and the exit code of every other bad input.
            let text = e.to_string();
            let first = text
                .lines()
                .find(|l| !l.trim().is_empty())
                .unwrap_or("invalid arguments");
            eprintln!(
                "vdbphoton: {} (see vdbphoton --help)",
                first.trim_start_matches("error: ").trim()
            );
            return ExitCode::from(1);
        }
    };
    vdbphoton::interrupt::install();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("vdbphoton: error: {}", one_line(&e));
            ExitCode::from(e.exit_code())
        }
    }
}

fn one_line(e: &Error) -> String {
    e.to_string().replace('\n', " ")
}
