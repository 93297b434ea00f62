//! Velocity motion blur: a moving emitting box against the time average of
//! its emission (both integrators), majorants that bound a moving density
//! over the whole shutter, and still frames unchanged by it.

mod common;

use common::const_box;
use glam::{DAffine3, DVec3, IVec3, Vec2, Vec3};
use vdbphoton::camera::{Camera, Shutter};
use vdbphoton::grid::{Grid, GridParts, Tile};
use vdbphoton::integrator::photon::PhotonSettings;
use vdbphoton::integrator::{Integrator, PathIntegrator, PhotonIntegrator};
use vdbphoton::light::{Environment, Light};
use vdbphoton::medium::{
    ExtraGrids, Material, Media, Principled, VelocityField, VelocityGrids, Volume,
};
use vdbphoton::phase::PhaseFunction;
use vdbphoton::render::passes::camera_sample;
use vdbphoton::world::World;
use vdbphoton::Rgb;

/// A velocity grid holding `v` over [-4, 4]^3 (8^3 tiles of voxels 1/8
/// wide), zero beyond: wide enough that every advected lookup of the tests
/// finds it.
fn uniform_velocity(v: Vec3) -> Grid<Vec3> {
    let h = 0.125;
    let xf = DAffine3::from_scale_rotation_translation(
        DVec3::splat(h),
        glam::DQuat::IDENTITY,
        DVec3::splat(-4.0 + 0.5 * h),
    );
    let mut p = GridParts::new("velocity", Vec3::ZERO, xf);
    for x in 0..8 {
        for y in 0..8 {
            for z in 0..8 {
                p.tiles.push(Tile {
                    origin: IVec3::new(x, y, z) * 8,
                    level: 1,
                    value: v,
                    active: true,
                });
            }
        }
    }
    Grid::from_parts(p).unwrap()
}

/// Pure emission, `e` per unit length per unit density, no extinction.
fn glow(e: f32) -> Material {
    Material::Raw {
        sigma_a: Rgb::ZERO,
        sigma_s: Rgb::ZERO,
        emission: Rgb::splat(e),
        phase: PhaseFunction::Isotropic,
    }
}

/// The box [-0.25, 0.25]^3 (16^3 voxels) of density 1 with material `m`,
/// moving at `v` world units per frame, for a shutter that reaches
/// `max_time` frames from the frame.
fn moving_box(m: Material, v: Vec3, max_time: f32) -> Volume {
    let density = const_box(
        "density",
        1.0,
        DVec3::splat(-0.25),
        0.5 / 16.0,
        IVec3::splat(2),
    );
    Volume::new(
        "box",
        density,
        ExtraGrids {
            velocity: Some(VelocityField {
                grids: VelocityGrids::Vector(uniform_velocity(v)),
                shutter: (-max_time, max_time),
                per_frame: Vec3::ONE,
            }),
            ..Default::default()
        },
        m,
        DAffine3::IDENTITY,
    )
    .unwrap()
}

const W: u32 = 48;
const H: u32 = 16;

/// Looking down −z at the box from z = 5, the image 1.05 units wide at
/// z = 0, with a shutter centred on the frame.
fn world(volume: Volume, lights: Vec<Light>, shutter: Option<f32>) -> World {
    let camera = Camera::new(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 4.0, W, H)
        .with_shutter(shutter.map(|s| Shutter {
            open: -0.5 * s,
            close: 0.5 * s,
        }));
    World {
        camera,
        lights,
        environment: Environment::Constant(Rgb::ZERO),
        media: Media::new(vec![volume]),
        warnings: vec![],
        shapes: vdbphoton::shape::Shapes::empty(),
        surfaces: Vec::new(),
        film_transparent: false,
        load_seconds: 0.0,
    }
}

