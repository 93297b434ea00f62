//! Resuming killed renders (`--checkpoint` writes the state, `--resume`
//! goes on from it): a render killed by SIGKILL between checkpoints, stopped
//! by SIGTERM, or killed while writing its state, and resumed, gives the
//! pixels of the uninterrupted render bit for bit, for both integrators
//! and for a tile; damaged states and states of other renders are refused
//! with a message and the render starts afresh without touching the old
//! files; a time budget counts the time already spent; two renders of one
//! output exclude each other; a sequence resumes at the frame it was
//! killed in.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use vdbphoton::image::{read_exr, Image};

const BIN: &str = env!("CARGO_BIN_EXE_vdbphoton");
const SCENES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");

/// The arguments of a render of the default cloud into `exr`.
fn args(exr: &Path, integrator: &str, spp: u32, extra: &[&str]) -> Vec<String> {
    let mut a: Vec<String> = [
        "render",
        &format!("{SCENES}/cloud.toml"),
        "-o",
        exr.to_str().unwrap(),
        "--no-preview",
        "--integrator",
        integrator,
        "--spp",
        &spp.to_string(),
        "--width",
        "96",
        "--height",
        "72",
        "--aovs",
        "--threads",
        "2",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    a.extend(extra.iter().map(|s| s.to_string()));
    a
}

struct Out {
    code: Option<i32>,
    stderr: String,
}

fn run(args: &[String], env: &[(&str, &str)]) -> Out {
    let out = Command::new(BIN)
        .args(args)
        .envs(env.iter().copied())
        .output()
        .unwrap();
    Out {
        code: out.status.code(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn ok(args: &[String]) -> Out {
    let o = run(args, &[]);
    assert_eq!(o.code, Some(0), "{args:?}: {}", o.stderr);
    o
}

fn spawn(args: &[String]) -> Child {
    Command::new(BIN)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Waits until `path` exists (a first checkpoint), at most a minute.
fn wait_for(path: &Path) {
    let t = Instant::now();
    while !path.exists() {
        assert!(t.elapsed() < Duration::from_secs(60), "no {path:?}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Sets option `key` of `args` to `value`.
fn set(args: &mut Vec<String>, key: &str, value: &str) {
    match args.iter().position(|x| x == key) {
        Some(i) => args[i + 1] = value.into(),
        None => args.extend([key.into(), value.into()]),
    }
}

fn state(exr: &Path) -> PathBuf {
    vdbphoton::render::resume::state_path(exr)
}

fn image(exr: &Path) -> Image {
    read_exr(exr).unwrap().0
}

/// The passes a resumed render says it took over (`resumed: ... after N
/// passes`).
fn resumed_after(stderr: &str) -> Option<u32> {
    let l = stderr.lines().find(|l| l.starts_with("resumed: "))?;
    let n = l.split(" after ").nth(1)?.split(' ').next()?;
    n.parse().ok()
}

/// Renders uninterrupted, then again killed by SIGKILL once its first
/// checkpoint is down, and resumed: the same pixels, every layer.
fn killed_and_resumed(integrator: &str, extra: &[&str]) {
    let dir = common::tempdir();
    let spp = 40;
    let whole = dir.path().join("whole.exr");
    ok(&args(&whole, integrator, spp, extra));
    let exr = dir.path().join("killed.exr");
    let mut a = args(&exr, integrator, spp, extra);
    a.extend(["--checkpoint".into(), "0.05s".into()]);
    let mut child = spawn(&a);
    wait_for(&state(&exr));
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(state(&exr).exists());
    a.push("--resume".into());
    let o = ok(&a);
    let k = resumed_after(&o.stderr).unwrap_or_else(|| panic!("not resumed: {}", o.stderr));
    assert!(k > 0 && k < spp, "resumed after {k} of {spp} passes");
    assert_eq!(image(&exr), image(&whole), "{integrator} {extra:?}");
    // The finished render leaves its EXR only.
    assert_eq!(
        common::dir_entries(dir.path()),
        vec!["killed.exr", "whole.exr"]
    );
}

#[test]
fn a_killed_path_traced_render_resumes_to_the_same_pixels() {
    killed_and_resumed("path", &[]);
}

#[test]
fn a_killed_photon_render_resumes_to_the_same_pixels() {
    killed_and_resumed("photon", &[]);
}

#[test]
fn a_killed_tile_resumes_to_the_same_pixels() {
    killed_and_resumed("photon", &["--tile", "1/4"]);
}

/// A render whose integrator `auto` chose, killed and resumed, goes on
/// with the integrator its state was made with, without a pilot of its own
/// (which could choose the other, and the state would then be refused):
/// the header says so, and the pixels are those of an uninterrupted render
/// with that integrator named.
#[test]
fn a_killed_auto_render_resumes_with_the_integrator_it_chose() {
    let dir = common::tempdir();
    let spp = 40;
    let exr = dir.path().join("killed.exr");
    let mut a = args(&exr, "auto", spp, &[]);
    a.extend(["--checkpoint".into(), "0.05s".into()]);
    let mut child = spawn(&a);
    wait_for(&state(&exr));
    child.kill().unwrap();
    child.wait().unwrap();
    let chosen = vdbphoton::render::resume::integrator_of(&state(&exr))
        .expect("the state names its integrator");
    a.push("--resume".into());
    let o = ok(&a);
    assert!(
        resumed_after(&o.stderr).is_some(),
        "not resumed: {}",
        o.stderr
    );
    let (img, attrs) = read_exr(&exr).unwrap();
    let get = |k: &str| attrs.iter().find(|(n, _)| n == k).map(|(_, v)| v.clone());
    assert_eq!(get("vdbphoton/integrator"), Some(chosen.clone()));
    let why = get("vdbphoton/auto").unwrap_or_default();
    assert!(why.contains("resumed"), "{why}");
    let whole = dir.path().join("whole.exr");
    ok(&args(&whole, &chosen, spp, &[]));
    assert_eq!(img, image(&whole), "{chosen}");
}

/// Runs a render and sends it SIGTERM `times` times at once once it has
/// reported progress (a pass is under way); returns its exit code and
/// stderr.
fn terminate_under_way(args: &[String], times: usize) -> (Option<i32>, String) {
    use std::io::{BufRead, BufReader, Read};
    let mut child = spawn(args);
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut text = String::new();
    let mut line = String::new();
    while err.read_line(&mut line).unwrap() > 0 {
        text.push_str(&line);
        if line.starts_with("rendering:") {
            break;
        }
        line.clear();
    }
    assert!(text.contains("rendering:"), "no progress: {text}");
    for _ in 0..times {
        Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap();
    }
    err.read_to_string(&mut text).unwrap();
    (child.wait().unwrap().code(), text)
}

#[test]
fn sigterm_finishes_the_pass_writes_a_checkpoint_and_resumes_exactly() {
    let dir = common::tempdir();
    let whole = dir.path().join("whole.exr");
    ok(&args(&whole, "photon", 60, &[]));
    let exr = dir.path().join("t.exr");
    // A checkpoint interval longer than the render: only the signal
    // writes one.
    let mut a = args(&exr, "photon", 60, &["--checkpoint", "1h"]);
    let (code, err) = terminate_under_way(&a, 1);
    assert_eq!(code, Some(143), "{err}");
    assert!(
        err.contains("keeps") && err.contains("--resume"),
        "the message says what is kept: {err}"
    );
    assert!(state(&exr).exists() && exr.exists());
    a.push("--resume".into());
    let o = ok(&a);
    assert!(
        resumed_after(&o.stderr).is_some_and(|k| k > 0),
        "{}",
        o.stderr
    );
    assert_eq!(image(&exr), image(&whole));
}

#[test]
fn a_render_killed_while_writing_its_state_resumes_from_the_one_before() {
    let dir = common::tempdir();
    let whole = dir.path().join("whole.exr");
    ok(&args(&whole, "path", 24, &[]));
    let exr = dir.path().join("p.exr");
    // A checkpoint after every pass; the process kills itself (SIGKILL)
    // halfway through the state of pass 3, as a power cut would.
    let mut a = args(&exr, "path", 24, &["--checkpoint", "0.001s"]);
    let o = run(&a, &[("VDBPHOTON_TEST_DIE_WRITING_STATE", "3")]);
    assert_eq!(o.code, None, "killed by its signal: {}", o.stderr);
    let names = common::dir_entries(dir.path());
    assert!(
        names.iter().any(|n| n.starts_with(".p.exr.vdbstate.tmp-")),
        "the half-written state: {names:?}"
    );
    a.push("--resume".into());
    let o = ok(&a);
    assert_eq!(resumed_after(&o.stderr), Some(2), "{}", o.stderr);
    assert_eq!(image(&exr), image(&whole));
    // The half-written temporary is gone with the render's lock.
    assert_eq!(common::dir_entries(dir.path()), vec!["p.exr", "whole.exr"]);
}

/// A killed render's checkpoint, EXR and state, in a fresh folder.
fn killed_render(integrator: &str, spp: u32) -> (tempfile::TempDir, PathBuf, Vec<String>) {
    let dir = common::tempdir();
    let exr = dir.path().join("k.exr");
    let a = args(&exr, integrator, spp, &["--checkpoint", "0.05s"]);
    let mut child = spawn(&a);
    // The state is written first, then the EXR.
    wait_for(&state(&exr));
    wait_for(&exr);
    child.kill().unwrap();
    child.wait().unwrap();
    (dir, exr, a)
}

#[test]
fn a_damaged_state_is_refused_and_nothing_is_overwritten_before_a_new_checkpoint() {
    for damage in ["truncate", "flip", "garbage", "empty"] {
        let (dir, exr, mut a) = killed_render("path", 400);
        let st = state(&exr);
        let mut bytes = std::fs::read(&st).unwrap();
        match damage {
            "truncate" => bytes.truncate(bytes.len() / 2),
            "flip" => {
                let i = bytes.len() - 100;
                bytes[i] ^= 0x10;
            }
            "garbage" => bytes = b"this is not a state\n".to_vec(),
            _ => bytes.clear(),
        }
        std::fs::write(&st, &bytes).unwrap();
        let exr_before = std::fs::read(&exr).unwrap();
        // Resumed without checkpoints and killed once it has said why it
        // does not resume: the old checkpoint and state are as they were.
        a.retain(|x| x != "--checkpoint" && x != "0.05s");
        a.push("--resume".into());
        let mut child = Command::new(BIN)
            .args(&a)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut err = String::new();
        {
            use std::io::{BufRead, BufReader};
            let mut lines = BufReader::new(child.stderr.take().unwrap());
            let mut line = String::new();
            while lines.read_line(&mut line).unwrap() > 0 {
                err.push_str(&line);
                if line.contains("not resuming") {
                    break;
                }
                line.clear();
            }
        }
        child.kill().unwrap();
        child.wait().unwrap();
        let why = err
            .lines()
            .find(|l| l.contains("not resuming"))
            .unwrap_or("");
        assert!(
            why.starts_with("vdbphoton: warning: not resuming from ")
                && why.contains("k.exr.vdbstate")
                && why.contains("starts from its first pass"),
            "{damage}: {err}"
        );
        let expect = match damage {
            "garbage" | "empty" => "not a vdbphoton render state",
            _ => "damaged",
        };
        assert!(why.contains(expect), "{damage}: {why}");
        assert_eq!(
            std::fs::read(&st).unwrap(),
            bytes,
            "{damage}: state touched"
        );
        assert_eq!(
            std::fs::read(&exr).unwrap(),
            exr_before,
            "{damage}: EXR touched"
        );
        drop(dir);
    }
}

#[test]
fn a_state_of_another_render_is_refused_with_the_reason() {
    let (_dir, exr, a) = killed_render("path", 400);
    let cases: [(&[&str], &str); 4] = [
        (&["--seed", "7"], "it is of seed 0, not 7"),
        (&["--width", "80"], "it is of a 96x72 image, not 80x72"),
        (&["--tile", "0/2"], "it is of the pixels"),
        (&["--max-bounces", "3"], "it is of another scene"),
    ];
    for (change, why) in cases {
        let mut b = a.clone();
        b.retain(|x| x != "--checkpoint" && x != "0.05s");
        set(&mut b, change[0], change[1]);
        b.push("--resume".into());
        set(&mut b, "--spp", "1");
        // Another output, so the killed render's state stays for the
        // next case: the state is named by copying it beside it.
        let other = exr.with_file_name(format!("o{}.exr", change.join("")).replace('/', "_"));
        std::fs::copy(state(&exr), state(&other)).unwrap();
        let i = b.iter().position(|x| x == "-o").unwrap();
        b[i + 1] = other.to_str().unwrap().into();
        let o = ok(&b);
        assert!(o.stderr.contains(why), "{change:?}: {}", o.stderr);
        assert!(resumed_after(&o.stderr).is_none());
    }
    // The integrator is part of what a state belongs to.
    let mut b = a.clone();
    b.retain(|x| x != "--checkpoint" && x != "0.05s");
    let i = b.iter().position(|x| x == "path").unwrap();
    b[i] = "photon".into();
    b.push("--resume".into());
    set(&mut b, "--spp", "1");
    let o = ok(&b);
    assert!(
        o.stderr.contains("it is of integrator path, not photon"),
        "{}",
        o.stderr
    );
}

#[test]
fn a_state_of_another_build_is_refused() {
    use vdbphoton::film::{Film, Region};
    use vdbphoton::render::resume::{read, write, Identity, Position};
    let dir = common::tempdir();
    let path = dir.path().join("s.vdbstate");
    let mut film = Film::new(8, 6, Region::full(8, 6), true).with_guides();
    film.add(
        3,
        2,
        &vdbphoton::film::SampleResult {
            l: vdbphoton::Rgb::new(0.1, 0.2, 0.3),
            direct: vdbphoton::Rgb::new(0.01, 0.02, 0.03),
            transmittance: 0.5,
            albedo: Some(vdbphoton::Rgb::new(0.7, 0.8, 0.9)),
            ..Default::default()
        },
    );
    let desc = vdbphoton::render::load_scene(format!("{SCENES}/cloud.toml")).unwrap();
    let id = Identity::of(&desc, "path", &film);
    let at = Position {
        passes: 1,
        seconds: 0.25,
        last_pass: 0.25,
    };
    write(&path, &id, at, &vec![], &film).unwrap();
    let empty = Film::new(8, 6, Region::full(8, 6), true).with_guides();
    let back = read(&path, &id, &empty).unwrap().unwrap();
    assert_eq!(back.film, film);
    assert_eq!(back.at, at);
    let other = Identity {
        binary: "0.0.1 0123456789abcdef".into(),
        ..id.clone()
    };
    let why = read(&path, &other, &empty).unwrap_err();
    assert!(why.contains("another build of vdbphoton"), "{why}");
    // A film of another layout (no AOVs, no albedo) is refused too.
    let no_aovs = Film::new(8, 6, Region::full(8, 6), false);
    let why = read(&path, &Identity::of(&desc, "path", &no_aovs), &no_aovs).unwrap_err();
    assert!(why.contains("aovs"), "{why}");
    // No state: nothing to resume, no error.
    assert!(read(&dir.path().join("none"), &id, &empty)
        .unwrap()
        .is_none());
}

#[test]
fn a_time_budget_counts_the_time_already_spent() {
    let (_dir, exr, mut a) = killed_render("path", 100_000);
    // The killed render ran at least until its first checkpoint; a budget
    // shorter than what the state holds adds no pass.
    std::thread::sleep(Duration::from_millis(10));
    a.retain(|x| x != "--checkpoint" && x != "0.05s");
    a.extend(["--resume".into(), "--time".into(), "0.01s".into()]);
    let o = ok(&a);
    let k = resumed_after(&o.stderr).expect("resumed");
    assert!(
        o.stderr.contains(&format!("({k} passes, {k} spp)")),
        "no pass beyond the {k} of the state: {}",
        o.stderr
    );
    assert!(!state(&exr).exists(), "the finished render's state stays");
}

#[test]
fn two_renders_of_one_output_exclude_each_other() {
    let dir = common::tempdir();
    let exr = dir.path().join("l.exr");
    let a = args(&exr, "path", 100_000, &["--checkpoint", "10s"]);
    let mut first = spawn(&a);
    let lock = vdbphoton::render::resume::lock_path(&exr);
    // The lock names its holder once the render is under way.
    let t = Instant::now();
    while std::fs::read_to_string(&lock)
        .unwrap_or_default()
        .is_empty()
    {
        assert!(t.elapsed() < Duration::from_secs(30));
        std::thread::sleep(Duration::from_millis(5));
    }
    let mut b = a.clone();
    b.push("--resume".into());
    let o = run(&b, &[]);
    first.kill().unwrap();
    first.wait().unwrap();
    assert_eq!(o.code, Some(1), "{}", o.stderr);
    assert_eq!(o.stderr.lines().count(), 1, "{}", o.stderr);
    assert!(
        o.stderr.contains("another render of")
            && o.stderr.contains(&format!("process {}", first.id()))
            && o.stderr.contains("l.exr.lock"),
        "{}",
        o.stderr
    );
    // The first died by SIGKILL, which frees its lock: a render goes on.
    let mut c = a.clone();
    set(&mut c, "--spp", "2");
    ok(&c);
}

#[test]
fn a_sequence_resumes_at_the_frame_it_was_killed_in() {
    let dir = common::tempdir();
    let d = dir.path();
    for f in 1..=3 {
        let o = Command::new(BIN)
            .current_dir(d)
            .args(["generate", "cloud", &format!("f_{f:04}.vdb"), "--res", "16"])
            .args(["--seed", &f.to_string()])
            .output()
            .unwrap();
        assert!(o.status.success());
    }
    std::fs::write(
        d.join("seq.toml"),
        r#"[render]
width = 64
height = 48
spp = 300
integrator = "path"
output = "OUT/f_{frame:04}.exr"

[camera]
framing = "auto"

[[light]]
type = "sun"
direction = [0.3, -1.0, 1.0]
irradiance = 2.0

[[volume]]
file = "f_{frame:04}.vdb"
bounds = "sequence"
[volume.material]
density = 8.0
"#,
    )
    .unwrap();
    let render = |out: &str, extra: &[&str]| {
        let mut c = Command::new(BIN);
        c.current_dir(d)
            .args(["render", "seq.toml", "--frames", "1-3", "-q", "-o"])
            .arg(format!("{out}/f_{{frame:04}}.exr"))
            .args(extra);
        c
    };
    let o = render("whole", &[]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let resume = ["--checkpoint", "0.05s", "--skip-existing", "--resume"];
    let mut child = render("k", &resume)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    wait_for(&state(&d.join("k/f_0002.exr")));
    child.kill().unwrap();
    child.wait().unwrap();
    let frame1 = std::fs::read(d.join("k/f_0001.exr")).unwrap();
    assert!(!d.join("k/f_0003.exr").exists());
    let o = render("k", &resume).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("frame 1: skipped"), "{err}");
    assert!(
        err.contains("resumed: ") && err.contains("f_0002.exr.vdbstate"),
        "{err}"
    );
    assert_eq!(std::fs::read(d.join("k/f_0001.exr")).unwrap(), frame1);
    for f in 1..=3 {
        let name = format!("f_{f:04}.exr");
        assert_eq!(
            image(&d.join("k").join(&name)),
            image(&d.join("whole").join(&name)),
            "frame {f}"
        );
    }
    assert_eq!(
        common::dir_entries(&d.join("k")),
        vec!["f_0001.exr", "f_0002.exr", "f_0003.exr"]
    );
}

#[test]
fn a_signal_delivered_twice_at_once_still_gets_its_last_checkpoint() {
    // Slurm signals every process of a requeued job, and the job script
    // passes its own signal on: the render sees SIGTERM twice within
    // milliseconds, which is one request, not an order to exit at once.
    let dir = common::tempdir();
    let exr = dir.path().join("twice.exr");
    let a = args(&exr, "photon", 60, &["--checkpoint", "1h"]);
    let (code, err) = terminate_under_way(&a, 2);
    assert_eq!(code, Some(143), "{err}");
    assert!(err.contains("keeps"), "{err}");
    assert!(state(&exr).exists() && exr.exists());
}

#[test]
fn an_output_folder_that_cannot_be_written_is_refused_before_the_render() {
    // /sys is read-only even for root (permission bits are not).
    let exr = Path::new("/sys/vdbphoton-test/out.exr");
    let t = Instant::now();
    let o = run(
        &args(exr, "path", 100_000, &["--checkpoint", "1s", "--resume"]),
        &[],
    );
    assert_eq!(o.code, Some(1), "{}", o.stderr);
    assert_eq!(o.stderr.lines().count(), 1, "{}", o.stderr);
    assert!(o.stderr.contains("/sys"), "{}", o.stderr);
    assert!(t.elapsed() < Duration::from_secs(10));
}

#[test]
fn resuming_a_finished_render_leaves_it_alone_and_another_render_replaces_it() {
    // A farm task run again after it finished (a requeue of a whole
    // array): its EXR, without a state beside it, is this render's.
    let dir = common::tempdir();
    let exr = dir.path().join("done.exr");
    let mut a = args(&exr, "path", 8, &["--checkpoint", "0.05s"]);
    ok(&a);
    let finished = std::fs::read(&exr).unwrap();
    a.push("--resume".into());
    let o = ok(&a);
    assert!(
        o.stderr
            .contains("is this render, finished (8 passes); nothing to resume"),
        "{}",
        o.stderr
    );
    assert_eq!(std::fs::read(&exr).unwrap(), finished);
    assert_eq!(common::dir_entries(dir.path()), vec!["done.exr"]);
    // Another seed is another render: it renders afresh.
    set(&mut a, "--seed", "5");
    let o = ok(&a);
    assert!(!o.stderr.contains("nothing to resume"), "{}", o.stderr);
    assert_ne!(std::fs::read(&exr).unwrap(), finished);
}
