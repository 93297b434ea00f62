//! Denoising a finished image with Intel Open Image Denoise (`oidn`), as
//! Blender does for a final render.
//!
//! The filter is OIDN's `RT` for HDR images, guided by the render's
//! denoising albedo: for volumes, the scattering colour seen along the
//! camera ray, ∫ T(s)·σs(s) ds, plus what the ray sees of the environment
//! behind (at most 1), as Cycles writes into its Denoising Albedo pass for
//! volumes (`film_write_denoising_features_volume`: the interaction
//! probability of each segment times σs/σt). No normal guide: volumes have
//! none (one made of the density's gradient gained nothing measurable and
//! doubled the denoiser's time: docs/performance.md, "Denoising"). The
//! guide is averaged over a pixel's first samples
//! (`crate::integrator::guide`), so it is nearly noise-free and goes in as
//! clean (`cleanAux`).
//!
//! What an image holds after denoising: RGBA is the denoised beauty (alpha
//! kept), as Blender's Combined pass is; the layer `noisy` (Cycles' "Noisy
//! Image") keeps the raw beauty RGBA bit for bit, and `albedo` the guide.
//! Everything that combines renders (`merge`, another seed's render, a
//! comparison of raw noise) reads `noisy` and denoises again afterwards:
//! a denoised image is never an input to anything.

pub mod oidn;

use crate::image::{Image, ImageError};
pub use oidn::{Oidn, Quality, HOW_TO_GET};

/// The layer that keeps the raw beauty of a denoised image.
pub const NOISY_LAYER: &str = "noisy";
/// The layer of the denoising albedo.
pub const ALBEDO_LAYER: &str = "albedo";
/// The layer of the mean of every other sample (`crate::film::Film`), by
/// which [`blend`] measures the denoiser's error.
pub const HALF_LAYER: &str = "half";

/// Bytes per pixel that denoising takes beside the image: OIDN's RT filter
/// at its highest quality (1.15 GB more for a 1920 x 1080 frame, measured
/// with `/usr/bin/time -v`, about 555 bytes a pixel) and the colour, guide
/// and output copies (36).
pub const BYTES_PER_PIXEL: u64 = 600;

/// Denoises `image` in place: its RGB becomes the denoised RGB (alpha is
/// kept), guided by its `albedo` layer when it has one; the raw RGBA moves
/// to a `noisy` layer. Returns an error (and leaves the image as it was)
/// when OIDN fails or gives back a non-finite pixel.
pub fn denoise_image(oidn: &Oidn, image: &mut Image, quality: Quality) -> Result<(), String> {
    if image.layer(NOISY_LAYER).is_some() {
        return Err("the image is denoised already".into());
    }
    let (w, h) = (image.width(), image.height());
    let color: Vec<[f32; 3]> = image
        .pixels()
        .iter()
        .map(|p| p.truncate().to_array())
        .collect();
    let albedo = image.layer(ALBEDO_LAYER).and_then(rgb_of);
    let finite =
        |out: Vec<[f32; 3]>| match out.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            Some(i) => Err(format!(
                "Open Image Denoise returned a non-finite pixel ({}, {})",
                i % w,
                i / w
            )),
            None => Ok(out),
        };
    let mut out = finite(oidn.denoise(&color, albedo.as_deref(), true, w, h, quality)?)?;
    if let Some(half) = image.layer(HALF_LAYER).and_then(rgb_of) {
        let denoised_half = finite(oidn.denoise(&half, albedo.as_deref(), true, w, h, quality)?)?;
        out = blend(&color, &half, &out, &denoised_half, w, h);
    }
    let raw: Vec<f32> = image.pixels().iter().flat_map(|p| p.to_array()).collect();
    let layer = image
        .add_layer(NOISY_LAYER, &["R", "G", "B", "A"])
        .map_err(|e: ImageError| e.to_string())?;
    layer.data_mut().copy_from_slice(&raw);
    for (p, d) in image.pixels_mut().iter_mut().zip(&out) {
        *p = glam::Vec4::new(d[0], d[1], d[2], p.w);
    }
    Ok(())
}

/// The R, G, B channels of an image layer, found by name (a file read back
/// lists them in its own order).
fn rgb_of(l: &crate::image::AovLayer) -> Option<Vec<[f32; 3]>> {
    let k = ["R", "G", "B"].map(|c| l.channel_index(c));
    let [Some(r), Some(g), Some(b)] = k else {
        return None;
    };
    Some(
        l.data()
            .chunks_exact(l.num_channels())
            .map(|c| [c[r], c[g], c[b]])
            .collect(),
    )
}

/// Half the side, less one, of the square of pixels over which
/// [`blend`] averages its error estimates: each pixel's own is a single
/// squared difference (one degree of freedom), so it takes 81 to know it
/// within about 15 %.
const BLEND_RADIUS: usize = 4;

