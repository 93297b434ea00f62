//! Meshes' cost (issue 49's figures):
//! - a 1 M-triangle mesh (a UV sphere, written as binary PLY and as OBJ):
//!   read time, BVH build time, the bytes the surfaces keep and the
//!   process's peak memory over the load;
//! - the render-time cost of a ground plane (a shadow catcher) and a ball
//!   (a holdout) on Blender's smoke + fire frame
//!   (`tests/data/cycles/smoke25_shot.toml`, the cache from
//!   `VDBPHOTON_REAL_DATA`, default `../shared/data`) at the same samples
//!   per pixel, against the frame without them, with each integrator
//!   (target: at most 1.2x), and with both as plain holdouts.
//!
//! Run with `cargo bench --bench meshes` (`BENCH_SPP`, default 64;
//! `BENCH_RUNS`, default 3: the best of them is printed).

use std::path::{Path, PathBuf};
use std::time::Instant;
use vdbphoton::film::{Film, Region};
use vdbphoton::mesh::{self, TriangleMesh};
use vdbphoton::render::{make_integrator, run_passes, Silent, Stop};
use vdbphoton::scene::SceneDesc;
use vdbphoton::world::{load_shapes, World};

fn env(name: &str, default: u32) -> u32 {
    std::env::var(name)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

/// `VmHWM` (peak resident memory) of this process, bytes.
fn peak_rss() -> u64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
        .map_or(0, |kb| kb * 1024)
}

/// Clears the peak so that the next [`peak_rss`] measures from here.
fn reset_peak() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// A UV sphere with `rings` x `segments` quads (2 · (rings − 1) ·
/// segments triangles).
fn sphere(rings: u32, segments: u32) -> TriangleMesh {
    let mut m = TriangleMesh::default();
    for i in 0..=rings {
        let th = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let ph = 2.0 * std::f32::consts::PI * j as f32 / segments as f32;
            m.positions.push(glam::Vec3::new(
                th.sin() * ph.cos(),
                th.sin() * ph.sin(),
                th.cos(),
            ));
        }
    }
    for i in 0..rings {
        for j in 0..segments {
            let a = i * segments + j;
            let b = i * segments + (j + 1) % segments;
            let (c, d) = (a + segments, b + segments);
            if i > 0 {
                m.triangles.push([a, c, b]);
            }
            if i < rings - 1 {
                m.triangles.push([b, c, d]);
            }
        }
    }
    m
}

fn write_files(m: &TriangleMesh, dir: &Path) -> (PathBuf, PathBuf) {
    use std::io::Write;
    let ply = dir.join("sphere_1m.ply");
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.positions.len(),
        m.triangles.len()
    )
    .into_bytes();
    for p in &m.positions {
        for c in p.to_array() {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for t in &m.triangles {
        b.push(3);
        for i in t {
            b.extend_from_slice(&(*i as i32).to_le_bytes());
        }
    }
    std::fs::write(&ply, b).unwrap();
    let obj = dir.join("sphere_1m.obj");
    let mut f = std::io::BufWriter::new(std::fs::File::create(&obj).unwrap());
    for p in &m.positions {
        writeln!(f, "v {} {} {}", p.x, p.y, p.z).unwrap();
    }
    for t in &m.triangles {
        writeln!(f, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
    }
    (ply, obj)
}

fn big_mesh() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-meshes");
    std::fs::create_dir_all(&dir).unwrap();
    let m = sphere(501, 1000);
    let (ply, obj) = write_files(&m, &dir);
    println!(
        "a UV sphere of {} triangles and {} vertices (PLY {:.1} MB, OBJ {:.1} MB):",
        m.triangles.len(),
        m.positions.len(),
        std::fs::metadata(&ply).unwrap().len() as f64 / 1e6,
        std::fs::metadata(&obj).unwrap().len() as f64 / 1e6
    );
    drop(m);
    for file in [&ply, &obj] {
        let before = peak_rss();
        reset_peak();
        let base = peak_rss();
        let t0 = Instant::now();
        let read = mesh::read(file).unwrap();
        let t_read = t0.elapsed().as_secs_f64();
        drop(read);
        let desc = vdbphoton::scene::MeshDesc {
            name: None,
            file: file.clone(),
            transform: glam::DAffine3::IDENTITY,
            holdout: false,
            shadow_catcher: false,
            visibility: Default::default(),
            material: None,
        };
        let t1 = Instant::now();
        let (shapes, _) = load_shapes(std::slice::from_ref(&desc), &mut Vec::new()).unwrap();
        let t_all = t1.elapsed().as_secs_f64();
        let peak = peak_rss().saturating_sub(base);
        println!(
            "  {}: read {t_read:.2} s; read, placed and in the BVH {t_all:.2} s; the surfaces keep {:.0} MB ({:.0} bytes a triangle); peak memory over the load {:.0} MB ({:.0} bytes a triangle; estimate {} bytes a triangle){}",
            file.extension().unwrap().to_string_lossy(),
            shapes.memory_bytes() as f64 / 1e6,
            shapes.memory_bytes() as f64 / shapes.triangles() as f64,
            peak as f64 / 1e6,
            peak as f64 / shapes.triangles() as f64,
            vdbphoton::shape::BYTES_PER_TRIANGLE,
            if before == 0 { " (no /proc)" } else { "" }
        );
    }
}

/// One render of `spp` samples per pixel: the seconds its passes take.
fn render(desc: &SceneDesc, world: &World, spp: u32) -> f64 {
    let r = &desc.render;
    let mut integrator = make_integrator(desc, world).unwrap();
    let mut film = Film::new(r.width, r.height, Region::full(r.width, r.height), false);
    if world.shapes.has_catcher() {
        film = film.with_catcher();
    }
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

fn time(desc: &SceneDesc, spp: u32, runs: u32) -> f64 {
    let world = World::load(desc).unwrap();
    (0..runs)
        .map(|_| render(desc, &world, spp))
        .fold(f64::INFINITY, f64::min)
}

fn shot() {
    let data = std::env::var_os("VDBPHOTON_REAL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/data"));
    let cache = data.join("blender_smoke/fluid_data_0025.vdb");
    if !cache.is_file() {
        println!("({} not found: no render cost)", cache.display());
        return;
    }
    let (spp, runs) = (env("BENCH_SPP", 64), env("BENCH_RUNS", 3));
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cycles/smoke25_shot.toml");
    let mut shot = SceneDesc::load(&scene).unwrap();
    for v in &mut shot.volumes {
        v.file = cache.clone();
    }
    let mut bare = shot.clone();
    bare.meshes.clear();
    let mut holes = shot.clone();
    for m in &mut holes.meshes {
        m.shadow_catcher = false;
        m.holdout = true;
    }
    println!(
        "Blender smoke + fire frame 25 ({}), {} x {}, {spp} spp, {} threads, best of {runs}:",
        scene.file_name().unwrap().to_string_lossy(),
        shot.render.width,
        shot.render.height,
        rayon::current_num_threads()
    );
    for integrator in ["path", "photon"] {
        let set = |d: &mut SceneDesc| d.render.integrator = integrator.into();
        for d in [&mut shot, &mut bare, &mut holes] {
            set(d);
        }
        let t0 = time(&bare, spp, runs);
        let t1 = time(&shot, spp, runs);
        let t2 = time(&holes, spp, runs);
        println!(
            "  {integrator:6}: no meshes {t0:.2} s; ground (shadow catcher) and ball (holdout) {t1:.2} s: {:.2}x; both holdouts {t2:.2} s: {:.2}x",
            t1 / t0,
            t2 / t0
        );
    }
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    big_mesh();
    shot();
}
