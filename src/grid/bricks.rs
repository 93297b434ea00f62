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
use std::alloc::{alloc, dealloc, handle_alloc_error, Layout};
use std::marker::PhantomData;
use std::ops::{Deref, DerefMut};
use std::ptr::NonNull;

#[derive(Clone, Copy)]
#[repr(C, align(2048))]
struct Block<T>([T; BRICK_VOXELS]);

/// Linux's transparent huge page size on x86-64 and AArch64 (4 KiB base
/// pages).
const HUGE_PAGE: usize = 1 << 21;

/// Voxel values, 512 per brick, in bricks aligned as the module describes.
/// It reads as one `[T]` slice (brick `b` at `b * 512..`) and grows like a
/// `Vec` (the last brick may be partial while it is built).
///
/// It owns its allocation rather than wrapping a `Vec<Block<T>>` so that
/// a buffer of 2 MiB or more can start on a 2 MiB boundary: then every
/// 2 MiB of it can be a huge page (`advise_huge_pages`), where a `Vec`'s
/// allocation starts anywhere and its unaligned head and tail fall back to
/// 4 KiB pages (pig.vdb: 4 of its 5.95 MiB of bricks were huge pages, now
/// all 6; the 512^3 cloud: 18 of 20.5, now 20). Each 4 KiB page costs a
/// fault at first touch (about 3.4 µs here, against 0.25 ms for a whole
/// 2 MiB page), and lookups miss the TLB more often in 4 KiB pages: loads
/// in a fresh process ran about 1 ms faster, lookups within the noise.
pub struct BrickValues<T> {
    ptr: NonNull<Block<T>>,
    /// Blocks allocated.
    cap: usize,
    /// Values in use; blocks up to `len.div_ceil(512)` are initialised.
    len: usize,
    _owns: PhantomData<Block<T>>,
}

// SAFETY: `BrickValues` owns its blocks as a `Vec` would.
unsafe impl<T: Send> Send for BrickValues<T> {}
// SAFETY: shared access only reads, as for a `Vec`.
unsafe impl<T: Sync> Sync for BrickValues<T> {}

impl<T: GridValue> BrickValues<T> {
    const NO_PADDING: () = assert!(
        std::mem::size_of::<Block<T>>() == BRICK_VOXELS * std::mem::size_of::<T>(),
        "a block must be its 512 values and nothing else"
    );

    pub fn new() -> Self {
        Self {
            ptr: NonNull::dangling(),
            cap: 0,
            len: 0,
            _owns: PhantomData,
        }
    }

    /// Room for `bricks` whole bricks without reallocating.
    pub fn with_brick_capacity(bricks: usize) -> Self {
        let mut v = Self::new();
        v.reserve_blocks(bricks);
        v
    }

    /// Blocks holding values (the last may be partial).
    fn blocks_in_use(&self) -> usize {
        self.len.div_ceil(BRICK_VOXELS)
    }

    /// Room for `blocks` blocks, growing as `Vec` does (at least doubling)
    /// when it must grow, so that appending stays linear.
    fn grow_for(&mut self, blocks: usize) {
        if blocks > self.cap {
            self.reserve_blocks(blocks.max(2 * self.cap));
        }
    }

    /// Grows the allocation to at least `blocks` blocks, moving the values.
    fn reserve_blocks(&mut self, blocks: usize) {
        if blocks <= self.cap {
            return;
        }
        let blocks = whole_huge_pages::<T>(blocks);
        let layout = block_layout::<T>(blocks);
        // SAFETY: the size is nonzero: blocks > cap >= 0, and a block is
        // 512 values of a `GridValue`, a sealed trait whose types (f32,
        // Vec3) are not zero-sized.
        let raw = unsafe { alloc(layout) };
        let Some(ptr) = NonNull::new(raw.cast::<Block<T>>()) else {
            handle_alloc_error(layout)
        };
        advise_huge_pages(raw, layout.size());
        let used = self.blocks_in_use();
        // SAFETY: both allocations hold at least `used` blocks and do not
        // overlap; the old one is freed with the layout it was made with.
        unsafe {
            std::ptr::copy_nonoverlapping(self.ptr.as_ptr(), ptr.as_ptr(), used);
            if self.cap > 0 {
                dealloc(self.ptr.as_ptr().cast(), block_layout::<T>(self.cap));
            }
        }
        self.ptr = ptr;
        self.cap = blocks;
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
        let mut v = Self::with_brick_capacity(bricks + spare_values.div_ceil(BRICK_VOXELS));
        let len = bricks * BRICK_VOXELS * T::CHANNELS;
        // A value is CHANNELS floats with no padding (`GridValue`), and a
        // block is its values (NO_PADDING), so the capacity holds `len`
        // floats.
        #[allow(clippy::let_unit_value)]
        let () = Self::NO_PADDING;
        fill(v.ptr.as_ptr().cast::<f32>(), len)?;
        // SAFETY: `fill` wrote every float of the `bricks` blocks, and any
        // float bits are valid values.
        v.len = bricks * BRICK_VOXELS;
        Ok(v)
    }

