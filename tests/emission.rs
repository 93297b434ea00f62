//! Emission and media without a control medium, against closed forms: the
//! minorant must not turn scattering into absorption where there is no
//! control (emissive media, overlapping volumes of different albedo),
//! emission must be collected where σt = 0 (flame without smoke), a
//! fire-only volume must glow, and blackbody emission must be filtered per
//! voxel as Cycles' stochastic lookups average it.

mod common;

use common::{const_box, empty_grid, unit_box_grid};
use glam::{DAffine3, DVec3, IVec3, Vec3};
use vdbphoton::camera::Camera;
use vdbphoton::grid::{Grid, GridParts};
use vdbphoton::integrator::path;
use vdbphoton::light::{Environment, Light};
use vdbphoton::medium::{BlackbodyFilter, ExtraGrids, Material, Media, Principled, Volume};
use vdbphoton::phase::{henyey_greenstein, PhaseFunction};
use vdbphoton::ray::Ray;
use vdbphoton::sampling::{Domain, Rng};
use vdbphoton::world::World;
use vdbphoton::Rgb;

fn raw(sigma_a: f32, sigma_s: f32, emission: f32, phase: PhaseFunction) -> Material {
    Material::Raw {
        sigma_a: Rgb::splat(sigma_a),
        sigma_s: Rgb::splat(sigma_s),
        emission: Rgb::splat(emission),
        phase,
    }
}

fn volume(grid: Grid<f32>, extra: ExtraGrids, m: Material) -> Volume {
    Volume::new("test", grid, extra, m, DAffine3::IDENTITY).expect("a volume")
}

fn world(media: Media, lights: Vec<Light>) -> World {
    World {
        camera: Camera::new(Vec3::new(-5.0, 0.0, 0.0), Vec3::ZERO, Vec3::Z, 30.0, 8, 8),
        lights,
        environment: Environment::Constant(Rgb::ZERO),
        media,
        warnings: vec![],
        shapes: vdbphoton::shape::Shapes::empty(),
        surfaces: Vec::new(),
        film_transparent: false,
        load_seconds: 0.0,
    }
}

/// Mean and standard error per channel of `n` path samples along `o + t d`.
fn estimate(world: &World, o: Vec3, d: Vec3, n: u64, max_bounces: u32) -> (Rgb, Rgb) {
    let (mut s, mut s2) = ([0.0f64; 3], [0.0f64; 3]);
    for i in 0..n {
        let mut rng = Rng::new(Domain::Test, 17, 0, i);
        let l = path::trace(world, max_bounces, &Ray::new(o, d), &mut rng).l;
        for c in 0..3 {
            s[c] += l[c] as f64;
            s2[c] += (l[c] as f64).powi(2);
        }
    }
    let nf = n as f64;
    let mean = s.map(|v| v / nf);
    let se = [0, 1, 2].map(|c| ((s2[c] / nf - mean[c] * mean[c]).max(0.0) / (nf - 1.0)).sqrt());
    (
        Rgb::new(mean[0] as f32, mean[1] as f32, mean[2] as f32),
        Rgb::new(se[0] as f32, se[1] as f32, se[2] as f32),
    )
}

/// Asserts `got` agrees with `want` per channel within 4 standard errors
/// (plus `slack`, relative).
fn assert_close(what: &str, (got, se): (Rgb, Rgb), want: Rgb, slack: f32) {
    for c in 0..3 {
        let tol = 4.0 * se[c] + slack * want[c].abs() + 1e-6;
        assert!(
            (got[c] - want[c]).abs() <= tol,
            "{what}, channel {c}: {} ± {} against the closed form {}",
            got[c],
            se[c],
            want[c]
        );
    }
}