/// The time average of the still box's emission along pixel (x, y)'s rays,
/// by quadrature over the pixel, the shutter and the ray: what the moving
/// box must render. The still box's density `still` is looked up at
/// x − τ·v, which is what a uniform velocity means.
fn expected(world: &World, still: &Volume, v: Vec3, shutter: f32, x: u32, y: u32) -> f32 {
    let cam = &world.camera;
    let (n_film, n_time, n_ray) = (6, 24, 160);
    let mut sum = 0.0f64;
    for fy in 0..n_film {
        for fx in 0..n_film {
            let film = Vec2::new(
                x as f32 + (fx as f32 + 0.5) / n_film as f32,
                y as f32 + (fy as f32 + 0.5) / n_film as f32,
            );
            let d = cam.direction(film);
            // The box spans z in [-0.25, 0.25]: t from 4.7 to 5.3 along d.
            let (t0, t1) = (4.6 / -d.z, 5.4 / -d.z);
            for k in 0..n_time {
                let tau = ((k as f32 + 0.5) / n_time as f32 - 0.5) * shutter;
                let dt = (t1 - t0) / n_ray as f32;
                for i in 0..n_ray {
                    let p = cam.position() + d * (t0 + (i as f32 + 0.5) * dt);
                    sum += (still.eval(p - tau * v, 0.0).emission.x * dt) as f64;
                }
            }
        }
    }
    (sum / (n_film * n_film * n_time) as f64) as f32
}

/// Per-pixel mean and standard error of `passes` samples of row `y`.
fn row(world: &World, integrator: &mut dyn Integrator, passes: u32, y: u32) -> Vec<(f64, f64)> {
    let mut s = vec![(0.0f64, 0.0f64); W as usize];
    for pass in 0..passes {
        integrator.begin_pass(world, pass);
        for x in 0..W {
            let l = camera_sample(world, integrator, 3, x, y, pass as u64).l.x as f64;
            s[x as usize].0 += l;
            s[x as usize].1 += l * l;
        }
    }
    let n = passes as f64;
    s.into_iter()
        .map(|(a, b)| {
            let m = a / n;
            (m, ((b / n - m * m).max(0.0) / (n - 1.0)).sqrt())
        })
        .collect()
}

#[test]
fn moving_emitting_box_renders_its_time_average() {
    // Moving 1 unit per frame along x, shutter 0.5 centred: the box, 0.5
    // wide, sweeps [-0.5, 0.5]; its edges become ramps a quarter of the
    // image wide.
    let (v, shutter) = (Vec3::X, 0.5);
    let w = world(
        moving_box(glow(2.0), v, 0.5 * shutter),
        vec![],
        Some(shutter),
    );
    let still = moving_box(glow(2.0), Vec3::ZERO, 0.0);
    let y = H / 2;
    let want: Vec<f32> = (0..W)
        .map(|x| expected(&w, &still, v, shutter, x, y))
        .collect();
    // The blur is there: pixels beyond the still box glow, and the centre
    // is dimmer than the still box's 2 × 0.5 = 1.
    assert!(want[2] > 0.01 && want[2] < 0.5, "{want:?}");
    assert!(want[24] < 0.999 && want[24] > 0.8, "{want:?}");
    let mut path = PathIntegrator::new(8);
    let mut photon = PhotonIntegrator::new(&w, PhotonSettings::default(), 8, 3).unwrap();
    for (name, got) in [
        ("path", row(&w, &mut path, 1024, y)),
        // One shutter time a pass: the mean over passes converges to the
        // time average.
        ("photon", row(&w, &mut photon, 1024, y)),
    ] {
        let mut worst = 0.0f64;
        for x in 0..W as usize {
            let (m, se) = got[x];
            let z = (m - want[x] as f64).abs() / (se + 1e-4 + 0.003 * want[x] as f64);
            worst = worst.max(z);
            assert!(
                z < 4.5,
                "{name}: pixel {x}: {m} ± {se}, the time average is {}",
                want[x]
            );
        }
        eprintln!("{name}: largest deviation {worst:.2} standard errors");
    }
}

#[test]
fn a_still_render_ignores_the_shutter_and_a_zero_velocity() {
    // A zero velocity grid makes no motion at all, so a render with the
    // shutter open is the still render, sample for sample.
    let lights = vec![Light::sun(Vec3::new(0.3, 0.2, 1.0), Rgb::splat(2.0), 0.0)];
    let m = Material::Principled(Principled {
        density: 4.0,
        ..Principled::DEFAULT
    });
    let zero = world(
        moving_box(m.clone(), Vec3::ZERO, 0.25),
        lights.clone(),
        Some(0.5),
    );
    assert!(!zero.media.is_moving());
    let still = world(moving_box(m, Vec3::ZERO, 0.25), lights, None);
    for x in 0..W {
        let a = camera_sample(&zero, &PathIntegrator::new(8), 1, x, 8, 0);
        let b = camera_sample(&still, &PathIntegrator::new(8), 1, x, 8, 0);
        assert_eq!(a.l.to_array(), b.l.to_array());
    }
}

