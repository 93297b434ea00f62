//! The `cxx` bridge declarations. Only `cpp/` includes OpenVDB; this module
//! declares the shared structs and the C++ functions, and `super` wraps them
//! in a safe API with errors that name the file and the grid.
//!
//! Data crosses in bulk: whole 8^3 leaves as flat arrays (origin, 512 values
//! per channel, 8 mask words) and every tile, so one call moves a whole grid.

#[cxx::bridge(namespace = "vdbphoton::ffi")]
pub(crate) mod bridge {
    /// One metadata entry, its value rendered as text by OpenVDB.
    #[derive(Debug, Clone)]
    struct MetaEntry {
        name: String,
        type_name: String,
        value: String,
    }

    /// What OpenVDB knows about a grid without (or after) reading its tree.
    #[derive(Debug, Clone)]
    struct GridInfo {
        name: String,
        value_type: String,
        grid_class: String,
        active_voxels: u64,
        empty: bool,
        bbox_min: [i32; 3],
        bbox_max: [i32; 3],
        linear: bool,
        map_type: String,
        /// world = A * index + t, three rows of four (row-major).
        world_from_index: [f64; 12],
        voxel_size: [f64; 3],
        metadata: Vec<MetaEntry>,
    }

    #[derive(Debug, Clone)]
    struct FileInfo {
        file_version: u32,
        library_version: [u32; 2],
        metadata: Vec<MetaEntry>,
        grids: Vec<GridInfo>,
    }

    /// A whole grid in flat arrays. `channels` is 1 (float, double read as
    /// f32) or 3 (vec3s), 0 when the value type is not supported.
    #[derive(Debug, Clone, Default)]
    struct GridData {
        info: GridInfo,
        channels: u32,
        background: Vec<f32>,
        leaf_origins: Vec<i32>,
        leaf_values: Vec<f32>,
        leaf_masks: Vec<u64>,
        tile_origins: Vec<i32>,
        /// 1: an 8^3 tile, 2: a 128^3 tile, 3: a 4096^3 root tile.
        tile_levels: Vec<u8>,
        tile_active: Vec<bool>,
        tile_values: Vec<f32>,
    }

    /// Everything about a read grid but its leaves: the value layout, the
    /// leaf count (for Rust to allocate the leaf arrays) and the tiles.
    /// `channels` is 0 when the value type or transform is not supported.
    #[derive(Debug, Clone)]
    struct GridLayout {
        info: GridInfo,
        channels: u32,
        leaf_count: u64,
        background: Vec<f32>,
        tiles: Vec<TileRecord>,
    }

    /// A tile of the root or an internal node: its origin, level (1: 8^3
    /// voxels, 2: 128^3, 3: 4096^3), whether it is active, and its value
    /// (`channels` floats, the rest 0). One record a tile, not one entry
    /// in each of several arrays: every `push_back` onto a Rust `Vec` from
    /// C++ is several calls across the bridge.
    #[derive(Debug, Clone, Copy)]
    struct TileRecord {
        origin: [i32; 3],
        level: u8,
        active: bool,
        value: [f32; 3],
    }

    /// A file's format and library version, which OpenVDB's readers take
    /// from the stream.
    #[derive(Debug, Clone, Copy)]
    struct StreamVersion {
        file_version: u32,
        library_major: u32,
        library_minor: u32,
    }

    /// OpenVDB's own read of one grid, for the load benchmark.
    #[derive(Debug, Clone, Copy)]
    struct ReadStats {
        seconds: f64,
        mem_bytes: u64,
        active_voxels: u64,
    }

    unsafe extern "C++" {
        include!("vdbphoton/cpp/vdb_bridge.h");

        /// A grid read by OpenVDB and held in C++ until Rust copies it.
        type LoadedGrid;

        /// File metadata (count and entries) parsed from bytes that
        /// `vdb::header` has checked.
        fn read_metadata(bytes: &[u8], v: &StreamVersion) -> Result<Vec<MetaEntry>>;
        /// A grid's compression flags, metadata and transform, parsed from
        /// bytes that `vdb::check` has walked (any value type; the name and
        /// value type are left for the caller).
        fn read_grid_head(bytes: &[u8], v: &StreamVersion) -> Result<GridInfo>;
        /// A whole grid read by OpenVDB from bytes that `vdb::check` has
        /// walked (its start to its end): the same bytes, not the file.
        fn load_grid_bytes(
            bytes: &[u8],
            unique_name: &str,
            type_name: &str,
            half: bool,
            v: &StreamVersion,
        ) -> Result<UniquePtr<LoadedGrid>>;
        fn grid_layout(g: &LoadedGrid) -> Result<GridLayout>;
        /// Copies every leaf into buffers Rust allocated from the layout's
        /// leaf count: 3 origin coordinates, 512·channels values and 8 mask
        /// words per leaf. `values` (`values_len` floats) may be
        /// uninitialised: on success every float has been written.
        ///
        /// # Safety
        /// `values` must be valid for writes of `values_len` floats.
        unsafe fn copy_leaves(
            g: &LoadedGrid,
            origins: &mut [i32],
            values: *mut f32,
            values_len: usize,
            masks: &mut [u64],
        ) -> Result<()>;
        fn write_grids(path: &str, grids: &[GridData], creator: &str) -> Result<()>;
        fn box_sample_world(path: &str, grid: &str, xyz: &[f64]) -> Result<Vec<f32>>;
        fn openvdb_read_stats(path: &str, grid: &str) -> Result<ReadStats>;
        fn write_test_fixture(path: &str, kind: &str) -> Result<()>;
        fn openvdb_version() -> Result<String>;
    }
}

// SAFETY: a `LoadedGrid` owns its OpenVDB grid alone (nothing else holds
// the grid's pointer), so it may be destroyed on any thread.
unsafe impl Send for bridge::LoadedGrid {}

impl Default for bridge::GridInfo {
    fn default() -> Self {
        Self {
            name: String::new(),
            value_type: String::new(),
            grid_class: "unknown".into(),
            active_voxels: 0,
            empty: true,
            bbox_min: [0; 3],
            bbox_max: [-1; 3],
            linear: true,
            map_type: String::new(),
            world_from_index: [1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0.],
            voxel_size: [1.0; 3],
            metadata: Vec::new(),
        }
    }
}