/// The unit box's majorant grid has a minorant equal to its majorant inside
/// (constant density): the condition under which a minorant subtracted
/// without a control medium loses light.
fn assert_minorant_inside(media: &Media) {
    let mut inside = 0;
    media.for_each_segment(Vec3::new(-3.0, 0.1, -0.2), Vec3::X, 0.0, 6.0, |s| {
        inside += (s.min_density > 0.0 && s.min_density == s.max_density) as u32;
        true
    });
    assert!(inside > 0, "the test needs cells with minorant = majorant");
}

#[test]
fn absorbing_emitting_box_with_a_minorant() {
    // σa = 1, emission 1 per unit length, no scattering, 2 units thick:
    // L = (1 − e^{−2}) / 1.
    let media = Media::new(vec![volume(
        unit_box_grid(),
        ExtraGrids::default(),
        raw(1.0, 0.0, 1.0, PhaseFunction::Isotropic),
    )]);
    assert!(media.control_albedo().is_none());
    assert_minorant_inside(&media);
    let w = world(media, vec![]);
    let est = estimate(&w, Vec3::new(-3.0, 0.1, -0.2), Vec3::X, 20_000, 64);
    assert_close(
        "absorbing, emitting box",
        est,
        Rgb::splat(1.0 - (-2.0f32).exp()),
        0.002,
    );
}

#[test]
fn scattering_emitting_box_along_the_camera_ray() {
    // σa = 1, σs = 1 (albedo 0.5), emission 1; with no scattering event
    // followed (max_bounces 0) the camera ray sees ∫ e^{−2t} dt over 2
    // units: (1 − e^{−4}) / 2.
    let media = Media::new(vec![volume(
        unit_box_grid(),
        ExtraGrids::default(),
        raw(1.0, 1.0, 1.0, PhaseFunction::hg(0.3)),
    )]);
    assert_minorant_inside(&media);
    let w = world(media, vec![]);
    let est = estimate(&w, Vec3::new(-3.0, 0.1, -0.2), Vec3::X, 20_000, 0);
    assert_close(
        "emitting box, albedo 0.5",
        est,
        Rgb::splat((1.0 - (-4.0f32).exp()) / 2.0),
        0.002,
    );
}

#[test]
fn emitting_scattering_furnace() {
    // Deep inside a homogeneous emitting medium every direction sees
    // L = emission / σa, whatever σs (the in-scattered light makes up for
    // the out-scattered): the box reaches 12 diffusion lengths from the
    // centre, so leakage is below 1e-6.
    let grid = const_box("density", 1.0, DVec3::splat(-6.0), 0.25, IVec3::splat(6));
    let media = Media::new(vec![volume(
        grid,
        ExtraGrids::default(),
        raw(1.0, 1.0, 1.0, PhaseFunction::hg(0.5)),
    )]);
    let w = world(media, vec![]);
    for d in [Vec3::X, Vec3::new(0.3, -0.8, 0.52).normalize()] {
        let est = estimate(&w, Vec3::new(0.05, -0.1, 0.2), d, 20_000, 100_000);
        assert_close("emitting furnace", est, Rgb::ONE, 0.002);
    }
}

