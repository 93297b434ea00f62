//! In-memory images and their file formats.
//!
//! * [`Image`]: the renderer's output, RGBA `f32` pixels plus optional named
//!   AOV layers ([`AovLayer`], any number of named `f32` channels each).
//! * [`ImageRgb`]: a plain RGB `f32` image, as read back by [`read_exr_rgb`]
//!   (reference images, environment maps) and compared by [`compare`].
//! * [`write_exr`] / [`write_png_preview`] / [`write_diff_png`] write files
//!   atomically: a temporary file in the target's directory, then `rename`.
//!   A failed write never leaves a partial file at the target path, nor a
//!   temporary file behind.
//! * [`ImageError`]: one-line messages naming the file and what is wrong.
//!
//! Pixels are stored row-major, top row first: pixel `(x, y)` is at index
//! `y * width + x`.

mod atomic;
mod exr_io;
mod metrics;
mod png_io;
mod sidebyside;
pub mod texture;
mod view;

use std::path::PathBuf;

use glam::Vec4;

use crate::Rgb;

pub use exr_io::{read_exr, read_exr_attributes, read_exr_rgb, write_exr};
pub use metrics::{compare, diff_rgb8, write_diff_png, Metrics};
pub use png_io::{preview_rgb8, srgb_encode, srgb_to_u8, write_png_preview};
pub use sidebyside::write_side_by_side;
pub use view::View;

/// Everything that can go wrong reading, writing or comparing images.
///
/// Every message is one line; file errors name the file and say what is wrong.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The operating system refused to create, write or rename the output.
    #[error("cannot write '{}': {source}", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The output could not be encoded (bad attribute, empty image, ...).
    #[error("cannot write '{}': {reason}", path.display())]
    Encode { path: PathBuf, reason: String },
    /// The operating system refused to open or read the input.
    #[error("cannot read '{}': {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The input does not start with the OpenEXR magic number.
    #[error("'{}' is not an OpenEXR file", path.display())]
    NotExr { path: PathBuf },
    /// The input is an OpenEXR file but damaged or cut short.
    #[error("'{}' is a damaged or truncated OpenEXR file ({reason})", path.display())]
    CorruptExr { path: PathBuf, reason: String },
    /// The input uses an OpenEXR feature this reader does not handle.
    #[error("'{}' uses an unsupported OpenEXR feature ({reason})", path.display())]
    UnsupportedExr { path: PathBuf, reason: String },
    /// No layer of the input has R, G and B channels.
    #[error("'{}' has no RGB channels (channels: {channels})", path.display())]
    NoRgbChannels { path: PathBuf, channels: String },
    /// Two images that must have the same size do not.
    #[error("image sizes differ: {a_width}x{a_height} vs reference {b_width}x{b_height}")]
    SizeMismatch {
        a_width: usize,
        a_height: usize,
        b_width: usize,
        b_height: usize,
    },
    /// An argument is unusable (empty image, bad layer or channel name, ...).
    #[error("{0}")]
    InvalidArgument(String),
}

impl From<ImageError> for crate::error::Error {
    fn from(e: ImageError) -> Self {
        crate::error::Error::Image(e.to_string())
    }
}

/// Make an arbitrary message fit on one line.
pub(crate) fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// A named AOV layer: `channels.len()` `f32` values per pixel, interleaved
/// (pixel-major: value `c` of pixel `i` is at `i * channels.len() + c`).
///
/// In an EXR file the channels are written as `<layer>.<channel>`, e.g.
/// `direct.R`, `direct.G`, `direct.B`, `transmittance.Y`.
#[derive(Debug, Clone, PartialEq)]
pub struct AovLayer {
    name: String,
    channels: Vec<String>,
    width: usize,
    height: usize,
    data: Vec<f32>,
}

impl AovLayer {
    /// Layer name (e.g. `"direct"`).
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Channel names (e.g. `["R", "G", "B"]`).
    pub fn channels(&self) -> &[String] {
        &self.channels
    }
    /// Number of channels per pixel.
    pub fn num_channels(&self) -> usize {
        self.channels.len()
    }
    /// Width in pixels (same as the owning image).
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels (same as the owning image).
    pub fn height(&self) -> usize {
        self.height
    }
    /// All values, interleaved per pixel, rows top first.
    pub fn data(&self) -> &[f32] {
        &self.data
    }
    /// All values, mutable (see [`AovLayer::data`] for the layout).
    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }
    fn offset(&self, x: usize, y: usize) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside {}x{} layer '{}'",
            self.width,
            self.height,
            self.name
        );
        (y * self.width + x) * self.channels.len()
    }
    /// The values of pixel `(x, y)`. Panics outside the image.
    pub fn get(&self, x: usize, y: usize) -> &[f32] {
        let o = self.offset(x, y);
        &self.data[o..o + self.channels.len()]
    }
    /// Set pixel `(x, y)`. Panics outside the image or if `values.len()` is
    /// not the number of channels.
    pub fn set(&mut self, x: usize, y: usize, values: &[f32]) {
        assert_eq!(
            values.len(),
            self.channels.len(),
            "layer '{}' has {} channels",
            self.name,
            self.channels.len()
        );
        let o = self.offset(x, y);
        self.data[o..o + values.len()].copy_from_slice(values);
    }
    /// Value of channel `c` (index into [`AovLayer::channels`]) at `(x, y)`.
    pub fn channel_value(&self, x: usize, y: usize, c: usize) -> f32 {
        self.get(x, y)[c]
    }
    /// Index of the channel named `name`.
    pub fn channel_index(&self, name: &str) -> Option<usize> {
        self.channels.iter().position(|c| c == name)
    }
}

