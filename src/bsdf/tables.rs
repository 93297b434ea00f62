//! Directional-albedo tables of the GGX lobe, laid out and read as Cycles
//! 5.0 reads its own (`kernel/util/lookup_table.h`; the tables' meaning in
//! `app/cycles_precompute.cpp`, their use in `bsdf_microfacet.h`), computed
//! by our generator (`tests/bsdf_tables.rs`, deterministic quadrature over
//! the visible normals in f64 instead of Cycles' 2²⁰–2²⁶ Sobol samples)
//! and committed as `tables_data.rs`. Axes, each sampled at i/(n − 1):
//! roughness r = √α (Blender's Roughness, clamped to ≥ 10⁻⁴), the viewer's
//! μ = cos θo (clamped to ≥ 10⁻⁴), and for the 3-D tables a third
//! parameter z.
//!
//! - [`ggx_e`]: E(r, μ) = ∫ f cos θi dωi of a GGX lobe with F = 1 (32 × 32).
//! - [`ggx_e_avg`]: E_avg(r) = ∫₀¹ 2μ E(r, μ) dμ (32).
//! - [`ggx_ior_s`]: the mean, over visible normals, of where the dielectric
//!   Fresnel term lies between its F0 and 1 (0 for normals whose reflection
//!   falls below the horizon), for z = √((η − 1)/(η + 1)) (16 × 16 × 16):
//!   Cycles' `ggx_gen_schlick_ior_s`, behind its albedo estimate of the
//!   specular layer.
//! - [`ggx_schlick5_s`]: the same for Schlick's (1 − cos)⁵, Cycles'
//!   `ggx_gen_schlick_s` read at z = 0.5 (the two slices it interpolates,
//!   exponents 40/7 and 35/8, 2 × 16 × 16), behind its albedo estimate of
//!   the metallic lobe.
//!
//! Against the tables Cycles 5.0 ships (`scene/shader.tables`), entry by
//! entry (`tests/bsdf_tables.rs`, `cycles_tables_agree`): see the figures
//! in that test's documentation.

#[path = "tables_data.rs"]
mod data;

pub use data::{GGX_E, GGX_E_AVG, GGX_IOR_S, GGX_SCHLICK5_S};

/// Points along the roughness and μ axes of [`GGX_E`] and [`GGX_E_AVG`].
pub const E_SIZE: usize = 32;
/// Points along each axis of [`GGX_IOR_S`] and of the slices of
/// [`GGX_SCHLICK5_S`].
pub const S_SIZE: usize = 16;

/// Linear interpolation in a table of `size` samples of x = i/(size − 1),
/// x held in [0, 1] (Cycles' `lookup_table_read`).
#[inline]
fn read_1d(table: &[f32], x: f32, size: usize) -> f32 {
    let x = x.clamp(0.0, 1.0) * (size - 1) as f32;
    let i = (x as usize).min(size - 1);
    let j = (i + 1).min(size - 1);
    let t = x - i as f32;
    if t == 0.0 {
        return table[i];
    }
    (1.0 - t) * table[i] + t * table[j]
}

/// Bilinear: x along rows of `xsize`, y across them.
#[inline]
fn read_2d(table: &[f32], x: f32, y: f32, xsize: usize, ysize: usize) -> f32 {
    let y = y.clamp(0.0, 1.0) * (ysize - 1) as f32;
    let i = (y as usize).min(ysize - 1);
    let j = (i + 1).min(ysize - 1);
    let t = y - i as f32;
    let a = read_1d(&table[xsize * i..xsize * (i + 1)], x, xsize);
    if t == 0.0 {
        return a;
    }
    let b = read_1d(&table[xsize * j..xsize * (j + 1)], x, xsize);
    (1.0 - t) * a + t * b
}

/// Trilinear: slices of `n` × `n` along z.
#[inline]
fn read_3d(table: &[f32], x: f32, y: f32, z: f32, n: usize) -> f32 {
    let z = z.clamp(0.0, 1.0) * (n - 1) as f32;
    let i = (z as usize).min(n - 1);
    let j = (i + 1).min(n - 1);
    let t = z - i as f32;
    let slice = n * n;
    let a = read_2d(&table[slice * i..slice * (i + 1)], x, y, n, n);
    if t == 0.0 {
        return a;
    }
    let b = read_2d(&table[slice * j..slice * (j + 1)], x, y, n, n);
    (1.0 - t) * a + t * b
}

/// Directional albedo of a GGX lobe without Fresnel, at roughness `rough`
/// (√α) seen at μ = cos θo.
#[inline]
pub fn ggx_e(rough: f32, mu: f32) -> f32 {
    read_2d(&GGX_E, rough, mu, E_SIZE, E_SIZE)
}

/// Its average over the hemisphere, ∫₀¹ 2μ E dμ.
#[inline]
pub fn ggx_e_avg(rough: f32) -> f32 {
    read_1d(&GGX_E_AVG, rough, E_SIZE)
}

/// The dielectric layer's interpolation factor between F0 and 1 (Cycles'
/// `ggx_gen_schlick_ior_s`) for relative index `eta`.
#[inline]
pub fn ggx_ior_s(rough: f32, mu: f32, eta: f32) -> f32 {
    let z = ((eta - 1.0) / (eta + 1.0)).abs().sqrt();
    read_3d(&GGX_IOR_S, rough, mu, z, S_SIZE)
}

/// Schlick's interpolation factor between F0 and 1 at exponent 5, as
/// Cycles reads `ggx_gen_schlick_s` for its metallic lobe (z = 0.5, half
/// way between the slices of exponents 40/7 and 35/8).
#[inline]
pub fn ggx_schlick5_s(rough: f32, mu: f32) -> f32 {
    let n2 = S_SIZE * S_SIZE;
    let a = read_2d(&GGX_SCHLICK5_S[..n2], rough, mu, S_SIZE, S_SIZE);
    let b = read_2d(&GGX_SCHLICK5_S[n2..], rough, mu, S_SIZE, S_SIZE);
    0.5 * (a + b)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reads land on table entries at grid points and interpolate
    /// linearly between them (an off-by-one in the index or a swapped
    /// axis fails here).
    #[test]
    fn reads_hit_grid_points_and_interpolate() {
        let (x, y) = (5usize, 9usize);
        let r = x as f32 / 31.0;
        let mu = y as f32 / 31.0;
        assert!((ggx_e(r, mu) - GGX_E[y * 32 + x]).abs() < 1e-6);
        let mid = ggx_e((x as f32 + 0.5) / 31.0, mu);
        let want = 0.5 * (GGX_E[y * 32 + x] + GGX_E[y * 32 + x + 1]);
        assert!((mid - want).abs() < 1e-6);
        assert!((ggx_e_avg(1.0) - GGX_E_AVG[31]).abs() < 1e-7);
        // z for IOR η with z = 6/15: F0 = z⁴.
        let z = 6.0f32 / 15.0;
        let s = z.powi(2);
        let eta = (1.0 + s) / (1.0 - s);
        let got = ggx_ior_s(3.0 / 15.0, 11.0 / 15.0, eta);
        assert!((got - GGX_IOR_S[6 * 256 + 11 * 16 + 3]).abs() < 1e-5);
    }

    #[test]
    fn tables_hold_fractions() {
        for t in [
            &GGX_E[..],
            &GGX_E_AVG[..],
            &GGX_IOR_S[..],
            &GGX_SCHLICK5_S[..],
        ] {
            assert!(t.iter().all(|v| (0.0..=1.0).contains(v)));
        }
    }
}
