//! A chi-square goodness-of-fit test for direction samplers, in the manner
//! of Mitsuba 3's `chi2.py` and pbrt-v4's sampling tests: bin samples on the
//! sphere in the local frame of `wo` by (cos θ, φ), integrate the density
//! over each bin numerically, pool bins with small expected counts, and
//! compare with the χ² distribution.
#![allow(dead_code)]

use glam::Vec3;
use std::f64::consts::PI;

/// Natural log of Γ(x) (Lanczos, g = 7, n = 9).
fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return (PI / (PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma Q(a, x) (Numerical Recipes: series
/// for x < a + 1, continued fraction otherwise).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    if x < a + 1.0 {
        let (mut sum, mut del, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - ln_gamma(a)).exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - ln_gamma(a)).exp() * h
    }
}

/// p-value of a χ² statistic with `dof` degrees of freedom.
pub fn chi2_p_value(stat: f64, dof: usize) -> f64 {
    gamma_q(dof as f64 / 2.0, stat / 2.0)
}

pub struct Chi2Result {
    pub statistic: f64,
    pub dof: usize,
    pub p_value: f64,
}

/// Bins `n` directions from `sample` (in the frame where `wo` = +Z) into
/// `res_cos` x `res_phi` bins of (cos θ, φ) and tests them against `pdf`.
pub fn chi2_test(
    n: usize,
    res_cos: usize,
    res_phi: usize,
    sample: impl FnMut(usize) -> Option<Vec3>,
    pdf: impl Fn(Vec3) -> f64,
) -> Chi2Result {
    chi2_test_with(n, res_cos, res_phi, 8, sample, pdf)
}

/// As [`chi2_test`], with `phi_sub` Simpson intervals in φ per bin (raise
/// it for densities with jumps in φ, such as environment maps).
pub fn chi2_test_with(
    n: usize,
    res_cos: usize,
    res_phi: usize,
    phi_sub: usize,
    mut sample: impl FnMut(usize) -> Option<Vec3>,
    pdf: impl Fn(Vec3) -> f64,
) -> Chi2Result {
    let bins = res_cos * res_phi;
    let mut observed = vec![0.0f64; bins];
    let bin_of = |w: Vec3| {
        let c = ((w.z as f64 + 1.0) * 0.5 * res_cos as f64)
            .floor()
            .clamp(0.0, res_cos as f64 - 1.0) as usize;
        let mut phi = (w.y as f64).atan2(w.x as f64);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let p = (phi / (2.0 * PI) * res_phi as f64)
            .floor()
            .clamp(0.0, res_phi as f64 - 1.0) as usize;
        c * res_phi + p
    };
    for i in 0..n {
        if let Some(w) = sample(i) {
            observed[bin_of(w)] += 1.0;
        }
    }
    // Expected counts: adaptive Simpson in cos θ (peaked lobes need it)
    // of a fixed Simpson rule in φ, over each bin; d(solid angle) =
    // d(cos θ) dφ.
    let mut expected = vec![0.0f64; bins];
    for p in 0..res_phi {
        let (p0, p1) = (
            2.0 * PI * p as f64 / res_phi as f64,
            2.0 * PI * (p + 1) as f64 / res_phi as f64,
        );
        let over_phi = |cz: f64| {
            let sub = phi_sub;
            let s = (1.0 - cz * cz).max(0.0).sqrt();
            let mut sum = 0.0;
            for j in 0..=sub {
                let wj = if j == 0 || j == sub {
                    1.0
                } else if j % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                // The end nodes sit just inside the bin: a density with a
                // jump on a bin edge (an environment map's texel edge) is
                // then integrated with its values in this bin, not with the
                // neighbour's that rounding at the edge may give.
                let x = (j as f64 / sub as f64).clamp(1e-5, 1.0 - 1e-5);
                let ph = p0 + (p1 - p0) * x;
                let w = Vec3::new((s * ph.cos()) as f32, (s * ph.sin()) as f32, cz as f32);
                sum += wj * pdf(w);
            }
            sum * (p1 - p0) / (3.0 * sub as f64)
        };
        for c in 0..res_cos {
            let (c0, c1) = (
                -1.0 + 2.0 * c as f64 / res_cos as f64,
                -1.0 + 2.0 * (c + 1) as f64 / res_cos as f64,
            );
            expected[c * res_phi + p] = adaptive_simpson(&over_phi, c0, c1, 1e-9, 24) * n as f64;
        }
    }
    chi2_counts(&observed, &expected)
}

/// χ² of `observed` counts against `expected` ones (the same bins, the
/// same total): bins whose expected count is below 5 are pooled into one,
/// and one degree of freedom is taken for the total. Counts in bins that
/// expect none make the statistic huge (p-value 0).
pub fn chi2_counts(observed: &[f64], expected: &[f64]) -> Chi2Result {
    assert_eq!(observed.len(), expected.len());
    let (mut stat, mut dof) = (0.0, 0usize);
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for (o, e) in observed.iter().zip(expected) {
        if *e < 5.0 {
            pool_o += o;
            pool_e += e;
        } else {
            stat += (o - e) * (o - e) / e;
            dof += 1;
        }
    }
    if pool_e > 0.0 || pool_o > 0.0 {
        stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e.max(1e-12);
        dof += 1;
    }
    let dof = dof.saturating_sub(1).max(1);
    Chi2Result {
        statistic: stat,
        dof,
        p_value: chi2_p_value(stat, dof),
    }
}

fn adaptive_simpson(f: &impl Fn(f64) -> f64, a: f64, b: f64, eps: f64, depth: u32) -> f64 {
    let (fa, fb) = (f(a), f(b));
    let m = 0.5 * (a + b);
    let fm = f(m);
    let whole = (b - a) / 6.0 * (fa + 4.0 * fm + fb);
    simpson_rec(f, a, b, fa, fm, fb, whole, eps, depth)
}

#[allow(clippy::too_many_arguments)]
fn simpson_rec(
    f: &impl Fn(f64) -> f64,
    a: f64,
    b: f64,
    fa: f64,
    fm: f64,
    fb: f64,
    whole: f64,
    eps: f64,
    depth: u32,
) -> f64 {
    let m = 0.5 * (a + b);
    let (lm, rm) = (0.5 * (a + m), 0.5 * (m + b));
    let (flm, frm) = (f(lm), f(rm));
    let left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
    let right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
    if depth == 0 || (left + right - whole).abs() <= 15.0 * eps {
        return left + right + (left + right - whole) / 15.0;
    }
    simpson_rec(f, a, m, fa, flm, fm, left, eps / 2.0, depth - 1)
        + simpson_rec(f, m, b, fm, frm, fb, right, eps / 2.0, depth - 1)
}
