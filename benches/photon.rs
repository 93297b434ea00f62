//! Photon-mapping benchmark: prints figures, asserts nothing. Run with
//! `cargo bench --bench photon` (`VDBPHOTON_REAL_DATA`, default
//! `../shared/data`, for the scenes; `BENCH_PHOTONS` for the photons of the
//! tracing run, default 1,000,000).
//!
//! On the shared reference scene (`reference/cloud96_sun.toml`) and its
//! dense variant (`reference/cloud96_dense.toml`):
//! - photons traced per second (all threads) and photons stored per photon;
//! - radius computation, BVH (beam) and k-d tree (point) build times for
//!   1 M and 10 M stored photons (photons are re-traced until there are
//!   enough);
//! - beam gathers per second along camera rays, point queries per second;
//! - bytes per stored photon (photon, radius, BVH; photon and k-d tree);
//! - the time a pass of the photon integrator takes, split into tracing,
//!   map building and camera rays.

use std::path::PathBuf;
use std::time::Instant;
use vdbphoton::integrator::{Integrator, PhotonIntegrator};
use vdbphoton::photon::beam::BeamMap;
use vdbphoton::photon::emitter::Emitters;
use vdbphoton::photon::map::{density_radii, median, PointMap};
use vdbphoton::photon::{self, Photon};
use vdbphoton::render::passes;
use vdbphoton::scene::SceneDesc;
use vdbphoton::world::World;

fn secs(t: Instant) -> f64 {
    t.elapsed().as_secs_f64()
}

/// Traces passes of `n` photons, storing every eligible collision with
/// probability `store`, until `want` photons are stored.
fn photons(world: &World, e: &Emitters, n: u32, store: f32, want: usize) -> Vec<Photon> {
    let mut all = Vec::new();
    let mut pass = 0;
    while all.len() < want {
        let (p, _) = photon::trace(
            world,
            e,
            n,
            7,
            pass,
            0.0,
            1024,
            photon::Store {
                scale: store,
                importance: None,
            },
        );
        all.extend(p);
        pass += 1;
    }
    all.truncate(want);
    all
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let data = std::env::var_os("VDBPHOTON_REAL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/data"));
    let n: u32 = std::env::var("BENCH_PHOTONS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    println!("{} threads", rayon::current_num_threads());
    for name in ["cloud96_sun", "cloud96_dense"] {
        let scene = data.join(format!("reference/{name}.toml"));
        if !scene.is_file() {
            println!("({} not found)", scene.display());
            continue;
        }
        let desc = SceneDesc::load(&scene).unwrap();
        let world = World::load(&desc).unwrap();
        let e = Emitters::new(&world).unwrap();
        println!("\n== {name} (max_bounces {})", desc.render.max_bounces);
        let t = Instant::now();
        let (p, st) = photon::trace(
            &world,
            &e,
            n,
            1,
            0,
            0.0,
            desc.render.max_bounces,
            photon::Store::ALL,
        );
        let dt = secs(t);
        println!(
            "tracing: {n} photons in {dt:.2} s = {:.2} M photons/s; {:.1} eligible collisions per photon, {} stored",
            n as f64 / dt / 1e6,
            st.eligible as f64 / n as f64,
            p.len()
        );
        drop(p);
        let store = 0.25f32;
        for want in [1_000_000usize, 10_000_000] {
            let ph = photons(&world, &e, n, store, want);
            let t = Instant::now();
            let r0 = density_radii(&ph, 32, 0.02, f32::INFINITY);
            let cell = median(&r0) / 1.5;
            let r = density_radii(&ph, 32, cell, 4.0 * median(&r0));
            let t_radii = secs(t);
            let t = Instant::now();
            let beam = BeamMap::new(
                ph.clone(),
                r,
                Vec::new(),
                vdbphoton::photon::beam::RATIO_MAX,
                1.0,
            )
            .unwrap();
            let t_bvh = secs(t);
            let beam_bytes = beam.memory_bytes();
            let t = Instant::now();
            let point = PointMap::new(ph.clone()).unwrap();
            let t_kd = secs(t);
            println!(
                "{:>9} photons: radii {t_radii:.3} s, BVH build {t_bvh:.3} s ({:.0} B/photon with radius and photon), k-d tree build {t_kd:.3} s; median radius {:.4}",
                want,
                beam_bytes as f64 / want as f64,
                median(&density_radii(&ph, 32, cell, f32::INFINITY))
            );
            // Gathers along the scene's camera rays through the image centre
            // rows; point queries at the photons' own positions, shifted.
            let cam = &world.camera;
            let rays = 20_000u32;
            let t = Instant::now();
            let mut sum = 0.0f32;
            for i in 0..rays {
                let x = (i % cam.width()) as f32 + 0.5;
                let y = (cam.height() / 2 + (i / cam.width()) % 16) as f32;
                let d = cam.direction(glam::Vec2::new(x, y));
                let (l, _) = beam.gather(&world.media, cam.position(), d, f32::INFINITY, |_| {
                    (glam::Vec3::ONE, 1.0)
                });
                sum += l.x;
            }
            let g = rays as f64 / secs(t);
            let t = Instant::now();
            for i in 0..rays as usize {
                let q = ph[(i * 7919) % ph.len()].p + glam::Vec3::splat(0.003);
                sum += point
                    .estimate(&world.media, q, 1.0, glam::Vec3::X, 32, 0.05)
                    .0
                    .x;
            }
            let q = rays as f64 / secs(t);
            println!(
                "           one thread: {g:.0} beam gathers/s (whole ray), {q:.0} point queries/s (k = 32) [{}]",
                sum.is_finite()
            );
        }
        // One pass of the integrator, split.
        let mut integ = PhotonIntegrator::new(
            &world,
            vdbphoton::integrator::photon::PhotonSettings::of(&desc).unwrap(),
            desc.render.max_bounces,
            1,
        )
        .unwrap();
        let region = vdbphoton::film::Region::full(desc.render.width, desc.render.height);
        for pass in 0..3 {
            let t = Instant::now();
            integ.begin_pass(&world, pass);
            let t_begin = secs(t);
            let mut film =
                vdbphoton::film::Film::new(desc.render.width, desc.render.height, region, false);
            let t = Instant::now();
            passes::render_pass(&world, &integ, &mut film, 1, pass, &|_, _| {});
            let t_cam = secs(t);
            println!(
                "pass {pass}: photons and map {t_begin:.3} s ({} stored), camera rays {t_cam:.3} s",
                integ.totals().last_stored
            );
        }
    }
}
