//! Phase functions: sampling matches the density (χ²), density = value,
//! normalisation, mean cosine, forward means forward, and no NaN at the
//! extremes; for Cycles 5's Fournier–Forand, Draine, Rayleigh and Mie also
//! their published formulas, Backscatter's meaning and Cycles' special
//! cases.

mod common;

use common::chi2::chi2_test;
use glam::{Vec2, Vec3};
use vdbphoton::phase::PhaseFunction;
use vdbphoton::sampling::{Domain, Rng};

const SAMPLES: usize = 400_000;
/// Significance of each test after a Šidák correction for the number of
/// tests in this file (Mitsuba's chi2.py does the same).
const TESTS: f64 = 60.0;
fn alpha() -> f64 {
    1.0 - (1.0 - 0.01f64).powf(1.0 / TESTS)
}

fn cases() -> Vec<(String, PhaseFunction)> {
    let mut v = vec![("isotropic".to_string(), PhaseFunction::Isotropic)];
    for g in [-0.99, -0.7, -0.3, 0.0, 0.3, 0.7, 0.9, 0.99] {
        v.push((format!("hg {g}"), PhaseFunction::hg(g)));
    }
    for g in [-0.9, 0.0, 0.5, 0.95] {
        v.push((format!("schlick g={g}"), PhaseFunction::schlick_from_g(g)));
    }
    v.push((
        "mix 2".into(),
        PhaseFunction::hg_mix(&[(0.8, 0.7), (-0.3, 0.3)]).unwrap(),
    ));
    v.push((
        "mix 3".into(),
        PhaseFunction::hg_mix(&[(0.95, 0.5), (0.2, 0.3), (-0.6, 0.2)]).unwrap(),
    ));
    v.extend(cycles_cases());
    v
}

/// Cycles 5's functions whose densities are bounded (Fournier–Forand's is
/// not: [`ff_cases`]). Draine's α spans Blender's socket (0 to 500) and
/// the Mie fit's 250; Mie's diameters each branch of the fit.
fn cycles_cases() -> Vec<(String, PhaseFunction)> {
    let mut v = vec![("rayleigh".to_string(), PhaseFunction::Rayleigh)];
    for (g, alpha) in [
        (0.0, 0.5),
        (0.005, 3.0),
        (0.5, 0.5),
        (-0.6, 2.0),
        (0.3, 500.0),
        (0.9, 27.0),
        (0.99, 1.0),
    ] {
        v.push((
            format!("draine g={g} alpha={alpha}"),
            PhaseFunction::draine(g, alpha),
        ));
    }
    for d in [0.0, 0.05, 0.5, 2.0, 20.0, 50.0] {
        v.push((format!("mie d={d}"), PhaseFunction::mie(d)));
    }
    v
}

/// Fournier–Forand at Blender's default (B 0.1, IOR 1.33) and across the
/// node's range; IOR 1.8165 puts δ at 90° on 1, where Cycles' B-to-v
/// formula is 0/0. All keep the mass closer than 10⁻⁴⁰ in sin²(θ/2) to
/// straight on (which no quadrature reaches) below 10⁻⁶.
fn ff_cases() -> Vec<(String, PhaseFunction)> {
    [
        (0.1, 1.33),
        (0.01, 1.05),
        (0.02, 1.1),
        (0.3, 1.9),
        (0.45, 1.1),
        (0.2, 1.8165),
        (0.5, 2.0),
    ]
    .into_iter()
    .map(|(b, n)| {
        (
            format!("fournier-forand B={b} n={n}"),
            PhaseFunction::fournier_forand(b, n),
        )
    })
    .collect()
}

/// `wo` = +Z so bins in the test's frame are bins around `wo`; strongly
/// peaked lobes get finer bins in cos θ.
fn run_chi2(name: &str, f: PhaseFunction) -> f64 {
    let wo = Vec3::Z;
    let res_cos = if f.mean_cosine().abs() > 0.8 { 200 } else { 40 };
    let r = chi2_test(
        SAMPLES,
        res_cos,
        24,
        |i| {
            let mut rng = Rng::new(Domain::Test, 7, 1, i as u64);
            f.sample(wo, rng.next_vec2()).map(|s| s.wi)
        },
        |w| f.pdf(wo, w) as f64,
    );
    eprintln!(
        "{name}: chi2 {:.1} dof {} p {:.3e}",
        r.statistic, r.dof, r.p_value
    );
    r.p_value
}

#[test]
fn sampling_matches_pdf_chi2() {
    for (name, f) in cases() {
        let p = run_chi2(&name, f);
        assert!(p > alpha(), "{name}: χ² rejects the sampler (p = {p:.3e})");
    }
}

