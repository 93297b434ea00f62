//! The walk of one grid's bytes, in Rust, before OpenVDB parses them.
//!
//! OpenVDB 10 trusts the counts and lengths it reads. The worst case is a
//! leaf's value block: `io::readCompressedValues` hands the leaf's buffer to
//! `bloscFromStream` or `unzipFromStream`, which read as many bytes as the
//! block's length field says *before* comparing that length with the
//! buffer's size (`openvdb/io/Compression.cc`), so one wrong length writes
//! past a heap buffer. A Blosc header claiming more compressed bytes than
//! the block holds makes c-blosc read past its input the same way.
//!
//! [`check_grid`] reads a grid exactly as `io::Archive::readGrid` will, in
//! the same order: compression flags, metadata, transform, the tree's
//! topology (root table, internal nodes' child and value masks with their
//! compressed values, leaves' value masks), then every leaf's buffer (value
//! mask, per-node metadata byte, inactive values and selection mask, the
//! compressed block). It refuses the grid unless every count, length and
//! flag agrees with the rest of it and with the grid's offsets: a block
//! whose length is not what its node needs, a Blosc header whose sizes
//! disagree with the block or the node, a topology that does not end where
//! the data block starts, buffers that do not end where the grid ends,
//! nodes out of order, masks that disagree. Where the grid's metadata
//! states its active voxel count and bounding box (OpenVDB writes both),
//! the tree must have exactly those. Only then are the same bytes, already
//! in memory, given to OpenVDB, which therefore cannot read a length this
//! walk has not checked.
//!
//! What it does not check: the compressed streams themselves. c-blosc
//! checks every offset and split size inside a chunk against the chunk's
//! stated compressed size (c-blosc 1.21 `blosc_d`), which this walk has
//! made equal to the block's true size, and never writes more than the
//! leaf's buffer; zlib's `uncompress` is bounded by the destination. A
//! corrupt stream inside a well-formed block therefore ends in an OpenVDB
//! exception or in changed values, not in a crash.
//!
//! Only file format 222 and later (OpenVDB 2.0 on, 2013) are walked; the
//! header check refuses older files.

pub use super::field::{Field, FieldKind};
use glam::IVec3;

const COMPRESS_ZIP: u32 = 0x1;
const COMPRESS_ACTIVE_MASK: u32 = 0x2;
const COMPRESS_BLOSC: u32 = 0x4;

/// Per-node metadata byte of mask compression (`io::NO_MASK_AND_ALL_VALS`).
const NO_MASK_AND_ALL_VALS: i8 = 6;

/// Value type of a tree this walk understands (the trees vdbphoton reads).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValueKind {
    Float,
    Double,
    Vec3s,
}

impl ValueKind {
    /// The value type and the half-float flag of a grid descriptor's type
    /// name, for the trees vdbphoton reads (`Tree_float_5_4_3`, ...).
    pub fn of_type_name(type_name: &str) -> Option<(ValueKind, bool)> {
        let (base, half) = match type_name.strip_suffix("_HalfFloat") {
            Some(b) => (b, true),
            None => (type_name, false),
        };
        let kind = match base {
            "Tree_float_5_4_3" => ValueKind::Float,
            "Tree_double_5_4_3" => ValueKind::Double,
            "Tree_vec3s_5_4_3" => ValueKind::Vec3s,
            _ => return None,
        };
        Some((kind, half))
    }
    /// Bytes of one value in memory (and in root tiles and inactive values).
    fn size(self) -> usize {
        match self {
            ValueKind::Float => 4,
            ValueKind::Double => 8,
            ValueKind::Vec3s => 12,
        }
    }
    /// Bytes of one value stored as half floats.
    fn half_size(self) -> usize {
        match self {
            ValueKind::Float | ValueKind::Double => 2,
            ValueKind::Vec3s => 6,
        }
    }
}

/// What the head of a grid (flags, metadata, transform) says.
#[derive(Debug, Clone, PartialEq)]
pub struct Head {
    pub compression: u32,
    /// Bytes from the grid's start to the end of its transform.
    pub len: usize,
    /// `file_voxel_count`, when the metadata has it.
    pub voxel_count: Option<i64>,
    /// `file_bbox_min` and `file_bbox_max`, when the metadata has both.
    pub bbox: Option<(IVec3, IVec3)>,
}

