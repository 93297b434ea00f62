//! Error metrics between a rendered image and a reference, and a signed
//! difference image.
//!
//! All metrics are over all `N` pixels and the three channels R, G, B
//! (`3N` values), accumulated in `f64`, with `a` the candidate and `b` the
//! reference (ground truth):
//!
//! ```text
//! mean_a     = mean(a)              mean_b = mean(b)
//! mean_ratio = mean_a / mean_b
//! MSE        = mean((a - b)^2)
//! RMSE       = sqrt(MSE)
//! relMSE     = mean((a - b)^2 / (b^2 + 0.01))
//! PSNR       = 10 log10(peak^2 / MSE)    peak = max over pixels and R,G,B of b
//! ```
//!
//! These match the reference harness (`/work/shared/data/reference/README.md`).

use std::path::Path;

use super::png_io::write_png_rgb8;
use super::{ImageError, ImageRgb};

/// Result of [`compare`]. See the module docs for the definitions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Metrics {
    /// Mean of the candidate over pixels and R, G, B.
    pub mean_a: f64,
    /// Mean of the reference over pixels and R, G, B.
    pub mean_b: f64,
    /// `mean_a / mean_b` (inf or NaN if `mean_b` is 0).
    pub mean_ratio: f64,
    /// Mean squared error.
    pub mse: f64,
    /// Root mean squared error.
    pub rmse: f64,
    /// Relative MSE, `mean((a-b)^2 / (b^2 + 0.01))`.
    pub rel_mse: f64,
    /// `10 log10(peak^2 / MSE)` in dB, `peak` = max of the reference;
    /// `+inf` for identical images.
    pub psnr: f64,
    /// The peak used for PSNR: the largest R, G or B value of the reference.
    pub peak: f64,
}

fn check_sizes(a: &ImageRgb, b: &ImageRgb) -> Result<(), ImageError> {
    if a.width != b.width || a.height != b.height {
        return Err(ImageError::SizeMismatch {
            a_width: a.width,
            a_height: a.height,
            b_width: b.width,
            b_height: b.height,
        });
    }
    let n = a.width * a.height;
    if n == 0 {
        return Err(ImageError::InvalidArgument(
            "cannot compare empty images".into(),
        ));
    }
    if a.pixels.len() != n || b.pixels.len() != n {
        return Err(ImageError::InvalidArgument(format!(
            "image pixel counts ({} and {}) do not match {}x{}",
            a.pixels.len(),
            b.pixels.len(),
            a.width,
            a.height
        )));
    }
    Ok(())
}

/// Compare candidate `a` with reference `b_reference` (see module docs).
/// Different sizes, or empty images, are an error.
pub fn compare(a: &ImageRgb, b_reference: &ImageRgb) -> Result<Metrics, ImageError> {
    let b = b_reference;
    check_sizes(a, b)?;
    let (mut sum_a, mut sum_b, mut sum_sq, mut sum_rel) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut peak = f64::NEG_INFINITY;
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let (va, vb) = (pa[c] as f64, pb[c] as f64);
            let d2 = (va - vb) * (va - vb);
            sum_a += va;
            sum_b += vb;
            sum_sq += d2;
            sum_rel += d2 / (vb * vb + 0.01);
            peak = peak.max(vb);
        }
    }
    let count = (3 * a.pixels.len()) as f64;
    let (mean_a, mean_b) = (sum_a / count, sum_b / count);
    let mse = sum_sq / count;
    Ok(Metrics {
        mean_a,
        mean_b,
        mean_ratio: mean_a / mean_b,
        mse,
        rmse: mse.sqrt(),
        rel_mse: sum_rel / count,
        psnr: 10.0 * (peak * peak / mse).log10(),
        peak,
    })
}

/// Write a false-colour PNG of the signed difference `a - b` and return the
/// scale used.
///
/// Per pixel, `d` = mean over R, G, B of `a - b`. The scale `s` is the 99th
/// percentile of `|d|` over the finite values (the maximum if that is 0, and
/// 1 if all differences are 0). `t = clamp(d / s, -1, 1)`: positive
/// (`a > b`) is red `(255 t, 0, 0)`, negative is blue `(0, 0, -255 t)`,
/// equal is black; a non-finite `d` (NaN or inf in either image) is green.
/// Written atomically; different sizes are an error.
pub fn write_diff_png(
    path: impl AsRef<Path>,
    a: &ImageRgb,
    b: &ImageRgb,
) -> Result<f32, ImageError> {
    let (rgb, scale) = diff_rgb8(a, b)?;
    write_png_rgb8(path.as_ref(), a.width, a.height, &rgb)?;
    Ok(scale)
}

/// The false-colour pixels of [`write_diff_png`] (three bytes a pixel) and
/// the scale used.
pub fn diff_rgb8(a: &ImageRgb, b: &ImageRgb) -> Result<(Vec<u8>, f32), ImageError> {
    check_sizes(a, b)?;
    let diffs: Vec<f32> = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(pa, pb)| ((*pa - *pb).element_sum()) / 3.0)
        .collect();
    let mut abs: Vec<f32> = diffs
        .iter()
        .filter(|d| d.is_finite())
        .map(|d| d.abs())
        .collect();
    let mut scale = 0.0f32;
    if !abs.is_empty() {
        let k = ((abs.len() as f64 * 0.99).ceil() as usize).clamp(1, abs.len()) - 1;
        let (_, p99, _) = abs.select_nth_unstable_by(k, f32::total_cmp);
        scale = *p99;
        if scale <= 0.0 {
            scale = abs.iter().copied().fold(0.0, f32::max);
        }
    }
    if scale <= 0.0 {
        scale = 1.0;
    }
    let mut rgb = Vec::with_capacity(diffs.len() * 3);
    for d in diffs {
        let px = if !d.is_finite() {
            [0, 255, 0]
        } else {
            let t = (d / scale).clamp(-1.0, 1.0);
            let v = (t.abs() * 255.0).round() as u8;
            if t >= 0.0 {
                [v, 0, 0]
            } else {
                [0, 0, v]
            }
        };
        rgb.extend_from_slice(&px);
    }
    Ok((rgb, scale))
}
