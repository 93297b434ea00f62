//! Our trilinear sampling against OpenVDB's own `BoxSampler`, called through
//! the bridge: 100,000 random world points per grid, equal to 1e-6 relative.

mod common;

use glam::{DAffine3, DVec3, IVec3, Vec3};
use std::path::Path;
use vdbphoton::generate;
use vdbphoton::grid::{Grid, GridParts, GridValue, Tile};
use vdbphoton::vdb::{reference, write_vdb, AnyGrid, VdbFile};

const POINTS: usize = 100_000;

/// Random world points over the stored region padded by 3 voxels (so the
/// boundary and the background around it are exercised), and a quarter of
/// them placed exactly on voxel centres and cell faces.
fn points<T: GridValue>(g: &Grid<T>, seed: u64) -> Vec<DVec3> {
    let (lo, hi) = g.stored_bounds().expect("grid is empty");
    let lo = lo.as_dvec3() - 3.0;
    let hi = hi.as_dvec3() + 3.0;
    let mut rng = common::TestRng(seed);
    (0..POINTS)
        .map(|i| {
            let mut p = rng.point(lo, hi);
            if i % 4 == 0 {
                p = p.round();
            } else if i % 4 == 1 {
                p.x = p.x.floor() + 0.5;
            }
            g.world_from_index().transform_point3(p)
        })
        .collect()
}

fn compare<T: GridValue>(g: &Grid<T>, file: &Path, seed: u64) -> f64 {
    let pts = points(g, seed);
    let ours: Vec<f32> = pts
        .iter()
        .flat_map(|p| T::to_flat(&[g.sample_world(*p)]))
        .collect();
    let theirs = reference::box_sample_world(file, g.name(), &pts).unwrap();
    assert_eq!(ours.len(), theirs.len());
    let mut worst = 0.0f64;
    for (i, (a, b)) in ours.iter().zip(&theirs).enumerate() {
        let (a, b) = (*a as f64, *b as f64);
        let rel = (a - b).abs() / b.abs().max(1e-6);
        assert!(
            rel <= 1e-6,
            "{} in {}: point {} ({:?}): ours {a}, OpenVDB {b}",
            g.name(),
            file.display(),
            i / T::CHANNELS,
            pts[i / T::CHANNELS]
        );
        worst = worst.max(rel);
    }
    // The samples are not all background: the test compares real values.
    let nonzero = theirs.iter().filter(|v| **v != 0.0).count();
    assert!(
        nonzero > theirs.len() / 100,
        "{}: only {nonzero} nonzero samples",
        g.name()
    );
    worst
}

fn compare_file(path: &Path) {
    let f = VdbFile::open(path).unwrap();
    let mut n = 0;
    for (k, d) in f.header().grids.iter().enumerate() {
        if d.channels().is_none() {
            continue;
        }
        let worst = match f.read_any(&d.name).unwrap() {
            AnyGrid::Float(g) => compare(&g, path, k as u64 + 1),
            AnyGrid::Vec3(g) => compare(&g, path, k as u64 + 1),
        };
        eprintln!(
            "{} / {}: worst relative difference {worst:.2e}",
            path.display(),
            d.name
        );
        n += 1;
    }
    assert!(n > 0, "{} has no readable grid", path.display());
}

#[test]
fn generated_cloud_matches_box_sampler() {
    let dir = common::tempdir();
    let path = dir.path().join("cloud.vdb");
    write_vdb(&path, &[AnyGrid::Float(generate::cloud(64, 9).unwrap())]).unwrap();
    compare_file(&path);
}

#[test]
fn generated_plume_matches_box_sampler() {
    let dir = common::tempdir();
    let path = dir.path().join("plume.vdb");
    write_vdb(&path, &generate::plume(40, 2).unwrap()).unwrap();
    compare_file(&path);
}

