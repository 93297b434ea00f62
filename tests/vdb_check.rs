//! The walk of a grid's bytes (`vdb::check`): every storage variant OpenVDB
//! writes reads back as OpenVDB reads it, and damaged lengths, counts and
//! flags are refused with one line naming the file and the grid.

mod common;

use glam::DVec3;
use std::path::Path;
use std::process::Command;
use vdbphoton::generate;
use vdbphoton::vdb::{file_fields, FieldKind};
use vdbphoton::vdb::{reference, write_vdb, AnyGrid, VdbFile};

const BIN: &str = env!("CARGO_BIN_EXE_vdbphoton");

/// Reads `grid` of `path` with vdbphoton and compares it with OpenVDB's
/// own sampler at random points of the active region.
fn assert_reads_as_openvdb(path: &Path, grid: &str) {
    let f = VdbFile::open(path).unwrap();
    let g = f.read_float(grid).unwrap();
    let (lo, hi) = g.active_bounds().unwrap();
    let xf = g.world_from_index();
    let mut rng = common::TestRng(7);
    let pts: Vec<DVec3> = (0..2000)
        .map(|_| {
            let p = rng.point(lo.as_dvec3() - 2.0, hi.as_dvec3() + 2.0);
            xf.transform_point3(p)
        })
        .collect();
    let want = reference::box_sample_world(path, grid, &pts).unwrap();
    for (p, w) in pts.iter().zip(&want) {
        let got = g.sample_world(*p);
        assert!(
            (got - w).abs() <= 1e-6 * w.abs().max(1.0),
            "{}: {got} vs OpenVDB {w} at {p}",
            path.display()
        );
    }
}

#[test]
fn every_storage_variant_reads_as_openvdb_reads_it() {
    let dir = common::tempdir();
    for kind in [
        "half",
        "zip",
        "uncompressed",
        "inactive",
        "instance",
        "double",
    ] {
        let p = dir.path().join(format!("{kind}.vdb"));
        reference::write_unsupported_fixture(&p, kind).unwrap();
        assert_reads_as_openvdb(&p, "density");
    }
}

#[test]
fn an_instance_reads_its_parents_tree_with_its_own_transform() {
    let dir = common::tempdir();
    let p = dir.path().join("instance.vdb");
    reference::write_unsupported_fixture(&p, "instance").unwrap();
    let f = VdbFile::open(&p).unwrap();
    assert_eq!(f.grid_names(), ["density", "density_copy"]);
    assert!(!f.header().grids[1].instance_parent.is_empty());
    let a = f.read_float("density").unwrap();
    let b = f.read_float("density_copy").unwrap();
    assert_eq!(a.active_voxel_count(), b.active_voxel_count());
    assert_eq!(b.name(), "density_copy");
    assert_eq!(b.world_from_index().matrix3.x_axis.x, 0.5);
    assert_eq!(a.world_from_index().matrix3.x_axis.x, 1.0);
    let info = f.info().unwrap();
    assert_eq!(info.grids[1].voxel_size, [0.5; 3]);
}

fn info_of(path: &Path) -> (i32, String) {
    let out = Command::new(BIN).arg("info").arg(path).output().unwrap();
    let code = out.status.code().expect("killed by a signal");
    (code, String::from_utf8_lossy(&out.stderr).into_owned())
}

