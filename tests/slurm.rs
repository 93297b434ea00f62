//! The Slurm tooling (`tools/slurm`) on a real cluster: a 4-frame array and
//! a frame in 4 tiles with its merge, submitted through `submit.sh`, give
//! the same pixels as single-machine renders; a frame whose input is
//! missing ends FAILED, and a failed tile cancels its merge; a tile
//! requeued mid-render (`scontrol requeue`, as a preemption does) resumes
//! from its checkpoint and the merged frame is the undisturbed one.
//!
//! Needs a cluster that answers `scontrol ping`: `SLURM_CONF` from the
//! environment, else the one `tools/slurm/cluster.sh start` makes in
//! `target/slurm` (`tools/slurm/selftest.sh` starts it, runs this test and
//! stops it). Without one the test is skipped with a note, except under
//! `CI=true`, where `.ci/run` starts the cluster first.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_vdbphoton");
const MANIFEST: &str = env!("CARGO_MANIFEST_DIR");
const TOOLS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tools/slurm");
/// Longest wait for all the jobs (they take about 10 s on 2 cores).
const JOBS_TIMEOUT: Duration = Duration::from_secs(50);
const POLL: Duration = Duration::from_millis(250);

/// Runs `cmd` and returns (success, stdout, stderr), killing it after `limit`.
fn try_run(cmd: &mut Command, limit: Duration) -> std::io::Result<(bool, String, String)> {
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()?;
    let t0 = Instant::now();
    while child.try_wait()?.is_none() {
        if t0.elapsed() > limit {
            let _ = child.kill();
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output()?;
    Ok((
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    ))
}

fn run_limited(cmd: &mut Command, limit: Duration) -> (bool, String, String) {
    try_run(cmd, limit).unwrap_or_else(|e| panic!("cannot run {cmd:?}: {e}"))
}

/// A `slurm.conf` whose controller answers `scontrol ping`.
fn cluster_conf() -> Option<PathBuf> {
    let mut candidates: Vec<PathBuf> = Vec::new();
    if let Some(c) = std::env::var_os("SLURM_CONF") {
        candidates.push(c.into());
    }
    candidates.push(Path::new(MANIFEST).join("target/slurm/slurm.conf"));
    for conf in candidates {
        // Slurm's commands wait a minute for a config file that is not there.
        if !conf.is_file() {
            continue;
        }
        let mut ping = Command::new("scontrol");
        ping.arg("ping").env("SLURM_CONF", &conf);
        match try_run(&mut ping, Duration::from_secs(20)) {
            Ok((true, out, _)) if out.contains("is UP") => return Some(conf),
            Ok(_) => {}
            Err(_) => return None, // no Slurm commands
        }
    }
    None
}

/// One record of `scontrol show job -o`: a job, an array task, or the
/// pending rest of an array.
#[derive(Debug, Clone)]
struct Record {
    job: String,
    task: Option<String>,
    state: String,
    exit_code: String,
    reason: String,
    restarts: u32,
}

const DONE: [&str; 9] = [
    "COMPLETED",
    "FAILED",
    "CANCELLED",
    "TIMEOUT",
    "NODE_FAIL",
    "OUT_OF_MEMORY",
    "BOOT_FAIL",
    "DEADLINE",
    "PREEMPTED",
];

impl Record {
    fn done(&self) -> bool {
        DONE.iter().any(|s| self.state.starts_with(s))
    }
}

/// The jobs this test submitted; cancelled if the test fails.
struct Cluster {
    conf: PathBuf,
    dir: PathBuf,
    logs: PathBuf,
    jobs: Vec<String>,
}

impl Drop for Cluster {
    fn drop(&mut self) {
        if std::thread::panicking() && !self.jobs.is_empty() {
            let _ = self
                .cmd("scancel")
                .args(&self.jobs)
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .status();
        }
    }
}

impl Cluster {
    /// The cluster of `conf`, its jobs run in a fresh folder under target/
    /// (which a real cluster's nodes see when the repository is on shared
    /// storage), named `prefix...`.
    fn in_new_folder(conf: PathBuf, prefix: &str) -> (tempfile::TempDir, Cluster) {
        let tmp = tempfile::Builder::new()
            .prefix(prefix)
            .tempdir_in(env!("CARGO_TARGET_TMPDIR"))
            .unwrap();
        let dir = tmp.path().to_path_buf();
        let cluster = Cluster {
            conf,
            logs: dir.join("logs"),
            dir,
            jobs: Vec::new(),
        };
        (tmp, cluster)
    }

    fn cmd(&self, program: impl AsRef<OsStr>) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf).current_dir(&self.dir);
        c
    }

    /// `tools/slurm/submit.sh ARGS` (split at spaces), returning its
    /// `KIND JOBID` lines.
    fn submit(&mut self, args: &str) -> Vec<(String, String)> {
        // submit.sh's own options go before `--`, the render's after.
        let (own, render) = args.split_once(" -- ").unwrap_or((args, ""));
        let mut c = self.cmd("bash");
        c.arg(format!("{TOOLS}/submit.sh"))
            .args(own.split_whitespace())
            .args(["--vdbphoton", BIN, "--logs"])
            .arg(&self.logs);
        if !render.is_empty() {
            c.arg("--").args(render.split_whitespace());
        }
        let (ok, out, err) = run_limited(&mut c, Duration::from_secs(30));
        assert!(ok, "submit.sh {args:?} failed:\n{out}{err}");
        let ids: Vec<(String, String)> = out
            .lines()
            .map(|l| {
                let (kind, id) = l
                    .split_once(' ')
                    .unwrap_or_else(|| panic!("submit.sh printed '{l}'"));
                assert!(id.parse::<u64>().is_ok(), "submit.sh printed '{l}'");
                (kind.to_string(), id.to_string())
            })
            .collect();
        self.jobs.extend(ids.iter().map(|(_, id)| id.clone()));
        ids
    }

    fn records(&self, id: &str) -> Vec<Record> {
        let (ok, out, err) = run_limited(
            self.cmd("scontrol").args(["show", "job", "-o", id]),
            Duration::from_secs(20),
        );
        assert!(ok, "scontrol show job {id}: {out}{err}");
        out.lines()
            .filter(|l| l.starts_with("JobId="))
            .map(|l| {
                let get = |key: &str| {
                    l.split_whitespace()
                        .find_map(|kv| kv.strip_prefix(key)?.strip_prefix('='))
                        .map(str::to_string)
                };
                Record {
                    job: get("ArrayJobId")
                        .or_else(|| get("JobId"))
                        .unwrap_or_default(),
                    task: get("ArrayTaskId"),
                    state: get("JobState").unwrap_or_default(),
                    exit_code: get("ExitCode").unwrap_or_default(),
                    reason: get("Reason").unwrap_or_default(),
                    restarts: get("Restarts").and_then(|r| r.parse().ok()).unwrap_or(0),
                }
            })
            .collect()
    }

    /// Everything that helps when a job went wrong: the queue, the jobs
    /// and their logs.
    fn diagnostics(&self) -> String {
        let mut s = String::new();
        let (_, q, _) = run_limited(&mut self.cmd("squeue"), Duration::from_secs(20));
        s += &format!("squeue:\n{q}");
        for id in &self.jobs {
            let (_, j, e) = run_limited(
                self.cmd("scontrol").args(["show", "job", "-o", id]),
                Duration::from_secs(20),
            );
            s += &format!("scontrol show job {id}:\n{j}{e}");
        }
        if let Ok(rd) = std::fs::read_dir(&self.logs) {
            let mut logs: Vec<PathBuf> = rd.map(|e| e.unwrap().path()).collect();
            logs.sort();
            for log in logs {
                let text = std::fs::read_to_string(&log).unwrap_or_default();
                s += &format!("---- {} ----\n{text}", log.display());
            }
        }
        s
    }

    /// Polls until every job (every task of every array) has ended.
    fn wait_all(&self) -> Vec<Record> {
        let t0 = Instant::now();
        loop {
            let records: Vec<Record> = self.jobs.iter().flat_map(|id| self.records(id)).collect();
            if records.iter().all(Record::done) {
                return records;
            }
            if t0.elapsed() > JOBS_TIMEOUT {
                panic!(
                    "the jobs did not finish within {JOBS_TIMEOUT:?}: {records:#?}\n{}",
                    self.diagnostics()
                );
            }
            std::thread::sleep(POLL);
        }
    }
}

