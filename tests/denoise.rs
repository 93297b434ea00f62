//! Denoising with Intel Open Image Denoise: the denoised image is closer to
//! a converged reference than the raw one, the raw render is kept bit for
//! bit, tiles are denoised when merged, and a missing library or too
//! little memory is one line before any work. The denoising albedo against
//! its closed form.
//!
//! The library comes from `bash scripts/install_oidn.sh` (setup.sh and CI
//! run it); where it is missing the tests that need it say so and pass.

mod common;

use common::unit_box_grid;
use glam::{DAffine3, Vec3, Vec4};
use std::path::Path;
use std::process::{Command, Output};
use vdbphoton::camera::Camera;
use vdbphoton::image::{read_exr, read_exr_rgb, Image};
use vdbphoton::integrator::guide;
use vdbphoton::integrator::photon::PhotonSettings;
use vdbphoton::integrator::{Integrator, PathIntegrator, PhotonIntegrator};
use vdbphoton::light::Environment;
use vdbphoton::medium::{ExtraGrids, Material, Media, Volume};
use vdbphoton::phase::PhaseFunction;
use vdbphoton::render::passes::camera_sample_guided;
use vdbphoton::world::World;
use vdbphoton::Rgb;

const BIN: &str = env!("CARGO_BIN_EXE_vdbphoton");
const SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cloud.toml");

fn run(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(BIN)
        .current_dir(dir)
        .args(args)
        .envs(env.iter().copied())
        .output()
        .unwrap()
}

fn ok(dir: &Path, args: &[&str]) -> Output {
    let out = run(dir, args, &[]);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Whether Open Image Denoise can be loaded here (else a note). Under CI
/// (`CI=true`, where `.ci/run` installs it) a missing library fails.
fn have_oidn() -> bool {
    match vdbphoton::denoise::Oidn::load(1) {
        Ok(_) => true,
        Err(e) if std::env::var("CI").is_ok_and(|v| v == "true") => {
            panic!("CI installs Open Image Denoise, but: {e}")
        }
        Err(e) => {
            eprintln!("skipped: {e}");
            false
        }
    }
}

/// A scratch folder, when Open Image Denoise is here ([`have_oidn`]).
fn oidn_tempdir() -> Option<tempfile::TempDir> {
    have_oidn().then(common::tempdir)
}

fn rel_mse(a: &Path, b: &Path) -> f64 {
    vdbphoton::image::compare(&read_exr_rgb(a).unwrap(), &read_exr_rgb(b).unwrap())
        .unwrap()
        .rel_mse
}

/// The `noisy` layer of a denoised image as RGBA pixels.
fn noisy(image: &Image) -> Vec<Vec4> {
    let l = image.layer("noisy").expect("a noisy layer");
    let k = ["R", "G", "B", "A"].map(|c| l.channel_index(c).expect("RGBA"));
    l.data()
        .chunks_exact(4)
        .map(|c| Vec4::new(c[k[0]], c[k[1]], c[k[2]], c[k[3]]))
        .collect()
}

#[test]
fn denoised_images_are_closer_to_the_reference_and_keep_the_raw_one() {
    let Some(d) = oidn_tempdir() else { return };
    let dir = d.path();
    let size = ["--width", "96", "--height", "72"];
    let mut args = vec![
        "render",
        SCENE,
        "-q",
        "--integrator",
        "path",
        "--spp",
        "1024",
    ];
    args.extend(["-o", "ref.exr", "--no-preview"]);
    args.extend(size);
    ok(dir, &args);
    for integrator in ["path", "photon"] {
        let base = |out: &'static str| {
            let mut a = vec![
                "render",
                SCENE,
                "-q",
                "--integrator",
                integrator,
                "--spp",
                "8",
            ];
            a.extend(["--seed", "3", "-o", out, "--no-preview"]);
            a.extend(size);
            a
        };
        ok(dir, &base("raw.exr"));
        let mut den = base("den.exr");
        den.push("--denoise");
        ok(dir, &den);
        let (raw, raw_attrs) = read_exr(dir.join("raw.exr")).unwrap();
        let (den, attrs) = read_exr(dir.join("den.exr")).unwrap();
        // The raw render, bit for bit, and the guide.
        assert_eq!(noisy(&den), raw.pixels(), "{integrator}");
        assert!(den.layer("albedo").is_some());
        assert!(
            raw.layer("albedo").is_none()
                && raw_attrs.iter().all(|(k, _)| k != "vdbphoton/denoiser")
        );
        let desc = attrs
            .iter()
            .find(|(k, _)| k == "vdbphoton/denoiser")
            .map(|(_, v)| v.clone())
            .unwrap_or_default();
        assert!(desc.starts_with("Intel Open Image Denoise 2."), "{desc}");
        // The photon integrator's denoised image is blended with its raw
        // one by the errors its halves show (`denoise::blend`); the path
        // tracer's is the denoiser's.
        let blended = integrator == "photon";
        assert_eq!(den.layer("half").is_some(), blended, "{integrator}");
        assert_eq!(desc.contains("blended"), blended, "{desc}");
        // Finite, the same mean, and much closer to the reference.
        assert!(den.pixels().iter().all(|p| p.is_finite()));
        let (m_raw, m_den) = (raw.mean_rgb().element_sum(), den.mean_rgb().element_sum());
        assert!(
            (m_den / m_raw - 1.0).abs() < 0.01,
            "{integrator}: denoising moved the mean from {m_raw} to {m_den}"
        );
        let (e_raw, e_den) = (
            rel_mse(&dir.join("raw.exr"), &dir.join("ref.exr")),
            rel_mse(&dir.join("den.exr"), &dir.join("ref.exr")),
        );
        eprintln!("{integrator}: relMSE raw {e_raw:.3e}, denoised {e_den:.3e}");
        // The path tracer's error at 8 spp is noise, which the denoiser
        // takes out (measured: 1.5e-2 to 8.6e-4); the photon integrator's
        // is mostly its photon map's blur, a bias the denoiser leaves
        // (2.87e-3 to 2.58e-3).
        let margin = if integrator == "path" { 0.25 } else { 0.95 };
        assert!(
            e_den < margin * e_raw,
            "{integrator}: denoised relMSE {e_den:.3e}, raw {e_raw:.3e}"
        );
    }
}

