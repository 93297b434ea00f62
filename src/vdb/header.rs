//! A check of a `.vdb` file's header and grid table, in Rust, before OpenVDB
//! reads it.
//!
//! OpenVDB 10 does not check its input after reading a length: a truncated
//! file makes it allocate gigabytes and spend a minute before it fails (see
//! `shared/REFERENCE.md`, "Damaged .vdb files"). The header tells where every
//! grid ends, so a file whose grids run past its end, whose lengths run past
//! it, or whose offsets are out of order is refused here in microseconds,
//! with the file and the grid named.
//!
//! Layout (little-endian), as `openvdb::io::Archive::readHeader` and
//! `io::File::readGridDescriptors` read it:
//! magic `0x56444220` (int64) · file version (u32) · library major, minor
//! (u32 each, version ≥ 211) · has-grid-offsets (u8) · is-compressed (u8,
//! versions 220–221) · UUID (36 bytes, version ≥ 212) · file metadata (i32
//! count; per entry name, type name, u32 size + value bytes) · grid count
//! (i32) · per grid: unique name, type name, instance parent (version ≥ 216),
//! then grid start, data block start, grid end (i64 each); the next
//! descriptor starts at the previous grid's end.

use super::check::check_meta_value;
use super::field::{Field, FieldKind};
use std::fmt;

/// Newest VDB file format version we accept (OpenVDB 10 writes 224).
pub const MAX_FILE_VERSION: u32 = 224;

const MAGIC: i64 = 0x5644_4220;
/// Oldest file version we accept: OpenVDB 2.0 (2013) and later write 222
/// and later, the layout `vdb::check` walks (older files stored leaf
/// origins, buffer counts and uncompressed internal nodes differently).
const MIN_VERSION: u32 = 222;

/// One entry of the grid table.
#[derive(Debug, Clone, PartialEq)]
pub struct GridDescriptor {
    /// Name as stored (OpenVDB appends "\x1e" and a number to duplicates).
    pub unique_name: String,
    /// Name without that suffix: what users type.
    pub name: String,
    /// Tree type, e.g. `Tree_float_5_4_3` (maybe with `_HalfFloat`).
    pub type_name: String,
    pub instance_parent: String,
    pub grid_pos: u64,
    pub block_pos: u64,
    pub end_pos: u64,
}

impl GridDescriptor {
    /// The value type of the tree: `float`, `double`, `vec3s`, `int32`, ...
    pub fn value_type(&self) -> &str {
        let t = self
            .type_name
            .strip_suffix("_HalfFloat")
            .unwrap_or(&self.type_name);
        let t = t.strip_prefix("Tree_").unwrap_or(t);
        t.strip_suffix("_5_4_3").unwrap_or(t)
    }
    /// Whether the value type is one vdbphoton reads.
    pub fn is_supported(&self) -> bool {
        self.type_name.ends_with("_5_4_3") || self.type_name.ends_with("_5_4_3_HalfFloat")
    }
    pub fn channels(&self) -> Option<usize> {
        if !self.is_supported() {
            return None;
        }
        match self.value_type() {
            "float" | "double" => Some(1),
            "vec3s" => Some(3),
            _ => None,
        }
    }
}

/// What the header says about a file.
#[derive(Debug, Clone)]
pub struct Header {
    pub file_version: u32,
    pub library_version: (u32, u32),
    pub uuid: String,
    /// File-level metadata: name, type name, raw value bytes.
    pub metadata: Vec<(String, String, Vec<u8>)>,
    pub grids: Vec<GridDescriptor>,
    pub file_size: u64,
    /// The file metadata's bytes as stored (count and entries), for
    /// OpenVDB to parse from memory once this check has passed them.
    pub metadata_bytes: Vec<u8>,
    /// The header's counts, lengths and offsets (for fuzzers).
    pub fields: Vec<Field>,
}

impl Header {
    /// A file metadata entry as text, when it is a string.
    pub fn meta_string(&self, name: &str) -> Option<String> {
        self.metadata
            .iter()
            .find(|(n, t, _)| n == name && t == "string")
            .map(|(_, _, v)| String::from_utf8_lossy(v).into_owned())
    }
}

/// Why a header was refused; the caller adds the file name.
#[derive(Debug, Clone, PartialEq)]
pub enum HeaderError {
    Empty,
    NotVdb,
    UnsupportedVersion(u32),
    NoGridOffsets,
    /// The file ends inside the header, while reading `what`.
    TruncatedHeader {
        what: String,
        at: u64,
    },
    /// A grid's data runs past the end of the file.
    TruncatedGrid {
        grid: String,
        end: u64,
    },
    Corrupt(String),
}

