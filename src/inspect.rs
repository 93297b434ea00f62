//! `vdbphoton info`: what a `.vdb` file holds, grid by grid (value type,
//! voxel counts, index and world boxes, transform, value range, the memory
//! a grid takes when loaded and its load time), as text or JSON. Every
//! supported grid is loaded into the renderer's own grid to measure it.

use crate::error::Result;
use crate::vdb::{AnyGrid, VdbFile};
use std::path::Path;
use std::time::Instant;

/// `info`'s output for one file.
#[derive(Debug, Clone)]
pub enum Report {
    /// Lines for people (each ends in a newline).
    Text(String),
    /// The JSON document of `--json` (its schema is the text's, key by key).
    Json(serde_json::Value),
}

/// `writeln!` into a `String` (which cannot fail).
macro_rules! outln {
    ($o:expr, $($t:tt)*) => {{
        use std::fmt::Write as _;
        let _ = writeln!($o, $($t)*);
    }};
}

struct Loaded {
    grid: AnyGrid,
    seconds: f64,
}

/// The grids of `file` as text (`vdbphoton info`, like `vdb_print -l`)
/// or as JSON (`--json`): only grid `only` when given (an unknown name
/// or an unsupported type is then an error).
pub fn report(file: &Path, only: Option<&str>, json: bool) -> Result<Report> {
    let mut text = String::new();
    let vdb = VdbFile::open(file)?;
    let names: Vec<String> = match &only {
        Some(g) => vec![vdb.descriptor(g)?.name.clone()],
        None => vdb.grid_names().iter().map(|s| s.to_string()).collect(),
    };
    // Load each supported grid into the Rust grid (an explicitly named grid
    // must load; in a listing, unsupported grids are shown, not loaded).
    let mut loaded = Vec::new();
    for n in &names {
        let d = vdb.descriptor(n)?;
        if d.channels().is_none() && only.is_none() {
            loaded.push(None);
            continue;
        }
        let t0 = Instant::now();
        let grid = vdb.read_any(n)?;
        loaded.push(Some(Loaded {
            grid,
            seconds: t0.elapsed().as_secs_f64(),
        }));
    }
    let finfo = vdb.info()?;
    let h = vdb.header();
    if json {
        let grids: Vec<serde_json::Value> = names
            .iter()
            .zip(&loaded)
            .map(|(n, l)| {
                let gi = finfo.grids.iter().find(|g| &g.name == n);
                let d = vdb.descriptor(n).ok();
                let mut o = serde_json::json!({
                    "name": n,
                    "value_type": d.map(|d| d.value_type().to_string()),
                    "supported": l.is_some(),
                });
                if let Some(gi) = gi {
                    o["grid_class"] = gi.grid_class.clone().into();
                    o["voxel_size"] = serde_json::json!(gi.voxel_size);
                    o["map_type"] = gi.map_type.clone().into();
                    o["world_from_index"] = serde_json::json!(gi.world_from_index);
                    o["metadata"] = gi
                        .metadata
                        .iter()
                        .map(|m| (m.name.clone(), serde_json::Value::from(m.value.clone())))
                        .collect::<serde_json::Map<_, _>>()
                        .into();
                }
                if let Some(l) = l {
                    o["active_voxels"] = l.grid.active_voxel_count().into();
                    o["memory_bytes"] = (l.grid.memory_bytes() as u64).into();
                    o["load_seconds"] = l.seconds.into();
                    let (bounds, bricks, tiles) = grid_summary(&l.grid);
                    o["index_bbox"] = serde_json::json!(bounds);
                    if let (Some(b), Some(gi)) = (bounds, gi) {
                        let [lo, hi] = world_box(gi, b);
                        o["world_bbox"] = serde_json::json!([lo, hi]);
                    }
                    o["bricks"] = bricks.into();
                    o["tiles"] = serde_json::json!(tiles);
                }
                o
            })
            .collect();
        let out = serde_json::json!({
            "file": file.display().to_string(),
            "file_bytes": h.file_size,
            "file_version": h.file_version,
            "library_version": format!("{}.{}", h.library_version.0, h.library_version.1),
            "metadata": finfo.metadata.iter().map(|m| (m.name.clone(), serde_json::Value::from(m.value.clone()))).collect::<serde_json::Map<_, _>>(),
            "grids": grids,
        });
        return Ok(Report::Json(out));
    }
    outln!(
        text,
        "{}: {} ({} grid{}, VDB format {}, written by OpenVDB {}.{})",
        file.display(),
        crate::units::human_bytes(h.file_size),
        h.grids.len(),
        if h.grids.len() == 1 { "" } else { "s" },
        h.file_version,
        h.library_version.0,
        h.library_version.1
    );
    for m in &finfo.metadata {
        outln!(text, "  {}: {}", m.name, m.value);
    }
    for (n, l) in names.iter().zip(&loaded) {
        let d = vdb.descriptor(n)?;
        let gi = finfo.grids.iter().find(|g| &g.name == n);
        let class = gi.map(|g| g.grid_class.as_str()).unwrap_or("?");
        outln!(text, "{n}  {}  {class}", d.value_type());
        let Some(l) = l else {
            outln!(
                text,
                "  (value type {} is not supported by vdbphoton: not loaded)",
                d.value_type()
            );
            continue;
        };
        let (bounds, bricks, tiles) = grid_summary(&l.grid);
        if let (Some(b), Some(gi)) = (bounds, gi) {
            let [lo, hi] = world_box(gi, b);
            outln!(
                text,
                "  world box [{:.4}, {:.4}, {:.4}] -> [{:.4}, {:.4}, {:.4}]  (size {:.4} x {:.4} x {:.4}; voxels reach half a voxel past their centres)",
                lo[0],
                lo[1],
                lo[2],
                hi[0],
                hi[1],
                hi[2],
                hi[0] - lo[0],
                hi[1] - lo[1],
                hi[2] - lo[2]
            );
        }
        match bounds {
            Some([lo, hi]) => outln!(
                text,
                "  active voxels {}   index bbox [{},{},{}] -> [{},{},{}]  ({} x {} x {})",
                l.grid.active_voxel_count(),
                lo[0],
                lo[1],
                lo[2],
                hi[0],
                hi[1],
                hi[2],
                hi[0] - lo[0] + 1,
                hi[1] - lo[1] + 1,
                hi[2] - lo[2] + 1
            ),
            None => outln!(text, "  empty (no active voxels)"),
        }
        if let Some(gi) = gi {
            let v = gi.voxel_size;
            outln!(
                text,
                "  voxel size {} x {} x {}   transform {} (linear)",
                v[0],
                v[1],
                v[2],
                gi.map_type
            );
            let m = gi.world_from_index;
            outln!(
                text,
                "  world_from_index [{} {} {} {}; {} {} {} {}; {} {} {} {}]",
                m[0],
                m[1],
                m[2],
                m[3],
                m[4],
                m[5],
                m[6],
                m[7],
                m[8],
                m[9],
                m[10],
                m[11]
            );
        }
        outln!(
            text,
            "  bricks {}   tiles 8^3: {}  128^3: {}  4096^3: {}",
            bricks,
            tiles[0],
            tiles[1],
            tiles[2]
        );
        match &l.grid {
            AnyGrid::Float(g) => {
                if let Some([a, b]) = g.value_range() {
                    outln!(text, "  values {a} .. {b}   background {}", g.background());
                }
            }
            AnyGrid::Vec3(g) => outln!(text, "  background {}", g.background()),
        }
        outln!(
            text,
            "  memory when rendered {}   load {:.1} ms",
            crate::units::human_bytes(l.grid.memory_bytes() as u64),
            l.seconds * 1e3
        );
    }
    Ok(Report::Text(text))
}

/// The world-space box of the voxels `[lo, hi]` (index, inclusive) of a
/// grid.
fn world_box(gi: &crate::vdb::GridInfo, [lo, hi]: [[i32; 3]; 2]) -> [[f64; 3]; 2] {
    let d = |v: [i32; 3]| glam::DVec3::from(v.map(f64::from));
    crate::world::index_box(gi, d(lo), d(hi)).map(|v| v.to_array())
}

type GridSummary = (Option<[[i32; 3]; 2]>, usize, [usize; 3]);

fn grid_summary(g: &AnyGrid) -> GridSummary {
    fn s<T: crate::grid::GridValue>(g: &crate::grid::Grid<T>) -> GridSummary {
        let mut tiles = [0; 3];
        for t in g.tiles() {
            tiles[(t.level as usize).clamp(1, 3) - 1] += 1;
        }
        (
            g.active_bounds().map(|(a, b)| [a.to_array(), b.to_array()]),
            g.brick_count(),
            tiles,
        )
    }
    match g {
        AnyGrid::Float(g) => s(g),
        AnyGrid::Vec3(g) => s(g),
    }
}
