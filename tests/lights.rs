//! Lights: point and spot single scattering against numerical quadrature,
//! a finite sun against the delta sun, and the environment map's importance
//! sampling (χ² against its pdf, normalisation, a furnace lit by a map).

mod common;

use common::chi2::chi2_test_with;
use glam::{DAffine3, Vec2, Vec3};
use vdbphoton::camera::Camera;
use vdbphoton::integrator::{self, Settings};
use vdbphoton::light::{EnvMap, Environment, Light};
use vdbphoton::medium::{ExtraGrids, Material, Media, Volume};
use vdbphoton::phase::PhaseFunction;
use vdbphoton::world::World;
use vdbphoton::Rgb;

const SA: f32 = 0.2;
const SS: f32 = 0.6;

fn box_world(lights: Vec<Light>, env: Environment, g: f32) -> World {
    let m = Material::Raw {
        sigma_a: Rgb::splat(SA),
        sigma_s: Rgb::splat(SS),
        emission: Rgb::ZERO,
        phase: PhaseFunction::hg(g),
    };
    let v = Volume::new(
        "box",
        common::unit_box_grid(),
        ExtraGrids::default(),
        m,
        DAffine3::IDENTITY,
    )
    .unwrap();
    World {
        camera: Camera::new(Vec3::new(-6.0, 0.0, 0.0), Vec3::ZERO, Vec3::Z, 0.2, 5, 5),
        lights,
        environment: env,
        media: Media::new(vec![v]),
        warnings: vec![],
        load_seconds: 0.0,
    }
}

/// Length of the segment p→q inside [-1, 1]^3.
fn length_in_box(p: Vec3, q: Vec3) -> f32 {
    let d = q - p;
    let len = d.length();
    let dir = d / len;
    let inv = dir.recip();
    let t1 = (Vec3::splat(-1.0) - p) * inv;
    let t2 = (Vec3::splat(1.0) - p) * inv;
    let t0 = t1.min(t2).max_element().max(0.0);
    let t3 = t1.max(t2).min_element().min(len);
    (t3 - t0).max(0.0)
}

/// Single scattering along the camera's centre ray (+x through the box
/// centre) from a light at `pos` with intensity `intensity(dir from light)`.
fn single_scattering_quadrature(pos: Vec3, g: f32, intensity: impl Fn(Vec3) -> f32) -> f32 {
    let st = SA + SS;
    let n = 20_000;
    let mut sum = 0.0f64;
    for i in 0..n {
        let x = -1.0 + 2.0 * (i as f32 + 0.5) / n as f32;
        let p = Vec3::new(x, 0.0, 0.0);
        let to_light = pos - p;
        let r2 = to_light.length_squared();
        let wi = to_light / r2.sqrt();
        let wo = -Vec3::X;
        let t_cam = (-st * (x + 1.0)).exp();
        let t_light = (-st * length_in_box(p, pos)).exp();
        let li = intensity(-wi) / r2;
        sum +=
            (SS * vdbphoton::phase::henyey_greenstein(wo.dot(wi), g) * li * t_cam * t_light) as f64;
    }
    (sum * 2.0 / n as f64) as f32
}

fn render_centre(world: &World, spp: u32) -> f32 {
    let settings = Settings {
        width: 5,
        height: 5,
        spp,
        seed: 11,
        max_bounces: 1,
    };
    integrator::render_pixel(world, &settings, 2, 2).0[0].x
}

#[test]
fn point_light_single_scattering() {
    let pos = Vec3::new(0.3, -0.4, 2.5);
    let world = box_world(
        vec![Light::Point {
            position: pos,
            intensity: Rgb::splat(10.0),
        }],
        Environment::Constant(Rgb::ZERO),
        0.3,
    );
    let want = single_scattering_quadrature(pos, 0.3, |_| 10.0);
    let got = render_centre(&world, 20_000);
    assert!(
        (got / want - 1.0).abs() < 0.02,
        "point light: {got} vs {want}"
    );
}

