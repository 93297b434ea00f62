//! The photon integrator against the reference path tracer and closed
//! forms: a white furnace, the σs factor of the estimate in a box and a
//! large sphere (a doubled or missing σs fails), overlapping emissive
//! volumes (emission counted once), small scenes of thin and dense media
//! under a sun, a spot, a point light, a constant environment, an
//! environment map and with blackbody emission (converged relative MSE
//! below a bound, and falling with the passes), point and beam estimates
//! on the same photon maps compared per block of pixels, and the same
//! image on one and two threads.

mod common;

use glam::{DAffine3, Vec3};
use vdbphoton::camera::Camera;
use vdbphoton::film::{Film, Region};
use vdbphoton::integrator::photon::{Estimate, PhotonSettings, Sky};
use vdbphoton::integrator::{Integrator, PathIntegrator, PhotonIntegrator};
use vdbphoton::light::{EnvMap, Environment, Light};
use vdbphoton::medium::{ExtraGrids, Material, Media, Principled, Volume};
use vdbphoton::phase::PhaseFunction;
use vdbphoton::render::passes::render_pass;
use vdbphoton::world::World;
use vdbphoton::{generate, Rgb};

const W: u32 = 24;
const H: u32 = 18;

fn raw(sigma_a: f32, sigma_s: f32, g: f32) -> Material {
    Material::Raw {
        sigma_a: Rgb::splat(sigma_a),
        sigma_s: Rgb::splat(sigma_s),
        emission: Rgb::ZERO,
        phase: PhaseFunction::hg(g),
    }
}

fn world(volumes: Vec<Volume>, lights: Vec<Light>, env: Rgb) -> World {
    World {
        camera: Camera::new(Vec3::new(0.3, -3.6, 0.6), Vec3::ZERO, Vec3::Z, 42.0, W, H),
        lights,
        environment: Environment::Constant(env),
        media: Media::new(volumes),
        warnings: vec![],
        shapes: vdbphoton::shape::Shapes::empty(),
        surfaces: Vec::new(),
        film_transparent: false,
        load_seconds: 0.0,
    }
}

fn cloud(m: Material) -> Volume {
    Volume::new(
        "cloud",
        generate::cloud(32, 3).unwrap(),
        ExtraGrids::default(),
        m,
        DAffine3::IDENTITY,
    )
    .unwrap()
}

fn settings(photons: u32) -> PhotonSettings {
    PhotonSettings {
        photons: Some(photons),
        ..PhotonSettings::default()
    }
}

/// Runs `passes` passes of `integrator` with camera seed `seed`, calling
/// `each` with the film after each one.
fn run(
    world: &World,
    integrator: &mut dyn Integrator,
    seed: u64,
    passes: u32,
    aovs: bool,
    mut each: impl FnMut(u32, &Film),
) -> Film {
    let mut film = Film::new(W, H, Region::full(W, H), aovs);
    for p in 0..passes {
        integrator.begin_pass(world, p);
        render_pass(world, integrator, &mut film, seed, p, &|_, _| {});
        each(p + 1, &film);
    }
    film
}

fn path_reference(world: &World, spp: u32, max_bounces: u32) -> Film {
    run(
        world,
        &mut PathIntegrator::new(max_bounces),
        77,
        spp,
        true,
        |_, _| {},
    )
}

/// Relative MSE as the shared reference defines it: mean over pixels and
/// channels of (a − b)² / (b² + 0.01).
fn rel_mse(a: &[Rgb], b: &[Rgb]) -> f64 {
    let mut s = 0.0f64;
    for (x, y) in a.iter().zip(b) {
        for c in 0..3 {
            let (x, y) = (x[c] as f64, y[c] as f64);
            s += (x - y) * (x - y) / (y * y + 0.01);
        }
    }
    s / (3 * a.len()) as f64
}

fn mean(v: &[Rgb]) -> f64 {
    v.iter().map(|c| c.element_sum() as f64).sum::<f64>() / (3 * v.len()) as f64
}

/// Least-squares slope of log(y) against log(x).
fn log_slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (lx, ly): (Vec<f64>, Vec<f64>) = points.iter().map(|(x, y)| (x.ln(), y.ln())).unzip();
    let mx = lx.iter().sum::<f64>() / n;
    let my = ly.iter().sum::<f64>() / n;
    let cov: f64 = lx.iter().zip(&ly).map(|(x, y)| (x - mx) * (y - my)).sum();
    let var: f64 = lx.iter().map(|x| (x - mx) * (x - mx)).sum();
    cov / var
}

#[test]
fn white_furnace() {
    // A non-absorbing cloud in a uniform environment of radiance 1: every
    // pixel is exactly 1, whatever the density. Photons carry the sky's
    // light here (`sky = "photons"`); `white_furnace_with_sky_paths` has
    // camera paths carry it.
    white_furnace_of(Sky::Photons, 24);
}

#[test]
fn white_furnace_with_sky_paths() {
    // The default for a constant sky: camera paths carry its light and the
    // march the background it sees. Counting the sky twice (photons from it as well,
    // or the paths adding what the camera ray sees before it scatters)
    // makes the cloud brighter than 1; a path that missed the light of its
    // later bounces, darker.
    white_furnace_of(Sky::Auto, 64);
}

