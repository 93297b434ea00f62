//! How a render runs and stops, from the command line: `--time` budgets,
//! `--checkpoint` rewrites, the photon integrator's header, SIGINT and
//! SIGTERM (exit 130 and 143, nothing partial left, the last checkpoint
//! still a valid image), extinction too high to render refused at once, and
//! renders that would not fit in memory refused before they start.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_vdbphoton");
const SCENES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");

fn render(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(BIN).arg("render").args(args).output().unwrap();
    (
        out.status.code().expect("killed by a signal"),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn header(exr: &Path) -> String {
    let meta = exr::meta::MetaData::read_from_file(exr, false).unwrap();
    format!("{:?}", meta.headers[0].own_attributes.other)
}

#[test]
fn time_budget_and_photon_header() {
    let dir = common::tempdir();
    let exr = dir.path().join("t.exr");
    let t = Instant::now();
    let (code, out, err) = render(&[
        &format!("{SCENES}/cloud.toml"),
        "-o",
        exr.to_str().unwrap(),
        "--no-preview",
        "--integrator",
        "photon",
        "--width",
        "48",
        "--height",
        "36",
        "--time",
        "2s",
        "-q",
    ]);
    let secs = t.elapsed().as_secs_f64();
    assert_eq!(code, 0, "{err}");
    assert!(secs < 8.0, "a 2 s budget took {secs} s");
    assert_eq!(out.trim(), format!("Saved: '{}'", exr.display()));
    let h = header(&exr);
    for key in [
        "vdbphoton/passes",
        "vdbphoton/photons_per_pass",
        "vdbphoton/photons_emitted",
        "vdbphoton/estimate",
        "vdbphoton/radius",
    ] {
        assert!(h.contains(key), "{key} not in the header: {h}");
    }
    assert!(h.contains("\"photon\""), "{h}");
    // Bad durations are one clear line each.
    for bad in ["0", "-3s", "ten", "5x"] {
        let (code, _, err) = render(&[&format!("{SCENES}/cloud.toml"), &format!("--time={bad}")]);
        assert_eq!(code, 1, "{bad}: {err}");
        assert!(err.contains("duration"), "{bad}: {err}");
        assert_eq!(err.lines().count(), 1, "{bad}: {err}");
    }
}

/// Starts a render of the default scene at many samples with a checkpoint
/// every `checkpoint`, waits until it is under way and then `wait` more,
/// sends `signal`.
fn interrupt(signal: &str, checkpoint: Option<&str>, wait: Duration) -> (i32, tempfile::TempDir) {
    let dir = common::tempdir();
    let exr = dir.path().join("i.exr");
    let mut args = vec![
        "render".to_string(),
        format!("{SCENES}/cloud.toml"),
        "-o".into(),
        exr.to_str().unwrap().into(),
        "--integrator".into(),
        "path".into(),
        "--spp".into(),
        "100000".into(),
        "--width".into(),
        "64".into(),
        "--height".into(),
        "48".into(),
        "-q".into(),
    ];
    if let Some(c) = checkpoint {
        args.push("--checkpoint".into());
        args.push(c.into());
    }
    let child = Command::new(BIN)
        .args(&args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Under way: the render names itself in its output's lock once it has
    // started (its signal handlers are in place by then; a signal before
    // that, on a loaded machine, would find the process still starting).
    let lock = vdbphoton::render::resume::lock_path(&exr);
    let t0 = Instant::now();
    while std::fs::read_to_string(&lock)
        .unwrap_or_default()
        .is_empty()
    {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "the render never started"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    // With checkpoints: once the first is down (a signal before the first
    // pass ends writes nothing, rightly).
    while checkpoint.is_some() && !exr.exists() {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "no first checkpoint"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(wait);
    let ok = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let out = child.wait_with_output().unwrap();
    let code = out
        .status
        .code()
        .expect("the render must exit, not die of the signal");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("interrupted"), "{err}");
    (code, dir)
}

#[test]
fn interrupted_render_leaves_nothing_partial() {
    let (code, dir) = interrupt("-INT", None, Duration::from_millis(1500));
    assert_eq!(code, 130);
    assert!(
        common::dir_entries(dir.path()).is_empty(),
        "left behind: {:?}",
        common::dir_entries(dir.path())
    );
    let (code, dir) = interrupt("-TERM", None, Duration::from_millis(1500));
    assert_eq!(code, 143);
    assert!(common::dir_entries(dir.path()).is_empty());
}

#[test]
fn the_last_checkpoint_survives_an_interruption() {
    let (code, dir) = interrupt("-INT", Some("0.3s"), Duration::from_millis(1000));
    assert_eq!(code, 130);
    // The checkpoint, its preview and its resume state (`tests/resume.rs`),
    // whole, and no temporary files.
    let names = common::dir_entries(dir.path());
    assert_eq!(names, vec!["i.exr", "i.exr.vdbstate", "i.png"], "{names:?}");
    let png = std::fs::read(dir.path().join("i.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG") && png.len() > 100);
    let img = vdbphoton::image::read_exr_rgb(dir.path().join("i.exr")).unwrap();
    assert_eq!((img.width, img.height), (64, 48));
    assert!(img.mean() > 0.0);
    let h = header(&dir.path().join("i.exr"));
    assert!(h.contains("vdbphoton/passes"), "{h}");
}

#[test]
fn extinction_beyond_reason_is_refused_at_once() {
    let dir = common::tempdir();
    let scene = dir.path().join("huge.toml");
    for sigma in ["1e12", "1e30"] {
        let text = std::fs::read_to_string(format!("{SCENES}/cloud.toml"))
            .unwrap()
            .replace("cloud.vdb", &format!("{SCENES}/cloud.vdb"));
        // The bundled scene is Principled: its density multiplier is what
        // scales the extinction.
        let text = text.replace("density = 25.0", &format!("density = {sigma}"));
        std::fs::write(&scene, text).unwrap();
        let t = Instant::now();
        let (code, _, err) = render(&[
            scene.to_str().unwrap(),
            "-o",
            dir.path().join("o.exr").to_str().unwrap(),
            "--width",
            "16",
            "--height",
            "12",
            "--spp",
            "1",
        ]);
        assert_eq!(code, 1, "{err}");
        assert!(t.elapsed() < Duration::from_secs(5));
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.contains("optical depth") && err.contains("cloud.vdb"),
            "{err}"
        );
        assert!(!dir.path().join("o.exr").exists());
    }
}

#[test]
fn a_render_that_will_not_fit_is_refused_before_it_starts() {
    let dir = common::tempdir();
    let out = dir.path().join("m.exr");
    let t = Instant::now();
    let (code, _, err) = render(&[
        &format!("{SCENES}/cloud.toml"),
        "-o",
        out.to_str().unwrap(),
        "--width",
        "16384",
        "--height",
        "8192",
        "--max-memory",
        "2G",
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(t.elapsed() < Duration::from_secs(5));
    assert!(
        err.contains("needs about") && err.contains("2.0 GiB"),
        "{err}"
    );
    assert!(common::dir_entries(dir.path()).is_empty());
    // A grid that does not fit in what is left of the limit is refused
    // before OpenVDB allocates its tree, naming the file and the grid (the
    // process itself holds more than 12 MiB, so nothing is left).
    let (code, _, err) = render(&[
        &format!("{SCENES}/cloud.toml"),
        "-o",
        out.to_str().unwrap(),
        "--width",
        "8",
        "--height",
        "8",
        "--integrator",
        "path",
        "--max-memory",
        "12M",
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("cloud.vdb', grid 'density'") && err.contains("left of --max-memory"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(common::dir_entries(dir.path()).is_empty());
    let (code, _, err) = render(&[&format!("{SCENES}/cloud.toml"), "--max-memory", "lots"]);
    assert_eq!(code, 1);
    assert!(err.contains("amount of memory"), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
}

/// Where photons cannot help (nothing scatters: a volume that only
/// absorbs), `auto` takes the path tracer at once and says why in the
/// header, and an explicit `--integrator photon` says in one warning that
/// it gains nothing.
#[test]
fn photons_are_not_spent_where_nothing_scatters() {
    let dir = common::tempdir();
    let text = std::fs::read_to_string(format!("{SCENES}/cloud.toml"))
        .unwrap()
        .replace("file = \"cloud.vdb\"", &format!("file = \"{SCENES}/cloud.vdb\""))
        .replace(
            "density = 25.0\ncolor = [0.95, 0.95, 0.95]\nabsorption_color = [0.0, 0.0, 0.0]\nanisotropy = 0.5",
            "sigma_a = 30.0",
        );
    assert!(text.contains("sigma_a = 30.0"), "{text}");
    let scene = dir.path().join("absorber.toml");
    std::fs::write(&scene, text).unwrap();
    let exr = dir.path().join("a.exr");
    let base = [
        scene.to_str().unwrap(),
        "-o",
        exr.to_str().unwrap(),
        "--no-preview",
        "--width",
        "32",
        "--height",
        "24",
        "--spp",
        "2",
        "-q",
    ];
    let mut auto = base.to_vec();
    auto.extend(["--integrator", "auto"]);
    let (code, _, err) = render(&auto);
    assert_eq!(code, 0, "{err}");
    let h = header(&exr);
    assert!(h.contains("nothing scatters light"), "{h}");
    assert!(!err.contains("warning"), "{err}");
    let mut photon = base.to_vec();
    photon.extend(["--integrator", "photon"]);
    let (code, _, err) = render(&photon);
    assert_eq!(code, 0, "{err}");
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("warning")).collect();
    assert_eq!(warnings.len(), 1, "{err}");
    assert!(
        warnings[0].contains("the photon integrator gains nothing here"),
        "{err}"
    );
}

/// The Blender add-on passes its version; a binary that does not speak an
/// add-on of that major version refuses in one line, before any work (the
/// add-on checks the binary's `--version` the other way).
#[test]
fn an_addon_of_another_version_is_refused() {
    let dir = common::tempdir();
    let exr = dir.path().join("v.exr");
    let args = |v: &str| {
        vec![
            format!("{SCENES}/cloud.toml"),
            "-o".into(),
            exr.to_str().unwrap().into(),
            "--no-preview".into(),
            "--width".into(),
            "16".into(),
            "--height".into(),
            "12".into(),
            "--spp".into(),
            "1".into(),
            "--addon-version".into(),
            v.into(),
        ]
    };
    let run = |v: &str| {
        let a = args(v);
        render(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let (code, _, err) = run("2.0.0");
    assert_eq!(code, 1, "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("add-on is version 2.0.0") && err.contains("1.x"),
        "{err}"
    );
    assert!(!exr.exists());
    let (code, _, err) = run("1.1.0");
    assert_eq!(code, 0, "{err}");
}