#[test]
fn majorants_bound_a_moving_density_over_the_whole_shutter() {
    // A lumpy density and emission moving fast along a swirl: at any point
    // and any time within the shutter, the advected lookup must lie within
    // the bounds the trackers sample against at that time (the time slab's,
    // `MajorantGrid::slab`). Without the dilation by the motion, the bounds
    // hold for the still volume only and this fails; at six times the
    // speed (lookups move 16 voxels), a slab bounding one slab's motion
    // too little fails too.
    bounds_hold_for_a_swirl(1.0, Vec3::ZERO, 0.1, false, (-0.25, 0.25));
    bounds_hold_for_a_swirl(6.0, Vec3::ZERO, 0.1, false, (-0.25, 0.25));
    // A drift of 16 voxels along z over the half shutter: the bounds per
    // axis are then exact, and every slab's margin counts.
    bounds_hold_for_a_swirl(0.0, Vec3::new(0.0, 0.0, 3.2), 0.1, false, (-0.25, 0.25));
    // The velocity on the density's voxels (Mantaflow's caches), whose
    // bounds are then taken voxel by voxel (`MotionReach::local`): a swirl
    // whose speed varies from voxel to voxel, where a lookup's second
    // velocity read may be faster than anything in its own cell, and a jet
    // confined to one brick, where most cells do not move at all.
    bounds_hold_for_a_swirl(6.0, Vec3::ZERO, 0.05, false, (-0.25, 0.25));
    bounds_hold_for_a_swirl(3.0, Vec3::new(0.4, -0.3, 2.0), 0.05, true, (-0.25, 0.25));
    // Shutters that open or close at the frame: the time slabs are signed,
    // and a lookup reads only upstream (or only downstream) of itself.
    bounds_hold_for_a_swirl(3.0, Vec3::new(0.4, -0.3, -2.0), 0.05, true, (0.0, 0.5));
    bounds_hold_for_a_swirl(0.0, Vec3::new(0.0, 0.0, 3.2), 0.1, false, (-0.5, 0.0));
}