/// The pixels of an EXR: display and data windows, then every channel of
/// every layer as raw f32 bits.
#[derive(PartialEq)]
struct Pixels {
    display: String,
    window: Vec<String>,
    channels: Vec<(String, Vec<u32>)>,
}

fn pixels(path: &Path) -> Pixels {
    let img = exr::prelude::read_all_flat_layers_from_file(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut window = Vec::new();
    let mut channels = Vec::new();
    for layer in &img.layer_data {
        let name = layer
            .attributes
            .layer_name
            .as_ref()
            .map(|t| t.to_string())
            .unwrap_or_default();
        window.push(format!(
            "{name}: {:?} {:?}",
            layer.attributes.layer_position, layer.size
        ));
        for ch in &layer.channel_data.list {
            let bits = ch.sample_data.values_as_f32().map(f32::to_bits).collect();
            channels.push((format!("{name}/{}", ch.name), bits));
        }
    }
    Pixels {
        display: format!("{:?}", img.attributes.display_window),
        window,
        channels,
    }
}

fn assert_same_pixels(image: &Path, reference: &Path) {
    let (a, b) = (pixels(image), pixels(reference));
    let what = format!("{} against {}", image.display(), reference.display());
    assert_eq!(a.display, b.display, "display windows differ: {what}");
    assert_eq!(a.window, b.window, "data windows differ: {what}");
    let names = |p: &Pixels| p.channels.iter().map(|c| c.0.clone()).collect::<Vec<_>>();
    assert_eq!(names(&a), names(&b), "channels differ: {what}");
    for ((name, x), (_, y)) in a.channels.iter().zip(&b.channels) {
        let differ = x.iter().zip(y).filter(|(p, q)| p != q).count();
        assert_eq!(differ, 0, "{what}: {differ} samples of {name} differ");
    }
    assert!(a.channels.iter().any(|(_, v)| v.iter().any(|&b| b != 0)));
}

/// `vdbphoton ARGS` (split at spaces) in `dir`.
fn vdbphoton(dir: &Path, args: &str) {
    let (ok, out, err) = run_limited(
        Command::new(BIN)
            .args(args.split_whitespace())
            .current_dir(dir),
        Duration::from_secs(60),
    );
    assert!(ok, "vdbphoton {args:?} failed:\n{out}{err}");
}

const SCENE: &str = r#"# A 4-frame sequence for tests/slurm.rs
[render]
width = 64
height = 48
spp = 4
seed = 3
max_bounces = 16
integrator = "path"
output = "out/frame_{frame:04}.exr"

[camera]
position = [0.0, -3.0, 0.7]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]
vfov = 40.0

