//! `auto` decides by measuring (`vdbphoton::render::auto`): the error its
//! pilots estimate from their halves against the closed form of an
//! integrator of known noise, the fall of the error with passes, the
//! prediction and the choice, the picks it makes at once (nothing
//! scatters, no light), the rule for denoised images, and the choice on
//! scenes where one integrator is far ahead.

use glam::{DAffine3, Vec3};
use vdbphoton::camera::Camera;
use vdbphoton::film::SampleResult;
use vdbphoton::integrator::{Integrator, SampleKey};
use vdbphoton::light::{Environment, Light};
use vdbphoton::medium::{ExtraGrids, Material, Media, Volume};
use vdbphoton::phase::PhaseFunction;
use vdbphoton::ray::Ray;
use vdbphoton::render::auto::{decide, measure, Horizon, Measured};
use vdbphoton::render::choose_integrator;
use vdbphoton::sampling::{Domain, Rng};
use vdbphoton::scene::{SceneDesc, SceneFormat};
use vdbphoton::world::World;
use vdbphoton::{generate, Rgb};

const W: u32 = 64;
const H: u32 = 48;

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

/// The cloud shrunk to a tenth about its centre: a hot core.
fn core(m: Material) -> Volume {
    let g = generate::cloud(32, 3).unwrap();
    let (lo, hi) = cloud(raw(1.0, 0.0, 0.0)).world_bounds();
    let c = (0.5 * (lo + hi)).as_dvec3();
    Volume::new(
        "core",
        g,
        ExtraGrids::default(),
        m,
        DAffine3::from_translation(c)
            * DAffine3::from_scale(glam::DVec3::splat(0.1))
            * DAffine3::from_translation(-c),
    )
    .unwrap()
}

fn raw(sigma_a: f32, sigma_s: f32, emission: f32) -> Material {
    Material::Raw {
        sigma_a: Rgb::splat(sigma_a),
        sigma_s: Rgb::splat(sigma_s),
        emission: Rgb::splat(emission),
        phase: PhaseFunction::hg(0.3),
    }
}

/// The render settings `choose_integrator` reads (the volume's file is
/// never opened: the world is made here).
fn desc(denoise: bool) -> SceneDesc {
    SceneDesc::from_str(
        &format!(
            "[render]\nwidth = {W}\nheight = {H}\nspp = 256\nseed = 3\nmax_bounces = 1024\ndenoise = {denoise}\n[camera]\nposition = [0, -4, 0]\nlook_at = [0, 0, 0]\n[[volume]]\nfile = \"cloud.vdb\"\n"
        ),
        SceneFormat::Toml,
        "/s",
    )
    .unwrap()
}

/// A stand-in integrator of known noise: every sample is `mean` plus a
/// normal deviate of standard deviation `sigma` · (pass + 1)^(`growth`/2)
/// (a variance growing as pass^growth, as a progressive photon map's
/// does while its kernels shrink), so that the mean of n passes has the
/// variance σ² Σ k^growth / n² ∝ n^−(1 − growth).
struct Noise {
    mean: f32,
    sigma: f32,
    growth: f32,
}

impl Integrator for Noise {
    fn name(&self) -> &'static str {
        "noise"
    }
    fn li(&self, _world: &World, _ray: &Ray, _rng: &mut Rng, key: SampleKey) -> SampleResult {
        let mut rng = key.rng(Domain::Guide);
        let (u1, u2) = (rng.next_f32().max(1e-7), rng.next_f32());
        let normal = (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos();
        let s = self.sigma * ((key.index + 1) as f32).powf(self.growth / 2.0);
        SampleResult {
            l: Rgb::splat(self.mean + s * normal),
            ..SampleResult::default()
        }
    }
}

