//! Writing grids through the bridge and reading them back gives identical
//! values, active masks, tiles and transforms.

mod common;

use glam::{DVec3, IVec3, Vec3};
use vdbphoton::generate;
use vdbphoton::grid::{Grid, GridValue, Tile};
use vdbphoton::vdb::{write_vdb, AnyGrid, VdbFile};

fn assert_same<T: GridValue>(a: &Grid<T>, b: &Grid<T>) {
    assert_eq!(a.name(), b.name());
    assert_eq!(a.class(), b.class());
    assert_eq!(a.background(), b.background());
    assert_eq!(
        a.world_from_index(),
        b.world_from_index(),
        "transform of {}",
        a.name()
    );
    assert_eq!(
        a.brick_count(),
        b.brick_count(),
        "brick count of {}",
        a.name()
    );
    // Brick order may differ: match by origin.
    let index: std::collections::HashMap<IVec3, usize> = b
        .brick_origins()
        .iter()
        .enumerate()
        .map(|(i, o)| (*o, i))
        .collect();
    for (i, o) in a.brick_origins().iter().enumerate() {
        let j = index[o];
        assert_eq!(a.brick_mask(i), b.brick_mask(j), "mask of brick at {o}");
        let (va, vb) = (a.brick_values(i), b.brick_values(j));
        for k in 0..va.len() {
            // Bit-identical, NaN-safe.
            assert!(
                T::to_flat(&va[k..k + 1])
                    .iter()
                    .zip(T::to_flat(&vb[k..k + 1]))
                    .all(|(x, y)| x.to_bits() == y.to_bits()),
                "value {k} of brick at {o}: {:?} vs {:?}",
                va[k],
                vb[k]
            );
        }
    }
    let mut ta: Vec<_> = a.tiles().to_vec();
    let mut tb: Vec<_> = b.tiles().to_vec();
    let key = |t: &Tile<T>| (t.level, t.origin.x, t.origin.y, t.origin.z);
    ta.sort_by_key(key);
    tb.sort_by_key(key);
    assert_eq!(ta, tb, "tiles of {}", a.name());
    assert_eq!(a.active_voxel_count(), b.active_voxel_count());
    a.validate().unwrap();
    b.validate().unwrap();
}

#[test]
fn hand_built_grid_reads_back_identical() {
    let dir = common::tempdir();
    let path = dir.path().join("tiles.vdb");
    let g = common::hand_built();
    assert_eq!(g.tiles().len(), 4);
    // Voxel lookups see every level of tile.
    assert_eq!(g.get(IVec3::new(5, 100, 127)), 0.75);
    assert_eq!(g.get(IVec3::new(130, 3, 7)), 0.25);
    assert_eq!(g.get(IVec3::new(-1, -1, 100)), 0.125);
    assert_eq!(g.get(IVec3::new(-5000, 0, 0)), 0.0);
    assert!(!g.is_active(IVec3::new(137, 9, 1)));
    assert_eq!(g.get(IVec3::new(137, 9, 1)), 0.5);
    write_vdb(&path, &[AnyGrid::Float(g.clone())]).unwrap();
    let back = VdbFile::open(&path).unwrap().read_float("tiles").unwrap();
    assert_same(&g, &back);
    assert_eq!(back.active_voxel_count(), g.active_voxel_count());
    assert_eq!(
        g.active_voxel_count(),
        128u64.pow(3)
            + 512
            + 4096u64.pow(3)
            + (0..4)
                .map(|b| g
                    .brick_mask(b)
                    .iter()
                    .map(|w| w.count_ones() as u64)
                    .sum::<u64>())
                .sum::<u64>()
    );
}

#[test]
fn generated_cloud_reads_back_identical() {
    let dir = common::tempdir();
    let path = dir.path().join("cloud.vdb");
    let g = generate::cloud(64, 3).unwrap();
    assert!(g.brick_count() > 50, "cloud has {} bricks", g.brick_count());
    assert!(
        !g.tiles().is_empty(),
        "the saturated core should become tiles"
    );
    write_vdb(&path, &[AnyGrid::Float(g.clone())]).unwrap();
    let f = VdbFile::open(&path).unwrap();
    assert_eq!(f.grid_names(), vec!["density"]);
    assert_same(&g, &f.read_float("density").unwrap());
    // The file records us as its creator.
    assert!(f
        .header()
        .meta_string("creator")
        .unwrap()
        .starts_with("vdbphoton"));
}

