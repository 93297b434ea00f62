//! Our path tracer against Blender Cycles 5.0.1 on saved renders
//! (`tests/data/cycles`, made by `tools/blender/render_cycles.py`; the
//! commands are in that folder's README): the Blender smoke + fire frame 25
//! with the Quick Smoke material under a dim sun and sky, the same with the
//! fire only, and boxes of constant temperature (where interpolation cannot
//! matter, so the blackbody formula alone is compared), thin and with no
//! density at all.
//!
//! Means must agree within 1 % per channel; per pixel, the squared
//! differences must be what the two renders' noise explains (each noise
//! estimated from a pair of independent renders), at full resolution and
//! on 4x4 blocks, where a systematic error (a shifted voxel, a wrong
//! filter) stands out of the noise.
//!
//! Issue 49's shot with meshes (a shadow catcher ground and a holdout ball
//! by the smoke + fire frame, film transparent): our image composited over
//! Cycles' plate with our Shadow Catcher pass against Cycles' full render
//! (`smoke_shot_with_a_shadow_catcher_and_a_holdout_ball_against_cycles`).

mod common;

use std::path::{Path, PathBuf};
use vdbphoton::image::{read_exr_rgb, ImageRgb};
use vdbphoton::render::passes::{self, Settings};
use vdbphoton::scene::SceneDesc;
use vdbphoton::world::World;
use vdbphoton::Rgb;

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cycles")
}

/// Our render of `scene` (its volume files taken from `real` when given)
/// at `spp` with `seed`.
fn ours(scene: &str, real: Option<&Path>, spp: u32, seed: u64) -> ImageRgb {
    let mut desc = SceneDesc::load(data().join(scene)).unwrap();
    if let Some(real) = real {
        for v in &mut desc.volumes {
            let name = v.file.file_name().unwrap().to_owned();
            v.file = real.join("blender_smoke").join(name);
        }
    }
    let world = World::load(&desc).unwrap();
    let r = &desc.render;
    let film = passes::render(
        &world,
        &Settings {
            width: r.width,
            height: r.height,
            spp,
            seed,
            max_bounces: r.max_bounces,
        },
        &|_, _| {},
    );
    ImageRgb {
        width: r.width as usize,
        height: r.height as usize,
        pixels: film.mean_rgb(),
    }
}

fn average(a: &ImageRgb, b: &ImageRgb) -> ImageRgb {
    ImageRgb {
        pixels: a
            .pixels
            .iter()
            .zip(&b.pixels)
            .map(|(x, y)| (*x + *y) * 0.5)
            .collect(),
        ..a.clone()
    }
}

/// Per-pixel variance of the mean of two independent renders: (a − b)²/4.
fn variance_of_mean(a: &ImageRgb, b: &ImageRgb) -> Vec<Rgb> {
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(x, y)| (*x - *y) * (*x - *y) * 0.25)
        .collect()
}

/// `img` averaged over blocks of `s` x `s` pixels (and a variance image
/// over the same blocks: divided by s² more).
fn blocks(img: &[Rgb], w: usize, h: usize, s: usize, variance: bool) -> Vec<Rgb> {
    let mut out = Vec::new();
    for by in 0..h / s {
        for bx in 0..w / s {
            let mut acc = Rgb::ZERO;
            for y in 0..s {
                for x in 0..s {
                    acc += img[(by * s + y) * w + bx * s + x];
                }
            }
            let n = (s * s) as f32;
            out.push(if variance { acc / (n * n) } else { acc / n });
        }
    }
    out
}

/// Σ (a − c)² over Σ (var_a + var_c), per channel.
fn noise_ratio(a: &[Rgb], c: &[Rgb], var_a: &[Rgb], var_c: &[Rgb]) -> Rgb {
    let mut num = [0.0f64; 3];
    let mut den = [0.0f64; 3];
    for i in 0..a.len() {
        for k in 0..3 {
            let d = (a[i][k] - c[i][k]) as f64;
            num[k] += d * d;
            den[k] += (var_a[i][k] + var_c[i][k]) as f64;
        }
    }
    Rgb::new(
        (num[0] / den[0]) as f32,
        (num[1] / den[1]) as f32,
        (num[2] / den[2]) as f32,
    )
}