#[test]
fn single_scattering_without_a_control_medium() {
    // The closed form of tests/transport.rs (sun straight down, camera ray
    // through the middle, one scattering event at most), with media that
    // have a minorant but no control: two overlapping boxes of different
    // albedo and phase (the analytic mixture adds σs·p), and one box that
    // also emits a little.
    let e = 3.0f32;
    let closed = |ss_p: f32, st: f32| ss_p * e * (-st).exp() * (1.0 - (-2.0 * st).exp()) / st;
    let sun = || vec![Light::sun(Vec3::Z, Rgb::splat(e), 0.0)];
    let o = Vec3::new(-4.0, 0.0, 0.0);

    let a = volume(
        unit_box_grid(),
        ExtraGrids::default(),
        raw(0.3, 0.7, 0.0, PhaseFunction::hg(0.5)),
    );
    let b = volume(
        unit_box_grid(),
        ExtraGrids::default(),
        raw(0.5, 0.2, 0.0, PhaseFunction::Isotropic),
    );
    let media = Media::new(vec![a, b]);
    assert!(media.control_albedo().is_none());
    assert_minorant_inside(&media);
    let want = closed(
        0.7 * henyey_greenstein(0.0, 0.5) + 0.2 / (4.0 * std::f32::consts::PI),
        1.7,
    );
    let est = estimate(&world(media, sun()), o, Vec3::X, 40_000, 1);
    assert_close(
        "two volumes of different albedo",
        est,
        Rgb::splat(want),
        0.003,
    );

    // An emissive box: what the sun adds to its own glow (which includes
    // glow scattered once) is the closed form.
    let emissive = || {
        Media::new(vec![volume(
            unit_box_grid(),
            ExtraGrids::default(),
            raw(0.3, 0.7, 0.05, PhaseFunction::hg(0.5)),
        )])
    };
    assert_minorant_inside(&emissive());
    let want = closed(0.7 * henyey_greenstein(0.0, 0.5), 1.0);
    let (lit, se_lit) = estimate(&world(emissive(), sun()), o, Vec3::X, 40_000, 1);
    let (dark, se_dark) = estimate(&world(emissive(), vec![]), o, Vec3::X, 40_000, 1);
    let se = (se_lit * se_lit + se_dark * se_dark).map(f32::sqrt);
    assert_close(
        "emissive box under a sun",
        (lit - dark, se),
        Rgb::splat(want),
        0.003,
    );
}

#[test]
fn colour_grid_scatters_as_its_colour() {
    // Principled Color 0.5 times a constant colour attribute c: σs = D·C·c,
    // σa = D·(1 − C·c), so σt = D in every channel; single scattering as
    // in the closed form above, per channel.
    let c = Vec3::new(0.8, 0.6, 0.4);
    let mut parts = GridParts::new("color", Vec3::ZERO, unit_box_grid().world_from_index());
    parts.tiles.push(vdbphoton::grid::Tile {
        origin: IVec3::ZERO,
        level: 2,
        value: c,
        active: true,
    });
    let color = Grid::from_parts(parts).unwrap();
    let d = 1.2f32;
    let m = Material::Principled(Principled {
        density: d,
        ..Principled::DEFAULT
    });
    let media = Media::new(vec![volume(
        unit_box_grid(),
        ExtraGrids {
            color: Some(color),
            ..Default::default()
        },
        m,
    )]);
    assert!(media.control_albedo().is_none());
    let e = 2.0f32;
    let p = 1.0 / (4.0 * std::f32::consts::PI);
    let want = c * 0.5 * d * p * e * (-d).exp() * (1.0 - (-2.0 * d).exp()) / d;
    let w = world(media, vec![Light::sun(Vec3::Z, Rgb::splat(e), 0.0)]);
    let est = estimate(&w, Vec3::new(-4.0, 0.0, 0.0), Vec3::X, 40_000, 1);
    assert_close("colour grid", est, want, 0.003);
}

fn blackbody(temperature: f32) -> Material {
    Material::Principled(Principled {
        blackbody_intensity: 1.0,
        temperature,
        ..Principled::DEFAULT
    })
}