#[test]
fn chi2_rejects_a_wrong_sampler() {
    // HG sampled with the sign of g flipped, tested against the right pdf.
    let right = PhaseFunction::hg(0.5);
    let wrong = PhaseFunction::hg(-0.5);
    let wo = Vec3::Z;
    let r = chi2_test(
        SAMPLES,
        40,
        24,
        |i| {
            let mut rng = Rng::new(Domain::Test, 7, 2, i as u64);
            wrong.sample(wo, rng.next_vec2()).map(|s| s.wi)
        },
        |w| right.pdf(wo, w) as f64,
    );
    assert!(
        r.p_value < 1e-12,
        "a wrong sampler passed: p = {}",
        r.p_value
    );
    // And a subtler one: g = 0.3 against 0.35.
    let r = chi2_test(
        SAMPLES,
        40,
        24,
        |i| {
            let mut rng = Rng::new(Domain::Test, 7, 3, i as u64);
            PhaseFunction::hg(0.3)
                .sample(wo, rng.next_vec2())
                .map(|s| s.wi)
        },
        |w| PhaseFunction::hg(0.35).pdf(wo, w) as f64,
    );
    assert!(
        r.p_value < alpha(),
        "g = 0.3 passed as 0.35: p = {}",
        r.p_value
    );
}

/// ∫ f(cos) dω by Simpson in cos θ with a fine grid near the peaks.
fn integrate(f: impl Fn(f64) -> f64) -> f64 {
    // Substitution cos = -1 + 2 s^4 and cos = 1 - 2 s^4 resolve the lobes at
    // ±1; split at 0.
    let n = 4000;
    let mut total = 0.0;
    for side in [-1.0f64, 1.0] {
        let mut sum = 0.0;
        for i in 0..=n {
            let s = i as f64 / n as f64;
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            // cos from side (s = 0) to 0 (s = 1): cos = side (1 - s^4).
            let cos = side * (1.0 - s.powi(4));
            let dcos = 4.0 * s.powi(3);
            sum += w * f(cos) * dcos;
        }
        total += sum / (3.0 * n as f64);
    }
    2.0 * std::f64::consts::PI * total
}

#[test]
fn pdf_equals_eval_and_integrates_to_one() {
    let wo = Vec3::new(0.3, -0.5, 0.81).normalize();
    for (name, f) in cases() {
        let mut rng = Rng::new(Domain::Test, 1, 2, 3);
        for _ in 0..1000 {
            let wi = vdbphoton::sampling::sample_uniform_sphere(rng.next_vec2());
            assert_eq!(f.pdf(wo, wi), f.eval(wo, wi), "{name}");
        }
        // Integrate in the frame of wo: the value depends on cos only.
        let integral = integrate(|c| {
            let s = (1.0 - c * c).max(0.0).sqrt() as f32;
            let (t, _) = vdbphoton::sampling::coordinate_system(wo);
            f.eval(wo, wo * c as f32 + t * s) as f64
        });
        assert!((integral - 1.0).abs() < 1e-3, "{name}: ∫p = {integral}");
    }
}

#[test]
fn mean_cosine_is_g() {
    // The mean cosine between the old direction of travel (−wi... for a
    // camera path, travel is −wo before and ... ) — measured as the mean of
    // −dot(wo, wi), which is the cosine between the incoming light's
    // direction of travel (−wi) and its outgoing one (wo).
    let wo = Vec3::new(-0.2, 0.7, 0.3).normalize();
    for (name, f) in cases() {
        let m = integrate(|c| {
            let s = (1.0 - c * c).max(0.0).sqrt() as f32;
            let (t, _) = vdbphoton::sampling::coordinate_system(wo);
            -c * f.eval(wo, wo * c as f32 + t * s) as f64
        });
        assert!(
            (m - f.mean_cosine() as f64).abs() < 2e-3,
            "{name}: measured mean cosine {m}, mean_cosine() {}",
            f.mean_cosine()
        );
        if let PhaseFunction::HenyeyGreenstein { g } = f {
            assert!(
                (m - g as f64).abs() < 2e-3,
                "{name}: mean cosine {m} vs g {g}"
            );
        }
    }
}

#[test]
fn positive_g_scatters_forward() {
    let f = PhaseFunction::hg(0.8);
    let d = Vec3::new(0.0, 0.6, 0.8); // direction of travel
    let mut forward = 0;
    let n = 10_000;
    for i in 0..n {
        let mut rng = Rng::new(Domain::Test, 3, 3, i);
        let (new_dir, _) = f.sample_travel(d, rng.next_vec2()).unwrap();
        if new_dir.dot(d) > 0.0 {
            forward += 1;
        }
        // In the wo/wi convention: wi = -d, wo = new direction.
        let s = f.sample(-new_dir, rng.next_vec2()).unwrap();
        assert!(s.p > 0.0);
    }
    assert!(forward > 9 * n / 10, "{forward} of {n} went forward");
    // The value is largest when light keeps going: wo = d, wi = -d.
    assert!(f.eval(d, -d) > 10.0 * f.eval(d, d));
}