/// What the walk of a tree found.
#[derive(Debug, Clone, PartialEq)]
pub struct TreeSummary {
    pub leaves: usize,
    /// Internal nodes: (4096^3 nodes, 128^3 nodes).
    pub internal_nodes: (usize, usize),
    /// Active voxels, tiles counted by their volume.
    pub active_voxels: u128,
    /// Inclusive bounds of the active voxels and tiles.
    pub bbox: Option<(IVec3, IVec3)>,
}

impl TreeSummary {
    /// Bytes OpenVDB's tree of these nodes takes (leaf buffers, node tables
    /// of 8-byte unions, masks), for a check before anything is allocated.
    pub fn openvdb_bytes(&self, kind: ValueKind) -> u64 {
        let leaf = 512 * kind.size() as u64 + 64 + 32;
        let n4 = 4096 * 8.max(kind.size() as u64) + 1024 + 64;
        let n5 = 32768 * 8.max(kind.size() as u64) + 8192 + 64;
        self.leaves as u64 * leaf
            + self.internal_nodes.1 as u64 * n4
            + self.internal_nodes.0 as u64 * n5
    }
}

/// Little-endian reads through a grid's bytes, every read bounds-checked,
/// optionally recording the fields it reads.
struct Cur<'a, 'f> {
    b: &'a [u8],
    pos: usize,
    /// File offset of `b[0]`, for messages.
    base: u64,
    fields: Option<&'f mut Vec<Field>>,
}

impl<'a> Cur<'a, '_> {
    fn at(&self) -> u64 {
        self.base + self.pos as u64
    }
    fn note(&mut self, size: usize, kind: FieldKind) {
        self.note_at(self.at(), size, kind);
    }
    fn note_at(&mut self, offset: u64, size: usize, kind: FieldKind) {
        if let Some(f) = self.fields.as_deref_mut() {
            f.push(Field {
                offset,
                size: size as u32,
                kind,
            });
        }
    }
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], String> {
        if n > self.b.len() - self.pos {
            return Err(format!(
                "{what} ({n} bytes at byte {}) runs past the grid's end at byte {}",
                self.at(),
                self.base + self.b.len() as u64
            ));
        }
        let s = &self.b[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], String> {
        Ok(self.take(N, what)?.try_into().unwrap())
    }
    fn u8(&mut self, what: &str) -> Result<u8, String> {
        Ok(self.take(1, what)?[0])
    }
    fn u32(&mut self, what: &str, kind: Option<FieldKind>) -> Result<u32, String> {
        if let Some(k) = kind {
            self.note(4, k);
        }
        Ok(u32::from_le_bytes(self.array(what)?))
    }
    fn i32(&mut self, what: &str) -> Result<i32, String> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }
    fn i64(&mut self, what: &str, kind: FieldKind) -> Result<i64, String> {
        self.note(8, kind);
        Ok(i64::from_le_bytes(self.array(what)?))
    }
    /// OpenVDB's `readString`: a u32 length and the bytes.
    fn string(&mut self, what: &str) -> Result<&'a [u8], String> {
        let n = self.u32(what, Some(FieldKind::Length))? as usize;
        self.take(n, what)
    }
    fn coord(&mut self, what: &str) -> Result<IVec3, String> {
        self.note(12, FieldKind::Origin);
        Ok(IVec3::new(
            self.i32(what)?,
            self.i32(what)?,
            self.i32(what)?,
        ))
    }
    fn mask(&mut self, words: usize, what: &str) -> Result<&'a [u8], String> {
        self.note(words * 8, FieldKind::Mask);
        self.take(words * 8, what)
    }
}