/// Checks the bounds at random points and times for the lumpy volume
/// moving with `speed` times the swirl plus `drift` (world units per
/// frame) with the shutter open over `(open, close)` frames, on velocity
/// voxels of `vel_h` world units; with `jet`, only the
/// velocity brick at (8, 8, 8) moves (no density there: at some times of
/// the shutter its lookups read the brick above it).
fn bounds_hold_for_a_swirl(
    speed: f32,
    drift: Vec3,
    vel_h: f64,
    jet: bool,
    (open, close): (f32, f32),
) {
    let h = 0.05f64;
    let mut state = 7u64;
    let mut rnd = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 40) as f32) / (1u64 << 24) as f32
    };
    let xf = DAffine3::from_scale(DVec3::splat(h));
    let mut dens = GridParts::new("density", 0.0f32, xf);
    let mut temp = GridParts::new("temperature", 0.0f32, xf);
    for o in [IVec3::ZERO, IVec3::new(8, 0, 0), IVec3::new(8, 8, 16)] {
        for p in [&mut dens, &mut temp] {
            p.brick_origins.push(o);
            p.masks.push([u64::MAX; 8]);
        }
        for _ in 0..512 {
            dens.values.push(rnd() * rnd());
            temp.values.push(3.0 * rnd());
        }
    }
    let mut vel = GridParts::new(
        "velocity",
        Vec3::ZERO,
        DAffine3::from_scale(DVec3::splat(vel_h)),
    );
    let bricks = if vel_h == h {
        [IVec3::ZERO, IVec3::new(8, 0, 0), IVec3::new(8, 8, 8)]
    } else {
        [IVec3::ZERO, IVec3::new(-8, 0, 0), IVec3::new(0, 8, 0)]
    };
    for o in bricks {
        vel.brick_origins.push(o);
        vel.masks.push([u64::MAX; 8]);
        for i in 0..512 {
            let l = Vec3::new((i >> 6) as f32, ((i >> 3) & 7) as f32, (i & 7) as f32);
            let v =
                Vec3::new(l.y - 3.5, 3.5 - l.x, 0.5 * l.z) * (0.05 + 0.1 * rnd()) * speed + drift;
            vel.values.push(if jet && o != IVec3::new(8, 8, 8) {
                Vec3::ZERO
            } else {
                v
            });
        }
    }
    let material = Material::Principled(Principled {
        density: 3.0,
        blackbody_intensity: 1.0,
        ..Principled::DEFAULT
    });
    let v = Volume::new(
        "swirl",
        Grid::from_parts(dens).unwrap(),
        ExtraGrids {
            temperature: Some(Grid::from_parts(temp).unwrap()),
            velocity: Some(VelocityField {
                grids: VelocityGrids::Vector(Grid::from_parts(vel).unwrap()),
                shutter: (open, close),
                per_frame: Vec3::ONE,
            }),
            ..Default::default()
        },
        material,
        DAffine3::IDENTITY,
    )
    .unwrap();
    let moved = v.motion().unwrap().max_displacement();
    assert!(
        moved > 0.1,
        "the test needs motion over several voxels: {moved}"
    );
    let media = Media::new(vec![v]);
    let (lo, hi) = media.bounds().unwrap();
    let mut checked = 0;
    let mut beyond_still = 0;
    let reach = open.abs().max(close.abs()) / 0.25;
    for _ in 0..(400_000.0 * speed.max(4.0) * reach) as usize {
        let p = lo + (hi - lo) * Vec3::new(rnd(), rnd(), rnd());
        let time = open + rnd() * (close - open);
        let m = media.eval(p, time);
        // The bounds at p: the segment of a short ray along x through it.
        let o = p - Vec3::X * 1e-3;
        let mut seg = None;
        media.for_each_segment_at(o, Vec3::X, 0.0, 2e-3, time, |s| {
            if s.t0 <= 1e-3 && 1e-3 < s.t1 {
                seg = Some(s);
            }
            true
        });
        let st = m.sigma_t().max_element();
        let e = m.emission.max_element();
        let Some(s) = seg else {
            assert!(
                st == 0.0 && e == 0.0,
                "{p} at {time}: sigma_t {st}, emission {e} where no cell is"
            );
            continue;
        };
        assert!(
            st <= s.max_density * (1.0 + 1e-5) + 1e-9,
            "{p} at {time}: sigma_t {st} above its majorant {}",
            s.max_density
        );
        assert!(
            m.sigma_t().min_element() >= s.min_density * (1.0 - 1e-5) - 1e-9,
            "{p} at {time}: sigma_t {st} below its minorant {}",
            s.min_density
        );
        assert!(
            e <= s.emission * (1.0 + 1e-5) + 1e-9,
            "{p} at {time}: emission {e} above its bound {}",
            s.emission
        );
        checked += (st > 0.0) as u32;
        beyond_still += (st > 0.0 && media.eval(p, 0.0).sigma_t().max_element() == 0.0) as u32;
    }
    assert!(checked > 15_000, "{checked}");
    assert!(beyond_still > 40, "{beyond_still}");
}

const BIN: &str = env!("CARGO_BIN_EXE_vdbphoton");

/// Renders `scene` (TOML text, written into `dir`) with the CLI: exit code,
/// stderr, and whether the output was written.
fn render_cli(dir: &std::path::Path, name: &str, scene: &str) -> (Option<i32>, String, bool) {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, scene).unwrap();
    let out_exr = dir.join(format!("{name}.exr"));
    let out = std::process::Command::new(BIN)
        .args([
            "render",
            path.to_str().unwrap(),
            "-o",
            out_exr.to_str().unwrap(),
        ])
        .args(["--width", "8", "--height", "6", "--spp", "1", "--quiet"])
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        out_exr.exists(),
    )
}

