//! Safe access to `.vdb` files: the header check of [`header`], then the
//! OpenVDB bridge of `ffi` for the grids themselves.
//!
//! Reading a grid: check the path and the header in Rust (a damaged file is
//! refused at once, see [`header`]), refuse unsupported value types from the
//! grid table, read the grid's bytes into memory and walk them in Rust
//! ([`check`]: every count, length and flag OpenVDB will trust), then let
//! OpenVDB parse those same bytes and move the grid into a [`Grid`] leaf by
//! leaf. OpenVDB never reads the file itself. Every error names the file and
//! the grid.

pub mod check;
mod ffi;
pub mod field;
pub mod header;

use crate::error::{Error, Result};
use crate::grid::{BrickValues, Grid, GridParts, GridValue, Tile};
use ffi::bridge;
pub use field::{Field, FieldKind};
use glam::{DAffine3, DMat3, DVec3, IVec3, Vec3};
pub use header::{GridDescriptor, Header, MAX_FILE_VERSION};
use std::path::{Path, PathBuf};

/// Metadata entry (name, OpenVDB type name, value as text).
pub type MetaEntry = bridge::MetaEntry;
/// What OpenVDB reports about a grid.
pub type GridInfo = bridge::GridInfo;

/// A grid of either supported value type.
#[derive(Debug, Clone)]
pub enum AnyGrid {
    Float(Grid<f32>),
    Vec3(Grid<Vec3>),
}

impl AnyGrid {
    pub fn name(&self) -> &str {
        match self {
            AnyGrid::Float(g) => g.name(),
            AnyGrid::Vec3(g) => g.name(),
        }
    }
    pub fn memory_bytes(&self) -> usize {
        match self {
            AnyGrid::Float(g) => g.memory_bytes(),
            AnyGrid::Vec3(g) => g.memory_bytes(),
        }
    }
    pub fn active_voxel_count(&self) -> u64 {
        match self {
            AnyGrid::Float(g) => g.active_voxel_count(),
            AnyGrid::Vec3(g) => g.active_voxel_count(),
        }
    }
}

/// An opened `.vdb` file whose header, and every grid's metadata and
/// transform, have been checked.
#[derive(Debug, Clone)]
pub struct VdbFile {
    path: PathBuf,
    header: Header,
    /// Per grid (in the header's order): its checked head, and the head's
    /// bytes (compression flags, metadata, transform) for OpenVDB to parse.
    heads: Vec<(check::Head, Vec<u8>)>,
}

/// Bytes read at first for a grid's head; most heads take under 2 KiB.
const HEAD_READ: u64 = 1 << 16;

/// Reads `len` bytes at `offset` of `path`; an error if the file holds fewer
/// (it changed after its header was read).
fn read_range(path: &Path, offset: u64, len: u64) -> Result<Vec<u8>> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    f.seek(SeekFrom::Start(offset))
        .map_err(|e| Error::io(path, e))?;
    let n = usize::try_from(len).map_err(|_| Error::file(path, "a grid is too large to read"))?;
    let mut buf = Vec::new();
    buf.try_reserve_exact(n)
        .map_err(|_| Error::file(path, format!("cannot allocate {n} bytes to read a grid")))?;
    f.take(len)
        .read_to_end(&mut buf)
        .map_err(|e| Error::io(path, e))?;
    if buf.len() as u64 != len {
        return Err(Error::file(
            path,
            "the file is shorter than its header says (it changed while being read)",
        ));
    }
    Ok(buf)
}

fn path_str(path: &Path) -> Result<&str> {
    path.to_str()
        .ok_or_else(|| Error::file(path, "the path is not valid UTF-8"))
}

/// Turns an OpenVDB exception text into words a user understands.
fn explain_openvdb(msg: &str) -> String {
    let lower = msg.to_ascii_lowercase();
    if lower.contains("not registered")
        || lower.contains("decompress")
        || lower.contains("unexpected end")
        || lower.contains("error reading")
        || lower.contains("ioerror")
        || lower.contains("read")
    {
        format!("the file is truncated or corrupt (OpenVDB: {msg})")
    } else {
        format!("OpenVDB could not read it: {msg}")
    }
}

fn affine_from_rows(m: &[f64; 12]) -> DAffine3 {
    DAffine3 {
        matrix3: DMat3::from_cols(
            DVec3::new(m[0], m[4], m[8]),
            DVec3::new(m[1], m[5], m[9]),
            DVec3::new(m[2], m[6], m[10]),
        ),
        translation: DVec3::new(m[3], m[7], m[11]),
    }
}

