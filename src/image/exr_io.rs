//! OpenEXR output of [`Image`] and RGB input of any EXR as [`ImageRgb`].
//!
//! # File layout written by [`write_exr`]
//! One single-part scan-line file, ZIP compression (lossless, 16 lines per
//! block), all channels `float32`:
//! * main layer: channels `R`, `G`, `B`, `A` (unprefixed, so every EXR
//!   reader shows it as the image);
//! * each AOV layer `name` with channels `c1..cn`: channels `name.c1` ...
//!   `name.cn` (the standard OpenEXR layer naming, which Blender, Nuke,
//!   OpenImageIO and the OpenEXR tools read as layers / passes);
//! * each `(key, value)` attribute: a header attribute `key` of type
//!   `string`, value stored as UTF-8 bytes.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Compression, Encoding, FlatSamples, LayerAttributes,
    LineOrder, ReadChannels, ReadLayers, SmallVec, Text, WritableImage,
};

use super::atomic::write_atomically;
use super::{one_line, Image, ImageError, ImageRgb};
use crate::Rgb;

/// Header attribute names defined by OpenEXR itself; user attributes may not
/// use them.
const RESERVED_ATTRIBUTES: &[&str] = &[
    "channels",
    "compression",
    "dataWindow",
    "displayWindow",
    "lineOrder",
    "pixelAspectRatio",
    "screenWindowCenter",
    "screenWindowWidth",
    "tiles",
    "name",
    "type",
    "version",
    "chunkCount",
    "maxSamplesPerPixel",
    "view",
    "multiView",
];

/// ZIP, 16 scan lines per block, top to bottom: lossless and what Blender
/// writes by default.
const ENCODING: Encoding = Encoding {
    compression: Compression::ZIP16,
    blocks: exr::image::Blocks::ScanLines,
    line_order: LineOrder::Increasing,
};