#[test]
fn fire_only_volume_glows() {
    // No density at all, temperature attribute 1 over [-1, 1]^3: a camera
    // ray through it sees Le(T)·2 (no extinction), with either filter.
    for (kelvin, filter) in [
        (1500.0, BlackbodyFilter::Emission),
        (1500.0, BlackbodyFilter::Temperature),
        (3000.0, BlackbodyFilter::Emission),
    ] {
        let m = blackbody(kelvin);
        // (At 1500 K Cycles' fit has a negative blue channel: kept.)
        let le = m.blackbody_radiance(1.0);
        assert!(le.max_element() > 0.0);
        let t = unit_box_grid().map_values("temperature", |v| v).unwrap();
        let v = Volume::new(
            "fire",
            empty_grid("density"),
            ExtraGrids {
                temperature: Some(t),
                blackbody_filter: filter,
                ..Default::default()
            },
            m,
            DAffine3::IDENTITY,
        )
        .expect("a fire-only volume is kept");
        let w = world(Media::new(vec![v]), vec![]);
        let (o, d) = (Vec3::new(-3.0, 0.1, -0.2), Vec3::X);
        // What the estimator must find: the integral of the lookups along
        // the ray (midpoint rule, 1,000 points a voxel). With the
        // temperature filter the blackbody of the interpolated temperature
        // in the half-voxel ramps at the box's faces is not the ramp of the
        // blackbody, so that integral is within a voxel's share (0.8 %)
        // of the sharp box's 2·Le, not equal to it.
        let n = 256_000;
        let dt = 4.0 / n as f32;
        let integral = (0..n)
            .map(|i| {
                w.media
                    .eval(o + d * (1.0 + (i as f32 + 0.5) * dt), 0.0)
                    .emission
                    * dt
            })
            .fold(Rgb::ZERO, |a, b| a + b);
        let what = format!("fire only, {kelvin} K, {filter:?}");
        let slack = if filter == BlackbodyFilter::Temperature {
            0.008
        } else {
            0.002
        };
        for c in 0..3 {
            assert!(
                (integral[c] - 2.0 * le[c]).abs() <= slack * 2.0 * le.abs().max_element(),
                "{what}: channel {c}: integral {} against 2·Le {}",
                integral[c],
                2.0 * le[c]
            );
        }
        let est = estimate(&w, o, d, 4_000, 8);
        assert_close(&what, est, integral, 0.002);
    }
}

#[test]
fn camera_ray_emission_through_smoke_in_front() {
    // A scattering slab that does not glow (σa 0.25, σs 0.5, x ∈ [−4, 0])
    // in front of an emitting one (σa 0.5, σs 0.5, emission 1 per unit
    // length, x ∈ [0, 4]), voxels of 0.5, so that the walk's rate in the
    // emitting slab is the emission rate (2, one collision per voxel)
    // against σt = 1. Along +x: T = e^{−3}·e^{−4}, and the emission
    // reaching the camera E = e^{−3}·(1 − e^{−4}). The walk of
    // `transmittance_emission` must give both (a missing 1/λ, or T taken
    // after a collision's own factor, miss E); the path tracer, which
    // takes its camera ray's emission from it, must give E with no
    // scattering followed (counting the camera ray's emission also at its
    // own collisions would double it).
    let slab = |x: f64| const_box("density", 1.0, DVec3::new(x, -1.0, -1.0), 0.5, IVec3::ONE);
    let media = Media::new(vec![
        volume(
            slab(-4.0),
            ExtraGrids::default(),
            raw(0.25, 0.5, 0.0, PhaseFunction::Isotropic),
        ),
        volume(
            slab(0.0),
            ExtraGrids::default(),
            raw(0.5, 0.5, 1.0, PhaseFunction::Isotropic),
        ),
    ]);
    assert_eq!(media.emission_rate(), 2.0);
    let (o, d) = (Vec3::new(-5.0, 0.1, -0.2), Vec3::X);
    let want_t = (-7.0f32).exp();
    let want_e = (-3.0f32).exp() * (1.0 - (-4.0f32).exp());
    let n = 200_000u64;
    let (mut st, mut st2, mut se, mut se2) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for i in 0..n {
        let mut rng = Rng::new(Domain::Test, 23, 0, i);
        let (t, e) = vdbphoton::tracking::transmittance_emission(
            &media,
            &Ray::new(o, d),
            f32::INFINITY,
            &mut rng,
        );
        st += t.x as f64;
        st2 += (t.x as f64).powi(2);
        se += e.x as f64;
        se2 += (e.x as f64).powi(2);
    }
    let (mt, me) = (st / n as f64, se / n as f64);
    let se_e = ((se2 / n as f64 - me * me) / (n as f64 - 1.0)).sqrt();
    let se_t = ((st2 / n as f64 - mt * mt) / (n as f64 - 1.0)).sqrt();
    assert!(
        (mt - want_t as f64).abs() <= 4.0 * se_t + 0.002 * want_t as f64,
        "transmittance {mt} ± {se_t} against {want_t}"
    );
    assert!(
        (me - want_e as f64).abs() <= 4.0 * se_e + 0.002 * want_e as f64,
        "emission {me} ± {se_e} against {want_e}"
    );
    let w = world(media, vec![]);
    let est = estimate(&w, o, d, 40_000, 0);
    assert_close("emission behind smoke", est, Rgb::splat(want_e), 0.003);
}

