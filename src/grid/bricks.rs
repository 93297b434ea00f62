//! Brick values in memory aligned to whole bricks.
//!
//! A trilinear lookup reads a 2x2x2 stencil: in OpenVDB's voxel order
//! (z fastest, rows of 8) that is two z-pairs in each of two x-planes.
//! With a brick starting on a 64-byte cache line, a row pair fills one line
//! and the stencil of a cell inside a brick touches 2.86 lines on average;
//! with the 16-byte offset that `malloc` gives a large `Vec<f32>`, half the
//! rows straddle a line and it touches 3.14. Random lookups in grids larger
//! than the caches are bound by those lines, so the values are stored as
//! blocks aligned to 2048 bytes: an `f32` brick is exactly 2048 bytes, so no
//! brick straddles a 4 KiB page either (a `Vec3` brick is 6144 bytes, also a
//! multiple of the alignment, so neither type is padded).

use super::{GridValue, BRICK_VOXELS};
use std::ops::{Deref, DerefMut};

#[derive(Clone, Copy)]
#[repr(C, align(2048))]
struct Block<T>([T; BRICK_VOXELS]);

/// Voxel values, 512 per brick, in bricks aligned as the module describes.
/// It reads as one `[T]` slice (brick `b` at `b * 512..`) and grows like a
/// `Vec` (the last brick may be partial while it is built).
#[derive(Clone)]
pub struct BrickValues<T> {
    blocks: Vec<Block<T>>,
    len: usize,
}

impl<T: GridValue> BrickValues<T> {
    const NO_PADDING: () = assert!(
        std::mem::size_of::<Block<T>>() == BRICK_VOXELS * std::mem::size_of::<T>(),
        "a block must be its 512 values and nothing else"
    );

    pub fn new() -> Self {
        Self {
            blocks: Vec::new(),
            len: 0,
        }
    }

    /// Room for `bricks` whole bricks without reallocating.
    pub fn with_brick_capacity(bricks: usize) -> Self {
        Self {
            blocks: Vec::with_capacity(bricks),
            len: 0,
        }
    }

    /// `bricks` bricks whose `CHANNELS` floats per value `fill` writes
    /// through a pointer to `len` floats, with room for `spare_values` more
    /// values after them, without zeroing them first: the
    /// loader's copy from OpenVDB touches the fresh pages once, from all
    /// threads, instead of after a zeroing pass (5 ms on the 512^3 cloud).
    ///
    /// # Safety
    /// When `fill` returns `Ok`, it must have written all `len` floats.
    pub(crate) unsafe fn from_fill<E>(
        bricks: usize,
        spare_values: usize,
        fill: impl FnOnce(*mut f32, usize) -> Result<(), E>,
    ) -> Result<Self, E> {
        let capacity = bricks + spare_values.div_ceil(BRICK_VOXELS);
        let mut blocks: Vec<Block<T>> = Vec::with_capacity(capacity);
        advise_huge_pages(
            blocks.as_mut_ptr().cast(),
            capacity * std::mem::size_of::<Block<T>>(),
        );
        let len = bricks * BRICK_VOXELS * T::CHANNELS;
        // A value is CHANNELS floats with no padding (`GridValue`), and a
        // block is its values (NO_PADDING), so the capacity holds `len`
        // floats.
        #[allow(clippy::let_unit_value)]
        let () = Self::NO_PADDING;
        fill(blocks.as_mut_ptr().cast::<f32>(), len)?;
        // SAFETY: `fill` wrote every float of the `bricks` blocks, and any
        // float bits are valid values.
        blocks.set_len(bricks);
        Ok(Self {
            blocks,
            len: bricks * BRICK_VOXELS,
        })
    }

    pub fn push(&mut self, v: T) {
        let k = self.len % BRICK_VOXELS;
        if k == 0 {
            self.blocks.push(Block([T::zero(); BRICK_VOXELS]));
        }
        let last = self.blocks.len() - 1;
        self.blocks[last].0[k] = v;
        self.len += 1;
    }

    pub fn extend_from_slice(&mut self, values: &[T]) {
        self.extend(values.iter().copied());
    }

    /// Bytes allocated.
    pub fn capacity_bytes(&self) -> usize {
        self.blocks.capacity() * std::mem::size_of::<Block<T>>()
    }
}

