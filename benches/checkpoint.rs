//! What a checkpoint costs on a 1920 x 1080 frame (issue 33: under 2 % of
//! the render at one checkpoint a minute): renders `scenes/cloud.toml` at
//! 1920 x 1080 with 4 samples of the path tracer and its AOVs (so the film
//! holds a real render's bits), then times, best of five, what a
//! checkpoint does: writing the resume state (synced to disk), writing the
//! EXR, and reading the state back as `--resume` does; prints the state's
//! size and the share of a minute. Run with `cargo bench --bench
//! checkpoint` (`BENCH_SIZE=WxH`, `BENCH_AOVS=0` for a film without AOVs,
//! `BENCH_DIR` for the folder written to, default `target/bench`).

use std::path::{Path, PathBuf};
use std::time::Instant;
use vdbphoton::film::{Film, Region};
use vdbphoton::render::resume::{self, Identity, Position};
use vdbphoton::render::{make_integrator, run_passes, Silent, Stop};
use vdbphoton::scene::SceneDesc;
use vdbphoton::world::World;

fn best_of(n: usize, mut f: impl FnMut()) -> f64 {
    (0..n)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let size = std::env::var("BENCH_SIZE").unwrap_or_else(|_| "1920x1080".into());
    let (w, h) = size
        .split_once('x')
        .and_then(|(a, b)| Some((a.parse::<u32>().ok()?, b.parse::<u32>().ok()?)))
        .expect("BENCH_SIZE=WxH");
    let aovs = std::env::var("BENCH_AOVS").as_deref() != Ok("0");
    let dir = PathBuf::from(
        std::env::var("BENCH_DIR")
            .unwrap_or_else(|_| concat!(env!("CARGO_MANIFEST_DIR"), "/target/bench").into()),
    );
    std::fs::create_dir_all(&dir).unwrap();
    let mut desc =
        SceneDesc::load(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cloud.toml")).unwrap();
    desc.render.width = w;
    desc.render.height = h;
    desc.render.integrator = "path".into();
    desc.render.aovs = aovs;
    desc.render.output = dir.join("checkpoint_bench.exr");
    let world = World::load(&desc).unwrap();
    let mut integrator = make_integrator(&desc, &world).unwrap();
    let mut film = Film::new(w, h, Region::full(w, h), aovs);
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
    let render = t.elapsed().as_secs_f64();

    let state = resume::state_path(&desc.render.output);
    let id = Identity::of(&desc, integrator.name(), &film);
    let at = Position {
        passes: 4,
        seconds: render,
        last_pass: render / 4.0,
    };
    let st = integrator.state();
    let write_state = best_of(5, || resume::write(&state, &id, at, &st, &film).unwrap());
    let bytes = std::fs::metadata(&state).unwrap().len();
    let write_exr = best_of(5, || {
        let image = film.to_image().unwrap();
        vdbphoton::image::write_exr(&desc.render.output, &image, &[]).unwrap();
    });
    let empty = Film::new(w, h, Region::full(w, h), aovs);
    let read_state = best_of(5, || {
        let back = resume::read(&state, &id, &empty).unwrap().unwrap();
        assert_eq!(back.film, film);
    });
    let _ = std::fs::remove_file(&state);
    let _ = std::fs::remove_file(&desc.render.output);

    let checkpoint = write_state + write_exr;
    println!(
        "checkpoint of a {w} x {h} film{} ({} threads; 4 passes rendered in {render:.2} s):",
        if aovs { " with AOVs" } else { "" },
        rayon::current_num_threads()
    );
    println!(
        "  state {:.1} MB: written and synced in {write_state:.3} s, read back and checked in {read_state:.3} s",
        bytes as f64 / 1e6
    );
    println!("  EXR written in {write_exr:.3} s");
    println!(
        "  a checkpoint (state + EXR) {checkpoint:.3} s: {:.2} % of a minute ({:.2} % for the state alone)",
        100.0 * checkpoint / 60.0,
        100.0 * write_state / 60.0
    );
}
