//! Meshes in the shot (issue 49): the files read (PLY ASCII and binary,
//! OBJ), surfaces that shadow the media exactly, holdouts that cut exact
//! holes, a shadow catcher whose pass is the transmittance towards the
//! sun, a transparent film, the pipeline (tiles, merge) with meshes, and
//! bad mesh input: one line naming the scene, the `[[mesh]]` and the
//! problem, exit 1, no output.

mod common;

use glam::{DVec3, IVec3, Vec3};
use std::f64::consts::PI;
use std::io::Write;
use std::path::Path;
use std::process::Command;
use vdbphoton::image::{read_exr, Image};
use vdbphoton::mesh::{self, TriangleMesh};
use vdbphoton::vdb::{write_vdb, AnyGrid};

const BIN: &str = env!("CARGO_BIN_EXE_vdbphoton");

/// A binary little-endian PLY of `m`.
fn write_ply(path: &Path, m: &TriangleMesh) {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by vdbphoton's tests\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
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
    std::fs::write(path, b).unwrap();
}

/// A quad `[a, b, c, d]` (counter-clockwise) as two triangles.
fn quad(v: [Vec3; 4]) -> TriangleMesh {
    TriangleMesh {
        positions: v.to_vec(),
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        ..Default::default()
    }
}

/// A UV sphere of `radius` around `c`: `rings` x `segments` quads.
fn sphere(c: Vec3, radius: f32, rings: u32, segments: u32) -> TriangleMesh {
    let mut m = TriangleMesh::default();
    for i in 0..=rings {
        let th = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let ph = 2.0 * std::f32::consts::PI * j as f32 / segments as f32;
            m.positions
                .push(c + radius * Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()));
        }
    }
    for i in 0..rings {
        for j in 0..segments {
            let a = i * segments + j;
            let b = i * segments + (j + 1) % segments;
            let (cc, d) = (a + segments, b + segments);
            if i > 0 {
                m.triangles.push([a, cc, b]);
            }
            if i < rings - 1 {
                m.triangles.push([b, cc, d]);
            }
        }
    }
    m
}

/// A homogeneous slab of density 1: x in `[x0, x1]`, y in [−4, 4], z in
/// `[z0, z0 + 1]`, voxels of 1/8 (so its trilinear ramps integrate to the
/// sharp slab along any line through its top and bottom faces).
fn write_slab(path: &Path, x0: f64, x1: f64, z0: f64) {
    let h = 1.0 / 8.0;
    let blocks = IVec3::new(((x1 - x0) / (8.0 * h)).round() as i32, 8, 1);
    let g = common::const_box("density", 1.0, DVec3::new(x0, -4.0, z0), h, blocks);
    write_vdb(path, &[AnyGrid::Float(g)]).unwrap();
}

struct Run {
    code: i32,
    stderr: String,
}

