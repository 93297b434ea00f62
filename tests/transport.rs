//! Light transport against closed forms: slab transmittance by ratio and
//! delta tracking, majorants that bound every lookup, the DDA's edge cases,
//! a white furnace, single scattering in a homogeneous box, and
//! thread-count independence.

mod common;

use glam::{DAffine3, DVec3, IVec3, Vec2, Vec3};
use vdbphoton::camera::Camera;
use vdbphoton::grid::{Grid, GridParts, Tile};
use vdbphoton::integrator::path;
use vdbphoton::light::{Environment, Light};
use vdbphoton::medium::{ExtraGrids, MajorantGrid, Material, Media, Volume, MAJORANT_CELL};
use vdbphoton::phase::PhaseFunction;
use vdbphoton::ray::Ray;
use vdbphoton::render::passes::{self, Settings};
use vdbphoton::sampling::{Domain, Rng};
use vdbphoton::tracking::{optical_depth, sample_t_maj, transmittance};
use vdbphoton::world::World;
use vdbphoton::{generate, Rgb};

fn raw(sigma_a: Rgb, sigma_s: Rgb, phase: PhaseFunction) -> Material {
    Material::Raw {
        sigma_a,
        sigma_s,
        emission: Rgb::ZERO,
        phase,
    }
}

fn media_of(grid: Grid<f32>, m: Material) -> Media {
    Media::new(vec![Volume::new(
        "test",
        grid,
        ExtraGrids::default(),
        m,
        DAffine3::IDENTITY,
    )
    .unwrap()])
}

fn world_of(media: Media, lights: Vec<Light>, env: Rgb, camera: Camera) -> World {
    World {
        camera,
        lights,
        environment: Environment::Constant(env),
        media,
        warnings: vec![],
        shapes: vdbphoton::shape::Shapes::empty(),
        surfaces: Vec::new(),
        film_transparent: false,
        load_seconds: 0.0,
    }
}