#[test]
fn tiles_at_two_levels_match_box_sampler() {
    let dir = common::tempdir();
    let path = dir.path().join("tiles.vdb");
    let g = common::hand_built();
    write_vdb(&path, &[AnyGrid::Float(g.clone())]).unwrap();
    // Points near the small tiles and bricks (the root tile is huge).
    let mut rng = common::TestRng(5);
    let pts: Vec<DVec3> = (0..POINTS)
        .map(|_| {
            let p = DVec3::new(
                rng.range(-12.0, 150.0),
                rng.range(-12.0, 140.0),
                rng.range(-12.0, 20.0),
            );
            g.world_from_index().transform_point3(p)
        })
        .collect();
    let theirs = reference::box_sample_world(&path, "tiles", &pts).unwrap();
    for (p, b) in pts.iter().zip(&theirs) {
        let a = g.sample_world(*p);
        assert!(
            (a - b).abs() as f64 <= 1e-6 * (b.abs() as f64).max(1e-6),
            "at {p}: {a} vs {b}"
        );
    }
    let distinct: std::collections::BTreeSet<u32> = theirs.iter().map(|v| v.to_bits()).collect();
    assert!(distinct.len() > 1000);
}

#[test]
fn single_precision_index_path_agrees() {
    // The renderer's f32 path in index space agrees with the f64 path.
    let g = generate::cloud(48, 4).unwrap();
    let (lo, hi) = g.stored_bounds().unwrap();
    let mut rng = common::TestRng(3);
    for _ in 0..POINTS {
        let p = rng.point(lo.as_dvec3(), hi.as_dvec3());
        let a = g.sample_index(p.as_vec3());
        let b = g.sample_index_f64(p);
        assert!((a - b).abs() < 2e-5, "at {p}: {a} vs {b}");
    }
}

/// `sample_index_batch`, and its scalar path alone, return `sample_index`
/// bit for bit at `pts`, in batches of every length from 0 to 40 and in one
/// batch of all of them.
fn check_batch<T: GridValue>(g: &Grid<T>, pts: &[Vec3]) {
    let bits = |v: T| {
        T::to_flat(&[v])
            .iter()
            .map(|f| f.to_bits())
            .collect::<Vec<_>>()
    };
    let single: Vec<T> = pts.iter().map(|p| g.sample_index(*p)).collect();
    type Batch<T> = fn(&Grid<T>, &[Vec3], &mut [T]);
    let paths: [(&str, Batch<T>); 2] = [
        ("sample_index_batch", Grid::sample_index_batch),
        ("sample_index_batch_scalar", Grid::sample_index_batch_scalar),
    ];
    for (name, batch) in paths {
        let mut out = vec![T::zero(); pts.len()];
        batch(g, pts, &mut out);
        for (i, p) in pts.iter().enumerate() {
            assert_eq!(bits(out[i]), bits(single[i]), "{name} at {p} (point {i})");
        }
        let mut start = 0;
        for len in (0..=40).cycle() {
            let end = (start + len).min(pts.len());
            let mut out = vec![T::zero(); end - start];
            batch(g, &pts[start..end], &mut out);
            for (k, v) in out.iter().enumerate() {
                assert_eq!(
                    bits(*v),
                    bits(single[start + k]),
                    "{name}, batch of {len}, point {}",
                    start + k
                );
            }
            start = end;
            if start == pts.len() {
                break;
            }
        }
    }
}

/// Points over the stored region padded by 10 voxels: half at random, half
/// in the last voxel of a block along one, two or three axes (the cells
/// whose corners span two, four or eight blocks), with far and NaN points
/// mixed in.
fn batch_points(lo: IVec3, hi: IVec3, seed: u64) -> Vec<Vec3> {
    let (lo, hi) = (lo.as_dvec3() - 10.0, hi.as_dvec3() + 10.0);
    let mut rng = common::TestRng(seed);
    (0..20_011)
        .map(|i| {
            let mut p = rng.point(lo, hi);
            if i % 2 == 1 {
                let axes = rng.next_u64();
                for a in 0..3 {
                    if axes >> a & 1 == 1 {
                        p[a] = (p[a] / 8.0).floor() * 8.0 + 7.0 + rng.f64();
                    }
                }
            }
            match i % 97 {
                13 => Vec3::new(f32::NAN, 1.0, 2.0),
                29 => Vec3::new(0.0, -3e9, 0.0),
                _ => p.as_vec3(),
            }
        })
        .collect()
}