#[test]
fn generated_plume_reads_back_identical() {
    let dir = common::tempdir();
    let path = dir.path().join("plume.vdb");
    let grids = generate::plume(48, 5).unwrap();
    write_vdb(&path, &grids).unwrap();
    let f = VdbFile::open(&path).unwrap();
    assert_eq!(
        f.grid_names(),
        vec!["velocity", "density", "flame", "temperature"]
    );
    for g in &grids {
        match (g, f.read_any(g.name()).unwrap()) {
            (AnyGrid::Float(a), AnyGrid::Float(b)) => assert_same(a, &b),
            (AnyGrid::Vec3(a), AnyGrid::Vec3(b)) => assert_same(a, &b),
            _ => panic!("type changed for {}", g.name()),
        }
    }
    // Blender's relation between flame and temperature holds voxel by voxel.
    let flame = f.read_float("flame").unwrap();
    let temp = f.read_float("temperature").unwrap();
    let mut checked = 0;
    for b in 0..flame.brick_count() {
        let o = flame.brick_origins()[b];
        for (v, &fl) in flame.brick_values(b).iter().enumerate() {
            let ijk = o + IVec3::new((v >> 6) as i32, ((v >> 3) & 7) as i32, (v & 7) as i32);
            let want = if fl > 0.01 { 1.5 + 1.5 * fl } else { 0.0 };
            assert_eq!(temp.get(ijk), want);
            checked += 1;
        }
    }
    assert!(checked > 1000);
    // A pure-scale transform with index 0 at the domain's corner.
    assert_eq!(flame.world_from_index().translation, DVec3::ZERO);
    let v: Grid<Vec3> = f.read_vec3("velocity").unwrap();
    assert!(v.active_voxel_count() > 0);
}

#[test]
fn generation_is_deterministic_and_seeded() {
    let a = generate::cloud(32, 11).unwrap();
    let b = generate::cloud(32, 11).unwrap();
    let c = generate::cloud(32, 12).unwrap();
    assert_same(&a, &b);
    let sum = |g: &Grid<f32>| {
        (0..g.brick_count())
            .map(|i| g.brick_values(i).iter().sum::<f32>())
            .sum::<f32>()
    };
    assert_ne!(sum(&a), sum(&c));
    // The same on one thread as on the default pool.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let d = pool.install(|| generate::cloud(32, 11).unwrap());
    assert_same(&a, &d);
}

#[test]
fn double_grid_reads_as_f32() {
    let dir = common::tempdir();
    let path = dir.path().join("double.vdb");
    vdbphoton::vdb::reference::write_unsupported_fixture(&path, "double").unwrap();
    let f = VdbFile::open(&path).unwrap();
    assert_eq!(f.descriptor("density").unwrap().value_type(), "double");
    let g = f.read_float("density").unwrap();
    for i in 0..20 {
        let want = (0.1 + 0.037 * i as f64 + 1e-12 * i as f64) as f32;
        assert_eq!(g.get(IVec3::new(i, 2 * i - 10, 3)), want);
        assert!(g.is_active(IVec3::new(i, 2 * i - 10, 3)));
    }
    assert_eq!(g.get(IVec3::new(5, 5, 5)), 0.75);
    assert!(!g.is_active(IVec3::new(5, 5, 5)));
    assert_eq!(g.get(IVec3::new(70, 3, 1)), 2.5);
    assert_eq!(g.active_voxel_count(), 20 + 512);
    // Trilinear samples agree with OpenVDB's sampler on the double grid to
    // the f32 precision of the values (we convert them to f32 on reading,
    // OpenVDB interpolates in double): 1e-6 of the largest value, 2.5.
    let mut rng = common::TestRng(3);
    let pts: Vec<DVec3> = (0..2000)
        .map(|_| {
            DVec3::new(
                rng.range(-1.0, 20.0),
                rng.range(-4.0, 8.0),
                rng.range(-1.0, 2.0),
            )
        })
        .collect();
    let theirs = vdbphoton::vdb::reference::box_sample_world(&path, "density", &pts).unwrap();
    for (p, b) in pts.iter().zip(&theirs) {
        let a = g.sample_world(*p);
        assert!((a - b).abs() <= 2.5e-6, "at {p}: {a} vs {b}");
    }
    // It is a scalar grid, so asking for a vector grid is an error naming it.
    let e = f.read_vec3("density").unwrap_err().to_string();
    assert!(e.contains("density") && e.contains("double"), "{e}");
}