/// Mean and standard error.
fn stats(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// A smooth field, 0.6 ± 0.35, filling 48³ voxels in [-1, 1]³: dense
/// everywhere inside, so most majorant cells have a minorant above 0
/// (generated clouds have few).
fn smooth_grid() -> Grid<f32> {
    let h = 2.0 / 48.0;
    let xf = DAffine3::from_scale_rotation_translation(
        DVec3::splat(h),
        glam::DQuat::IDENTITY,
        DVec3::splat(-1.0 + 0.5 * h),
    );
    let mut p = GridParts::new("density", 0.0f32, xf);
    for bx in 0..6 {
        for by in 0..6 {
            for bz in 0..6 {
                let o = IVec3::new(bx, by, bz) * 8;
                p.brick_origins.push(o);
                p.masks.push([u64::MAX; 8]);
                for x in 0..8 {
                    for y in 0..8 {
                        for z in 0..8 {
                            let v = (o + IVec3::new(x, y, z)).as_vec3();
                            p.values.push(
                                0.6 + 0.35
                                    * (v.x / 5.0).sin()
                                    * (v.y / 7.0).cos()
                                    * (v.z / 4.0 + 1.0).sin(),
                            );
                        }
                    }
                }
            }
        }
    }
    Grid::from_parts(p).unwrap()
}

/// [`smooth_grid`] as a medium of material `m`, with the minorants of its
/// majorant grid or with them cleared (no control medium).
fn smooth_media(m: Material, minorant: bool) -> Media {
    let mut media = media_of(smooth_grid(), m);
    media.volumes_mut()[0].set_majorant_cell(8, minorant);
    media
}

#[test]
fn slab_transmittance_ratio_and_delta_tracking() {
    let sigma_t = Rgb::new(0.5, 1.0, 1.5);
    let media = media_of(
        common::unit_box_grid(),
        raw(sigma_t * 0.25, sigma_t * 0.75, PhaseFunction::Isotropic),
    );
    let o = Vec3::new(-3.0, 0.1, -0.2);
    let d = Vec3::X;
    // The box is 2 units thick along the ray.
    let expected = (-sigma_t * 2.0).map(f32::exp);
    let tau = optical_depth(&media, &Ray::new(o, d), 0.0, 6.0, 4096, 0.5);
    assert!(
        (tau - sigma_t * 2.0).abs().max_element() < 2e-3,
        "optical depth {tau}"
    );

    let n = 40_000;
    for c in 0..3 {
        let est: Vec<f64> = (0..n)
            .map(|i| {
                let mut rng = Rng::new(Domain::Test, 1, 0, i);
                transmittance(&media, &Ray::new(o, d), f32::INFINITY, &mut rng)[c] as f64
            })
            .collect();
        let (m, se) = stats(&est);
        let want = expected[c] as f64;
        assert!(
            (m - want).abs() < 4.0 * se + 1e-4,
            "ratio tracking channel {c}: {m} ± {se} vs {want}"
        );
    }
    // A finite t_max stops in the middle of the slab: T = exp(-σt·1).
    let mid: Vec<f64> = (0..n)
        .map(|i| {
            transmittance(
                &media,
                &Ray::new(o, d),
                3.0,
                &mut Rng::new(Domain::Test, 2, 0, i),
            )
            .x as f64
        })
        .collect();
    let (m, se) = stats(&mid);
    assert!(
        (m - (-0.5f64).exp()).abs() < 4.0 * se + 1e-4,
        "half slab: {m}"
    );

    // Delta tracking (grey): the fraction of flights that pass without a
    // real collision.
    let grey = media_of(
        common::unit_box_grid(),
        raw(Rgb::splat(0.3), Rgb::splat(0.7), PhaseFunction::Isotropic),
    );
    let n = 200_000;
    let mut escaped = 0u32;
    for i in 0..n {
        let mut rng = Rng::new(Domain::Test, 3, 0, i);
        if sample_t_maj(&grey, &Ray::new(o, d), f32::INFINITY, &mut rng, |c, rng| {
            rng.next_f32() >= c.medium().sigma_t().x / c.sigma_maj
        }) {
            escaped += 1;
        }
    }
    let p = escaped as f64 / n as f64;
    let want = (-2.0f64).exp();
    let se = (want * (1.0 - want) / n as f64).sqrt();
    assert!((p - want).abs() < 4.0 * se, "delta tracking: {p} vs {want}");
}

/// A random sparse grid: bricks of random (partly negative) values and
/// tiles at levels 1 and 2, under a random affine transform.
fn random_grid(seed: u64) -> Grid<f32> {
    let mut rng = common::TestRng(seed);
    let xf = DAffine3::from_scale_rotation_translation(
        DVec3::splat(rng.range(0.01, 0.2)),
        glam::DQuat::from_euler(
            glam::EulerRot::XYZ,
            rng.range(0.0, 3.0),
            rng.range(0.0, 3.0),
            rng.range(0.0, 3.0),
        ),
        DVec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        ),
    );
    let mut p = GridParts::new("density", 0.0f32, xf);
    let mut used = std::collections::HashSet::new();
    p.tiles.push(Tile {
        origin: IVec3::new(128, 0, 0),
        level: 2,
        value: rng.range(0.0, 3.0) as f32,
        active: true,
    });
    for _ in 0..40 {
        let o = IVec3::new(
            (rng.range(-3.0, 16.0) as i32) * 8,
            (rng.range(-3.0, 16.0) as i32) * 8,
            (rng.range(-3.0, 16.0) as i32) * 8,
        );
        if !used.insert(o) || o.x >= 128 {
            continue;
        }
        if rng.f64() < 0.3 {
            p.tiles.push(Tile {
                origin: o,
                level: 1,
                value: rng.range(0.0, 5.0) as f32,
                active: true,
            });
            continue;
        }
        p.brick_origins.push(o);
        p.masks.push([u64::MAX; 8]);
        let scale = rng.range(0.1, 10.0);
        for _ in 0..512 {
            p.values.push((rng.range(-0.2, 1.0) * scale) as f32);
        }
    }
    Grid::from_parts(p).unwrap()
}