/// [`white_furnace`] with `sky` carrying the sky's light, `passes` passes:
/// four independent renders give each pixel's noise; every pixel's mean
/// must be within 5 standard errors of 1 (plus 1 % for the kernel's bias at
/// the cloud's edges), and the image mean within 0.5 %. A pixel's variance
/// is pooled over its 3x3 neighbourhood, leaving out neighbours with none
/// (the sky beside the cloud, exactly 1 in every render), which would
/// otherwise make an edge pixel's noise look smaller than it is.
fn white_furnace_of(sky: Sky, passes: u32) {
    let w = world(vec![cloud(raw(0.0, 12.0, 0.5))], vec![], Rgb::ONE);
    let render = |seed| {
        let s = PhotonSettings {
            sky,
            ..settings(20_000)
        };
        let mut ph = PhotonIntegrator::new(&w, s, 100_000, seed).unwrap();
        let film = run(&w, &mut ph, seed, passes, false, |_, _| {}).mean_rgb();
        // No photons at all when the paths carry the only source, and
        // then every sample traces one.
        let want = if sky == Sky::Photons { 0.0 } else { 1.0 };
        assert_eq!(ph.sky_share(), want);
        film
    };
    let renders: Vec<Vec<Rgb>> = (1..=4).map(render).collect();
    let n = renders.len() as f32;
    let mean_at = |i: usize| renders.iter().map(|r| r[i].x).sum::<f32>() / n;
    // Unbiased sample variance of one render at pixel i.
    let var_at = |i: usize| {
        let m = mean_at(i);
        renders.iter().map(|r| (r[i].x - m).powi(2)).sum::<f32>() / (n - 1.0)
    };
    let se_at = |i: usize| {
        let (x, y) = ((i % W as usize) as i32, (i / W as usize) as i32);
        let mut s = 0.0;
        let mut k = 0.0;
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (u, v) = (x + dx, y + dy);
                if u >= 0 && v >= 0 && u < W as i32 && v < H as i32 {
                    let var = var_at((v * W as i32 + u) as usize);
                    if var > 0.0 {
                        s += var;
                        k += 1.0;
                    }
                }
            }
        }
        if k == 0.0 {
            0.0
        } else {
            (s / k / n).sqrt()
        }
    };
    let mut worst: f32 = 0.0;
    for i in 0..(W * H) as usize {
        let (m, se) = (mean_at(i), se_at(i));
        worst = worst.max((m - 1.0).abs() / (5.0 * se + 0.01));
        assert!(
            (m - 1.0).abs() <= 5.0 * se + 0.01,
            "pixel {i}: {m} ± {se} is not 1"
        );
    }
    let m = renders.iter().map(|r| mean(r)).sum::<f64>() / renders.len() as f64;
    assert!((m - 1.0).abs() < 0.005, "image mean {m}");
    assert!(worst > 0.0);
}

#[test]
fn multiple_scattering_carries_sigma_s_once() {
    // A box of σs = 4, albedo 0.8, under a sun: the light that scattered
    // more than once (the `indirect` AOV) from the photon map against the
    // path tracer's. Multiplying the photon estimate by σs again would
    // make it 4x, leaving σs out of the stored power 5/4x.
    let volumes = || {
        vec![Volume::new(
            "box",
            common::unit_box_grid(),
            ExtraGrids::default(),
            raw(1.0, 4.0, 0.0),
            DAffine3::from_scale(glam::DVec3::splat(0.6)),
        )
        .unwrap()]
    };
    let sun = || vec![Light::sun(Vec3::new(-0.3, -0.5, 1.0), Rgb::splat(3.0), 0.0)];
    let w = world(volumes(), sun(), Rgb::ZERO);
    let reference = path_reference(&w, 1024, 256);
    let mut ph = PhotonIntegrator::new(&w, settings(40_000), 256, 2).unwrap();
    let photon = run(&w, &mut ph, 2, 16, true, |_, _| {});
    let indirect = |f: &Film| {
        let img = f.to_image().unwrap();
        let l = img.layer("indirect").unwrap();
        l.data().iter().map(|&v| v as f64).sum::<f64>() / l.data().len() as f64
    };
    let (a, b) = (indirect(&photon), indirect(&reference));
    assert!(
        b > 0.01,
        "the box must scatter much light more than once: {b}"
    );
    assert!(
        (a / b - 1.0).abs() < 0.05,
        "indirect {a} against the path tracer's {b}"
    );
    let (ma, mb) = (mean(&photon.mean_rgb()), mean(&reference.mean_rgb()));
    assert!((ma / mb - 1.0).abs() < 0.03, "image mean {ma} against {mb}");
}

/// The mean over the image of an AOV layer of `film` (made with AOVs).
fn layer_mean(film: &Film, name: &str) -> f64 {
    let img = film.to_image().unwrap();
    let l = img.layer(name).unwrap();
    l.data().iter().map(|&v| v as f64).sum::<f64>() / l.data().len() as f64
}