    pub fn push(&mut self, v: T) {
        let k = self.len % BRICK_VOXELS;
        let b = self.len / BRICK_VOXELS;
        if k == 0 {
            self.grow_for(b + 1);
            // SAFETY: block `b` is allocated (b < cap); a new block is
            // zeroed whole, so every block below `len.div_ceil(512)` is
            // initialised.
            unsafe {
                self.ptr
                    .as_ptr()
                    .add(b)
                    .write(Block([T::zero(); BRICK_VOXELS]))
            };
        }
        // SAFETY: block `b` is initialised (written above or earlier).
        unsafe { (*self.ptr.as_ptr().add(b)).0[k] = v };
        self.len += 1;
    }

    /// Appends `values`, growing the allocation as `Vec` does (at least
    /// doubling it), so that appending a brick at a time stays linear.
    pub fn extend_from_slice(&mut self, values: &[T]) {
        self.grow_for((self.len + values.len()).div_ceil(BRICK_VOXELS));
        self.extend(values.iter().copied());
    }

    /// Room for `additional` more values, and no more (beyond rounding to
    /// whole bricks and huge pages).
    pub fn reserve_exact(&mut self, additional: usize) {
        self.reserve_blocks((self.len + additional).div_ceil(BRICK_VOXELS));
    }

    /// Bytes allocated.
    pub fn capacity_bytes(&self) -> usize {
        self.cap * std::mem::size_of::<Block<T>>()
    }
}

impl<T> Drop for BrickValues<T> {
    fn drop(&mut self) {
        if self.cap > 0 {
            // SAFETY: allocated by `reserve_blocks` with this layout; the
            // values are plain floats with nothing to drop (`GridValue`).
            unsafe { dealloc(self.ptr.as_ptr().cast(), block_layout::<T>(self.cap)) };
        }
    }
}

/// `blocks`, or more to end on a 2 MiB boundary where that adds no more
/// than 1 MiB and no more than an eighth of the size: the last 2 MiB can
/// then be a huge page too, instead of up to 512 pages of 4 KiB, each a
/// fault (pig.vdb's 5.95 MiB of bricks had 1.95 MiB of them). Only where
/// the boundary is a whole number of blocks: always for `f32` bricks
/// (2 KiB), for `Vec3` bricks (6 KiB) only at multiples of 6 MiB.
fn whole_huge_pages<T>(blocks: usize) -> usize {
    let block = std::mem::size_of::<Block<T>>();
    let Some(bytes) = blocks.checked_mul(block) else {
        return blocks;
    };
    let Some(up) = bytes.checked_next_multiple_of(HUGE_PAGE) else {
        return blocks;
    };
    if up - bytes <= (HUGE_PAGE / 2).min(bytes / 8) && up % block == 0 {
        up / block
    } else {
        blocks
    }
}

/// The allocation of `blocks` blocks: aligned to a huge page from 2 MiB on
/// (see [`BrickValues`]), else to a block.
fn block_layout<T>(blocks: usize) -> Layout {
    let size = blocks
        .checked_mul(std::mem::size_of::<Block<T>>())
        .expect("brick buffer size overflows");
    let align = if size >= HUGE_PAGE {
        HUGE_PAGE
    } else {
        std::mem::align_of::<Block<T>>()
    };
    Layout::from_size_align(size, align).expect("brick buffer size overflows")
}

impl<T: GridValue> Clone for BrickValues<T> {
    fn clone(&self) -> Self {
        let used = self.blocks_in_use();
        let mut v = Self::with_brick_capacity(used);
        // SAFETY: `used` initialised blocks here, room for them there.
        unsafe { std::ptr::copy_nonoverlapping(self.ptr.as_ptr(), v.ptr.as_ptr(), used) };
        v.len = self.len;
        v
    }
}