#[test]
fn majorants_bound_every_lookup_on_random_grids() {
    for seed in 0..6 {
        let g = random_grid(seed);
        let m = MajorantGrid::build(&g, 8).unwrap();
        m.validate(&g, 40)
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        // And along rays, through the whole tracker: every tentative
        // collision has sigma_t ≤ sigma_maj. Optically thick (cells of 8
        // voxels hold several mean free paths: the volume gets cells of 4)
        // and thin (it keeps cells of 8).
        for (k, cell) in [(1.0f32, MAJORANT_CELL / 2), (1e-3, MAJORANT_CELL)] {
            let sigma = Rgb::new(2.0, 3.0, 5.0) * k;
            let media = media_of(
                g.clone(),
                raw(sigma * 0.5, sigma * 0.5, PhaseFunction::Isotropic),
            );
            assert_eq!(
                media.volumes()[0].majorant_grid().cell(),
                cell,
                "seed {seed}, sigma {sigma}"
            );
            tracked_collisions_are_bounded(&media, seed, k == 1.0);
        }
    }
}

/// Every tentative collision of the tracker through `media`, along random
/// rays, has σt within the majorant and minorant; with `many`, over a
/// thousand were checked.
fn tracked_collisions_are_bounded(media: &Media, seed: u64, many: bool) {
    let (lo, hi) = media.bounds().unwrap();
    let mut rng = Rng::new(Domain::Test, seed, 9, 9);
    let mut collisions = 0;
    for _ in 0..300 {
        let target = lo + (hi - lo) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let dir = vdbphoton::sampling::sample_uniform_sphere(rng.next_vec2());
        let o = target - dir * (hi - lo).length();
        sample_t_maj(media, &Ray::new(o, dir), f32::INFINITY, &mut rng, |c, _| {
            let st = c.medium().sigma_t();
            assert!(
                st.max_element() <= c.sigma_maj * (1.0 + 1e-5),
                "seed {seed}: sigma_t {st} above the majorant {} at {}",
                c.sigma_maj,
                c.p
            );
            assert!(
                st.min_element() >= c.sigma_c * (1.0 - 1e-5),
                "seed {seed}: sigma_t {st} below the minorant {} at {}",
                c.sigma_c,
                c.p
            );
            collisions += 1;
            true
        });
    }
    assert!(
        !many || collisions > 1000,
        "seed {seed}: only {collisions} collisions were checked"
    );
}

#[test]
fn majorant_grid_needs_fewer_lookups_than_a_global_bound() {
    // Expected tentative collisions along a ray = ∫ majorant dt, and the
    // lookups of residual ratio tracking ∫ (majorant − minorant) dt. Over
    // random rays through the bounding box of the generated cloud, compared
    // with one global majorant over the same box. The cloud is dense over
    // most of its box, so no grid can do very much better on such rays
    // (render rays do better: they stop inside). The bounds, a little under
    // the measured figures, guard against bounds that stop adapting.
    let g = generate::cloud(96, 3).unwrap();
    let m = MajorantGrid::build(&g, 8).unwrap();
    m.validate(&g, 10).unwrap();
    let global = MajorantGrid::build(&g, 4096).unwrap();
    assert_eq!(global.resolution(), IVec3::ONE);
    // Rays from all around aimed at random points of the bounding box, as
    // camera and shadow rays are.
    let (lo, hi) = m.bounds();
    let mut rng = Rng::new(Domain::Test, 5, 5, 5);
    let (mut e_grid, mut e_residual, mut e_global) = (0.0f64, 0.0f64, 0.0f64);
    for _ in 0..4000 {
        let target = lo + (hi - lo) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let d = vdbphoton::sampling::sample_uniform_sphere(rng.next_vec2());
        let o = target - d * (hi - lo).length();
        for s in m.walk(o, d, 0.0, f32::INFINITY) {
            e_grid += ((s.t1 - s.t0) * s.max_density) as f64;
            e_residual += ((s.t1 - s.t0) * (s.max_density - s.min_density)) as f64;
            e_global += ((s.t1 - s.t0) * global.max()) as f64;
        }
    }
    let (ratio, ratio_residual) = (e_global / e_grid, e_global / e_residual);
    eprintln!(
        "expected lookups: global majorant / majorant grid = {ratio:.2}, / residual = {ratio_residual:.2}"
    );
    assert!(ratio >= 1.8, "the majorant grid saves only {ratio:.2}x");
    assert!(
        ratio_residual >= 2.3,
        "residual tracking saves only {ratio_residual:.2}x"
    );
}

