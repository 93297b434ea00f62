//! `vdbfuzz`: vdbphoton's fuzz harness (see tools/fuzz/README.md).
//!
//! - `vdbfuzz run`: a deterministic campaign. Mutated `.vdb` files through
//!   the reader (header check, grid walk, OpenVDB, grid build), mutated
//!   scenes through the parser and validator, and whole renders of a
//!   16 x 12 image from a mutated scene and a mutated VDB. Every input runs
//!   in a child process with time and address-space limits; the report
//!   counts crashes (signals, aborts, panics), hangs (over 2 s), peak
//!   memory over 200 MB, inputs accepted that should not be, refusals
//!   that are not one line naming the file, and the time of refusals.
//! - `vdbfuzz target vdb|scene FILE`: the child side (also for replaying).
//! - `vdbfuzz seeds DIR`: writes the generated seed grids.

pub mod oracle;
mod rng;
mod runner;
mod scene_mut;
mod seeds;
mod vdb_mut;

use clap::{Parser, Subcommand};
use rng::Rng;
use runner::{Limits, Outcome, Status};
use scene_mut::{Format, SceneSeed};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use vdb_mut::Seed;

#[derive(Parser)]
#[command(
    name = "vdbfuzz",
    about = "Fuzz harness for vdbphoton's reader, scene parser and renderer"
)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a campaign and print its report (exit 1 if anything failed).
    Run(RunArgs),
    /// The child side: read a .vdb file or a scene, as the campaign does.
    Target {
        /// `vdb` or `scene`.
        kind: String,
        file: PathBuf,
    },
    /// Write the generated seed grids into DIR.
    Seeds { dir: PathBuf },
    /// The launcher of one child (internal): `exec REPORT ADDRESS_SPACE -- PROGRAM ARGS`.
    #[command(hide = true)]
    Exec {
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
}

#[derive(clap::Args, Clone)]
struct RunArgs {
    /// Mutated .vdb files to read.
    #[arg(long, default_value_t = 1000)]
    vdb: usize,
    /// Mutated scenes to parse and validate.
    #[arg(long, default_value_t = 1000)]
    scenes: usize,
    /// Renders of a mutated scene with a mutated VDB.
    #[arg(long, default_value_t = 100)]
    renders: usize,
    /// Campaign seed: the same seed gives the same inputs.
    #[arg(long, default_value_t = 24)]
    seed: u64,
    /// Children at once.
    #[arg(long, default_value_t = 2)]
    jobs: usize,
    /// Work directory (seeds, scratch); failing inputs go to WORK/failures.
    #[arg(long, default_value = "target/vdbfuzz")]
    work: PathBuf,
    /// The vdbphoton binary (default: beside this one).
    #[arg(long)]
    vdbphoton: Option<PathBuf>,
    /// Read the .vdb inputs with `vdbphoton info` instead of the dedicated
    /// target (to fuzz another build's reader).
    #[arg(long)]
    via_info: bool,
    /// Kill a child after this many seconds (a run over 2 s is a hang).
    #[arg(long, default_value_t = 6.0)]
    timeout: f64,
    /// Address-space limit of a child, in MiB.
    #[arg(long, default_value_t = 4096)]
    address_space_mib: u64,
    /// Without glibc's heap checks in the children (libc_malloc_debug with
    /// MALLOC_CHECK_=3, on by default where the library exists).
    #[arg(long)]
    no_malloc_check: bool,
    /// Real data folder (default: VDBPHOTON_REAL_DATA, if set).
    #[arg(long)]
    real_data: Option<PathBuf>,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Cmd::Run(a) => run(a),
        Cmd::Target { kind, file } => target(&kind, &file),
        Cmd::Exec { args } => runner::launcher(&args),
        Cmd::Seeds { dir } => {
            for p in seeds::write_generated(&dir) {
                println!("{}", p.display());
            }
            ExitCode::SUCCESS
        }
    }
}