fn compare_smoke(scene: &str, real: &Path) {
    let stem = scene.trim_end_matches(".toml");
    let c1 = read_exr_rgb(data().join(format!("{stem}_cycles_seed1.exr"))).unwrap();
    let c2 = read_exr_rgb(data().join(format!("{stem}_cycles_seed2.exr"))).unwrap();
    let (o1, o2) = (
        ours(scene, Some(real), 128, 11),
        ours(scene, Some(real), 128, 12),
    );
    let (c, o) = (average(&c1, &c2), average(&o1, &o2));
    let ratio = o.mean_rgb() / c.mean_rgb();
    eprintln!(
        "{stem}: ours {} Cycles {} ratio {ratio}",
        o.mean_rgb(),
        c.mean_rgb()
    );
    for k in 0..3 {
        assert!(
            (ratio[k] - 1.0).abs() < 0.01,
            "{stem}: channel {k}: our mean / Cycles' = {}",
            ratio[k]
        );
    }
    let (vc, vo) = (variance_of_mean(&c1, &c2), variance_of_mean(&o1, &o2));
    let full = noise_ratio(&o.pixels, &c.pixels, &vo, &vc);
    let (w, h) = (c.width, c.height);
    let block = noise_ratio(
        &blocks(&o.pixels, w, h, 4, false),
        &blocks(&c.pixels, w, h, 4, false),
        &blocks(&vo, w, h, 4, true),
        &blocks(&vc, w, h, 4, true),
    );
    eprintln!("{stem}: squared differences / noise: pixels {full}, 4x4 blocks {block}");
    for k in 0..3 {
        assert!(
            full[k] < 1.25 && block[k] < 1.5,
            "{stem}: channel {k}: the difference is more than noise (pixels {}, blocks {})",
            full[k],
            block[k]
        );
    }
}

#[test]
fn blender_smoke_and_fire_frame_25_against_cycles() {
    let Some(real) = common::real_data() else {
        return;
    };
    compare_smoke("smoke25_fire.toml", &real);
    compare_smoke("smoke25_sun.toml", &real);
}

#[test]
fn constant_temperature_boxes_against_cycles() {
    // 800 K (where the fit's green and blue are negative) to 6500 K, thin
    // and with no density at all (fire only).
    for name in [
        "box_fire_T0800",
        "box_fire_T1500",
        "box_fire_T3000",
        "box_fire_T6500",
        "box_nodens_T1500",
        "box_thin_T1500",
        "box_thin_T6500",
    ] {
        let c = read_exr_rgb(data().join(format!("{name}_cycles.exr"))).unwrap();
        let o = ours(&format!("{name}.toml"), None, 256, 3);
        let (mo, mc) = (o.mean(), c.mean());
        eprintln!("{name}: ours {mo} Cycles {mc} ratio {}", mo / mc);
        assert!(
            (mo / mc - 1.0).abs() < 0.01,
            "{name}: image mean {mo} against Cycles' {mc}"
        );
    }
}

/// Our render of `scene` with the integrator it names (`choice`), `spp`
/// passes, `seed` (its volume files from `real` when given).
fn ours_with(scene: &str, real: Option<&Path>, choice: &str, spp: u32, seed: u64) -> ImageRgb {
    use vdbphoton::film::{Film, Region};
    use vdbphoton::render::{make_integrator, run_passes, Silent, Stop};
    let mut desc = SceneDesc::load(data().join(scene)).unwrap();
    if let Some(real) = real {
        for v in &mut desc.volumes {
            let name = v.file.file_name().unwrap().to_owned();
            v.file = real.join("blender_smoke").join(name);
        }
    }
    desc.render.integrator = choice.to_string();
    desc.render.seed = seed;
    let world = World::load(&desc).unwrap();
    let r = &desc.render;
    let mut integrator = make_integrator(&desc, &world).unwrap();
    let mut film = Film::new(r.width, r.height, Region::full(r.width, r.height), false);
    run_passes(
        &world,
        integrator.as_mut(),
        &mut film,
        seed,
        Stop::Passes(spp),
        &Silent,
        |_, _, _| Ok(()),
    )
    .unwrap();
    ImageRgb {
        width: r.width as usize,
        height: r.height as usize,
        pixels: film.mean_rgb(),
    }
}