/// Two bricks 20,000 voxels apart (a valid sparse file; AFL++ found the
/// like of it) would need 2,500³ cells of 8 voxels. That count overflowed
/// (a panic, or in release a wrapped size); now the cells grow to fit a
/// budget, and still bound every lookup, in every cell and along rays
/// through both bricks.
#[test]
fn far_apart_bricks_get_coarser_cells_that_still_bound() {
    let mut p = GridParts::new("density", 0.0f32, DAffine3::IDENTITY);
    let mut values = Vec::new();
    for (k, o) in [IVec3::ZERO, IVec3::splat(20000)].into_iter().enumerate() {
        p.brick_origins.push(o);
        p.masks.push([u64::MAX; 8]);
        values.extend((0..512).map(|i| (1 + (i * 7 + k) % 5) as f32));
    }
    p.values = values.into();
    let g = Grid::from_parts(p).unwrap();
    let m = MajorantGrid::build(&g, 8).unwrap();
    let r = m.resolution().as_i64vec3();
    assert!(r.x * r.y * r.z <= 1 << 22, "{} cells", r.x * r.y * r.z);
    let (_, edge) = m.cell_box(IVec3::ZERO);
    assert!(edge > 8.0, "cells of {edge} voxels");
    m.validate(&g, 2).unwrap();
    assert_eq!(m.max(), 5.0);
    // Through the tracker: rays from each brick to the other.
    let sigma = Rgb::splat(1.0);
    let media = media_of(g, raw(sigma * 0.5, sigma * 0.5, PhaseFunction::Isotropic));
    let mut rng = Rng::new(Domain::Test, 7, 7, 7);
    let mut collisions = 0;
    for i in 0..200 {
        let jitter = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 8.0;
        let (a, b) = (
            jitter,
            Vec3::splat(20000.0) + Vec3::new(jitter.z, jitter.x, jitter.y),
        );
        let (o, d) = if i % 2 == 0 { (a, b - a) } else { (b, a - b) };
        sample_t_maj(
            &media,
            &Ray::new(o, d.normalize()),
            d.length(),
            &mut rng,
            |c, _| {
                let st = c.medium().sigma_t();
                assert!(
                    st.max_element() <= c.sigma_maj * (1.0 + 1e-5),
                    "above the majorant at {}",
                    c.p
                );
                assert!(
                    st.min_element() >= c.sigma_c * (1.0 - 1e-5),
                    "below the minorant at {}",
                    c.p
                );
                collisions += 1;
                true
            },
        );
    }
    assert!(
        collisions > 200,
        "only {collisions} collisions were checked"
    );
}