#[test]
fn bad_motion_blur_input_is_refused_in_one_line() {
    use vdbphoton::vdb::{write_vdb, AnyGrid};
    let dir = common::tempdir();
    let density = const_box(
        "density",
        1.0,
        DVec3::splat(-0.25),
        0.5 / 16.0,
        IVec3::splat(2),
    );
    let vel = |v: Vec3| {
        uniform_velocity(Vec3::ONE)
            .map_values("velocity", move |_| v)
            .unwrap()
    };
    let file = |name: &str, grids: Vec<AnyGrid>| {
        write_vdb(dir.path().join(name), &grids).unwrap();
    };
    file(
        "ok.vdb",
        vec![AnyGrid::Float(density.clone()), AnyGrid::Vec3(vel(Vec3::X))],
    );
    file(
        "nan.vdb",
        vec![
            AnyGrid::Float(density.clone()),
            AnyGrid::Vec3(vel(Vec3::new(f32::NAN, 0.0, 0.0))),
        ],
    );
    file(
        "fast.vdb",
        vec![
            AnyGrid::Float(density.clone()),
            AnyGrid::Vec3(vel(Vec3::new(1e6, 0.0, 0.0))),
        ],
    );
    let scene = |file: &str, render: &str, volume: &str| {
        format!(
            "[render]\nmotion_blur = true\n{render}\n[[volume]]\nfile = \"{}\"\n{volume}\n",
            dir.path().join(file).display()
        )
    };
    // (name, scene, what the one line must say)
    let cases = [
        (
            "missing",
            scene("ok.vdb", "", "velocity_grid = \"vel\""),
            vec![
                "[[volume]] 1",
                "no velocity grid 'vel'",
                "density, velocity",
            ],
        ),
        (
            "float",
            scene("ok.vdb", "", "velocity_grid = \"density\""),
            vec!["[[volume]] 1", "grid 'density'", "is a float grid", "vec3s"],
        ),
        (
            "nan",
            scene("nan.vdb", "", ""),
            vec!["[[volume]] 1", "grid 'velocity'", "NaN or infinite"],
        ),
        (
            "fast",
            scene("fast.vdb", "", ""),
            vec!["[[volume]] 1", "grid 'velocity'", "times its", "at most 4"],
        ),
        (
            "negative",
            scene("ok.vdb", "shutter = -0.5", ""),
            vec!["shutter", "[0, 1000]", "-0.5"],
        ),
        (
            "infinite",
            scene("ok.vdb", "shutter = inf", ""),
            vec!["shutter", "inf"],
        ),
        (
            "fps",
            scene("ok.vdb", "fps = 0", ""),
            vec!["fps", "more than 0"],
        ),
        (
            "scale",
            scene("ok.vdb", "", "velocity_scale = nan"),
            vec!["velocity_scale", "[[volume]]"],
        ),
        (
            "position",
            scene("ok.vdb", "shutter_position = \"middle\"", ""),
            vec!["shutter_position", "middle"],
        ),
    ];
    for (name, text, want) in cases {
        let (code, err, written) = render_cli(dir.path(), name, &text);
        eprintln!("{name}: {}", err.trim());
        assert_eq!(code, Some(1), "{name}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{name}: {err}");
        assert!(err.contains(&format!("{name}.toml")), "{name}: {err}");
        for w in want {
            assert!(err.contains(w), "{name}: '{w}' not in: {err}");
        }
        assert!(!written, "{name}: an output was written");
    }
    // The good file renders, and says in its header how it was blurred.
    let (code, err, written) = render_cli(dir.path(), "good", &scene("ok.vdb", "", ""));
    assert_eq!(code, Some(0), "{err}");
    assert!(written);
    let exr = exr::meta::MetaData::read_from_file(dir.path().join("good.exr"), false).unwrap();
    let attrs = format!("{:?}", exr.headers[0].own_attributes.other);
    assert!(
        attrs.contains("shutter 0.5 frames, center, 24 fps"),
        "{attrs}"
    );
}