fn rows_from_affine(a: &DAffine3) -> [f64; 12] {
    let c = a.matrix3;
    let t = a.translation;
    [
        c.x_axis.x, c.y_axis.x, c.z_axis.x, t.x, c.x_axis.y, c.y_axis.y, c.z_axis.y, t.y,
        c.x_axis.z, c.y_axis.z, c.z_axis.z, t.z,
    ]
}

impl VdbFile {
    /// Opens `path` and checks its header and grid table.
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
        if meta.is_dir() {
            return Err(Error::file(path, "is a directory, not a .vdb file"));
        }
        let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let header =
            header::parse(&mut f, meta.len()).map_err(|e| Error::file(path, e.to_string()))?;
        let mut heads = Vec::with_capacity(header.grids.len());
        for d in &header.grids {
            let corrupt =
                |e: String| Error::grid(path, &d.name, format!("the file is corrupt: {e}"));
            let len = d.end_pos - d.grid_pos;
            let mut bytes = read_range(path, d.grid_pos, len.min(HEAD_READ))?;
            let mut head = check::check_head(&bytes, d.grid_pos);
            if head.is_err() && len > HEAD_READ {
                // A head longer than the first read (long metadata).
                bytes = read_range(path, d.grid_pos, len)?;
                head = check::check_head(&bytes, d.grid_pos);
            }
            let head = head.map_err(corrupt)?;
            if !d.instance_parent.is_empty() && head.len as u64 != len {
                return Err(corrupt(format!(
                    "the instance grid's metadata and transform end at byte {}, but the grid ends at byte {}",
                    d.grid_pos + head.len as u64,
                    d.end_pos
                )));
            }
            bytes.truncate(head.len);
            bytes.shrink_to_fit();
            heads.push((head, bytes));
        }
        Ok(Self {
            path: path.to_path_buf(),
            header,
            heads,
        })
    }

    fn stream_version(&self) -> bridge::StreamVersion {
        bridge::StreamVersion {
            file_version: self.header.file_version,
            library_major: self.header.library_version.0,
            library_minor: self.header.library_version.1,
        }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
    pub fn header(&self) -> &Header {
        &self.header
    }
    pub fn grid_names(&self) -> Vec<&str> {
        self.header.grids.iter().map(|g| g.name.as_str()).collect()
    }

    /// The grid table entry for `name`, or an error that lists the grids.
    pub fn descriptor(&self, name: &str) -> Result<&GridDescriptor> {
        self.header
            .grids
            .iter()
            .find(|g| g.name == name || g.unique_name == name)
            .ok_or_else(|| {
                let names = self.grid_names();
                let list = if names.is_empty() {
                    "it has no grids".to_string()
                } else {
                    format!("its grids: {}", names.join(", "))
                };
                Error::file(&self.path, format!("no grid named '{name}' ({list})"))
            })
    }

    /// File metadata and each grid's info, without reading the trees:
    /// OpenVDB parses the checked header and grid heads from memory.
    pub fn info(&self) -> Result<bridge::FileInfo> {
        let v = self.stream_version();
        let metadata = bridge::read_metadata(&self.header.metadata_bytes, &v)
            .map_err(|e| Error::file(&self.path, explain_openvdb(e.what())))?;
        let mut grids = Vec::with_capacity(self.heads.len());
        for (d, (_, bytes)) in self.header.grids.iter().zip(&self.heads) {
            let mut g = bridge::read_grid_head(bytes, &v)
                .map_err(|e| Error::grid(&self.path, &d.name, explain_openvdb(e.what())))?;
            g.name = d.name.clone();
            g.value_type = d.value_type().to_string();
            grids.push(g);
        }
        Ok(bridge::FileInfo {
            file_version: self.header.file_version,
            library_version: [self.header.library_version.0, self.header.library_version.1],
            metadata,
            grids,
        })
    }

    /// The descriptor of the grid whose tree `d` uses: `d` itself, or the
    /// parent of an instance (which must exist, have the same type and not
    /// be an instance itself).
    fn tree_owner<'a>(&'a self, d: &'a GridDescriptor) -> Result<&'a GridDescriptor> {
        if d.instance_parent.is_empty() {
            return Ok(d);
        }
        let p = self
            .header
            .grids
            .iter()
            .find(|p| p.unique_name == d.instance_parent)
            .ok_or_else(|| {
                Error::grid(
                    &self.path,
                    &d.name,
                    "the file is corrupt: its instance parent is missing",
                )
            })?;
        if p.type_name != d.type_name || !p.instance_parent.is_empty() {
            return Err(Error::grid(
                &self.path,
                &d.name,
                format!(
                    "the file is corrupt: it is an instance of '{}', a {} grid{}",
                    p.name,
                    p.type_name,
                    if p.instance_parent.is_empty() {
                        ""
                    } else {
                        " that is itself an instance"
                    }
                ),
            ));
        }
        Ok(p)
    }

    fn read_typed<T: GridValue>(&self, name: &str) -> Result<Grid<T>> {
        let d = self.descriptor(name)?;
        let channels = T::CHANNELS;
        let have = d.channels().ok_or_else(|| {
            Error::grid(
                &self.path,
                &d.name,
                format!(
                    "has value type {}; vdbphoton reads float, double and vec3s grids",
                    d.value_type()
                ),
            )
        })?;
        if have != channels {
            let want = if channels == 1 {
                "a scalar (float or double)"
            } else {
                "a vec3s"
            };
            return Err(Error::grid(
                &self.path,
                &d.name,
                format!(
                    "has value type {} where {want} grid is needed",
                    d.value_type()
                ),
            ));
        }
        let openvdb_err =
            |e: cxx::Exception| Error::grid(&self.path, &d.name, explain_openvdb(e.what()));
        let owner = self.tree_owner(d)?;
        let kind = check::ValueKind::of_type_name(&owner.type_name).ok_or_else(|| {
            Error::grid(
                &self.path,
                &d.name,
                format!(
                    "has tree type {}, which vdbphoton does not read",
                    owner.type_name
                ),
            )
        })?;
        let bytes = read_range(&self.path, owner.grid_pos, owner.end_pos - owner.grid_pos)?;
        let (_, tree) = check::check_grid(&bytes, owner.grid_pos, owner.block_pos, kind, None)
            .map_err(|e| Error::grid(&self.path, &d.name, format!("the file is corrupt: {e}")))?;
        // Refuse what cannot fit before OpenVDB allocates it (a small file
        // can describe far more nodes than it stores values).
        let need =
            tree.openvdb_bytes(kind.0) + tree.leaves as u64 * (512 * 4 * channels as u64 + 96);
        if let Some(avail) = crate::memory::budget() {
            if need > avail {
                return Err(Error::grid(
                    &self.path,
                    &d.name,
                    format!(
                        "loading it would take about {:.1} GiB ({} leaves, {} internal nodes); {:.1} GiB {}",
                        need as f64 / (1u64 << 30) as f64,
                        tree.leaves,
                        tree.internal_nodes.0 + tree.internal_nodes.1,
                        avail as f64 / (1u64 << 30) as f64,
                        if crate::memory::limit().is_some() {
                            "are left of --max-memory"
                        } else {
                            "are available"
                        }
                    ),
                ));
            }
        }
        let base_type = owner
            .type_name
            .strip_suffix("_HalfFloat")
            .unwrap_or(&owner.type_name);
        let loaded = bridge::load_grid_bytes(
            &bytes,
            &owner.unique_name,
            base_type,
            kind.1,
            &self.stream_version(),
        )
        .map_err(openvdb_err)?;
        drop(bytes);
        let mut layout = bridge::grid_layout(&loaded).map_err(openvdb_err)?;
        if !std::ptr::eq(owner, d) {
            // An instance: the parent's tree under the instance's own name,
            // metadata and transform.
            let i = self
                .header
                .grids
                .iter()
                .position(|g| std::ptr::eq(g, d))
                .unwrap_or(0);
            let mut info = bridge::read_grid_head(&self.heads[i].1, &self.stream_version())
                .map_err(openvdb_err)?;
            info.name = d.name.clone();
            info.value_type = layout.info.value_type.clone();
            layout.info = info;
        }
        if !layout.info.linear {
            return Err(Error::grid(
                &self.path,
                &d.name,
                format!(
                    "uses a non-linear ({}) transform; vdbphoton reads only linear (affine) transforms",
                    layout.info.map_type
                ),
            ));
        }
        if layout.channels as usize != channels {
            return Err(Error::grid(
                &self.path,
                &d.name,
                format!(
                    "has value type {}, which vdbphoton does not read",
                    layout.info.value_type
                ),
            ));
        }
        let n = usize::try_from(layout.leaf_count).unwrap_or(usize::MAX);
        if n > (1usize << 31) / 8 {
            return Err(Error::grid(
                &self.path,
                &d.name,
                format!("has {n} leaves, more than vdbphoton can hold"),
            ));
        }
        let mut origins = vec![0i32; 3 * n];
        let mut masks = vec![0u64; 8 * n];
        // SAFETY: `copy_leaves` writes every value float when it succeeds
        // (the bridge checks the buffer sizes against the leaf count, then
        // copies each leaf whole), and it may write `len` floats.
        let values = unsafe {
            // Room for the grid's constants after the bricks (one per
            // tile and the background: `Grid::from_parts` appends them).
            let constants = layout.tiles.len() + 1;
            BrickValues::<T>::from_fill(n, constants, |ptr, len| {
                bridge::copy_leaves(&loaded, &mut origins, ptr, len, &mut masks)
            })
        }
        .map_err(openvdb_err)?;
        // OpenVDB's tree is freed on another thread while this one builds
        // the index (2-3 ms each on the 512^3 cloud). The thread is joined
        // before returning: a scope alone waits for the closure, not for the
        // thread's exit, and its thread-local destructors (TBB's, since
        // OpenVDB frees a tree with `tbb::parallel_for`) would run after.
        std::thread::scope(|s| {
            // If no thread can be made, `spawn_scoped` drops the closure,
            // and `loaded` with it, before it returns.
            let free = std::thread::Builder::new().spawn_scoped(s, move || drop(loaded));
            let parts = parts_from_layout::<T>(layout, origins, values, masks);
            let grid = Grid::from_parts(parts)
                .map_err(|e| Error::grid(&self.path, &d.name, e.to_string()));
            if let Ok(free) = free {
                // A panic there would be a C++ destructor throwing, which
                // terminates the process before this: nothing to report.
                let _ = free.join();
            }
            grid
        })
    }

    /// Reads a `float` or `double` grid (doubles become f32).
    pub fn read_float(&self, name: &str) -> Result<Grid<f32>> {
        self.read_typed(name)
    }

    /// Reads a `vec3s` grid.
    pub fn read_vec3(&self, name: &str) -> Result<Grid<Vec3>> {
        self.read_typed(name)
    }

    /// Reads a grid of any supported type.
    pub fn read_any(&self, name: &str) -> Result<AnyGrid> {
        let d = self.descriptor(name)?;
        match d.channels() {
            Some(3) => self.read_vec3(name).map(AnyGrid::Vec3),
            _ => self.read_float(name).map(AnyGrid::Float),
        }
    }
}