#[test]
fn extremes_give_finite_values() {
    let dirs = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    for g in [-1.0, 1.0, -0.999_9, 0.999_9] {
        for f in [
            PhaseFunction::hg(g),
            PhaseFunction::schlick_from_g(g),
            PhaseFunction::hg_mix(&[(g, 1.0)]).unwrap(),
        ] {
            for wo in dirs {
                for u in [Vec2::ZERO, Vec2::splat(0.5), Vec2::splat(0.999_999_9)] {
                    let s = f.sample(wo, u).expect("no sample");
                    assert!(
                        s.wi.is_finite() && (s.wi.length() - 1.0).abs() < 1e-4,
                        "{f:?} {wo} {u}: {:?}",
                        s.wi
                    );
                    assert!(
                        s.p.is_finite() && s.p > 0.0 && s.pdf == s.p,
                        "{f:?}: {}",
                        s.p
                    );
                }
                for wi in dirs {
                    assert!(f.eval(wo, wi).is_finite());
                }
            }
        }
    }
}

/// Blurring a phase function over directions by an HG kernel of mean
/// cosine s (the photon estimate's angular kernel) is HG(g·s), lobe by
/// lobe: checked against the convolution ∫ p(wo, w) K_s(w, wi) dw by
/// quadrature, the kernel peaking at w = wi. A blur by s² (0.365 against
/// 0.714), or lobes 0.05 off (0.260 against 0.303), fails by far more
/// than the 2·10⁻³ allowed.
#[test]
fn blurring_by_an_hg_kernel_multiplies_g() {
    use vdbphoton::sampling::coordinate_system;
    let kernel = |s: f32| move |w: Vec3, wi: Vec3| PhaseFunction::hg(s).eval(-w, wi) as f64;
    // ∫ over the sphere, polar axis `pole` (where the sharper lobe is),
    // cos θ finely resolved near it.
    let convolve = |f: &PhaseFunction, s: f32, wo: Vec3, wi: Vec3| {
        let pole = -wo;
        let (t, b) = coordinate_system(pole);
        let k = kernel(s);
        let phis = 720;
        integrate(|c| {
            let sin = (1.0 - c * c).max(0.0).sqrt();
            let mut sum = 0.0;
            for j in 0..phis {
                let phi = (j as f64 + 0.5) / phis as f64 * std::f64::consts::TAU;
                let w =
                    (pole * c as f32 + t * (sin * phi.cos()) as f32 + b * (sin * phi.sin()) as f32)
                        .normalize();
                sum += f.eval(wo, w) as f64 * k(w, wi);
            }
            // integrate() takes ∫ dω of a function of cos alone: 2π × the
            // mean over φ.
            sum / phis as f64
        })
    };
    let blurs = [
        ("hg 0.8", PhaseFunction::hg(0.8), 0.75),
        ("hg -0.5", PhaseFunction::hg(-0.5), 0.5),
        (
            "mix",
            PhaseFunction::hg_mix(&[(0.8, 0.7), (-0.3, 0.3)]).unwrap(),
            0.6,
        ),
    ];
    let wo = Vec3::new(0.2, -0.4, 0.89).normalize();
    for (name, f, s) in blurs {
        let blurred = f.blurred(s);
        for cos in [-0.99f32, -0.8, -0.3, 0.0, 0.5, 0.95] {
            let (t, _) = coordinate_system(wo);
            let wi = (wo * cos + t * (1.0 - cos * cos).sqrt()).normalize();
            let want = convolve(&f, s, wo, wi);
            let got = blurred.eval(wo, wi) as f64;
            assert!(
                (got - want).abs() < 2e-3 * want.max(0.05),
                "{name}, s = {s}, cos {cos}: blurred {got}, convolution {want}"
            );
        }
    }
    // No blur, and functions without a closed form, stay as they are.
    for (name, f) in cases() {
        let same = f.blurred(1.0);
        assert_eq!(same, f, "{name}");
    }
    let schlick = PhaseFunction::schlick_from_g(0.7);
    assert_eq!(schlick.blurred(0.5), schlick);
    assert_eq!(
        PhaseFunction::Isotropic.blurred(0.5),
        PhaseFunction::Isotropic
    );
}

// ---------------------------------------------------------------------------
// Cycles 5's phase functions. Their densities are functions of
// s = sin²(θ/2), θ between the old and new directions of travel; with
// wo = +Z, straight on is wi = −Z. Fournier–Forand's density is singular
// there, so these tests integrate over ln s instead of cos θ.

/// The direction `wi` at sin²(θ/2) = `s` from straight on, for wo = +Z.
fn wi_at(s: f64) -> Vec3 {
    Vec3::new(
        (2.0 * (s * (1.0 - s)).sqrt()) as f32,
        0.0,
        -(1.0 - 2.0 * s) as f32,
    )
}