/// The denoised image where it is better than the raw one, the raw one
/// where it is better, and a mix between, pixel by pixel: the denoiser
/// blurs what it takes for noise, and where little noise is left (a photon
/// map's image after many passes is smooth already, its error in blotches
/// the size of its kernels) the detail it blurs away costs more than the
/// noise it removes. On the Blender smoke + fire frame at 30 s the photon
/// integrator's raw image was 4.8e-6 from the truth, its denoised one
/// 6.5e-6 and the blend 4.8e-6 (docs/performance.md, "Denoising").
///
/// The errors come from the render's two halves (every other sample,
/// [`HALF_LAYER`]: A, and the rest, B = 2·raw − A, independent of it;
/// exactly so for an even number of samples, nearly for many), the
/// denoiser run on A as well (D_A), luminance per pixel, averaged over a
/// (2·[`BLEND_RADIUS`] + 1)² square:
/// - the raw image's variance, (A − B)²/4;
/// - the denoiser's error on half the samples, (D_A − B)² − (A − B)²/2 (B
///   is independent of D_A, so the squared difference is D_A's error plus
///   B's variance, which is half (A − B)²), halved for all the samples as
///   the residual noise of a denoiser is; this makes it a little
///   pessimistic where blur is the error, which a denoiser shrinks more
///   slowly.
///
/// Each pixel is raw + w·(denoised − raw), w = e_raw / (e_raw + e_denoised),
/// the weight that minimises the mix's error were the two independent (as
/// the denoiser's blur and the raw noise are, nearly).
pub fn blend(
    raw: &[[f32; 3]],
    half: &[[f32; 3]],
    denoised: &[[f32; 3]],
    denoised_half: &[[f32; 3]],
    w: usize,
    h: usize,
) -> Vec<[f32; 3]> {
    let lum = |p: &[f32; 3]| (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0;
    let n = w * h;
    let mut e_raw = vec![0.0f64; n];
    let mut e_den = vec![0.0f64; n];
    for i in 0..n {
        let a = lum(&half[i]) - lum(&raw[i]); // (A − B)/2
        let db = lum(&denoised_half[i]) - 2.0 * lum(&raw[i]) + lum(&half[i]); // D_A − B
        e_raw[i] = a * a;
        e_den[i] = db * db - 2.0 * a * a;
    }
    let e_den_sq: Vec<f64> = e_den.iter().map(|e| e * e).collect();
    let e_raw = box_mean(&e_raw, w, h, BLEND_RADIUS);
    let e_den_sq = box_mean(&e_den_sq, w, h, BLEND_RADIUS);
    let e_den = box_mean(&e_den, w, h, BLEND_RADIUS);
    let side = |k: usize, len: usize| {
        ((k + BLEND_RADIUS + 1).min(len) - k.saturating_sub(BLEND_RADIUS)) as f64
    };
    (0..n)
        .map(|i| {
            // The denoiser's error less one standard error of the
            // square's mean. Under heavy noise the estimate is the
            // difference of two large squares, and its chance excursions
            // (clipped at zero, so biased upwards) would pull the image
            // back to the noise; less of it keeps more of the denoiser's
            // gain where it helps, more keeps more of the raw image where
            // it does not (docs/performance.md, "Denoising": 0, 1 and 2
            // standard errors measured).
            let count = side(i % w, w) * side(i / w, h);
            let se = ((e_den_sq[i] - e_den[i] * e_den[i]).max(0.0) / count).sqrt();
            let (r, d) = (e_raw[i].max(0.0), 0.5 * (e_den[i] - se).max(0.0));
            let k = if r + d > 0.0 {
                (r / (r + d)) as f32
            } else {
                0.0
            };
            std::array::from_fn(|c| raw[i][c] + k * (denoised[i][c] - raw[i][c]))
        })
        .collect()
}

/// The mean of `v` (a `w` x `h` image) over the square of side 2r + 1
/// around each pixel, cut at the image's edges: two passes of running sums.
fn box_mean(v: &[f64], w: usize, h: usize, r: usize) -> Vec<f64> {
    let pass = |src: &[f64], len: usize, stride: usize, lines: usize, step: usize| {
        let mut out = vec![0.0f64; src.len()];
        for line in 0..lines {
            let at = |k: usize| line * step + k * stride;
            let mut prefix = vec![0.0f64; len + 1];
            for k in 0..len {
                prefix[k + 1] = prefix[k] + src[at(k)];
            }
            for k in 0..len {
                let (lo, hi) = (k.saturating_sub(r), (k + r + 1).min(len));
                out[at(k)] = (prefix[hi] - prefix[lo]) / (hi - lo) as f64;
            }
        }
        out
    };
    let rows = pass(v, w, 1, h, w);
    pass(&rows, h, w, w, 1)
}

/// Undoes what [`denoise_image`] did to an image read back: the raw RGBA
/// from its `noisy` layer, that layer removed. An image never denoised is
/// left as it is. Returns whether it was denoised.
pub fn restore_raw(image: &mut Image) -> bool {
    let Some(noisy) = image.remove_layer(NOISY_LAYER) else {
        return false;
    };
    // Channels by name: a file read back lists them in its own order.
    let k = ["R", "G", "B", "A"].map(|c| noisy.channel_index(c));
    let n = noisy.num_channels();
    for (p, c) in image
        .pixels_mut()
        .iter_mut()
        .zip(noisy.data().chunks_exact(n))
    {
        let at = |i: usize, keep: f32| k[i].map_or(keep, |j| c[j]);
        *p = glam::Vec4::new(at(0, p.x), at(1, p.y), at(2, p.z), at(3, p.w));
    }
    true
}

/// The header's description of the denoiser.
pub fn describe(oidn: &Oidn, quality: Quality, albedo: bool, blended: bool) -> String {
    format!(
        "Intel Open Image Denoise {} (RT filter, HDR, quality {}, {}{})",
        oidn.version,
        match quality {
            Quality::High => "high",
            Quality::Balanced => "balanced",
            Quality::Fast => "fast",
        },
        if albedo { "albedo guide" } else { "no guide" },
        if blended {
            "; blended with the raw image by their errors, measured on half the samples"
        } else {
            ""
        }
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const W: usize = 64;
    const H: usize = 48;

    /// A repeatable normal-ish number (the sum of four uniforms, unit
    /// variance) for pixel `i` and stream `k`.
    fn noise(i: usize, k: u64) -> f32 {
        let mut x = (i as u64) << 8 | k;
        (0..4)
            .map(|_| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((x >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 3f32.sqrt()
            })
            .sum::<f32>()
    }

    /// A stand-in denoiser: a 5 x 5 box blur, which removes noise and
    /// blurs detail as a real one does where it takes detail for noise.
    fn blur(img: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let c: Vec<f64> = img.iter().map(|p| p[0] as f64).collect();
        box_mean(&c, W, H, 2)
            .into_iter()
            .map(|v| [v as f32; 3])
            .collect()
    }

    fn mse(a: &[[f32; 3]], truth: &[f32]) -> f64 {
        a.iter()
            .zip(truth)
            .map(|(p, t)| ((p[0] - t) as f64).powi(2))
            .sum::<f64>()
            / a.len() as f64
    }

    /// The two halves of a render of `truth` with per-sample noise `sigma`
    /// (each half's mean carries noise sigma), its mean, and what the
    /// stand-in denoiser makes of the whole and of one half.
    fn render(truth: &[f32], sigma: f32) -> [Vec<[f32; 3]>; 4] {
        let half = |k: u64| -> Vec<[f32; 3]> {
            (0..W * H)
                .map(|i| [truth[i] + sigma * noise(i, k); 3])
                .collect()
        };
        let (a, b) = (half(1), half(2));
        let raw: Vec<[f32; 3]> = a
            .iter()
            .zip(&b)
            .map(|(a, b)| [(a[0] + b[0]) / 2.0; 3])
            .collect();
        let (d, d_a) = (blur(&raw), blur(&a));
        [raw, a, d, d_a]
    }

    /// A render of `truth` with per-sample noise `sigma` ([`render`]): the
    /// raw image, and the errors of the raw, denoised and blended images.
    fn errors(truth: &[f32], sigma: f32) -> (Vec<[f32; 3]>, f64, f64, f64) {
        let [raw, a, d, d_a] = render(truth, sigma);
        let out = blend(&raw, &a, &d, &d_a, W, H);
        let (e_raw, e_d, e_out) = (mse(&raw, truth), mse(&d, truth), mse(&out, truth));
        (raw, e_raw, e_d, e_out)
    }

    /// Where the raw image is nearly clean and the denoiser blurs its
    /// detail away (stripes 2 pixels wide), the blend keeps the raw image;
    /// where the raw image is noisy and the denoiser removes the noise (a
    /// smooth ramp), it keeps the denoised one. A weight the wrong way
    /// round, or no weight at all, fails one or the other.
    #[test]
    fn the_blend_keeps_whichever_image_is_closer() {
        let stripes: Vec<f32> = (0..W * H)
            .map(|i| {
                if ((i % W) / 2).is_multiple_of(2) {
                    1.0
                } else {
                    0.5
                }
            })
            .collect();
        let (_, e_raw, e_d, e_out) = errors(&stripes, 0.01);
        assert!(
            e_d > 100.0 * e_raw,
            "the stand-in must blur: {e_d} against {e_raw}"
        );
        assert!(
            e_out < 1.5 * e_raw,
            "blend {e_out}, raw {e_raw}, denoised {e_d}"
        );

        let ramp: Vec<f32> = (0..W * H)
            .map(|i| 0.5 + (i % W) as f32 / W as f32)
            .collect();
        let (raw, e_raw, e_d, e_out) = errors(&ramp, 0.3);
        assert!(
            e_raw > 5.0 * e_d,
            "the stand-in must denoise: {e_raw} against {e_d}"
        );
        assert!(
            e_out < 1.5 * e_d,
            "blend {e_out}, raw {e_raw}, denoised {e_d}"
        );
        // Nothing to measure (both halves equal, the denoiser idle): the
        // raw image, unchanged.
        assert_eq!(blend(&raw, &raw, &raw, &raw, W, H), raw);
    }
}