// ---------------------------------------------------------------- targets

fn target(kind: &str, file: &Path) -> ExitCode {
    let r = match kind {
        "vdb" => oracle::target_vdb(file),
        "scene" => vdbphoton::scene::SceneDesc::load(file)
            .map(|s| serde_json::json!({"volumes": s.volumes.len()}).to_string())
            .map_err(vdbphoton::Error::from),
        _ => {
            eprintln!("vdbfuzz: unknown target '{kind}' (vdb or scene)");
            return ExitCode::from(2);
        }
    };
    match r {
        Ok(line) => {
            println!("{line}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("vdbphoton: error: {}", e.to_string().replace('\n', " "));
            ExitCode::FAILURE
        }
    }
}

// --------------------------------------------------------------- campaign

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Kind {
    Vdb,
    Scene,
    Render,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Vdb => "vdb",
            Kind::Scene => "scene",
            Kind::Render => "render",
        }
    }
}

/// What went wrong with one input, if anything.
#[derive(Debug, Clone)]
struct Failure {
    kind: Kind,
    item: usize,
    what: String,
    labels: Vec<&'static str>,
    saved: PathBuf,
    detail: String,
}

#[derive(Default)]
struct Tally {
    runs: usize,
    accepted: usize,
    refused: usize,
    refused_seconds: Vec<f64>,
    /// The slowest refusal: seconds, item.
    slowest_refusal: (f64, usize),
    /// The refused command's own wall time (one process start).
    refused_own: Vec<f64>,
    /// Its user + system CPU time.
    refused_cpu: Vec<f64>,
    /// The slowest refusal by its own time: seconds, item.
    slowest_own: (f64, usize),
    max_seconds: f64,
    max_rss: u64,
    crashes: usize,
    hangs: usize,
    memory: usize,
    wrong_accepts: usize,
    bad_messages: usize,
}

struct Campaign {
    args: RunArgs,
    vdbphoton: PathBuf,
    me: PathBuf,
    vdb_seeds: Vec<Seed>,
    scene_seeds: Vec<SceneSeed>,
    /// For renders: scenes and the VDB seed each refers to.
    render_seeds: Vec<(usize, usize, Vec<String>)>,
    failures: Mutex<Vec<Failure>>,
    tallies: Mutex<[Tally; 3]>,
    /// Runs over the hang limit that were run again.
    retries: AtomicUsize,
}

const HANG_SECONDS: f64 = 2.0;
const MEMORY_BYTES: u64 = 200 << 20;
/// The target for a refusal: reported, not failed (a timed figure on a
/// shared machine is a benchmark, not a test).
const REFUSAL_SECONDS: f64 = 0.1;

impl Campaign {
    /// Runs `program args` in a child under the campaign's limits.
    fn exec(&self, program: &Path, args: &[&std::ffi::OsStr], scratch: &Path) -> Outcome {
        const LIB: &str = "/usr/lib/x86_64-linux-gnu/libc_malloc_debug.so.0";
        let env: Vec<(&str, &str)> = if !self.args.no_malloc_check && Path::new(LIB).is_file() {
            vec![("LD_PRELOAD", LIB), ("MALLOC_CHECK_", "3")]
        } else {
            vec![]
        };
        let args: Vec<std::ffi::OsString> = args.iter().map(|a| a.to_os_string()).collect();
        let out = runner::run(program, &args, &env, scratch, &self.limits());
        if out.status != Status::Killed && out.seconds <= HANG_SECONDS {
            return out;
        }
        // On a shared machine a child can be starved past the limit: a
        // hang counts only if the input is slow twice.
        self.retries.fetch_add(1, Ordering::Relaxed);
        runner::run(program, &args, &env, scratch, &self.limits())
    }

    fn limits(&self) -> Limits {
        Limits {
            seconds: self.args.timeout,
            address_space: self.args.address_space_mib << 20,
        }
    }