/// Asks Linux to back the whole 2 MiB pages inside `[ptr, ptr + bytes)`
/// with huge pages (`madvise(MADV_HUGEPAGE)`; Debian's default
/// transparent-huge-page mode `madvise` uses them only where asked), before
/// anything touches them. Random lookups in a grid larger than the caches
/// miss the TLB on most 4 KiB pages; with 2 MiB pages the batched lookups
/// on the 512^3 cloud ran 5-16 % faster (`benches/grid.rs`), and first
/// touches fault once per 2 MiB instead of once per 4 KiB. Advice only:
/// errors are ignored, and other systems skip it.
fn advise_huge_pages(ptr: *mut u8, bytes: usize) {
    // MADV_HUGEPAGE is 14 in Linux's generic constants, which x86-64 and
    // AArch64 use (some other architectures number it differently).
    #[cfg(all(
        target_os = "linux",
        any(target_arch = "x86_64", target_arch = "aarch64")
    ))]
    {
        const MADV_HUGEPAGE: i32 = 14;
        extern "C" {
            fn madvise(addr: *mut std::ffi::c_void, len: usize, advice: i32) -> i32;
        }
        let start = (ptr as usize).next_multiple_of(HUGE_PAGE);
        let end = (ptr as usize + bytes) / HUGE_PAGE * HUGE_PAGE;
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
        // (NO_PADDING), so the initialised blocks are `len` (and more)
        // initialised `T`s in a row; with no blocks, `ptr` is dangling but
        // aligned and `len` is 0.
        unsafe { std::slice::from_raw_parts(self.ptr.as_ptr().cast::<T>(), self.len) }
    }
}

impl<T: GridValue> DerefMut for BrickValues<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        #[allow(clippy::let_unit_value)]
        let () = Self::NO_PADDING;
        // SAFETY: as in `deref`, through the unique borrow of `self`.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.as_ptr().cast::<T>(), self.len) }
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

    #[test]
    fn large_buffers_start_on_huge_pages_and_keep_values_as_they_grow() {
        // Grown by pushes across the 2 MiB threshold (1024 f32 bricks):
        // the values move with each reallocation.
        let n = 1100 * 512 + 3;
        let mut v = BrickValues::<f32>::new();
        v.extend((0..n).map(|i| i as f32));
        assert_eq!(v.len(), n);
        assert!(v.iter().enumerate().all(|(i, &x)| x == i as f32));
        assert_eq!(v.as_ptr() as usize % HUGE_PAGE, 0);
        let c = v.clone();
        assert!(c == v);
        assert_eq!(c.as_ptr() as usize % HUGE_PAGE, 0);
        // Reserved at once, as the loader does; below 2 MiB, block-aligned.
        let w = BrickValues::<Vec3>::with_brick_capacity(400);
        assert_eq!(w.as_ptr() as usize % HUGE_PAGE, 0);
        assert_eq!(w.capacity_bytes(), 400 * 512 * 12);
        // Just under a whole number of huge pages: rounded up to it.
        let r = BrickValues::<f32>::with_brick_capacity(2 * 1024 - 100);
        assert_eq!(r.capacity_bytes(), 2 * HUGE_PAGE);
        assert_eq!(r.as_ptr() as usize % HUGE_PAGE, 0);
        let small = BrickValues::<f32>::with_brick_capacity(3);
        assert_eq!(small.as_ptr() as usize % 2048, 0);
        assert_eq!(small.capacity_bytes(), 3 * 2048);
        // Filled through the loader's path.
        // SAFETY: the closure writes all `len` floats.
        let f = unsafe {
            BrickValues::<f32>::from_fill(1500, 700, |p, len| {
                for i in 0..len {
                    p.add(i).write(i as f32 * 0.5);
                }
                Ok::<(), ()>(())
            })
        }
        .unwrap();
        assert_eq!(f.len(), 1500 * 512);
        assert_eq!(f[1499 * 512 + 511], (1500 * 512 - 1) as f32 * 0.5);
        assert_eq!(f.as_ptr() as usize % HUGE_PAGE, 0);
        assert_eq!(f.capacity_bytes(), (1500 + 2) * 2048);
    }

    #[test]
    fn appending_a_brick_at_a_time_grows_geometrically() {
        // As the generator appends: a handful of reallocations, not one a
        // brick (which made appending quadratic).
        let mut v = BrickValues::<f32>::new();
        let brick = [1.5f32; 512];
        let mut caps = Vec::new();
        for _ in 0..100 {
            v.extend_from_slice(&brick);
            caps.push(v.capacity_bytes());
        }
        caps.dedup();
        assert!(caps.len() <= 8, "{} reallocations", caps.len());
        assert_eq!(v.len(), 100 * 512);
        assert!(v.iter().all(|&x| x == 1.5));
        // `reserve_exact` adds only what is asked, in whole bricks.
        let mut w = BrickValues::<f32>::with_brick_capacity(3);
        w.extend_from_slice(&[2.0; 3 * 512]);
        w.reserve_exact(10);
        assert_eq!(w.capacity_bytes(), 4 * 2048);
    }
}