/// Every block length of a written cloud, set to values that once made
/// OpenVDB write past a leaf's buffer (a longer uncompressed block), or
/// disagree with the node: refused by the walk, naming the grid and the
/// leaf or node.
#[test]
fn damaged_block_lengths_are_refused_before_openvdb() {
    let dir = common::tempdir();
    let p = dir.path().join("cloud.vdb");
    write_vdb(&p, &[AnyGrid::Float(generate::cloud(24, 3).unwrap())]).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    let fields = file_fields(&bytes);
    let blocks: Vec<_> = fields
        .iter()
        .filter(|f| f.kind == FieldKind::BlockLength)
        .collect();
    assert!(blocks.len() > 10, "{} block lengths", blocks.len());
    let mut rng = common::TestRng(11);
    for case in 0..12 {
        let f = blocks[rng.next_u64() as usize % blocks.len()];
        let at = f.offset as usize;
        let old = i64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
        let new = match case % 6 {
            0 => -4096,      // more raw bytes than a float leaf holds
            1 => -(1 << 40), // far more
            2 => i64::MIN,
            3 => old + 1,
            4 => 1 << 40,
            _ => 0,
        };
        if new == old {
            continue;
        }
        let mut b = bytes.clone();
        b[at..at + 8].copy_from_slice(&new.to_le_bytes());
        let q = dir.path().join(format!("bad{case}.vdb"));
        std::fs::write(&q, &b).unwrap();
        let (code, err) = info_of(&q);
        assert_eq!(code, 1, "case {case} ({old} -> {new}): {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(&format!("bad{case}.vdb")), "{err}");
        assert!(err.contains("grid 'density'"), "{err}");
        assert!(err.contains("corrupt"), "{err}");
    }
}

/// The Blosc header's sizes: a compressed size other than the block's (c-blosc
/// would read past the block) or an uncompressed size other than the leaf's.
#[test]
fn blosc_headers_that_disagree_with_their_block_are_refused() {
    let dir = common::tempdir();
    let p = dir.path().join("cloud.vdb");
    write_vdb(&p, &[AnyGrid::Float(generate::cloud(24, 3).unwrap())]).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    let sizes: Vec<_> = file_fields(&bytes)
        .into_iter()
        .filter(|f| f.kind == FieldKind::BloscSizes)
        .collect();
    assert!(!sizes.is_empty());
    for (case, (word, delta)) in [(0usize, 4i64), (2, 64), (2, -1), (0, -4)]
        .iter()
        .enumerate()
    {
        let f = sizes[(case * 7) % sizes.len()];
        let at = f.offset as usize + 4 * word;
        let v = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        let mut b = bytes.clone();
        b[at..at + 4].copy_from_slice(&((v as i64 + delta) as u32).to_le_bytes());
        let q = dir.path().join(format!("blosc{case}.vdb"));
        std::fs::write(&q, &b).unwrap();
        let (code, err) = info_of(&q);
        assert_eq!(code, 1, "{err}");
        assert!(err.contains("Blosc"), "{err}");
    }
}

/// A value mask changed in the topology or in the buffers: the two copies
/// disagree, or the voxel count no longer matches the metadata.
#[test]
fn damaged_masks_are_refused() {
    let dir = common::tempdir();
    let p = dir.path().join("cloud.vdb");
    write_vdb(&p, &[AnyGrid::Float(generate::cloud(24, 3).unwrap())]).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    let masks: Vec<_> = file_fields(&bytes)
        .into_iter()
        .filter(|f| f.kind == FieldKind::Mask && f.size == 64)
        .collect();
    for (case, f) in masks.iter().step_by(masks.len() / 5 + 1).enumerate() {
        let mut b = bytes.clone();
        b[f.offset as usize + 9] ^= 0x10;
        let q = dir.path().join(format!("mask{case}.vdb"));
        std::fs::write(&q, &b).unwrap();
        let (code, err) = info_of(&q);
        assert_eq!(code, 1, "{err}");
        assert!(err.contains("grid 'density'"), "{err}");
    }
}

#[test]
fn old_file_versions_are_refused_with_the_version() {
    let dir = common::tempdir();
    let p = dir.path().join("cloud.vdb");
    write_vdb(&p, &[AnyGrid::Float(generate::cloud(16, 1).unwrap())]).unwrap();
    let mut b = std::fs::read(&p).unwrap();
    b[8..12].copy_from_slice(&221u32.to_le_bytes());
    std::fs::write(&p, &b).unwrap();
    let (code, err) = info_of(&p);
    assert_eq!(code, 1);
    assert!(err.contains("version 221"), "{err}");
}

#[test]
fn real_files_pass_the_walk() {
    let Some(dir) = common::real_data() else {
        return;
    };
    for f in [
        "cloud96.vdb",
        "blender_smoke/fluid_data_0015.vdb",
        "blender_smoke/fluid_data_0025.vdb",
        "blender_smoke/fluid_data_0040.vdb",
        "external/pig.vdb",
        "external/pyro.vdb",
        "external/test.vdb",
        "external/fogTommy.vdb",
    ] {
        let v = VdbFile::open(dir.join(f)).unwrap();
        for n in v.grid_names() {
            v.read_any(n).unwrap_or_else(|e| panic!("{f}: {e}"));
        }
    }
}