#[test]
fn overlapping_emissive_volumes_emit_once() {
    // Two identical emissive boxes on top of each other (each σa = 0.5,
    // σs = 2, emission 1 per unit length) are one box of σa = 1, σs = 4,
    // emission 2. Photons from the media carry the emission of the volume
    // whose cell emitted them: taking the sum over all volumes there counts
    // the overlap twice. The emission they deliver after scattering is in
    // the `emission` AOV with the emission the march sees directly; it is
    // compared with the path tracer's on the single box.
    let emissive = |sa: f32, ss: f32, e: f32| {
        let m = Material::Raw {
            sigma_a: Rgb::splat(sa),
            sigma_s: Rgb::splat(ss),
            emission: Rgb::splat(e),
            phase: PhaseFunction::hg(0.3),
        };
        Volume::new(
            "box",
            common::unit_box_grid(),
            ExtraGrids::default(),
            m,
            DAffine3::from_scale(glam::DVec3::splat(0.6)),
        )
        .unwrap()
    };
    let two = world(
        vec![emissive(0.5, 2.0, 1.0), emissive(0.5, 2.0, 1.0)],
        vec![],
        Rgb::ZERO,
    );
    let one = world(vec![emissive(1.0, 4.0, 2.0)], vec![], Rgb::ZERO);
    let reference = layer_mean(&path_reference(&one, 256, 256), "emission");
    // The part seen without scattering (what the march computes itself).
    let unscattered = layer_mean(&path_reference(&one, 64, 0), "emission");
    let photon = |w: &World| {
        let mut ph = PhotonIntegrator::new(w, settings(20_000), 256, 3).unwrap();
        layer_mean(&run(w, &mut ph, 3, 8, true, |_, _| {}), "emission")
    };
    let (a, b) = (photon(&two), photon(&one));
    eprintln!(
        "emission: two boxes {a:.4}, one box {b:.4}, path tracer {reference:.4} \
         (of which unscattered {unscattered:.4})"
    );
    // Measured (8 passes of 20,000 photons): two boxes 0.1783, one box
    // 0.1784, the path tracer 0.1832 (256 spp), of which 0.0677 unscattered:
    // the photons carry the other 63 %. Counting the overlap twice gave
    // 0.2889 for the two boxes (the unscattered part plus twice the
    // scattered one, 0.2987, less the photon estimate's bias). The photon
    // images are 2.7 % below the path tracer's, the kernel's blur at the
    // boxes' faces (32 passes: 1.8 %), the same for both worlds.
    assert!(
        unscattered < 0.5 * reference,
        "most of the emission must reach the camera through photons: {unscattered} of {reference}"
    );
    assert!(
        (a / b - 1.0).abs() < 0.02,
        "two overlapping boxes {a} against one box of their sum {b}"
    );
    for (name, x) in [("two overlapping boxes", a), ("one box", b)] {
        assert!(
            (x / reference - 1.0).abs() < 0.05,
            "{name}: emission {x} against the path tracer's {reference}"
        );
    }
}

/// The mean of AOV `name` over blocks of `bw` x `bh` pixels, row-major.
fn block_means(film: &Film, name: &str, bw: u32, bh: u32) -> Vec<f64> {
    let img = film.to_image().unwrap();
    let layer = img.layer(name).unwrap();
    let (nx, ny) = (W / bw, H / bh);
    let mut out = vec![0.0f64; (nx * ny) as usize];
    for y in 0..ny * bh {
        for x in 0..nx * bw {
            let v = layer.get(x as usize, y as usize);
            out[((y / bh) * nx + x / bw) as usize] +=
                v.iter().map(|&c| c as f64).sum::<f64>() / v.len() as f64;
        }
    }
    for v in &mut out {
        *v /= (bw * bh) as f64;
    }
    out
}

#[test]
fn multiple_scattering_in_a_large_sphere_carries_sigma_s_once() {
    // A homogeneous ball of radius 1 (σs = 4, σa = 0.4, HG g = 0.5, 4.4
    // mean free paths to its centre) under a sun: most of what the camera
    // sees has scattered more than once. The `indirect` AOV of the photon
    // integrator (two seeds) against the path tracer's (two halves): the
    // estimate is Σ p·Φ / V with Φ after the collision's weight, which is
    // σs·L_s already. Multiplying it by σs again makes it 4x (+300 %),
    // dividing by σs 1/4x (−75 %), storing the power before the
    // collision's weight σs/σt 1.1x (+10 %).
    let ball = Volume::new(
        "ball",
        common::ball_grid(1.0, 32),
        ExtraGrids::default(),
        raw(0.4, 4.0, 0.5),
        DAffine3::IDENTITY,
    )
    .unwrap();
    let sun = vec![Light::sun(Vec3::new(-0.3, -0.5, 1.0), Rgb::splat(3.0), 0.0)];
    let w = world(vec![ball], sun, Rgb::ZERO);
    let path = |seed| {
        run(
            &w,
            &mut PathIntegrator::new(256),
            seed,
            1024,
            true,
            |_, _| {},
        )
    };
    let photon = |seed| {
        let mut ph = PhotonIntegrator::new(&w, settings(40_000), 256, seed).unwrap();
        run(&w, &mut ph, seed, 16, true, |_, _| {})
    };
    let (ra, rb, pa, pb) = (path(77), path(78), photon(2), photon(3));
    let m = |a: &Film, b: &Film| (layer_mean(a, "indirect") + layer_mean(b, "indirect")) * 0.5;
    let (reference, estimate) = (m(&ra, &rb), m(&pa, &pb));
    let direct = layer_mean(&ra, "direct");
    eprintln!("ball: indirect {estimate:.5} against the path tracer's {reference:.5} (direct {direct:.5})");
    // Measured: indirect 0.04050 against 0.04076 (−0.6 %; the two photon
    // seeds differ by 1.1 %, the path tracer's halves by 0.15 %); the
    // direct light is 0.0103.
    assert!(
        reference > 2.0 * direct,
        "the ball must scatter most light more than once: {reference} against {direct}"
    );
    assert!(
        (estimate / reference - 1.0).abs() < 0.03,
        "indirect {estimate} against the path tracer's {reference}"
    );
    // Per block of 4x3 pixels, where the block holds at least a quarter of
    // the brightest block's light (11 of the 36): within 4 standard errors
    // of the difference (the half differences of each pair, pooled over
    // those blocks as relative errors: 2.0 % measured) plus 4 % for the
    // kernel's blur across the image (measured deviations up to 3.8 %).
    let blocks = |f: &Film| block_means(f, "indirect", 4, 3);
    let (bra, brb, bpa, bpb) = (blocks(&ra), blocks(&rb), blocks(&pa), blocks(&pb));
    let brightest = bra.iter().zip(&brb).map(|(a, b)| a + b).fold(0.0, f64::max) * 0.5;
    let bright: Vec<usize> = (0..bra.len())
        .filter(|&i| (bra[i] + brb[i]) * 0.5 >= 0.25 * brightest)
        .collect();
    assert!(bright.len() >= 8, "too few bright blocks: {bright:?}");
    let rel_var = bright
        .iter()
        .map(|&i| {
            let (r, p) = ((bra[i] + brb[i]) * 0.5, (bpa[i] + bpb[i]) * 0.5);
            ((bra[i] - brb[i]) * 0.5 / r).powi(2) + ((bpa[i] - bpb[i]) * 0.5 / p).powi(2)
        })
        .sum::<f64>()
        / bright.len() as f64;
    let se = rel_var.sqrt();
    let mut worst = 0.0f64;
    for &i in &bright {
        let (r, p) = ((bra[i] + brb[i]) * 0.5, (bpa[i] + bpb[i]) * 0.5);
        let dev = (p / r - 1.0).abs();
        worst = worst.max(dev);
        assert!(
            dev < 4.0 * se + 0.04,
            "block {i}: indirect {p} against the path tracer's {r} (standard error {se})"
        );
    }
    eprintln!(
        "ball: {} blocks, relative standard error {se:.4}, worst deviation {worst:.4}",
        bright.len()
    );
}

