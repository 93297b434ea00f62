//! Integration tests of `vdbphoton::image`.

mod common;

use std::fs;
use std::path::{Path, PathBuf};

use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Compression, Encoding, FlatSamples, LayerAttributes,
    LineOrder, MetaData, ReadChannels, ReadLayers, SmallVec, Text, WritableImage,
};
use glam::{Vec3, Vec4};
use vdbphoton::image::{
    compare, read_exr_rgb, write_diff_png, write_exr, write_png_preview, Image, ImageError,
    ImageRgb, View,
};
use vdbphoton::Rgb;

fn attrs(pairs: &[(&str, &str)]) -> Vec<(String, String)> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

/// A 7x5 image with awkward values (negative, subnormal, huge, -0, inf) and
/// two AOV layers.
fn test_image() -> Image {
    let mut image = Image::from_fn(7, 5, |x, y| {
        let i = (y * 7 + x) as f32;
        Vec4::new(
            i * 0.123_456_79 - 1.0,
            (i + 1.0).recip(),
            i * 1e-39,
            1.0 - i / 40.0,
        )
    });
    image.set(0, 0, Vec4::new(-0.0, f32::MAX, f32::INFINITY, 0.0));
    image.set(6, 4, Vec4::new(1e-45, 65504.5, 3.0e38, 1.0));
    let direct = image.add_rgb_layer("direct").unwrap();
    for y in 0..5 {
        for x in 0..7 {
            let v = (x * 10 + y) as f32 / 3.0;
            direct.set(x, y, &[v, v * 2.0, -v]);
        }
    }
    let t = image.add_layer("transmittance", &["Y"]).unwrap();
    t.set(3, 2, &[0.25]);
    image
}

fn bits(v: f32) -> u32 {
    v.to_bits()
}

fn read_all(
    path: &Path,
) -> exr::image::Image<SmallVec<[exr::image::Layer<AnyChannels<FlatSamples>>; 2]>> {
    exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(path)
        .unwrap()
}

fn f32_samples(ch: &AnyChannel<FlatSamples>) -> &[f32] {
    match &ch.sample_data {
        FlatSamples::F32(v) => v,
        _ => panic!("channel {} is not f32", ch.name),
    }
}

#[test]
fn exr_round_trip_is_bit_exact_with_layers_and_attributes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.exr");
    let image = test_image();
    let attributes = attrs(&[
        ("spp", "256"),
        ("seed", "99"),
        ("integrator", "volpath-delta-tracking"),
        ("passes", "4"),
    ]);
    write_exr(&path, &image, &attributes).unwrap();
    assert_eq!(common::dir_entries(dir.path()), vec!["out.exr"]);

    // Our reader: dimensions and bit-identical RGB.
    let back = read_exr_rgb(&path).unwrap();
    assert_eq!((back.width, back.height), (7, 5));
    for (p, q) in image.pixels().iter().zip(&back.pixels) {
        for c in 0..3 {
            assert_eq!(bits(p[c]), bits(q[c]), "{p} vs {q}");
        }
    }

    // Header attributes via the exr crate's metadata reader.
    let meta = MetaData::read_from_file(&path, false).unwrap();
    assert_eq!(meta.headers.len(), 1);
    let header = &meta.headers[0];
    assert_eq!(header.compression, Compression::ZIP16);
    for (k, v) in &attributes {
        match header.own_attributes.other.get(&Text::from(k.as_str())) {
            Some(AttributeValue::Text(t)) => assert_eq!(t.to_string(), *v),
            other => panic!("attribute {k}: {other:?}"),
        }
    }
    let names = common::channel_names(header);
    assert_eq!(
        names,
        vec![
            "A",
            "B",
            "G",
            "R",
            "direct.B",
            "direct.G",
            "direct.R",
            "transmittance.Y"
        ]
    );

    // All channels via the exr crate: alpha and AOV layers bit-exact.
    let all = read_all(&path);
    let list = &all.layer_data[0].channel_data.list;
    let get = |name: &str| {
        f32_samples(
            list.iter()
                .find(|c| c.name.to_string() == name)
                .unwrap_or_else(|| panic!("no channel {name}")),
        )
    };
    let alpha = get("A");
    for (i, p) in image.pixels().iter().enumerate() {
        assert_eq!(bits(alpha[i]), bits(p.w));
    }
    let direct = image.layer("direct").unwrap();
    for (c, ch) in ["R", "G", "B"].iter().enumerate() {
        let v = get(&format!("direct.{ch}"));
        assert_eq!(v.len(), 35);
        for (i, value) in v.iter().enumerate() {
            assert_eq!(bits(*value), bits(direct.data()[i * 3 + c]));
        }
    }
    let t = get("transmittance.Y");
    assert_eq!(t[2 * 7 + 3], 0.25);
    assert_eq!(t.iter().filter(|&&v| v != 0.0).count(), 1);
}