fn rel_mse(a: &ImageRgb, reference: &ImageRgb) -> f64 {
    vdbphoton::image::compare(a, reference).unwrap().rel_mse
}

#[test]
fn blender_smoke_frame_25_with_motion_blur_against_cycles() {
    // Blender's defaults (shutter 0.5 frames, centred, 24 fps), the cache's
    // velocity grid read as a Volume object reads it. Cycles: two renders
    // of 256 spp (render_cycles.py, ray-marching integrator).
    let Some(real) = common::real_data() else {
        return;
    };
    let c1 = read_exr_rgb(data().join("smoke25_sun_mb_cycles_seed1.exr")).unwrap();
    let c2 = read_exr_rgb(data().join("smoke25_sun_mb_cycles_seed2.exr")).unwrap();
    let c = average(&c1, &c2);
    // Cycles' own error at 256 spp: E relMSE(c2, c1) = 2 var.
    let own = rel_mse(&c2, &c1) / 2.0;
    // The blur is there: the still frame is far from the blurred one.
    let still = read_exr_rgb(data().join("smoke25_sun_cycles_seed1.exr")).unwrap();
    assert!(rel_mse(&still, &c1) > 3.0 * rel_mse(&c2, &c1));
    let mut found = vec![];
    for choice in ["path", "photon"] {
        let o = ours_with("smoke25_sun_mb.toml", Some(&real), choice, 256, 11);
        let ratio = o.mean() / c.mean();
        // E relMSE(o, c1) = var_o + bias² + var_c: ours' own error is the
        // excess over Cycles'.
        let err = rel_mse(&o, &c1);
        let excess = (err - own) / own;
        eprintln!(
            "smoke25_sun_mb, {choice}: mean ratio {ratio:.5}, relMSE against Cycles {err:.3e} \
             (Cycles' own at 256 spp {own:.3e}: ours {excess:.2}x)"
        );
        found.push((choice, ratio, excess));
    }
    for (choice, ratio, excess) in found {
        assert!((ratio - 1.0).abs() < 0.02, "{choice}: mean ratio {ratio}");
        // Issue 30 asks for twice Cycles' own error at 256 spp. Measured:
        // path 1.13x (2.40x before the camera ray's emission was estimated
        // along the whole ray, tracking::transmittance_emission), photon
        // 0.31x (0.52x before the time slabs of the majorant grid).
        let bar = 2.0;
        assert!(excess <= bar, "{choice}: relMSE {excess:.2}x Cycles' own");
    }
}

/// The intensity-weighted centroid (pixels) and the variances along the
/// image diagonal (1, −1)/√2 (right and up) and across it.
fn moments(img: &ImageRgb) -> (glam::DVec2, f64, f64) {
    let (mut w, mut c) = (0.0f64, glam::DVec2::ZERO);
    for y in 0..img.height {
        for x in 0..img.width {
            let v = img.pixels[y * img.width + x].element_sum() as f64;
            w += v;
            c += v * glam::DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
        }
    }
    c /= w;
    let (u, n) = (
        glam::DVec2::new(1.0, -1.0).normalize(),
        glam::DVec2::new(1.0, 1.0).normalize(),
    );
    let (mut vu, mut vn) = (0.0, 0.0);
    for y in 0..img.height {
        for x in 0..img.width {
            let v = img.pixels[y * img.width + x].element_sum() as f64;
            let d = glam::DVec2::new(x as f64 + 0.5, y as f64 + 0.5) - c;
            vu += v * d.dot(u).powi(2);
            vn += v * d.dot(n).powi(2);
        }
    }
    (c, vu / w, vn / w)
}