#[test]
fn dda_exact_entry_exit_and_signed_zero_directions() {
    // A grid of two voxels at x = 0 and 1 (values 1, 2) in one brick: the
    // majorant box is that brick widened by one voxel, [-1, 8] in index
    // space, with 8-voxel cells aligned with the bricks.
    let mut p = GridParts::new("d", 0.0f32, DAffine3::IDENTITY);
    p.brick_origins.push(IVec3::ZERO);
    let mut vals = vec![0.0f32; 512];
    vals[0] = 1.0;
    vals[64] = 2.0;
    p.values = vals.into();
    p.masks.push([1 | (1 << 0), 0, 0, 0, 0, 0, 0, 0]);
    let g = Grid::from_parts(p).unwrap();
    let m = MajorantGrid::build(&g, 8).unwrap();
    let (lo, hi) = m.bounds();
    assert_eq!(lo, Vec3::splat(-1.0));
    assert_eq!(hi, Vec3::splat(8.0));
    // Along +x from outside: enters at x = -1, leaves at 8.
    let segs: Vec<_> = m
        .walk(Vec3::new(-5.0, 0.5, 0.5), Vec3::X, 0.0, f32::INFINITY)
        .collect();
    assert_eq!(segs.first().unwrap().t0, 4.0);
    assert_eq!(segs.last().unwrap().t1, 13.0);
    assert_eq!(segs.len(), 2);
    // The cell [-8, 0) sees voxel x = 0 only; [0, 8) both, and background.
    assert_eq!(segs[0].t1, 5.0);
    assert_eq!((segs[0].min_density, segs[0].max_density), (0.0, 1.0));
    assert_eq!((segs[1].min_density, segs[1].max_density), (0.0, 2.0));
    for w in segs.windows(2) {
        assert_eq!(w[0].t1, w[1].t0);
    }
    // ±0 components of the direction: no NaN, the same walk.
    for d in [
        Vec3::new(1.0, 0.0, -0.0),
        Vec3::new(1.0, -0.0, 0.0),
        Vec3::new(1.0, -0.0, -0.0),
    ] {
        let s: Vec<_> = m
            .walk(Vec3::new(-5.0, 0.5, 0.5), d, 0.0, f32::INFINITY)
            .collect();
        assert_eq!(s, segs, "direction {d:?}");
    }
    // Along a face of the box (y = -1 exactly) and outside it.
    assert_eq!(
        m.walk(Vec3::new(-5.0, -1.5, 0.5), Vec3::X, 0.0, f32::INFINITY)
            .count(),
        0
    );
    // Starting inside, and a t range that ends inside.
    let s: Vec<_> = m
        .walk(Vec3::new(3.0, 0.5, 0.5), -Vec3::X, 0.0, 2.0)
        .collect();
    assert_eq!(s.len(), 1);
    assert_eq!((s[0].t0, s[0].t1), (0.0, 2.0));
    // Backwards through the box.
    let s: Vec<_> = m
        .walk(Vec3::new(20.0, 3.0, 3.0), -Vec3::X, 0.0, f32::INFINITY)
        .collect();
    assert_eq!((s[0].t0, s.last().unwrap().t1), (12.0, 21.0));
}

#[test]
fn white_furnace() {
    // Albedo 1 in every channel (different sigma_s per channel), any
    // density field, constant environment 1, no lights: every pixel is 1.
    let g = generate::cloud(48, 5).unwrap();
    let media = media_of(
        g,
        raw(
            Rgb::ZERO,
            Rgb::new(10.0, 25.0, 40.0),
            PhaseFunction::hg(0.6),
        ),
    );
    let cam = Camera::new(Vec3::new(0.0, -3.5, 0.3), Vec3::ZERO, Vec3::Z, 40.0, 12, 9);
    let world = world_of(media, vec![], Rgb::ONE, cam);
    let settings = Settings {
        width: 12,
        height: 9,
        spp: 256,
        seed: 3,
        max_bounces: 100_000,
    };
    let mut worst: f64 = 0.0;
    for y in 0..9 {
        for x in 0..12 {
            let mut v = [vec![], vec![], vec![]];
            for s in 0..settings.spp {
                let mut rng = Rng::new(Domain::Test, settings.seed, (y * 12 + x) as u64, s as u64);
                let d = world
                    .camera
                    .direction(Vec2::new(x as f32, y as f32) + rng.next_vec2());
                let r = path::trace(
                    &world,
                    settings.max_bounces,
                    &Ray::new(world.camera.position(), d),
                    &mut rng,
                );
                for (c, vc) in v.iter_mut().enumerate() {
                    vc.push(r.l[c] as f64);
                }
            }
            for (c, vc) in v.iter().enumerate() {
                let (m, se) = stats(vc);
                assert!(
                    (m - 1.0).abs() < 5.0 * se + 1e-3,
                    "pixel ({x},{y}) channel {c}: {m} ± {se}"
                );
                worst = worst.max((m - 1.0).abs());
            }
        }
    }
    eprintln!("white furnace: worst pixel deviation {worst:.4}");
}

