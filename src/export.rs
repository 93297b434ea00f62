//! Grids written out in other renderers' formats, for comparison renders:
//! Mitsuba's dense `.vol` (`vdbphoton export-vol`).

use crate::error::{Error, Result};
use crate::vdb::VdbFile;
use std::path::Path;

/// What [`export_vol`] wrote.
#[derive(Debug, Clone, Copy)]
pub struct VolSummary {
    /// Voxels along x, y, z.
    pub resolution: [i32; 3],
    /// The world-space box of the cells.
    pub world_box: [[f64; 3]; 2],
}

/// Writes grid `grid` of `file` as a dense Mitsuba `.vol` (atomically): the
/// active bounding box padded by one voxel, cell centres on the voxel
/// centres; the header's box is the world-space box of the cells.
///
/// Mitsuba's binary volume format: "VOL", version 3, encoding 1 (float32),
/// x/y/z resolution, channels, bounding box (6 floats), then the values with
/// x varying fastest.
pub fn export_vol(file: &Path, out: &Path, grid: &str) -> Result<VolSummary> {
    let g = VdbFile::open(file)?.read_float(grid)?;
    let m = g.world_from_index().matrix3;
    if m.x_axis.y != 0.0
        || m.x_axis.z != 0.0
        || m.y_axis.x != 0.0
        || m.y_axis.z != 0.0
        || m.z_axis.x != 0.0
        || m.z_axis.y != 0.0
    {
        return Err(Error::grid(
            file,
            grid,
            "export-vol needs an axis-aligned (scale and translate) transform",
        ));
    }
    let (lo, hi) = g
        .active_bounds()
        .ok_or_else(|| Error::grid(file, grid, "the grid has no active voxels"))?;
    let (lo, hi) = (lo - 1, hi + 1);
    let res = hi - lo + 1;
    let mut bytes: Vec<u8> = b"VOL".to_vec();
    bytes.push(3);
    for v in [1i32, res.x, res.y, res.z, 1] {
        bytes.extend(v.to_le_bytes());
    }
    let wlo = g.index_to_world(lo.as_dvec3() - 0.5);
    let whi = g.index_to_world(hi.as_dvec3() + 0.5);
    for v in [wlo.x, wlo.y, wlo.z, whi.x, whi.y, whi.z] {
        bytes.extend((v as f32).to_le_bytes());
    }
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                bytes.extend(g.get(glam::IVec3::new(x, y, z)).to_le_bytes());
            }
        }
    }
    crate::atomic::replace_with(
        out,
        |tmp| std::fs::write(tmp, &bytes).map_err(|e| Error::io(out, e)),
        |e| Error::io(out, e),
    )?;
    Ok(VolSummary {
        resolution: res.to_array(),
        world_box: [wlo.to_array(), whi.to_array()],
    })
}
