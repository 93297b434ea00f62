//! The photon integrator against the reference path tracer and closed
//! forms: a white furnace, the σs factor of the estimate (a doubled or
//! missing σs fails), small scenes of thin and dense media under a sun, a
//! spot, an environment and with blackbody emission (converged relative
//! MSE below a bound, and falling with the passes), point and beam
//! estimates on the same photon maps, and the same image on one and two
//! threads.

mod common;

use glam::{DAffine3, Vec3};
use vdbphoton::camera::Camera;
use vdbphoton::film::{Film, Region};
use vdbphoton::integrator::{render_pass, Integrator, PathIntegrator, PhotonIntegrator};
use vdbphoton::light::{Environment, Light};
use vdbphoton::medium::{ExtraGrids, Material, Media, Principled, Volume};
use vdbphoton::phase::PhaseFunction;
use vdbphoton::scene::{Estimate, PhotonSettings};
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
        photons,
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
    // pixel is exactly 1, whatever the density. Two independent renders
    // give each pixel's noise: every pixel must be within 5 standard errors
    // of 1 (plus 1 % for the kernel's bias at the cloud's edges), and the
    // image mean within 0.5 %.
    let w = world(vec![cloud(raw(0.0, 12.0, 0.5))], vec![], Rgb::ONE);
    let render = |seed| {
        let mut ph = PhotonIntegrator::new(&w, settings(20_000), 100_000, seed).unwrap();
        run(&w, &mut ph, seed, 24, false, |_, _| {}).mean_rgb()
    };
    let (a, b) = (render(1), render(2));
    // A pixel's standard error: the half differences of the two renders,
    // pooled (root mean square) over its 3x3 neighbourhood.
    let half = |i: usize| ((a[i].x - b[i].x) * 0.5).powi(2);
    let se_at = |i: usize| {
        let (x, y) = ((i % W as usize) as i32, (i / W as usize) as i32);
        let mut s = 0.0;
        let mut n = 0.0;
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (u, v) = (x + dx, y + dy);
                if u >= 0 && v >= 0 && u < W as i32 && v < H as i32 {
                    s += half((v * W as i32 + u) as usize);
                    n += 1.0;
                }
            }
        }
        (s / n as f32).sqrt()
    };
    let mut worst: f32 = 0.0;
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        let m = (x.x + y.x) * 0.5;
        let se = se_at(i);
        worst = worst.max((m - 1.0).abs() / (5.0 * se + 0.01));
        assert!(
            (m - 1.0).abs() <= 5.0 * se + 0.01,
            "pixel {i}: {m} ± {se} is not 1"
        );
    }
    let m = (mean(&a) + mean(&b)) * 0.5;
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

/// A case of the comparison with the path tracer: the world, the max
/// bounces, and the bound on the relative MSE after 32 passes of 40,000
/// photons, beyond the reference's own noise.
struct Case {
    name: &'static str,
    world: World,
    max_bounces: u32,
    bound: f64,
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
    vec![
        Case {
            name: "thin, isotropic, sun and sky",
            world: world(vec![cloud(raw(0.5, 3.0, 0.0))], sun(), Rgb::splat(0.1)),
            max_bounces: 64,
            bound: 2e-3,
        },
        Case {
            name: "dense, g = 0.8, sun and sky",
            world: world(vec![cloud(raw(0.1, 40.0, 0.8))], sun(), Rgb::splat(0.1)),
            max_bounces: 1024,
            bound: 1e-2,
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
        },
        Case {
            name: "environment only",
            world: world(
                vec![cloud(raw(0.3, 12.0, 0.5))],
                vec![],
                Rgb::new(0.8, 0.9, 1.0),
            ),
            max_bounces: 256,
            bound: 2e-3,
        },
        Case {
            name: "blackbody fire",
            world: world(vec![fire_volume], vec![], Rgb::ZERO),
            max_bounces: 64,
            bound: 4e-3,
        },
    ]
}

#[test]
fn converges_to_the_path_tracer() {
    for case in cases() {
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
        let mut ph = PhotonIntegrator::new(w, settings(40_000), case.max_bounces, 9).unwrap();
        let mut errors = Vec::new();
        let last = run(w, &mut ph, 9, 32, false, |p, f| {
            if p.is_power_of_two() {
                errors.push((p as f64, rel_mse(&f.mean_rgb(), &reference)));
            }
        })
        .mean_rgb();
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
}

#[test]
fn point_and_beam_estimates_agree() {
    // The same photon maps (same seed and pass numbers), gathered by beams
    // and by point queries at every march step: the multiple scattering
    // they see agrees within their noise and the difference of kernels.
    let w = world(
        vec![cloud(raw(0.2, 15.0, 0.3))],
        vec![Light::sun(Vec3::new(0.2, -0.6, 0.8), Rgb::splat(2.0), 0.0)],
        Rgb::ZERO,
    );
    let indirect = |estimate| {
        let mut ph = PhotonIntegrator::new(
            &w,
            PhotonSettings {
                estimate,
                ..settings(20_000)
            },
            256,
            4,
        )
        .unwrap();
        let f = run(&w, &mut ph, 4, 8, true, |_, _| {});
        let img = f.to_image().unwrap();
        let l = img.layer("indirect").unwrap();
        l.data().iter().map(|&v| v as f64).sum::<f64>() / l.data().len() as f64
    };
    let (beam, point) = (indirect(Estimate::Beam), indirect(Estimate::Point));
    assert!(beam > 1e-3);
    assert!(
        (beam / point - 1.0).abs() < 0.04,
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

#[test]
fn auto_picks_photons_for_thick_media_and_paths_for_thin_ones() {
    use vdbphoton::render::choose_integrator;
    use vdbphoton::scene::Integrator as Choice;
    let sun = || vec![Light::sun(Vec3::Z, Rgb::ONE, 0.0)];
    let thick = world(vec![cloud(raw(0.2, 15.0, 0.3))], sun(), Rgb::ZERO);
    let thin = world(vec![cloud(raw(0.05, 0.3, 0.3))], sun(), Rgb::ZERO);
    assert_eq!(choose_integrator(&thick).0, Choice::Photon);
    assert_eq!(choose_integrator(&thin).0, Choice::Path);
}
