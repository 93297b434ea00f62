//! 8-bit sRGB PNG previews.

use std::io::Write;
use std::path::Path;

pub use super::view::View;

use super::atomic::write_atomically;
use super::{Image, ImageError};

/// The sRGB opto-electronic transfer function (IEC 61966-2-1), linear
/// `[0, 1]` to encoded `[0, 1]`: `12.92 v` up to `0.0031308`, then
/// `1.055 v^(1/2.4) - 0.055`. Not a plain 2.2 gamma.
pub fn srgb_encode(linear: f32) -> f32 {
    if linear <= 0.003_130_8 {
        12.92 * linear
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    }
}

/// Linear value to an 8-bit sRGB code: clamped to `[0, 1]` first (NaN and
/// negative values give 0, `+inf` gives 255), then [`srgb_encode`], then
/// rounded to nearest.
pub fn srgb_to_u8(linear: f32) -> u8 {
    let v = if linear > 0.0 { linear.min(1.0) } else { 0.0 };
    (srgb_encode(v) * 255.0).round() as u8
}

/// Write an opaque 8-bit RGB PNG of `path` to `write` (shared by previews and
/// difference images). `rgb` holds 3 bytes per pixel, rows top first.
pub(crate) fn write_png_rgb8(
    path: &Path,
    width: usize,
    height: usize,
    rgb: &[u8],
) -> Result<(), ImageError> {
    let encode_err = |reason: String| ImageError::Encode {
        path: path.to_path_buf(),
        reason,
    };
    if width == 0 || height == 0 {
        return Err(encode_err(format!("the image is empty ({width}x{height})")));
    }
    let (Ok(w), Ok(h)) = (u32::try_from(width), u32::try_from(height)) else {
        return Err(encode_err("the image is too large for PNG".into()));
    };
    debug_assert_eq!(rgb.len(), width * height * 3);
    let png_err = |e: png::EncodingError| match e {
        png::EncodingError::IoError(source) => ImageError::Write {
            path: path.to_path_buf(),
            source,
        },
        other => encode_err(super::one_line(&other.to_string())),
    };
    write_atomically(path, |file| {
        let mut encoder = png::Encoder::new(&mut *file, w, h);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut writer = encoder.write_header().map_err(png_err)?;
        writer.write_image_data(rgb).map_err(png_err)?;
        writer.finish().map_err(png_err)?;
        file.flush().map_err(|source| ImageError::Write {
            path: path.to_path_buf(),
            source,
        })
    })
}

/// Write an 8-bit sRGB preview PNG of the main layer of `image`.
///
/// Each linear RGB value is multiplied by `2^exposure_stops`, then shown
/// through `view` ([`View::display`]: Blender's Standard, AgX or Filmic for
/// the sRGB display); the PNG is tagged sRGB. Alpha is ignored: the PNG is
/// opaque RGB, showing RGB as it is (the renderer's RGB already contains the
/// background seen through the volume, so no compositing is done). AOV layers
/// are not shown.
///
/// Written atomically like [`super::write_exr`]; a missing parent directory
/// is an error naming `path`.
pub fn write_png_preview(
    path: impl AsRef<Path>,
    image: &Image,
    exposure_stops: f32,
    view: View,
) -> Result<(), ImageError> {
    let path = path.as_ref();
    let rgb = preview_rgb8(
        image.pixels().iter().map(|p| p.truncate()),
        exposure_stops,
        view,
    );
    write_png_rgb8(path, image.width(), image.height(), &rgb)
}

/// 8-bit sRGB display values of linear pixels under `view`, three bytes a
/// pixel.
pub fn preview_rgb8(
    pixels: impl Iterator<Item = crate::Rgb>,
    exposure_stops: f32,
    view: View,
) -> Vec<u8> {
    let scale = exposure_stops.exp2();
    let mut rgb = Vec::new();
    for p in pixels {
        rgb.extend(view.display(p * scale));
    }
    rgb
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn oetf_known_values() {
        assert_eq!(srgb_to_u8(0.0), 0);
        assert_eq!(srgb_to_u8(-1.0), 0);
        assert_eq!(srgb_to_u8(f32::NAN), 0);
        assert_eq!(srgb_to_u8(f32::INFINITY), 255);
        assert_eq!(srgb_to_u8(0.5), 188);
        assert_eq!(srgb_to_u8(1.0), 255);
        assert_eq!(srgb_to_u8(7.0), 255);
        // Both branches meet at the boundary: 12.92 * 0.0031308 = 0.04045.
        let lo = srgb_encode(0.003_130_8);
        let hi = 1.055 * 0.003_130_8f32.powf(1.0 / 2.4) - 0.055;
        assert!((lo - 0.040_45).abs() < 1e-6 && (hi - lo).abs() < 1e-5);
        assert_eq!(srgb_to_u8(0.003_130_8), 10);
        // Gamma 2.2 would give 186 for 0.5; the sRGB curve gives 188.
        assert_eq!((0.5f32.powf(1.0 / 2.2) * 255.0).round() as u8, 186);
    }
}