impl fmt::Display for HeaderError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HeaderError::Empty => write!(f, "the file is empty (0 bytes): not an OpenVDB file"),
            HeaderError::NotVdb => write!(f, "not an OpenVDB file (no VDB magic number at its start)"),
            HeaderError::UnsupportedVersion(v) => write!(
                f,
                "VDB file format version {v} is not supported (this build reads {MIN_VERSION} to {})",
                MAX_FILE_VERSION
            ),
            HeaderError::NoGridOffsets => {
                write!(f, "the file has no grid offset table (written by a very old OpenVDB); re-save it")
            }
            HeaderError::TruncatedHeader { what, at } => write!(
                f,
                "the file is truncated or corrupt: it ends at byte {at}, inside the header ({what})"
            ),
            HeaderError::TruncatedGrid { grid, end } => write!(
                f,
                "the file is truncated or corrupt: grid '{grid}' should end at byte {end}, past the end of the file"
            ),
            HeaderError::Corrupt(m) => write!(f, "the file is corrupt: {m}"),
        }
    }
}

/// Random access to the file's bytes (a file on disk, or a slice in tests).
pub trait Source {
    fn read_at(&mut self, offset: u64, len: usize) -> std::io::Result<Vec<u8>>;
}

impl Source for &[u8] {
    fn read_at(&mut self, offset: u64, len: usize) -> std::io::Result<Vec<u8>> {
        let a = (offset as usize).min(self.len());
        let b = a.saturating_add(len).min(self.len());
        Ok(self[a..b].to_vec())
    }
}

impl Source for std::fs::File {
    fn read_at(&mut self, offset: u64, len: usize) -> std::io::Result<Vec<u8>> {
        use std::io::{Read, Seek, SeekFrom};
        self.seek(SeekFrom::Start(offset))?;
        let mut buf = Vec::with_capacity(len);
        self.take(len as u64).read_to_end(&mut buf)?;
        Ok(buf)
    }
}

const CHUNK: usize = 1 << 16;
/// Longest single field (a name or a metadata value) we believe.
const MAX_FIELD: usize = 1 << 26;

/// Reads little-endian fields through a window onto the file.
struct Reader<'s> {
    src: &'s mut dyn Source,
    size: u64,
    buf: Vec<u8>,
    base: u64,
    pos: usize,
    fields: Vec<Field>,
}

