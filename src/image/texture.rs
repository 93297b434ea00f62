//! Image textures for surfaces: PNG (8 or 16 bits, grey or colour, with or
//! without alpha), JPEG (`zune-jpeg`) and EXR, read into linear RGB, and
//! looked up as Blender's Image Texture node does by default: Linear
//! (bilinear) interpolation between texel centres, Repeat extension, `v`
//! up (row 0 of the file is the top of the image, `v = 1`).
//!
//! A colour space of `srgb` decodes the stored values with the sRGB
//! transfer function (IEC 61966-2-1: Blender's "sRGB"); `linear` takes them
//! as they are (Blender's "Linear Rec.709" and "Non-Color"). As Cycles 5
//! does with byte images, an sRGB texture is interpolated in its stored
//! values and decoded after (measured on a test texture: that order matches
//! Cycles' render to 1.2e-4 RMS, decoding each texel first is off by
//! 0.055).

use super::ImageError;
use crate::Rgb;
use glam::Vec2;
use std::path::Path;

/// How stored texel values become linear RGB.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ColorSpace {
    /// The sRGB transfer function (8- and 16-bit images usually are).
    #[default]
    Srgb,
    /// Values as stored (EXR images; data such as roughness).
    Linear,
}

impl ColorSpace {
    /// The spelling used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            ColorSpace::Srgb => "srgb",
            ColorSpace::Linear => "linear",
        }
    }
}

/// Images larger than this many texels are refused (a 16k x 16k texture:
/// 3 GiB as linear RGB).
pub const MAX_TEXELS: usize = 1 << 28;

/// A texture: RGB texels as stored, row-major from the top, and whether
/// a lookup decodes them from sRGB.
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    width: usize,
    height: usize,
    texels: Vec<Rgb>,
    srgb: bool,
}

/// The sRGB transfer function's inverse: stored value to linear.
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

impl Texture {
    /// A texture of `width` x `height` linear texels (row-major from the
    /// top).
    pub fn new(width: usize, height: usize, texels: Vec<Rgb>) -> Result<Self, ImageError> {
        if width == 0 || height == 0 || texels.len() != width * height {
            return Err(ImageError::InvalidArgument(format!(
                "a texture of {width} x {height} texels needs {} of them, got {}",
                width * height,
                texels.len()
            )));
        }
        Ok(Self {
            width,
            height,
            texels,
            srgb: false,
        })
    }