fn encode_err(path: &Path, reason: impl Into<String>) -> ImageError {
    ImageError::Encode {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// Write `image` to `path` as a float32 OpenEXR file (layout in the module
/// docs), with `attributes` as string attributes in the header (e.g. `spp`,
/// `seed`, `integrator`, `passes`).
///
/// Attribute keys must be 1 to 255 printable ASCII characters, unique, and
/// not one of OpenEXR's own attribute names (`channels`, `compression`, ...).
///
/// The file is written atomically (temporary file in the same directory, then
/// rename); on error nothing appears at `path` and no temporary is left. A
/// missing parent directory is an error, it is not created.
pub fn write_exr(
    path: impl AsRef<Path>,
    image: &Image,
    attributes: &[(String, String)],
) -> Result<(), ImageError> {
    let path = path.as_ref();
    if image.width() == 0 || image.height() == 0 {
        return Err(encode_err(
            path,
            format!("the image is empty ({}x{})", image.width(), image.height()),
        ));
    }
    if image.width() > i32::MAX as usize / 2 || image.height() > i32::MAX as usize / 2 {
        return Err(encode_err(path, "the image is too large for OpenEXR"));
    }

    let mut layer_attributes = LayerAttributes::default();
    for (i, (key, value)) in attributes.iter().enumerate() {
        let key_ok =
            !key.is_empty() && key.len() <= 255 && key.bytes().all(|b| b.is_ascii_graphic());
        if !key_ok {
            return Err(encode_err(
                path,
                format!("invalid attribute name {key:?} (use 1 to 255 printable ASCII characters)"),
            ));
        }
        if RESERVED_ATTRIBUTES.contains(&key.as_str()) {
            return Err(encode_err(
                path,
                format!("attribute name '{key}' is reserved by OpenEXR"),
            ));
        }
        if attributes[..i].iter().any(|(k, _)| k == key) {
            return Err(encode_err(path, format!("attribute '{key}' given twice")));
        }
        layer_attributes.other.insert(
            Text::from_slice_unchecked(key.as_bytes()),
            AttributeValue::Text(Text::from_slice_unchecked(value.as_bytes())),
        );
    }

    let mut channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (c, name) in ["R", "G", "B", "A"].into_iter().enumerate() {
        let samples: Vec<f32> = image.pixels().iter().map(|p| p[c]).collect();
        channels.push(AnyChannel::new(name, FlatSamples::F32(samples)));
    }
    for layer in image.layers() {
        let n = layer.num_channels();
        for (c, channel) in layer.channels().iter().enumerate() {
            let samples: Vec<f32> = layer.data().iter().skip(c).step_by(n).copied().collect();
            let name = Text::from_slice_unchecked(format!("{}.{channel}", layer.name()).as_bytes());
            channels.push(AnyChannel::new(name, FlatSamples::F32(samples)));
        }
    }

    let (ox, oy) = image.origin();
    let (dw, dh) = image.display_size();
    if dw > i32::MAX as usize / 2 || dh > i32::MAX as usize / 2 {
        return Err(encode_err(path, "the image is too large for OpenEXR"));
    }
    layer_attributes.layer_position = exr::math::Vec2(ox as i32, oy as i32);
    let exr_layer = exr::image::Layer::new(
        (image.width(), image.height()),
        layer_attributes,
        ENCODING,
        AnyChannels::sort(channels),
    );
    let mut exr_image = exr::image::Image::from_layer(exr_layer);
    // The data window is this image; the display window the whole frame.
    exr_image.attributes.display_window =
        exr::meta::attribute::IntegerBounds::new((0, 0), (dw, dh));

    write_atomically(path, |writer| {
        exr_image.write().to_buffered(writer).map_err(|e| match e {
            exr::error::Error::Io(source) => ImageError::Write {
                path: path.to_path_buf(),
                source,
            },
            other => encode_err(path, one_line(&other.to_string())),
        })
    })
}

/// Map an error of the exr crate while reading `path` to an [`ImageError`].
fn read_err(path: &Path, error: exr::error::Error) -> ImageError {
    let path = path.to_path_buf();
    match error {
        exr::error::Error::Io(source) => ImageError::Read { path, source },
        exr::error::Error::NotSupported(reason) => ImageError::UnsupportedExr {
            path,
            reason: one_line(&reason),
        },
        exr::error::Error::Invalid(reason) => ImageError::CorruptExr {
            path,
            reason: one_line(&reason),
        },
        exr::error::Error::Aborted => ImageError::CorruptExr {
            path,
            reason: "reading was aborted".into(),
        },
    }
}

/// The most pixels a display window read back may have (2^27, the most a
/// render may have): a header can claim any size, and the image is
/// allocated at that size before any pixel is read.
const MAX_READ_PIXELS: usize = 1 << 27;

/// The OpenEXR magic number, the first four bytes of every EXR file.
const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// Find `(layer index, [r, g, b] channel indices)` of the first RGB layer:
/// parts in file order; within a part, the unprefixed `R`,`G`,`B` first,
/// otherwise the first `<prefix>.R/G/B` group in channel order.
fn find_rgb(layers: &[exr::image::Layer<AnyChannels<FlatSamples>>]) -> Option<(usize, [usize; 3])> {
    for (li, layer) in layers.iter().enumerate() {
        let names: Vec<String> = layer
            .channel_data
            .list
            .iter()
            .map(|c| c.name.to_string())
            .collect();
        let mut prefixes: Vec<&str> = vec![""];
        for name in &names {
            if let Some((prefix, _)) = name.rsplit_once('.') {
                if !prefixes.contains(&prefix) {
                    prefixes.push(prefix);
                }
            }
        }
        for prefix in prefixes {
            let find = |c: &str| {
                let full = if prefix.is_empty() {
                    c.to_string()
                } else {
                    format!("{prefix}.{c}")
                };
                names.iter().position(|n| *n == full)
            };
            if let (Some(r), Some(g), Some(b)) = (find("R"), find("G"), find("B")) {
                return Some((li, [r, g, b]));
            }
        }
    }
    None
}

fn sample_f32(samples: &FlatSamples, i: usize) -> f32 {
    match samples {
        FlatSamples::F16(v) => v[i].to_f32(),
        FlatSamples::F32(v) => v[i],
        FlatSamples::U32(v) => v[i] as f32,
    }
}

type Decoded = exr::image::Image<exr::image::Layers<AnyChannels<FlatSamples>>>;

/// The string attributes of an EXR's header, without reading its pixels
/// (`None` when it cannot be read as an EXR).
pub fn read_exr_attributes(path: impl AsRef<Path>) -> Option<Vec<(String, String)>> {
    let meta = exr::meta::MetaData::read_from_file(path.as_ref(), false).ok()?;
    let h = meta.headers.first()?;
    Some(
        h.shared_attributes
            .other
            .iter()
            .chain(h.own_attributes.other.iter())
            .filter_map(|(k, v)| match v {
                AttributeValue::Text(t) => Some((k.to_string(), t.to_string())),
                _ => None,
            })
            .collect(),
    )
}

/// Decodes any OpenEXR file (largest resolution level, all channels and
/// attributes), refusing what is not one with one line naming it.
fn decode(path: &Path) -> Result<Decoded, ImageError> {
    let read_io = |source: std::io::Error| ImageError::Read {
        path: path.to_path_buf(),
        source,
    };
    let mut file = File::open(path).map_err(read_io)?;
    if file.metadata().map_err(read_io)?.is_dir() {
        return Err(read_io(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "it is a directory",
        )));
    }
    let mut magic = [0u8; 4];
    match file.read_exact(&mut magic) {
        Ok(()) if magic == MAGIC => {}
        Ok(()) => {
            return Err(ImageError::NotExr {
                path: path.to_path_buf(),
            })
        }
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            return Err(ImageError::NotExr {
                path: path.to_path_buf(),
            })
        }
        Err(e) => return Err(read_io(e)),
    }
    file.seek(SeekFrom::Start(0)).map_err(read_io)?;

    // The exr crate should report malformed input as errors; the panic guard
    // turns any remaining panic on hostile input into an error as well.
    let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .from_buffered(BufReader::new(file))
    }));
    match decoded {
        Ok(Ok(image)) => Ok(image),
        Ok(Err(e)) => Err(read_err(path, e)),
        Err(_) => Err(ImageError::CorruptExr {
            path: path.to_path_buf(),
            reason: "the decoder failed on malformed data".into(),
        }),
    }
}