#[test]
fn exr_write_overwrites_existing_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.exr");
    fs::write(&path, "old").unwrap();
    let image = Image::filled(3, 2, Vec4::new(0.5, 0.25, 0.125, 1.0));
    write_exr(&path, &image, &[]).unwrap();
    let back = read_exr_rgb(&path).unwrap();
    assert_eq!(back.pixels, vec![Vec3::new(0.5, 0.25, 0.125); 6]);
    assert_eq!(common::dir_entries(dir.path()), vec!["x.exr"]);
}

#[test]
fn write_into_missing_directory_names_the_path_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let image = Image::filled(2, 2, Vec4::ONE);
    for name in ["x.exr", "x.png"] {
        let path = dir.path().join("missing").join(name);
        let err = if name.ends_with("exr") {
            write_exr(&path, &image, &[]).unwrap_err()
        } else {
            write_png_preview(&path, &image, 0.0, View::Standard).unwrap_err()
        };
        assert!(matches!(err, ImageError::Write { .. }), "{err:?}");
        assert_eq!(
            err.to_string(),
            format!(
                "cannot write '{}': No such file or directory (os error 2)",
                path.display()
            )
        );
        assert!(!path.exists());
    }
    assert!(common::dir_entries(dir.path()).is_empty());
}

#[test]
fn failing_write_leaves_no_temporary_behind() {
    // The target is an existing directory: the temporary is written fully,
    // then the rename fails; the temporary must be removed.
    let dir = tempfile::tempdir().unwrap();
    let image = Image::filled(4, 3, Vec4::splat(0.5));
    for name in ["taken.exr", "taken.png"] {
        let target = dir.path().join(name);
        fs::create_dir(&target).unwrap();
        let err = if name.ends_with("exr") {
            write_exr(&target, &image, &[]).unwrap_err()
        } else {
            write_png_preview(&target, &image, 0.0, View::Standard).unwrap_err()
        };
        let msg = err.to_string();
        assert!(
            msg.starts_with(&format!("cannot write '{}': ", target.display())),
            "{msg}"
        );
        assert!(target.is_dir() && common::dir_entries(&target).is_empty());
    }
    assert_eq!(
        common::dir_entries(dir.path()),
        vec!["taken.exr", "taken.png"]
    );
}

#[test]
fn invalid_exr_arguments_are_errors_without_files() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.exr");
    let image = Image::filled(2, 2, Vec4::ONE);
    for bad in [
        attrs(&[("compression", "none")]),
        attrs(&[("", "x")]),
        attrs(&[("has space", "x")]),
        attrs(&[("spp", "1"), ("spp", "2")]),
    ] {
        let err = write_exr(&path, &image, &bad).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.starts_with(&format!("cannot write '{}': ", path.display())),
            "{msg}"
        );
    }
    let err = write_exr(&path, &Image::new(0, 3), &[]).unwrap_err();
    assert!(
        err.to_string().contains("the image is empty (0x3)"),
        "{err}"
    );
    assert!(common::dir_entries(dir.path()).is_empty());
    // Non-ASCII values are stored as UTF-8 bytes and accepted.
    write_exr(&path, &image, &attrs(&[("note", "Dichte σ")])).unwrap();
}

