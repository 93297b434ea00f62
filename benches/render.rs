//! Render benchmark on the shared reference scene (`cloud96_sun.toml`, from
//! `VDBPHOTON_REAL_DATA`, default `../shared/data`): prints figures, asserts
//! nothing. Run with `cargo bench --bench render` (`BENCH_SPP` to change
//! the samples per pixel, default 64).
//!
//! Reports, with the per-brick grid of majorants and minorants (the
//! default), with the same grid without its minorants, and with one global
//! majorant: samples per second (all threads), density lookups per second,
//! lookups and tentative collisions per sample and the fraction of tentative
//! collisions that are real (counted on one thread), and each image's error
//! against Mitsuba's ground truth. The target of issue 3 is 3x fewer lookups
//! than the global majorant.

use std::path::PathBuf;
use std::time::Instant;
use vdbphoton::image::{compare, read_exr_rgb, ImageRgb};
use vdbphoton::render::passes::{self, Settings};
use vdbphoton::scene::SceneDesc;
use vdbphoton::tracking;
use vdbphoton::world::World;

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let data = std::env::var_os("VDBPHOTON_REAL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/data"));
    let scene = data.join("reference/cloud96_sun.toml");
    if !scene.is_file() {
        println!("({} not found: nothing to benchmark)", scene.display());
        return;
    }
    let spp: u32 = std::env::var("BENCH_SPP")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(64);
    let desc = SceneDesc::load(&scene).unwrap();
    let truth = read_exr_rgb(data.join("reference/mitsuba_2048.exr")).unwrap();
    let r = &desc.render;
    let settings = Settings {
        width: r.width,
        height: r.height,
        spp,
        seed: 1,
        max_bounces: r.max_bounces,
    };
    let samples = (r.width * r.height * spp) as f64;
    println!(
        "reference scene {}x{}, {spp} spp, {} threads",
        r.width,
        r.height,
        rayon::current_num_threads()
    );
    for (label, cell, minorant) in [
        ("majorant grid (8^3 cells) with minorant", 8, true),
        ("majorant grid (4^3 cells) with minorant", 4, true),
        ("majorant grid (8^3 cells), majorant only", 8, false),
        ("global majorant", 1 << 20, false),
    ] {
        let mut world = World::load(&desc).unwrap();
        for v in world.media.volumes_mut() {
            v.set_majorant_cell(cell, minorant);
        }
        let t0 = Instant::now();
        let film = passes::render(&world, &settings, &|_, _| {});
        let secs = t0.elapsed().as_secs_f64();
        let img = ImageRgb {
            width: r.width as usize,
            height: r.height as usize,
            pixels: film.mean_rgb(),
        };
        let m = compare(&img, &truth).unwrap();
        // Counts on one thread over a quarter of the rows.
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let (counters, n) = one.install(|| {
            tracking::take_counters();
            let mut n = 0u64;
            for y in (0..r.height).step_by(4) {
                for x in 0..r.width {
                    passes::render_pixel(&world, &settings, x, y);
                    n += spp as u64;
                }
            }
            (tracking::take_counters(), n)
        });
        let lookups = counters.lookups;
        // The same share of the render's lookups per second.
        let lookups_per_sample = lookups as f64 / n as f64;
        println!("\n== {label}");
        println!(
            "  render {secs:.2} s: {:.0} samples/s, {:.1} M density lookups/s",
            samples / secs,
            samples * lookups_per_sample / secs / 1e6
        );
        println!(
            "  {lookups_per_sample:.2} lookups per sample (camera path, shadow rays and alpha), {:.2} tentative collisions; real collisions {:.1} % of tentative ones",
            counters.tentative as f64 / n as f64,
            100.0 * counters.real as f64 / counters.tentative as f64
        );
        println!(
            "  vs Mitsuba 2048 spp: mean ratio {:.5}, relMSE {:.3e}",
            m.mean_ratio, m.rel_mse
        );
    }
}