/// Read the first RGB(A) layer of any OpenEXR file (alpha and other channels
/// are ignored): `half`, `float` or `uint` samples, any compression the exr
/// crate decodes (none, RLE, ZIP, PIZ, PXR24, B44, DWA), scan lines or tiles
/// (largest mip level). Used for reference images and environment maps.
///
/// The returned image covers the file's display window; pixels of it outside
/// the data window are zero. "First RGB layer": the first part (in file
/// order) with channels `R`, `G`, `B`, preferring unprefixed names, otherwise
/// the first `<layer>.R/G/B` group, e.g. `ViewLayer.Combined.R`.
///
/// Errors (never panics): unreadable file, not an EXR ("is not an OpenEXR
/// file"), damaged or truncated, unsupported feature (deep data, subsampled
/// RGB), no RGB channels (the message lists the channels found).
pub fn read_exr_rgb(path: impl AsRef<Path>) -> Result<ImageRgb, ImageError> {
    let path = path.as_ref();
    let exr_image = decode(path)?;

    let layers = &exr_image.layer_data;
    let Some((li, rgb)) = find_rgb(layers) else {
        let mut channels: Vec<String> = layers
            .iter()
            .flat_map(|l| l.channel_data.list.iter().map(|c| c.name.to_string()))
            .collect();
        if channels.len() > 24 {
            let more = channels.len() - 24;
            channels.truncate(24);
            channels.push(format!("... {more} more"));
        }
        let channels = if channels.is_empty() {
            "none".to_string()
        } else {
            channels.join(", ")
        };
        return Err(ImageError::NoRgbChannels {
            path: path.to_path_buf(),
            channels,
        });
    };
    let layer = &layers[li];
    let list = &layer.channel_data.list;
    for &c in &rgb {
        if list[c].sampling.x() != 1 || list[c].sampling.y() != 1 {
            return Err(ImageError::UnsupportedExr {
                path: path.to_path_buf(),
                reason: format!("channel '{}' is subsampled", list[c].name),
            });
        }
    }

    let display = exr_image.attributes.display_window;
    let (width, height) = (display.size.x(), display.size.y());
    let (data_w, data_h) = (layer.size.x(), layer.size.y());
    for &c in &rgb {
        let len = match &list[c].sample_data {
            FlatSamples::F16(v) => v.len(),
            FlatSamples::F32(v) => v.len(),
            FlatSamples::U32(v) => v.len(),
        };
        if len != data_w * data_h {
            return Err(ImageError::CorruptExr {
                path: path.to_path_buf(),
                reason: format!(
                    "channel '{}' has {len} samples for {data_w}x{data_h} pixels",
                    list[c].name
                ),
            });
        }
    }
    if width == 0 || height == 0 {
        return Err(ImageError::CorruptExr {
            path: path.to_path_buf(),
            reason: "the display window is empty".into(),
        });
    }
    let n = width
        .checked_mul(height)
        .filter(|&n| n <= MAX_READ_PIXELS)
        .ok_or_else(|| ImageError::CorruptExr {
            path: path.to_path_buf(),
            reason: format!(
                "the display window of {width}x{height} pixels is larger than {MAX_READ_PIXELS} pixels"
            ),
        })?;

    let mut pixels = vec![Rgb::ZERO; n];
    // Offset of the data window inside the display window.
    let dx = layer.attributes.layer_position.x() as i64 - display.position.x() as i64;
    let dy = layer.attributes.layer_position.y() as i64 - display.position.y() as i64;
    for sy in 0..data_h {
        let y = sy as i64 + dy;
        if y < 0 || y >= height as i64 {
            continue;
        }
        for sx in 0..data_w {
            let x = sx as i64 + dx;
            if x < 0 || x >= width as i64 {
                continue;
            }
            let i = sy * data_w + sx;
            pixels[y as usize * width + x as usize] = Rgb::new(
                sample_f32(&list[rgb[0]].sample_data, i),
                sample_f32(&list[rgb[1]].sample_data, i),
                sample_f32(&list[rgb[2]].sample_data, i),
            );
        }
    }
    Ok(ImageRgb {
        width,
        height,
        pixels,
    })
}

