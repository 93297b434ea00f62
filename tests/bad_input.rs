//! Bad input to `vdbphoton info`: each case gives one clear line naming the
//! file, a nonzero exit, and never a panic or an abort.

mod common;

use std::path::Path;
use std::process::Command;
use vdbphoton::generate;
use vdbphoton::vdb::{reference, write_vdb, AnyGrid};

const BIN: &str = env!("CARGO_BIN_EXE_vdbphoton");

/// Runs `vdbphoton info ARGS`, returns (exit code, stderr).
fn info(args: &[&str]) -> (i32, String) {
    let out = Command::new(BIN).arg("info").args(args).output().unwrap();
    let code = out
        .status
        .code()
        .expect("killed by a signal (an abort or a crash)");
    (code, String::from_utf8_lossy(&out.stderr).into_owned())
}

/// The case fails cleanly: exit 1, one line that names `name` and contains
/// every word of `words`, no panic.
fn assert_clean_error(path: &Path, extra: &[&str], name: &str, words: &[&str]) {
    let mut args = vec![path.to_str().unwrap()];
    args.extend_from_slice(extra);
    let (code, err) = info(&args);
    assert_eq!(
        code,
        1,
        "{}: exit code {code}, stderr: {err}",
        path.display()
    );
    assert!(!err.contains("panicked"), "panic: {err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "expected one line, got: {err}");
    assert!(lines[0].starts_with("vdbphoton: error: "), "{err}");
    assert!(
        lines[0].contains(name),
        "the message does not name '{name}': {err}"
    );
    for w in words {
        assert!(lines[0].contains(w), "the message lacks '{w}': {err}");
    }
}

#[test]
fn missing_file() {
    let dir = common::tempdir();
    let p = dir.path().join("nothere.vdb");
    assert_clean_error(&p, &[], "nothere.vdb", &["No such file"]);
}

#[test]
fn directory() {
    let dir = common::tempdir();
    assert_clean_error(
        dir.path(),
        &[],
        &dir.path().display().to_string(),
        &["directory"],
    );
}

#[test]
fn empty_file() {
    let dir = common::tempdir();
    let p = dir.path().join("empty.vdb");
    std::fs::write(&p, b"").unwrap();
    assert_clean_error(&p, &[], "empty.vdb", &["empty"]);
}

#[test]
fn text_file() {
    let dir = common::tempdir();
    let p = dir.path().join("notes.vdb");
    std::fs::write(&p, "this is not a volume\n".repeat(50)).unwrap();
    assert_clean_error(&p, &[], "notes.vdb", &["not an OpenVDB file"]);
}

#[test]
fn truncated_cloud_at_twenty_lengths() {
    let dir = common::tempdir();
    let full = dir.path().join("cloud.vdb");
    write_vdb(&full, &[AnyGrid::Float(generate::cloud(48, 2).unwrap())]).unwrap();
    let bytes = std::fs::read(&full).unwrap();
    let n = bytes.len();
    // Inside the header, inside the grid descriptor, and all through the data.
    let mut lengths = vec![1, 7, 8, 20, 64, 100, 140, 200, 250, 320];
    lengths.extend((1..=9).map(|k| n * k / 10));
    lengths.push(n - 1);
    assert_eq!(lengths.len(), 20);
    for len in lengths {
        let p = dir.path().join(format!("cut{len}.vdb"));
        std::fs::write(&p, &bytes[..len]).unwrap();
        let t0 = std::time::Instant::now();
        assert_clean_error(&p, &[], &format!("cut{len}.vdb"), &[]);
        let (_, err) = info(&[p.to_str().unwrap()]);
        assert!(
            err.contains("truncated") || err.contains("not an OpenVDB file"),
            "length {len}: {err}"
        );
        // Refused by the header check, not after OpenVDB allocates for a
        // garbage length (which takes a minute and gigabytes).
        assert!(
            t0.elapsed().as_secs() < 20,
            "length {len} took {:?}",
            t0.elapsed()
        );
    }
}

#[test]
fn corrupt_bytes_never_crash() {
    // Random bytes overwritten in the data block: OpenVDB either reports an
    // error (exit 1, one line naming the file) or reads changed values
    // (exit 0). Never a signal, never a panic.
    let dir = common::tempdir();
    let full = dir.path().join("cloud.vdb");
    write_vdb(&full, &[AnyGrid::Float(generate::cloud(48, 6).unwrap())]).unwrap();
    let bytes = std::fs::read(&full).unwrap();
    let mut rng = common::TestRng(2024);
    let mut failures = 0;
    for case in 0..24 {
        let mut b = bytes.clone();
        let k = 1 + (rng.next_u64() % 16) as usize;
        for _ in 0..k {
            let at = 300 + (rng.next_u64() as usize % (b.len() - 300));
            b[at] = rng.next_u64() as u8;
        }
        let p = dir.path().join(format!("bad{case}.vdb"));
        std::fs::write(&p, &b).unwrap();
        let (code, err) = info(&[p.to_str().unwrap()]);
        assert!(!err.contains("panicked"), "case {case}: {err}");
        assert!(code == 0 || code == 1, "case {case}: exit {code}");
        if code == 1 {
            failures += 1;
            assert_eq!(err.lines().count(), 1, "case {case}: {err}");
            assert!(
                err.contains(&format!("bad{case}.vdb")),
                "case {case}: {err}"
            );
        }
    }
    assert!(failures > 0, "no corruption was detected at all");
}

#[test]
fn wrong_grid_name_lists_the_grids() {
    let dir = common::tempdir();
    let p = dir.path().join("plume.vdb");
    write_vdb(&p, &generate::plume(24, 1).unwrap()).unwrap();
    assert_clean_error(
        &p,
        &["--grid", "densty"],
        "plume.vdb",
        &[
            "no grid named 'densty'",
            "density",
            "flame",
            "temperature",
            "velocity",
        ],
    );
}

#[test]
fn unsupported_value_type() {
    let dir = common::tempdir();
    let p = dir.path().join("labels.vdb");
    reference::write_unsupported_fixture(&p, "int32").unwrap();
    assert_clean_error(
        &p,
        &["--grid", "labels"],
        "labels.vdb",
        &["labels", "int32"],
    );
    // Listed without --grid, it is shown as unsupported and the command works.
    let (code, _) = info(&[p.to_str().unwrap()]);
    assert_eq!(code, 0);
}

#[test]
fn frustum_transform() {
    let dir = common::tempdir();
    let p = dir.path().join("frustum.vdb");
    reference::write_unsupported_fixture(&p, "frustum").unwrap();
    assert_clean_error(
        &p,
        &["--grid", "density"],
        "frustum.vdb",
        &["density", "non-linear"],
    );
}

#[test]
fn good_file_prints_its_grids() {
    let dir = common::tempdir();
    let p = dir.path().join("plume.vdb");
    write_vdb(&p, &generate::plume(24, 1).unwrap()).unwrap();
    let out = Command::new(BIN)
        .args(["info", p.to_str().unwrap(), "--json"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let grids = v["grids"].as_array().unwrap();
    assert_eq!(grids.len(), 4);
    let d = grids.iter().find(|g| g["name"] == "density").unwrap();
    assert_eq!(d["value_type"], "float");
    assert!(d["active_voxels"].as_u64().unwrap() > 100);
    assert!(d["memory_bytes"].as_u64().unwrap() > 0);
    assert_eq!(
        v["metadata"]["creator"].as_str().unwrap(),
        concat!("vdbphoton ", env!("CARGO_PKG_VERSION"))
    );
}

/// A density or colour grid holding NaN or infinite values (a simulation
/// that blew up) is refused at load with one line naming the file and the
/// grid, not rendered into black or white pixels.
#[test]
fn nan_and_infinite_grids_are_refused_at_load() {
    use glam::{DVec3, IVec3, Vec3};
    let dir = common::tempdir();
    let base = common::const_box(
        "density",
        1.0,
        DVec3::splat(-0.5),
        1.0 / 16.0,
        IVec3::splat(2),
    );
    let nan = base.map_values("density", |_| f32::NAN).unwrap();
    write_vdb(dir.path().join("nan.vdb"), &[AnyGrid::Float(nan)]).unwrap();
    let colour = base
        .map_values("color", |v| Vec3::new(v, f32::INFINITY, 0.5))
        .unwrap();
    write_vdb(
        dir.path().join("colour.vdb"),
        &[AnyGrid::Float(base.clone()), AnyGrid::Vec3(colour)],
    )
    .unwrap();
    for (file, extra, grid) in [
        ("nan.vdb", "", "density"),
        ("colour.vdb", "color_grid = \"color\"\n", "color"),
    ] {
        let scene = dir.path().join(format!("{file}.toml"));
        std::fs::write(
            &scene,
            format!(
                "[render]\nwidth = 8\nheight = 8\nspp = 1\n[[volume]]\nfile = \"{file}\"\n{extra}"
            ),
        )
        .unwrap();
        let out = Command::new(BIN)
            .current_dir(dir.path())
            .args(["render", scene.to_str().unwrap(), "-o", "o.exr"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{file}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{file}: {err}");
        assert!(
            err.contains(file)
                && err.contains(&format!("grid '{grid}'"))
                && err.contains("NaN or infinite"),
            "{file}: {err}"
        );
        assert!(!dir.path().join("o.exr").exists());
    }
}