/// One 8^3 block of voxels of edge `h` from world point `lo` whose
/// densities vary from voxel to voxel between 0.5 and 1 (a fixed hash), so
/// that every majorant cell's minorant lies below its voxels and its
/// majorant above them.
fn lumpy_block(lo: DVec3, h: f64) -> Grid<f32> {
    let xf = DAffine3::from_translation(lo + DVec3::splat(0.5 * h))
        * DAffine3::from_scale(DVec3::splat(h));
    let mut p = GridParts::new("density", 0.0f32, xf);
    p.brick_origins.push(IVec3::ZERO);
    p.values.extend((0u32..512).map(|v| {
        let x = v.wrapping_mul(2_654_435_761) >> 16;
        0.5 + 0.5 * (x & 0xff) as f32 / 255.0
    }));
    p.masks.push([u64::MAX; 8]);
    Grid::from_parts(p).unwrap()
}

#[test]
fn the_first_flight_and_the_camera_walk_share_their_collisions() {
    // Smoke that does not glow (σa 0.25, σs 0.5 per unit density, lumpy,
    // x ∈ [−4, 0]: the walk keeps a residual control there) in front of a
    // glowing, scattering slab (σa 0.5, σs 0.5, emission 1 per unit length,
    // x ∈ [0, 4], where the walk's rate is the emission rate 2 against
    // σt = 1), seen along +x. `sample_t_maj_camera` runs the camera
    // ray's flight (decided by `collide`) and the emission walk on the same
    // collisions, the walk alone after the flight scatters. Each must keep
    // its own expectation, taken from the field itself by a fine walk
    // along the ray: T = e^{−τ}, the emission E = ∫ e(t)·e^{−τ(t)} dt; the
    // flight crosses unscattered with probability e^{−τ} and scatters at
    // the mean depth the field gives. Stopping the walk with the flight,
    // counting a shared collision's emission twice, or taking the control's
    // share of the smoke both analytically and at every collision, misses
    // them.
    let media = Media::new(vec![
        volume(
            lumpy_block(DVec3::new(-4.0, -2.0, -2.0), 0.5),
            ExtraGrids::default(),
            raw(0.25, 0.5, 0.0, PhaseFunction::Isotropic),
        ),
        volume(
            const_box("density", 1.0, DVec3::new(0.0, -1.0, -1.0), 0.5, IVec3::ONE),
            ExtraGrids::default(),
            raw(0.5, 0.5, 1.0, PhaseFunction::Isotropic),
        ),
    ]);
    assert_eq!(media.emission_rate(), 2.0);
    assert!(media.control_albedo().is_none());
    camera_walk_keeps_its_expectations(&media);
    // The smoke alone: no emission, and a control medium, whose collisions
    // the flight takes without a lookup and the walk leaves out.
    let smoke = Media::new(vec![volume(
        lumpy_block(DVec3::new(-4.0, -2.0, -2.0), 0.5),
        ExtraGrids::default(),
        raw(0.25, 0.5, 0.0, PhaseFunction::Isotropic),
    )]);
    assert!(smoke.control_albedo().is_some());
    camera_walk_keeps_its_expectations(&smoke);
}

