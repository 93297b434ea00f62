//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod chi2;
pub mod quad;

use glam::{DAffine3, DQuat, DVec3, IVec3};
use std::path::{Path, PathBuf};
use vdbphoton::grid::{Grid, GridParts, Tile};

/// A small deterministic RNG for test inputs (SplitMix64).
pub struct TestRng(pub u64);

impl TestRng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f64()
    }
    /// A uniform point in the box `[lo, hi)`.
    pub fn point(&mut self, lo: DVec3, hi: DVec3) -> DVec3 {
        DVec3::new(
            self.range(lo.x, hi.x),
            self.range(lo.y, hi.y),
            self.range(lo.z, hi.z),
        )
    }
}

/// The real-data folder from `VDBPHOTON_REAL_DATA`. `None` (with a note)
/// when the variable is unset; a panic when it is set but the folder is
/// missing, so CI cannot pass by skipping.
pub fn real_data() -> Option<PathBuf> {
    match std::env::var_os("VDBPHOTON_REAL_DATA") {
        None => {
            eprintln!(
                "note: VDBPHOTON_REAL_DATA is not set; skipping the real-data part of this test"
            );
            None
        }
        Some(p) => {
            // Absolute, so that scenes written elsewhere can name it.
            let p = PathBuf::from(p);
            let p = std::path::absolute(&p).unwrap_or(p);
            assert!(
                p.join("cloud96.vdb").is_file(),
                "VDBPHOTON_REAL_DATA={} does not hold cloud96.vdb",
                p.display()
            );
            Some(p)
        }
    }
}

/// The names in `dir`, sorted (to check that no temporary file is left).
pub fn dir_entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// The channel names of an EXR part, in the file's (sorted) order.
pub fn channel_names(header: &exr::meta::header::Header) -> Vec<String> {
    header
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect()
}

pub fn tempdir() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("vdbphoton-test")
        .tempdir()
        .unwrap()
}

/// A hand-built grid with tiles at every level, bricks with partial masks,
/// an inactive non-background tile, negative coordinates and a rotated,
/// translated, non-uniformly scaled transform.
pub fn hand_built() -> Grid<f32> {
    let xf = DAffine3::from_scale_rotation_translation(
        DVec3::new(0.05, 0.07, 0.04),
        DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.2, 0.9),
        DVec3::new(1.5, -2.0, 0.25),
    );
    let mut p = GridParts::new("tiles", 0.0f32, xf);
    p.tiles.push(Tile {
        origin: IVec3::new(0, 0, 0),
        level: 2,
        value: 0.75,
        active: true,
    });
    p.tiles.push(Tile {
        origin: IVec3::new(128, 0, 0),
        level: 1,
        value: 0.25,
        active: true,
    });
    p.tiles.push(Tile {
        origin: IVec3::new(136, 8, 0),
        level: 1,
        value: 0.5,
        active: false,
    });
    p.tiles.push(Tile {
        origin: IVec3::new(-4096, -4096, 0),
        level: 3,
        value: 0.125,
        active: true,
    });
    let mut rng = TestRng(7);
    for o in [
        IVec3::new(128, 8, 0),
        IVec3::new(-8, -8, -8),
        IVec3::new(120, 128, 0),
        IVec3::new(136, 0, 8),
    ] {
        p.brick_origins.push(o);
        let mut mask = [0u64; 8];
        for v in 0..512 {
            let x = rng.f64() as f32;
            p.values.push(if x < 0.2 { 0.0 } else { x });
            if x >= 0.2 {
                mask[v >> 6] |= 1 << (v & 63);
            }
        }
        p.masks.push(mask);
    }
    Grid::from_parts(p).unwrap()
}