/// The renderer's output: `width x height` RGBA `f32` pixels, row-major, top
/// row first, plus optional named AOV layers of the same size.
///
/// Alpha is `1 - transmittance` as produced by the renderer (not
/// premultiplied into RGB: RGB already contains the background).
///
/// An image may be part of a larger one (a tile of a frame): its pixels
/// are then the data window at [`Image::origin`] inside a display window
/// of [`Image::display_size`], as OpenEXR stores it. By default the image
/// is the whole display window.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    width: usize,
    height: usize,
    pixels: Vec<Vec4>,
    layers: Vec<AovLayer>,
    /// Top-left pixel of this image in the display window.
    origin: (usize, usize),
    /// Size of the whole image this one is part of.
    display: (usize, usize),
}

fn check_name(kind: &str, name: &str) -> Result<(), ImageError> {
    let ok = !name.is_empty()
        && name.len() <= 200
        && name
            .chars()
            .all(|c| c.is_ascii_graphic() && c != '.' && c != '\'');
    if ok {
        Ok(())
    } else {
        Err(ImageError::InvalidArgument(format!(
            "invalid {kind} name {name:?}: use 1 to 200 printable ASCII characters without '.', quotes or spaces"
        )))
    }
}

impl Image {
    /// A `width x height` image of transparent black (all zeros), no layers.
    pub fn new(width: usize, height: usize) -> Self {
        Self::filled(width, height, Vec4::ZERO)
    }

    /// A `width x height` image with every pixel set to `rgba`.
    pub fn filled(width: usize, height: usize, rgba: Vec4) -> Self {
        let n = width.checked_mul(height).expect("image size overflows");
        Self {
            width,
            height,
            pixels: vec![rgba; n],
            layers: Vec::new(),
            origin: (0, 0),
            display: (width, height),
        }
    }

    /// An image from row-major RGBA pixels (top row first).
    /// Fails if `pixels.len() != width * height`.
    pub fn from_pixels(width: usize, height: usize, pixels: Vec<Vec4>) -> Result<Self, ImageError> {
        if width.checked_mul(height) != Some(pixels.len()) {
            return Err(ImageError::InvalidArgument(format!(
                "{} pixels given for a {width}x{height} image",
                pixels.len()
            )));
        }
        Ok(Self {
            width,
            height,
            pixels,
            layers: Vec::new(),
            origin: (0, 0),
            display: (width, height),
        })
    }

