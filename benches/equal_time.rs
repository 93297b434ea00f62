//! Equal-time comparison of the photon integrator and the path tracer:
//! prints figures, asserts nothing. `cargo bench --bench equal_time`
//! (`BENCH_BUDGETS=10,30,120` seconds by default; `BENCH_SCENES=sun,dense`;
//! `BENCH_SEED`, 7 by default; `BENCH_INTEGRATORS=path,photon`;
//! `BENCH_PHOTONS`, `BENCH_K`, `BENCH_ALPHA`, `BENCH_ESTIMATE` override
//! the scene's photon settings).
//!
//! Both integrators render each scene for each wall-clock budget on all
//! threads (passes until the budget, as `vdbphoton render --time`), and
//! each image is compared with a ground truth: relative MSE
//! (mean((a − b)² / (b² + 0.01)), the shared reference's formula) and the
//! image-mean ratio.
//! - `sun`: `reference/cloud96_sun.toml` (from `VDBPHOTON_REAL_DATA`,
//!   default `../shared/data`) against Mitsuba's 2048-spp ground truth.
//! - `dense`: `reference/cloud96_dense.toml` against the mean of two
//!   path-traced halves of 2048 spp, `cloud96_dense_a.exr` and `_b.exr`
//!   in `BENCH_TRUTH` (default `target/ground_truth`); when they are
//!   missing the bench prints the commands that make them (about 20
//!   minutes each on two cores). The halves' relative MSE against each
//!   other is printed (the ground truth's own noise is about a quarter of
//!   it).

use std::path::PathBuf;
use std::time::{Duration, Instant};
use vdbphoton::film::{Film, Region};
use vdbphoton::image::{compare, read_exr_rgb, ImageRgb};
use vdbphoton::integrator::photon::{photons_for, PhotonSettings};
use vdbphoton::render::{make_integrator, run_passes, Silent, Stop};
use vdbphoton::scene::SceneDesc;
use vdbphoton::world::World;

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

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let data = std::env::var_os("VDBPHOTON_REAL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/data"));
    let truth_dir = std::env::var_os("BENCH_TRUTH")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("target/ground_truth"));
    let budgets: Vec<f64> = std::env::var("BENCH_BUDGETS")
        .unwrap_or_else(|_| "10,30,120".into())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let scenes = std::env::var("BENCH_SCENES").unwrap_or_else(|_| "sun,dense".into());
    println!("{} threads", rayon::current_num_threads());
    for scene in scenes.split(',') {
        let (file, truth) = match scene.trim() {
            "sun" => (
                data.join("reference/cloud96_sun.toml"),
                read_exr_rgb(data.join("reference/mitsuba_2048.exr")).ok(),
            ),
            "dense" => {
                let a = read_exr_rgb(truth_dir.join("cloud96_dense_a.exr"));
                let b = read_exr_rgb(truth_dir.join("cloud96_dense_b.exr"));
                let t = match (a, b) {
                    (Ok(a), Ok(b)) => {
                        let m = compare(&a, &b).unwrap();
                        println!(
                            "dense ground truth: halves' relMSE against each other {:.3e}, mean ratio {:.5}",
                            m.rel_mse, m.mean_ratio
                        );
                        Some(average(&a, &b))
                    }
                    _ => {
                        println!(
                            "(no dense ground truth in {}: make it with\n  vdbphoton render {}/reference/cloud96_dense.toml --integrator path --spp 2048 --seed 1001 -o {}/cloud96_dense_a.exr --no-preview\n  and the same with --seed 2002 -o .../cloud96_dense_b.exr)",
                            truth_dir.display(),
                            data.display(),
                            truth_dir.display()
                        );
                        None
                    }
                };
                (data.join("reference/cloud96_dense.toml"), t)
            }
            other => {
                println!("(unknown scene {other})");
                continue;
            }
        };
        let Some(truth) = truth else {
            continue;
        };
        let mut desc = SceneDesc::load(&file).unwrap();
        // Photon settings from the environment, into [render.photon].
        {
            use vdbphoton::scene::Param;
            let photon = desc.render.settings.entry("photon".into()).or_default();
            for (var, key) in [("BENCH_PHOTONS", "photons"), ("BENCH_K", "k")] {
                if let Some(n) = std::env::var(var).ok().and_then(|v| v.parse().ok()) {
                    photon.insert(key.into(), Param::Int(n));
                }
            }
            if let Some(a) = std::env::var("BENCH_ALPHA")
                .ok()
                .and_then(|v| v.parse().ok())
            {
                photon.insert("alpha".into(), Param::Float(a));
            }
            if let Ok(e) = std::env::var("BENCH_ESTIMATE") {
                photon.insert("estimate".into(), Param::Str(e));
            }
        }
        let settings = PhotonSettings::of(&desc).unwrap();
        let choices: Vec<String> = std::env::var("BENCH_INTEGRATORS")
            .unwrap_or_else(|_| "path,photon".into())
            .split(',')
            .map(|c| c.trim().to_string())
            .collect();
        println!(
            "\n== {} (photons {} a pass, {:?} estimate, alpha {:?}, k {:?})",
            file.display(),
            photons_for(&settings, desc.render.width, desc.render.height),
            settings.estimate,
            settings.alpha,
            settings.k
        );
        let seed: u64 = std::env::var("BENCH_SEED")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(7);
        for &budget in &budgets {
            for choice in &choices {
                desc.render.integrator = choice.clone();
                desc.render.seed = seed;
                let world = World::load(&desc).unwrap();
                let mut integ = make_integrator(&desc, &world).unwrap();
                let (w, h) = (desc.render.width, desc.render.height);
                let mut film = Film::new(w, h, Region::full(w, h), false);
                let t = Instant::now();
                let passes = run_passes(
                    &world,
                    integ.as_mut(),
                    &mut film,
                    seed,
                    Stop::Time(Duration::from_secs_f64(budget)),
                    &Silent,
                    |_, _, _| Ok(()),
                )
                .unwrap();
                let secs = t.elapsed().as_secs_f64();
                let img = ImageRgb {
                    width: w as usize,
                    height: h as usize,
                    pixels: film.mean_rgb(),
                };
                let m = compare(&img, &truth).unwrap();
                println!(
                    "budget {budget:>5.0} s  {:<6}  {passes:>5} passes in {secs:6.1} s  relMSE {:.3e}  mean ratio {:.5}",
                    integ.name(),
                    m.rel_mse,
                    m.mean_ratio
                );
            }
        }
    }
}