#[test]
fn reading_a_text_file_is_not_an_exr_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sky.exr");
    fs::write(&path, "this is not an image\n").unwrap();
    let err = read_exr_rgb(&path).unwrap_err();
    assert!(matches!(err, ImageError::NotExr { .. }));
    assert_eq!(
        err.to_string(),
        format!("'{}' is not an OpenEXR file", path.display())
    );
    fs::write(&path, "").unwrap();
    assert!(matches!(
        read_exr_rgb(&path).unwrap_err(),
        ImageError::NotExr { .. }
    ));

    let missing = dir.path().join("nope.exr");
    let err = read_exr_rgb(&missing).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "cannot read '{}': No such file or directory (os error 2)",
            missing.display()
        )
    );
    let err = read_exr_rgb(dir.path()).unwrap_err();
    assert!(
        err.to_string()
            .starts_with(&format!("cannot read '{}'", dir.path().display())),
        "{err}"
    );
}

#[test]
fn truncated_or_corrupted_exr_gives_errors_not_panics() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.exr");
    let mut image = Image::from_fn(40, 30, |x, y| {
        Vec4::new(x as f32 * 0.1, y as f32, (x ^ y) as f32, 1.0)
    });
    image.add_rgb_layer("direct").unwrap();
    write_exr(&good, &image, &attrs(&[("spp", "4")])).unwrap();
    let bytes = fs::read(&good).unwrap();
    let cut = dir.path().join("cut.exr");
    let mut lengths: Vec<usize> = (0..bytes.len()).step_by(53).collect();
    lengths.push(bytes.len() - 1);
    for len in lengths {
        fs::write(&cut, &bytes[..len]).unwrap();
        let err = read_exr_rgb(&cut).expect_err(&format!("truncated to {len} bytes"));
        let msg = err.to_string();
        assert!(
            msg.contains(&format!("'{}'", cut.display())) && !msg.contains('\n'),
            "{msg}"
        );
        if len >= 4 {
            assert!(!matches!(err, ImageError::NotExr { .. }), "{msg}");
        }
    }
    // Flipped bytes anywhere: an error or some image, never a panic.
    for pos in (4..bytes.len()).step_by(37) {
        let mut damaged = bytes.clone();
        damaged[pos] ^= 0xA5;
        fs::write(&cut, &damaged).unwrap();
        if let Err(err) = read_exr_rgb(&cut) {
            assert!(!err.to_string().contains('\n'));
        }
    }
}

/// Write a single-layer EXR with the exr crate directly.
fn write_with_exr_crate(
    path: &Path,
    size: (usize, usize),
    channels: Vec<AnyChannel<FlatSamples>>,
    compression: Compression,
    attributes: LayerAttributes,
) -> exr::image::Image<exr::image::Layer<AnyChannels<FlatSamples>>> {
    let layer = exr::image::Layer::new(
        size,
        attributes,
        Encoding {
            compression,
            blocks: exr::image::Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
        AnyChannels::sort(channels.into()),
    );
    let image = exr::image::Image::from_layer(layer);
    image.write().to_file(path).unwrap();
    image
}

#[test]
fn reads_half_piz_and_uncompressed_and_prefixed_layers() {
    use exr::prelude::f16;
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (5usize, 3usize);
    let val = |i: usize, c: usize| (i * 3 + c) as f32 * 0.25;
    for (k, compression) in [
        Compression::PIZ,
        Compression::ZIP1,
        Compression::Uncompressed,
    ]
    .into_iter()
    .enumerate()
    {
        let path = dir.path().join(format!("half{k}.exr"));
        let channels = ["R", "G", "B"]
            .iter()
            .enumerate()
            .map(|(c, n)| {
                let v = (0..w * h).map(|i| f16::from_f32(val(i, c))).collect();
                AnyChannel::new(*n, FlatSamples::F16(v))
            })
            .collect();
        write_with_exr_crate(
            &path,
            (w, h),
            channels,
            compression,
            LayerAttributes::default(),
        );
        let img = read_exr_rgb(&path).unwrap();
        assert_eq!((img.width, img.height), (w, h));
        for (i, p) in img.pixels.iter().enumerate() {
            assert_eq!(*p, Vec3::new(val(i, 0), val(i, 1), val(i, 2)));
        }
    }

    // Blender-style names: the first <prefix>.R/G/B group is used.
    let path = dir.path().join("blender.exr");
    let mut channels = Vec::new();
    for (prefix, base) in [("ViewLayer.Combined", 1.0f32), ("ViewLayer.Diffuse", 9.0)] {
        for (c, n) in ["R", "G", "B", "A"].iter().enumerate() {
            channels.push(AnyChannel::new(
                format!("{prefix}.{n}").as_str(),
                FlatSamples::F32(vec![base + c as f32; w * h]),
            ));
        }
    }
    write_with_exr_crate(
        &path,
        (w, h),
        channels,
        Compression::ZIP16,
        LayerAttributes::default(),
    );
    let img = read_exr_rgb(&path).unwrap();
    assert_eq!(img.pixels, vec![Vec3::new(1.0, 2.0, 3.0); w * h]);
}

#[test]
fn luminance_only_exr_has_no_rgb_channels() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sky.exr");
    let ch = vec![AnyChannel::new("Y", FlatSamples::F32(vec![0.5; 4]))];
    write_with_exr_crate(
        &path,
        (2, 2),
        ch,
        Compression::ZIP16,
        LayerAttributes::default(),
    );
    let err = read_exr_rgb(&path).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!("'{}' has no RGB channels (channels: Y)", path.display())
    );
}