/// Reads back an EXR as [`write_exr`] writes it: the main layer's `R`, `G`,
/// `B` (and `A`, 1 when absent), every `layer.channel` group as an AOV
/// layer, the data window inside the display window
/// ([`Image::origin`], [`Image::display_size`]) and the header's string
/// attributes (OpenEXR's own attributes left out). Used to merge tiles and
/// renders; other layouts are refused with a message naming the channels.
pub fn read_exr(path: impl AsRef<Path>) -> Result<(Image, Vec<(String, String)>), ImageError> {
    let path = path.as_ref();
    let exr_image = decode(path)?;
    let corrupt = |reason: String| ImageError::CorruptExr {
        path: path.to_path_buf(),
        reason,
    };
    let Some(layer) = exr_image.layer_data.first() else {
        return Err(corrupt("the file has no image part".into()));
    };
    if exr_image.layer_data.len() > 1 {
        return Err(ImageError::UnsupportedExr {
            path: path.to_path_buf(),
            reason: "it has several parts; vdbphoton writes one".into(),
        });
    }
    let (w, h) = (layer.size.x(), layer.size.y());
    let n = w
        .checked_mul(h)
        .filter(|&n| n > 0 && n <= MAX_READ_PIXELS)
        .ok_or_else(|| corrupt(format!("a data window of {w}x{h} pixels")))?;
    let display = exr_image.attributes.display_window;
    let (ox, oy) = (
        layer.attributes.layer_position.x() as i64 - display.position.x() as i64,
        layer.attributes.layer_position.y() as i64 - display.position.y() as i64,
    );
    let list = &layer.channel_data.list;
    let channel = |name: &str| -> Result<Option<Vec<f32>>, ImageError> {
        let Some(c) = list.iter().find(|c| c.name.to_string() == name) else {
            return Ok(None);
        };
        if c.sampling.x() != 1 || c.sampling.y() != 1 {
            return Err(ImageError::UnsupportedExr {
                path: path.to_path_buf(),
                reason: format!("channel '{name}' is subsampled"),
            });
        }
        let v: Vec<f32> = (0..n).map(|i| sample_f32(&c.sample_data, i)).collect();
        Ok(Some(v))
    };
    let names: Vec<String> = list.iter().map(|c| c.name.to_string()).collect();
    for c in list {
        let len = match &c.sample_data {
            FlatSamples::F16(v) => v.len(),
            FlatSamples::F32(v) => v.len(),
            FlatSamples::U32(v) => v.len(),
        };
        if len != n {
            return Err(corrupt(format!(
                "channel '{}' has {len} samples for {w}x{h} pixels",
                c.name
            )));
        }
    }
    let (Some(r), Some(g), Some(b)) = (channel("R")?, channel("G")?, channel("B")?) else {
        return Err(ImageError::NoRgbChannels {
            path: path.to_path_buf(),
            channels: names.join(", "),
        });
    };
    let a = channel("A")?;
    let pixels = (0..n)
        .map(|i| glam::Vec4::new(r[i], g[i], b[i], a.as_ref().map_or(1.0, |a| a[i])))
        .collect();
    let mut image = Image::from_pixels(w, h, pixels)?;
    // AOV layers: channels `layer.c`, in the order their first channel
    // comes.
    let mut layers: Vec<(String, Vec<String>)> = Vec::new();
    for name in &names {
        if let Some((l, c)) = name.rsplit_once('.') {
            match layers.iter_mut().find(|(x, _)| x == l) {
                Some((_, cs)) => cs.push(c.to_string()),
                None => layers.push((l.to_string(), vec![c.to_string()])),
            }
        }
    }
    for (l, cs) in &layers {
        let data: Vec<Vec<f32>> = cs
            .iter()
            .map(|c| channel(&format!("{l}.{c}")).map(|v| v.unwrap_or_default()))
            .collect::<Result<_, _>>()?;
        let refs: Vec<&str> = cs.iter().map(|c| c.as_str()).collect();
        let layer = image
            .add_layer(l, &refs)
            .map_err(|_| ImageError::UnsupportedExr {
                path: path.to_path_buf(),
                reason: format!("layer '{l}' has names vdbphoton does not write"),
            })?;
        let k = cs.len();
        for (ci, d) in data.iter().enumerate() {
            for (i, v) in d.iter().enumerate() {
                layer.data_mut()[i * k + ci] = *v;
            }
        }
    }
    let (dw, dh) = (display.size.x(), display.size.y());
    if ox < 0 || oy < 0 {
        return Err(corrupt(
            "the data window starts outside the display window".into(),
        ));
    }
    image
        .set_window((ox as usize, oy as usize), (dw, dh))
        .map_err(|_| corrupt("the data window lies outside the display window".into()))?;
    let mut attributes: Vec<(String, String)> = exr_image
        .attributes
        .other
        .iter()
        .chain(layer.attributes.other.iter())
        .filter_map(|(k, v)| match v {
            AttributeValue::Text(t) => Some((k.to_string(), t.to_string())),
            _ => None,
        })
        .collect();
    attributes.sort();
    attributes.dedup();
    Ok((image, attributes))
}