/// Asks Linux to back the whole 2 MiB pages inside `[ptr, ptr + bytes)`
/// with huge pages (`madvise(MADV_HUGEPAGE)`; Debian's default
/// transparent-huge-page mode `madvise` uses them only where asked), before
/// anything touches them. Random lookups in a grid larger than the caches
/// miss the TLB on most 4 KiB pages; with 2 MiB pages the batched lookups
/// on the 512^3 cloud ran 5-16 % faster (`benches/grid.rs`). Advice only:
/// errors are ignored, and other systems skip it.
fn advise_huge_pages(ptr: *mut u8, bytes: usize) {
    // MADV_HUGEPAGE is 14 in Linux's generic constants, which x86-64 and
    // AArch64 use (some other architectures number it differently).
    #[cfg(all(
        target_os = "linux",
        any(target_arch = "x86_64", target_arch = "aarch64")
    ))]
    {
        const HUGE: usize = 1 << 21;
        const MADV_HUGEPAGE: i32 = 14;
        extern "C" {
            fn madvise(addr: *mut std::ffi::c_void, len: usize, advice: i32) -> i32;
        }
        let start = (ptr as usize).next_multiple_of(HUGE);
        let end = (ptr as usize + bytes) / HUGE * HUGE;
        if end > start {
            // SAFETY: the range lies inside the allocation at `ptr`, and
            // the advice changes how its pages are backed, never what they
            // hold.
            unsafe { madvise(start as *mut _, end - start, MADV_HUGEPAGE) };
        }
    }
    #[cfg(not(all(
        target_os = "linux",
        any(target_arch = "x86_64", target_arch = "aarch64")
    )))]
    let _ = (ptr, bytes);
}

impl<T: GridValue> Default for BrickValues<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: GridValue> Extend<T> for BrickValues<T> {
    fn extend<I: IntoIterator<Item = T>>(&mut self, iter: I) {
        for v in iter {
            self.push(v);
        }
    }
}

impl<T: GridValue> From<Vec<T>> for BrickValues<T> {
    fn from(v: Vec<T>) -> Self {
        let mut b = Self::with_brick_capacity(v.len().div_ceil(BRICK_VOXELS));
        b.extend_from_slice(&v);
        b
    }
}

impl<T: GridValue> Deref for BrickValues<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        #[allow(clippy::let_unit_value)]
        let () = Self::NO_PADDING;
        // SAFETY: `Block<T>` is `repr(C)` around `[T; 512]` with no padding
        // (NO_PADDING), so `blocks` is `blocks.len() * 512` initialised `T`s
        // in a row, and `len` never exceeds that.
        unsafe { std::slice::from_raw_parts(self.blocks.as_ptr().cast::<T>(), self.len) }
    }
}

impl<T: GridValue> DerefMut for BrickValues<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        #[allow(clippy::let_unit_value)]
        let () = Self::NO_PADDING;
        // SAFETY: as in `deref`, through the unique borrow of `blocks`.
        unsafe { std::slice::from_raw_parts_mut(self.blocks.as_mut_ptr().cast::<T>(), self.len) }
    }
}

impl<T: GridValue> std::fmt::Debug for BrickValues<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "BrickValues({} values)", self.len)
    }
}

impl<T: GridValue> PartialEq for BrickValues<T> {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn bricks_start_on_2048_byte_boundaries() {
        let mut v = BrickValues::<f32>::new();
        v.extend((0..3 * 512 + 5).map(|i| i as f32));
        assert_eq!(v.len(), 3 * 512 + 5);
        assert_eq!(v.as_ptr() as usize % 2048, 0);
        assert_eq!(v[512 * 2 + 7], (512 * 2 + 7) as f32);
        assert_eq!(v[3 * 512 + 4], (3 * 512 + 4) as f32);
        let w: BrickValues<Vec3> = vec![Vec3::ZERO; 1024].into();
        assert_eq!(w.as_ptr() as usize % 2048, 0);
        assert_eq!(w.len(), 1024);
        assert_eq!(w.capacity_bytes(), 2 * 512 * 12);
    }

    #[test]
    fn floats_view_covers_every_channel() {
        let mut w: BrickValues<Vec3> = vec![Vec3::ZERO; 512].into();
        let f = Vec3::as_floats_mut(&mut w);
        assert_eq!(f.len(), 1536);
        f[3 * 10 + 2] = 7.0;
        assert_eq!(w[10], Vec3::new(0.0, 0.0, 7.0));
        let v: BrickValues<f32> = vec![1.0; 600].into();
        assert_eq!(v.len(), 600);
        assert_eq!(v.capacity_bytes(), 2 * 2048);
    }
}