#[test]
fn data_window_is_placed_inside_display_window() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("window.exr");
    // Data window 2x1 at (1, 2) inside a 4x3 display window at (0, 0).
    let attributes = LayerAttributes {
        layer_position: exr::prelude::Vec2(1, 2),
        ..Default::default()
    };
    let layer = exr::image::Layer::new(
        (2, 1),
        attributes,
        Encoding::UNCOMPRESSED,
        AnyChannels::sort(SmallVec::from_vec(
            ["R", "G", "B"]
                .iter()
                .map(|n| AnyChannel::new(*n, FlatSamples::F32(vec![1.0, 2.0])))
                .collect(),
        )),
    );
    let image = exr::image::Image::new(
        exr::prelude::ImageAttributes::new(exr::prelude::IntegerBounds::new((0, 0), (4, 3))),
        layer,
    );
    image.write().to_file(&path).unwrap();
    let img = read_exr_rgb(&path).unwrap();
    assert_eq!((img.width, img.height), (4, 3));
    assert_eq!(img.get(1, 2), Vec3::splat(1.0));
    assert_eq!(img.get(2, 2), Vec3::splat(2.0));
    assert_eq!(img.pixels.iter().filter(|p| **p != Vec3::ZERO).count(), 2);
}

fn decode_png(path: &Path) -> (png::OutputInfo, Vec<u8>, bool) {
    let data = fs::read(path).unwrap();
    let decoder = png::Decoder::new(std::io::Cursor::new(data));
    let mut reader = decoder.read_info().unwrap();
    let srgb = reader.info().srgb.is_some();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info, buf, srgb)
}

#[test]
fn png_preview_is_8bit_srgb() {
    let dir = tempfile::tempdir().unwrap();
    let values = [0.0f32, 0.003_130_8, 0.5, 1.0, 0.25, 2.0, -0.5, f32::NAN];
    // Row 0: grey values; row 1: colour channels kept apart; alpha ignored.
    let mut image = Image::new(values.len(), 2);
    for (x, v) in values.iter().enumerate() {
        image.set(x, 0, Vec4::new(*v, *v, *v, 0.0));
    }
    image.set(0, 1, Vec4::new(1.0, 0.5, 0.0, 0.3));
    let path = dir.path().join("p.png");
    write_png_preview(&path, &image, 0.0, View::Standard).unwrap();
    let (info, buf, srgb) = decode_png(&path);
    assert_eq!((info.width, info.height), (8, 2));
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    assert!(srgb, "sRGB chunk");
    let row0: Vec<u8> = buf[..24].iter().step_by(3).copied().collect();
    assert_eq!(row0, vec![0, 10, 188, 255, 137, 255, 0, 0]);
    assert!(buf[..24].chunks(3).all(|p| p[0] == p[1] && p[1] == p[2]));
    assert_eq!(&buf[24..27], &[255, 188, 0]);

    // Exposure +1 doubles: 0.25 -> like 0.5, 0.5 -> like 1.0.
    write_png_preview(&path, &image, 1.0, View::Standard).unwrap();
    let (_, buf, _) = decode_png(&path);
    let row0: Vec<u8> = buf[..24].iter().step_by(3).copied().collect();
    assert_eq!(row0, vec![0, 18, 255, 255, 188, 255, 0, 0]);
    // Exposure -1 halves: 1.0 -> like 0.5.
    write_png_preview(&path, &image, -1.0, View::Standard).unwrap();
    let (_, buf, _) = decode_png(&path);
    assert_eq!(buf[9], 188);
    assert_eq!(common::dir_entries(dir.path()), vec!["p.png"]);
}

