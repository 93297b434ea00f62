//! The seed corpus: generated grids of every supported type and storage
//! (written here, deterministic), the real files of `VDBPHOTON_REAL_DATA`
//! (read where they are, never copied), and the example scenes.

use glam::{DAffine3, DMat3, DQuat, DVec3, IVec3, Vec3};
use std::path::{Path, PathBuf};
use vdbphoton::generate;
use vdbphoton::grid::{Grid, GridParts, GridValue, Tile};
use vdbphoton::vdb::{reference, write_vdb, AnyGrid};

fn hand_grid<T: GridValue>(
    name: &str,
    xf: DAffine3,
    bricks: &[(IVec3, T)],
    tiles: Vec<Tile<T>>,
    background: T,
) -> Grid<T> {
    let mut values = Vec::new();
    let mut masks = Vec::new();
    for (i, (_, v)) in bricks.iter().enumerate() {
        values.extend(std::iter::repeat_n(*v, 512));
        // A few voxels active, a different pattern in each brick.
        let mut m = [0u64; 8];
        for (w, word) in m.iter_mut().enumerate() {
            *word = 0x0101_0101_0101_0101u64.rotate_left((i * 3 + w) as u32) | (1 << (w * 7));
        }
        masks.push(m);
    }
    Grid::from_parts(GridParts {
        name: name.into(),
        class: "fog volume".into(),
        background,
        world_from_index: xf,
        brick_origins: bricks.iter().map(|b| b.0).collect(),
        values: values.into(),
        masks,
        tiles,
    })
    .expect("seed grid")
}

fn tile<T>(origin: IVec3, level: u8, value: T, active: bool) -> Tile<T> {
    Tile {
        origin,
        level,
        value,
        active,
    }
}

/// Writes the generated seeds into `dir`; returns their paths.
pub fn write_generated(dir: &Path) -> Vec<PathBuf> {
    std::fs::create_dir_all(dir).expect("seed directory");
    let mut out = Vec::new();
    let mut put = |name: &str, grids: Vec<AnyGrid>| {
        let p = dir.join(name);
        write_vdb(&p, &grids).expect("write seed");
        out.push(p);
    };
    put(
        "cloud16.vdb",
        vec![AnyGrid::Float(generate::cloud(16, 1).unwrap())],
    );
    put(
        "cloud32.vdb",
        vec![AnyGrid::Float(generate::cloud(32, 2).unwrap())],
    );
    put("plume16.vdb", generate::plume(16, 1).unwrap());
    let scale = DAffine3::from_scale(DVec3::new(0.5, 0.25, 2.0));
    let affine = DAffine3 {
        matrix3: DMat3::from_quat(DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1))
            * DMat3::from_cols(
                DVec3::new(1.0, 0.2, 0.0),
                DVec3::Y,
                DVec3::new(0.1, 0.0, 0.8),
            ),
        translation: DVec3::new(3.0, -2.0, 0.5),
    };
    let bricks = [
        (IVec3::new(0, 0, 0), 0.5f32),
        (IVec3::new(8, 0, 0), 0.25),
        (IVec3::new(-16, 40, 8), 1.0),
    ];
    let tiles = vec![
        tile(IVec3::new(128, 0, 0), 2, 0.75f32, true),
        tile(IVec3::new(64, 8, 0), 1, 0.125, true),
        tile(IVec3::new(72, 8, 0), 1, 0.3, false),
        tile(IVec3::new(4096, 0, 0), 3, 0.05, true),
    ];
    put(
        "tiles_every_level.vdb",
        vec![AnyGrid::Float(hand_grid(
            "density",
            DAffine3::IDENTITY,
            &bricks,
            tiles,
            0.0,
        ))],
    );
    put(
        "empty.vdb",
        vec![AnyGrid::Float(hand_grid(
            "density",
            DAffine3::IDENTITY,
            &[],
            vec![],
            0.0,
        ))],
    );
    put(
        "nonuniform.vdb",
        vec![AnyGrid::Float(hand_grid(
            "density",
            scale,
            &bricks[..2],
            vec![],
            0.0,
        ))],
    );
    put(
        "affine.vdb",
        vec![AnyGrid::Float(hand_grid(
            "density",
            affine,
            &bricks,
            vec![],
            0.0,
        ))],
    );
    let vbricks = [
        (IVec3::new(0, 0, 0), Vec3::new(1.0, -2.0, 0.5)),
        (IVec3::new(0, 8, 0), Vec3::X),
    ];
    let several = vec![
        AnyGrid::Float(hand_grid("density", scale, &bricks, vec![], 0.0)),
        AnyGrid::Vec3(hand_grid(
            "color",
            scale,
            &vbricks,
            vec![tile(IVec3::new(128, 0, 0), 2, Vec3::splat(0.5), true)],
            Vec3::ZERO,
        )),
        AnyGrid::Float(hand_grid("temperature", scale, &bricks[1..], vec![], 0.0)),
        AnyGrid::Float(hand_grid("empty", scale, &[], vec![], 0.0)),
    ];
    put("several.vdb", several);
    for kind in [
        "half",
        "zip",
        "uncompressed",
        "inactive",
        "instance",
        "double",
        "int32",
        "frustum",
    ] {
        let p = dir.join(format!("fixture_{kind}.vdb"));
        reference::write_unsupported_fixture(&p, kind).expect("fixture");
        out.push(p);
    }
    out
}

/// The `.vdb` files under `dir` (recursively), sorted.
pub fn real_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(rd) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "vdb") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Example scenes: `scenes/`, `scripts/cycles/`, and the reference scenes
/// of the real-data folder.
pub fn scene_files(repo: &Path, real: Option<&Path>) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut dirs = vec![repo.join("scenes"), repo.join("scripts/cycles")];
    if let Some(r) = real {
        dirs.push(r.join("reference"));
    }
    for d in dirs {
        if let Ok(rd) = std::fs::read_dir(&d) {
            for e in rd.flatten() {
                let p = e.path();
                if p.extension().is_some_and(|x| x == "toml" || x == "json") {
                    out.push(p);
                }
            }
        }
    }
    out.sort();
    out
}
