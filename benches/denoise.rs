//! Denoising a 1920 x 1080 frame (issue 31: under 3 s on 2 cores): renders
//! `scenes/cloud.toml` at 1920 x 1080 with 4 samples of the path tracer and
//! its denoising albedo, then times loading Open Image Denoise, a first and
//! a second denoising of the frame, and prints the process's peak resident
//! memory around them (Linux's VmHWM, reset before each step). Run with
//! `cargo bench --bench denoise` (`BENCH_SIZE=WxH`, `BENCH_THREADS`,
//! default all cores; `BENCH_QUALITY=high|balanced|fast`, default high).
//! Needs the library (`bash scripts/install_oidn.sh`).

mod common;

use common::{cpu, gib, reset_peak, status_bytes};
use std::path::Path;
use std::time::Instant;
use vdbphoton::film::{Film, Region};
use vdbphoton::render::{make_integrator, run_passes, Denoiser, Silent, Stop};
use vdbphoton::scene::SceneDesc;
use vdbphoton::world::World;

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let size = std::env::var("BENCH_SIZE").unwrap_or_else(|_| "1920x1080".into());
    let (w, h) = size
        .split_once('x')
        .and_then(|(a, b)| Some((a.parse::<u32>().ok()?, b.parse::<u32>().ok()?)))
        .expect("BENCH_SIZE=WxH");
    let threads: usize = std::env::var("BENCH_THREADS")
        .ok()
        .and_then(|t| t.parse().ok())
        .unwrap_or(0);
    let mut desc =
        SceneDesc::load(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cloud.toml")).unwrap();
    desc.render.width = w;
    desc.render.height = h;
    desc.render.integrator = "path".into();
    let world = World::load(&desc).unwrap();
    let mut integrator = make_integrator(&desc, &world).unwrap();
    let mut film = Film::new(w, h, Region::full(w, h), false).with_guides();
    let t = Instant::now();
    run_passes(
        &world,
        integrator.as_mut(),
        &mut film,
        1,
        Stop::Passes(4),
        &Silent,
        |_, _, _| Ok(()),
    )
    .unwrap();
    println!(
        "{w} x {h}: rendered 4 spp in {:.2} s; {} threads of {}",
        t.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
        cpu()
    );
    let image = film.to_image().unwrap();
    let base = status_bytes("VmRSS:");
    reset_peak();
    let t = Instant::now();
    let denoiser = match Denoiser::load(threads) {
        Ok(d) => d,
        Err(e) => {
            println!("({e})");
            return;
        }
    };
    println!(
        "load Open Image Denoise: {:.3} s",
        t.elapsed().as_secs_f64()
    );
    let denoiser = denoiser.with_quality(match std::env::var("BENCH_QUALITY").as_deref() {
        Ok("balanced") => vdbphoton::denoise::Quality::Balanced,
        Ok("fast") => vdbphoton::denoise::Quality::Fast,
        _ => vdbphoton::denoise::Quality::High,
    });
    for run in ["first", "second"] {
        let mut img = image.clone();
        reset_peak();
        let before = status_bytes("VmRSS:");
        let t = Instant::now();
        denoiser.apply(&mut img).unwrap();
        println!(
            "{run} denoising: {:.2} s, peak {} over the {} before it ({} over the image alone)",
            t.elapsed().as_secs_f64(),
            gib(status_bytes("VmHWM:").saturating_sub(before)),
            gib(before),
            gib(status_bytes("VmHWM:").saturating_sub(base)),
        );
    }
    println!("{}", denoiser.describe(&image));
}