    /// An image whose pixel `(x, y)` is `f(x, y)`.
    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> Vec4) -> Self {
        let mut pixels = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                pixels.push(f(x, y));
            }
        }
        Self {
            width,
            height,
            pixels,
            layers: Vec::new(),
            origin: (0, 0),
            display: (width, height),
        }
    }

    /// Places this image at `origin` inside a `display`-sized image (a tile
    /// of a frame). Fails if it does not fit.
    pub fn set_window(
        &mut self,
        origin: (usize, usize),
        display: (usize, usize),
    ) -> Result<(), ImageError> {
        if origin.0 + self.width > display.0 || origin.1 + self.height > display.1 {
            return Err(ImageError::InvalidArgument(format!(
                "a {}x{} image at ({}, {}) does not fit in {}x{}",
                self.width, self.height, origin.0, origin.1, display.0, display.1
            )));
        }
        self.origin = origin;
        self.display = display;
        Ok(())
    }

    /// Top-left pixel of this image in its display window.
    pub fn origin(&self) -> (usize, usize) {
        self.origin
    }

    /// Size of the display window (the whole frame).
    pub fn display_size(&self) -> (usize, usize) {
        self.display
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// All RGBA pixels, row-major, top row first.
    pub fn pixels(&self) -> &[Vec4] {
        &self.pixels
    }
    /// All RGBA pixels, mutable.
    pub fn pixels_mut(&mut self) -> &mut [Vec4] {
        &mut self.pixels
    }

    fn index(&self, x: usize, y: usize) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside {}x{} image",
            self.width,
            self.height
        );
        y * self.width + x
    }
    /// RGBA of pixel `(x, y)`. Panics outside the image.
    pub fn get(&self, x: usize, y: usize) -> Vec4 {
        self.pixels[self.index(x, y)]
    }
    /// Set RGBA of pixel `(x, y)`. Panics outside the image.
    pub fn set(&mut self, x: usize, y: usize, rgba: Vec4) {
        let i = self.index(x, y);
        self.pixels[i] = rgba;
    }

    /// Mean of R, G and B separately over all pixels (accumulated in `f64`).
    /// Zero for an empty image.
    pub fn mean_rgb(&self) -> Rgb {
        mean_of(self.pixels.iter().map(|p| p.truncate()))
    }

    /// Add a zero-filled AOV layer with the given channel names and return it.
    ///
    /// Names are 1 to 200 printable ASCII characters without `.`, quotes or
    /// spaces; layer names must be unique, channel names unique in the layer.
    pub fn add_layer(
        &mut self,
        name: &str,
        channels: &[&str],
    ) -> Result<&mut AovLayer, ImageError> {
        check_name("layer", name)?;
        if self.layers.iter().any(|l| l.name == name) {
            return Err(ImageError::InvalidArgument(format!(
                "layer '{name}' already exists"
            )));
        }
        if channels.is_empty() {
            return Err(ImageError::InvalidArgument(format!(
                "layer '{name}' needs at least one channel"
            )));
        }
        for (i, c) in channels.iter().enumerate() {
            check_name("channel", c)?;
            if channels[..i].contains(c) {
                return Err(ImageError::InvalidArgument(format!(
                    "layer '{name}' has channel '{c}' twice"
                )));
            }
        }
        self.layers.push(AovLayer {
            name: name.to_string(),
            channels: channels.iter().map(|c| c.to_string()).collect(),
            width: self.width,
            height: self.height,
            data: vec![0.0; self.pixels.len() * channels.len()],
        });
        Ok(self.layers.last_mut().expect("just pushed"))
    }

    /// Add a zero-filled RGB AOV layer (channels `R`, `G`, `B`).
    pub fn add_rgb_layer(&mut self, name: &str) -> Result<&mut AovLayer, ImageError> {
        self.add_layer(name, &["R", "G", "B"])
    }

    /// Takes the AOV layer named `name` out of the image.
    pub fn remove_layer(&mut self, name: &str) -> Option<AovLayer> {
        let i = self.layers.iter().position(|l| l.name == name)?;
        Some(self.layers.remove(i))
    }

    /// All AOV layers, in the order they were added.
    pub fn layers(&self) -> &[AovLayer] {
        &self.layers
    }
    /// All AOV layers, mutable.
    pub fn layers_mut(&mut self) -> &mut [AovLayer] {
        &mut self.layers
    }
    /// The AOV layer named `name`.
    pub fn layer(&self, name: &str) -> Option<&AovLayer> {
        self.layers.iter().find(|l| l.name == name)
    }
    /// The AOV layer named `name`, mutable.
    pub fn layer_mut(&mut self, name: &str) -> Option<&mut AovLayer> {
        self.layers.iter_mut().find(|l| l.name == name)
    }

    /// The RGB part of the main layer (alpha and AOVs dropped).
    pub fn to_rgb(&self) -> ImageRgb {
        ImageRgb {
            width: self.width,
            height: self.height,
            pixels: self.pixels.iter().map(|p| p.truncate()).collect(),
        }
    }
}

/// A plain RGB `f32` image, row-major, top row first.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageRgb {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<Rgb>,
}

impl ImageRgb {
    /// A `width x height` image with every pixel `rgb`.
    pub fn filled(width: usize, height: usize, rgb: Rgb) -> Self {
        Self {
            width,
            height,
            pixels: vec![rgb; width * height],
        }
    }
    /// RGB of pixel `(x, y)`. Panics outside the image.
    pub fn get(&self, x: usize, y: usize) -> Rgb {
        assert!(x < self.width && y < self.height, "pixel outside image");
        self.pixels[y * self.width + x]
    }
    /// Set RGB of pixel `(x, y)`. Panics outside the image.
    pub fn set(&mut self, x: usize, y: usize, rgb: Rgb) {
        assert!(x < self.width && y < self.height, "pixel outside image");
        self.pixels[y * self.width + x] = rgb;
    }
    /// Mean of R, G and B separately (accumulated in `f64`).
    pub fn mean_rgb(&self) -> Rgb {
        mean_of(self.pixels.iter().copied())
    }
    /// The "image mean": mean over all pixels and the three channels,
    /// accumulated in `f64`. NaN for an empty image.
    pub fn mean(&self) -> f64 {
        let sum: f64 = self
            .pixels
            .iter()
            .map(|p| p.x as f64 + p.y as f64 + p.z as f64)
            .sum();
        sum / (3 * self.pixels.len()) as f64
    }
}

fn mean_of(pixels: impl Iterator<Item = Rgb>) -> Rgb {
    let mut sum = [0.0f64; 3];
    let mut n = 0usize;
    for p in pixels {
        sum[0] += p.x as f64;
        sum[1] += p.y as f64;
        sum[2] += p.z as f64;
        n += 1;
    }
    if n == 0 {
        return Rgb::ZERO;
    }
    let n = n as f64;
    Rgb::new(
        (sum[0] / n) as f32,
        (sum[1] / n) as f32,
        (sum[2] / n) as f32,
    )
}