/// The density at sin²(θ/2) = `s`, through `eval`.
fn density(f: &PhaseFunction, s: f64) -> f64 {
    f.eval(Vec3::Z, wi_at(s)) as f64
}

/// ∫ₐᵇ h(s) ds by Simpson's rule in z = ln s (a > 0), `n` intervals.
fn integral_ln(h: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let (za, zb) = (a.ln(), b.ln());
    let dz = (zb - za) / n as f64;
    let mut sum = 0.0;
    for i in 0..=n {
        let z = za + dz * i as f64;
        let w = if i == 0 || i == n {
            1.0
        } else if i % 2 == 1 {
            4.0
        } else {
            2.0
        };
        sum += w * h(z.exp()) * z.exp();
    }
    sum * dz / 3.0
}

/// Where these quadratures start: closer to straight on than this, f32
/// directions cannot go (`ff_cases` keep their mass there negligible).
const S_FLOOR: f64 = 1e-40;

/// ∫ h(θ)·p dω over the sphere: 4π ∫₀¹ h(s)·p(s) ds.
fn sphere_integral(f: &PhaseFunction, h: impl Fn(f64) -> f64) -> f64 {
    4.0 * std::f64::consts::PI * integral_ln(|s| h(s) * density(f, s), S_FLOOR, 1.0, 40_000)
}

/// χ² of `f`'s samples in bins of s (by decades from 10⁻¹² to 10⁻², then
/// steps of 0.01) and of φ, against the density's integral over each bin
/// in ln s: resolves a forward peak, singular (Fournier–Forand) or as
/// sharp as HG's at g = 0.999, which the (cos θ, φ) harness's bins of
/// equal cos θ cannot.
fn zonal_chi2(name: &str, f: PhaseFunction, stream: u64) -> f64 {
    let wo = Vec3::Z;
    let mut edges = vec![0.0f64];
    for e in -12..-2 {
        edges.push(10f64.powi(e));
        edges.push(3.0 * 10f64.powi(e));
    }
    edges.extend((1..=100).map(|i| i as f64 / 100.0));
    let (bins, res_phi) = (edges.len() - 1, 6);
    let mut observed = vec![0.0f64; bins * res_phi];
    for i in 0..SAMPLES {
        let mut rng = Rng::new(Domain::Test, 11, stream, i as u64);
        let Some(smp) = f.sample(wo, rng.next_vec2()) else {
            continue;
        };
        let w = smp.wi;
        let s = ((wo + w).length_squared() as f64 * 0.25).min(1.0);
        let bin = edges.partition_point(|&e| e <= s).clamp(1, bins) - 1;
        let phi = (w.y as f64)
            .atan2(w.x as f64)
            .rem_euclid(std::f64::consts::TAU);
        let pb = ((phi / std::f64::consts::TAU * res_phi as f64) as usize).min(res_phi - 1);
        observed[bin * res_phi + pb] += 1.0;
    }
    let mut expected = vec![0.0f64; bins * res_phi];
    for b in 0..bins {
        let lo = edges[b].max(S_FLOOR);
        let mass =
            4.0 * std::f64::consts::PI * integral_ln(|s| density(&f, s), lo, edges[b + 1], 400);
        for pb in 0..res_phi {
            expected[b * res_phi + pb] = mass * SAMPLES as f64 / res_phi as f64;
        }
    }
    let r = common::chi2::chi2_counts(&observed, &expected);
    eprintln!(
        "{name} (zonal): chi2 {:.1} dof {} p {:.3e}",
        r.statistic, r.dof, r.p_value
    );
    r.p_value
}

/// Every sampler of Cycles' functions against its own density, in bins
/// fine near straight on. Checked to fail with: Fournier–Forand's
/// (3cos²θ − 1) term weighted 2c₃ instead of c₃/2 in the density (every
/// case, p ≤ 10⁻⁸³), its sampler mirrored (s → 1 − s), its density over
/// 2π, its density mirrored; Draine sampled as HG (its second moment left
/// out of the CDF), its density mirrored (μ → −μ) or normalised by
/// 1 + α/3; Mie's lobe choice swapped (HG below w_D); Rayleigh's density
/// 1 + cos²θ over 4π.
#[test]
fn cycles_samplers_match_their_densities_zonal_chi2() {
    let mut failed = vec![];
    for (i, (name, f)) in ff_cases().into_iter().chain(cycles_cases()).enumerate() {
        let p = zonal_chi2(&name, f, i as u64);
        if p <= alpha() {
            failed.push(format!("{name}: p = {p:.3e}"));
        }
    }
    assert!(failed.is_empty(), "χ² rejects: {failed:?}");
}

