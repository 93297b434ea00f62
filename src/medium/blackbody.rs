//! Blackbody colour as Blender Cycles computes it for the Principled Volume:
//! `svm_math_blackbody_color_rec709` (Cycles `kernel/svm/math_util.h`,
//! adapted from Open Shading Language), a piecewise fit of Planck's law
//! integrated against the CIE 1931 observer, in linear Rec.709, normalised
//! so its luminance is about 1. Seven segments between 800 K and 12000 K:
//! R and G as a/T + bT + c, B as a cubic in T; constant outside that range.
//! Components may be negative (colours outside Rec.709, as Cycles leaves
//! them).

// The constants are written with the digits Cycles publishes, so they can
// be checked against its source; f32 rounds them the same way.
#![allow(clippy::excessive_precision)]

use crate::Rgb;

// Coefficients of the fit, per segment (the constants Cycles uses).
const TABLE_R: [[f32; 3]; 7] = [
    [1.619_191_1e3, -2.050_109_2e-3, 5.029_957_6],
    [2.488_454_7e3, -1.113_309_1e-3, 3.226_215_4],
    [3.341_431_9e3, -4.865_511_9e-4, 1.764_867_7],
    [4.094_617_4e3, -1.274_465_8e-4, 7.257_316_4e-1],
    [4.670_280_4e3, 2.912_582e-5, 1.267_034_4e-1],
    [4.595_091_9e3, 2.874_956_5e-5, 1.503_450_2e-1],
    [3.787_174_5e3, 9.359_078_3e-6, 3.990_758_7e-1],
];
const TABLE_G: [[f32; 3]; 7] = [
    [-4.889_997_5e2, 6.043_307_5e-4, -7.558_075_3e-2],
    [-7.559_942_8e2, 3.167_301e-4, 4.783_061_4e-1],
    [-1.023_639_8e3, 1.202_234_7e-4, 9.366_623_2e-1],
    [-1.265_713_2e3, 4.873_409e-6, 1.270_545],
    [-1.425_293_3e3, -4.011_504_3e-5, 1.439_727_8],
    [-1.175_548_2e3, -2.163_780_5e-5, 1.304_080_2],
    [-5.007_995_7e2, -4.598_320_3e-6, 1.090_987_6],
];
const TABLE_B: [[f32; 4]; 7] = [
    [
        5.969_453_1e-11,
        -4.857_428_9e-8,
        -9.706_222_5e-5,
        -4.079_361_5e-3,
    ],
    [
        2.404_303_7e-11,
        5.550_210_8e-8,
        -1.985_037_1e-4,
        2.893_128_6e-2,
    ],
    [
        -1.409_497_3e-11,
        1.898_789_7e-7,
        -3.566_328_2e-4,
        9.107_677_8e-2,
    ],
    [
        -3.614_608_7e-11,
        2.848_220_1e-7,
        -4.932_113_2e-4,
        1.567_234_4e-1,
    ],
    [
        -1.970_757_4e-11,
        1.753_593_5e-7,
        -2.505_428_3e-4,
        -2.227_832_7e-2,
    ],
    [
        -1.619_979_6e-13,
        -1.642_160_1e-8,
        3.862_162_7e-4,
        -7.380_774_2e-1,
    ],
    [
        6.726_502_8e-13,
        -2.730_788_1e-8,
        4.240_982_6e-4,
        -7.523_356_9e-1,
    ],
];

/// Lower bounds (K) of segments 1..6; below 965 K is segment 0.
const SEGMENT_START: [f32; 6] = [965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0];

/// Blackbody colour of temperature `t` in kelvin, exactly as Cycles'
/// Principled Volume uses it.
pub fn blackbody_rgb_cycles(t: f32) -> Rgb {
    if t >= 12000.0 {
        return Rgb::new(0.826_295_5, 0.994_508_05, 1.566_307_7);
    }
    if t < 800.0 {
        return Rgb::new(5.413_294_5, -0.203_193_9, -0.082_253_52);
    }
    let i = SEGMENT_START.iter().filter(|&&s| t >= s).count();
    let (r, g, b) = (TABLE_R[i], TABLE_G[i], TABLE_B[i]);
    let t_inv = 1.0 / t;
    Rgb::new(
        r[0] * t_inv + r[1] * t + r[2],
        g[0] * t_inv + g[1] * t + g[2],
        ((b[0] * t + b[1]) * t + b[2]) * t + b[3],
    )
}

/// CIE 1931 2° colour matching functions, by the multi-lobe Gaussian fit of
/// Wyman, Sloan & Shirley 2013 ("Simple Analytic Approximations to the CIE
/// XYZ Color Matching Functions"), λ in nm.
fn cie_xyz(lambda: f64) -> [f64; 3] {
    let g = |mu: f64, s1: f64, s2: f64| {
        let t = (lambda - mu) / if lambda < mu { s1 } else { s2 };
        (-0.5 * t * t).exp()
    };
    [
        1.056 * g(599.8, 37.9, 31.0) + 0.362 * g(442.0, 16.0, 26.7) - 0.065 * g(501.1, 20.4, 26.2),
        0.821 * g(568.8, 46.9, 40.5) + 0.286 * g(530.9, 16.3, 31.1),
        1.217 * g(437.0, 11.8, 36.0) + 0.681 * g(459.0, 26.0, 13.8),
    ]
}

/// Blackbody colour of temperature `t` (K) from first principles: Planck's
/// law integrated against the CIE 1931 observer (360–830 nm, 1 nm steps),
/// converted to linear Rec.709 and normalised to luminance 1 — the quantity
/// Cycles' fit approximates. The renderer uses [`blackbody_rgb_cycles`] so
/// that images match Blender; this one checks that fit from first
/// principles. The largest channel difference relative to the largest
/// channel is 1.72 % over 2000–12000 K and 6.53 % over 1000–2000 K, as
/// `tests/medium.rs` measures and bounds. Below 2000 K the difference is
/// mostly this function's own error: the analytic colour-matching fit is
/// too low in the deep red (x̄ about half the tabulated value at 700 nm),
/// which matters for the red-heavy spectra of cool flames. Integrating
/// against the tabulated 5 nm CIE 1931 functions instead (not done here)
/// reproduces Cycles' fit to about 1e-4, a colleague measured.
pub fn blackbody_rgb_planck(t: f32) -> Rgb {
    const H: f64 = 6.626_070_15e-34;
    const C: f64 = 2.997_924_58e8;
    const K: f64 = 1.380_649e-23;
    let t = t.max(1.0) as f64;
    let mut xyz = [0.0f64; 3];
    for nm in 360..=830 {
        let l = nm as f64 * 1e-9;
        let b = 2.0 * H * C * C / l.powi(5) / ((H * C / (l * K * t)).exp_m1());
        let c = cie_xyz(nm as f64);
        for i in 0..3 {
            xyz[i] += b * c[i];
        }
    }
    let [x, y, z] = xyz.map(|v| v / xyz[1]);
    Rgb::new(
        (3.240_454_2 * x - 1.537_138_5 * y - 0.498_531_4 * z) as f32,
        (-0.969_266 * x + 1.876_010_8 * y + 0.041_556 * z) as f32,
        (0.055_643_4 * x - 0.204_025_9 * y + 1.057_225_2 * z) as f32,
    )
}