[[light]]
type = "sun"
direction = [0.6, -0.4, 0.7]
irradiance = [3.2, 3.0, 2.7]
angle = 0.5

[environment]
radiance = [0.10, 0.16, 0.28]

[[volume]]
file = "f_{frame:04}.vdb"
density_grid = "density"
[volume.material]
density = 25.0
color = [0.95, 0.95, 0.95]
absorption_color = [0.0, 0.0, 0.0]
anisotropy = 0.5
"#;

fn state_of<'a>(records: &'a [Record], job: &str, task: Option<&str>) -> &'a Record {
    records
        .iter()
        .find(|r| r.job == job && r.task.as_deref() == task)
        .unwrap_or_else(|| panic!("no record of job {job} task {task:?} in {records:#?}"))
}

/// The tests share the cluster's two CPUs: one at a time.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The cluster's `slurm.conf`, or `None` (with a note) when no cluster
/// answers outside CI.
fn cluster_or_skip() -> Option<PathBuf> {
    let Some(conf) = cluster_conf() else {
        if std::env::var("CI").as_deref() == Ok("true") {
            panic!(
                "no Slurm cluster answers (SLURM_CONF or {MANIFEST}/target/slurm/slurm.conf): \
                 CI starts one with tools/slurm/cluster.sh start before the tests"
            );
        }
        eprintln!(
            "note: no Slurm cluster answers `scontrol ping`; skipping the Slurm test \
             (run tools/slurm/selftest.sh, or tools/slurm/cluster.sh start first)"
        );
        return None;
    };
    Some(conf)
}

