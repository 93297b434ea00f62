//! `vdbphoton render` from the command line: the bundled scenes render,
//! outputs and headers are right, and bad scenes fail cleanly without
//! leaving an output file.

mod common;

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_vdbphoton");
const SCENES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");

fn render(args: &[&str]) -> (i32, String) {
    let out = Command::new(BIN).arg("render").args(args).output().unwrap();
    let code = out.status.code().expect("killed by a signal");
    (code, String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn bundled_scenes_render() {
    let dir = common::tempdir();
    for name in ["cloud", "plume"] {
        let exr = dir.path().join(format!("{name}.exr"));
        let png = dir.path().join(format!("{name}.png"));
        let scene = format!("{SCENES}/{name}.toml");
        let (code, err) = render(&[
            &scene,
            "-o",
            exr.to_str().unwrap(),
            "--preview",
            png.to_str().unwrap(),
            "--spp",
            "4",
            "--width",
            "64",
            "--height",
            "48",
            "--aovs",
        ]);
        assert_eq!(code, 0, "{name}: {err}");
        assert!(
            err.contains("render") && err.contains("total"),
            "no timing summary: {err}"
        );
        let img = vdbphoton::image::read_exr_rgb(&exr).unwrap();
        assert_eq!((img.width, img.height), (64, 48));
        assert!(img.mean() > 0.0);
        // The header carries the settings; the AOV layers are there.
        let meta = exr::meta::MetaData::read_from_file(&exr, false).unwrap();
        let header = &meta.headers[0];
        let text = format!("{:?}", header.own_attributes.other);
        assert!(
            text.contains("vdbphoton/spp") && text.contains("vdbphoton/integrator"),
            "{text}"
        );
        let channels = common::channel_names(header);
        for c in [
            "A",
            "B",
            "G",
            "R",
            "direct.R",
            "emission.G",
            "indirect.B",
            "transmittance.Y",
        ] {
            assert!(
                channels.iter().any(|x| x == c),
                "{name}: no channel {c} in {channels:?}"
            );
        }
        let png_data = std::fs::read(&png).unwrap();
        assert_eq!(&png_data[1..4], b"PNG");
    }
}

#[test]
fn bad_scenes_fail_cleanly_without_output() {
    let dir = common::tempdir();
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let out = out_dir.join("x.exr");
    let cases: Vec<(&str, String, &str)> = vec![
        ("missing.toml", String::new(), "missing.toml"),
        ("typo.toml", format!("[render]\nwidht = 10\n[[volume]]\nfile = \"{SCENES}/cloud.vdb\"\n"), "widht"),
        ("novdb.toml", "[[volume]]\nfile = \"nothere.vdb\"\n".to_string(), "nothere.vdb"),
        ("grid.toml", format!("[[volume]]\nfile = \"{SCENES}/cloud.vdb\"\ndensity_grid = \"smoke\"\n"), "no grid named 'smoke'"),
        ("broken.toml", "[render\nwidth = 3".to_string(), "broken.toml"),
        ("badphase.toml", format!("[[volume]]\nfile = \"{SCENES}/cloud.vdb\"\n[volume.material]\nsigma_s = 1.0\nphase = {{ type = \"hg\", g = 3.0 }}\n"), "g"),
    ];
    for (name, text, needle) in cases {
        let scene = dir.path().join(name);
        if !text.is_empty() {
            std::fs::write(&scene, text).unwrap();
        }
        let (code, err) = render(&[
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--quiet",
        ]);
        assert_eq!(code, 1, "{name}: {err}");
        assert_eq!(err.lines().count(), 1, "{name}: {err}");
        assert!(err.contains(needle), "{name}: '{needle}' not in: {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
        assert!(
            common::dir_entries(&out_dir).is_empty(),
            "{name} left a file behind"
        );
    }
    // An output folder that cannot be made (its parent is a file): an
    // error naming the path before any work, and nothing written anywhere.
    let blocker = common::tempdir();
    let file = blocker.path().join("file");
    std::fs::write(&file, b"x").unwrap();
    let bad_out = file.join("dir/x.exr");
    let (code, err) = render(&[
        &format!("{SCENES}/cloud.toml"),
        "-o",
        bad_out.to_str().unwrap(),
        "--spp",
        "1",
        "--width",
        "8",
        "--height",
        "8",
        "--quiet",
    ]);
    assert_eq!(code, 1);
    assert!(err.contains(bad_out.to_str().unwrap()), "{err}");
    assert_eq!(
        common::dir_entries(blocker.path()),
        vec!["file".to_string()]
    );
    // --spp 0 is refused.
    let (code, err) = render(&[
        &format!("{SCENES}/cloud.toml"),
        "--spp",
        "0",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(common::dir_entries(&out_dir).is_empty());
    // An image too large to hold in memory is refused before anything is
    // allocated (65536 x 65536 would also overflow 32-bit pixel counts).
    let (code, err) = render(&[
        &format!("{SCENES}/cloud.toml"),
        "--width",
        "65536",
        "--height",
        "65536",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("4294967296 pixels"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(common::dir_entries(&out_dir).is_empty());
}

#[test]
fn environment_map_from_an_exr_file() {
    // A constant map of 0.5 at strength 2: rays that miss the cloud see 1.
    let dir = common::tempdir();
    let sky = dir.path().join("sky.exr");
    let img = vdbphoton::image::Image::filled(32, 16, glam::Vec4::new(0.5, 0.5, 0.5, 1.0));
    vdbphoton::image::write_exr(&sky, &img, &[]).unwrap();
    let scene = dir.path().join("scene.toml");
    std::fs::write(
        &scene,
        format!(
            "[render]\nwidth = 16\nheight = 12\nspp = 4\n[camera]\nposition = [0.0, -3.0, 0.0]\nvfov = 60.0\n\
             [environment]\nmap = \"sky.exr\"\nstrength = 2.0\n[[volume]]\nfile = \"{SCENES}/cloud.vdb\"\n"
        ),
    )
    .unwrap();
    let out = dir.path().join("x.exr");
    let (code, err) = render(&[
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(code, 0, "{err}");
    let img = vdbphoton::image::read_exr_rgb(&out).unwrap();
    assert_eq!(img.get(0, 0), glam::Vec3::splat(1.0));
    // A map that is not an EXR is an error naming it.
    std::fs::write(&sky, "not an image").unwrap();
    let (code, err) = render(&[
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("sky.exr"), "{err}");
}

#[test]
fn export_vol_writes_a_whole_file_or_nothing() {
    // `export-vol` (for Mitsuba comparisons): the header and size of the
    // dense file, the temporary name gone after success, and nothing left
    // behind when the output cannot be written.
    let dir = common::tempdir();
    let export = |to: &std::path::Path| {
        Command::new(BIN)
            .args(["export-vol", &format!("{SCENES}/cloud.vdb")])
            .arg(to)
            .output()
            .unwrap()
    };
    let vol = dir.path().join("c.vol");
    let out = export(&vol);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(&vol).unwrap();
    assert_eq!(&bytes[..4], b"VOL\x03");
    let int = |i: usize| i32::from_le_bytes(bytes[4 + 4 * i..8 + 4 * i].try_into().unwrap());
    assert_eq!((int(0), int(4)), (1, 1), "float32, one channel");
    let n = (int(1) * int(2) * int(3)) as usize;
    assert!(n > 1000);
    assert_eq!(bytes.len(), 48 + 4 * n);
    assert_eq!(common::dir_entries(dir.path()), ["c.vol"]);

    let out = export(&dir.path().join("no/such/dir/c.vol"));
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no/such/dir/c.vol"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
}