/// Bytes OpenVDB 10 reads for a metadata value of a registered fixed-size
/// type (`TypedMetadata<T>::readValue` reads `sizeof(T)` whatever the
/// stored size says), `None` for strings and unregistered types, which
/// take the stored size. vdbphoton unregisters `__delayedload` (see
/// `cpp/vdb_bridge.cc`), so it is read as raw bytes too.
pub(crate) fn fixed_meta_size(type_name: &str) -> Option<usize> {
    Some(match type_name {
        "bool" => 1,
        "float" | "int32" | "ptidx32" | "ptdataidx32" => 4,
        "double" | "int64" | "ptidx64" | "ptdataidx64" | "vec2i" | "vec2s" => 8,
        "vec3i" | "vec3s" => 12,
        "vec2d" | "vec4i" | "vec4s" => 16,
        "vec3d" => 24,
        "vec4d" => 32,
        "mat4s" => 64,
        "mat4d" => 128,
        _ => return None,
    })
}

/// Checks one metadata value against its type; the caller names the entry.
pub(crate) fn check_meta_value(type_name: &str, value: &[u8]) -> Result<(), String> {
    if let Some(n) = fixed_meta_size(type_name) {
        if value.len() != n {
            return Err(format!(
                "its value has {} bytes where a {type_name} has {n}",
                value.len()
            ));
        }
        if type_name == "bool" && value[0] > 1 {
            return Err(format!("its bool value is {}", value[0]));
        }
    }
    Ok(())
}

