//! Every integrator in `integrator::REGISTRY` goes through the whole
//! renderer by its registration alone: named in a scene, built, rendered to
//! an EXR whose header names it, listed by `vdbphoton integrators`,
//! accepted by `--integrator`, its header keys held equal by `merge`, and
//! its image right on two closed forms. A new integrator registered with
//! its one line is tested here without a line of its own.

mod common;

use glam::{DVec3, IVec3};
use std::path::Path;
use std::process::Command;
use vdbphoton::integrator::REGISTRY;
use vdbphoton::render::{load_scene, render_scene, RenderOptions, Silent};

const BIN: &str = env!("CARGO_BIN_EXE_vdbphoton");

/// A box of density 1 over [-1, 1]^3 in `dir/box.vdb`, and a scene that
/// looks at it down the z axis (2° field of view, so every ray crosses
/// 2.0006 units at most) against a uniform sky of radiance 1.
fn scene(dir: &Path, integrator: &str, material: &str) -> std::path::PathBuf {
    let g = common::const_box("density", 1.0, DVec3::splat(-1.0), 0.25, IVec3::splat(1));
    vdbphoton::vdb::write_vdb(dir.join("box.vdb"), &[vdbphoton::vdb::AnyGrid::Float(g)]).unwrap();
    let p = dir.join(format!("{integrator}.toml"));
    std::fs::write(
        &p,
        format!(
            "[render]\nwidth = 16\nheight = 16\nspp = 256\nintegrator = \"{integrator}\"\n\
             output = \"{integrator}.exr\"\n\
             [camera]\nposition = [0, 0, 10]\nlook_at = [0, 0, 0]\nup = [0, 1, 0]\nvfov = 2.0\n\
             [environment]\nradiance = 1.0\n\
             [[volume]]\nfile = \"box.vdb\"\n[volume.material]\n{material}\n"
        ),
    )
    .unwrap();
    p
}

/// Renders `scene` through the library, as the CLI does: the image's mean
/// over pixels and channels, and its header.
fn render(scene: &Path) -> (f64, Vec<(String, String)>) {
    let desc = load_scene(scene).unwrap_or_else(|e| panic!("{e}"));
    let opts = RenderOptions {
        threads: Some(2),
        ..Default::default()
    };
    let s = render_scene(&desc, &opts, &Silent).unwrap_or_else(|e| panic!("{e}"));
    let (_, attrs) = vdbphoton::image::read_exr(&s.outputs[0]).unwrap();
    let rgb = vdbphoton::image::read_exr_rgb(&s.outputs[0]).unwrap();
    let mean = rgb
        .pixels
        .iter()
        .map(|p| p.element_sum() as f64)
        .sum::<f64>()
        / (3.0 * rgb.pixels.len() as f64);
    (mean, attrs)
}

/// Absorption only (σa = 0.5, no scattering): every pixel sees the sky
/// through the box, e^(−0.5·2) = 0.3679, whatever the integrator.
/// A doubled or missing σt shows at once (0.135 or 0.607).
#[test]
fn every_integrator_renders_the_absorbing_box() {
    for reg in REGISTRY {
        let d = common::tempdir();
        let (mean, attrs) = render(&scene(d.path(), reg.name, "sigma_a = 0.5"));
        eprintln!("{}: absorbing box mean {mean:.5}", reg.name);
        let name = attrs
            .iter()
            .find(|(k, _)| k == "vdbphoton/integrator")
            .map(|(_, v)| v.as_str());
        assert_eq!(name, Some(reg.name));
        // 65,536 samples; a path's transmittance is 0 or 1 (relative
        // standard deviation of the mean 0.5 %).
        let want = (-1.0f64).exp();
        assert!(
            (mean / want - 1.0).abs() < 0.02,
            "{}: mean {mean}, closed form {want}",
            reg.name
        );
        for key in reg.header_keys {
            assert!(
                attrs.iter().any(|(k, _)| k == key),
                "{}: header key {key} missing",
                reg.name
            );
        }
    }
}

/// A white furnace: a scattering box (σs = 2, no absorption) under a
/// uniform sky of radiance 1 is radiance 1 everywhere, whatever the
/// scattering order. Losing light at any bounce (a missing σs, an
/// absorbed photon, a wrong kernel normalisation) shows as a darker box.
#[test]
fn every_integrator_keeps_the_white_furnace_white() {
    for reg in REGISTRY {
        let d = common::tempdir();
        let (mean, _) = render(&scene(d.path(), reg.name, "sigma_s = 2.0"));
        eprintln!("{}: white furnace mean {mean:.5}", reg.name);
        // The photon estimate's kernel straddles the box's faces (its
        // bias); the path tracer is exact up to noise.
        assert!(
            (mean - 1.0).abs() < 0.03,
            "{}: white furnace mean {mean}",
            reg.name
        );
    }
}

#[test]
fn every_integrator_is_on_the_command_line_and_in_merge() {
    let out = Command::new(BIN).arg("integrators").output().unwrap();
    assert!(out.status.success());
    let listing = String::from_utf8_lossy(&out.stdout);
    let keys = vdbphoton::merge::must_agree();
    for reg in REGISTRY {
        assert!(
            listing.lines().any(|l| l.starts_with(reg.name)),
            "{} not listed:\n{listing}",
            reg.name
        );
        for (key, _) in reg.keys {
            assert!(
                listing.contains(&format!("[render.{}] {key}:", reg.name)),
                "{}: key {key} not listed",
                reg.name
            );
        }
        for key in reg.header_keys {
            assert!(keys.contains(key), "merge does not hold {key} equal");
        }
        // `--integrator NAME` is accepted (and an unknown name refused in
        // one line that lists the names).
        let d = common::tempdir();
        let s = scene(d.path(), "auto", "sigma_a = 0.5");
        let out = Command::new(BIN)
            .args(["render", s.to_str().unwrap(), "--spp", "1", "-q"])
            .args(["--integrator", reg.name])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}: {}",
            reg.name,
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let d = common::tempdir();
    let s = scene(d.path(), "auto", "sigma_a = 0.5");
    let out = Command::new(BIN)
        .args(["render", s.to_str().unwrap(), "--integrator", "bdpt"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    for reg in REGISTRY {
        assert!(err.contains(reg.name), "{err}");
    }
}