/// [`the_first_flight_and_the_camera_walk_share_their_collisions`] for
/// `media`, along +x from (−5, 0.1, −0.2).
fn camera_walk_keeps_its_expectations(media: &Media) {
    let ray = Ray::new(Vec3::new(-5.0, 0.1, -0.2), Vec3::X);
    // The expectations, from the probability of a first collision in each
    // step of a fine walk (the faces are ramps half a voxel wide).
    let (steps, h) = (100_000, 1e-4f64);
    let (mut tau, mut num, mut want_e) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..steps {
        let t = (k as f64 + 0.5) * h;
        let m = media.eval(ray.at(t as f32), 0.0);
        let s = m.sigma_t().x as f64;
        num += t * (-tau).exp() * (1.0 - (-s * h).exp());
        want_e += m.emission.x as f64 * (-(tau + 0.5 * s * h)).exp() * h;
        tau += s * h;
    }
    let want_t = (-tau).exp();
    let want_depth = num / (1.0 - want_t);
    let n = 200_000u64;
    let mut sums = [0.0f64; 7]; // T, T², E, E², crossings, depth, depth²
    let mut scattered = 0u64;
    for i in 0..n {
        let mut rng = Rng::new(Domain::Test, 29, 0, i);
        let mut depth = None;
        let (left, t, e) = vdbphoton::tracking::sample_t_maj_camera(
            media,
            &ray,
            f32::INFINITY,
            &mut rng,
            |c, rng| match vdbphoton::tracking::collide(c, Rgb::ONE, rng) {
                Some(step) if step.scatter => {
                    depth = Some(c.t);
                    false
                }
                Some(_) => true,
                None => false,
            },
        );
        let (t, e) = (t.x as f64, e.x as f64);
        sums[0] += t;
        sums[1] += t * t;
        sums[2] += e;
        sums[3] += e * e;
        if left {
            sums[4] += 1.0;
        }
        if let Some(x) = depth {
            sums[5] += x as f64;
            sums[6] += (x as f64).powi(2);
            scattered += 1;
        }
    }
    let nf = n as f64;
    let mean_se = |s: f64, s2: f64| {
        let m = s / nf;
        (m, ((s2 / nf - m * m) / (nf - 1.0)).sqrt())
    };
    let (mt, st) = mean_se(sums[0], sums[1]);
    let (me, se) = mean_se(sums[2], sums[3]);
    assert!(
        (mt - want_t).abs() <= 4.0 * st + 1e-3 * want_t,
        "transmittance {mt} ± {st} against {want_t}"
    );
    assert!(
        (me - want_e).abs() <= 4.0 * se + 1e-3 * want_e,
        "emission {me} ± {se} against {want_e}"
    );
    let crossed = sums[4] / nf;
    let sc = (want_t * (1.0 - want_t) / nf).sqrt();
    assert!(
        (crossed - want_t).abs() <= 4.0 * sc,
        "unscattered {crossed} against {want_t}"
    );
    assert_eq!(
        scattered as f64 + sums[4],
        nf,
        "every flight crosses or scatters"
    );
    let ns = scattered as f64;
    let depth = sums[5] / ns;
    let sd = ((sums[6] / ns - depth * depth) / (ns - 1.0)).sqrt();
    assert!(
        (depth - want_depth).abs() <= 4.0 * sd,
        "scattering depth {depth} against {want_depth}"
    );
}

#[test]
fn emission_where_there_is_no_extinction() {
    // Temperature over [-1, 1]^3, absorbing smoke only in x ∈ [0, 1]
    // (Principled Color 0: σa = D·density). Seen from −x: the front half
    // glows unattenuated, the back half through its own absorption:
    // L = Le·(1 + (1 − e^{−D})/D).
    let d = 2.0f32;
    let m = Material::Principled(Principled {
        density: d,
        color: Rgb::ZERO,
        blackbody_intensity: 1.0,
        temperature: 2000.0,
        ..Principled::DEFAULT
    });
    let le = m.blackbody_radiance(1.0);
    let smoke = const_box(
        "density",
        1.0,
        DVec3::new(0.0, -1.0, -1.0),
        2.0 / 128.0,
        IVec3::new(8, 16, 16),
    );
    let v = volume(
        smoke,
        ExtraGrids {
            temperature: Some(unit_box_grid()),
            ..Default::default()
        },
        m,
    );
    let w = world(Media::new(vec![v]), vec![]);
    let est = estimate(&w, Vec3::new(-3.0, 0.1, -0.2), Vec3::X, 20_000, 8);
    assert_close(
        "flame beside smoke",
        est,
        le * (1.0 + (1.0 - (-d).exp()) / d),
        0.003,
    );
}