/// A case of the comparison with the path tracer: the world, the max
/// bounces, and the bound on the relative MSE after 32 passes of 40,000
/// photons, beyond the reference's own noise.
struct Case {
    name: &'static str,
    world: World,
    max_bounces: u32,
    bound: f64,
    /// Who carries the environment's light, and the share of camera
    /// samples that trace it then (`PhotonIntegrator::sky_share`).
    sky: (Sky, f32),
}

fn cases() -> Vec<Case> {
    let sun = || {
        vec![Light::sun(
            Vec3::new(-0.4, -0.5, 0.75),
            Rgb::splat(2.0),
            0.0,
        )]
    };
    let fire = Material::Principled(Principled {
        density: 6.0,
        blackbody_intensity: 1.0,
        temperature: 1800.0,
        ..Principled::DEFAULT
    });
    let fire_volume = {
        let d = generate::cloud(32, 4).unwrap();
        let t = d.map_values("temperature", |v| v * 1.2).unwrap();
        Volume::new(
            "fire",
            d,
            ExtraGrids {
                temperature: Some(t),
                ..Default::default()
            },
            fire,
            DAffine3::IDENTITY,
        )
        .unwrap()
    };
    let sky_only = || {
        world(
            vec![cloud(raw(0.3, 12.0, 0.5))],
            vec![],
            Rgb::new(0.8, 0.9, 1.0),
        )
    };
    vec![
        Case {
            name: "thin, isotropic, sun and sky",
            world: world(vec![cloud(raw(0.5, 3.0, 0.0))], sun(), Rgb::splat(0.1)),
            max_bounces: 64,
            bound: 2e-3,
            sky: (Sky::Auto, 1.0),
        },
        Case {
            name: "dense, g = 0.8, sun and sky",
            world: world(vec![cloud(raw(0.1, 40.0, 0.8))], sun(), Rgb::splat(0.1)),
            max_bounces: 1024,
            bound: 1e-2,
            sky: (Sky::Auto, 0.5),
        },
        Case {
            name: "spot light",
            world: world(
                vec![cloud(raw(0.5, 10.0, 0.3))],
                vec![Light::spot(
                    Vec3::new(-2.0, -2.0, 2.0),
                    Vec3::new(1.0, 1.0, -1.0),
                    Rgb::splat(40.0),
                    40.0,
                    0.2,
                )],
                Rgb::ZERO,
            ),
            max_bounces: 256,
            bound: 4e-3,
            sky: (Sky::Auto, 0.0),
        },
        Case {
            name: "environment only",
            world: sky_only(),
            max_bounces: 256,
            bound: 2e-3,
            sky: (Sky::Auto, 1.0),
        },
        Case {
            name: "environment only, photons carry it",
            world: sky_only(),
            max_bounces: 256,
            bound: 2e-3,
            sky: (Sky::Photons, 0.0),
        },
        Case {
            name: "blackbody fire",
            world: world(vec![fire_volume], vec![], Rgb::ZERO),
            max_bounces: 64,
            bound: 4e-3,
            sky: (Sky::Auto, 0.0),
        },
    ]
}

/// Renders `case` with the path tracer (two halves of 1024 spp) and 32
/// passes of 40,000 photons, and checks the photon image's relative MSE
/// beyond the reference's noise, the slope of its error over the passes
/// and its mean.
fn check_convergence(case: &Case) {
    let w = &case.world;
    // The reference in two independent halves: a quarter of their
    // relative MSE against each other is the reference's own noise,
    // taken off the photon image's error.
    let half = |seed| {
        run(
            w,
            &mut PathIntegrator::new(case.max_bounces),
            seed,
            1024,
            false,
            |_, _| {},
        )
        .mean_rgb()
    };
    let (ra, rb) = (half(77), half(78));
    let reference: Vec<Rgb> = ra.iter().zip(&rb).map(|(a, b)| (*a + *b) * 0.5).collect();
    let noise = rel_mse(&ra, &rb) / 4.0;
    assert!(mean(&reference) > 1e-3, "{}: a black image", case.name);
    let s = PhotonSettings {
        sky: case.sky.0,
        ..settings(40_000)
    };
    let mut ph = PhotonIntegrator::new(w, s, case.max_bounces, 9).unwrap();
    let mut errors = Vec::new();
    let last = run(w, &mut ph, 9, 32, false, |p, f| {
        if p.is_power_of_two() {
            errors.push((p as f64, rel_mse(&f.mean_rgb(), &reference)));
        }
    })
    .mean_rgb();
    assert_eq!(
        ph.sky_share(),
        case.sky.1,
        "{}: sky paths' share",
        case.name
    );
    let e = rel_mse(&last, &reference) - noise;
    let slope = log_slope(&errors);
    let ratio = mean(&last) / mean(&reference);
    eprintln!(
        "{}: relMSE {e:.2e} beyond the reference's noise {noise:.1e} (bound {:.0e}), slope {slope:.2}, mean ratio {ratio:.4}, errors {errors:?}",
        case.name, case.bound
    );
    assert!(
        e < case.bound,
        "{}: relMSE {e} above {}",
        case.name,
        case.bound
    );
    assert!(
        slope < -0.3,
        "{}: the error does not fall with passes: {errors:?}",
        case.name
    );
    assert!(
        (ratio - 1.0).abs() < 0.02,
        "{}: image mean ratio {ratio}",
        case.name
    );
}

