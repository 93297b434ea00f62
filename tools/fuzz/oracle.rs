//! What the fuzz targets check an input against, shared by `vdbfuzz`
//! (its child processes) and the AFL targets (`tools/fuzz/afl`).

use std::path::Path;
use vdbphoton::vdb::{AnyGrid, VdbFile};

/// Numbers in a metadata value as OpenVDB prints it (`[1, 2, 3]`, `42`).
pub fn numbers(s: &str) -> Vec<i64> {
    s.split(|c: char| !(c.is_ascii_digit() || c == '-'))
        .filter_map(|t| t.parse().ok())
        .collect()
}

/// Reads every supported grid as `vdbphoton info` does, then checks what
/// it got against the grid's metadata: the loaded grid's active voxel
/// count and bounds must be what the header claims (a reader that accepts
/// more is wrong).
pub fn read_vdb(path: &Path) -> vdbphoton::Result<Report> {
    let f = VdbFile::open(path)?;
    let info = f.info()?;
    let mut nonfinite = Vec::new();
    let mut mismatch = Vec::new();
    let mut loaded = 0;
    for (d, gi) in f.header().grids.iter().zip(&info.grids) {
        if d.channels().is_none() {
            continue;
        }
        let g = f.read_any(&d.unique_name)?;
        loaded += 1;
        let (finite, count, bounds) = match &g {
            AnyGrid::Float(g) => (g.all_finite(), g.active_voxel_count(), g.active_bounds()),
            AnyGrid::Vec3(g) => (g.all_finite(), g.active_voxel_count(), g.active_bounds()),
        };
        if !finite {
            nonfinite.push(d.name.clone());
        }
        // What the header claims, when it claims it in the form OpenVDB
        // writes (a metadata entry whose type was changed claims nothing).
        let meta = |k: &str, type_name: &str, len: usize| {
            gi.metadata
                .iter()
                .find(|m| m.name == k && m.type_name == type_name)
                .map(|m| numbers(&m.value))
                .filter(|v| v.len() == len)
        };
        if d.instance_parent.is_empty() {
            if let Some(n) = meta("file_voxel_count", "int64", 1).map(|v| v[0]) {
                if n != count as i64 {
                    mismatch.push(format!("{}: {count} active voxels, header {n}", d.name));
                }
            }
            if let (Some(lo), Some(hi), Some((a, b))) = (
                meta("file_bbox_min", "vec3i", 3),
                meta("file_bbox_max", "vec3i", 3),
                bounds,
            ) {
                if lo != a.to_array().map(i64::from) || hi != b.to_array().map(i64::from) {
                    mismatch.push(format!(
                        "{}: bounds {a}..{b}, header {lo:?}..{hi:?}",
                        d.name
                    ));
                }
            }
        }
    }
    Ok(Report {
        loaded,
        nonfinite,
        mismatch,
    })
}

/// What [`read_vdb`] found in a file it accepted.
pub struct Report {
    /// Grids loaded.
    pub loaded: usize,
    /// Grids holding NaN or infinite values.
    pub nonfinite: Vec<String>,
    /// Grids unlike their header's metadata (a wrong accept).
    pub mismatch: Vec<String>,
}

/// [`read_vdb`] as one JSON line, the child side of `vdbfuzz`.
pub fn target_vdb(path: &Path) -> vdbphoton::Result<String> {
    let r = read_vdb(path)?;
    Ok(serde_json::json!({
        "loaded": r.loaded,
        "nonfinite": r.nonfinite,
        "mismatch": r.mismatch
    })
    .to_string())
}