fn name_of(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn vec3i(v: &[u8]) -> IVec3 {
    let c = |i: usize| i32::from_le_bytes(v[4 * i..4 * i + 4].try_into().unwrap());
    IVec3::new(c(0), c(1), c(2))
}

/// Bytes a linear map's body takes in the file (`math::*Map::read`).
fn linear_map_size(name: &[u8]) -> Option<usize> {
    Some(match name {
        b"AffineMap" | b"UnitaryMap" => 128,
        b"ScaleMap" | b"UniformScaleMap" => 120,
        b"TranslationMap" => 24,
        b"ScaleTranslateMap" | b"UniformScaleTranslateMap" => 144,
        _ => return None,
    })
}

fn read_head(c: &mut Cur) -> Result<Head, String> {
    let compression = c.u32("the compression flags", Some(FieldKind::Flags))?;
    if compression & !(COMPRESS_ZIP | COMPRESS_ACTIVE_MASK | COMPRESS_BLOSC) != 0 {
        return Err(format!("unknown compression flags 0x{compression:x}"));
    }
    let count = c.u32("the metadata count", Some(FieldKind::Count))?;
    let mut voxel_count = None;
    let (mut bmin, mut bmax) = (None, None);
    for i in 0..count {
        let name = c.string("a metadata name")?;
        let ty = c.string("a metadata type name")?;
        let value = c.string("a metadata value")?;
        check_meta_value(&name_of(ty), value).map_err(|e| {
            format!(
                "metadata entry {} ('{}', {}): {e}",
                i + 1,
                name_of(name),
                name_of(ty)
            )
        })?;
        match (name, ty) {
            (b"file_voxel_count", b"int64") => {
                voxel_count = Some(i64::from_le_bytes(value.try_into().unwrap()))
            }
            (b"file_bbox_min", b"vec3i") => bmin = Some(vec3i(value)),
            (b"file_bbox_max", b"vec3i") => bmax = Some(vec3i(value)),
            _ => {}
        }
    }
    let map = c.string("the transform's map type")?;
    if map == b"NonlinearFrustumMap" {
        // Bounding box, taper, depth, then a second map, which must be
        // linear (a frustum inside a frustum would recurse in OpenVDB).
        c.take(64, "the frustum map")?;
        let second = c.string("the frustum's second map type")?;
        let n = linear_map_size(second).ok_or_else(|| {
            format!(
                "the frustum transform's second map has type '{}'",
                name_of(second)
            )
        })?;
        c.take(n, "the frustum's second map")?;
    } else {
        let n = linear_map_size(map)
            .ok_or_else(|| format!("unknown transform map type '{}'", name_of(map)))?;
        c.take(n, "the transform")?;
    }
    Ok(Head {
        compression,
        len: c.pos,
        voxel_count,
        bbox: bmin.zip(bmax),
    })
}

/// How a grid's node values are stored (`io::readCompressedValues`).
#[derive(Clone, Copy)]
struct Storage {
    compression: u32,
    kind: ValueKind,
    half: bool,
}

/// Walks one node's compressed values: `dest` values, `active` of them
/// active, a selection mask of `mask_words` words.
fn values(
    c: &mut Cur,
    s: Storage,
    dest: usize,
    active: usize,
    mask_words: usize,
) -> Result<(), String> {
    let mask_compressed = s.compression & COMPRESS_ACTIVE_MASK != 0;
    c.note(1, FieldKind::NodeMeta);
    let meta = c.u8("the node's compression byte")? as i8;
    if !(0..=NO_MASK_AND_ALL_VALS).contains(&meta) {
        return Err(format!(
            "its compression byte is {meta} (0 to 6 are defined)"
        ));
    }
    if !mask_compressed && meta != NO_MASK_AND_ALL_VALS {
        return Err(format!(
            "its compression byte is {meta} in a grid without mask compression"
        ));
    }
    let vs = s.kind.size();
    // One or two inactive values, stored at full size even for half floats.
    match meta {
        2 | 4 => drop(c.take(vs, "an inactive value")?),
        5 => drop(c.take(2 * vs, "two inactive values")?),
        _ => {}
    }
    if (3..=5).contains(&meta) {
        c.mask(mask_words, "the selection mask")?;
    }
    let count = if mask_compressed && meta != NO_MASK_AND_ALL_VALS {
        active
    } else {
        dest
    };
    let bytes = count * if s.half { s.kind.half_size() } else { vs };
    if s.half && count == 0 {
        // `HalfReader::read` returns before reading anything.
        return Ok(());
    }
    if s.compression & (COMPRESS_BLOSC | COMPRESS_ZIP) == 0 {
        c.take(bytes, "the values")?;
        return Ok(());
    }
    let blosc = s.compression & COMPRESS_BLOSC != 0;
    let n = c.i64("the block length", FieldKind::BlockLength)?;
    if n <= 0 {
        // Stored uncompressed: OpenVDB reads -n bytes into the buffer.
        if n.checked_neg() != Some(bytes as i64) {
            return Err(format!(
                "its uncompressed block claims {} bytes where the node's {count} values take {bytes}",
                -(n as i128)
            ));
        }
        c.take(bytes, "the values")?;
        return Ok(());
    }
    if bytes == 0 && !blosc {
        return Err(format!("it has a {n}-byte zlib block for no values"));
    }
    let block_at = c.at();
    let block = c.take(n as usize, "the compressed block")?;
    if blosc {
        // c-blosc trusts its header: its compressed size must be the
        // block's, its uncompressed size what the node needs.
        if block.len() < 16 {
            return Err(format!(
                "its {n}-byte Blosc block is shorter than a Blosc header"
            ));
        }
        c.note_at(block_at + 4, 12, FieldKind::BloscSizes);
        let word = |i: usize| u32::from_le_bytes(block[i..i + 4].try_into().unwrap());
        let (nbytes, cbytes) = (word(4), word(12));
        if cbytes as u64 != n as u64 {
            return Err(format!(
                "its Blosc header says {cbytes} compressed bytes in a {n}-byte block"
            ));
        }
        if nbytes as usize != bytes {
            return Err(format!(
                "its Blosc block would decompress to {nbytes} bytes where the node's {count} values take {bytes}"
            ));
        }
    } else {
        // zlib: a deflate stream with no stored size; `uncompress` is
        // bounded by the node's buffer. The two header bytes must agree.
        let valid = block.len() >= 2
            && block[0] & 0x0f == 8
            && (u16::from(block[0]) << 8 | u16::from(block[1])) % 31 == 0;
        if !valid {
            return Err("its zlib block has no valid zlib header".into());
        }
    }
    Ok(())
}

fn words(b: &[u8]) -> impl Iterator<Item = u64> + '_ {
    b.chunks_exact(8)
        .map(|w| u64::from_le_bytes(w.try_into().unwrap()))
}

fn popcount(b: &[u8]) -> usize {
    words(b).map(|w| w.count_ones() as usize).sum()
}