#[test]
fn converges_to_the_path_tracer() {
    for case in cases() {
        check_convergence(&case);
    }
}

/// A 32x16 sky: a small bright sun 45° up behind the cloud as the camera
/// sees it (azimuth 65°-88°), a sky brighter towards the zenith and a dark
/// ground.
fn sky_map() -> EnvMap {
    let (w, h) = (32, 16);
    let mut t = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let mut c = if y < h / 2 {
                Rgb::new(0.3, 0.45, 0.8) * (1.0 - y as f32 / h as f32)
            } else {
                Rgb::splat(0.05)
            };
            if (10..12).contains(&x) && (3..5).contains(&y) {
                c += Rgb::new(60.0, 55.0, 45.0);
            }
            t.push(c);
        }
    }
    EnvMap::new(w, h, t, 20.0)
}

#[test]
fn converges_to_the_path_tracer_under_a_point_light_and_a_map() {
    // The lights the cases above leave out: a point light beside the
    // cloud (photons aimed at the cone around the volumes) and an
    // importance-sampled environment map with a bright sun in it.
    let mut map_world = world(vec![cloud(raw(0.3, 12.0, 0.5))], vec![], Rgb::ZERO);
    map_world.environment = Environment::Map(Box::new(sky_map()));
    let cases = [
        Case {
            name: "point light",
            world: world(
                vec![cloud(raw(0.5, 10.0, 0.3))],
                vec![Light::Point {
                    position: Vec3::new(-1.6, -1.4, 1.5),
                    intensity: Rgb::splat(20.0),
                }],
                Rgb::ZERO,
            ),
            max_bounces: 256,
            // Measured 7.0e-4, slope −0.96, mean ratio 0.984.
            bound: 2e-3,
            sky: (Sky::Auto, 0.0),
        },
        Case {
            name: "environment map",
            world: map_world,
            max_bounces: 256,
            // Measured 1.7e-3, slope −0.85, mean ratio 0.989.
            bound: 4e-3,
            sky: (Sky::Auto, 0.0),
        },
    ];
    for case in &cases {
        check_convergence(case);
    }
}

#[test]
fn point_and_beam_estimates_agree() {
    // The same photon maps (same seed and pass numbers), gathered by beams
    // and by point queries at every march step, with the camera close on
    // the cloud: the multiple scattering (`indirect`) they see agrees per
    // block of 2x2 pixels within their noise and the difference of their
    // kernels. Each estimate is rendered with two seeds; a block's standard
    // error is that of the difference of the two means (the half
    // differences of each pair, pooled over the block's 3x3 neighbourhood).
    let mut w = world(
        vec![cloud(raw(0.2, 15.0, 0.3))],
        vec![Light::sun(Vec3::new(0.2, -0.6, 0.8), Rgb::splat(2.0), 0.0)],
        Rgb::ZERO,
    );
    w.camera = Camera::new(
        Vec3::new(0.3, -3.6, 0.6),
        Vec3::new(-0.07, 0.0, 0.07),
        Vec3::Z,
        18.0,
        W,
        H,
    );
    let film = |estimate, seed| {
        let mut ph = PhotonIntegrator::new(
            &w,
            PhotonSettings {
                estimate,
                ..settings(40_000)
            },
            256,
            seed,
        )
        .unwrap();
        run(&w, &mut ph, seed, 16, true, |_, _| {})
    };
    let (ba, bb) = (film(Estimate::Beam, 4), film(Estimate::Beam, 5));
    let (pa, pb) = (film(Estimate::Point, 4), film(Estimate::Point, 5));
    let (beam, point) = (
        (layer_mean(&ba, "indirect") + layer_mean(&bb, "indirect")) * 0.5,
        (layer_mean(&pa, "indirect") + layer_mean(&pb, "indirect")) * 0.5,
    );
    let blocks = |f: &Film| block_means(f, "indirect", 2, 2);
    let (ba, bb, pa, pb) = (blocks(&ba), blocks(&bb), blocks(&pa), blocks(&pb));
    let (nx, ny) = ((W / 2) as i32, (H / 2) as i32);
    let var = |i: usize| ((ba[i] - bb[i]) * 0.5).powi(2) + ((pa[i] - pb[i]) * 0.5).powi(2);
    let brightest = ba.iter().zip(&bb).map(|(a, b)| a + b).fold(0.0, f64::max) * 0.5;
    let (mut z2, mut n, mut worst) = (0.0f64, 0usize, 0.0f64);
    for i in 0..ba.len() {
        let (b, p) = ((ba[i] + bb[i]) * 0.5, (pa[i] + pb[i]) * 0.5);
        if b < 0.05 * brightest {
            continue;
        }
        let (x, y) = (i as i32 % nx, i as i32 / nx);
        let (mut s, mut k) = (0.0, 0.0);
        for v in (y - 1).max(0)..=(y + 1).min(ny - 1) {
            for u in (x - 1).max(0)..=(x + 1).min(nx - 1) {
                s += var((v * nx + u) as usize);
                k += 1.0;
            }
        }
        let se = (s / k).sqrt();
        let z = (p - b) / se;
        z2 += z * z;
        n += 1;
        worst = worst.max((p - b).abs() / (4.0 * se + 0.03 * b));
        assert!(
            (p - b).abs() <= 4.0 * se + 0.03 * b,
            "block {i}: point {p} against beam {b}, standard error {se}"
        );
    }
    let z2 = z2 / n as f64;
    eprintln!(
        "point and beam: indirect {point:.5} and {beam:.5}, {n} blocks, mean z² {z2:.3}, worst {worst:.3} of the bound"
    );
    // Measured: indirect 0.1086 (point) and 0.1070 (beam), +1.5 %; 75
    // blocks hold light, with relative standard errors of 7 % (the seeds'
    // photon maps, shared by both estimates, dominate them), mean z² 0.2
    // and the largest deviation 0.4 of its bound. Independent estimates
    // would give a mean z² of 1; 2 allows for the kernels' difference, and
    // a bias of one estimate of 10 % in the bright blocks exceeds it.
    assert!(n >= 50, "too few blocks hold light: {n}");
    assert!(z2 < 2.0, "mean z² {z2} of the blocks");
    assert!(beam > 1e-3);
    assert!(
        (point / beam - 1.0).abs() < 0.03,
        "beam {beam}, point {point}"
    );
}