/// A box of constant density 1 filling [-1, 1]^3 (a 128^3 tile; trilinear
/// ramps of one voxel outside it integrate to exactly the sharp box along
/// any axis-aligned line).
pub fn unit_box_grid() -> Grid<f32> {
    let h = 2.0 / 128.0;
    let xf = DAffine3::from_scale_rotation_translation(
        DVec3::splat(h),
        DQuat::IDENTITY,
        DVec3::splat(-1.0 + 0.5 * h),
    );
    let mut p = GridParts::new("density", 0.0f32, xf);
    p.tiles.push(Tile {
        origin: IVec3::ZERO,
        level: 2,
        value: 1.0,
        active: true,
    });
    Grid::from_parts(p).unwrap()
}

/// A grid named `name` holding `value` over `blocks` 8^3 blocks of voxels of
/// edge `h` whose box starts at world point `lo` (voxel (0,0,0) centred at
/// `lo + h/2`), stored as 8^3 tiles. Like [`unit_box_grid`], its trilinear
/// ramps integrate to the sharp box along axis-aligned lines.
pub fn const_box(name: &str, value: f32, lo: DVec3, h: f64, blocks: IVec3) -> Grid<f32> {
    let xf = DAffine3::from_scale_rotation_translation(
        DVec3::splat(h),
        DQuat::IDENTITY,
        lo + DVec3::splat(0.5 * h),
    );
    let mut p = GridParts::new(name, 0.0f32, xf);
    for x in 0..blocks.x {
        for y in 0..blocks.y {
            for z in 0..blocks.z {
                p.tiles.push(Tile {
                    origin: IVec3::new(x, y, z) * 8,
                    level: 1,
                    value,
                    active: true,
                });
            }
        }
    }
    Grid::from_parts(p).unwrap()
}

/// A grid with nothing stored, with the transform of [`unit_box_grid`].
pub fn empty_grid(name: &str) -> Grid<f32> {
    let h = 2.0 / 128.0;
    let xf = DAffine3::from_scale_rotation_translation(
        DVec3::splat(h),
        DQuat::IDENTITY,
        DVec3::splat(-1.0 + 0.5 * h),
    );
    Grid::from_parts(GridParts::new(name, 0.0f32, xf)).unwrap()
}

/// A ball of density 1 and radius `radius` centred at the origin, on
/// `n`^3 voxels (`n` a multiple of 8) spanning [−radius, radius]^3; a
/// voxel holds the share of 4^3 points spread over it that fall inside
/// the ball, so the edge is smooth to a voxel.
pub fn ball_grid(radius: f64, n: i32) -> Grid<f32> {
    assert!(n > 0 && n % 8 == 0, "n must be a positive multiple of 8");
    let h = 2.0 * radius / n as f64;
    let xf = DAffine3::from_scale_rotation_translation(
        DVec3::splat(h),
        DQuat::IDENTITY,
        DVec3::splat(-radius + 0.5 * h),
    );
    let mut p = GridParts::new("density", 0.0f32, xf);
    let cover = |i: IVec3| {
        let mut inside = 0;
        for s in 0..64 {
            let o = DVec3::new((s & 3) as f64, ((s >> 2) & 3) as f64, (s >> 4) as f64);
            let q = (i.as_dvec3() + (o + 0.5) / 4.0) * h - DVec3::splat(radius);
            if q.length_squared() <= radius * radius {
                inside += 1;
            }
        }
        inside as f32 / 64.0
    };
    for bx in 0..n / 8 {
        for by in 0..n / 8 {
            for bz in 0..n / 8 {
                let origin = IVec3::new(bx, by, bz) * 8;
                let mut mask = [0u64; 8];
                let mut any = false;
                let mut values = [0.0f32; 512];
                for (v, value) in values.iter_mut().enumerate() {
                    let l = IVec3::new((v >> 6) as i32, ((v >> 3) & 7) as i32, (v & 7) as i32);
                    *value = cover(origin + l);
                    if *value > 0.0 {
                        mask[v >> 6] |= 1 << (v & 63);
                        any = true;
                    }
                }
                if any {
                    p.brick_origins.push(origin);
                    p.values.extend_from_slice(&values);
                    p.masks.push(mask);
                }
            }
        }
    }
    Grid::from_parts(p).unwrap()
}