/// ∫ p dω = 1 for Fournier–Forand (by quadrature in ln s: its peak is
/// singular), and `pdf` = `eval` = the value a sample reports. Checked to
/// fail with the density over 2π instead of 4π (∫ = 2), v from ln δ₁₈₀
/// instead of ln δ₉₀ or with its sign flipped (v > 0 or c > 1 at some
/// inputs: ∫ = −∞), and the density mirrored.
#[test]
fn fournier_forand_integrates_to_one_and_pdf_is_eval() {
    let wo = Vec3::new(0.3, -0.5, 0.81).normalize();
    for (name, f) in ff_cases() {
        let integral = sphere_integral(&f, |_| 1.0);
        assert!((integral - 1.0).abs() < 1e-4, "{name}: ∫p = {integral}");
        for i in 0..1000 {
            let mut rng = Rng::new(Domain::Test, 4, 5, i);
            let wi = vdbphoton::sampling::sample_uniform_sphere(rng.next_vec2());
            assert_eq!(f.pdf(wo, wi), f.eval(wo, wi), "{name}");
            let s = f.sample(wo, rng.next_vec2()).unwrap();
            assert_eq!(s.p, f.eval(wo, s.wi), "{name}");
            assert_eq!(s.pdf, f.pdf(wo, s.wi), "{name}");
        }
    }
}

/// Backscatter is the fraction of the light scattered by more than 90°
/// (Fournier & Forand's b_b/b, which Cycles inverts for v): 4π∫ₛ₌½¹ p ds
/// = B, also at B = 0.5 (clamped to 0.499 as Cycles does) and IOR 1.8165
/// (δ₉₀ = 1). Checked to fail with the lobe mirrored (μ for −μ: the
/// fraction is 1 − B), v from ln δ₁₈₀ instead of ln δ₉₀, v's sign
/// flipped, and the density over 2π.
#[test]
fn fournier_forand_backscatter_is_the_fraction_beyond_90_degrees() {
    for b in [0.0001f32, 0.01, 0.1, 0.25, 0.45, 0.5] {
        for n in [1.01f32, 1.1, 1.33, 1.5, 1.8165, 2.0] {
            let f = PhaseFunction::fournier_forand(b, n);
            let back = 4.0 * std::f64::consts::PI * integral_ln(|s| density(&f, s), 0.5, 1.0, 2000);
            let want = b.min(0.499) as f64;
            assert!(
                (back - want).abs() < 1e-5 + 1e-4 * want,
                "B = {b}, n = {n}: {back} scattered backwards"
            );
        }
    }
}

/// Fournier & Forand's function as Fournier & Jonasz 1999 print it (and
/// Mobley, Sundman & Boss 2002, "Phase function effects on oceanic light
/// fields", eq. 6), with v from B as Cycles finds it, evaluated plainly
/// in f64 away from δ = 1 (where it is 0/0): `eval` agrees to 10⁻⁵.
/// Checked to fail with the (3cos²θ − 1) term weighted 2c₃ (a wrong
/// weight that ∫p = 1 and Backscatter cannot see: the term integrates to
/// 0 over each hemisphere), the lobe mirrored, the density over 2π, and v
/// from ln δ₁₈₀ or with its sign flipped.
#[test]
fn fournier_forand_is_the_published_formula() {
    use std::f64::consts::PI;
    for (b, n) in [
        (0.1f64, 1.33f64),
        (0.01, 1.05),
        (0.3, 1.9),
        (0.45, 1.1),
        (0.05, 1.2),
    ] {
        let f = PhaseFunction::fournier_forand(b as f32, n as f32);
        let (b, n) = (b as f32 as f64, n as f32 as f64);
        let delta = |s: f64| 4.0 * s / (3.0 * (n - 1.0) * (n - 1.0));
        let d90 = delta(0.5);
        let v = -(1.0 + 2.0 * b * (d90 - 1.0)).ln() / d90.ln();
        let d180 = delta(1.0);
        for deg in [
            0.01f64, 0.1, 1.0, 5.0, 20.0, 45.0, 90.0, 120.0, 170.0, 179.9,
        ] {
            let theta = deg.to_radians();
            let s = (0.5 * theta).sin().powi(2);
            let d = delta(s);
            if (1.0 - d).abs() < 1e-2 {
                continue;
            }
            let dv = d.powf(v);
            let want = (v * (1.0 - d) - (1.0 - dv) + (d * (1.0 - dv) - v * (1.0 - d)) / s)
                / (4.0 * PI * (1.0 - d).powi(2) * dv)
                + (1.0 - d180.powf(v)) / (16.0 * PI * (d180 - 1.0) * d180.powf(v))
                    * (3.0 * theta.cos().powi(2) - 1.0);
            let got = density(&f, s);
            assert!(
                (got / want - 1.0).abs() < 1e-5,
                "B = {b}, n = {n}, θ = {deg}°: eval {got}, formula {want}"
            );
        }
    }
}