fn parts_from_layout<T: GridValue>(
    d: bridge::GridLayout,
    origins: Vec<i32>,
    values: BrickValues<T>,
    masks: Vec<u64>,
) -> GridParts<T> {
    let brick_origins = origins
        .chunks_exact(3)
        .map(|c| IVec3::new(c[0], c[1], c[2]))
        .collect();
    let masks = masks
        .chunks_exact(8)
        .map(|c| c.try_into().unwrap())
        .collect();
    let n = T::CHANNELS;
    let tiles = d
        .tiles
        .iter()
        .map(|r| Tile {
            origin: IVec3::from_array(r.origin),
            level: r.level,
            value: T::from_slice(&r.value[..n]),
            active: r.active,
        })
        .collect();
    GridParts {
        name: d.info.name,
        class: d.info.grid_class,
        background: T::from_slice(&d.background),
        world_from_index: affine_from_rows(&d.info.world_from_index),
        brick_origins,
        values,
        masks,
        tiles,
    }
}

fn data_from_grid<T: GridValue>(g: &Grid<T>) -> bridge::GridData {
    let mut d = bridge::GridData {
        channels: T::CHANNELS as u32,
        ..Default::default()
    };
    d.info.name = g.name().to_string();
    d.info.grid_class = g.class().to_string();
    d.info.world_from_index = rows_from_affine(&g.world_from_index());
    g.background().write_to(&mut d.background);
    d.leaf_origins = g
        .brick_origins()
        .iter()
        .flat_map(|o| o.to_array())
        .collect();
    d.leaf_masks = (0..g.brick_count())
        .flat_map(|b| *g.brick_mask(b))
        .collect();
    d.leaf_values = Vec::with_capacity(g.brick_count() * 512 * T::CHANNELS);
    for b in 0..g.brick_count() {
        d.leaf_values.extend(T::to_flat(g.brick_values(b)));
    }
    for t in g.tiles() {
        d.tile_origins.extend(t.origin.to_array());
        d.tile_levels.push(t.level);
        d.tile_active.push(t.active);
        t.value.write_to(&mut d.tile_values);
    }
    d
}