#[test]
fn spot_light_single_scattering_with_blend() {
    // A spot above the box aimed at (0.4, 0, 0): the camera ray crosses its
    // soft edge, so the cone and the blend both matter.
    let pos = Vec3::new(0.0, 0.0, 3.0);
    let target = Vec3::new(0.4, 0.0, 0.0);
    let axis = (target - pos).normalize();
    let (cone, blend) = (30.0f32, 0.4f32);
    let spot = Light::spot(pos, axis, Rgb::splat(20.0), cone, blend);
    let world = box_world(vec![spot], Environment::Constant(Rgb::ZERO), 0.0);
    let cos_half = (cone.to_radians() * 0.5).cos();
    let smooth = (1.0 - cos_half) * blend;
    let want = single_scattering_quadrature(pos, 0.0, |d| {
        let c = d.dot(axis);
        if c <= cos_half {
            return 0.0;
        }
        let t = c - cos_half;
        let f = if t < smooth {
            let x = t / smooth;
            x * x * (3.0 - 2.0 * x)
        } else {
            1.0
        };
        20.0 * f
    });
    assert!(want > 0.0);
    let got = render_centre(&world, 20_000);
    assert!(
        (got / want - 1.0).abs() < 0.02,
        "spot light: {got} vs {want}"
    );
}

#[test]
fn finite_sun_matches_delta_sun_for_isotropic_scattering() {
    // Same irradiance: a disk of 8° gives the same single scattering as the
    // delta sun to within the small change of path lengths (< 0.5 %).
    let delta = box_world(
        vec![Light::sun(Vec3::Z, Rgb::splat(3.0), 0.0)],
        Environment::Constant(Rgb::ZERO),
        0.0,
    );
    let disk = box_world(
        vec![Light::sun(Vec3::Z, Rgb::splat(3.0), 8.0)],
        Environment::Constant(Rgb::ZERO),
        0.0,
    );
    let a = render_centre(&delta, 20_000);
    let b = render_centre(&disk, 20_000);
    assert!(
        (b / a - 1.0).abs() < 0.02,
        "finite sun {b} vs delta sun {a}"
    );
    // A ray that escapes towards the disk sees E / (π sin²(θ/2)).
    let sun = Light::sun(Vec3::Z, Rgb::splat(3.0), 8.0);
    let (le, pdf) = sun.le_escaped(Vec3::Z);
    let s = (4.0f32).to_radians().sin();
    assert!((le.x - 3.0 / (std::f32::consts::PI * s * s)).abs() < 1e-3 * le.x);
    assert!(pdf > 0.0);
    assert_eq!(sun.le_escaped(Vec3::new(0.0, 0.2, 1.0).normalize()).1, 0.0);
}

/// A 64x32 map with a bright spot, a gradient and a dark band.
fn test_map(rotate: f32) -> EnvMap {
    let (w, h) = (64, 32);
    let mut t = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let mut v = 0.2 + (x as f32 / w as f32);
            if (20..24).contains(&x) && (8..11).contains(&y) {
                v += 40.0;
            }
            if y > 24 {
                v *= 0.05;
            }
            t.push(Rgb::new(v, v * 0.8, v * 0.6));
        }
    }
    EnvMap::new(w, h, t, rotate)
}

#[test]
fn environment_map_sampling_matches_its_pdf() {
    for rotate in [0.0, 33.0] {
        let env = Environment::Map(Box::new(test_map(rotate)));
        let r = chi2_test_with(
            200_000,
            32,
            32,
            64,
            |i| {
                let mut rng = vdbphoton::sampling::Rng::new(
                    vdbphoton::sampling::Domain::Test,
                    4,
                    4,
                    i as u64,
                );
                env.sample(rng.next_vec2()).map(|(w, _, _)| w)
            },
            |w| env.pdf(w) as f64,
        );
        assert!(
            r.p_value > 1e-3,
            "rotate {rotate}: χ² {} dof {} p {}",
            r.statistic,
            r.dof,
            r.p_value
        );
        // The pdf integrates to 1 over the sphere and agrees with sample().
        let n = 400_000;
        let mut sum = 0.0f64;
        for i in 0..n {
            let mut rng = vdbphoton::sampling::Rng::new(vdbphoton::sampling::Domain::Test, 5, 5, i);
            let w = vdbphoton::sampling::sample_uniform_sphere(rng.next_vec2());
            sum += env.pdf(w) as f64 * 4.0 * std::f64::consts::PI;
        }
        assert!(
            (sum / n as f64 - 1.0).abs() < 0.02,
            "∫pdf = {}",
            sum / n as f64
        );
        for i in 0..1000 {
            let mut rng = vdbphoton::sampling::Rng::new(vdbphoton::sampling::Domain::Test, 6, 6, i);
            let (w, le, pdf) = env.sample(rng.next_vec2()).unwrap();
            assert!(
                (pdf - env.pdf(w)).abs() <= 1e-3 * pdf,
                "pdf {pdf} vs {}",
                env.pdf(w)
            );
            assert!((le - env.le(w)).abs().max_element() <= 1e-4 * le.max_element().max(1.0));
        }
    }
}

