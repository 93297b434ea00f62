//! Motion blur's cost: the Blender smoke + fire frame 25
//! (`tests/data/cycles/smoke25_sun_mb.toml`, the cache from
//! `VDBPHOTON_REAL_DATA`, default `../shared/data`) rendered with motion
//! blur (Blender's defaults) and still, at the same samples per pixel, with
//! each integrator. Prints each render's time (the best of `BENCH_RUNS`,
//! default 3) and the ratio blurred / still (issue 30's target: at most
//! 1.3). Run with
//! `cargo bench --bench motion_blur` (`BENCH_SPP`, default 64).

use std::path::{Path, PathBuf};
use std::time::Instant;
use vdbphoton::film::{Film, Region};
use vdbphoton::render::{make_integrator, run_passes, Silent, Stop};
use vdbphoton::scene::SceneDesc;
use vdbphoton::tracking;
use vdbphoton::world::World;

fn env(name: &str, default: u32) -> u32 {
    std::env::var(name)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

/// One render of `spp` samples per pixel: the seconds its passes take.
/// The integrator (with its photon pilot) and film are made first, then
/// `start` runs and the clock starts.
fn render(desc: &SceneDesc, world: &World, spp: u32, start: impl FnOnce()) -> f64 {
    let r = &desc.render;
    let mut integrator = make_integrator(desc, world).unwrap();
    let mut film = Film::new(r.width, r.height, Region::full(r.width, r.height), false);
    start();
    let t = Instant::now();
    run_passes(
        world,
        integrator.as_mut(),
        &mut film,
        r.seed,
        Stop::Passes(spp),
        &Silent,
        |_, _, _| Ok(()),
    )
    .unwrap();
    t.elapsed().as_secs_f64()
}

/// Seconds of the best of `runs` renders.
fn time(desc: &SceneDesc, spp: u32, runs: u32) -> f64 {
    let world = World::load(desc).unwrap();
    (0..runs)
        .map(|_| render(desc, &world, spp, || {}))
        .fold(f64::INFINITY, f64::min)
}

/// Lookups and tentative collisions per sample, counted on one thread
/// over `spp` samples per pixel.
fn counts(desc: &SceneDesc, spp: u32) -> (f64, f64) {
    let world = World::load(desc).unwrap();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let c = one.install(|| {
        render(desc, &world, spp, || {
            tracking::take_counters();
        });
        tracking::take_counters()
    });
    let r = &desc.render;
    let n = (r.width * r.height * spp) as f64;
    (c.lookups as f64 / n, c.tentative as f64 / n)
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let data = std::env::var_os("VDBPHOTON_REAL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/data"));
    let cache = data.join("blender_smoke/fluid_data_0025.vdb");
    if !cache.is_file() {
        println!("({} not found: nothing to benchmark)", cache.display());
        return;
    }
    let (spp, runs) = (env("BENCH_SPP", 64), env("BENCH_RUNS", 3));
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cycles/smoke25_sun_mb.toml");
    let mut blurred = SceneDesc::load(&scene).unwrap();
    for v in &mut blurred.volumes {
        v.file = cache.clone();
    }
    println!(
        "Blender smoke + fire frame 25, {} x {}, {spp} spp, {} threads; motion blur: shutter {} frames, {}",
        blurred.render.width,
        blurred.render.height,
        rayon::current_num_threads(),
        blurred.render.motion_blur.shutter,
        blurred.render.motion_blur.position.name()
    );
    for integrator in ["path", "photon"] {
        blurred.render.integrator = integrator.into();
        let mut still = blurred.clone();
        still.render.motion_blur.enabled = false;
        let ts = time(&still, spp, runs);
        let tb = time(&blurred, spp, runs);
        println!(
            "{:6}: still {ts:.2} s, blurred {tb:.2} s: {:.2}x",
            integrator,
            tb / ts
        );
        let ((ls, cs), (lb, cb)) = (counts(&still, 4), counts(&blurred, 4));
        println!(
            "        per camera sample (camera, shadow and photon work alike): lookups {ls:.1} still, {lb:.1} blurred; tentative collisions {cs:.1}, {cb:.1}"
        );
    }
}
