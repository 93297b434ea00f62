//! Inputs the fuzz campaigns (tools/fuzz) found, kept small under
//! `tests/data/fuzz/`: each must now be refused with one line naming the
//! file and a nonzero exit, quickly, never with a signal.

mod common;

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_vdbphoton");

fn data(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/fuzz")
        .join(name)
}

/// Runs vdbphoton with `args`; asserts a clean refusal naming `name`.
fn assert_refused(args: &[&std::ffi::OsStr], name: &str, within: Duration) -> String {
    let t0 = Instant::now();
    let out = Command::new(BIN).args(args).output().unwrap();
    let took = t0.elapsed();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    let code = out
        .status
        .code()
        .unwrap_or_else(|| panic!("killed by a signal: {err}"));
    assert_eq!(code, 1, "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("vdbphoton: error: ") && err.contains(name),
        "{err}"
    );
    assert!(took < within, "took {took:?}");
    err
}

/// A 9.6 MB scene of 100,000 lights (the campaign's "array lengthened")
/// took 1.6 s and 450 MB to be refused; scene files over 1 MiB are now
/// refused unread. Made here rather than committed.
#[test]
fn huge_scene_file_is_refused_unread() {
    let dir = common::tempdir();
    let p = dir.path().join("lights.toml");
    let light = "[[light]]\ntype = \"sun\"\ndirection = [0.0, 0.0, 1.0]\nirradiance = 1.0\n\n";
    std::fs::write(&p, light.repeat(30_000)).unwrap();
    let err = assert_refused(
        &["render".as_ref(), p.as_os_str()],
        "lights.toml",
        Duration::from_secs(2),
    );
    assert!(err.contains("larger than 1 MiB"), "{err}");
}

/// Campaign seed 1, input 4, against the reader before the grid walk: one
/// byte of a half-float leaf's block length (the top byte, making it a
/// huge negative "uncompressed" length). OpenVDB's `bloscFromStream` read
/// that many bytes into the leaf's buffer: SIGSEGV or glibc's "corrupted
/// size vs. prev_size".
#[test]
fn leaf_block_length_that_overran_a_heap_buffer() {
    let p = data("leaf_block_length_half.vdb");
    let err = assert_refused(
        &["info".as_ref(), p.as_os_str()],
        "leaf_block_length_half.vdb",
        Duration::from_secs(2),
    );
    assert!(
        err.contains("grid 'density'") && err.contains("leaf 14 of 30"),
        "{err}"
    );
    assert!(err.contains("uncompressed block claims"), "{err}");
}

/// Input 114: the same in an internal node's value block
/// (`InternalNode::readTopology`): "free(): invalid pointer" or SIGSEGV.
#[test]
fn internal_node_block_length_that_overran_a_heap_buffer() {
    let p = data("node_block_length.vdb");
    let err = assert_refused(
        &["info".as_ref(), p.as_os_str()],
        "node_block_length.vdb",
        Duration::from_secs(2),
    );
    assert!(
        err.contains("node at (-128, 0, -128)") && err.contains("its values"),
        "{err}"
    );
}

/// Input 1801: one byte of the root's tile count. OpenVDB read millions of
/// tiles past the topology's end and took 107 s to fail.
#[test]
fn root_tile_count_that_took_minutes() {
    let p = data("root_tile_count.vdb");
    let err = assert_refused(
        &["info".as_ref(), p.as_os_str()],
        "root_tile_count.vdb",
        Duration::from_secs(2),
    );
    assert!(err.contains("root tile"), "{err}");
}

/// Input 1922: one byte of a grid metadata name's length. OpenVDB
/// allocated for it and the garbage after it: 15 s and 9.5 GB.
#[test]
fn metadata_name_length_that_took_gigabytes() {
    let p = data("metadata_name_length.vdb");
    let err = assert_refused(
        &["info".as_ref(), p.as_os_str()],
        "metadata_name_length.vdb",
        Duration::from_secs(2),
    );
    assert!(
        err.contains("a metadata name") && err.contains("runs past the grid's end"),
        "{err}"
    );
}

/// The render hang of the second campaign: raw `sigma_a = 1e12` on a cloud
/// (`tests/data/fuzz/sigma_a_1e12.toml`) is refused at load, at once, for
/// both integrators, naming the file and the grid.
#[test]
fn absurd_absorption_is_refused_at_load() {
    for integrator in ["path", "photon"] {
        let err = assert_render_refused(
            "sigma_a_1e12.toml",
            &["--integrator", integrator],
            "cloud.vdb', grid 'density'",
        );
        assert!(err.contains("optical depth"), "{err}");
    }
}

/// Renders the scene `name` of tests/data/fuzz with `args` into a fresh
/// directory; asserts a clean refusal naming `names` within 2 s, and
/// nothing written.
fn assert_render_refused(name: &str, args: &[&str], names: &str) -> String {
    let scene = data(name);
    let dir = common::tempdir();
    let out = dir.path().join("o.exr");
    let mut all: Vec<&std::ffi::OsStr> = vec!["render".as_ref(), scene.as_os_str()];
    all.extend(args.iter().map(std::ffi::OsStr::new));
    all.extend(["-o".as_ref(), out.as_os_str()]);
    let err = assert_refused(&all, names, Duration::from_secs(2));
    assert!(common::dir_entries(dir.path()).is_empty());
    err
}

/// AFL++'s render target (stop 28): a temperature grid whose transform puts
/// its voxels 10^5 density voxels away (`afl_temperature_far.*`, written by
/// `make_afl_cases.py`). The majorant grid over the density and the
/// emitting voxels wanted 2 x 19,200 x 19,200 cells of 8 voxels: the
/// original input rendered 16 x 12 for 121 s in 3 GB, this one ran past
/// 100 s, and a larger extent overflowed the cell count. The cells now
/// grow to a budget; both integrators render it at once, finite.
#[test]
fn emission_far_from_the_density_renders_at_once() {
    let scene = data("afl_temperature_far.toml");
    for integrator in ["path", "photon"] {
        let dir = common::tempdir();
        let out = dir.path().join("o.exr");
        let t0 = Instant::now();
        let run = Command::new(BIN)
            .args(["render".as_ref(), scene.as_os_str()])
            .args(["--integrator", integrator, "--quiet", "--no-preview", "-o"])
            .arg(&out)
            .output()
            .unwrap();
        let took = t0.elapsed();
        assert!(
            run.status.success(),
            "{integrator}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        // Generous: the point is minutes against a fraction of a second.
        assert!(
            took < Duration::from_secs(30),
            "{integrator}: took {took:?}"
        );
        let img = vdbphoton::image::read_exr_rgb(&out).unwrap();
        assert!(img.pixels.iter().all(|p| p.is_finite()), "{integrator}");
    }
}

/// AFL++'s render target (stop 28): a density grid translated by -1.8e115
/// (`afl_density_1e115.*`). World space is single precision, so the volume
/// was nowhere: a black image without a word, and the emitting grid's box
/// overflowed the majorant grid's cell count. Now refused at load, naming
/// the grid, before any acceleration grid is built.
#[test]
fn a_volume_beyond_single_precision_is_refused() {
    let err = assert_render_refused(
        "afl_density_1e115.toml",
        &[],
        "afl_density_1e115.vdb', grid 'density'",
    );
    assert!(err.contains("single-precision world space"), "{err}");
}