#[test]
fn a_box_moving_diagonally_smears_as_far_as_in_cycles() {
    // make_moving_box.py: a glowing cube 0.3 wide moving at (6, 0, 6) units
    // per second, seen from −Y at 143.0 px per unit. A box blur of length L
    // adds L²/12 to the variance along the motion and nothing across it
    // (the cube looks the same along both diagonals), so
    // L = √(12 (var_along − var_across)).
    let px = 120.0 / (2.0 * 6.0 * 4f64.to_radians().tan());
    for (scene, shutter, shift) in [
        // Centred shutter 0.5 at 24 fps: 0.125 units along x and z, no
        // shift of the centroid.
        ("moving_box_center", 0.5, 0.0),
        // Shutter 1 opening at the frame, velocity per frame 6/24: 0.25
        // units, the centroid half of it ahead (right and up).
        ("moving_box_start_frame", 1.0, 0.125),
    ] {
        let want_len = 6.0 * shutter / 24.0 * std::f64::consts::SQRT_2 * px;
        let want_c = glam::DVec2::new(80.0 + shift * px, 60.0 - shift * px);
        let cy = read_exr_rgb(data().join(format!("{scene}_cycles.exr"))).unwrap();
        let mut found = vec![];
        for (who, img) in [
            ("Cycles", cy.clone()),
            (
                "path",
                ours_with(&format!("{scene}.toml"), None, "path", 256, 5),
            ),
            (
                "photon",
                ours_with(&format!("{scene}.toml"), None, "photon", 256, 5),
            ),
        ] {
            let (c, along, across) = moments(&img);
            let len = (12.0 * (along - across)).max(0.0).sqrt();
            eprintln!(
                "{scene}: {who}: smear {len:.2} px (expected {want_len:.2}), centroid {c:.2} \
                 (expected {want_c:.2}), image mean {:.5}",
                img.mean()
            );
            found.push((who, len, c, img.mean()));
        }
        for (who, len, c, mean) in &found {
            assert!(
                (len - want_len).abs() < 1.0,
                "{scene}: {who}: smear {len:.2} px, expected {want_len:.2}"
            );
            assert!(
                (*c - want_c).length() < 0.5,
                "{scene}: {who}: centroid {c}, expected {want_c}"
            );
            let cm = found[0].3;
            assert!(
                (mean / cm - 1.0).abs() < 0.01,
                "{scene}: {who}: image mean {mean} against Cycles' {cm}"
            );
        }
    }
}

// ------------------------------------------- meshes: issue 49's shot