/// Bricks, 8^3 tiles (active or not) and a 128^3 tile over a compact
/// extent, so the grid has the flat index (the vector path's case).
fn tiles_with_flat_index() -> Grid<f32> {
    let mut p = GridParts::new("mixed", 0.25f32, DAffine3::IDENTITY);
    let mut rng = common::TestRng(11);
    let mut used = std::collections::HashSet::new();
    p.tiles.push(Tile {
        origin: IVec3::new(128, 0, 0),
        level: 2,
        value: 3.0,
        active: true,
    });
    for n in 0..700 {
        let o = IVec3::new(
            (rng.next_u64() % 16) as i32,
            (rng.next_u64() % 16) as i32,
            (rng.next_u64() % 16) as i32,
        ) * 8;
        if !used.insert(o) {
            continue;
        }
        if n % 3 == 0 {
            p.tiles.push(Tile {
                origin: o,
                level: 1,
                value: rng.range(0.0, 4.0) as f32,
                active: n % 2 == 0,
            });
        } else {
            p.brick_origins.push(o);
            p.masks.push([u64::MAX; 8]);
            p.values
                .extend((0..512).map(|_| rng.range(-0.5, 2.0) as f32));
        }
    }
    let g = Grid::from_parts(p).unwrap();
    assert!(g.has_flat_index());
    g
}

#[test]
fn batched_lookups_equal_single_lookups() {
    // A grid with tiles at two levels and the two-level index, one with
    // tiles and the flat index, a generated cloud, and a vec3s grid; the
    // batched path with and without its vector version (`check_batch`).
    for (g, seed) in [
        (common::hand_built(), 1),
        (tiles_with_flat_index(), 4),
        (generate::cloud(48, 2).unwrap(), 2),
    ] {
        let (lo, hi) = g.stored_bounds().unwrap();
        let pts = batch_points(lo, hi, seed);
        assert_eq!(g.has_flat_index(), seed != 1);
        check_batch(&g, &pts);
    }
    // Non-finite values: results agree, NaN only as NaN (see the method's
    // documentation).
    let mut g = tiles_with_flat_index().to_parts();
    for (k, v) in g.values.iter_mut().enumerate() {
        match k % 37 {
            0 => *v = f32::NAN,
            1 => *v = f32::INFINITY,
            2 => *v = f32::NEG_INFINITY,
            _ => {}
        }
    }
    let g = Grid::from_parts(g).unwrap();
    let (lo, hi) = g.stored_bounds().unwrap();
    let pts = batch_points(lo, hi, 5);
    let mut out = vec![0.0; pts.len()];
    g.sample_index_batch(&pts, &mut out);
    let mut nan = 0;
    for (p, v) in pts.iter().zip(&out) {
        let want = g.sample_index(*p);
        if want.is_nan() {
            nan += 1;
            assert!(v.is_nan(), "at {p}: {v} where {want} was expected");
        } else {
            assert_eq!(v.to_bits(), want.to_bits(), "at {p}");
        }
    }
    assert!(
        nan > 100,
        "only {nan} NaN results: the case is not exercised"
    );
    let grids = generate::plume(32, 3).unwrap();
    let vel = grids
        .iter()
        .find_map(|g| match g {
            AnyGrid::Vec3(v) => Some(v),
            _ => None,
        })
        .expect("the plume has a vec3s grid");
    let (lo, hi) = vel.stored_bounds().unwrap();
    check_batch(vel, &batch_points(lo, hi, 3));
}

#[test]
fn far_and_nan_points_read_the_background() {
    // Points beyond ±2^30 in index space and NaN read the background rather
    // than wrapping around to some voxel (the lookup converts to integers
    // without saturation after a range check).
    for g in [common::hand_built(), generate::cloud(40, 8).unwrap()] {
        for p in [
            Vec3::new(3e9, 0.0, 0.0),
            Vec3::new(0.0, -2e9, 5.0),
            Vec3::new(1.0, 2.0, f32::INFINITY),
            Vec3::new(f32::NAN, 0.0, 0.0),
            Vec3::new(4.0, f32::NAN, 1.0),
        ] {
            assert_eq!(g.sample_index(p), g.background(), "at {p}");
        }
        // Just inside the range check, far outside the data: background.
        assert_eq!(g.sample_index(Vec3::splat(1.0e9)), g.background());
        // The double-precision path too (its integer cast would saturate).
        for p in [
            DVec3::new(1e12, 0.0, 0.0),
            DVec3::new(0.0, -3e9, 0.0),
            DVec3::new(f64::NAN, 0.0, 0.0),
            DVec3::new(0.0, 0.0, f64::NEG_INFINITY),
        ] {
            assert_eq!(g.sample_index_f64(p), g.background(), "at {p}");
            let w = g.world_from_index().transform_point3(p);
            assert_eq!(g.sample_world(w), g.background(), "at {p}");
        }
    }
}