#[test]
fn tiles_are_denoised_when_merged_as_the_whole_frame_is() {
    // The photon integrator's too, whose tiles carry the `half` layer the
    // blend of the merged frame needs.
    for integrator in ["path", "photon"] {
        tiles_denoised_when_merged(integrator);
    }
}

fn tiles_denoised_when_merged(integrator: &str) {
    let Some(d) = oidn_tempdir() else { return };
    let dir = d.path();
    let base = [
        "render",
        SCENE,
        "-q",
        "--integrator",
        integrator,
        "--spp",
        "4",
        "--width",
        "64",
        "--height",
        "48",
        "--denoise",
        "--no-preview",
    ];
    let mut full = base.to_vec();
    full.extend(["-o", "full.exr"]);
    ok(dir, &full);
    for i in 0..4 {
        let tile = format!("{i}/4");
        let mut t = base.to_vec();
        t.extend(["--tile", &tile, "-o", "t_{tile}.exr"]);
        ok(dir, &t);
        // A tile is never denoised alone: raw, with its guide, and the
        // request for the merge.
        let (img, attrs) = read_exr(dir.join(format!("t_{i}.exr"))).unwrap();
        assert!(img.layer("noisy").is_none() && img.layer("albedo").is_some());
        assert_eq!(img.layer("half").is_some(), integrator == "photon");
        assert!(attrs
            .iter()
            .any(|(k, v)| k == "vdbphoton/denoise" && v == "at merge"));
    }
    // Every tile asked for denoising: merge does it without being told.
    ok(
        dir,
        &["merge", "m.exr", "t_0.exr", "t_1.exr", "t_2.exr", "t_3.exr"],
    );
    let (m, _) = read_exr(dir.join("m.exr")).unwrap();
    let (f, _) = read_exr(dir.join("full.exr")).unwrap();
    assert_eq!(noisy(&m), noisy(&f), "the merged raw frame");
    let worst = m
        .pixels()
        .iter()
        .zip(f.pixels())
        .map(|(a, b)| (*a - *b).abs().max_element())
        .fold(0.0f32, f32::max);
    assert!(
        worst < 1e-4,
        "merged and whole-frame denoising differ by {worst}"
    );
    // A denoised frame merged again starts from its raw pixels.
    ok(dir, &["merge", "again.exr", "full.exr", "--denoise"]);
    let (a, _) = read_exr(dir.join("again.exr")).unwrap();
    assert_eq!(noisy(&a), noisy(&f));
}