    /// Reads the image at `path` (PNG, JPEG or EXR by its extension) as
    /// linear RGB in `space` (EXR is linear whatever `space` says, as in
    /// Blender, where float images default to linear).
    pub fn read(path: &Path, space: ColorSpace) -> Result<Self, ImageError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .unwrap_or_default();
        // Byte images keep their stored values (decoded after a lookup's
        // interpolation, as Cycles does).
        let decode = |v: f32| v;
        let srgb = space == ColorSpace::Srgb;
        let stored = |t: Result<Self, ImageError>| t.map(|t| Self { srgb, ..t });
        let bad = |m: String| ImageError::InvalidArgument(format!("'{}': {m}", path.display()));
        match ext.as_str() {
            "exr" => {
                let img = super::read_exr_rgb(path)?;
                let (w, h) = (img.width, img.height);
                Self::new(w, h, img.pixels)
            }
            "png" => {
                let file = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
                let mut d = png::Decoder::new(std::io::BufReader::new(file));
                d.set_transformations(png::Transformations::EXPAND);
                let mut r = d.read_info().map_err(|e| bad(format!("not a readable PNG: {e}")))?;
                let (w, h) = (r.info().width as usize, r.info().height as usize);
                if w.saturating_mul(h) > MAX_TEXELS {
                    return Err(bad(format!("{w} x {h} texels is too large a texture")));
                }
                let size = r
                    .output_buffer_size()
                    .ok_or_else(|| bad("its size overflows".into()))?;
                let mut buf = vec![0u8; size];
                let info = r
                    .next_frame(&mut buf)
                    .map_err(|e| bad(format!("not a readable PNG: {e}")))?;
                let channels = info.color_type.samples();
                let wide = info.bit_depth == png::BitDepth::Sixteen;
                let value = |i: usize| -> f32 {
                    if wide {
                        u16::from_be_bytes([buf[2 * i], buf[2 * i + 1]]) as f32 / 65535.0
                    } else {
                        buf[i] as f32 / 255.0
                    }
                };
                let texels = (0..w * h)
                    .map(|k| {
                        let base = k * channels;
                        if channels >= 3 {
                            Rgb::new(
                                decode(value(base)),
                                decode(value(base + 1)),
                                decode(value(base + 2)),
                            )
                        } else {
                            Rgb::splat(decode(value(base)))
                        }
                    })
                    .collect();
                stored(Self::new(w, h, texels))
            }
            "jpg" | "jpeg" => {
                let bytes = std::fs::read(path).map_err(|e| bad(e.to_string()))?;
                let options = zune_jpeg::zune_core::options::DecoderOptions::default()
                    .jpeg_set_out_colorspace(zune_jpeg::zune_core::colorspace::ColorSpace::RGB);
                let mut d = zune_jpeg::JpegDecoder::new_with_options(
                    zune_jpeg::zune_core::bytestream::ZCursor::new(&bytes),
                    options,
                );
                let rgb = d
                    .decode()
                    .map_err(|e| bad(format!("not a readable JPEG: {e:?}")))?;
                let info = d.info().ok_or_else(|| bad("no JPEG header".into()))?;
                let (w, h) = (info.width as usize, info.height as usize);
                if rgb.len() < w * h * 3 {
                    return Err(bad("the JPEG decoded to fewer texels than its size".into()));
                }
                let texels = rgb
                    .chunks_exact(3)
                    .take(w * h)
                    .map(|c| {
                        Rgb::new(
                            decode(c[0] as f32 / 255.0),
                            decode(c[1] as f32 / 255.0),
                            decode(c[2] as f32 / 255.0),
                        )
                    })
                    .collect();
                stored(Self::new(w, h, texels))
            }
            _ => Err(bad(
                "not an image vdbphoton reads as a texture: the name must end in .png, .jpg, .jpeg or .exr".into(),
            )),
        }
    }

    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }

    /// Bytes the texture takes.
    pub fn memory_bytes(&self) -> usize {
        self.texels.capacity() * std::mem::size_of::<Rgb>()
    }

    #[inline]
    fn texel(&self, x: i64, y: i64) -> Rgb {
        let x = x.rem_euclid(self.width as i64) as usize;
        let y = y.rem_euclid(self.height as i64) as usize;
        self.texels[y * self.width + x]
    }

    /// The colour at texture coordinates `uv` (Blender's: `v` up),
    /// bilinear between texel centres, repeated beyond [0, 1].
    #[inline]
    pub fn lookup(&self, uv: Vec2) -> Rgb {
        if !uv.is_finite() {
            return Rgb::ZERO;
        }
        let x = uv.x * self.width as f32 - 0.5;
        let y = (1.0 - uv.y) * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let a = self.texel(x0, y0) * (1.0 - fx) + self.texel(x0 + 1, y0) * fx;
        let b = self.texel(x0, y0 + 1) * (1.0 - fx) + self.texel(x0 + 1, y0 + 1) * fx;
        let c = a * (1.0 - fy) + b * fy;
        if self.srgb {
            c.map(srgb_to_linear)
        } else {
            c
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Texel centres give their texels; between them the mix is bilinear;
    /// `v` runs up and the image repeats.
    #[test]
    fn lookups_are_bilinear_between_centres_and_repeat() {
        let t = Texture::new(
            2,
            2,
            vec![
                Rgb::new(1.0, 0.0, 0.0),
                Rgb::new(0.0, 1.0, 0.0),
                Rgb::new(0.0, 0.0, 1.0),
                Rgb::new(1.0, 1.0, 1.0),
            ],
        )
        .unwrap();
        // Top-left texel: u 0.25, v 0.75.
        assert_eq!(t.lookup(Vec2::new(0.25, 0.75)), Rgb::new(1.0, 0.0, 0.0));
        assert_eq!(t.lookup(Vec2::new(0.25, 0.25)), Rgb::new(0.0, 0.0, 1.0));
        assert_eq!(t.lookup(Vec2::new(1.25, -0.75)), Rgb::new(0.0, 0.0, 1.0));
        let mid = t.lookup(Vec2::new(0.5, 0.75));
        assert!((mid - Rgb::new(0.5, 0.5, 0.0)).length() < 1e-6);
        // Across the edge it wraps: halfway between the right and left
        // columns.
        let edge = t.lookup(Vec2::new(0.0, 0.75));
        assert!((edge - Rgb::new(0.5, 0.5, 0.0)).length() < 1e-6);
    }

    #[test]
    fn srgb_decodes_as_the_standard_says() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(0.5) - 0.214_041_14).abs() < 1e-6);
        assert!((srgb_to_linear(0.04) - 0.04 / 12.92).abs() < 1e-9);
    }
}