/// Every channel of an EXR by its full name (Blender's multilayer files:
/// `ViewLayer.Combined.R`; ours: `R`, `shadow_catcher.R`), top row first,
/// and the size.
fn exr_channels(path: &Path) -> (std::collections::BTreeMap<String, Vec<f32>>, usize, usize) {
    let img = exr::prelude::read_all_flat_layers_from_file(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut out = std::collections::BTreeMap::new();
    let (mut w, mut h) = (0, 0);
    for layer in &img.layer_data {
        (w, h) = (layer.size.width(), layer.size.height());
        for ch in &layer.channel_data.list {
            out.insert(
                ch.name.to_string(),
                ch.sample_data.values_as_f32().collect(),
            );
        }
    }
    (out, w, h)
}

/// The mean of R, G, B over `px` in the box `[x0, x1) x [y0, y1)` (y down),
/// or over the whole image.
fn box_mean(px: &[Rgb], w: usize, b: Option<[usize; 4]>) -> f64 {
    let h = px.len() / w;
    let [x0, y0, x1, y1] = b.unwrap_or([0, 0, w, h]);
    let mut s = 0.0f64;
    for y in y0..y1 {
        for x in x0..x1 {
            s += px[y * w + x].element_sum() as f64;
        }
    }
    s / (3 * (x1 - x0) * (y1 - y0)) as f64
}

/// Issue 49's shot (`tools/blender/test_export/build_mesh_shot.py`; commands
/// and figures in tests/data/cycles/README.md): the Blender smoke + fire
/// frame 25 over a ground plane, a ball in front of the plume's base, a sun
/// casting the plume's shadow on the ground. Cycles 5.0.1 rendered it whole
/// (`smoke25_shot_full_cycles.exr`, film opaque) and the geometry alone
/// (`smoke25_shot_plate_cycles.exr`, the smoke hidden). vdbphoton renders
/// our export of it (`smoke25_shot.toml`: the ground a shadow catcher, the
/// ball a holdout, film transparent; meshes in `smoke25_shot_meshes/`) with
/// each integrator at low cost; composited as an artist would,
/// `ours.rgb + (1 − ours.alpha) · plate.rgb · ours.shadow_catcher`, it must
/// match Cycles' full render: the image mean within 2 %, and within 3 % in
/// the plume's shadow on the ground (`SHADOW_BOX`) and where the ball
/// covers the smoke (`BALL_BOX`). The ground bounces no light into the
/// smoke in the shot (that is issue 50's), so nothing else differs. Cycles'
/// own shadow-catcher render of the shot (`smoke25_shot_catcher_cycles.exr`)
/// composited the same way is checked against the full render too (the
/// references agree with each other and with the formula).
#[test]
fn smoke_shot_with_a_shadow_catcher_and_a_holdout_ball_against_cycles() {
    // Pixel boxes [x0, y0, x1, y1), y down (README.md, "Meshes").
    const SHADOW_BOX: [usize; 4] = [54, 89, 78, 96];
    const BALL_BOX: [usize; 4] = [128, 80, 138, 94];
    let Some(real) = common::real_data() else {
        return;
    };
    let full = read_exr_rgb(data().join("smoke25_shot_full_cycles.exr")).unwrap();
    let plate = read_exr_rgb(data().join("smoke25_shot_plate_cycles.exr")).unwrap();
    let (w, h) = (full.width, full.height);
    assert_eq!((plate.width, plate.height), (w, h));

    let check = |who: &str, comp: &[Rgb]| -> Vec<(String, f64)> {
        let mut found = vec![];
        for (what, b) in [
            ("image", None),
            ("shadow box", Some(SHADOW_BOX)),
            ("ball box", Some(BALL_BOX)),
        ] {
            let (o, c) = (box_mean(comp, w, b), box_mean(&full.pixels, w, b));
            eprintln!(
                "smoke25_shot, {who}: {what}: composite {o:.6} Cycles {c:.6} ratio {:.5}",
                o / c
            );
            found.push((what.to_string(), o / c));
        }
        found
    };

    // Cycles' own shadow catcher, composited the same way.
    let (cy, cw, ch) = exr_channels(&data().join("smoke25_shot_catcher_cycles.exr"));
    assert_eq!((cw, ch), (w, h));
    let get = |m: &std::collections::BTreeMap<String, Vec<f32>>, k: &str| -> Vec<f32> {
        m.get(k)
            .unwrap_or_else(|| panic!("no channel {k} in {:?}", m.keys()))
            .clone()
    };
    let composite = |rgb: [Vec<f32>; 3], a: &[f32], sc: [Vec<f32>; 3]| -> Vec<Rgb> {
        (0..w * h)
            .map(|i| {
                let over = Rgb::new(rgb[0][i], rgb[1][i], rgb[2][i]);
                let catcher = Rgb::new(sc[0][i], sc[1][i], sc[2][i]);
                over + (1.0 - a[i]) * plate.pixels[i] * catcher
            })
            .collect()
    };
    let l = |p: &str, c: &str| format!("ViewLayer.{p}.{c}");
    let cycles_comp = composite(
        ["R", "G", "B"].map(|c| get(&cy, &l("Combined", c))),
        &get(&cy, &l("Combined", "A")),
        ["R", "G", "B"].map(|c| get(&cy, &l("Shadow Catcher", c))),
    );
    for (what, ratio) in check("Cycles' own shadow catcher", &cycles_comp) {
        assert!(
            (ratio - 1.0).abs() < 0.01,
            "the references disagree: Cycles' own composite, {what}: ratio {ratio}"
        );
    }

    // Ours: our export, its volume read from the real data and its meshes
    // from tests/data/cycles, rendered by the command line.
    let mut found = vec![];
    for (choice, spp) in [("path", 256), ("photon", 128)] {
        let (_tmp, exr) = render_cli("smoke25_shot", Some(&real), choice, spp);
        let (ours, ow, oh) = exr_channels(&exr);
        assert_eq!((ow, oh), (w, h));
        let comp = composite(
            ["R", "G", "B"].map(|c| get(&ours, c)),
            &get(&ours, "A"),
            ["R", "G", "B"].map(|c| get(&ours, &format!("shadow_catcher.{c}"))),
        );
        for (what, ratio) in check(choice, &comp) {
            found.push((choice, what, ratio));
        }
    }
    for (choice, what, ratio) in found {
        let tol = if what == "image" { 0.02 } else { 0.03 };
        assert!(
            (ratio - 1.0).abs() < tol,
            "{choice}: {what}: our composite / Cycles' full render = {ratio:.5} (tolerance \
             {tol})"
        );
    }
}

// ------------------------------------------- surfaces: issue 50's shots

/// Our render of one of the scenes of issue 49's and 50's shots
/// (`tests/data/cycles/NAME.toml`, its meshes beside it, its volumes from
/// `real`) by the command line with `integrator` at `spp`, seed 11, 2
/// threads: the EXR, in the folder returned with it.
fn render_cli(
    name: &str,
    real: Option<&Path>,
    integrator: &str,
    spp: u32,
) -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let mut scene: toml::Value =
        toml::from_str(&std::fs::read_to_string(data().join(format!("{name}.toml"))).unwrap())
            .unwrap();
    if let Some(vs) = scene.get_mut("volume").and_then(|v| v.as_array_mut()) {
        for v in vs {
            let file = Path::new(v["file"].as_str().unwrap()).file_name().unwrap();
            let real = real.expect("a scene with volumes needs the real data");
            v["file"] = toml::Value::String(
                real.join("blender_smoke")
                    .join(file)
                    .to_string_lossy()
                    .into_owned(),
            );
        }
    }
    // Every `file` of the meshes (their PLYs, their textures) made
    // absolute, since the scene is written elsewhere.
    fn absolute(v: &mut toml::Value) {
        match v {
            toml::Value::Table(t) => {
                for (k, v) in t.iter_mut() {
                    match v {
                        toml::Value::String(f) if k == "file" => {
                            *f = data().join(&*f).to_string_lossy().into_owned();
                        }
                        _ => absolute(v),
                    }
                }
            }
            toml::Value::Array(a) => a.iter_mut().for_each(absolute),
            _ => {}
        }
    }
    absolute(&mut scene["mesh"]);
    let toml_path = tmp.path().join(format!("{name}.toml"));
    std::fs::write(&toml_path, toml::to_string(&scene).unwrap()).unwrap();
    let exr = tmp.path().join("out.exr");
    let t = std::time::Instant::now();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_vdbphoton"))
        .arg("render")
        .arg(&toml_path)
        .arg("-o")
        .arg(&exr)
        .args(["--no-preview", "--quiet", "--threads", "2", "--seed", "11"])
        .args(["--integrator", integrator, "--spp", &spp.to_string()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "vdbphoton render {name} ({integrator}) failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!(
        "{name}, {integrator}: {spp} spp in {:.1} s",
        t.elapsed().as_secs_f64()
    );
    (tmp, exr)
}

/// [`render_cli`]'s image: its RGB, top row first.
fn ours_cli(name: &str, real: Option<&Path>, integrator: &str, spp: u32) -> ImageRgb {
    let (_tmp, exr) = render_cli(name, real, integrator, spp);
    read_exr_rgb(&exr).unwrap()
}

/// Issue 50's shots against Cycles 5.0.1 (`build_surface_shot.py`; commands,
/// boxes and Cycles' timings in tests/data/cycles/README.md, "Surfaces"):
/// the Blender smoke + fire frame 25 over a grey Principled ground with a
/// Principled ball, a sun and a sky, film opaque (`surface_smoke`); three
/// Principled spheres (rough dielectric, glossy dielectric, metal) under a
/// sun and a sky (`surface_spheres`); two diffuse quads with an sRGB and a
/// Non-Color image texture under a white sky (`surface_texture`). Each
/// render of each integrator against the mean of Cycles' two references
/// (4096 spp for the smoke, 16384 for the spheres, 1024 for the texture):
/// the image mean within 2 %, each box within 3 %. On the smoke shot the
/// relative MSE must also be no worse than Cycles' own at 256 spp (8.42e-5,
/// seed 3 against the same references, 11.9 s on this 2-core machine):
/// ours takes 8-16 s at these counts (the equal-time figures are in
/// docs/performance.md, "Surfaces"). What the boxes catch: the ground's
/// light into the smoke (`SMOKE`, 0.94 when photons aimed at the volumes
/// alone), the smoke's shadow on the ground (`SHADOW`), the fire on the
/// ground (`FIRE`, `FIRE_NEAR`), each sphere's BSDF.
#[test]
fn surface_shots_against_cycles() {
    type Boxes = &'static [(&'static str, [usize; 4])];
    type Shot = (&'static str, Boxes, [(&'static str, u32); 2], Option<f64>);
    let smoke: Boxes = &[
        ("SHADOW", [51, 89, 87, 99]),
        ("SMOKE", [110, 37, 150, 50]),
        ("FIRE", [98, 111, 113, 119]),
        ("FIRE_NEAR", [105, 97, 118, 101]),
    ];
    let spheres: Boxes = &[
        ("ROUGH", [19, 58, 53, 92]),
        ("GLOSSY", [83, 58, 117, 92]),
        ("METAL", [146, 58, 180, 92]),
    ];
    let texture: Boxes = &[
        ("sRGB quad", [0, 0, 64, 64]),
        ("Linear quad", [64, 0, 128, 64]),
    ];
    let real = common::real_data();
    let mut shots: Vec<Shot> = vec![
        (
            "surface_spheres",
            spheres,
            [("path", 256), ("photon", 256)],
            None,
        ),
        (
            "surface_texture",
            texture,
            [("path", 16), ("photon", 16)],
            None,
        ),
    ];
    if real.is_some() {
        shots.push((
            "surface_smoke",
            smoke,
            [("path", 320), ("photon", 256)],
            Some(8.42e-5),
        ));
    }
    for (name, boxes, runs, most_rel_mse) in shots {
        let a = read_exr_rgb(data().join(format!("{name}_cycles_seed1.exr"))).unwrap();
        let b = read_exr_rgb(data().join(format!("{name}_cycles_seed2.exr"))).unwrap();
        let cycles = average(&a, &b);
        let w = cycles.width;
        for (integrator, spp) in runs {
            let img = ours_cli(name, real.as_deref(), integrator, spp);
            assert_eq!((img.width, img.height), (cycles.width, cycles.height));
            let mut fails = vec![];
            let (o, c) = (
                box_mean(&img.pixels, w, None),
                box_mean(&cycles.pixels, w, None),
            );
            eprintln!(
                "{name}, {integrator}: image {o:.6} Cycles {c:.6} ratio {:.5}",
                o / c
            );
            if (o / c - 1.0).abs() > 0.02 {
                fails.push(format!("image mean ratio {:.4}", o / c));
            }
            for (what, bx) in boxes {
                let (o, c) = (
                    box_mean(&img.pixels, w, Some(*bx)),
                    box_mean(&cycles.pixels, w, Some(*bx)),
                );
                eprintln!(
                    "{name}, {integrator}: {what} {o:.6} Cycles {c:.6} ratio {:.5}",
                    o / c
                );
                if (o / c - 1.0).abs() > 0.03 {
                    fails.push(format!("{what} ratio {:.4}", o / c));
                }
            }
            let e = rel_mse(&img, &cycles);
            eprintln!("{name}, {integrator}: relative MSE {e:.3e}");
            if let Some(most) = most_rel_mse {
                if e > most {
                    fails.push(format!("relative MSE {e:.3e} above Cycles' {most:.3e}"));
                }
            }
            assert!(
                fails.is_empty(),
                "{name}, {integrator}: {}",
                fails.join(", ")
            );
        }
    }
}