/// Writes grids to a `.vdb` file: to a temporary name first, then renamed,
/// so an interrupted or failed write never leaves a partial file.
pub fn write_vdb(path: impl AsRef<Path>, grids: &[AnyGrid]) -> Result<()> {
    let path = path.as_ref();
    let data: Vec<bridge::GridData> = grids
        .iter()
        .map(|g| match g {
            AnyGrid::Float(g) => data_from_grid(g),
            AnyGrid::Vec3(g) => data_from_grid(g),
        })
        .collect();
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        if !dir.is_dir() {
            return Err(Error::file(
                path,
                "cannot write: its directory does not exist",
            ));
        }
    }
    let creator = format!("vdbphoton {}", env!("CARGO_PKG_VERSION"));
    crate::atomic::replace_with(
        path,
        |tmp| {
            bridge::write_grids(path_str(tmp)?, &data, &creator)
                .map_err(|e| Error::file(path, format!("cannot write: {}", e.what())))
        },
        |e| Error::io(path, e),
    )
}

/// OpenVDB's own version string (ABI version).
pub fn openvdb_version() -> String {
    bridge::openvdb_version().unwrap_or_else(|_| "unknown".into())
}

/// Direct calls into OpenVDB for tests and benchmarks: its own trilinear
/// sampler, its own read timing, and files our writer refuses to make.
pub mod reference {
    use super::*;