impl Reader<'_> {
    fn offset(&self) -> u64 {
        self.base + self.pos as u64
    }
    fn seek(&mut self, offset: u64) {
        self.base = offset;
        self.buf.clear();
        self.pos = 0;
    }
    fn take(&mut self, n: usize, what: &str) -> Result<&[u8], HeaderError> {
        if self.offset() + n as u64 > self.size {
            return Err(HeaderError::TruncatedHeader {
                what: what.to_string(),
                at: self.size,
            });
        }
        if self.pos + n > self.buf.len() {
            if n > MAX_FIELD {
                return Err(HeaderError::Corrupt(format!(
                    "{what} claims a length of {n} bytes"
                )));
            }
            let at = self.offset();
            self.buf = self
                .src
                .read_at(at, n.max(CHUNK))
                .map_err(|e| HeaderError::Corrupt(format!("cannot read {what}: {e}")))?;
            self.base = at;
            self.pos = 0;
            if self.buf.len() < n {
                return Err(HeaderError::TruncatedHeader {
                    what: what.to_string(),
                    at: at + self.buf.len() as u64,
                });
            }
        }
        let s = &self.buf[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u8(&mut self, what: &str) -> Result<u8, HeaderError> {
        Ok(self.take(1, what)?[0])
    }
    fn u32(&mut self, what: &str) -> Result<u32, HeaderError> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn i32(&mut self, what: &str) -> Result<i32, HeaderError> {
        Ok(i32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn i64(&mut self, what: &str) -> Result<i64, HeaderError> {
        Ok(i64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn note(&mut self, size: u32, kind: FieldKind) {
        let offset = self.offset();
        self.fields.push(Field { offset, size, kind });
    }
    fn bytes(&mut self, what: &str) -> Result<Vec<u8>, HeaderError> {
        self.note(4, FieldKind::Length);
        let n = self.u32(what)? as usize;
        Ok(self.take(n, what)?.to_vec())
    }
    fn string(&mut self, what: &str) -> Result<String, HeaderError> {
        let b = self.bytes(what)?;
        Ok(String::from_utf8_lossy(&b).into_owned())
    }
}

/// Parses and checks the header and grid table of a file of `file_size`
/// bytes, reading only the header and the descriptors.
pub fn parse(src: &mut dyn Source, file_size: u64) -> Result<Header, HeaderError> {
    if file_size == 0 {
        return Err(HeaderError::Empty);
    }
    let mut r = Reader {
        src,
        size: file_size,
        buf: Vec::new(),
        base: 0,
        pos: 0,
        fields: Vec::new(),
    };
    let magic = r.i64("magic number").map_err(|_| HeaderError::NotVdb)?;
    if magic != MAGIC {
        return Err(HeaderError::NotVdb);
    }
    let file_version = r.u32("file version")?;
    if !(MIN_VERSION..=MAX_FILE_VERSION).contains(&file_version) {
        return Err(HeaderError::UnsupportedVersion(file_version));
    }
    let major = r.u32("library version")?;
    let minor = r.u32("library version")?;
    let has_offsets = r.u8("grid offset flag")?;
    let uuid = String::from_utf8_lossy(r.take(36, "UUID")?).into_owned();
    let metadata_start = r.offset();
    r.note(4, FieldKind::Count);
    let count = r.i32("file metadata count")?;
    if count < 0 || count as u64 > file_size {
        return Err(HeaderError::Corrupt(format!("file metadata count {count}")));
    }
    let mut metadata = Vec::new();
    for _ in 0..count {
        let name = r.string("file metadata name")?;
        let ty = r.string("file metadata type")?;
        let value = r.bytes("file metadata value")?;
        check_meta_value(&ty, &value).map_err(|e| {
            HeaderError::Corrupt(format!("file metadata '{name}' of type {ty}: {e}"))
        })?;
        metadata.push((name, ty, value));
    }
    let metadata_end = r.offset();
    if has_offsets == 0 {
        return Err(HeaderError::NoGridOffsets);
    }
    r.note(4, FieldKind::Count);
    let grid_count = r.i32("grid count")?;
    if grid_count < 0 || grid_count as u64 > file_size / 16 {
        return Err(HeaderError::Corrupt(format!("grid count {grid_count}")));
    }
    let mut grids: Vec<GridDescriptor> = Vec::new();
    for g in 0..grid_count {
        let what = format!("descriptor of grid {}", g + 1);
        let unique_name = r.string(&what)?;
        let type_name = r.string(&what)?;
        let instance_parent = r.string(&what)?;
        let at = r.offset();
        for k in 0..3 {
            r.fields.push(Field {
                offset: at + 8 * k,
                size: 8,
                kind: FieldKind::Offset,
            });
        }
        let grid_pos = r.i64(&what)?;
        let block_pos = r.i64(&what)?;
        let end_pos = r.i64(&what)?;
        let name = unique_name.split('\u{1e}').next().unwrap_or("").to_string();
        let desc_end = r.offset() as i64;
        // The grid starts right after its descriptor; an instance (which
        // shares its parent's tree) has no data block and OpenVDB writes 0
        // as its data block offset.
        let block_ok = if instance_parent.is_empty() {
            (grid_pos..=end_pos).contains(&block_pos)
        } else {
            block_pos == 0
        };
        if grid_pos != desc_end || end_pos < grid_pos || !block_ok {
            return Err(HeaderError::Corrupt(format!(
                "grid '{name}' has offsets out of order ({grid_pos}, {block_pos}, {end_pos}; its descriptor ends at {desc_end})"
            )));
        }
        if end_pos as u64 > file_size {
            return Err(HeaderError::TruncatedGrid {
                grid: name,
                end: end_pos as u64,
            });
        }
        grids.push(GridDescriptor {
            unique_name,
            name,
            type_name,
            instance_parent,
            grid_pos: grid_pos as u64,
            block_pos: block_pos as u64,
            end_pos: end_pos as u64,
        });
        // The next descriptor starts where this grid ends.
        if g + 1 < grid_count {
            r.seek(end_pos as u64);
        }
    }
    for g in &grids {
        if !g.instance_parent.is_empty()
            && !grids.iter().any(|p| p.unique_name == g.instance_parent)
        {
            return Err(HeaderError::Corrupt(format!(
                "grid '{}' is an instance of a grid '{}' that the file does not have",
                g.name, g.instance_parent
            )));
        }
    }
    let metadata_bytes = r
        .src
        .read_at(metadata_start, (metadata_end - metadata_start) as usize)
        .map_err(|e| HeaderError::Corrupt(format!("cannot read the file metadata: {e}")))?;
    if metadata_bytes.len() as u64 != metadata_end - metadata_start {
        return Err(HeaderError::TruncatedHeader {
            what: "file metadata".into(),
            at: metadata_start + metadata_bytes.len() as u64,
        });
    }
    Ok(Header {
        file_version,
        library_version: (major, minor),
        uuid,
        metadata,
        grids,
        file_size,
        metadata_bytes,
        fields: r.fields,
    })
}
