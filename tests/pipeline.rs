//! What a pipeline drives from the command line: frame sequences
//! (`--frames`, patterns, missing frames, `--skip-existing`, seeds per
//! frame), tiles of a frame (`--tile`, `--region`) and `merge`, the quick
//! look at a bare `.vdb`, `info` on several files, `compare
//! --side-by-side`, and the messages a new user meets.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use vdbphoton::image::{read_exr, read_exr_rgb, write_exr};

const BIN: &str = env!("CARGO_BIN_EXE_vdbphoton");

struct Run {
    code: i32,
    stdout: String,
    stderr: String,
}

fn run(dir: &Path, args: &[&str]) -> Run {
    let out = Command::new(BIN)
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    Run {
        code: out.status.code().expect("killed by a signal"),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn ok(dir: &Path, args: &[&str]) -> Run {
    let r = run(dir, args);
    assert_eq!(r.code, 0, "{args:?}: {}", r.stderr);
    r
}

/// A sequence of `n` small generated clouds `f_0001.vdb` ... in `dir`
/// (each of another seed, so each frame differs).
fn sequence(dir: &Path, frames: &[u32]) {
    for &f in frames {
        ok(
            dir,
            &[
                "generate",
                "cloud",
                &format!("f_{f:04}.vdb"),
                "--res",
                "16",
                "--seed",
                &f.to_string(),
            ],
        );
    }
}

/// A scene over `f_{frame:04}.vdb`; `integrator` and extra `[render]`
/// lines given.
fn scene(dir: &Path, integrator: &str, render: &str) -> PathBuf {
    let p = dir.join("seq.toml");
    std::fs::write(
        &p,
        format!(
            r#"[render]
width = 40
height = 30
spp = 3
integrator = "{integrator}"
output = "out/f_{{frame:04}}.exr"
{render}

[render.photon]
photons = 3000

[camera]
framing = "auto"
focal_length = 40.0

[[light]]
type = "sun"
direction = [0.3, -1.0, 1.0]
irradiance = 2.0

[environment]
radiance = 0.1

[[volume]]
file = "f_{{frame:04}}.vdb"
bounds = "sequence"
[volume.material]
density = 8.0
"#
        ),
    )
    .unwrap();
    p
}

fn pixels(p: &Path) -> Vec<glam::Vec4> {
    read_exr(p).unwrap().0.pixels().to_vec()
}

fn saved(stdout: &str) -> Vec<String> {
    stdout
        .lines()
        .filter_map(|l| {
            l.strip_prefix("Saved: '")?
                .strip_suffix('\'')
                .map(String::from)
        })
        .collect()
}

#[test]
fn a_sequence_renders_each_frame_and_reports_missing_ones_by_number() {
    let d = common::tempdir();
    let dir = d.path();
    sequence(dir, &[1, 2, 4]);
    scene(dir, "path", "");
    let r = run(dir, &["render", "seq.toml", "--frames", "1-4", "-q"]);
    // Frame 3 is missing: it fails with its number, the others are written,
    // and the exit code says not every frame was.
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(
        r.stderr.contains("frame 3") && r.stderr.contains("f_0003.vdb"),
        "{}",
        r.stderr
    );
    assert!(r.stderr.contains("1 of 4 frames failed: 3"), "{}", r.stderr);
    let out: Vec<String> = saved(&r.stdout)
        .iter()
        .map(|p| {
            Path::new(p)
                .file_name()
                .unwrap()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    assert_eq!(out, ["f_0001.exr", "f_0002.exr", "f_0004.exr"]);
    // Neighbouring frames differ (their own volumes and seeds), and a frame
    // rendered alone is the frame of the sequence, bit for bit.
    let f1 = pixels(&dir.join("out/f_0001.exr"));
    let f2 = pixels(&dir.join("out/f_0002.exr"));
    assert_ne!(f1, f2);
    ok(
        dir,
        &[
            "render",
            "seq.toml",
            "--frame",
            "2",
            "-o",
            "alone.exr",
            "-q",
        ],
    );
    assert_eq!(pixels(&dir.join("alone.exr")), f2);

    // Resuming: existing frames are skipped, not rendered again.
    let before = std::fs::metadata(dir.join("out/f_0001.exr"))
        .unwrap()
        .modified()
        .unwrap();
    sequence(dir, &[3]);
    let r = ok(
        dir,
        &[
            "render",
            "seq.toml",
            "--frames",
            "1-4",
            "--skip-existing",
            "-q",
        ],
    );
    assert!(r.stderr.contains("frame 1: skipped"), "{}", r.stderr);
    assert_eq!(saved(&r.stdout).len(), 1, "{}", r.stdout);
    assert!(dir.join("out/f_0003.exr").is_file());
    let after = std::fs::metadata(dir.join("out/f_0001.exr"))
        .unwrap()
        .modified()
        .unwrap();
    assert_eq!(before, after);
}

#[test]
fn the_same_frame_of_one_seed_has_the_same_noise_but_frames_do_not_share_it() {
    // One static volume, so only the seeds can differ between frames.
    let d = common::tempdir();
    let dir = d.path();
    ok(dir, &["generate", "cloud", "c.vdb", "--res", "16"]);
    std::fs::write(
        dir.join("s.toml"),
        "[render]\nwidth = 24\nheight = 18\nspp = 1\nintegrator = \"path\"\noutput = \"o_####.exr\"\n\
         [camera]\nframing = \"auto\"\n[[light]]\ntype = \"sun\"\ndirection = [0, -1, 1]\nirradiance = 1\n\
         [[volume]]\nfile = \"c.vdb\"\n[volume.material]\ndensity = 4\n",
    )
    .unwrap();
    ok(dir, &["render", "s.toml", "--frames", "7-8", "-q"]);
    let (a, b) = (
        pixels(&dir.join("o_0007.exr")),
        pixels(&dir.join("o_0008.exr")),
    );
    assert_ne!(a, b, "frames 7 and 8 share their noise");
    ok(
        dir,
        &["render", "s.toml", "--frame", "7", "-o", "again.exr", "-q"],
    );
    assert_eq!(pixels(&dir.join("again.exr")), a);
}

#[test]
fn sequence_mistakes_are_refused_before_anything_renders() {
    let d = common::tempdir();
    let dir = d.path();
    sequence(dir, &[1, 2]);
    scene(dir, "path", "");
    // A pattern and no frames.
    let r = run(dir, &["render", "seq.toml", "-q"]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("--frame"), "{}", r.stderr);
    // No file for any of the frames: one message with the frames that exist.
    let r = run(dir, &["render", "seq.toml", "--frames", "10-12", "-q"]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("no file for frames 10-12")
            && r.stderr.contains("its files are frames 1-2"),
        "{}",
        r.stderr
    );
    // Several frames into one file.
    let r = run(
        dir,
        &[
            "render", "seq.toml", "--frames", "1-2", "-o", "one.exr", "-q",
        ],
    );
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("overwrite each other"), "{}", r.stderr);
    // A pattern that is not one, and frame lists that are not lists.
    let r = run(
        dir,
        &[
            "render",
            "seq.toml",
            "--frame",
            "1",
            "-o",
            "f_{frame:x}.exr",
            "-q",
        ],
    );
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("not a frame pattern"), "{}", r.stderr);
    for bad in ["4-1", "1-x", "", "1-10000000"] {
        let r = run(dir, &["render", "seq.toml", "--frames", bad, "-q"]);
        assert_ne!(r.code, 0, "{bad}");
        assert!(r.stderr.contains("frame"), "{bad}: {}", r.stderr);
    }
    assert!(common::dir_entries(dir).iter().all(|n| n != "out"));
}

#[test]
fn sequence_bounds_keep_an_automatic_camera_fixed_over_the_frames() {
    use vdbphoton::scene::{SceneDesc, VolumeBounds};
    use vdbphoton::world::World;
    // Frames 1 and 2 are clouds of other shapes: framed by each frame's
    // own voxels the camera moves; framed by the sequence's box it stays.
    let d = common::tempdir();
    let dir = d.path();
    sequence(dir, &[1, 2]);
    ok(
        dir,
        &[
            "generate",
            "cloud",
            "f_0002.vdb",
            "--res",
            "16",
            "--seed",
            "77",
        ],
    );
    let p = scene(dir, "path", "");
    let desc = SceneDesc::load(&p).unwrap();
    let camera = |desc: &SceneDesc, frame| {
        let d = vdbphoton::frames::scene_at(desc, Some(frame), None).unwrap();
        World::load(&d).unwrap().camera.position()
    };
    let pattern = vdbphoton::sequence::PathPattern::new(&desc.volumes[0].file).unwrap();
    let b = vdbphoton::world::sequence_file_box(&pattern, "density").unwrap();
    let mut fixed = desc.clone();
    fixed.volumes[0].bounds = VolumeBounds::Box(b);
    assert_eq!(camera(&fixed, 1), camera(&fixed, 2));
    let mut active = desc.clone();
    active.volumes[0].bounds = VolumeBounds::Active;
    assert_ne!(camera(&active, 1), camera(&active, 2));
}

#[test]
fn frame_offset_shifts_the_frames_a_volume_reads() {
    // Film frames 1001-1002 read cache frames 1-2 (Blender's Start Frame
    // and Offset).
    let d = common::tempdir();
    let dir = d.path();
    sequence(dir, &[1, 2]);
    let p = scene(dir, "path", "");
    let text = std::fs::read_to_string(&p).unwrap().replace(
        "bounds = \"sequence\"",
        "bounds = \"sequence\"\nframe_offset = -1000",
    );
    std::fs::write(&p, text).unwrap();
    let r = ok(dir, &["render", "seq.toml", "--frames", "1001-1002", "-q"]);
    assert_eq!(saved(&r.stdout).len(), 2, "{}", r.stdout);
    assert!(dir.join("out/f_1001.exr").is_file() && dir.join("out/f_1002.exr").is_file());
    // Frame 999 would read frame -1.
    let r = run(dir, &["render", "seq.toml", "--frame", "999", "-q"]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("frame_offset"), "{}", r.stderr);
}

#[test]
fn temperature_from_flame_is_blenders_domain_temperature() {
    // The generated plume's `temperature` grid is Blender's domain
    // temperature made from its `flame` grid with ignition 1.5 and maximum
    // 3 (`generate.rs`): making it from the flame grid gives the same
    // image.
    let d = common::tempdir();
    let dir = d.path();
    ok(dir, &["generate", "plume", "p.vdb", "--res", "24"]);
    let scene = |name: &str, grid: &str| {
        std::fs::write(
            dir.join(name),
            format!(
                "[render]\nwidth = 24\nheight = 32\nspp = 2\nintegrator = \"path\"\n\
                 [camera]\nframing = \"auto\"\n\
                 [[volume]]\nfile = \"p.vdb\"\ntemperature_grid = \"{grid}\"\n{}",
                if grid == "flame" {
                    "temperature_from_flame = [1.5, 3.0]\n"
                } else {
                    ""
                }
            ),
        )
        .unwrap();
    };
    scene("t.toml", "temperature");
    scene("f.toml", "flame");
    ok(dir, &["render", "t.toml", "-o", "t.exr", "-q"]);
    ok(dir, &["render", "f.toml", "-o", "f.exr", "-q"]);
    let (a, b) = (pixels(&dir.join("t.exr")), pixels(&dir.join("f.exr")));
    let mean: f32 = a.iter().map(|p| p.x).sum::<f32>() / a.len() as f32;
    assert!(mean > 1e-3, "the fire does not glow: {mean}");
    for (x, y) in a.iter().zip(&b) {
        assert!(
            (*x - *y).abs().max_element() <= 1e-5 * (1.0 + x.abs().max_element()),
            "{x} {y}"
        );
    }
    // Without a temperature grid to make it from, the key is refused.
    std::fs::write(
        dir.join("n.toml"),
        "[[volume]]\nfile = \"p.vdb\"\ntemperature_from_flame = [1.5, 3.0]\n",
    )
    .unwrap();
    let r = run(dir, &["render", "n.toml", "-q"]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("needs temperature_grid"), "{}", r.stderr);
}

#[test]
fn a_damaged_frame_fails_alone() {
    let d = common::tempdir();
    let dir = d.path();
    sequence(dir, &[1, 2, 3]);
    let bytes = std::fs::read(dir.join("f_0002.vdb")).unwrap();
    std::fs::write(dir.join("f_0002.vdb"), &bytes[..bytes.len() / 2]).unwrap();
    scene(dir, "path", "");
    let r = run(dir, &["render", "seq.toml", "--frames", "1-3", "-q"]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("frame 2") && r.stderr.contains("f_0002.vdb"),
        "{}",
        r.stderr
    );
    assert!(dir.join("out/f_0001.exr").is_file() && dir.join("out/f_0003.exr").is_file());
    assert!(!dir.join("out/f_0002.exr").exists());
}

/// Renders the four tiles of frame 1 and the whole frame; returns the
/// tile paths.
fn tiles(dir: &Path, integrator: &str) -> Vec<String> {
    sequence(dir, &[1]);
    scene(dir, integrator, "aovs = true");
    ok(
        dir,
        &["render", "seq.toml", "--frame", "1", "-o", "full.exr", "-q"],
    );
    for i in 0..4 {
        ok(
            dir,
            &[
                "render",
                "seq.toml",
                "--frame",
                "1",
                "--tile",
                &format!("{i}/4"),
                "-o",
                "tile_{tile}.exr",
                "-q",
            ],
        );
    }
    (0..4).map(|i| format!("tile_{i}.exr")).collect()
}

#[test]
fn tiles_are_the_pixels_of_the_whole_frame_and_merge_into_it() {
    for integrator in ["path", "photon"] {
        let d = common::tempdir();
        let dir = d.path();
        let t = tiles(dir, integrator);
        // Each tile's data window sits in the whole frame's display window.
        let (tile0, attrs) = read_exr(dir.join(&t[0])).unwrap();
        assert_eq!(tile0.display_size(), (40, 30));
        assert_eq!(tile0.origin(), (0, 0));
        assert_eq!((tile0.width(), tile0.height()), (20, 15));
        assert!(attrs
            .iter()
            .any(|(k, v)| k == "vdbphoton/tile" && v == "0/4"));
        let (tile3, _) = read_exr(dir.join(&t[3])).unwrap();
        assert_eq!(tile3.origin(), (20, 15));
        let (full, _) = read_exr(dir.join("full.exr")).unwrap();
        for y in 0..15 {
            for x in 0..20 {
                assert_eq!(tile3.get(x, y), full.get(x + 20, y + 15), "{integrator}");
            }
        }
        // Merged in any order: the same bits as the whole frame, AOVs too.
        let mut args = vec!["merge", "m.exr", &t[2], &t[0], &t[3], &t[1]];
        args.extend(["--preview", "m.png"]);
        let r = ok(dir, &args);
        assert_eq!(saved(&r.stdout), ["m.exr", "m.png"]);
        let (m, _) = read_exr(dir.join("m.exr")).unwrap();
        assert_eq!(m.pixels(), full.pixels(), "{integrator}");
        assert_eq!(m.layers(), full.layers(), "{integrator}");
    }
}

/// Tiles whose integrators `auto` chose (their headers say why) merge
/// even when the jobs chose differently: both integrators estimate the same
/// image, and the merged header names both. Tiles of integrators named
/// explicitly must agree.
#[test]
fn tiles_of_integrators_auto_chose_differently_merge() {
    let d = common::tempdir();
    let dir = d.path();
    let t = tiles(dir, "path");
    ok(
        dir,
        &[
            "render",
            "seq.toml",
            "--frame",
            "1",
            "--tile",
            "3/4",
            "--integrator",
            "photon",
            "-o",
            "p3.exr",
            "-q",
        ],
    );
    // Tiles of one scene whose integrator is "auto" (one scene hash); the
    // photon tile was rendered with another integrator named, so its hash
    // is set to the others'.
    let edit = |f: &str, auto: bool, hash: &str| {
        let (image, mut attrs) = read_exr(dir.join(f)).unwrap();
        for (k, v) in attrs.iter_mut() {
            if k == "vdbphoton/scene_hash" {
                *v = hash.to_string();
            }
        }
        if auto {
            attrs.push(("vdbphoton/auto".into(), "measured on pilots".into()));
        }
        write_exr(dir.join(f), &image, &attrs).unwrap();
    };
    let scene_hash = read_exr(dir.join(&t[0]))
        .unwrap()
        .1
        .into_iter()
        .find(|(k, _)| k == "vdbphoton/scene_hash")
        .unwrap()
        .1;
    edit("p3.exr", false, &scene_hash);
    // Integrators named explicitly must agree.
    let r = run(dir, &["merge", "bad.exr", &t[0], &t[1], &t[2], "p3.exr"]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("vdbphoton/integrator"), "{}", r.stderr);
    assert!(!dir.join("bad.exr").exists());
    // As `auto` would have written them, saying why they chose.
    for f in [&t[0], &t[1], &t[2], &"p3.exr".to_string()] {
        edit(f, true, &scene_hash);
    }
    ok(dir, &["merge", "m.exr", &t[0], &t[1], &t[2], "p3.exr"]);
    let (m, attrs) = read_exr(dir.join("m.exr")).unwrap();
    let (p3, _) = read_exr(dir.join("p3.exr")).unwrap();
    for y in 0..15 {
        for x in 0..20 {
            assert_eq!(m.get(x + 20, y + 15), p3.get(x, y));
        }
    }
    assert!(
        attrs
            .iter()
            .any(|(k, v)| k == "vdbphoton/merged_integrators" && v.starts_with("path, photon")),
        "{attrs:?}"
    );
}

#[test]
fn merge_refuses_what_is_not_one_frame() {
    let d = common::tempdir();
    let dir = d.path();
    let t = tiles(dir, "path");
    let err = |args: &[&str]| {
        let r = run(dir, args);
        assert_eq!(r.code, 1, "{args:?}");
        assert!(!dir.join("bad.exr").exists(), "{args:?}: output written");
        r.stderr
    };
    // A missing tile is named with its region.
    let e = err(&["merge", "bad.exr", &t[0], &t[1], &t[3]]);
    assert!(e.contains("tile 2/4 (0,15,20,30) is missing"), "{e}");
    // The same tile twice.
    let e = err(&["merge", "bad.exr", &t[0], &t[1], &t[2], &t[3], &t[1]]);
    assert!(e.contains("overlaps"), "{e}");
    // A tile of another scene (another density) or other layers.
    let other = dir.join("other.toml");
    let text = std::fs::read_to_string(dir.join("seq.toml"))
        .unwrap()
        .replace("density = 8.0", "density = 9.0");
    std::fs::write(&other, text).unwrap();
    ok(
        dir,
        &[
            "render",
            "other.toml",
            "--frame",
            "1",
            "--tile",
            "3/4",
            "-o",
            "o3.exr",
            "-q",
        ],
    );
    let e = err(&["merge", "bad.exr", &t[0], &t[1], &t[2], "o3.exr"]);
    assert!(e.contains("scene_hash") && e.contains("o3.exr"), "{e}");
    // Tiles of different seeds: each seed's tiles must cover the frame on
    // their own (renders of other seeds are averaged, never mixed).
    ok(
        dir,
        &[
            "render", "seq.toml", "--frame", "1", "--tile", "3/4", "--seed", "99", "-o", "s3.exr",
            "-q",
        ],
    );
    let e = err(&["merge", "bad.exr", &t[0], &t[1], &t[2], "s3.exr"]);
    assert!(
        e.contains("no input of seed") && e.contains("covers pixels"),
        "{e}"
    );
    // An empty list, a file that is not an EXR.
    let r = run(dir, &["merge", "bad.exr"]);
    assert_ne!(r.code, 0);
    std::fs::write(dir.join("junk.exr"), b"not an exr").unwrap();
    let e = err(&["merge", "bad.exr", &t[0], "junk.exr"]);
    assert!(e.contains("junk.exr"), "{e}");
    // A region outside the image; a tile number out of range.
    for bad in [
        ["--region", "0,0,41,30"],
        ["--tile", "4/4"],
        ["--region", "5,5,5,9"],
    ] {
        let r = run(
            dir,
            &[
                "render", "seq.toml", "--frame", "1", bad[0], bad[1], "-o", "bad.exr", "-q",
            ],
        );
        assert_ne!(r.code, 0, "{bad:?}");
        assert!(!dir.join("bad.exr").exists());
    }
}

#[test]
fn merge_averages_renders_of_other_seeds_by_their_samples() {
    let d = common::tempdir();
    let dir = d.path();
    sequence(dir, &[1]);
    scene(dir, "path", "");
    let base = ["render", "seq.toml", "--frame", "1", "-q"];
    let mut a = base.to_vec();
    a.extend(["--seed", "1", "--spp", "1", "-o", "a.exr"]);
    ok(dir, &a);
    let mut b = base.to_vec();
    b.extend(["--seed", "2", "--spp", "3", "-o", "b.exr"]);
    ok(dir, &b);
    let r = ok(dir, &["merge", "ab.exr", "a.exr", "b.exr"]);
    assert!(r.stderr.contains("4 spp"), "{}", r.stderr);
    let (pa, pb, m) = (
        pixels(&dir.join("a.exr")),
        pixels(&dir.join("b.exr")),
        pixels(&dir.join("ab.exr")),
    );
    for i in 0..m.len() {
        let want = (pa[i] + 3.0 * pb[i]) / 4.0;
        assert!((m[i] - want).abs().max_element() <= 1e-6 * (1.0 + want.abs().max_element()));
    }
    let attrs = read_exr(dir.join("ab.exr")).unwrap().1;
    assert!(attrs.iter().any(|(k, v)| k == "vdbphoton/spp" && v == "4"));
}

#[test]
fn a_bare_vdb_renders_as_a_quick_look() {
    let d = common::tempdir();
    let dir = d.path();
    ok(dir, &["generate", "plume", "smoke.vdb", "--res", "24"]);
    // `view` and `render FILE.vdb` both: a PNG beside a framed image.
    let r = ok(
        dir,
        &["view", "smoke.vdb", "--width", "48", "--height", "36"],
    );
    assert_eq!(saved(&r.stdout), ["smoke.exr", "smoke.png"]);
    assert!(r.stderr.contains("temperature"), "{}", r.stderr);
    let img = read_exr_rgb(dir.join("smoke.exr")).unwrap();
    // The volume is in view: the centre differs from the sky in a corner.
    let (c, corner) = (img.get(24, 18), img.get(1, 1));
    assert!((c - corner).abs().max_element() > 1e-3, "{c} {corner}");
    let r = ok(
        dir,
        &[
            "render",
            "smoke.vdb",
            "-o",
            "q.exr",
            "--width",
            "32",
            "--height",
            "24",
            "-q",
        ],
    );
    assert_eq!(saved(&r.stdout), ["q.exr", "q.png"]);
    // Not a VDB despite its name: one line naming it.
    std::fs::write(dir.join("junk.vdb"), b"junk").unwrap();
    let r = run(dir, &["render", "junk.vdb"]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("junk.vdb") && r.stderr.lines().count() == 1,
        "{}",
        r.stderr
    );
}

#[test]
fn info_reads_several_files_and_shows_the_world_box() {
    let d = common::tempdir();
    let dir = d.path();
    ok(dir, &["generate", "cloud", "a.vdb", "--res", "16"]);
    ok(dir, &["generate", "plume", "b.vdb", "--res", "16"]);
    let r = ok(dir, &["info", "a.vdb", "b.vdb"]);
    assert!(r.stdout.contains("a.vdb:") && r.stdout.contains("b.vdb:"));
    // The cloud fills [-1, 1]^3 (voxel 2/16): its world box reaches there.
    assert_eq!(r.stdout.matches("  world box [").count(), 5, "{}", r.stdout);
    assert!(r.stdout.contains("memory when rendered"), "{}", r.stdout);
    let r = ok(dir, &["info", "a.vdb", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    let wb = &v["grids"][0]["world_bbox"];
    let lo = wb[0][0].as_f64().unwrap();
    let hi = wb[1][0].as_f64().unwrap();
    assert!(
        lo >= -1.0 - 1e-9 && hi <= 1.0 + 1e-9 && hi - lo > 0.5,
        "{wb}"
    );
    // One bad file among good ones: an error line for it, the rest shown,
    // exit 1.
    let r = run(dir, &["info", "a.vdb", "missing.vdb", "b.vdb"]);
    assert_eq!(r.code, 1);
    assert!(r.stdout.contains("b.vdb:") && r.stderr.contains("missing.vdb"));
}

#[test]
fn compare_writes_a_side_by_side_picture() {
    let d = common::tempdir();
    let dir = d.path();
    sequence(dir, &[1]);
    scene(dir, "path", "");
    ok(
        dir,
        &["render", "seq.toml", "--frame", "1", "-o", "a.exr", "-q"],
    );
    ok(
        dir,
        &[
            "render", "seq.toml", "--frame", "1", "-o", "b.exr", "--seed", "5", "-q",
        ],
    );
    let r = ok(
        dir,
        &["compare", "a.exr", "b.exr", "--side-by-side", "sbs.png"],
    );
    assert!(r.stdout.contains("relMSE"), "{}", r.stdout);
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(dir.join("sbs.png")).unwrap(),
    ));
    let reader = decoder.read_info().unwrap();
    let info = reader.info();
    // Three 40 x 30 panels with gaps, and lines of text under them.
    assert_eq!(info.width, 3 * 40 + 4 * 8);
    assert!(info.height > 30 + 3 * 9);
}

#[test]
fn new_users_get_one_clear_message_for_each_mistake() {
    let d = common::tempdir();
    let dir = d.path();
    ok(dir, &["generate", "cloud", "c.vdb", "--res", "16"]);
    std::fs::write(
        dir.join("s.toml"),
        "[render]\nwidth = 16\nheight = 12\nspp = 1\n[[volume]]\nfile = \"c.vdb\"\n",
    )
    .unwrap();
    // --spp: the same message for every bad value and spelling.
    for args in [
        &["--spp", "-4"][..],
        &["--spp=-4"],
        &["--spp", "0"],
        &["--spp", "x"],
    ] {
        let mut a = vec!["render", "s.toml"];
        a.extend(args);
        let r = run(dir, &a);
        assert_ne!(r.code, 0);
        assert!(
            r.stderr.contains("--spp") && r.stderr.contains("whole number"),
            "{args:?}: {}",
            r.stderr
        );
    }
    // Outputs whose names say another format.
    let r = run(dir, &["render", "s.toml", "-o", "t.png"]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains(".exr") && !dir.join("t.png").exists());
    let r = run(dir, &["render", "s.toml", "--preview", "p.exr"]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains(".png"), "{}", r.stderr);
    // A missing output folder is made, not a finished render lost.
    ok(dir, &["render", "s.toml", "-o", "new/deeper/o.exr", "-q"]);
    assert!(dir.join("new/deeper/o.exr").is_file());
    // --quiet keeps the one summary line a farm log wants.
    let r = ok(dir, &["render", "s.toml", "-o", "q.exr", "-q"]);
    assert_eq!(r.stderr.lines().count(), 1, "{}", r.stderr);
    assert!(r.stderr.starts_with("rendered 16 x 12"), "{}", r.stderr);
    // A huge image says what it will take before it starts (here it is
    // then refused by the memory limit, at once).
    let r = run(
        dir,
        &[
            "render",
            "s.toml",
            "--width",
            "65536",
            "--height",
            "2048",
            "--max-memory",
            "1G",
            "-o",
            "h.exr",
        ],
    );
    assert_eq!(r.code, 1);
    assert!(
        r.stderr
            .contains("a large image: 65536 x 2048 pixels (134 M)")
            && r.stderr.contains("needs about"),
        "{}",
        r.stderr
    );
    assert!(!dir.join("h.exr").exists());
    // A misspelt table.
    std::fs::write(
        dir.join("l.toml"),
        "[[lights]]\ntype = \"sun\"\n[[volume]]\nfile = \"c.vdb\"\n",
    )
    .unwrap();
    let r = run(dir, &["render", "l.toml"]);
    assert!(
        r.stderr.contains("unknown table [[lights]]")
            && r.stderr.contains("did you mean [[light]]"),
        "{}",
        r.stderr
    );
    // A grid named for nothing: a warning says why it has no effect. A
    // volume naming fire grids gets Blender's Quick Smoke fire material.
    ok(dir, &["generate", "plume", "p.vdb", "--res", "16"]);
    std::fs::write(
        dir.join("f.toml"),
        "[render]\nwidth = 8\nheight = 8\nspp = 1\n[[volume]]\nfile = \"p.vdb\"\nflame_grid = \"flame\"\n",
    )
    .unwrap();
    let r = ok(dir, &["render", "f.toml", "-o", "f.exr", "-q"]);
    assert!(
        r.stderr.contains("flame_grid 'flame' has no effect"),
        "{}",
        r.stderr
    );
    let scene = vdbphoton::scene::SceneDesc::load(dir.join("f.toml")).unwrap();
    assert_eq!(
        scene.volumes[0].material,
        vdbphoton::scene::MaterialDesc::Principled(vdbphoton::scene::Principled::QUICK_SMOKE_FIRE)
    );
    // A volume's error names the scene and which [[volume]].
    std::fs::write(
        dir.join("g.toml"),
        "[render]\nwidth = 8\nheight = 8\n[[volume]]\nfile = \"c.vdb\"\n[[volume]]\nfile = \"c.vdb\"\ndensity_grid = \"smoke\"\n",
    )
    .unwrap();
    let r = run(dir, &["render", "g.toml"]);
    assert_eq!(r.code, 1);
    let line = r.stderr.trim();
    assert!(
        line.contains("g.toml")
            && line.contains("[[volume]] 2")
            && line.contains("smoke")
            && line.contains("density"),
        "{line}"
    );
    assert_eq!(line.lines().count(), 1);
}

/// The progress (and its ETA) counts tiles done; tiles come in a shuffled
/// order, so a tenth of them is about a tenth of the work even when the
/// top rows are empty sky (the default scene's ETA at 10 % was off 10x
/// with rows in order).
#[test]
fn tiles_are_spread_over_the_image_in_render_order() {
    use vdbphoton::film::Region;
    let (w, h) = (320u32, 240u32);
    let order = vdbphoton::render::passes::tiles(Region::full(w, h));
    assert_eq!(order.len(), 20 * 15);
    let tenth = &order[..order.len() / 10];
    // The first tenth reaches every quarter of the image's height, and its
    // mean row is near the middle.
    for q in 0..4 {
        let (lo, hi) = (q * h / 4, (q + 1) * h / 4);
        assert!(
            tenth.iter().any(|t| t.y0 >= lo && t.y0 < hi),
            "no early tile in rows {lo}..{hi}"
        );
    }
    let mean_y = tenth.iter().map(|t| t.y0 as f64 + 8.0).sum::<f64>() / tenth.len() as f64;
    assert!(
        (mean_y - h as f64 / 2.0).abs() < h as f64 * 0.15,
        "{mean_y}"
    );
    // Every pixel once.
    let pixels: usize = order.iter().map(|t| t.pixels()).sum();
    assert_eq!(pixels, (w * h) as usize);
}
