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

mod common;

use std::path::{Path, PathBuf};
use vdbphoton::image::{read_exr_rgb, ImageRgb};
use vdbphoton::integrator::{self, Settings};
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
    let film = integrator::render(
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