fn run(dir: &Path, args: &[&str]) -> Run {
    let out = Command::new(BIN)
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    Run {
        code: out.status.code().expect("killed by a signal"),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn render(dir: &Path, scene: &str, args: &[&str]) -> Image {
    let mut a = vec!["render", scene, "--no-preview", "--quiet"];
    a.extend_from_slice(args);
    let r = run(dir, &a);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let out = args
        .windows(2)
        .find(|w| w[0] == "-o")
        .map_or("out.exr", |w| w[1]);
    read_exr(dir.join(out)).unwrap().0
}

/// The scene text: a camera at height 10 looking straight down (image x
/// along world +x, image top towards +y), `width` square, the slab file,
/// raw material `sigma_a`, `sigma_s` (isotropic), a sun of irradiance 2
/// from `sun`, a black world, `extra` appended.
fn top_down(width: u32, sigma_a: f32, sigma_s: f32, sun: Vec3, extra: &str) -> String {
    format!(
        r#"[render]
width = {width}
height = {width}
max_bounces = 1
[camera]
position = [0, 0, 10]
look_at = [0, 0, 0]
up = [0, 1, 0]
vfov = 20
[[light]]
type = "sun"
direction = [{}, {}, {}]
irradiance = 2
[[volume]]
file = "slab.vdb"
[volume.material]
sigma_a = {sigma_a}
sigma_s = {sigma_s}
{extra}
"#,
        sun.x, sun.y, sun.z
    )
}

/// The unit direction of the camera ray through pixel centre (x, y) of
/// [`top_down`]'s camera.
fn pixel_ray(x: u32, y: u32, width: u32) -> DVec3 {
    let t = (10.0f64).to_radians().tan();
    let u = ((x as f64 + 0.5) / width as f64 * 2.0 - 1.0) * t;
    let v = (1.0 - (y as f64 + 0.5) / width as f64 * 2.0) * t;
    DVec3::new(u, v, -1.0).normalize()
}

/// A sun from straight above and an opaque square above half of a
/// homogeneous slab that camera rays do not see: with single scattering
/// only, pixels in the square's shadow are exactly 0, the others the
/// closed form σs·p·E·(1 − e^(−σt(1+μ)D/μ))/(σt(1+μ)) of a ray at cos μ
/// to the vertical (p = 1/4π, E the sun's irradiance, D = 1), with both
/// integrators. Fails if the shadow ray ignores the mesh (the shadowed
/// half lights up), or if the mesh stops camera rays (the image is
/// black).
#[test]
fn an_opaque_square_shadows_a_slab_exactly() {
    let dir = common::tempdir();
    let d = dir.path();
    write_slab(&d.join("slab.vdb"), -4.0, 4.0, 0.0);
    write_ply(
        &d.join("square.ply"),
        &quad([
            Vec3::new(-10.0, -10.0, 2.0),
            Vec3::new(0.0, -10.0, 2.0),
            Vec3::new(0.0, 10.0, 2.0),
            Vec3::new(-10.0, 10.0, 2.0),
        ]),
    );
    let (sa, ss) = (0.4f32, 0.8f32);
    let w = 24;
    let scene = top_down(
        w,
        sa,
        ss,
        Vec3::Z,
        "[[mesh]]\nfile = \"square.ply\"\nvisibility = { camera = false }\n",
    );
    std::fs::write(d.join("s.toml"), scene).unwrap();
    let st = (sa + ss) as f64;
    let expected = |x: u32, y: u32| {
        let mu = -pixel_ray(x, y, w).z;
        ss as f64 / (4.0 * PI) * 2.0 * (1.0 - (-st * (1.0 + mu) / mu).exp()) / (st * (1.0 + mu))
    };
    for integrator in ["path", "photon"] {
        let img = render(d, "s.toml", &["--integrator", integrator, "--spp", "256"]);
        let (mut lit, mut want, mut n) = (0.0, 0.0, 0);
        for y in 0..w {
            for x in 0..w {
                // Where on the slab's top the pixel looks, and how far the
                // slant of its ray reaches through the slab.
                let r = pixel_ray(x, y, w);
                let at = r.x * 9.0 / -r.z;
                let reach = r.x.abs() / -r.z;
                let c = img.get(x as usize, y as usize);
                if at + reach < -0.1 {
                    assert_eq!(c.x, 0.0, "{integrator}: ({x}, {y}) in the shadow");
                } else if at - reach > 0.1 {
                    lit += c.x as f64;
                    want += expected(x, y);
                    n += 1;
                }
            }
        }
        assert!(n > 100);
        let ratio = lit / want;
        assert!(
            (ratio - 1.0).abs() < 0.01,
            "{integrator}: the lit half is {ratio} of the closed form"
        );
    }
}

/// Möller–Trumbore, written out apart from the renderer's BVH, for the
/// coverage the test expects.
fn hits(m: &TriangleMesh, o: DVec3, d: DVec3) -> bool {
    m.triangles.iter().any(|t| {
        let [a, b, c] = t.map(|i| m.positions[i as usize].as_dvec3());
        let (e1, e2) = (b - a, c - a);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            return false;
        }
        let s = o - a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = d.dot(q) / det;
        u >= 0.0 && v >= 0.0 && u + v <= 1.0 && e2.dot(q) / det > 0.0
    })
}

/// A holdout sphere in front of a slab: where it covers a pixel, colour
/// and alpha are exactly 0; where it covers part of one, alpha is
/// (1 − coverage)·(1 − T) with the coverage of the pixel by the sphere's
/// triangles (found here by 32 x 32 rays a pixel), within the binomial
/// noise of the samples; elsewhere alpha is the slab's 1 − e^(−σt·D/μ).
/// Fails if the holdout lets the slab through, or adds the world.
#[test]
fn a_holdout_cuts_an_exact_hole() {
    let dir = common::tempdir();
    let d = dir.path();
    write_slab(&d.join("slab.vdb"), -4.0, 4.0, 0.0);
    let ball = sphere(Vec3::new(0.3, 0.2, 5.0), 0.45, 24, 48);
    write_ply(&d.join("ball.ply"), &ball);
    let w = 24;
    let spp = 512;
    let scene = top_down(
        w,
        0.6,
        0.3,
        Vec3::new(0.3, 0.2, 1.0),
        "[[mesh]]\nfile = \"ball.ply\"\nholdout = true\n[environment]\nradiance = 0.5\n",
    );
    std::fs::write(d.join("s.toml"), scene).unwrap();
    let t = (10.0f64).to_radians().tan();
    for integrator in ["path", "photon"] {
        let img = render(
            d,
            "s.toml",
            &["--integrator", integrator, "--spp", &spp.to_string()],
        );
        // Alpha's sums over the pixels the sphere leaves open and over those
        // it covers in part, with their variances (a sample's alpha is
        // close to a Bernoulli variable of its mean: here the trackers'
        // transmittance is nearly always 0 or 1).
        // Rays that pass the ball's centre closer than the polyhedron's
        // inscribed radius hit it, those beyond its radius miss it; the
        // triangles decide in between.
        let centre = DVec3::new(0.3, 0.2, 5.0);
        let eye = DVec3::new(0.0, 0.0, 10.0);
        let inscribed = 0.45 * (PI / 24.0).cos() * (PI / 48.0).cos();
        let covers = |r: DVec3| {
            let to = centre - eye;
            let miss = (to - r * to.dot(r)).length();
            miss < inscribed || (miss <= 0.45 && hits(&ball, eye, r))
        };
        let (mut open, mut edge) = ([0.0f64; 3], [0.0f64; 3]);
        let mut full = 0;
        for y in 0..w {
            for x in 0..w {
                let k = 32;
                let mut covered = 0;
                for j in 0..k {
                    for i in 0..k {
                        let u =
                            ((x as f64 + (i as f64 + 0.5) / k as f64) / w as f64 * 2.0 - 1.0) * t;
                        let v =
                            (1.0 - (y as f64 + (j as f64 + 0.5) / k as f64) / w as f64 * 2.0) * t;
                        let r = DVec3::new(u, v, -1.0).normalize();
                        covered += covers(r) as u32;
                    }
                }
                let cov = covered as f64 / (k * k) as f64;
                let mu = -pixel_ray(x, y, w).z;
                let want = (1.0 - cov) * (1.0 - (-0.9 / mu).exp());
                let c = img.get(x as usize, y as usize);
                let sums = if cov == 1.0 {
                    full += 1;
                    assert_eq!(
                        c,
                        glam::Vec4::ZERO,
                        "{integrator}: ({x}, {y}) under the holdout"
                    );
                    continue;
                } else if cov == 0.0 {
                    &mut open
                } else {
                    &mut edge
                };
                sums[0] += c.w as f64;
                sums[1] += want;
                sums[2] += want * (1.0 - want) / spp as f64;
            }
        }
        assert!(full > 10, "{full} covered pixels");
        for (what, [got, want, var]) in [("open", open), ("edge", edge)] {
            let sigma = var.sqrt();
            assert!(
                want > 5.0 && (got - want).abs() < 4.0 * sigma + 0.003 * want,
                "{integrator}: the {what} pixels' alpha sums to {got}, expected {want} ± {sigma}"
            );
        }
    }
}

/// A slab over half the ground (x < 0, z from 1 to 2) and a 40 x 40
/// ground at z = 0: `slab.vdb` and `ground.ply` in `d`.
fn write_slab_over_ground(d: &Path) {
    write_slab(&d.join("slab.vdb"), -4.0, 0.0, 1.0);
    write_ply(
        &d.join("ground.ply"),
        &quad([
            Vec3::new(-20.0, -20.0, 0.0),
            Vec3::new(20.0, -20.0, 0.0),
            Vec3::new(20.0, 20.0, 0.0),
            Vec3::new(-20.0, 20.0, 0.0),
        ]),
    );
}

/// A shadow catcher under an absorbing slab over half the ground, the sun
/// 30° from the zenith across the slab's edge: the Shadow Catcher pass is
/// the slab's transmittance towards the sun, e^(−σa·D/cos 30°), where the
/// slab shadows the ground and exactly 1 where it does not; the colour is
/// 0 (the slab neither scatters nor glows, the film is transparent) and
/// alpha is 1 − the transmittance of the camera ray. Fails if the pass
/// ignores the media's shadow, divides the wrong way, or counts the
/// camera ray's own transmittance.
#[test]
fn a_shadow_catcher_under_a_slab_gives_its_transmittance() {
    let dir = common::tempdir();
    let d = dir.path();
    write_slab_over_ground(d);
    let sa = 0.7f32;
    let sun = Vec3::new(0.0, 0.5, 3f32.sqrt() / 2.0);
    let w = 24;
    let scene = top_down(
        w,
        sa,
        0.0,
        sun,
        "[[mesh]]\nfile = \"ground.ply\"\nshadow_catcher = true\n",
    )
    .replace("[render]\n", "[render]\nfilm_transparent = true\n");
    std::fs::write(d.join("s.toml"), scene).unwrap();
    let shadow = (-(sa as f64) / (30f64).to_radians().cos()).exp();
    for integrator in ["path", "photon"] {
        let img = render(d, "s.toml", &["--integrator", integrator, "--spp", "1024"]);
        let pass = img.layer("shadow_catcher").expect("a shadow_catcher layer");
        let (mut passes, mut alpha) = (Vec::new(), [0.0f64; 2]);
        for y in 0..w {
            for x in 0..w {
                let r = pixel_ray(x, y, w);
                let ground_x = r.x * 10.0 / -r.z;
                let at_slab = r.x * 8.0 / -r.z;
                let c = img.get(x as usize, y as usize);
                let p = pass.get(x as usize, y as usize);
                assert_eq!([c.x, c.y, c.z], [0.0; 3], "{integrator}: ({x}, {y})");
                if ground_x > 0.1 {
                    assert_eq!(p, &[1.0, 1.0, 1.0], "{integrator}: ({x}, {y}) in the sun");
                    assert_eq!(c.w, 0.0);
                } else if ground_x < -0.1 && at_slab < -0.1 {
                    passes.push(p[0] as f64);
                    assert!((p[0] - p[2]).abs() < 1e-6);
                    alpha[0] += c.w as f64;
                    alpha[1] += 1.0 - (-(sa as f64) / -r.z).exp();
                }
            }
        }
        let n = passes.len() as f64;
        assert!(n > 100.0);
        let mean = passes.iter().sum::<f64>() / n;
        let sigma = (passes.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
        assert!(
            (mean - shadow).abs() < 4.0 * sigma + 0.002,
            "{integrator}: the pass is {mean} ± {sigma} in the shadow, e^(-σa D / cos 30°) = {shadow}"
        );
        assert!(
            (alpha[0] / alpha[1] - 1.0).abs() < 0.01,
            "{integrator}: alpha {} against 1 - e^(-σa D / μ) {}",
            alpha[0] / n,
            alpha[1] / n
        );
    }
}

/// The irradiance at ground point `p` (z = 0, facing up) from an
/// absorbing, glowing box (`lo`..`hi`, absorption `sigma_a`, emission `e`
/// per unit length): ∫ L cos θ dω with L = e/σa · (1 − e^(−σa ℓ)) over the
/// chord ℓ of each direction, by the midpoint rule in u = sin²θ (cos θ dω
/// = du dφ / 2).
fn glow_irradiance(p: DVec3, lo: DVec3, hi: DVec3, sigma_a: f64, e: f64) -> f64 {
    let (nu, nphi) = (200, 400);
    let mut sum = 0.0;
    for i in 0..nu {
        let u = (i as f64 + 0.5) / nu as f64;
        let (st, ct) = (u.sqrt(), (1.0 - u).sqrt());
        for j in 0..nphi {
            let phi = 2.0 * PI * (j as f64 + 0.5) / nphi as f64;
            let d = DVec3::new(st * phi.cos(), st * phi.sin(), ct);
            let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
            for k in 0..3 {
                let (a, b) = ((lo[k] - p[k]) / d[k], (hi[k] - p[k]) / d[k]);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
            if t1 > t0 {
                sum += e / sigma_a * (1.0 - (-sigma_a * (t1 - t0)).exp());
            }
        }
    }
    sum * 0.5 * (2.0 * PI) / (nu * nphi) as f64
}

/// A shadow catcher beside and under a glowing, absorbing slab, the sun
/// 30° from the zenith: the pass is (E_sun·T + E_glow) / E_sun, T the
/// slab's transmittance towards the sun where it shadows the ground (1
/// elsewhere) and E_glow the slab's irradiance on the ground
/// ([`glow_irradiance`], a quadrature). The path tracer finds the glow by
/// its catcher bounce on a share of the samples where the sun reaches the
/// ground (Russian roulette around the sky) and by sampling the emission
/// (MIS against the bounce's collisions); the photon integrator by the
/// bounce on every sample. Fails if the roulette's survivors are not
/// divided by their probability (the glow 1/8 of itself in the sun), if
/// the emission is counted by both the sample and the collisions (twice),
/// or by neither.
#[test]
fn a_shadow_catcher_beside_a_glowing_slab_takes_its_light() {
    let dir = common::tempdir();
    let d = dir.path();
    write_slab_over_ground(d);
    let (sa, e) = (0.7f32, 0.6f32);
    let sun = Vec3::new(0.0, 0.5, 3f32.sqrt() / 2.0);
    let w = 16;
    let scene = top_down(
        w,
        sa,
        0.0,
        sun,
        "emission = 0.6\n[[mesh]]\nfile = \"ground.ply\"\nshadow_catcher = true\n",
    )
    .replace("[render]\n", "[render]\nfilm_transparent = true\n");
    std::fs::write(d.join("s.toml"), scene).unwrap();
    let (lo, hi) = (DVec3::new(-4.0, -4.0, 1.0), DVec3::new(0.0, 4.0, 2.0));
    let sun_e = 2.0 * (30f64).to_radians().cos();
    let shadow = (-(sa as f64) / (30f64).to_radians().cos()).exp();
    // The expected pass at each pixel's centre, and whether the pixel is
    // in the slab's shadow (pixels over the shadow's edge are left out).
    let mut want = vec![];
    for y in 0..w {
        for x in 0..w {
            let r = pixel_ray(x, y, w);
            let g = DVec3::new(r.x * 10.0 / -r.z, r.y * 10.0 / -r.z, 0.0);
            if g.x.abs() < 0.15 {
                continue;
            }
            let t = if g.x < 0.0 { shadow } else { 1.0 };
            let glow = glow_irradiance(g, lo, hi, sa as f64, e as f64);
            want.push((x, y, g.x < 0.0, t + glow / sun_e, glow / sun_e));
        }
    }
    for integrator in ["path", "photon"] {
        let img = render(d, "s.toml", &["--integrator", integrator, "--spp", "1024"]);
        let pass = img.layer("shadow_catcher").expect("a shadow_catcher layer");
        for in_shadow in [false, true] {
            let (mut got, mut sum, mut glow, mut var) = (0.0f64, 0.0, 0.0, 0.0);
            let mut n = 0.0;
            for &(x, y, _, pass_want, g) in want.iter().filter(|p| p.2 == in_shadow) {
                got += pass.get(x as usize, y as usize)[0] as f64;
                sum += pass_want;
                glow += g;
                n += 1.0;
            }
            for &(x, y, _, pass_want, _) in want.iter().filter(|p| p.2 == in_shadow) {
                let p = pass.get(x as usize, y as usize)[0] as f64;
                var += (p - pass_want).powi(2);
            }
            let sigma = (var / (n - 1.0) / n).sqrt();
            let (got, sum, glow) = (got / n, sum / n, glow / n);
            let what = if in_shadow { "shadow" } else { "sun" };
            eprintln!("{integrator}, {what}: pass {got:.5} ± {sigma:.5}, expected {sum:.5} (glow {glow:.4})");
            assert!(
                n > 50.0 && glow > 0.05,
                "{what}: {n} pixels, the glow {glow} of the sun"
            );
            assert!(
                (got - sum).abs() < 4.0 * sigma + 0.01 * sum,
                "{integrator}, in the {what}: the pass is {got} ± {sigma}, expected {sum} (the glow {glow} of it)"
            );
        }
    }
}

/// With a transparent film the world seen directly is not in the colour,
/// and only that changes: where the camera sees past everything, colour
/// and alpha are 0 (the opaque film's colour is the world there); through
/// an absorbing slab the colour is 0 and alpha the same bits as the opaque
/// film's, whose colour is the world times the transmittance.
#[test]
fn a_transparent_film_leaves_out_the_world() {
    let dir = common::tempdir();
    let d = dir.path();
    write_slab(&d.join("slab.vdb"), -4.0, 0.0, 0.0);
    let scene = top_down(16, 0.5, 0.0, Vec3::Z, "[environment]\nradiance = 0.25\n");
    std::fs::write(d.join("opaque.toml"), &scene).unwrap();
    std::fs::write(
        d.join("clear.toml"),
        scene.replace("[render]\n", "[render]\nfilm_transparent = true\n"),
    )
    .unwrap();
    let a = render(d, "opaque.toml", &["--spp", "64", "-o", "a.exr"]);
    let b = render(d, "clear.toml", &["--spp", "64", "-o", "b.exr"]);
    let (mut colour, mut clear, mut n) = (0.0, 0.0, 0);
    for y in 0..16u32 {
        for x in 0..16u32 {
            let (p, q) = (a.get(x as usize, y as usize), b.get(x as usize, y as usize));
            assert_eq!([q.x, q.y, q.z], [0.0; 3], "({x}, {y})");
            assert_eq!(p.w, q.w, "({x}, {y}): alpha is the same");
            let r = pixel_ray(x, y, 16);
            let at = r.x * 9.0 / -r.z;
            if at > 0.3 {
                assert_eq!(p, glam::Vec4::new(0.25, 0.25, 0.25, 0.0), "({x}, {y})");
            } else if at < -0.3 {
                colour += p.x as f64;
                clear += 1.0 - q.w as f64;
                n += 1;
            }
        }
    }
    assert!(n > 50);
    assert!(
        (colour / (0.25 * clear) - 1.0).abs() < 0.03,
        "the opaque film's colour {colour} against the world x transmittance {}",
        0.25 * clear
    );
}

/// The same mesh as binary PLY (little- and big-endian), ASCII PLY with a
/// quad, and OBJ with a quad and negative indices reads as the same
/// triangles; extra properties and elements are read past.
#[test]
fn ply_and_obj_read_the_same_mesh() {
    let dir = common::tempdir();
    let d = dir.path();
    let q = quad([
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(1.0, 1.0, 0.5),
        Vec3::new(0.0, 1.0, 0.5),
    ]);
    write_ply(&d.join("le.ply"), &q);
    let mut be = b"ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nelement face 1\nproperty list uchar uint vertex_indices\nelement edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n".to_vec();
    for p in &q.positions {
        for c in p.to_array() {
            be.extend_from_slice(&(c as f64).to_be_bytes());
        }
        be.push(200);
    }
    be.push(4);
    for i in [0u32, 1, 2, 3] {
        be.extend_from_slice(&i.to_be_bytes());
    }
    be.extend_from_slice(&0i32.to_be_bytes());
    be.extend_from_slice(&1i32.to_be_bytes());
    std::fs::write(d.join("be.ply"), be).unwrap();
    std::fs::write(
        d.join("ascii.ply"),
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nelement face 1\nproperty list uchar int vertex_index\nend_header\n0 0 0 1\n1 0 0 1\n1 1 0.5 1\n0 1 0.5 1\n4 0 1 2 3\n",
    )
    .unwrap();
    std::fs::write(
        d.join("quad.obj"),
        "# a quad\nmtllib missing.mtl\no Quad\nv 0 0 0\nv 1 0 0\nv 1 1 0.5\nv 0 1 0.5\nvn 0 0 1\nusemtl grey\nf -4//1 -3//1 -2//1 -1//1\n",
    )
    .unwrap();
    for f in ["le.ply", "be.ply", "ascii.ply", "quad.obj"] {
        let m = mesh::read(&d.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        assert_eq!(m.positions, q.positions, "{f}");
        assert_eq!(m.triangles, q.triangles, "{f}");
        let size = mesh::size_of_file(&d.join(f)).unwrap();
        assert_eq!(
            (size.vertices, size.triangles),
            (4, 1 + (f == "le.ply") as u64),
            "{f}"
        );
    }
}

/// The scene of the bad-input cases: a small cloud and one `[[mesh]]`.
fn bad_scene(d: &Path, mesh_file: &str) {
    let run = run(
        d,
        &[
            "generate",
            "cloud",
            "cloud.vdb",
            "--res",
            "16",
            "--seed",
            "1",
        ],
    );
    assert_eq!(run.code, 0, "{}", run.stderr);
    std::fs::write(
        d.join("s.toml"),
        format!(
            "[render]\nwidth = 8\nheight = 8\nspp = 1\n[[volume]]\nfile = \"cloud.vdb\"\n[[mesh]]\nname = \"Prop\"\nfile = \"{mesh_file}\"\n"
        ),
    )
    .unwrap();
}

/// Renders `s.toml` and checks a clean failure: exit 1, one line naming
/// the scene, the `[[mesh]]` and `words`, no output.
fn assert_refused(d: &Path, extra: &[&str], words: &[&str]) {
    let mut args = vec!["render", "s.toml", "-o", "out.exr", "--no-preview"];
    args.extend_from_slice(extra);
    let r = run(d, &args);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(!r.stderr.contains("panicked"), "{}", r.stderr);
    let lines: Vec<&str> = r.stderr.lines().filter(|l| l.contains("error")).collect();
    assert_eq!(lines.len(), 1, "{}", r.stderr);
    for w in ["s.toml", "[[mesh]] 1", "'Prop'"].iter().chain(words) {
        assert!(lines[0].contains(w), "'{w}' missing from: {}", lines[0]);
    }
    assert!(!d.join("out.exr").exists());
    assert_eq!(
        common::dir_entries(d)
            .iter()
            .filter(|n| n.starts_with("out") || n.contains(".tmp"))
            .count(),
        0
    );
}

#[test]
fn bad_meshes_are_refused_in_one_line() {
    let dir = common::tempdir();
    let d = dir.path();
    let good = sphere(Vec3::ZERO, 0.3, 6, 8);
    // Missing.
    bad_scene(d, "nothere.ply");
    assert_refused(d, &[], &["nothere.ply", "No such file"]);
    // Not a mesh file by name, and not a mesh inside.
    bad_scene(d, "cloud.vdb");
    assert_refused(d, &[], &["cloud.vdb", ".ply or .obj"]);
    std::fs::write(d.join("junk.ply"), b"\x00\x01binary junk\xff\xfe").unwrap();
    bad_scene(d, "junk.ply");
    assert_refused(d, &[], &["junk.ply", "PLY"]);
    std::fs::write(d.join("points.ply"), "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n").unwrap();
    bad_scene(d, "points.ply");
    assert_refused(d, &[], &["points.ply", "no 'face'"]);
    std::fs::write(d.join("empty.obj"), "# nothing\n").unwrap();
    bad_scene(d, "empty.obj");
    assert_refused(d, &[], &["empty.obj", "no faces"]);
    // Truncated: every cut of a binary file.
    write_ply(&d.join("ball.ply"), &good);
    let bytes = std::fs::read(d.join("ball.ply")).unwrap();
    for cut in [10, 120, 200, bytes.len() / 2, bytes.len() - 1] {
        std::fs::write(d.join("cut.ply"), &bytes[..cut]).unwrap();
        bad_scene(d, "cut.ply");
        assert_refused(d, &[], &["cut.ply"]);
    }
    // NaN and infinite vertices, indices out of range, degenerate faces.
    for (name, broken, word) in [
        ("nan.ply", 0, "not finite"),
        ("inf.ply", 1, "not finite"),
        ("range.ply", 2, "refers to vertex"),
        ("degenerate.ply", 3, "degenerate"),
    ] {
        let mut m = good.clone();
        match broken {
            0 => m.positions[3].y = f32::NAN,
            1 => m.positions[5].z = f32::INFINITY,
            2 => m.triangles[4][1] = 9999,
            _ => m.triangles[2][2] = m.triangles[2][0],
        }
        write_ply(&d.join(name), &m);
        bad_scene(d, name);
        assert_refused(d, &[], &[name, word]);
    }
    // A hundred million triangles: refused from the header, beyond the
    // memory given, before anything is read.
    let mut f = std::fs::File::create(d.join("huge.ply")).unwrap();
    f.write_all(b"ply\nformat ascii 1.0\nelement vertex 300000000\nproperty float x\nproperty float y\nproperty float z\nelement face 100000000\nproperty list uchar int vertex_indices\nend_header\n").unwrap();
    drop(f);
    bad_scene(d, "huge.ply");
    assert_refused(
        d,
        &["--max-memory", "4G"],
        &["huge.ply", "100000000 triangles"],
    );
    // The same counts in a binary file too short for them: truncated.
    std::fs::write(d.join("short.ply"), b"ply\nformat binary_little_endian 1.0\nelement vertex 300000000\nproperty float x\nproperty float y\nproperty float z\nelement face 100000000\nproperty list uchar int vertex_indices\nend_header\n").unwrap();
    bad_scene(d, "short.ply");
    assert_refused(d, &[], &["short.ply", "truncated"]);
}

/// Tiles of a frame with meshes (a catcher and a shaded ball) merge into the
/// full render's bits, shadow catcher layer included.
#[test]
fn tiles_with_meshes_merge_into_the_full_frame() {
    let dir = common::tempdir();
    let d = dir.path();
    write_slab_over_ground(d);
    write_ply(
        &d.join("ball.ply"),
        &sphere(Vec3::new(0.5, 0.0, 4.0), 0.5, 8, 16),
    );
    let scene = top_down(
        16,
        0.5,
        0.5,
        Vec3::new(0.2, 0.3, 1.0),
        "[[mesh]]\nfile = \"ground.ply\"\nshadow_catcher = true\n[[mesh]]\nfile = \"ball.ply\"\n[environment]\nradiance = 0.2\n",
    );
    std::fs::write(d.join("s.toml"), scene).unwrap();
    for integrator in ["path", "photon"] {
        let full = render(
            d,
            "s.toml",
            &[
                "--integrator",
                integrator,
                "--spp",
                "4",
                "-o",
                "full.exr",
                "--aovs",
            ],
        );
        for i in 0..4 {
            let t = format!("{i}/4");
            let o = format!("tile{i}.exr");
            render(
                d,
                "s.toml",
                &[
                    "--integrator",
                    integrator,
                    "--spp",
                    "4",
                    "--tile",
                    &t,
                    "-o",
                    &o,
                    "--aovs",
                ],
            );
        }
        let r = run(
            d,
            &[
                "merge",
                "merged.exr",
                "tile0.exr",
                "tile1.exr",
                "tile2.exr",
                "tile3.exr",
            ],
        );
        assert_eq!(r.code, 0, "{}", r.stderr);
        let merged = read_exr(d.join("merged.exr")).unwrap().0;
        assert_eq!(merged.pixels(), full.pixels(), "{integrator}");
        assert!(
            full.layer("diffuse_direct")
                .unwrap()
                .data()
                .iter()
                .any(|&v| v > 0.0),
            "{integrator}: the ball's Diffuse Direct is empty"
        );
        for layer in ["shadow_catcher", "diffuse_direct", "diffuse_indirect"] {
            assert_eq!(
                merged.layer(layer).unwrap().data(),
                full.layer(layer).unwrap().data(),
                "{integrator}: {layer}"
            );
        }
    }
}

/// A scene without meshes renders the bits it rendered before meshes
/// existed: images made by the build before them (5e59df1) with the same
/// commands, kept in `tests/data/no_mesh` (the bundled plume and cloud,
/// both integrators, with AOVs; one denoised), compared channel by
/// channel.
#[test]
fn scenes_without_meshes_render_the_bits_they_did() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = common::tempdir();
    let mut cases: Vec<(&str, &str, bool)> = vec![
        ("plume", "path", false),
        ("plume", "photon", false),
        ("cloud", "path", false),
        ("cloud", "photon", false),
    ];
    match vdbphoton::denoise::Oidn::load(1) {
        Ok(_) => cases.push(("plume", "path", true)),
        Err(e) => eprintln!("the denoised case is skipped: {e}"),
    }
    for (scene, integrator, denoise) in cases {
        let name = format!(
            "{scene}_{integrator}{}.exr",
            if denoise { "_denoise" } else { "" }
        );
        let out = dir.path().join(&name);
        let scene_file = root.join(format!("scenes/{scene}.toml"));
        let mut args = vec![
            "render",
            scene_file.to_str().unwrap(),
            "--integrator",
            integrator,
            "--width",
            "48",
            "--height",
            "36",
            "--spp",
            "4",
            "--seed",
            "3",
            "-o",
            out.to_str().unwrap(),
            "--no-preview",
            "--quiet",
        ];
        args.push(if denoise { "--denoise" } else { "--aovs" });
        let r = run(dir.path(), &args);
        assert_eq!(r.code, 0, "{}", r.stderr);
        let (now, _) = read_exr(&out).unwrap();
        let (then, _) = read_exr(root.join("tests/data/no_mesh").join(&name)).unwrap();
        assert_eq!(now.pixels(), then.pixels(), "{name}: RGBA");
        let names = |i: &Image| {
            i.layers()
                .iter()
                .map(|l| l.name().to_string())
                .collect::<Vec<_>>()
        };
        assert_eq!(names(&now), names(&then), "{name}");
        for l in then.layers() {
            assert_eq!(
                now.layer(l.name()).unwrap().data(),
                l.data(),
                "{name}: {}",
                l.name()
            );
        }
    }
}

/// The ground-and-ball scene of [`tiles_with_meshes_merge_into_the_full_frame`]
/// in `d` (`s.toml`), larger, for renders that take a while.
fn ground_and_ball(d: &Path) {
    write_slab_over_ground(d);
    write_ply(
        &d.join("ball.ply"),
        &sphere(Vec3::new(0.5, 0.0, 4.0), 0.5, 8, 16),
    );
    let scene = top_down(
        72,
        0.5,
        0.5,
        Vec3::new(0.2, 0.3, 1.0),
        "[[mesh]]\nfile = \"ground.ply\"\nshadow_catcher = true\n[[mesh]]\nfile = \"ball.ply\"\nholdout = true\n[environment]\nradiance = 0.2\n",
    )
    .replace("max_bounces = 1", "max_bounces = 64");
    std::fs::write(d.join("s.toml"), scene).unwrap();
}

/// A render with meshes killed by SIGKILL once a checkpoint is down and
/// resumed gives the uninterrupted render's bits, the Shadow Catcher pass
/// included (its sums are part of the state).
#[test]
fn a_killed_render_with_meshes_resumes_to_the_same_bits() {
    let dir = common::tempdir();
    let d = dir.path();
    ground_and_ball(d);
    for integrator in ["path", "photon"] {
        let args = |out: &str| -> Vec<String> {
            [
                "render",
                "s.toml",
                "--integrator",
                integrator,
                "--spp",
                "64",
                "-o",
                out,
                "--no-preview",
                "--threads",
                "2",
                "--aovs",
            ]
            .iter()
            .map(|s| s.to_string())
            .collect()
        };
        let whole = render(
            d,
            "s.toml",
            &[
                "--integrator",
                integrator,
                "--spp",
                "64",
                "-o",
                "whole.exr",
                "--aovs",
            ],
        );
        let mut a = args("killed.exr");
        a.extend(["--checkpoint".into(), "0.05s".into()]);
        let mut child = Command::new(BIN)
            .current_dir(d)
            .args(&a)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        let state = vdbphoton::render::resume::state_path(&d.join("killed.exr"));
        let t = std::time::Instant::now();
        while !state.exists() && t.elapsed().as_secs() < 60 {
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        child.kill().unwrap();
        child.wait().unwrap();
        assert!(state.exists(), "{integrator}: no checkpoint");
        a.push("--resume".into());
        let refs: Vec<&str> = a.iter().map(|s| s.as_str()).collect();
        let r = run(d, &refs);
        assert_eq!(r.code, 0, "{}", r.stderr);
        assert!(r.stderr.contains("resumed"), "{integrator}: {}", r.stderr);
        let resumed = read_exr(d.join("killed.exr")).unwrap().0;
        assert_eq!(resumed.pixels(), whole.pixels(), "{integrator}");
        for layer in ["shadow_catcher", "diffuse_direct", "glossy_indirect"] {
            assert_eq!(
                resumed.layer(layer).unwrap().data(),
                whole.layer(layer).unwrap().data(),
                "{integrator}: {layer}"
            );
        }
    }
}

/// Blender's smoke + fire frame over a shadow-catcher ground behind a
/// holdout ball (`tests/data/cycles/smoke25_shot.toml`), motion-blurred
/// and denoised, renders with both integrators: every pixel and pass
/// finite, alpha in [0, 1], the pass 1 above the horizon, and the
/// denoiser's layers there (needs `VDBPHOTON_REAL_DATA` and, for the
/// denoising, Open Image Denoise).
#[test]
fn the_smoke_shot_renders_blurred_and_denoised() {
    let Some(data) = common::real_data() else {
        eprintln!("skipped: no VDBPHOTON_REAL_DATA");
        return;
    };
    let denoise = vdbphoton::denoise::Oidn::load(1).is_ok();
    let dir = common::tempdir();
    let d = dir.path();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cycles");
    let text = std::fs::read_to_string(root.join("smoke25_shot.toml"))
        .unwrap()
        .replace("../../../../shared/data", data.to_str().unwrap())
        .replace(
            "smoke25_shot_meshes/",
            &format!("{}/smoke25_shot_meshes/", root.display()),
        )
        .replace(
            "film_transparent = true",
            "film_transparent = true\nmotion_blur = true",
        );
    std::fs::write(d.join("s.toml"), text).unwrap();
    for integrator in ["path", "photon"] {
        let mut args = vec![
            "--integrator",
            integrator,
            "--spp",
            "8",
            "--width",
            "100",
            "--height",
            "75",
            "-o",
            "o.exr",
        ];
        if denoise {
            args.push("--denoise");
        }
        let img = render(d, "s.toml", &args);
        let pass = img.layer("shadow_catcher").unwrap();
        for y in 0..75 {
            for x in 0..100 {
                let c = img.get(x, y);
                assert!(
                    c.is_finite() && (0.0..=1.0).contains(&c.w),
                    "{integrator} ({x}, {y}) {c}"
                );
                assert!(pass.get(x, y).iter().all(|v| v.is_finite() && *v >= 0.0));
            }
        }
        assert_eq!(pass.get(50, 0), &[1.0, 1.0, 1.0], "{integrator}: the sky");
        if denoise {
            assert!(img.layer("noisy").is_some() && img.layer("albedo").is_some());
        }
    }
}

/// Vertex normals and texture coordinates are read where the file has
/// them: PLY's `nx ny nz` and `s t` (Blender's names), OBJ's `vn` and `vt`
/// (a vertex whose corners differ is split); a file without them has
/// none.
#[test]
fn normals_and_texture_coordinates_are_read() {
    let dir = common::tempdir();
    let d = dir.path();
    std::fs::write(
        d.join("a.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float s\nproperty float t\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 0 0 1 0 0\n1 0 0 0 0.6 0.8 1 0\n0 1 0 0.6 0 0.8 0 1\n3 0 1 2\n",
    )
    .unwrap();
    let m = mesh::read(&d.join("a.ply")).unwrap();
    assert_eq!(
        m.normals,
        vec![Vec3::Z, Vec3::new(0.0, 0.6, 0.8), Vec3::new(0.6, 0.0, 0.8)]
    );
    assert_eq!(m.uvs, vec![glam::Vec2::ZERO, glam::Vec2::X, glam::Vec2::Y]);
    std::fs::write(
        d.join("a.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nvn 0 0 1\nvn 0 0 -1\nf 1/1/1 2/2/1 3/3/1\nf 2/2/2 4/4/2 3/3/2\n",
    )
    .unwrap();
    let m = mesh::read(&d.join("a.obj")).unwrap();
    assert_eq!(m.triangles.len(), 2);
    assert_eq!(m.normals.len(), m.positions.len());
    assert_eq!(m.uvs.len(), m.positions.len());
    for (t, n) in m.triangles.iter().zip([Vec3::Z, -Vec3::Z]) {
        for &i in t {
            assert_eq!(m.normals[i as usize], n);
            let p = m.positions[i as usize];
            assert_eq!(m.uvs[i as usize], glam::Vec2::new(p.x, p.y));
        }
    }
    write_ply(
        &d.join("b.ply"),
        &quad([Vec3::ZERO, Vec3::X, Vec3::ONE, Vec3::Y]),
    );
    let m = mesh::read(&d.join("b.ply")).unwrap();
    assert!(m.normals.is_empty() && m.uvs.is_empty());
}