/// The pilots' error from their halves is the relative MSE of their mean:
/// samples of variance σ² around m give σ²/n / (m² + 0.01) after n passes
/// (σ small against m, so that the estimate's own m in the denominator
/// adds no bias worth the name)
/// (a missing /4 on the halves' squared difference gives 4x, a variance
/// of one half instead of the mean's 2x); the error of independent passes
/// falls as 1/n, that of passes whose variance grows as pass^0.4 (a
/// progressive photon map's) as the discrete sum says (n^−0.6 in the
/// limit).
#[test]
fn pilots_estimate_their_error_from_their_halves() {
    let w = world(vec![], vec![], Rgb::ZERO);
    let (mean, sigma) = (0.5f32, 0.05f32);
    let mut flat = Noise {
        mean,
        sigma,
        growth: 0.0,
    };
    let mut growing = Noise {
        mean,
        sigma,
        growth: 0.4,
    };
    let m = measure(
        &w,
        vec![
            ("flat", &mut flat as &mut dyn Integrator),
            ("growing", &mut growing as &mut dyn Integrator),
        ],
        5,
        Horizon::Passes(400),
    );
    let flat = &m[0];
    let n = flat.passes as f64;
    assert!(n >= 4.0 && flat.passes.is_multiple_of(2), "{flat:?}");
    let want = (sigma as f64).powi(2) / n / ((mean as f64).powi(2) + 0.01);
    // All 48 x 64 pixels (4 x 3 tiles, fewer than the least a pilot takes),
    // each channel the same deviate: the estimate's own spread is about
    // √(2 / 3072) of it.
    assert!(
        (flat.rel_mse / want - 1.0).abs() < 0.15,
        "estimated {} against σ²/n/(m² + 0.01) = {want}",
        flat.rel_mse
    );
    assert!(
        (flat.exponent - 1.0).abs() < 0.1,
        "the error of independent passes fell as n^-{}",
        flat.exponent
    );
    // The growing variance's mean after n passes: σ² Σ_{k ≤ n} k^0.4 / n²,
    // so between n/2 and n passes (n even) the error falls by
    // 2^exponent, exponent → 0.6 as n grows.
    let g = &m[1];
    let var = |n: u32| (1..=n).map(|k| (k as f64).powf(0.4)).sum::<f64>() / (n as f64).powi(2);
    let n = g.passes;
    let half = 2 * (n / 4).max(1);
    let exact = (var(half) / var(n)).ln() / (n as f64 / half as f64).ln();
    assert!(
        (g.exponent - exact).abs() < 0.12,
        "the error fell as n^-{} over {n} passes (want n^-{exact})",
        g.exponent
    );
    // Predictions follow the measured fall.
    let t = 100.0 * g.seconds_per_pass;
    let p = g.predicted(t);
    let by_hand = g.rel_mse * (g.passes as f64 / 100.0).powf(g.exponent);
    assert!((p / by_hand - 1.0).abs() < 1e-9, "{p} against {by_hand}");
}

/// The pilots' pixels are an even lattice: one in eight of each row, the
/// columns cycling row by row, so every column and every row is sampled
/// alike.
#[test]
fn pilot_pixels_cover_the_frame_evenly() {
    use vdbphoton::render::auto::{pilot_pixels, PILOT_STRIDE};
    let (w, h) = (160u32, 120u32);
    let p = pilot_pixels(w, h);
    assert_eq!(p.len() as u32, w * h / PILOT_STRIDE);
    let mut columns = vec![0u32; w as usize];
    let mut rows = vec![0u32; h as usize];
    for &(x, y) in &p {
        assert!(x < w && y < h);
        columns[x as usize] += 1;
        rows[y as usize] += 1;
    }
    assert!(rows.iter().all(|&n| n == w / PILOT_STRIDE), "{rows:?}");
    assert!(
        columns.iter().all(|&n| n == h / PILOT_STRIDE),
        "{columns:?}"
    );
}

/// The choice is the lower predicted error at the horizon, whatever the
/// order, and the header line gives each candidate's figures.
#[test]
fn the_lower_predicted_error_wins() {
    let m = |name, rel_mse, exponent, seconds_per_pass| Measured {
        name,
        passes: 8,
        rel_mse,
        rel_mse_half: rel_mse * 2f64.powf(exponent),
        exponent,
        seconds_per_pass,
        seconds: 0.1,
    };
    // Equal error per pass, the photon passes 4x dearer: the path tracer.
    let a = [m("path", 1e-3, 1.0, 0.1), m("photon", 1e-3, 1.0, 0.4)];
    assert_eq!(decide(&a, Horizon::Seconds(10.0)).0, "path");
    // A tenth of the error per pass at 4x the cost: photons.
    let b = [m("path", 1e-3, 1.0, 0.1), m("photon", 1e-4, 1.0, 0.4)];
    let (name, why) = decide(&b, Horizon::Seconds(10.0));
    assert_eq!(name, "photon");
    assert!(
        why.contains("path: 8 pilot passes") && why.contains("photon"),
        "{why}"
    );
    let rev = [b[1].clone(), b[0].clone()];
    assert_eq!(decide(&rev, Horizon::Passes(100)).0, "photon");
    // A slower fall loses over a long render what it wins in a short one:
    // 3x ahead at the pilot, falling as n^-0.5 against n^-1.
    let c = [m("path", 3e-3, 1.0, 0.1), m("photon", 1e-3, 0.5, 0.1)];
    assert_eq!(decide(&c, Horizon::Passes(16)).0, "photon");
    assert_eq!(decide(&c, Horizon::Passes(1000)).0, "path");
}