#[test]
fn denoising_without_the_library_or_the_memory_stops_before_any_work() {
    let d = common::tempdir();
    let dir = d.path();
    let missing = [("VDBPHOTON_OIDN", "/nonexistent/libOpenImageDenoise.so.2")];
    let out = run(
        dir,
        &["render", SCENE, "-o", "o.exr", "--spp", "1", "--denoise"],
        &missing,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("Open Image Denoise") && err.contains("scripts/setup.sh"));
    assert!(!dir.join("o.exr").exists());
    // Too little memory for the denoiser of a large frame: refused first.
    let out = run(
        dir,
        &[
            "render",
            SCENE,
            "-o",
            "o.exr",
            "--spp",
            "1",
            "--denoise",
            "--width",
            "4000",
            "--height",
            "3000",
            "--max-memory",
            "2G",
        ],
        &[],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("denoising") && err.contains("max-memory"),
        "{err}"
    );
    assert!(!dir.join("o.exr").exists());
    // merge --denoise without the library: nothing written, the inputs kept.
    ok(
        dir,
        &[
            "render", SCENE, "-o", "a.exr", "--spp", "1", "-q", "--width", "32", "--height", "24",
        ],
    );
    let out = run(dir, &["merge", "m.exr", "a.exr", "--denoise"], &missing);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(!dir.join("m.exr").exists() && dir.join("a.exr").exists());
}

/// A world of the box [-1, 1]^3 (128^3 voxels) of σs = `sigma_s`,
/// σa = `sigma_a`, before a constant sky, seen by a camera at `eye` looking
/// at its centre through a single pixel of a narrow field.
fn box_world(sigma_s: Rgb, sigma_a: f32, sky: f32, eye: Vec3) -> World {
    let v = Volume::new(
        "box",
        unit_box_grid(),
        ExtraGrids::default(),
        Material::Raw {
            sigma_a: Rgb::splat(sigma_a),
            sigma_s,
            emission: Rgb::ZERO,
            phase: PhaseFunction::Isotropic,
        },
        DAffine3::IDENTITY,
    )
    .unwrap();
    World {
        camera: Camera::new(eye, Vec3::ZERO, Vec3::Z, 0.01, 1, 1),
        lights: vec![],
        environment: Environment::Constant(Rgb::splat(sky)),
        media: Media::new(vec![v]),
        warnings: vec![],
        shapes: vdbphoton::shape::Shapes::empty(),
        surfaces: Vec::new(),
        film_transparent: false,
        load_seconds: 0.0,
    }
}

#[test]
fn the_denoising_albedo_is_the_scattering_seen_along_the_ray() {
    // The box of σs = (0.7, 0.35, 0), σa = 0.3 before a sky of radiance
    // 0.4 (and one of 3, which counts as 1): a camera ray through its
    // centre sees ∫ T σs = σs/σt (1 − e^{−2σt}) and the sky behind through
    // T = e^{−2σt}, per channel. The guide is the camera ray's, whichever
    // the integrator, and only the first GUIDE_SAMPLES samples carry it.
    for (sky, seen) in [(0.4f32, 0.4f32), (3.0, 1.0)] {
        let sigma_s = Rgb::new(0.7, 0.35, 0.0);
        let world = box_world(sigma_s, 0.3, sky, Vec3::new(0.0, -6.0, 0.0));
        let sigma_t = sigma_s + Rgb::splat(0.3);
        let t = (-2.0 * sigma_t).map(f32::exp);
        let want = sigma_s / sigma_t * (Rgb::ONE - t) + seen * t;
        let mut path = PathIntegrator::new(8);
        let mut photon = PhotonIntegrator::new(&world, PhotonSettings::default(), 8, 1).unwrap();
        let step = Some(guide::step(&world));
        for (name, integ) in [
            ("path", &mut path as &mut dyn Integrator),
            ("photon", &mut photon as &mut dyn Integrator),
        ] {
            let n = guide::GUIDE_SAMPLES;
            let mut sum = Rgb::ZERO;
            for s in 0..n {
                integ.begin_pass(&world, s as u32);
                let r = camera_sample_guided(&world, integ, 5, (0, 0), s, step);
                sum += r.albedo.expect("a guided sample");
            }
            let got = sum / n as f32;
            assert!(
                (got - want).abs().max_element() < 0.01,
                "{name}, sky {sky}: albedo {got}, expected {want}"
            );
            integ.begin_pass(&world, n as u32);
            let later = camera_sample_guided(&world, integ, 5, (0, 0), n, step);
            assert!(later.albedo.is_none(), "{name}: sample {n} carries a guide");
        }
    }
}

