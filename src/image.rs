//! Image output and input: OpenEXR (float RGBA plus AOV channels, header
//! attributes) through the `exr` crate, an 8-bit sRGB PNG preview, and the
//! error metrics used against reference renders.
//!
//! Every file is written to a temporary name in its directory and renamed
//! when complete, so a failure never leaves a partial file behind.

use crate::Rgb;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("cannot write '{}': {message}", path.display())]
    Write { path: PathBuf, message: String },
    #[error("cannot read '{}': {message}", path.display())]
    Read { path: PathBuf, message: String },
    #[error("{0}")]
    Mismatch(String),
}

/// A float RGB image, row-major from the top row.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageRgb {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<Rgb>,
}

impl ImageRgb {
    pub fn mean(&self) -> f64 {
        let s: f64 = self.pixels.iter().map(|p| (p.x + p.y + p.z) as f64).sum();
        s / (3 * self.pixels.len().max(1)) as f64
    }
}

/// An extra layer of an EXR: a name and 1 or 3 channels per pixel.
pub struct Aov<'a> {
    pub name: &'a str,
    pub rgb: Option<&'a [Rgb]>,
    pub gray: Option<&'a [f32]>,
}

fn temp_path(path: &Path) -> PathBuf {
    crate::vdb::temp_path_for(path)
}

fn check_dir(path: &Path) -> Result<(), ImageError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        if !dir.is_dir() {
            return Err(ImageError::Write {
                path: path.to_path_buf(),
                message: "its directory does not exist".into(),
            });
        }
    }
    Ok(())
}

/// Writes to a temporary file with `write`, then renames it to `path`.
fn atomic_write(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), String>,
) -> Result<(), ImageError> {
    check_dir(path)?;
    let tmp = temp_path(path);
    let result = write(&tmp).and_then(|_| std::fs::rename(&tmp, path).map_err(|e| e.to_string()));
    if let Err(message) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(ImageError::Write {
            path: path.to_path_buf(),
            message,
        });
    }
    Ok(())
}

/// Writes an RGBA float32 EXR (ZIP compression) with the AOVs as extra
/// channels named `LAYER.R`, `LAYER.G`, `LAYER.B` (or `LAYER.Y`), and the
/// attributes as string attributes of the header.
pub fn write_exr(
    path: &Path,
    width: usize,
    height: usize,
    rgb: &[Rgb],
    alpha: &[f32],
    aovs: &[Aov],
    attributes: &[(String, String)],
) -> Result<(), ImageError> {
    use exr::prelude::*;
    let mut channels: Vec<AnyChannel<FlatSamples>> = Vec::new();
    let mut add = |name: String, data: Vec<f32>| {
        channels.push(AnyChannel::new(
            Text::from(name.as_str()),
            FlatSamples::F32(data),
        ));
    };
    add("R".into(), rgb.iter().map(|p| p.x).collect());
    add("G".into(), rgb.iter().map(|p| p.y).collect());
    add("B".into(), rgb.iter().map(|p| p.z).collect());
    add("A".into(), alpha.to_vec());
    for a in aovs {
        if let Some(v) = a.rgb {
            add(format!("{}.R", a.name), v.iter().map(|p| p.x).collect());
            add(format!("{}.G", a.name), v.iter().map(|p| p.y).collect());
            add(format!("{}.B", a.name), v.iter().map(|p| p.z).collect());
        }
        if let Some(v) = a.gray {
            add(format!("{}.Y", a.name), v.to_vec());
        }
    }
    let mut layer_attrs = LayerAttributes::default();
    for (k, v) in attributes {
        layer_attrs.other.insert(
            Text::from(k.as_str()),
            AttributeValue::Text(Text::from(v.as_str())),
        );
    }
    let layer = Layer::new(
        (width, height),
        layer_attrs,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    let image = Image::from_layer(layer);
    atomic_write(path, |tmp| {
        image.write().to_file(tmp).map_err(|e| e.to_string())
    })
}

/// Reads the RGB channels of the first layer of an EXR (any compression,
/// f16 or f32), e.g. a reference render or an environment map.
pub fn read_exr_rgb(path: &Path) -> Result<ImageRgb, ImageError> {
    use exr::prelude::*;
    let err = |m: String| ImageError::Read {
        path: path.to_path_buf(),
        message: m,
    };
    let meta = std::fs::metadata(path).map_err(|e| err(e.to_string()))?;
    if meta.is_dir() {
        return Err(err("it is a directory".into()));
    }
    let image = read_first_rgba_layer_from_file(
        path,
        |res, _| ImageRgb {
            width: res.width(),
            height: res.height(),
            pixels: vec![Rgb::ZERO; res.width() * res.height()],
        },
        |img: &mut ImageRgb, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width;
            img.pixels[pos.y() * w + pos.x()] = Rgb::new(r, g, b);
        },
    )
    .map_err(|e| err(format!("not a readable OpenEXR RGB image ({e})")))?;
    Ok(image.layer_data.channel_data.pixels)
}

/// sRGB opto-electronic transfer function (IEC 61966-2-1).
pub fn srgb_encode(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x.max(0.0)
    } else {
        1.055 * x.min(1.0).powf(1.0 / 2.4) - 0.055
    }
}

/// Writes an 8-bit sRGB PNG preview, scaled by 2^`exposure` and clipped.
pub fn write_png(
    path: &Path,
    width: usize,
    height: usize,
    rgb: &[Rgb],
    exposure: f32,
) -> Result<(), ImageError> {
    let scale = 2f32.powf(exposure);
    let data: Vec<u8> = rgb
        .iter()
        .flat_map(|p| (*p * scale).to_array())
        .map(|v| (srgb_encode(v) * 255.0 + 0.5).clamp(0.0, 255.0) as u8)
        .collect();
    atomic_write(path, |tmp| {
        let file = std::fs::File::create(tmp).map_err(|e| e.to_string())?;
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), width as u32, height as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(|e| e.to_string())?;
        w.write_image_data(&data).map_err(|e| e.to_string())?;
        w.finish().map_err(|e| e.to_string())
    })
}

/// Error of an image against a reference, over all pixels and R, G, B.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Metrics {
    pub mean: f64,
    pub mean_reference: f64,
    /// mean / mean_reference.
    pub mean_ratio: f64,
    /// sqrt(mean (a − b)²).
    pub rmse: f64,
    /// mean((a − b)² / (b² + 0.01)), as `shared/data/reference` defines it.
    pub rel_mse: f64,
    /// 10 log10(peak² / MSE), peak = the reference's maximum.
    pub psnr: f64,
}

/// Compares `a` with the reference `b`.
pub fn compare(a: &ImageRgb, b: &ImageRgb) -> Result<Metrics, ImageError> {
    if a.width != b.width || a.height != b.height {
        return Err(ImageError::Mismatch(format!(
            "the images differ in size: {}x{} and {}x{}",
            a.width, a.height, b.width, b.height
        )));
    }
    let (mut se, mut rel, mut peak) = (0.0f64, 0.0f64, 0.0f64);
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let (x, y) = (p[c] as f64, q[c] as f64);
            se += (x - y) * (x - y);
            rel += (x - y) * (x - y) / (y * y + 0.01);
            peak = peak.max(y);
        }
    }
    let n = (3 * a.pixels.len().max(1)) as f64;
    let mse = se / n;
    let (ma, mb) = (a.mean(), b.mean());
    Ok(Metrics {
        mean: ma,
        mean_reference: mb,
        mean_ratio: ma / mb,
        rmse: mse.sqrt(),
        rel_mse: rel / n,
        psnr: 10.0 * (peak * peak / mse).log10(),
    })
}