/// Draine's density is its formula (Draine 2003, eq. 4; Cycles'
/// `phase_draine`) and Cycles' special cases hold: α = 0 is HG, g = 0 with
/// α > 0.999 is Rayleigh (also α = 250: Cycles' switch, which Mie's
/// smallest droplets reach), g clamped to ±0.999. Checked to fail with
/// Draine's normalisation 1 + α/3 (without 2g²), with μ for −μ, and with
/// Rayleigh's 3/(16π) as 1/(4π).
#[test]
fn draine_is_its_formula_with_cycles_special_cases() {
    use std::f64::consts::PI;
    let hg = |mu: f64, g: f64| (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5));
    for (g, a) in [
        (0.5f64, 0.5f64),
        (-0.6, 2.0),
        (0.9, 27.0),
        (0.3, 500.0),
        (0.0, 0.5),
    ] {
        let f = PhaseFunction::draine(g as f32, a as f32);
        for i in 0..=20 {
            let s = i as f64 / 20.0;
            let mu = 1.0 - 2.0 * s;
            let want = hg(mu, g) * (1.0 + a * mu * mu) / (1.0 + a * (1.0 + 2.0 * g * g) / 3.0);
            let got = density(&f, s);
            assert!(
                (got / want - 1.0).abs() < 1e-5,
                "g {g}, α {a}, μ {mu}: {got} vs {want}"
            );
        }
    }
    let rayleigh = |s: f64| density(&PhaseFunction::Rayleigh, s);
    for i in 0..=20 {
        let s = i as f64 / 20.0;
        let mu = 1.0 - 2.0 * s;
        let r = 3.0 / (16.0 * PI) * (1.0 + mu * mu);
        assert!((rayleigh(s) / r - 1.0).abs() < 1e-6);
        for a in [1.0f32, 250.0] {
            let d = density(&PhaseFunction::draine(0.0, a), s);
            assert!(
                (d / r - 1.0).abs() < 1e-6,
                "Draine(0, {a}) is Rayleigh in Cycles"
            );
        }
        let d = density(&PhaseFunction::draine(0.4, 0.0), s);
        assert!((d / hg(mu, 0.4) - 1.0).abs() < 1e-5, "Draine(g, 0) is HG");
    }
    assert_eq!(
        PhaseFunction::draine(1.5, 1.0),
        PhaseFunction::draine(0.999, 1.0)
    );
    assert_eq!(
        PhaseFunction::draine(0.2, 0.0005),
        PhaseFunction::draine(0.2, 0.0)
    );
}

/// The Mie fit's parameters as Cycles' `phase_mie_fitted_parameters`
/// computes them, at a diameter in each branch (values from the formulas
/// in f64), within their ranges over Blender's 0 to 50 µm, and the lobes'
/// mixture as Cycles allocates them: (1 − w_D)·HG + w_D·Draine. Checked
/// to fail with the weights swapped (1 − w_D for Draine) and with the
/// 5–50 µm branch's g_HG from d + 1.67154.
#[test]
fn mie_is_cycles_fit() {
    use vdbphoton::phase::mie_fit;
    for (d, want) in [
        (0.05f32, [0.0345f32, 0.025_661_2, 250.0, 0.252_181]),
        (0.5, [0.793_295, 0.718_333, 250.0, 0.404_244]),
        (2.0, [0.918_084, 0.387_49, 11.3792, 0.411_993]),
        (20.0, [0.994_61, 0.593_791, 27.1137, 0.498_159]),
        (50.0, [0.997_952, 0.625_084, 32.3154, 0.507_618]),
    ] {
        let m = mie_fit(d);
        let got = [m.g_hg, m.g_d, m.alpha, m.w_d];
        for (g, w) in got.iter().zip(want) {
            assert!((g / w - 1.0).abs() < 1e-4, "d = {d}: {got:?} vs {want:?}");
        }
    }
    for i in 0..=5000 {
        let d = i as f32 * 0.01;
        let m = mie_fit(d);
        assert!(
            (0.0..1.0).contains(&m.g_hg)
                && m.g_d.abs() < 1.0
                && m.alpha > 0.0
                && (0.0..=1.0).contains(&m.w_d),
            "d = {d}: {m:?}"
        );
    }
    assert_eq!(mie_fit(-3.0), mie_fit(0.0));
    let f = PhaseFunction::mie(20.0);
    let m = mie_fit(20.0);
    let dr = PhaseFunction::draine(m.g_d, m.alpha);
    let g = m.g_hg as f64;
    for i in 0..=20 {
        let s = i as f64 / 20.0;
        let hg = (1.0 - g * g)
            / (4.0 * std::f64::consts::PI * (1.0 + g * g - 2.0 * g * (1.0 - 2.0 * s)).powf(1.5));
        let want = (1.0 - m.w_d as f64) * hg + m.w_d as f64 * density(&dr, s);
        assert!((density(&f, s) / want - 1.0).abs() < 1e-5, "s = {s}");
    }
}

