//! Denoising a finished image with Intel Open Image Denoise (`oidn`), as
//! Blender does for a final render.
//!
//! The filter is OIDN's `RT` for HDR images, guided by the render's
//! denoising albedo: for volumes, the scattering colour seen along the
//! camera ray, ∫ T(s)·σs(s) ds, plus what the ray sees of the environment
//! behind (at most 1), as Cycles writes into its Denoising Albedo pass for
//! volumes (`film_write_denoising_features_volume`: the interaction
//! probability of each segment times σs/σt). No normal guide: volumes have
//! none. The guide is averaged over all of a pixel's samples, so it is
//! nearly noise-free and goes in as clean (`cleanAux`).
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
    let albedo: Option<Vec<[f32; 3]>> = image.layer(ALBEDO_LAYER).and_then(|l| {
        // Channels by name: a file read back lists them in its own order.
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
    });
    let out = oidn.denoise(&color, albedo.as_deref(), true, w, h, quality)?;
    if let Some(i) = out.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(format!(
            "Open Image Denoise returned a non-finite pixel ({}, {})",
            i % w,
            i / w
        ));
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
pub fn describe(oidn: &Oidn, quality: Quality, albedo: bool) -> String {
    format!(
        "Intel Open Image Denoise {} (RT filter, HDR, quality {}, {})",
        oidn.version,
        match quality {
            Quality::High => "high",
            Quality::Balanced => "balanced",
            Quality::Fast => "fast",
        },
        if albedo { "albedo guide" } else { "no guide" }
    )
}