/// Set bits of a mask, in order.
fn ones(b: &[u8]) -> impl Iterator<Item = usize> + '_ {
    words(b).enumerate().flat_map(|(i, mut w)| {
        std::iter::from_fn(move || {
            (w != 0).then(|| {
                let t = w.trailing_zeros() as usize;
                w &= w - 1;
                64 * i + t
            })
        })
    })
}

#[derive(Default)]
struct Walk {
    /// Leaves: offset of their topology mask in the grid's bytes, origin.
    leaves: Vec<(usize, IVec3)>,
    n4: usize,
    n5: usize,
    active: u128,
    lo: IVec3,
    hi: IVec3,
}

impl Walk {
    fn expand(&mut self, lo: IVec3, hi: IVec3) {
        self.lo = self.lo.min(lo);
        self.hi = self.hi.max(hi);
    }
    /// Active tiles of an internal node: `dim` voxels a side, `log2` its
    /// table's side.
    fn tiles(&mut self, origin: IVec3, value_mask: &[u8], log2: u32, child_total: u32) {
        let dim = 1i32 << child_total;
        let mut n = 0u128;
        for i in ones(value_mask) {
            let i = i as i32;
            let l = IVec3::new(
                i >> (2 * log2),
                (i >> log2) & ((1 << log2) - 1),
                i & ((1 << log2) - 1),
            );
            let o = origin + (l << child_total as i32);
            self.expand(o, o + (dim - 1));
            n += 1;
        }
        self.active += n << (3 * child_total);
    }
}

/// Bounds of a leaf's active voxels from its mask (bit x·64 + y·8 + z).
fn leaf_bounds(mask: &[u8]) -> Option<(IVec3, IVec3)> {
    let (mut xlo, mut xhi, mut or) = (8, 0, 0u64);
    for (x, w) in words(mask).enumerate() {
        if w != 0 {
            xlo = xlo.min(x as i32);
            xhi = x as i32;
            or |= w;
        }
    }
    if or == 0 {
        return None;
    }
    let ylo = or.trailing_zeros() as i32 / 8;
    let yhi = 7 - or.leading_zeros() as i32 / 8;
    let mut zbits = 0u8;
    for y in 0..8 {
        zbits |= (or >> (8 * y)) as u8;
    }
    let zlo = zbits.trailing_zeros() as i32;
    let zhi = 7 - zbits.leading_zeros() as i32;
    Some((IVec3::new(xlo, ylo, zlo), IVec3::new(xhi, yhi, zhi)))
}

/// An internal node of `log2` (5 or 4) at `origin`: masks, values, children.
fn internal(c: &mut Cur, s: Storage, w: &mut Walk, origin: IVec3, log2: u32) -> Result<(), String> {
    let n = 1usize << (3 * log2);
    let mask_words = n / 64;
    let child_total = if log2 == 5 { 7 } else { 3 };
    let children = c.mask(mask_words, "the child mask")?;
    let value_mask = c.mask(mask_words, "the value mask")?;
    if words(children)
        .zip(words(value_mask))
        .any(|(a, b)| a & b != 0)
    {
        return Err("a child and an active tile at the same place".into());
    }
    values(c, s, n, popcount(value_mask), mask_words).map_err(|e| format!("its values: {e}"))?;
    w.tiles(origin, value_mask, log2, child_total);
    if log2 == 5 {
        w.n5 += 1;
    } else {
        w.n4 += 1;
    }
    for i in ones(children) {
        let i = i as i32;
        let m = (1 << log2) - 1;
        let l = IVec3::new(i >> (2 * log2), (i >> log2) & m, i & m);
        let o = origin + (l << child_total as i32);
        if log2 == 5 {
            internal(c, s, w, o, 4)
                .map_err(|e| format!("node at ({}, {}, {}): {e}", o.x, o.y, o.z))?;
        } else {
            let at = c.pos;
            let mask = c.mask(8, "a leaf's value mask")?;
            if let Some((lo, hi)) = leaf_bounds(mask) {
                w.expand(o + lo, o + hi);
                w.active += popcount(mask) as u128;
            }
            w.leaves.push((at, o));
        }
    }
    Ok(())
}

