//! Voxel value types a [`Grid`](super::Grid) can hold.

use glam::Vec3;

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for glam::Vec3 {}
}

/// A value stored in a grid: `f32` (density, temperature, flame) or [`Vec3`]
/// (velocity, colour). `CHANNELS` floats per voxel, laid out as OpenVDB lays
/// out `float` and `vec3s` leaves, so whole leaves copy without conversion.
///
/// Sealed: the loader writes values as raw floats (`BrickValues::from_fill`),
/// which is sound only for types that are exactly `CHANNELS` floats.
pub trait GridValue:
    sealed::Sealed + Copy + PartialEq + Send + Sync + std::fmt::Debug + 'static
{
    const CHANNELS: usize;
    /// OpenVDB's value type name (`float`, `vec3s`).
    const TYPE_NAME: &'static str;
    fn zero() -> Self;
    fn from_slice(s: &[f32]) -> Self;
    fn write_to(self, out: &mut Vec<f32>);
    /// `a + (b - a) * w` computed as OpenVDB's `BoxSampler` does: the
    /// difference in the value type, the product in double, the sum in the
    /// value type again (so results match it to the last bit or two).
    fn lerp_f64(a: Self, b: Self, w: f64) -> Self;
    fn lerp_f32(a: Self, b: Self, w: f32) -> Self;
    fn min(a: Self, b: Self) -> Self;
    fn max(a: Self, b: Self) -> Self;
    fn is_finite(self) -> bool;
    fn max_component(self) -> f32;
    /// [min, max] over `v` (NaN ignored) and whether every value is finite.
    /// Written to vectorise: it runs over every voxel at load time.
    fn range_of(v: &[Self]) -> ([Self; 2], bool);
    /// The values as `CHANNELS` floats each, in place (for bulk copies).
    fn as_floats_mut(v: &mut [Self]) -> &mut [f32];
    /// `CHANNELS` floats per value.
    fn to_flat(v: &[Self]) -> Vec<f32>;
}

impl GridValue for f32 {
    const CHANNELS: usize = 1;
    const TYPE_NAME: &'static str = "float";
    fn zero() -> Self {
        0.0
    }
    fn from_slice(s: &[f32]) -> Self {
        s[0]
    }
    fn write_to(self, out: &mut Vec<f32>) {
        out.push(self);
    }
    #[inline(always)]
    fn lerp_f64(a: Self, b: Self, w: f64) -> Self {
        a + (((b - a) as f64) * w) as f32
    }
    #[inline(always)]
    fn lerp_f32(a: Self, b: Self, w: f32) -> Self {
        a + (b - a) * w
    }
    #[inline(always)]
    fn min(a: Self, b: Self) -> Self {
        // NaN-propagating, so a NaN voxel shows up in the brick ranges.
        if a.is_nan() || a < b {
            a
        } else {
            b
        }
    }
    #[inline(always)]
    fn max(a: Self, b: Self) -> Self {
        if a.is_nan() || a > b {
            a
        } else {
            b
        }
    }
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    fn max_component(self) -> f32 {
        self
    }
    fn range_of(v: &[Self]) -> ([Self; 2], bool) {
        let mut lo = [f32::INFINITY; 8];
        let mut hi = [f32::NEG_INFINITY; 8];
        let mut special = 0u32;
        let chunks = v.chunks_exact(8);
        let rest = chunks.remainder();
        for c in chunks {
            for i in 0..8 {
                lo[i] = lo[i].min(c[i]);
                hi[i] = hi[i].max(c[i]);
                special |= ((c[i].to_bits() & 0x7f80_0000) == 0x7f80_0000) as u32;
            }
        }
        for &x in rest {
            lo[0] = lo[0].min(x);
            hi[0] = hi[0].max(x);
            special |= !x.is_finite() as u32;
        }
        let lo = lo.iter().copied().fold(f32::INFINITY, f32::min);
        let hi = hi.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        ([lo, hi], special == 0)
    }
    fn as_floats_mut(v: &mut [Self]) -> &mut [f32] {
        v
    }
    fn to_flat(v: &[Self]) -> Vec<f32> {
        v.to_vec()
    }
}

impl GridValue for Vec3 {
    const CHANNELS: usize = 3;
    const TYPE_NAME: &'static str = "vec3s";
    fn zero() -> Self {
        Vec3::ZERO
    }
    fn from_slice(s: &[f32]) -> Self {
        Vec3::new(s[0], s[1], s[2])
    }
    fn write_to(self, out: &mut Vec<f32>) {
        out.extend_from_slice(&self.to_array());
    }
    #[inline(always)]
    fn lerp_f64(a: Self, b: Self, w: f64) -> Self {
        Vec3::new(
            f32::lerp_f64(a.x, b.x, w),
            f32::lerp_f64(a.y, b.y, w),
            f32::lerp_f64(a.z, b.z, w),
        )
    }
    #[inline(always)]
    fn lerp_f32(a: Self, b: Self, w: f32) -> Self {
        a + (b - a) * w
    }
    fn min(a: Self, b: Self) -> Self {
        Vec3::new(
            <f32 as GridValue>::min(a.x, b.x),
            <f32 as GridValue>::min(a.y, b.y),
            <f32 as GridValue>::min(a.z, b.z),
        )
    }
    fn max(a: Self, b: Self) -> Self {
        Vec3::new(
            <f32 as GridValue>::max(a.x, b.x),
            <f32 as GridValue>::max(a.y, b.y),
            <f32 as GridValue>::max(a.z, b.z),
        )
    }
    fn is_finite(self) -> bool {
        Vec3::is_finite(self)
    }
    fn max_component(self) -> f32 {
        self.max_element()
    }
    fn range_of(v: &[Self]) -> ([Self; 2], bool) {
        let mut lo = Vec3::INFINITY;
        let mut hi = Vec3::NEG_INFINITY;
        let mut finite = true;
        for &x in v {
            lo = lo.min(x);
            hi = hi.max(x);
            finite &= x.is_finite();
        }
        ([lo, hi], finite)
    }
    fn as_floats_mut(v: &mut [Self]) -> &mut [f32] {
        const _: () =
            assert!(std::mem::size_of::<Vec3>() == 12 && std::mem::align_of::<Vec3>() == 4);
        // SAFETY: glam's `Vec3` is `repr(C)` with fields x, y, z of f32 and
        // no padding (checked above), so n of them are 3n floats, and any
        // float bits are a valid `Vec3`.
        unsafe { std::slice::from_raw_parts_mut(v.as_mut_ptr().cast::<f32>(), 3 * v.len()) }
    }
    fn to_flat(v: &[Self]) -> Vec<f32> {
        v.iter().flat_map(|x| x.to_array()).collect()
    }
}