/// Mean cosines against quadrature of the density, and against their
/// closed forms: Rayleigh's 0, Draine's g(1 + α(3 + 2g²)/5)/(1 + α(1 +
/// 2g²)/3) (HG's g at α = 0), Mie's mixture of its lobes'. Fournier–
/// Forand's is a quadrature of its CDF, here checked against one of its
/// density. Checked to fail with Draine's 3 + 2g² as 3 + g², Fournier–
/// Forand's mean cosine from 1 − 2∫F ds (the sign of the lobe), the Mie
/// weights swapped, and each density mirrored or mis-normalised (Draine
/// by 1 + α/3, Fournier–Forand over 2π).
#[test]
fn cycles_mean_cosines() {
    for (name, f) in ff_cases().into_iter().chain(cycles_cases()) {
        let m = sphere_integral(&f, |s| 1.0 - 2.0 * s);
        assert!(
            (m - f.mean_cosine() as f64).abs() < 1e-4,
            "{name}: quadrature {m}, mean_cosine() {}",
            f.mean_cosine()
        );
    }
    assert_eq!(PhaseFunction::Rayleigh.mean_cosine(), 0.0);
    for (g, a) in [(0.5f32, 0.5f32), (-0.6, 2.0), (0.9, 27.0), (0.3, 500.0)] {
        let (g64, a64) = (g as f64, a as f64);
        let want = g64 * (1.0 + a64 * (3.0 + 2.0 * g64 * g64) / 5.0)
            / (1.0 + a64 * (1.0 + 2.0 * g64 * g64) / 3.0);
        let got = PhaseFunction::draine(g, a).mean_cosine() as f64;
        assert!((got - want).abs() < 1e-6, "draine {g} {a}: {got} vs {want}");
    }
    assert!((PhaseFunction::draine(0.7, 0.0).mean_cosine() - 0.7).abs() < 1e-6);
    let m = vdbphoton::phase::mie_fit(20.0);
    let want = (1.0 - m.w_d) * m.g_hg + m.w_d * PhaseFunction::draine(m.g_d, m.alpha).mean_cosine();
    assert!((PhaseFunction::mie(20.0).mean_cosine() - want).abs() < 1e-6);
}

/// g > 0 (Draine, Mie) and Fournier–Forand scatter along the direction of
/// travel, as Cycles' do (its μ = dot(−sd->wi, wo) = 1 is straight on),
/// and Draine's g < 0 backwards: photons keep going (sample_travel), and
/// the value is larger for light that keeps going. Checked to fail with
/// Fournier–Forand's and Draine's densities mirrored (at −μ),
/// Fournier–Forand's sampler mirrored, v's sign flipped, and Fournier–
/// Forand's mean cosine of the wrong sign.
#[test]
fn cycles_lobes_scatter_forward_for_positive_g() {
    let d = Vec3::new(0.0, 0.6, 0.8);
    for (name, f, forward) in [
        ("ff", PhaseFunction::fournier_forand(0.1, 1.33), true),
        ("draine 0.8", PhaseFunction::draine(0.8, 0.5), true),
        ("draine -0.7", PhaseFunction::draine(-0.7, 2.0), false),
        ("mie 20", PhaseFunction::mie(20.0), true),
        ("mie 0.5", PhaseFunction::mie(0.5), true),
    ] {
        let n = 10_000;
        let ahead = (0..n)
            .filter(|&i| {
                let mut rng = Rng::new(Domain::Test, 3, 9, i);
                f.sample_travel(d, rng.next_vec2()).unwrap().0.dot(d) > 0.0
            })
            .count();
        let want = (1.0 + f.mean_cosine()) / 2.0;
        assert_eq!(
            ahead > n as usize / 2,
            forward,
            "{name}: {ahead} of {n} went on"
        );
        assert_eq!(f.mean_cosine() > 0.0, forward, "{name}");
        // The fraction ahead is not far from (1 + ⟨μ⟩)/2 for these lobes.
        assert!(
            (ahead as f32 / n as f32 - want).abs() < 0.25,
            "{name}: {ahead}, mean cosine {}",
            f.mean_cosine()
        );
        assert_eq!(f.eval(d, -d) > f.eval(d, d), forward, "{name}");
    }
}