fn rgb_image(width: usize, height: usize, pixels: &[[f32; 3]]) -> ImageRgb {
    ImageRgb {
        width,
        height,
        pixels: pixels.iter().map(|p| Rgb::from_array(*p)).collect(),
    }
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn metrics_match_hand_computed_values() {
    // One pixel: d = (0.1, 0, -0.2), d^2 = (0.01, 0, 0.04).
    let a = rgb_image(1, 1, &[[0.2, 0.4, 0.6]]);
    let b = rgb_image(1, 1, &[[0.1, 0.4, 0.8]]);
    let m = compare(&a, &b).unwrap();
    assert!(close(m.mean_a, 0.4, 1e-7), "{m:?}");
    assert!(close(m.mean_b, 1.3 / 3.0, 1e-7));
    assert!(close(m.mean_ratio, 1.2 / 1.3, 1e-7));
    assert!(close(m.mse, 0.05 / 3.0, 1e-8));
    assert!(close(m.rmse, (0.05f64 / 3.0).sqrt(), 1e-7));
    // (0.01/0.02 + 0/0.17 + 0.04/0.65) / 3
    assert!(close(m.rel_mse, (0.5 + 0.04 / 0.65) / 3.0, 1e-7));
    assert!(close(m.peak, 0.8, 1e-7));
    // 10 log10(0.64 / (0.05/3)) = 10 log10(38.4)
    assert!(close(m.psnr, 15.843_312_2, 1e-5), "{}", m.psnr);

    // Two pixels, second one black vs white.
    let a = rgb_image(2, 1, &[[0.5; 3], [0.0; 3]]);
    let b = rgb_image(2, 1, &[[0.5; 3], [1.0; 3]]);
    let m = compare(&a, &b).unwrap();
    assert!(close(m.mean_a, 0.25, 1e-12) && close(m.mean_b, 0.75, 1e-12));
    assert!(close(m.mean_ratio, 1.0 / 3.0, 1e-12));
    assert!(close(m.rmse, 0.5f64.sqrt(), 1e-12));
    assert!(close(m.rel_mse, 0.5 / 1.01, 1e-12));
    assert!(close(m.psnr, 10.0 * 2f64.log10(), 1e-12));

    // Identical: zero error, infinite PSNR.
    let m = compare(&b, &b).unwrap();
    assert_eq!((m.rmse, m.rel_mse, m.mean_ratio), (0.0, 0.0, 1.0));
    assert_eq!(m.psnr, f64::INFINITY);

    // Size mismatch.
    let c = rgb_image(1, 2, &[[0.5; 3], [1.0; 3]]);
    let err = compare(&a, &c).unwrap_err();
    assert!(matches!(err, ImageError::SizeMismatch { .. }));
    assert_eq!(err.to_string(), "image sizes differ: 2x1 vs reference 1x2");
}

#[test]
fn diff_png_colours_sign_and_uses_robust_scale() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("diff.png");
    let b = rgb_image(4, 1, &[[1.0; 3]; 4]);
    let a = rgb_image(4, 1, &[[1.5; 3], [0.75; 3], [1.0; 3], [f32::NAN, 1.0, 1.0]]);
    let scale = write_diff_png(&path, &a, &b).unwrap();
    assert_eq!(scale, 0.5);
    let (info, buf, _) = decode_png(&path);
    assert_eq!((info.width, info.height), (4, 1));
    assert_eq!(buf, vec![255, 0, 0, 0, 0, 128, 0, 0, 0, 0, 255, 0]);

    // 200 small differences and one outlier: the scale ignores the outlier.
    let b = ImageRgb::filled(201, 1, Vec3::ZERO);
    let mut a = ImageRgb::filled(201, 1, Vec3::splat(-0.01));
    a.set(100, 0, Vec3::splat(10.0));
    let scale = write_diff_png(&path, &a, &b).unwrap();
    assert!(close(scale as f64, 0.01, 1e-7), "{scale}");
    let (_, buf, _) = decode_png(&path);
    assert_eq!(&buf[..3], &[0, 0, 255]);
    assert_eq!(&buf[300..303], &[255, 0, 0]);

    let c = ImageRgb::filled(3, 1, Vec3::ZERO);
    assert!(write_diff_png(&path, &a, &c).is_err());
}