fn run_ok(dir: &std::path::Path, args: &[&str]) {
    let out = std::process::Command::new(BIN)
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn exr_pixels(p: &std::path::Path) -> Vec<glam::Vec4> {
    vdbphoton::image::read_exr(p).unwrap().0.pixels().to_vec()
}

#[test]
fn tiles_and_sequence_frames_are_the_pixels_of_the_blurred_frame() {
    for integrator in ["path", "photon"] {
        let d = common::tempdir();
        let dir = d.path();
        run_ok(dir, &["generate", "plume", "p.vdb", "--res", "24"]);
        let scene = |blur: bool| {
            format!(
                "[render]\nwidth = 32\nheight = 24\nspp = 4\nintegrator = \"{integrator}\"\n\
                 aovs = true\nmotion_blur = {blur}\nshutter = 1.0\n\
                 output = \"o_{{frame:04}}.exr\"\n\
                 [render.photon]\nphotons = 3000\n\
                 [camera]\nframing = \"auto\"\n\
                 [[light]]\ntype = \"sun\"\ndirection = [0.3, -1.0, 1.0]\nirradiance = 2.0\n\
                 [[volume]]\nfile = \"p.vdb\"\ntemperature_grid = \"temperature\"\n\
                 velocity_scale = 24\n"
            )
        };
        std::fs::write(dir.join("mb.toml"), scene(true)).unwrap();
        std::fs::write(dir.join("still.toml"), scene(false)).unwrap();
        run_ok(
            dir,
            &["render", "mb.toml", "--frame", "3", "-o", "full.exr", "-q"],
        );
        run_ok(
            dir,
            &[
                "render",
                "still.toml",
                "--frame",
                "3",
                "-o",
                "still.exr",
                "-q",
            ],
        );
        let full = exr_pixels(&dir.join("full.exr"));
        assert_ne!(
            full,
            exr_pixels(&dir.join("still.exr")),
            "{integrator}: no blur"
        );
        for i in 0..4 {
            let tile = format!("{i}/4");
            run_ok(
                dir,
                &[
                    "render",
                    "mb.toml",
                    "--frame",
                    "3",
                    "--tile",
                    &tile,
                    "-o",
                    "t_{tile}.exr",
                    "-q",
                ],
            );
        }
        run_ok(
            dir,
            &["merge", "m.exr", "t_0.exr", "t_1.exr", "t_2.exr", "t_3.exr"],
        );
        let (m, _) = vdbphoton::image::read_exr(dir.join("m.exr")).unwrap();
        let (f, _) = vdbphoton::image::read_exr(dir.join("full.exr")).unwrap();
        assert_eq!(m.pixels(), f.pixels(), "{integrator}: merged tiles");
        assert_eq!(m.layers(), f.layers(), "{integrator}: merged AOVs");
        // A frame of a sequence is the frame rendered alone.
        run_ok(dir, &["render", "mb.toml", "--frames", "2-3", "-q"]);
        assert_eq!(exr_pixels(&dir.join("o_0003.exr")), full, "{integrator}");
    }
}

#[test]
fn the_shutter_position_moves_the_smear_before_around_or_after_the_frame() {
    // Moving 0.4 units per frame along +x with a shutter of 0.5 frames:
    // the emission's centroid sits where the box is at the shutter's
    // mid-time, +0.1, 0 and −0.1 units for start, center and end (the
    // smear stays inside the image).
    let px = H as f32 / (2.0 * 5.0 * 2f32.to_radians().tan());
    for (open, close, shift) in [(0.0, 0.5, 0.1), (-0.25, 0.25, 0.0), (-0.5, 0.0, -0.1)] {
        let mut w = world(moving_box(glow(2.0), 0.4 * Vec3::X, 0.5), vec![], None);
        w.camera = w.camera.with_shutter(Some(Shutter { open, close }));
        let row = row(&w, &mut PathIntegrator::new(8), 256, H / 2);
        let (s, sx) = row
            .iter()
            .enumerate()
            .fold((0.0, 0.0), |(s, sx), (x, (m, _))| {
                (s + m, sx + m * (x as f64 + 0.5))
            });
        let centroid = sx / s;
        let want = W as f64 / 2.0 + (shift * px) as f64;
        assert!(
            (centroid - want).abs() < 0.3,
            "shutter [{open}, {close}]: centroid {centroid:.2} px, expected {want:.2}"
        );
    }
}