/// A row of voxels along x at y = z = 0 alternating between two
/// temperature attributes, inside a brick-aligned block of 16 x 8 x 8.
fn striped_temperature(cold: f32, hot: f32, h: f64) -> Grid<f32> {
    let xf = DAffine3::from_scale(DVec3::splat(h));
    let mut p = GridParts::new("temperature", 0.0f32, xf);
    for bx in 0..2 {
        p.brick_origins.push(IVec3::new(bx * 8, 0, 0));
        p.masks.push([u64::MAX; 8]);
        for x in 0..8 {
            for _y in 0..8 {
                for _z in 0..8 {
                    let i = bx * 8 + x;
                    p.values.push(if i % 2 == 0 { cold } else { hot });
                }
            }
        }
    }
    Grid::from_parts(p).unwrap()
}

#[test]
fn blackbody_is_filtered_per_voxel_as_cycles_averages_it() {
    // Along a line through voxel centres trilinear weights are a hat per
    // voxel that integrates to h, so interpolating the radiance per voxel
    // gives exactly h·Σ Le(Tᵢ) (the mean of Cycles' one-tap lookups);
    // interpolating the temperature gives less (T⁴ is convex).
    let h = 0.05f64;
    let (cold, hot) = (0.6f32, 2.4f32);
    let m = blackbody(1000.0);
    let n_cold = 8.0f32;
    let n_hot = 8.0f32;
    let want = (m.blackbody_radiance(cold) * n_cold + m.blackbody_radiance(hot) * n_hot) * h as f32;
    let render = |filter| {
        let v = Volume::new(
            "stripes",
            empty_grid("density"),
            ExtraGrids {
                temperature: Some(striped_temperature(cold, hot, h)),
                blackbody_filter: filter,
                ..Default::default()
            },
            m.clone(),
            DAffine3::IDENTITY,
        )
        .unwrap();
        let w = world(Media::new(vec![v]), vec![]);
        // Voxel (i, 3, 4) is centred at (i h, 3h, 4h).
        estimate(
            &w,
            Vec3::new(-1.0, 3.0 * h as f32, 4.0 * h as f32),
            Vec3::X,
            20_000,
            0,
        )
    };
    let per_voxel = render(BlackbodyFilter::Emission);
    assert_close("per-voxel radiance", per_voxel, want, 0.003);
    let smooth = render(BlackbodyFilter::Temperature);
    assert!(
        smooth.0.x < 0.8 * want.x,
        "interpolating the temperature should be much dimmer here: {} against {}",
        smooth.0.x,
        want.x
    );
}