#[test]
fn single_scattering_in_a_box_matches_the_closed_form() {
    // Camera ray along +x through the centre of the box [-1,1]^3, sun
    // straight down from +z, one scattering event at most (max_bounces 1):
    // L = σs p(cos = 0) E e^{-σt·1} (1 − e^{-2σt}) / σt, with the sun's
    // path to the top face of length 1 and the camera segment of length 2.
    let (sa, ss, g, e) = (0.3f32, 0.7f32, 0.5f32, 3.0f32);
    let st = sa + ss;
    let media = media_of(
        common::unit_box_grid(),
        raw(Rgb::splat(sa), Rgb::splat(ss), PhaseFunction::hg(g)),
    );
    let cam = Camera::new(Vec3::new(-6.0, 0.0, 0.0), Vec3::ZERO, Vec3::Z, 0.2, 5, 5);
    let world = world_of(
        media,
        vec![Light::sun(Vec3::Z, Rgb::splat(e), 0.0)],
        Rgb::ZERO,
        cam,
    );
    let settings = Settings {
        width: 5,
        height: 5,
        spp: 20_000,
        seed: 1,
        max_bounces: 1,
    };
    let (acc, tr) = passes::render_pixel(&world, &settings, 2, 2);
    let p = vdbphoton::phase::henyey_greenstein(0.0, g);
    let want = ss * p * e * (-st).exp() * (1.0 - (-2.0 * st).exp()) / st;
    let got = acc[0].x;
    assert!(
        (got / want - 1.0).abs() < 0.02,
        "single scattering {got} vs closed form {want}"
    );
    // All of it is single scattering; the camera ray's transmittance is
    // exp(-2σt).
    assert!((acc[1].x / want - 1.0).abs() < 0.02);
    assert!((tr - (-2.0 * st).exp()).abs() < 0.01, "transmittance {tr}");
}

#[test]
fn image_is_the_same_on_one_and_two_threads() {
    let g = generate::cloud(32, 2).unwrap();
    let media = media_of(
        g,
        raw(
            Rgb::splat(1.0),
            Rgb::new(8.0, 10.0, 12.0),
            PhaseFunction::hg(0.4),
        ),
    );
    let cam = Camera::new(Vec3::new(0.2, -3.0, 0.5), Vec3::ZERO, Vec3::Z, 45.0, 40, 30);
    let world = world_of(
        media,
        vec![Light::sun(Vec3::new(1.0, -1.0, 2.0), Rgb::splat(3.0), 2.0)],
        Rgb::splat(0.2),
        cam,
    );
    let settings = Settings {
        width: 40,
        height: 30,
        spp: 8,
        seed: 42,
        max_bounces: 64,
    };
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| passes::render(&world, &settings, &|_, _| {}))
    };
    let (a, b) = (run(1), run(2));
    // Film sums equal to the bit: equal means, transmittance, AOVs.
    assert!(a == b);
    let (a, b) = (a.mean_rgb(), b.mean_rgb());
    assert!(a
        .iter()
        .zip(&b)
        .all(|(x, y)| x.to_array().map(f32::to_bits) == y.to_array().map(f32::to_bits)));
    assert!(a.iter().any(|p| p.x > 0.0));
    // A different seed gives a different image.
    let c = passes::render(
        &world,
        &Settings {
            seed: 43,
            ..settings.clone()
        },
        &|_, _| {},
    );
    assert_ne!(a, c.mean_rgb());
}