#[test]
fn frames_and_tiles_on_slurm() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let t0 = Instant::now();
    let Some(conf) = cluster_or_skip() else {
        return;
    };
    // Jobs run in this folder (the submit folder).
    let (tmp, mut cluster) = Cluster::in_new_folder(conf, "vdbphoton-slurm");
    let dir = tmp.path().to_path_buf();

    // A sequence of 4 frames (frame 5 is missing on purpose).
    for f in 1..=4 {
        vdbphoton(
            &dir,
            &format!("generate cloud f_{f:04}.vdb --res 16 --seed {f}"),
        );
    }
    std::fs::write(dir.join("seq.toml"), SCENE).unwrap();

    // submit.sh refuses a scene that is not there, before any job.
    let mut refused = cluster.cmd("bash");
    refused.arg(format!("{TOOLS}/submit.sh"));
    refused.args("frames nothere.toml 1-4 --vdbphoton".split(' '));
    let (ok, out, err) = run_limited(refused.arg(BIN), Duration::from_secs(30));
    assert!(!ok && err.contains("scene file not found"), "{out}{err}");

    // The jobs: frames 1-4; frame 2 in 4 tiles and merged; frame 5, whose
    // input is missing; frame 3 in 4 tiles where tile 2 cannot be written
    // (a folder is in its way); and a scene that is not there, submitted
    // straight to the job script.
    let frames = cluster.submit("frames seq.toml 1-4 --name seq --skip-existing");
    assert_eq!(frames.len(), 1);
    assert_eq!(frames[0].0, "frames");
    let frames = frames[0].1.clone();

    let tiled = cluster.submit("tile seq.toml 2 4 tiled/frame_0002.exr --name tiled -r 4");
    assert_eq!(
        tiled.iter().map(|t| t.0.as_str()).collect::<Vec<_>>(),
        ["tiles", "merge"]
    );
    let (tiles, merge) = (tiled[0].1.clone(), tiled[1].1.clone());

    let missing = cluster.submit("frames seq.toml 5 --name missing");
    let missing = missing[0].1.clone();

    std::fs::create_dir_all(dir.join("broken/frame_0003.tiles/tile_2.exr")).unwrap();
    let broken = cluster.submit("tile seq.toml 3 4 broken/frame_0003.exr --name broken");
    let (broken_tiles, broken_merge) = (broken[0].1.clone(), broken[1].1.clone());

    let logs = cluster.logs.clone();
    let (ok, out, err) = run_limited(
        cluster
            .cmd("sbatch")
            .args(["--parsable", "--array=0", "--job-name=noscene", "--output"])
            .arg(logs.join("%x-%A_%a.out"))
            .arg(format!("{TOOLS}/frames.sbatch"))
            .args(["--base", "1", "--vdbphoton", BIN])
            .arg(dir.join("nothere.toml")),
        Duration::from_secs(30),
    );
    assert!(ok, "sbatch: {out}{err}");
    let noscene = out.trim().split(';').next().unwrap().to_string();
    cluster.jobs.push(noscene.clone());
    let submitted = t0.elapsed();

    // Single-machine renders of the same frames, while the cluster works.
    for f in 1..=4 {
        vdbphoton(
            &dir,
            &format!("render seq.toml --frame {f} -o ref/frame_{f:04}.exr --no-preview"),
        );
    }

    let records = cluster.wait_all();
    let jobs_done = t0.elapsed();
    let diag = || cluster.diagnostics();

    // Frames 1-4: COMPLETED, the same pixels as the single-machine renders.
    for task in ["0", "1", "2", "3"] {
        let r = state_of(&records, &frames, Some(task));
        assert!(
            r.state == "COMPLETED" && r.exit_code == "0:0",
            "frame task {task}: {r:?}\n{}",
            diag()
        );
    }
    for f in 1..=4 {
        let name = format!("frame_{f:04}.exr");
        assert_same_pixels(&dir.join("out").join(&name), &dir.join("ref").join(&name));
    }

    // Frame 2 in tiles: the merge ran after them and equals the full render.
    for task in ["0", "1", "2", "3"] {
        let r = state_of(&records, &tiles, Some(task));
        assert!(r.state == "COMPLETED", "tile {task}: {r:?}\n{}", diag());
        assert!(dir
            .join(format!("tiled/frame_0002.tiles/tile_{task}.exr"))
            .is_file());
    }
    let r = state_of(&records, &merge, None);
    assert!(r.state == "COMPLETED", "merge: {r:?}\n{}", diag());
    assert_same_pixels(
        &dir.join("tiled/frame_0002.exr"),
        &dir.join("ref/frame_0002.exr"),
    );

    // Frame 5 has no input: FAILED, and its log names the sequence's file.
    let r = state_of(&records, &missing, Some("0"));
    assert!(
        r.state == "FAILED" && r.exit_code != "0:0",
        "frame 5: {r:?}\n{}",
        diag()
    );
    let log = std::fs::read_to_string(logs.join(format!("missing-frames-{missing}_0.out")))
        .unwrap_or_else(|e| panic!("log of frame 5: {e}\n{}", diag()));
    assert!(
        log.lines()
            .any(|l| l.starts_with("vdbphoton: error:") && l.contains("f_")),
        "no error naming the input in the log of frame 5:\n{log}"
    );
    assert!(log.contains("frame 5 FAILED"), "{log}");
    assert!(!dir.join("out/frame_0005.exr").exists());

    // Frame 3: tile 2 FAILED, the others COMPLETED, the merge CANCELLED
    // without running.
    for task in ["0", "1", "3"] {
        let r = state_of(&records, &broken_tiles, Some(task));
        assert!(r.state == "COMPLETED", "tile {task}: {r:?}\n{}", diag());
    }
    let r = state_of(&records, &broken_tiles, Some("2"));
    assert!(r.state == "FAILED", "tile 2: {r:?}\n{}", diag());
    let r = state_of(&records, &broken_merge, None);
    assert!(
        r.state == "CANCELLED" && r.reason.contains("Dependency"),
        "merge after a failed tile: {r:?}\n{}",
        diag()
    );
    assert!(!dir.join("broken/frame_0003.exr").exists());
    assert!(!logs
        .join(format!("broken-merge-{broken_merge}.out"))
        .exists());

    // No scene: FAILED with a clear message in the job's log.
    let r = state_of(&records, &noscene, Some("0"));
    assert!(r.state == "FAILED", "no scene: {r:?}\n{}", diag());
    let log = std::fs::read_to_string(logs.join(format!("noscene-{noscene}_0.out"))).unwrap();
    assert!(log.contains("scene file not found"), "{log}");

    eprintln!(
        "slurm: {} jobs submitted in {:.1} s, all ended after {:.1} s; test took {:.1} s",
        cluster.jobs.len(),
        submitted.as_secs_f64(),
        jobs_done.as_secs_f64(),
        t0.elapsed().as_secs_f64()
    );
}