#[test]
fn same_image_on_one_and_two_threads() {
    let w = world(
        vec![cloud(raw(0.2, 15.0, 0.6))],
        vec![Light::sun(Vec3::new(0.2, -0.6, 0.8), Rgb::splat(2.0), 0.0)],
        Rgb::splat(0.1),
    );
    let render = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let mut ph = PhotonIntegrator::new(&w, settings(5_000), 256, 11).unwrap();
                run(&w, &mut ph, 11, 3, true, |_, _| {})
            })
    };
    let (a, b) = (render(1), render(2));
    assert!(a == b, "the films differ between one and two threads");
    assert!(mean(&a.mean_rgb()) > 0.0);
}

/// The pilot measures the media's scattering order, and the automatic
/// settings follow it: a photon in a medium of albedo 0 scatters exactly
/// once (its collision is its end), a dense bright cloud gets the dense
/// tuning, a thin one the thin tuning, and a key the scene gives is kept.
#[test]
fn tuning_follows_the_scattering_order() {
    use vdbphoton::integrator::photon::{Tuning, DENSE_ORDER};
    use vdbphoton::photon::{self, emitter::Emitters, Store};
    let sun = || vec![Light::sun(Vec3::new(0.3, -0.4, 1.0), Rgb::ONE, 0.0)];
    let order = |w: &World| {
        let e = Emitters::new(w).unwrap();
        let (_, st) = photon::trace(w, &e, 4000, 5, 0, 0.0, 1024, Store::ALL);
        st.order()
    };
    let black = world(vec![cloud(raw(3.0, 0.0, 0.0))], sun(), Rgb::ZERO);
    assert_eq!(order(&black), 1.0);
    let dense = world(vec![cloud(raw(0.01, 60.0, 0.8))], sun(), Rgb::ZERO);
    let thin = world(vec![cloud(raw(0.05, 0.3, 0.3))], sun(), Rgb::ZERO);
    let (od, ot) = (order(&dense), order(&thin));
    assert!(od >= 2.0 * DENSE_ORDER, "dense cloud: order {od}");
    assert!(ot < 0.5 * DENSE_ORDER, "thin cloud: order {ot}");
    let attribute = |w: &World, s: PhotonSettings| {
        let mut integ = PhotonIntegrator::new(w, s, 1024, 3).unwrap();
        integ.begin_pass(w, 0);
        let a = integ.attributes();
        let get = |k: &str| a.iter().find(|(n, _)| n == k).unwrap().1.clone();
        (
            get("vdbphoton/k"),
            get("vdbphoton/alpha"),
            get("vdbphoton/angular_kernel"),
        )
    };
    // Only dense media blur the photons' directions (their error is the
    // variance; a thin medium's is the bias).
    const { assert!(Tuning::DENSE.angular < 1.0) };
    let d = Tuning::DENSE;
    let t = Tuning::THIN;
    assert_eq!(
        attribute(&dense, settings(4000)),
        (d.k.to_string(), d.alpha.to_string(), d.angular.to_string())
    );
    assert_eq!(
        attribute(&thin, settings(4000)),
        (t.k.to_string(), t.alpha.to_string(), "1".to_string())
    );
    let given = PhotonSettings {
        k: Some(40),
        ..settings(4000)
    };
    assert_eq!(
        attribute(&dense, given),
        ("40".to_string(), d.alpha.to_string(), d.angular.to_string())
    );
}