/// What `auto` picks without a pilot, and what it measures for.
#[test]
fn auto_picks_at_once_only_when_there_is_nothing_to_measure() {
    let sun = || vec![Light::sun(Vec3::Z, Rgb::ONE, 0.0)];
    let horizon = Horizon::Passes(64);
    // Nothing scatters (a thick absorber, a fire of pure emission, an
    // empty volume): the path tracer at once.
    for (what, m) in [
        ("absorber", raw(15.0, 0.0, 0.0)),
        ("pure emission", raw(0.5, 0.0, 2.0)),
        ("empty", raw(0.0, 0.0, 0.0)),
    ] {
        let w = world(vec![cloud(m)], sun(), Rgb::ZERO);
        let (name, why) = choose_integrator(&desc(false), &w, horizon).unwrap();
        assert_eq!(name, "path", "{what}");
        assert!(
            why.contains("nothing scatters") && why.contains("at once"),
            "{what}: {why}"
        );
    }
    // No light at all.
    let dark = world(vec![cloud(raw(0.002, 20.0, 0.0))], vec![], Rgb::ZERO);
    let (name, why) = choose_integrator(&desc(false), &dark, horizon).unwrap();
    assert_eq!(name, "path");
    assert!(why.contains("no light") && why.contains("at once"), "{why}");
    // Denoised: the path tracer unless the volumes glow and scatter it.
    let dense_sun = world(vec![cloud(raw(0.002, 40.0, 0.0))], sun(), Rgb::ZERO);
    let (name, why) = choose_integrator(&desc(true), &dense_sun, horizon).unwrap();
    assert_eq!(name, "path", "{why}");
    assert!(why.contains("denoised"), "{why}");
    let fire = world(vec![cloud(raw(0.2, 15.0, 1.0))], vec![], Rgb::ZERO);
    let (name, why) = choose_integrator(&desc(true), &fire, horizon).unwrap();
    assert_eq!(name, "photon", "{why}");
    // Otherwise the pilots measure, and the header says so.
    let (_, why) = choose_integrator(&desc(false), &dense_sun, horizon).unwrap();
    assert!(
        why.contains("measured on pilots") && why.contains("pilot passes"),
        "{why}"
    );
}

/// Where one integrator is far ahead the pilots find it: a dense cloud
/// under sky light alone, where photon mapping's error at equal time was
/// 11-21x the path tracer's on the benchmark set, and a small glowing core
/// inside a scattering cloud, whose light the path tracer finds only when
/// a path happens to hit the core. Measured once on this world (64 x 48,
/// 10 s, 2 threads, seeds 1 and 2): the path tracer's relative MSE against
/// a 60 s path-traced render 2.1e-2 (its error hardly falls: the 60 s
/// render has about a sixth of it), photon mapping's 5.6e-3 against the
/// same render and 5.7e-4 against a 60 s photon render.
#[test]
fn auto_finds_the_integrator_far_ahead() {
    let sky = world(vec![cloud(raw(0.002, 40.0, 0.0))], vec![], Rgb::splat(0.5));
    let (name, why) = choose_integrator(&desc(false), &sky, Horizon::Seconds(4.0)).unwrap();
    eprintln!("dense cloud under a sky: {why}");
    assert_eq!(name, "path", "{why}");
    let fire = world(
        vec![cloud(raw(0.002, 15.0, 0.0)), core(raw(3.0, 0.0, 3000.0))],
        vec![],
        Rgb::ZERO,
    );
    let (name, why) = choose_integrator(&desc(false), &fire, Horizon::Seconds(10.0)).unwrap();
    eprintln!("glowing core in a cloud: {why}");
    assert_eq!(name, "photon", "{why}");
}