fn read_tree(c: &mut Cur, s: Storage, block_rel: usize) -> Result<TreeSummary, String> {
    let buffers = c.u32("the buffer count", Some(FieldKind::Count))?;
    if buffers != 1 {
        return Err(format!(
            "the tree has buffer count {buffers} (OpenVDB writes 1)"
        ));
    }
    let vs = s.kind.size();
    c.take(vs, "the background value")?;
    let tiles = c.u32("the root tile count", Some(FieldKind::Count))?;
    let children = c.u32("the root child count", Some(FieldKind::Count))?;
    let mut w = Walk {
        lo: IVec3::MAX,
        hi: IVec3::MIN,
        ..Default::default()
    };
    // Keys must be aligned, unique and in OpenVDB's map order (x, y, z),
    // which is the order `RootNode::readBuffers` visits the children in.
    let aligned = |o: IVec3| o & 4095 == IVec3::ZERO;
    let key = |o: IVec3| (o.x, o.y, o.z);
    let mut keys: Vec<(i32, i32, i32)> = Vec::new();
    let mut last: Option<(i32, i32, i32)> = None;
    for t in 0..tiles {
        let o = c.coord("a root tile")?;
        c.take(vs, "a root tile's value")?;
        let active = c.u8("a root tile's state")?;
        let bad = |m: &str| format!("root tile {} at ({}, {}, {}) {m}", t + 1, o.x, o.y, o.z);
        if !aligned(o) {
            return Err(bad("is not aligned to 4096"));
        }
        if active > 1 {
            return Err(bad(&format!("has state byte {active}")));
        }
        if last.is_some_and(|l| l >= key(o)) {
            return Err(bad("is out of order or a duplicate"));
        }
        last = Some(key(o));
        keys.push(key(o));
        if active == 1 {
            w.expand(o, o + 4095);
            w.active += 1u128 << 36;
        }
    }
    last = None;
    for k in 0..children {
        let o = c.coord("a root child's origin")?;
        let bad = |m: &str| format!("root child {} at ({}, {}, {}) {m}", k + 1, o.x, o.y, o.z);
        if !aligned(o) {
            return Err(bad("is not aligned to 4096"));
        }
        if last.is_some_and(|l| l >= key(o)) {
            return Err(bad("is out of order or a duplicate"));
        }
        if keys.binary_search(&key(o)).is_ok() {
            return Err(bad("is also a root tile"));
        }
        last = Some(key(o));
        internal(c, s, &mut w, o, 5)
            .map_err(|e| format!("node at ({}, {}, {}): {e}", o.x, o.y, o.z))?;
    }
    if c.pos != block_rel {
        return Err(format!(
            "the tree's topology ends at byte {}, but the grid's data block starts at byte {}",
            c.at(),
            c.base + block_rel as u64
        ));
    }
    for (i, &(mask_at, o)) in w.leaves.iter().enumerate() {
        let leaf = |e: String| {
            format!(
                "leaf {} of {} at ({}, {}, {}): {e}",
                i + 1,
                w.leaves.len(),
                o.x,
                o.y,
                o.z
            )
        };
        let topo = &c.b[mask_at..mask_at + 64];
        let mask = c.mask(8, "a leaf's value mask").map_err(leaf)?;
        if mask != topo {
            return Err(leaf(
                "its value mask differs from the one in the topology".into(),
            ));
        }
        values(c, s, 512, popcount(mask), 8).map_err(leaf)?;
    }
    if c.pos != c.b.len() {
        return Err(format!(
            "the last leaf ends at byte {}, but the grid ends at byte {}",
            c.at(),
            c.base + c.b.len() as u64
        ));
    }
    let bbox = (w.lo.cmple(w.hi).all()).then_some((w.lo, w.hi));
    Ok(TreeSummary {
        leaves: w.leaves.len(),
        internal_nodes: (w.n5, w.n4),
        active_voxels: w.active,
        bbox,
    })
}

/// Checks the head of a grid: `bytes` start at the grid's start (the
/// descriptor's first offset, file offset `base`).
pub fn check_head(bytes: &[u8], base: u64) -> Result<Head, String> {
    let mut c = Cur {
        b: bytes,
        pos: 0,
        base,
        fields: None,
    };
    read_head(&mut c)
}