#[test]
fn block_lookup_ranges_are_exact() {
    // The range of each 8^3 block with its +x/+y/+z apron (the voxels a
    // lookup in the block reads) equals the brute-force range of those
    // 9^3 voxels, across bricks, tiles of two levels and empty space.
    let grids = [common::hand_built(), generate::cloud(40, 8).unwrap()];
    for g in &grids {
        let (lo, hi) = g.stored_bounds().unwrap();
        let (lo, hi): (IVec3, IVec3) = ((lo >> 3i32) - 1, (hi >> 3i32) + 1);
        let (lo, hi) = (lo.max(IVec3::splat(-6)), hi.min(IVec3::splat(24)));
        let mut checked = 0;
        for bx in lo.x..=hi.x {
            for by in lo.y..=hi.y {
                for bz in lo.z..=hi.z {
                    let o = IVec3::new(bx, by, bz) * 8;
                    let (mut vmin, mut vmax) = (f32::MAX, f32::MIN);
                    for x in 0..=8 {
                        for y in 0..=8 {
                            for z in 0..=8 {
                                let v = g.get(o + IVec3::new(x, y, z));
                                vmin = vmin.min(v);
                                vmax = vmax.max(v);
                            }
                        }
                    }
                    assert_eq!(g.block_lookup_range(o), [vmin, vmax], "block at {o}");
                    checked += 1;
                }
            }
        }
        assert!(checked > 200, "only {checked} blocks");
    }
}

#[test]
fn range_in_box_bounds_every_lookup() {
    // The brick ranges that majorants are built from bound every voxel in
    // any box, including boxes that straddle tiles, bricks and empty space.
    let grids = [common::hand_built(), generate::cloud(40, 8).unwrap()];
    let mut rng = common::TestRng(99);
    for g in &grids {
        g.validate().unwrap();
        let (lo, hi) = g.stored_bounds().unwrap();
        let (lo, hi) = (lo.max(IVec3::splat(-40)), hi.min(IVec3::splat(200)));
        for _ in 0..300 {
            let a = IVec3::new(
                rng.range(lo.x as f64 - 10.0, hi.x as f64) as i32,
                rng.range(lo.y as f64 - 10.0, hi.y as f64) as i32,
                rng.range(lo.z as f64 - 10.0, hi.z as f64) as i32,
            );
            let b = a + IVec3::new(
                rng.range(0.0, 20.0) as i32,
                rng.range(0.0, 20.0) as i32,
                rng.range(0.0, 20.0) as i32,
            );
            let [mn, mx] = g.range_in_box(a, b).unwrap();
            let (mut vmin, mut vmax) = (f32::MAX, f32::MIN);
            for x in a.x..=b.x {
                for y in a.y..=b.y {
                    for z in a.z..=b.z {
                        let v = g.get(IVec3::new(x, y, z));
                        vmin = vmin.min(v);
                        vmax = vmax.max(v);
                    }
                }
            }
            assert!(
                mn <= vmin && mx >= vmax,
                "box {a}..{b}: range [{mn}, {mx}] vs values [{vmin}, {vmax}]"
            );
        }
    }
}

#[test]
fn real_files_match_box_sampler() {
    let Some(dir) = common::real_data() else {
        return;
    };
    let mut files = vec![dir.join("cloud96.vdb")];
    for sub in ["external", "blender_smoke"] {
        let mut v: Vec<_> = std::fs::read_dir(dir.join(sub))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "vdb"))
            .collect();
        v.sort();
        assert!(!v.is_empty(), "no .vdb files in {sub}");
        files.extend(v);
    }
    for f in &files {
        compare_file(f);
    }
    assert!(files.len() >= 8);
}