/// No NaN, no zero, unit directions, and p = pdf = eval on the sample
/// at and beyond the ends of every input's range: Backscatter 0 (below
/// Cycles' own degenerate 0: see FournierForand's B_MIN) to beyond 0.5,
/// IOR 1 to 5, g ±1, α 0 to 10⁹, diameters 0 to 10³ µm and negative, NaN
/// inputs; u at 0 and just below 1. Checked to fail without the lower
/// clamp on B (B = 0: the density is 0 everywhere, no sample) and with
/// Draine's |g| clamped to 1 instead of 0.999 (a density of 0).
#[test]
fn cycles_extremes_give_finite_values() {
    let mut fs = vec![PhaseFunction::Rayleigh];
    for b in [0.0f32, 1e-9, 1e-5, 0.499, 0.5, 1.0, -0.3, f32::NAN] {
        for n in [1.0f32, 1.000_1, 1.8165, 2.0, 5.0, f32::NAN] {
            fs.push(PhaseFunction::fournier_forand(b, n));
        }
    }
    for g in [-1.0f32, -0.999_9, 0.0, 1e-4, 0.999_9, 1.0, f32::NAN] {
        for a in [0.0f32, 1e-4, 0.999, 1.0, 500.0, 1e9, -2.0, f32::NAN] {
            fs.push(PhaseFunction::draine(g, a));
        }
    }
    for d in [
        0.0f32,
        1e-3,
        0.1,
        0.100_01,
        1.5,
        4.81,
        5.0,
        50.0,
        1000.0,
        -1.0,
        f32::NAN,
    ] {
        fs.push(PhaseFunction::mie(d));
    }
    let dirs = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    for f in fs {
        assert!(f.mean_cosine().is_finite(), "{f:?}");
        for wo in dirs {
            for u in [
                Vec2::ZERO,
                Vec2::splat(0.5),
                Vec2::new(1e-7, 0.3),
                Vec2::splat(0.999_999_9),
            ] {
                let s = f.sample(wo, u).expect("no sample");
                assert!(
                    s.wi.is_finite() && (s.wi.length() - 1.0).abs() < 1e-4,
                    "{f:?} {wo} {u}: {:?}",
                    s.wi
                );
                assert!(
                    s.p.is_finite() && s.p > 0.0 && s.pdf == s.p && s.p == f.eval(wo, s.wi),
                    "{f:?} {u}: {}",
                    s.p
                );
            }
            for wi in dirs {
                let p = f.eval(wo, wi);
                assert!(p.is_finite() && p >= 0.0, "{f:?}: {p}");
            }
        }
    }
}

/// Blurring (the photon gather's angular kernel) as `blurred` documents
/// it: Rayleigh exactly (against the convolution, in
/// `blurring_by_an_hg_kernel_multiplies_g`'s quadrature), Mie's HG lobe
/// HG(g·s) with its Draine lobe unchanged, Draine and Fournier–Forand
/// unchanged. Checked to fail with Rayleigh's α = 3s/(4 − s), Mie's
/// Draine weight dropped, and the Mie weights swapped.
#[test]
fn cycles_functions_blurred() {
    let s = 0.6f32;
    let blurred = PhaseFunction::Rayleigh.blurred(s);
    let kernel = PhaseFunction::hg(s);
    let wo = Vec3::new(0.2, -0.4, 0.89).normalize();
    let (t, b) = vdbphoton::sampling::coordinate_system(wo);
    for cos in [-0.99f32, -0.5, 0.0, 0.4, 0.95] {
        let wi = (wo * cos + t * (1.0 - cos * cos).sqrt()).normalize();
        // ∫ p(wo, w) K(w, wi) dw, the kernel peaking at w = wi.
        let (tw, bw) = vdbphoton::sampling::coordinate_system(wi);
        let n = 600;
        let mut sum = 0.0f64;
        for i in 0..n {
            let c = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
            let sn = (1.0 - c * c).sqrt();
            for j in 0..48 {
                let phi = (j as f64 + 0.5) / 48.0 * std::f64::consts::TAU;
                let w =
                    (wi * c as f32 + tw * (sn * phi.cos()) as f32 + bw * (sn * phi.sin()) as f32)
                        .normalize();
                sum += PhaseFunction::Rayleigh.eval(wo, w) as f64 * kernel.eval(-w, wi) as f64;
            }
        }
        let want = sum * 4.0 * std::f64::consts::PI / (n * 48) as f64;
        let got = blurred.eval(wo, wi) as f64;
        assert!(
            (got / want - 1.0).abs() < 2e-3,
            "cos {cos}: blurred {got}, convolution {want}"
        );
        let _ = b;
    }
    let mie = PhaseFunction::mie(20.0);
    let m = vdbphoton::phase::mie_fit(20.0);
    let want = |wo: Vec3, wi: Vec3| {
        (1.0 - m.w_d) * PhaseFunction::hg(m.g_hg * s).eval(wo, wi)
            + m.w_d * PhaseFunction::draine(m.g_d, m.alpha).eval(wo, wi)
    };
    for cos in [-0.99f32, -0.5, 0.0, 0.9] {
        let wi = (wo * cos + t * (1.0 - cos * cos).sqrt()).normalize();
        let (got, want) = (mie.blurred(s).eval(wo, wi), want(wo, wi));
        assert!((got / want - 1.0).abs() < 1e-5, "mie: {got} vs {want}");
    }
    for f in [
        PhaseFunction::draine(0.7, 3.0),
        PhaseFunction::fournier_forand(0.1, 1.33),
    ] {
        assert_eq!(f.blurred(s), f);
    }
}