#[test]
fn emission_bounds_hold_at_random_points() {
    // The majorant grid's emission bound must be positive wherever the
    // emission is, and bound it, for both filters and an emission-strength
    // term driven by a flame grid.
    let mut state = 99u64;
    let mut rnd = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 40) as f32) / (1u64 << 24) as f32
    };
    let h = 0.05f64;
    let xf = DAffine3::from_scale(DVec3::splat(h));
    let random = |name: &str, rnd: &mut dyn FnMut() -> f32, scale: f32| {
        let mut p = GridParts::new(name, 0.0f32, xf);
        for o in [IVec3::ZERO, IVec3::new(8, 0, 0), IVec3::new(8, 8, 16)] {
            p.brick_origins.push(o);
            p.masks.push([u64::MAX; 8]);
            for _ in 0..512 {
                p.values.push(rnd() * scale);
            }
        }
        Grid::from_parts(p).unwrap()
    };
    let density = random("density", &mut rnd, 1.0);
    let temperature = random("temperature", &mut rnd, 3.0);
    let flame = random("flame", &mut rnd, 1.0);
    for filter in [BlackbodyFilter::Emission, BlackbodyFilter::Temperature] {
        let m = Material::Principled(Principled {
            blackbody_intensity: 1.0,
            emission_strength: 2.0,
            ..Principled::DEFAULT
        });
        let v = Volume::new(
            "random",
            density.clone(),
            ExtraGrids {
                temperature: Some(temperature.clone()),
                flame: Some(flame.clone()),
                blackbody_filter: filter,
                ..Default::default()
            },
            m,
            DAffine3::IDENTITY,
        )
        .unwrap();
        let g = v.majorant_grid();
        assert!(g.is_emissive());
        let res = g.resolution();
        let mut checked = 0;
        for z in 0..res.z {
            for y in 0..res.y {
                for x in 0..res.x {
                    let c = IVec3::new(x, y, z);
                    let bound = g.cell_emission(c);
                    let (lo, size) = g.cell_box(c);
                    for _ in 0..256 {
                        let pi = lo + Vec3::new(rnd(), rnd(), rnd()) * size;
                        let pw = v.world_from_index().transform_point3(pi);
                        let e = v.eval(pw, 0.0).emission.max_element();
                        assert!(
                            e <= bound * (1.0 + 1e-5) + 1e-12,
                            "{filter:?}: cell {c}: emission {e} above its bound {bound}"
                        );
                        checked += (e > 0.0) as u32;
                    }
                }
            }
        }
        assert!(checked > 1000);
    }
}

#[test]
fn overlapping_volumes_choose_phase_functions_by_their_scattering() {
    // Three volumes with σs 1, 2, 3: a scattering event takes each one's
    // phase function with probability 1/6, 2/6, 3/6, at one lookup.
    let phases = [
        PhaseFunction::hg(0.1),
        PhaseFunction::hg(0.2),
        PhaseFunction::hg(0.3),
    ];
    let media = Media::new(
        phases
            .iter()
            .enumerate()
            .map(|(i, &ph)| {
                volume(
                    unit_box_grid(),
                    ExtraGrids::default(),
                    raw(0.1, (i + 1) as f32, 0.0, ph),
                )
            })
            .collect(),
    );
    vdbphoton::tracking::take_counters();
    let n = 60_000;
    let mut counts = [0u32; 3];
    for i in 0..n {
        let u = Rng::new(Domain::Test, 3, 3, i).next_f32();
        let ph = media.phase_at(Vec3::new(0.2, 0.1, -0.3), 0.0, u);
        let k = phases.iter().position(|p| *p == ph).unwrap();
        counts[k] += 1;
    }
    assert_eq!(vdbphoton::tracking::take_counters().lookups, n);
    let chi2: f64 = counts
        .iter()
        .enumerate()
        .map(|(k, &c)| {
            let e = n as f64 * (k + 1) as f64 / 6.0;
            (c as f64 - e).powi(2) / e
        })
        .sum();
    // χ² with 2 degrees of freedom: P(> 13.8) = 0.001.
    assert!(chi2 < 13.8, "counts {counts:?}, χ² {chi2}");
}

#[test]
fn random_streams_of_different_uses_never_coincide() {
    for (a, b) in [
        (Domain::Camera, Domain::Photon),
        (Domain::Camera, Domain::Guide),
    ] {
        for k in 0..100u64 {
            let x: Vec<u32> = {
                let mut r = Rng::new(a, 5, k, k + 1);
                (0..4).map(|_| r.next_u32()).collect()
            };
            let y: Vec<u32> = {
                let mut r = Rng::new(b, 5, k, k + 1);
                (0..4).map(|_| r.next_u32()).collect()
            };
            assert_ne!(x, y, "{a:?} and {b:?} share stream {k}");
        }
    }
}
