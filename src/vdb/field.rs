//! The fields of a `.vdb` file that the header check and the grid walk
//! read: where each is and what it is, for a fuzzer that damages lengths
//! and counts rather than random bytes (`crate::vdb::file_fields`).

/// What a field of the file is, for a fuzzer that wants to damage lengths
/// and counts rather than random bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FieldKind {
    /// A count of entries (metadata entries, root tiles or children, buffer
    /// count, the grid count).
    Count,
    /// A string's or a metadata value's length.
    Length,
    /// A grid's compression flags.
    Flags,
    /// A grid descriptor's offset.
    Offset,
    /// A node's mask-compression metadata byte.
    NodeMeta,
    /// The signed length before a compressed block.
    BlockLength,
    /// A Blosc header's uncompressed, block and compressed sizes.
    BloscSizes,
    /// A child or value mask.
    Mask,
    /// A root tile's or child's origin.
    Origin,
}

/// One field: where it is in the file, how many bytes, what it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Field {
    pub offset: u64,
    pub size: u32,
    pub kind: FieldKind,
}