/// `--denoise-quality` (and `[render] denoise_quality`) reaches the
/// denoiser and its header; checkpoints are denoised at the fast quality,
/// the finished frame at the one asked for; a bad quality is one line.
#[test]
fn the_denoising_quality_is_the_one_asked_for() {
    let Some(d) = oidn_tempdir() else { return };
    let dir = d.path();
    let header = |f: &str| {
        let (_, attrs) = vdbphoton::image::read_exr(dir.join(f)).unwrap();
        attrs
            .into_iter()
            .find(|(k, _)| k == "vdbphoton/denoiser")
            .map(|(_, v)| v)
            .unwrap_or_default()
    };
    let base = [
        "render",
        SCENE,
        "-q",
        "--integrator",
        "path",
        "--spp",
        "2",
        "--width",
        "48",
        "--height",
        "36",
        "--no-preview",
        "--denoise",
    ];
    for (q, want) in [("fast", "quality fast"), ("high", "quality high")] {
        let out = format!("{q}.exr");
        let mut a = base.to_vec();
        a.extend(["--denoise-quality", q, "-o", &out]);
        ok(dir, &a);
        assert!(header(&out).contains(want), "{}", header(&out));
    }
    // The scene key, and a checkpoint written after every pass.
    let scene = std::fs::read_to_string(SCENE)
        .unwrap()
        .replace("[render]", "[render]\ndenoise_quality = \"balanced\"");
    let scene = scene.replace(
        "\"cloud.vdb\"",
        &format!("{:?}", Path::new(SCENE).with_file_name("cloud.vdb")),
    );
    std::fs::write(dir.join("q.toml"), scene).unwrap();
    let mut a = base.to_vec();
    a[1] = "q.toml";
    a.extend(["-o", "q.exr"]);
    ok(dir, &a);
    assert!(
        header("q.exr").contains("quality balanced"),
        "{}",
        header("q.exr")
    );
    // A checkpoint: kill the render after its first checkpoint lands.
    let mut child = Command::new(BIN)
        .current_dir(dir)
        .args([
            "render",
            SCENE,
            "-q",
            "--integrator",
            "path",
            "--spp",
            "100000",
        ])
        .args([
            "--width",
            "48",
            "--height",
            "36",
            "--no-preview",
            "--denoise",
        ])
        .args(["--checkpoint", "0.2s", "-o", "cp.exr"])
        .spawn()
        .unwrap();
    let t = std::time::Instant::now();
    while !dir.join("cp.exr").exists() && t.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    std::thread::sleep(std::time::Duration::from_millis(100));
    let _ = child.kill();
    let _ = child.wait();
    assert!(
        header("cp.exr").contains("quality fast"),
        "{}",
        header("cp.exr")
    );
    // `auto` takes the path tracer for a denoised image, and says why.
    ok(
        dir,
        &[
            "render",
            SCENE,
            "-q",
            "--spp",
            "1",
            "--width",
            "48",
            "--height",
            "36",
            "--no-preview",
            "--denoise",
            "--integrator",
            "auto",
            "-o",
            "auto.exr",
        ],
    );
    let (_, attrs) = vdbphoton::image::read_exr(dir.join("auto.exr")).unwrap();
    let get = |k: &str| attrs.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str());
    assert_eq!(get("vdbphoton/integrator"), Some("path"));
    assert!(
        get("vdbphoton/auto").is_some_and(|w| w.contains("denoised")),
        "{attrs:?}"
    );
    let out = run(dir, &["render", SCENE, "--denoise-quality", "best"], &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("high, balanced or fast"), "{err}");
}