#[test]
fn a_requeued_tile_resumes_from_its_checkpoint() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let t0 = Instant::now();
    let Some(conf) = cluster_or_skip() else {
        return;
    };
    let (tmp, mut cluster) = Cluster::in_new_folder(conf, "vdbphoton-requeue");
    let dir = tmp.path().to_path_buf();
    vdbphoton(&dir, "generate cloud f_0001.vdb --res 16 --seed 1");
    // One frame, long enough (about 3 s a tile on one CPU) to be requeued
    // in the middle.
    let scene = SCENE
        .replace("spp = 4", "spp = 800")
        .replace("out/frame_{frame:04}.exr", "out/frame.exr")
        .replace("f_{frame:04}.vdb", "f_0001.vdb");
    std::fs::write(dir.join("one.toml"), scene).unwrap();
    let ids = cluster.submit("tile one.toml - 2 tiled/frame.exr --name rq -- --checkpoint 0.2s");
    let (tiles, merge) = (ids[0].1.clone(), ids[1].1.clone());
    let task = format!("{tiles}_1");

    // Tile 1 running with a checkpoint: requeue it, as a preemption would.
    let state = dir.join("tiled/frame.tiles/tile_1.exr.vdbstate");
    while !state.exists() {
        assert!(
            t0.elapsed() < JOBS_TIMEOUT,
            "tile 1 wrote no checkpoint\n{}",
            cluster.diagnostics()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let checkpointed = t0.elapsed();
    let (ok, out, err) = run_limited(
        cluster.cmd("scontrol").args(["requeue", &task]),
        Duration::from_secs(20),
    );
    assert!(ok, "scontrol requeue {task}: {out}{err}");
    let requeued = t0.elapsed();
    // Slurm holds a requeued job back for its credential lifetime (the
    // test cluster's cred_expire, 10 s; 120 s by default) and then starts
    // it on its own. Forcing an earlier start (`scontrol update
    // StartTime=now`) races the old run's revoked credential: the new run
    // is then killed at launch ("Job credential revoked") with an empty log.
    loop {
        let r = cluster.records(&task);
        if r.iter().any(|r| r.state == "PENDING" && r.restarts > 0) {
            break;
        }
        assert!(
            t0.elapsed() < JOBS_TIMEOUT,
            "{task} was not requeued: {r:?}\n{}",
            cluster.diagnostics()
        );
        std::thread::sleep(POLL);
    }
    let pending = t0.elapsed();

    // The undisturbed frame, on this machine, while the cluster works.
    vdbphoton(&dir, "render one.toml -o ref.exr --no-preview");
    let records = cluster.wait_all();
    let done = t0.elapsed();
    let diag = || cluster.diagnostics();
    for t in ["0", "1"] {
        let r = state_of(&records, &tiles, Some(t));
        assert!(r.state == "COMPLETED", "tile {t}: {r:?}\n{}", diag());
    }
    assert_eq!(
        state_of(&records, &tiles, Some("1")).restarts,
        1,
        "{}",
        diag()
    );
    let r = state_of(&records, &merge, None);
    assert!(r.state == "COMPLETED", "merge: {r:?}\n{}", diag());

    // The log: stopped with a checkpoint, run again, resumed from it.
    let log = std::fs::read_to_string(cluster.logs.join(format!("rq-tiles-{tiles}_1.out")))
        .unwrap_or_else(|e| panic!("log of tile 1: {e}\n{}", diag()));
    let kept = log
        .lines()
        .find(|l| l.contains("interrupted by SIGTERM") && l.contains("keeps"))
        .unwrap_or_else(|| panic!("no last checkpoint on SIGTERM:\n{log}"));
    let resumed = log
        .lines()
        .find(|l| l.starts_with("resumed: "))
        .unwrap_or_else(|| panic!("the requeued task did not resume:\n{log}"));
    assert!(log.contains("run 2 (requeued)"), "{log}");
    let passes = |l: &str, word: &str| -> u32 {
        l.split(word)
            .nth(1)
            .unwrap()
            .split(' ')
            .nth(1)
            .unwrap()
            .parse()
            .unwrap()
    };
    assert_eq!(passes(kept, "keeps"), passes(resumed, "after"), "{log}");
    assert!(passes(resumed, "after") > 0 && passes(resumed, "after") < 800);
    assert!(!state.exists(), "the finished tile keeps its state");

    assert_same_pixels(&dir.join("tiled/frame.exr"), &dir.join("ref.exr"));
    eprintln!(
        "slurm requeue: tile 1 checkpointed at {:.1} s, requeued at {:.1} s ({kept}), \
         pending again at {:.1} s, {resumed}; all done at {:.1} s; merged frame identical to the undisturbed render",
        checkpointed.as_secs_f64(),
        requeued.as_secs_f64(),
        pending.as_secs_f64(),
        done.as_secs_f64()
    );
}