/// Photons from glowing media start where the emission is, in proportion
/// to it down to about a voxel: their mean power is the media's emitted
/// power 4π·∫ε dV (a closed form for trilinear lookups: the sum of the
/// voxels' values times a voxel's volume), and their spread is small even
/// where the emission falls by orders of magnitude within a majorant cell,
/// as fire's does. A photon from a uniform point of its cell (the cell
/// chosen by its mean) carries a power that varies with the emission there:
/// E[Φ²]/E[Φ]² was 7.0 on this volume, 1.19 with boxes of a voxel.
#[test]
fn media_photons_carry_the_emitted_power_evenly() {
    use glam::IVec3;
    use vdbphoton::grid::{Grid, GridParts};
    use vdbphoton::photon::emitter::Emitters;
    use vdbphoton::sampling::{Domain, Rng};
    let scale = 0.1;
    let xf = DAffine3::from_scale(glam::DVec3::splat(scale));
    let mut parts = GridParts::new("density", 0.0f32, xf);
    let mut sum = 0.0f64;
    for b in 0..8 {
        let origin = IVec3::new(b & 1, (b >> 1) & 1, b >> 2) * 8;
        let mut mask = [0u64; 8];
        for v in 0..512usize {
            let ijk = origin + IVec3::new((v >> 6) as i32, ((v >> 3) & 7) as i32, (v & 7) as i32);
            let r = (ijk.as_vec3() - Vec3::splat(7.5)).length() / 7.0;
            let value = 100.0 * (1.0 - r).max(0.0).powi(8);
            if value > 0.0 {
                mask[v >> 6] |= 1 << (v & 63);
            }
            parts.values.push(value);
            sum += value as f64;
        }
        parts.brick_origins.push(origin);
        parts.masks.push(mask);
    }
    let grid = Grid::from_parts(parts).unwrap();
    let emission = 0.7;
    let material = Material::Raw {
        sigma_a: Rgb::splat(0.5),
        sigma_s: Rgb::splat(0.5),
        emission: Rgb::splat(emission),
        phase: PhaseFunction::Isotropic,
    };
    let fire = Volume::new(
        "fire",
        grid,
        ExtraGrids::default(),
        material,
        DAffine3::IDENTITY,
    )
    .unwrap();
    let w = world(vec![fire], vec![], Rgb::ZERO);
    let exact = 4.0 * std::f64::consts::PI * emission as f64 * sum * scale.powi(3);
    let e = Emitters::new(&w).unwrap();
    let n = 200_000;
    let (mut s1, mut s2) = (0.0f64, 0.0f64);
    for i in 0..n {
        let mut rng = Rng::new(Domain::Photon, 9, 0, i);
        if let Some(ph) = e.sample(&w, 0.0, &mut rng) {
            assert!(ph.from_media);
            let p = ph.ray.power.x as f64;
            s1 += p;
            s2 += p * p;
        }
    }
    let mean = s1 / n as f64;
    let spread = s2 / n as f64 / (mean * mean);
    let sigma = (spread - 1.0).max(0.0).sqrt() * mean / (n as f64).sqrt();
    assert!(
        (mean - exact).abs() < 4.0 * sigma + 1e-3 * exact,
        "mean power {mean} against {exact} (σ {sigma})"
    );
    assert!(spread < 1.5, "E[Φ²]/E[Φ]² = {spread}");
}