#[test]
fn overlapping_volumes_add_their_extinction() {
    // Two boxes, the second shifted by 0.5 along x and 0.3 along y: along a
    // ray through both, optical depths add wherever they overlap.
    let m1 = raw(
        Rgb::splat(0.2),
        Rgb::new(0.3, 0.5, 0.7),
        PhaseFunction::Isotropic,
    );
    let m2 = raw(
        Rgb::splat(0.1),
        Rgb::new(0.6, 0.2, 0.1),
        PhaseFunction::hg(0.5),
    );
    let shift = DAffine3::from_translation(DVec3::new(0.5, 0.3, 0.0));
    let v1 = Volume::new(
        "a",
        common::unit_box_grid(),
        ExtraGrids::default(),
        m1.clone(),
        DAffine3::IDENTITY,
    )
    .unwrap();
    let v2 = Volume::new(
        "b",
        common::unit_box_grid(),
        ExtraGrids::default(),
        m2.clone(),
        shift,
    )
    .unwrap();
    let media = Media::new(vec![v1, v2]);
    let o = Vec3::new(-4.0, 0.0, 0.1);
    let st1 = Rgb::new(0.5, 0.7, 0.9);
    let st2 = Rgb::new(0.7, 0.3, 0.2);
    let want = (-(st1 * 2.0 + st2 * 2.0)).map(f32::exp);
    let tau = optical_depth(&media, &Ray::new(o, Vec3::X), 0.0, 8.0, 8192, 0.5);
    assert!(
        (tau - (st1 + st2) * 2.0).abs().max_element() < 3e-3,
        "optical depth {tau}"
    );
    let n = 40_000;
    for c in 0..3 {
        let est: Vec<f64> = (0..n)
            .map(|i| {
                transmittance(
                    &media,
                    &Ray::new(o, Vec3::X),
                    f32::INFINITY,
                    &mut Rng::new(Domain::Test, 8, 0, i),
                )[c] as f64
            })
            .collect();
        let (m, se) = stats(&est);
        assert!(
            (m - want[c] as f64).abs() < 4.0 * se + 1e-4,
            "channel {c}: {m} ± {se} vs {}",
            want[c]
        );
    }
    // In the overlap the coefficients are the sums; outside it, one box's.
    let both = media.eval(Vec3::new(0.7, 0.5, 0.0), 0.0);
    assert!((both.sigma_s - Rgb::new(0.9, 0.7, 0.8)).abs().max_element() < 1e-5);
    let one = media.eval(Vec3::new(-0.8, 0.0, 0.0), 0.0);
    assert!((one.sigma_s - Rgb::new(0.3, 0.5, 0.7)).abs().max_element() < 1e-5);
    // The phase function in the overlap is chosen in proportion to σs.
    let mut hg = 0;
    for i in 0..10_000 {
        if media.phase_at(
            Vec3::new(0.7, 0.5, 0.0),
            0.0,
            Rng::new(Domain::Test, 1, 1, i).next_f32(),
        ) != PhaseFunction::Isotropic
        {
            hg += 1;
        }
    }
    let p = 0.9 / 2.4; // avg σs of the second / avg of both
    assert!(((hg as f64 / 10_000.0) - p).abs() < 0.02, "{hg}");
}