#[test]
fn environment_map_orientation_is_blenders() {
    // Blender's equirectangular mapping, as a Cycles 5.0.1 render of a map
    // whose texels encode their own coordinates shows it: the centre of
    // the image (u = 0.5) faces +X, u = 0.25 faces +Y; the top row is +Z.
    let (w, h) = (8, 4);
    let mut t = vec![Rgb::ZERO; w * h];
    t[w + 4] = Rgb::splat(1.0); // row 1 (above the horizon), u ∈ [0.5, 0.625)
    t[w * 2 + 6] = Rgb::splat(2.0); // row 2 (below), u ∈ [0.75, 0.875)
    let env = Environment::Map(Box::new(EnvMap::new(w, h, t, 0.0)));
    // az = atan2(y, x), u = 0.5 − az/(2π): u ∈ [0.5, 0.625) ↔ az ∈ (−π/4, 0].
    let dir = |az: f32, el: f32| Vec3::new(az.cos() * el.cos(), az.sin() * el.cos(), el.sin());
    assert_eq!(env.le(dir(-0.3, 0.3)).x, 1.0);
    assert_eq!(
        env.le(dir(-(std::f32::consts::FRAC_PI_2 + 0.3), -0.3)).x,
        2.0
    );
    assert_eq!(env.le(dir(-0.3, -0.3)).x, 0.0);
    assert_eq!(env.le(dir(0.3, 0.3)).x, 0.0);
    // +Y is at u = 0.25 (column 2 from just past it).
    let mut t = vec![Rgb::ZERO; w * h];
    for y in 0..h {
        t[y * w + 2] = Rgb::ONE;
    }
    let env = Environment::Map(Box::new(EnvMap::new(w, h, t, 0.0)));
    assert_eq!(env.le(dir(std::f32::consts::FRAC_PI_2 - 0.1, 0.1)).x, 1.0);
    assert_eq!(env.le(dir(-std::f32::consts::FRAC_PI_2, 0.1)).x, 0.0);
}

#[test]
fn furnace_under_a_uniform_map() {
    // Albedo 1 and a map of constant radiance 1 (importance sampling of a
    // flat map): every pixel is 1.
    let map = EnvMap::new(16, 8, vec![Rgb::ONE; 128], 10.0);
    let m = Material::Raw {
        sigma_a: Rgb::ZERO,
        sigma_s: Rgb::splat(6.0),
        emission: Rgb::ZERO,
        phase: PhaseFunction::hg(-0.4),
    };
    let v = Volume::new(
        "box",
        common::unit_box_grid(),
        ExtraGrids::default(),
        m,
        DAffine3::IDENTITY,
    )
    .unwrap();
    let world = World {
        camera: Camera::new(Vec3::new(0.5, -4.0, 0.3), Vec3::ZERO, Vec3::Z, 40.0, 6, 6),
        lights: vec![],
        environment: Environment::Map(Box::new(map)),
        media: Media::new(vec![v]),
        warnings: vec![],
        load_seconds: 0.0,
    };
    let settings = Settings {
        width: 6,
        height: 6,
        spp: 512,
        seed: 2,
        max_bounces: 100_000,
    };
    let rgb = integrator::render(&world, &settings, &|_, _| {}).mean_rgb();
    for (i, p) in rgb.iter().enumerate() {
        assert!((p.x - 1.0).abs() < 0.08, "pixel {i}: {p}");
    }
    let mean: f32 = rgb.iter().map(|p| p.x).sum::<f32>() / rgb.len() as f32;
    assert!((mean - 1.0).abs() < 0.01, "mean {mean}");
    let _ = Vec2::ZERO;
}