    /// Classifies an outcome; one of `names` must appear in a refusal.
    fn judge(
        &self,
        kind: Kind,
        item: usize,
        out: &Outcome,
        names: &[&str],
    ) -> (Option<String>, bool) {
        let crashed = match out.status {
            Status::Signal(s) => Some(format!("killed by signal {s}")),
            Status::Killed => None,
            Status::Exit(0) | Status::Exit(1) => None,
            Status::Exit(c) => Some(format!("exit code {c}")),
        };
        let mut t = self.tallies.lock().unwrap();
        let t = &mut t[kind as usize];
        t.runs += 1;
        t.max_seconds = t.max_seconds.max(out.seconds);
        t.max_rss = t.max_rss.max(out.max_rss);
        let panicked = out.stderr.contains("panicked");
        if let Some(c) = crashed.or_else(|| panicked.then(|| "panic".to_string())) {
            t.crashes += 1;
            return (Some(format!("crash: {c}")), false);
        }
        if out.status == Status::Killed || out.seconds > HANG_SECONDS {
            t.hangs += 1;
            return (Some(format!("hang: {:.2} s", out.seconds)), false);
        }
        if out.max_rss > MEMORY_BYTES {
            t.memory += 1;
            return (Some(format!("memory: {} MiB", out.max_rss >> 20)), false);
        }
        if out.status == Status::Exit(1) {
            t.refused += 1;
            t.refused_seconds.push(out.seconds);
            if out.seconds > t.slowest_refusal.0 {
                t.slowest_refusal = (out.seconds, item);
            }
            if let (Some(own), Some(cpu)) = (out.own_seconds, out.cpu_seconds) {
                t.refused_own.push(own);
                t.refused_cpu.push(cpu);
                if own > t.slowest_own.0 {
                    t.slowest_own = (own, item);
                }
            }
            let lines: Vec<&str> = out
                .stderr
                .lines()
                .filter(|l| !l.trim().is_empty())
                .collect();
            let ok = lines.len() == 1
                && lines[0].starts_with("vdbphoton: error: ")
                && names.iter().any(|n| lines[0].contains(n));
            if !ok {
                t.bad_messages += 1;
                return (
                    Some("refusal is not one line naming the file".into()),
                    false,
                );
            }
            return (None, false);
        }
        t.accepted += 1;
        (None, true)
    }

    fn fail(&self, f: Failure) {
        self.failures.lock().unwrap().push(f);
    }

    fn save(&self, kind: Kind, item: usize, files: &[(&str, &Path)]) -> PathBuf {
        self.save_in("failures", kind, item, files)
    }

    /// Keeps a refusal slower than [`REFUSAL_SECONDS`] (by the refused
    /// command's own time) under WORK/slow, to look at.
    fn keep_if_slow(&self, kind: Kind, item: usize, out: &Outcome, files: &[(&str, &Path)]) {
        if out.status == Status::Exit(1) && out.own_seconds.is_some_and(|s| s > REFUSAL_SECONDS) {
            self.save_in("slow", kind, item, files);
        }
    }

    fn save_in(&self, under: &str, kind: Kind, item: usize, files: &[(&str, &Path)]) -> PathBuf {
        let dir = self
            .args
            .work
            .join(under)
            .join(format!("{}-{item}", kind.name()));
        std::fs::create_dir_all(&dir).ok();
        for (name, p) in files {
            std::fs::copy(p, dir.join(name)).ok();
        }
        dir
    }