#[test]
fn image_accessors_and_layers() {
    let mut image = Image::new(3, 2);
    assert_eq!(image.get(2, 1), Vec4::ZERO);
    image.set(2, 1, Vec4::new(3.0, 6.0, 9.0, 1.0));
    assert_eq!(image.pixels()[5], Vec4::new(3.0, 6.0, 9.0, 1.0));
    assert_eq!(image.mean_rgb(), Vec3::new(0.5, 1.0, 1.5));
    assert_eq!(image.to_rgb().mean(), 1.0);
    assert!(Image::from_pixels(2, 2, vec![Vec4::ONE; 3]).is_err());
    assert_eq!(
        Image::from_pixels(2, 2, vec![Vec4::ONE; 4])
            .unwrap()
            .mean_rgb(),
        Vec3::ONE
    );

    let l = image.add_rgb_layer("emission").unwrap();
    l.set(1, 1, &[1.0, 2.0, 3.0]);
    assert_eq!(l.get(1, 1), &[1.0, 2.0, 3.0]);
    assert_eq!(l.data()[12..15], [1.0, 2.0, 3.0]);
    assert!(image.add_rgb_layer("emission").is_err());
    assert!(image.add_layer("a.b", &["R"]).is_err());
    assert!(image.add_layer("t", &[]).is_err());
    assert!(image.add_layer("t", &["Y", "Y"]).is_err());
    assert!(image.add_layer("t", &["Y.Z"]).is_err());
    image.add_layer("t", &["Y"]).unwrap();
    assert_eq!(image.layers().len(), 2);
    assert_eq!(image.layer("t").unwrap().channel_index("Y"), Some(0));
    assert!(image.layer("missing").is_none());
}

/// Root of the real data (`VDBPHOTON_REAL_DATA`, e.g. /work/shared/data), or
/// `None` (with a note) when the variable is unset.
fn real_data() -> Option<PathBuf> {
    match std::env::var_os("VDBPHOTON_REAL_DATA") {
        Some(dir) => Some(PathBuf::from(dir)),
        None => {
            eprintln!("note: VDBPHOTON_REAL_DATA is unset; skipping the real reference-image test");
            None
        }
    }
}

fn check_reference(file: &str, expected_mean: f64) {
    let Some(root) = real_data() else { return };
    let path = root.join("reference").join(file);
    assert!(
        path.is_file(),
        "VDBPHOTON_REAL_DATA is set but {} is missing",
        path.display()
    );
    let img = read_exr_rgb(&path).unwrap();
    assert_eq!((img.width, img.height), (256, 192));
    let mean = img.mean();
    assert!(
        (mean - expected_mean).abs() <= 1e-5,
        "{file}: mean {mean} expected {expected_mean}"
    );
    // The README: the background is 0.1 (to float rounding) and the image is grey.
    assert!((img.get(0, 0) - Vec3::splat(0.1)).abs().max_element() < 1e-6);
    assert!(img.pixels.iter().all(|p| p.x == p.y && p.y == p.z));
}

#[test]
fn real_reference_mitsuba_2048_piz_rgb() {
    check_reference("mitsuba_2048.exr", 0.109437);
}

#[test]
fn real_reference_cycles_256_zip_rgba() {
    check_reference("cycles_256.exr", 0.109446);
}

#[test]
fn real_reference_metrics_match_readme() {
    let Some(root) = real_data() else { return };
    let dir = root.join("reference");
    let truth = read_exr_rgb(dir.join("mitsuba_2048.exr")).unwrap();
    let cycles = read_exr_rgb(dir.join("cycles_256.exr")).unwrap();
    let m = compare(&cycles, &truth).unwrap();
    // README table: Cycles 256 spp vs ground truth, RMSE 0.003060, relMSE 0.000222.
    assert!(close(m.rmse, 0.003060, 5e-7), "{m:?}");
    assert!(close(m.rel_mse, 0.000222, 5e-7), "{m:?}");
    assert!(close(m.mean_ratio, 1.000076, 5e-6), "{m:?}");
}