/// Cycles 5's new phase functions through both integrators: a thin slab
/// (z in [−h, h], optical depth 2hσt = 0.02 straight through) of Cycles'
/// Mie medium (20 µm droplets) and of Fournier–Forand (B 0.1, IOR 1.33),
/// lit from below by a sun 35° off the vertical and seen from straight
/// above through a 1° lens, so that its light reaches the camera scattered
/// by 35°. Single scattering in closed form: along the camera ray, t
/// below the top face, the sun's light has crossed (2h − t)/cos 35° of the
/// slab, so L = σs·p(35°)·E·e^{−2hσt/cos 35°}·(1 − e^{−2ha})/a with
/// a = σt(1 − 1/cos 35°). The path tracer's image mean lies within 4
/// standard errors of it (its passes' spread: most camera rays cross the
/// slab without a collision) plus 1.5 % for what scattered more than once
/// adds, the photon integrator's (single scattering marched, the rest
/// gathered from photons) within 3 %. p(35°) comes from the published
/// forms (Cycles' Mie fit with HG and Draine; Fournier & Jonasz 1999), not
/// from `eval`. Checked to fail with each function's lobe mirrored in
/// `eval` (its value at 145° instead: both integrators then give an
/// eighth of the closed form for Fournier–Forand, a fifteenth for Mie).
#[test]
fn thin_slab_of_cycles_phase_functions_matches_single_scattering() {
    let (sa, ss, h, e) = (0.1f32, 0.9f32, 0.01f32, 2.0f32);
    let st = sa + ss;
    let tilt = 35f32.to_radians();
    let to_sun = Vec3::new(tilt.sin(), 0.0, -tilt.cos());
    use std::f64::consts::PI;
    // Henyey–Greenstein and Draine in μ = cos θ, θ the deflection.
    let hg = |mu: f64, g: f64| (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5));
    let draine = |mu: f64, g: f64, a: f64| {
        hg(mu, g) * (1.0 + a * mu * mu) / (1.0 + a * (1.0 + 2.0 * g * g) / 3.0)
    };
    let published = |name: &str, mu: f64| {
        if name.starts_with("mie") {
            let m = vdbphoton::phase::mie_fit(20.0);
            let (g, gd, a, w) = (m.g_hg as f64, m.g_d as f64, m.alpha as f64, m.w_d as f64);
            (1.0 - w) * hg(mu, g) + w * draine(mu, gd, a)
        } else {
            // Fournier & Jonasz 1999, v from B = 0.1 at IOR 1.33.
            let (b, n) = (0.1f32 as f64, 1.33f32 as f64);
            let delta = |s: f64| 4.0 * s / (3.0 * (n - 1.0) * (n - 1.0));
            let d90 = delta(0.5);
            let v = -(1.0 + 2.0 * b * (d90 - 1.0)).ln() / d90.ln();
            let (s, d180) = ((1.0 - mu) / 2.0, delta(1.0));
            let (d, dv) = (delta(s), delta(s).powf(v));
            (v * (1.0 - d) - (1.0 - dv) + (d * (1.0 - dv) - v * (1.0 - d)) / s)
                / (4.0 * PI * (1.0 - d).powi(2) * dv)
                + (1.0 - d180.powf(v)) / (16.0 * PI * (d180 - 1.0) * d180.powf(v))
                    * (3.0 * mu * mu - 1.0)
        }
    };
    for (name, phase) in [
        ("mie 20 µm", PhaseFunction::mie(20.0)),
        ("fournier-forand", PhaseFunction::fournier_forand(0.1, 1.33)),
    ] {
        let slab = Volume::new(
            "slab",
            common::unit_box_grid(),
            ExtraGrids::default(),
            Material::Raw {
                sigma_a: Rgb::splat(sa),
                sigma_s: Rgb::splat(ss),
                emission: Rgb::ZERO,
                phase,
            },
            DAffine3::from_scale(glam::DVec3::new(4.0, 4.0, h as f64)),
        )
        .unwrap();
        let w = World {
            camera: Camera::new(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 1.0, W, H),
            lights: vec![Light::sun(to_sun, Rgb::splat(e), 0.0)],
            environment: Environment::Constant(Rgb::ZERO),
            media: Media::new(vec![slab]),
            warnings: vec![],
            shapes: vdbphoton::shape::Shapes::empty(),
            surfaces: Vec::new(),
            film_transparent: false,
            load_seconds: 0.0,
        };
        // The phase function at 35° from its published form, not from
        // `eval`, which the renders use.
        let p = published(name, (tilt as f64).cos()) as f32;
        let a = st * (1.0 - 1.0 / tilt.cos());
        let want = (ss * p * e * (-2.0 * h * st / tilt.cos()).exp() * (1.0 - (-2.0 * h * a).exp())
            / a) as f64;

        let passes = 1200;
        let mut cumulative = vec![];
        run(
            &w,
            &mut PathIntegrator::new(256),
            5,
            passes,
            false,
            |_, f| cumulative.push(mean(&f.mean_rgb())),
        );
        let per_pass: Vec<f64> = (0..cumulative.len())
            .map(|k| {
                let before = if k == 0 {
                    0.0
                } else {
                    k as f64 * cumulative[k - 1]
                };
                (k + 1) as f64 * cumulative[k] - before
            })
            .collect();
        let n = per_pass.len() as f64;
        let path = per_pass.iter().sum::<f64>() / n;
        let se = (per_pass.iter().map(|x| (x - path).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
        let mut ph = PhotonIntegrator::new(&w, settings(20_000), 256, 3).unwrap();
        let photon = mean(&run(&w, &mut ph, 4, 16, false, |_, _| {}).mean_rgb());
        eprintln!("{name}: closed form {want:.5}, path {path:.5} ± {se:.5}, photon {photon:.5}");
        assert!(
            (path - want).abs() < 4.0 * se + 0.015 * want,
            "{name}: path tracer {path} ± {se}, single scattering {want}"
        );
        assert!(
            (photon / want - 1.0).abs() < 0.03,
            "{name}: photon integrator {photon}, single scattering {want}"
        );
    }
}

/// The photon gather with Cycles 5's phase functions: in a box (σs 4,
/// albedo 0.8, 1.2 across) lit from behind by a sun, the light scattered
/// more than once (the `indirect` AOV), which the photon integrator
/// gathers from its photons weighted by the volume's phase function
/// (blurred by its angular kernel), against the path tracer's, for Mie
/// (2 µm droplets: an HG lobe of g 0.92 and a Draine lobe) and
/// Fournier–Forand (B 0.3, IOR 1.33). (Mie's 20 µm droplets, with an HG
/// lobe of g 0.995, make both estimates too noisy for a quick test.) The
/// photon estimate lies 3 to 5 % below the path tracer's here at 32
/// passes, as it does for HG(0.7) (−3 % at 128 passes: the kernels' bias
/// in a small box), hence 6 %. Checked to fail with `blurred` turning Mie or Fournier–Forand
/// isotropic (the fallback of a missing match arm) and with Mie's HG lobe
/// blurred to half its g.
#[test]
fn photon_gather_with_cycles_phase_functions_matches_the_path_tracer() {
    for (name, phase) in [
        ("mie 2 µm", PhaseFunction::mie(2.0)),
        ("fournier-forand", PhaseFunction::fournier_forand(0.3, 1.33)),
    ] {
        let volumes = || {
            vec![Volume::new(
                "box",
                common::unit_box_grid(),
                ExtraGrids::default(),
                Material::Raw {
                    sigma_a: Rgb::splat(1.0),
                    sigma_s: Rgb::splat(4.0),
                    emission: Rgb::ZERO,
                    phase,
                },
                DAffine3::from_scale(glam::DVec3::splat(0.6)),
            )
            .unwrap()]
        };
        let sun = || vec![Light::sun(Vec3::new(-0.3, 0.8, 0.6), Rgb::splat(3.0), 0.0)];
        let w = world(volumes(), sun(), Rgb::ZERO);
        let reference = path_reference(&w, 512, 256);
        let mut ph = PhotonIntegrator::new(&w, settings(40_000), 256, 2).unwrap();
        let photon = run(&w, &mut ph, 2, 32, true, |_, _| {});
        let (a, b) = (
            layer_mean(&photon, "indirect"),
            layer_mean(&reference, "indirect"),
        );
        eprintln!("{name}: indirect photon {a:.5}, path {b:.5}");
        assert!(b > 0.005, "{name}: too little multiple scattering: {b}");
        assert!(
            (a / b - 1.0).abs() < 0.06,
            "{name}: indirect {a} against the path tracer's {b}"
        );
    }
}