    fn wrong_accept(
        &self,
        kind: Kind,
        item: usize,
        what: String,
        labels: &[&'static str],
        files: &[(&str, &Path)],
    ) {
        self.tallies.lock().unwrap()[kind as usize].wrong_accepts += 1;
        let saved = self.save(kind, item, files);
        self.fail(Failure {
            kind,
            item,
            what,
            labels: labels.to_vec(),
            saved,
            detail: String::new(),
        });
    }

    fn vdb_item(&self, i: usize, scratch: &Path) {
        let mut rng = Rng::for_item(self.args.seed, 1, i as u64);
        // Small seeds more often: large files cost time and find the same.
        let s = loop {
            let s = rng.pick(&self.vdb_seeds);
            if s.bytes.len() < 1 << 20 || rng.chance(0.25) {
                break s;
            }
        };
        let (bytes, labels) = vdb_mut::mutate(&mut rng, s, &self.vdb_seeds);
        let input = scratch.join("input.vdb");
        std::fs::write(&input, &bytes).expect("write input");
        let out = if self.args.via_info {
            self.exec(
                &self.vdbphoton,
                &["info".as_ref(), input.as_os_str()],
                scratch,
            )
        } else {
            self.exec(
                &self.me,
                &["target".as_ref(), "vdb".as_ref(), input.as_os_str()],
                scratch,
            )
        };
        let (failure, accepted) = self.judge(Kind::Vdb, i, &out, &["input.vdb"]);
        self.keep_if_slow(Kind::Vdb, i, &out, &[("input.vdb", &input)]);
        if let Some(what) = failure {
            let saved = self.save(Kind::Vdb, i, &[("input.vdb", &input)]);
            self.fail(Failure {
                kind: Kind::Vdb,
                item: i,
                what,
                labels,
                saved,
                detail: format!(
                    "seed {}; {}",
                    s.name,
                    out.stderr.lines().last().unwrap_or("")
                ),
            });
        } else if accepted && !self.args.via_info {
            if let Ok(v) = serde_json::from_str::<serde_json::Value>(out.stdout.trim()) {
                if v["mismatch"].as_array().is_some_and(|m| !m.is_empty()) {
                    self.wrong_accept(
                        Kind::Vdb,
                        i,
                        format!("accepted a grid unlike its header: {}", v["mismatch"]),
                        &labels,
                        &[("input.vdb", &input)],
                    );
                }
            }
        }
    }

    fn scene_item(&self, i: usize, scratch: &Path) {
        let mut rng = Rng::for_item(self.args.seed, 2, i as u64);
        let seed = rng.pick(&self.scene_seeds);
        let format = if rng.chance(0.5) {
            Format::Toml
        } else {
            Format::Json
        };
        let (bytes, labels) = scene_mut::mutate(&mut rng, seed, format, None);
        let name = if format == Format::Toml {
            "input.toml"
        } else {
            "input.json"
        };
        let input = scratch.join(name);
        std::fs::write(&input, &bytes).expect("write input");
        let out = self.exec(
            &self.me,
            &["target".as_ref(), "scene".as_ref(), input.as_os_str()],
            scratch,
        );
        let (failure, accepted) = self.judge(Kind::Scene, i, &out, &[name]);
        self.keep_if_slow(Kind::Scene, i, &out, &[(name, &input)]);
        if let Some(what) = failure {
            let saved = self.save(Kind::Scene, i, &[(name, &input)]);
            self.fail(Failure {
                kind: Kind::Scene,
                item: i,
                what,
                labels,
                saved,
                detail: format!(
                    "seed {}; {}",
                    seed.name,
                    out.stderr.lines().last().unwrap_or("")
                ),
            });
        } else if accepted && labels.contains(&"non-finite literal") {
            // Review: the validator accepted a scene where a number was
            // replaced by a non-finite literal (fine only if that key is not
            // a number the renderer uses).
            let text = String::from_utf8_lossy(&bytes);
            if ["nan", "inf", "NaN", "Infinity"]
                .iter()
                .any(|l| text.contains(l))
            {
                self.wrong_accept(
                    Kind::Scene,
                    i,
                    "accepted a scene with a non-finite number".into(),
                    &labels,
                    &[(name, &input)],
                );
            }
        }
    }

    fn render_item(&self, i: usize, scratch: &Path) {
        let mut rng = Rng::for_item(self.args.seed, 3, i as u64);
        let (si, vi, grids) = rng.pick(&self.render_seeds).clone();
        let vseed = &self.vdb_seeds[vi];
        let (vbytes, mut labels) = if rng.chance(0.7) {
            vdb_mut::mutate(&mut rng, vseed, &[])
        } else {
            (vseed.bytes.clone(), vec![])
        };
        let vdb = scratch.join("input.vdb");
        std::fs::write(&vdb, &vbytes).expect("write vdb");
        let format = if rng.chance(0.5) {
            Format::Toml
        } else {
            Format::Json
        };
        let (sbytes, sl) = if rng.chance(0.7) {
            scene_mut::mutate(&mut rng, &self.scene_seeds[si], format, Some("input.vdb"))
        } else {
            // Unmutated, but reading the (maybe mutated) VDB.
            let mut v = self.scene_seeds[si].value.clone();
            if let Some(vols) = v.get_mut("volume").and_then(|x| x.as_array_mut()) {
                for vol in vols {
                    if let Some(t) = vol.as_table_mut() {
                        t.insert("file".into(), toml::Value::String("input.vdb".into()));
                    }
                }
            }
            let text = match format {
                Format::Toml => toml::to_string(&v).unwrap_or_default(),
                Format::Json => serde_json::to_string_pretty(&v).unwrap_or_default(),
            };
            (text.into_bytes(), vec![])
        };
        labels.extend(sl);
        let name = if format == Format::Toml {
            "input.toml"
        } else {
            "input.json"
        };
        let scene = scratch.join(name);
        std::fs::write(&scene, &sbytes).expect("write scene");
        let exr = scratch.join("out.exr");
        let _ = std::fs::remove_file(&exr);
        let png = scratch.join("out.png");
        let mut args: Vec<&std::ffi::OsStr> = vec!["render".as_ref(), scene.as_os_str()];
        for a in [
            "--width",
            "16",
            "--height",
            "12",
            "--spp",
            "1",
            "--threads",
            "1",
            "--quiet",
            "-o",
        ] {
            args.push(a.as_ref());
        }
        args.extend([exr.as_os_str(), "--preview".as_ref(), png.as_os_str()]);
        let out = self.exec(&self.vdbphoton, &args, scratch);
        // A refusal names the scene, the VDB, or another file the mutated
        // scene refers to.
        let (failure, accepted) = self.judge(Kind::Render, i, &out, &[name, "input.vdb", ".vdb'"]);
        let files = [(name, scene.as_path()), ("input.vdb", vdb.as_path())];
        self.keep_if_slow(Kind::Render, i, &out, &files);
        if let Some(what) = failure {
            let saved = self.save(Kind::Render, i, &files);
            self.fail(Failure {
                kind: Kind::Render,
                item: i,
                what,
                labels,
                saved,
                detail: out.stderr.lines().last().unwrap_or("").to_string(),
            });
            return;
        }
        if !accepted {
            return;
        }
        // Accepted: the image must be finite, and no grid the scene reads
        // may hold NaN or infinite values.
        match vdbphoton::image::read_exr_rgb(&exr) {
            Ok(img) => {
                if img.pixels.iter().any(|p| !p.is_finite()) {
                    self.wrong_accept(
                        Kind::Render,
                        i,
                        "non-finite pixels in the image".into(),
                        &labels,
                        &files,
                    );
                }
            }
            Err(e) => self.wrong_accept(
                Kind::Render,
                i,
                format!("exit 0 but no readable image: {e}"),
                &labels,
                &files,
            ),
        }
        let check = self.exec(
            &self.me,
            &["target".as_ref(), "vdb".as_ref(), vdb.as_os_str()],
            scratch,
        );
        if let Ok(v) = serde_json::from_str::<serde_json::Value>(check.stdout.trim()) {
            let bad: Vec<String> = v["nonfinite"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|n| n.as_str())
                .filter(|n| grids.iter().any(|g| g == n))
                .map(String::from)
                .collect();
            if !bad.is_empty() {
                self.wrong_accept(
                    Kind::Render,
                    i,
                    format!("rendered grids with NaN or infinite values: {bad:?}"),
                    &labels,
                    &files,
                );
            }
        }
    }
}

fn percentile(v: &mut [f64], p: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[((v.len() - 1) as f64 * p).round() as usize]
}

/// Median, 99th percentile and maximum.
fn spread(v: &mut [f64]) -> (f64, f64, f64) {
    (percentile(v, 0.5), percentile(v, 0.99), percentile(v, 1.0))
}

fn run(a: RunArgs) -> ExitCode {
    let me = std::env::current_exe().expect("own path");
    let vdbphoton = a
        .vdbphoton
        .clone()
        .unwrap_or_else(|| me.with_file_name("vdbphoton"));
    let real = a
        .real_data
        .clone()
        .or_else(|| std::env::var_os("VDBPHOTON_REAL_DATA").map(PathBuf::from));
    std::fs::create_dir_all(&a.work).expect("work directory");
    let _ = std::fs::remove_dir_all(a.work.join("failures"));
    let _ = std::fs::remove_dir_all(a.work.join("slow"));
    let t0 = std::time::Instant::now();
    // Seeds: generated ones, then the real files where they are.
    let mut vdb_paths = seeds::write_generated(&a.work.join("seeds"));
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    vdb_paths.extend(["scenes/cloud.vdb", "scenes/plume.vdb"].map(|p| repo.join(p)));
    if let Some(r) = &real {
        vdb_paths.extend(seeds::real_files(r));
    }
    let vdb_seeds: Vec<Seed> = vdb_paths
        .iter()
        .map(|p| {
            Seed::new(
                p.display().to_string(),
                std::fs::read(p).expect("read seed"),
            )
        })
        .collect();
    let scene_paths = seeds::scene_files(repo, real.as_deref());
    let scene_seeds: Vec<SceneSeed> = scene_paths
        .iter()
        .filter_map(|p| scene_mut::load_seed(p))
        .collect();
    // Renders: scenes whose first volume's file is one of the VDB seeds.
    let mut render_seeds = Vec::new();
    for (si, (p, s)) in scene_paths.iter().zip(&scene_seeds).enumerate() {
        let vols = s.value.get("volume").and_then(|v| v.as_array());
        let Some(vol) = vols.and_then(|v| v.first()) else {
            continue;
        };
        let Some(file) = vol.get("file").and_then(|f| f.as_str()) else {
            continue;
        };
        let target = p.parent().unwrap_or(Path::new(".")).join(file);
        let Ok(target) = target.canonicalize() else {
            continue;
        };
        let Some(vi) = vdb_paths
            .iter()
            .position(|q| q.canonicalize().ok().as_ref() == Some(&target))
        else {
            continue;
        };
        let grids = [
            "density_grid",
            "temperature_grid",
            "flame_grid",
            "color_grid",
        ]
        .iter()
        .map(|k| {
            vol.get(*k)
                .and_then(|g| g.as_str())
                .unwrap_or(if *k == "density_grid" { "density" } else { "" })
                .to_string()
        })
        .filter(|g| !g.is_empty())
        .collect();
        render_seeds.push((si, vi, grids));
    }
    println!(
        "vdbfuzz: seed {}, {} VDB seeds ({} generated{}), {} scene seeds, {} render seeds; {} jobs",
        a.seed,
        vdb_seeds.len(),
        vdb_paths.len() - real.as_ref().map_or(0, |r| seeds::real_files(r).len()),
        real.as_ref()
            .map_or(String::new(), |r| format!(", real data {}", r.display())),
        scene_seeds.len(),
        render_seeds.len(),
        a.jobs
    );
    let renders = if render_seeds.is_empty() {
        0
    } else {
        a.renders
    };
    let c = Campaign {
        args: a.clone(),
        vdbphoton,
        me,
        vdb_seeds,
        scene_seeds,
        render_seeds,
        failures: Mutex::new(Vec::new()),
        tallies: Mutex::new(Default::default()),
        retries: AtomicUsize::new(0),
    };
    let items: Vec<(Kind, usize)> = (0..a.vdb)
        .map(|i| (Kind::Vdb, i))
        .chain((0..a.scenes).map(|i| (Kind::Scene, i)))
        .chain((0..renders).map(|i| (Kind::Render, i)))
        .collect();
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    std::thread::scope(|s| {
        for j in 0..a.jobs.max(1) {
            let (c, items, next, done) = (&c, &items, &next, &done);
            s.spawn(move || {
                let scratch = c.args.work.join(format!("job{j}"));
                std::fs::create_dir_all(&scratch).expect("scratch");
                loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(&(kind, i)) = items.get(k) else {
                        break;
                    };
                    match kind {
                        Kind::Vdb => c.vdb_item(i, &scratch),
                        Kind::Scene => c.scene_item(i, &scratch),
                        Kind::Render => c.render_item(i, &scratch),
                    }
                    let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                    if d % 1000 == 0 {
                        eprintln!(
                            "  {d} of {} inputs ({:.0} s)",
                            items.len(),
                            t0.elapsed().as_secs_f64()
                        );
                    }
                }
            });
        }
    });
    // Report.
    let retries = c.retries.load(Ordering::Relaxed);
    let mut tallies = c.tallies.into_inner().unwrap();
    let failures = c.failures.into_inner().unwrap();
    let mut bad = 0;
    println!("kind     inputs  accepted  refused  crashes  hangs  memory  wrong-accepts  bad-messages  refusal time median/p99/max  slowest  peak RSS");
    for k in [Kind::Vdb, Kind::Scene, Kind::Render] {
        let t = &mut tallies[k as usize];
        let (m, p99, mx) = spread(&mut t.refused_seconds);
        bad += t.crashes + t.hangs + t.memory + t.wrong_accepts + t.bad_messages;
        println!(
            "{:<7} {:>7} {:>9} {:>8} {:>8} {:>6} {:>7} {:>14} {:>13}   {:>6.3} / {:.3} / {:.3} s   {:>6.2} s  {:>4} MiB",
            k.name(),
            t.runs,
            t.accepted,
            t.refused,
            t.crashes,
            t.hangs,
            t.memory,
            t.wrong_accepts,
            t.bad_messages,
            m,
            p99,
            mx,
            t.max_seconds,
            t.max_rss >> 20
        );
        if t.refused > 0 {
            let (om, op99, omx) = spread(&mut t.refused_own);
            let (cm, cp99, cmx) = spread(&mut t.refused_cpu);
            let slow = t
                .refused_own
                .iter()
                .filter(|&&s| s > REFUSAL_SECONDS)
                .count();
            println!(
                "        slowest refusal: #{} ({:.3} s); the refused command alone: median/p99/max {om:.3} / {op99:.3} / {omx:.3} s wall, {cm:.3} / {cp99:.3} / {cmx:.3} s CPU; over {REFUSAL_SECONDS} s: {} (slowest #{}, {:.3} s)",
                t.slowest_refusal.1, t.slowest_refusal.0, slow, t.slowest_own.1, t.slowest_own.0
            );
        }
    }
    for f in &failures {
        println!(
            "  {} #{}: {} [{}] -> {} {}",
            f.kind.name(),
            f.item,
            f.what,
            f.labels.join(", "),
            f.saved.display(),
            f.detail
        );
    }
    println!("runs over {HANG_SECONDS} s run a second time (a hang only if slow twice): {retries}");
    println!(
        "vdbfuzz: {} inputs in {:.0} s, {} failures",
        items.len(),
        t0.elapsed().as_secs_f64(),
        failures.len()
    );
    if bad > 0 {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