/// Checks a whole grid: `bytes` are the grid's bytes from its start to its
/// end (file offsets `base` to `base + bytes.len()`), `block_pos` the file
/// offset of its data block, `kind` its tree's value type and half-float
/// flag. The metadata's voxel count and bounding box, when present, must
/// be the tree's.
pub fn check_grid(
    bytes: &[u8],
    base: u64,
    block_pos: u64,
    kind: (ValueKind, bool),
    fields: Option<&mut Vec<Field>>,
) -> Result<(Head, TreeSummary), String> {
    let mut c = Cur {
        b: bytes,
        pos: 0,
        base,
        fields,
    };
    let head = read_head(&mut c)?;
    let block_rel = block_pos
        .checked_sub(base)
        .filter(|&r| r <= bytes.len() as u64)
        .ok_or_else(|| format!("its data block offset {block_pos} lies outside the grid"))?;
    let s = Storage {
        compression: head.compression,
        kind: kind.0,
        half: kind.1,
    };
    let tree = read_tree(&mut c, s, block_rel as usize)?;
    if let Some(n) = head.voxel_count {
        if i128::from(n) != tree.active_voxels as i128 {
            return Err(format!(
                "its metadata claims {n} active voxels, its tree has {}",
                tree.active_voxels
            ));
        }
    }
    if let Some((lo, hi)) = head.bbox {
        let claimed = lo.cmple(hi).all().then_some((lo, hi));
        if claimed != tree.bbox {
            let show = |b: Option<(IVec3, IVec3)>| match b {
                Some((a, b)) => {
                    format!("[{}, {}, {}] -> [{}, {}, {}]", a.x, a.y, a.z, b.x, b.y, b.z)
                }
                None => "empty".to_string(),
            };
            return Err(format!(
                "its metadata claims active bounds {}, its tree has {}",
                show(claimed),
                show(tree.bbox)
            ));
        }
    }
    Ok((head, tree))
}

/// The fields the walk of one grid reads (`b`: the grid's bytes, from
/// `grid_pos` in the file, its data block at `block_pos`), appended to
/// `out` up to where the walk fails (`crate::vdb::file_fields`).
pub fn grid_fields(
    b: &[u8],
    grid_pos: u64,
    block_pos: u64,
    type_name: &str,
    instanced: bool,
    out: &mut Vec<Field>,
) {
    let mut c = Cur {
        b,
        pos: 0,
        base: grid_pos,
        fields: Some(out),
    };
    let Ok(head) = read_head(&mut c) else {
        return;
    };
    if let Some(kind) = ValueKind::of_type_name(type_name) {
        if instanced {
            return;
        }
        let s = Storage {
            compression: head.compression,
            kind: kind.0,
            half: kind.1,
        };
        let rel = (block_pos - grid_pos) as usize;
        let _ = read_tree(&mut c, s, rel);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leaf_bounds_from_mask_bits() {
        let mut m = [0u8; 64];
        // Voxel (x=2, y=5, z=3): bit 2*64 + 5*8 + 3.
        let set = |m: &mut [u8; 64], x: usize, y: usize, z: usize| {
            let n = x * 64 + y * 8 + z;
            m[n / 8] |= 1 << (n % 8);
        };
        assert_eq!(leaf_bounds(&m), None);
        set(&mut m, 2, 5, 3);
        assert_eq!(
            leaf_bounds(&m),
            Some((IVec3::new(2, 5, 3), IVec3::new(2, 5, 3)))
        );
        set(&mut m, 7, 0, 6);
        set(&mut m, 4, 7, 0);
        assert_eq!(
            leaf_bounds(&m),
            Some((IVec3::new(2, 0, 0), IVec3::new(7, 7, 6)))
        );
    }

    #[test]
    fn ones_in_order() {
        let mut m = [0u8; 16];
        m[0] = 0b101;
        m[9] = 0x80;
        assert_eq!(ones(&m).collect::<Vec<_>>(), vec![0, 2, 79]);
        assert_eq!(popcount(&m), 3);
    }
}