    /// Samples `grid` of `path` at world points with OpenVDB's
    /// `GridSampler<_, BoxSampler>::wsSample` (1 or 3 floats per point).
    pub fn box_sample_world(path: &Path, grid: &str, points: &[DVec3]) -> Result<Vec<f32>> {
        let xyz: Vec<f64> = points.iter().flat_map(|p| p.to_array()).collect();
        bridge::box_sample_world(path_str(path)?, grid, &xyz)
            .map_err(|e| Error::grid(path, grid, e.what().to_string()))
    }

    /// Time to open the file and read one grid with OpenVDB alone, and the
    /// grid's `memUsage()`.
    pub fn openvdb_read(path: &Path, grid: &str) -> Result<(f64, u64, u64)> {
        let s = bridge::openvdb_read_stats(path_str(path)?, grid)
            .map_err(|e| Error::grid(path, grid, e.what().to_string()))?;
        Ok((s.seconds, s.mem_bytes, s.active_voxels))
    }

    /// Writes a file our writer cannot make, for the reader's tests: an
    /// `int32` grid ("int32") or a frustum transform ("frustum"), which the
    /// reader must refuse, or a `double` grid ("double"), which it reads as
    /// f32; a small float grid stored as half floats ("half"), with zlib
    /// ("zip"), without compression ("uncompressed"), with inactive values
    /// that need every mask-compression case ("inactive"), or with a second
    /// grid that is an instance of it ("instance").
    pub fn write_unsupported_fixture(path: &Path, kind: &str) -> Result<()> {
        bridge::write_test_fixture(path_str(path)?, kind)
            .map_err(|e| Error::file(path, e.what().to_string()))
    }
}

/// Every length, count, offset, flag and mask of a file that the header
/// check and the grid walk read, in file order where possible: for a
/// fuzzer, which damages these rather than random bytes. Best effort: a
/// grid that fails its walk contributes the fields before the failure.
pub fn file_fields(bytes: &[u8]) -> Vec<Field> {
    let mut out = Vec::new();
    let Ok(h) = header::parse(&mut { bytes }, bytes.len() as u64) else {
        return out;
    };
    out.extend(h.fields.iter().copied());
    for d in &h.grids {
        let Some(b) = bytes.get(d.grid_pos as usize..d.end_pos as usize) else {
            continue;
        };
        check::grid_fields(
            b,
            d.grid_pos,
            d.block_pos,
            &d.type_name,
            !d.instance_parent.is_empty(),
            &mut out,
        );
    }
    out
}