#[test]
fn residual_ratio_tracking_matches_quadrature_in_a_heterogeneous_cloud() {
    // exp(−∫σt) by fine quadrature against the mean of residual ratio
    // tracking (the default, with the minorant as control) and of plain
    // ratio tracking (minorant cleared), along rays through a smooth
    // heterogeneous medium with chromatic extinction.
    let sigma = Rgb::new(0.5, 1.0, 1.5);
    let mk = |minorant| {
        smooth_media(
            raw(sigma * 0.2, sigma * 0.8, PhaseFunction::Isotropic),
            minorant,
        )
    };
    let (with, without) = (mk(true), mk(false));
    let (lo, hi) = with.bounds().unwrap();
    let mut rng = Rng::new(Domain::Test, 21, 0, 0);
    let mut controlled = 0;
    for ray in 0..8 {
        let target = (lo + hi) * 0.5
            + (hi - lo) * 0.2 * (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5);
        let d = vdbphoton::sampling::sample_uniform_sphere(rng.next_vec2());
        let o = target - d * (hi - lo).length();
        let t1 = 2.0 * (hi - lo).length();
        let tau = optical_depth(&with, &Ray::new(o, d), 0.0, t1, 20_000, 0.5);
        let want = (-tau).map(f32::exp);
        with.for_each_segment(o, d, 0.0, t1, |s| {
            controlled += (s.min_density > 0.0) as u32;
            true
        });
        for (label, media) in [("residual", &with), ("plain", &without)] {
            for c in 0..3 {
                let est: Vec<f64> = (0..20_000)
                    .map(|i| {
                        let mut r = Rng::new(Domain::Test, 22, ray, i);
                        transmittance(media, &Ray::new(o, d), f32::INFINITY, &mut r)[c] as f64
                    })
                    .collect();
                let (m, se) = stats(&est);
                let w = want[c] as f64;
                assert!(
                    (m - w).abs() < 4.0 * se + 2e-4,
                    "{label} ratio tracking, ray {ray} channel {c}: {m} ± {se} vs {w} (τ {})",
                    tau[c]
                );
            }
        }
    }
    assert!(controlled > 20, "only {controlled} segments had a minorant");
}

#[test]
fn chromatic_medium_equals_its_grey_channels() {
    // Spectral tracking with a control medium: a medium whose σs and σa
    // differ per channel gives, in each channel, what a grey medium with
    // that channel's coefficients gives, with the minorant (decomposition
    // tracking) and without it.
    let sigma_s = Rgb::new(1.0, 2.5, 4.0);
    let sigma_a = Rgb::new(0.6, 0.2, 0.1);
    let volume =
        |sa: Rgb, ss: Rgb, minorant| smooth_media(raw(sa, ss, PhaseFunction::hg(0.3)), minorant);
    let cam = Camera::new(Vec3::new(0.3, -3.0, 0.4), Vec3::ZERO, Vec3::Z, 35.0, 8, 6);
    let light = Light::sun(Vec3::new(-0.4, -0.5, 0.75), Rgb::splat(2.0), 0.0);
    let settings = Settings {
        width: 8,
        height: 6,
        spp: 1,
        seed: 0,
        max_bounces: 256,
    };
    // Mean radiance and its standard error over n paths through random
    // film points, per channel.
    let run = |media: Media, stream: u64| {
        let world = world_of(media, vec![light.clone()], Rgb::splat(0.1), cam);
        let n = 40_000;
        let mut v = [vec![], vec![], vec![]];
        for i in 0..n {
            let mut rng = Rng::new(Domain::Test, 5, stream, i);
            let film = Vec2::new(rng.next_f32() * 8.0, rng.next_f32() * 6.0);
            let d = world.camera.direction(film);
            let r = path::trace(
                &world,
                settings.max_bounces,
                &Ray::new(world.camera.position(), d),
                &mut rng,
            );
            for (c, vc) in v.iter_mut().enumerate() {
                vc.push(r.l[c] as f64);
            }
        }
        v.map(|vc| stats(&vc))
    };
    let chromatic = run(volume(sigma_a, sigma_s, true), 1);
    let chromatic_plain = run(volume(sigma_a, sigma_s, false), 2);
    for c in 0..3 {
        let (grey, se_g) = run(
            volume(Rgb::splat(sigma_a[c]), Rgb::splat(sigma_s[c]), true),
            10 + c as u64,
        )[c];
        for (label, (m, se)) in [
            ("control", chromatic[c]),
            ("no control", chromatic_plain[c]),
        ] {
            let tol = 4.0 * (se * se + se_g * se_g).sqrt();
            eprintln!(
                "channel {c} {label}: chromatic {m:.5} ± {se:.5}, grey {grey:.5} ± {se_g:.5}"
            );
            assert!(
                (m - grey).abs() < tol,
                "channel {c} ({label}): chromatic {m} vs grey {grey} (tolerance {tol})"
            );
        }
    }
}
