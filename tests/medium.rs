//! Optics: Principled Volume coefficients as Cycles computes them, and the
//! blackbody colour (Cycles' fit checked against its own table and against
//! Planck's law).

use vdbphoton::medium::blackbody::{blackbody_rgb_cycles, blackbody_rgb_planck};
use vdbphoton::medium::{Material, Principled, Temperature};
use vdbphoton::scene::MaterialDesc;
use vdbphoton::Rgb;

fn principled(f: impl FnOnce(&mut MaterialDesc)) -> Material {
    let mut d = MaterialDesc::PRINCIPLED_DEFAULT;
    f(&mut d);
    Material::from_desc(&d)
}

#[test]
fn principled_defaults_and_absorption_colour() {
    let m = principled(|_| {});
    let p = m.coefficients(2.0, Temperature::Uniform, None, None);
    assert_eq!(p.sigma_s, Rgb::splat(1.0));
    assert_eq!(p.sigma_a, Rgb::splat(1.0));
    assert_eq!(p.emission, Rgb::ZERO);
    // Density 5, colour (0.8, 0.5, 0.2), absorption colour 0.25: σa =
    // D (1 − C)(1 − √A) = 5 (0.2, 0.5, 0.8) · 0.5.
    let m = principled(|d| {
        if let MaterialDesc::Principled(Principled {
            density,
            color,
            absorption_color,
            ..
        }) = d
        {
            *density = 5.0;
            *color = Rgb::new(0.8, 0.5, 0.2);
            *absorption_color = Rgb::splat(0.25);
        }
    });
    let p = m.coefficients(1.0, Temperature::Uniform, None, None);
    assert!((p.sigma_s - Rgb::new(4.0, 2.5, 1.0)).abs().max_element() < 1e-6);
    assert!((p.sigma_a - Rgb::new(0.5, 1.25, 2.0)).abs().max_element() < 1e-6);
    // A white absorption colour absorbs nothing; negative density is 0.
    let m = principled(|d| {
        if let MaterialDesc::Principled(Principled {
            absorption_color, ..
        }) = d
        {
            *absorption_color = Rgb::ONE;
        }
    });
    assert_eq!(
        m.coefficients(3.0, Temperature::Uniform, None, None)
            .sigma_a,
        Rgb::ZERO
    );
    assert_eq!(
        m.coefficients(0.0, Temperature::Uniform, None, None)
            .sigma_s,
        Rgb::ZERO
    );
    // The majorant bound holds for these.
    assert!(m.sigma_t_bound_per_density(None) >= 0.5);
}

#[test]
fn principled_blackbody_emission() {
    // Quick Smoke: Blackbody Intensity 1, Temperature 1000 K × temperature.
    let m = principled(|d| {
        if let MaterialDesc::Principled(Principled {
            density,
            blackbody_intensity,
            ..
        }) = d
        {
            *density = 5.0;
            *blackbody_intensity = 1.0;
        }
    });
    assert!(m.is_emissive());
    let t_attr = 2.5f32;
    let t = 1000.0 * t_attr as f64;
    let p = m.coefficients(0.5, Temperature::Attribute(t_attr), None, None);
    // intensity = σ_SB 1e-6 / π · T⁴, colour = the fit at 2500 K.
    let intensity = 5.670373e-8 * 1e-6 / std::f64::consts::PI * t.powi(4);
    // The fit's segment for 1902 ≤ T < 3315 K, evaluated in f64 here.
    let r = 4.67028036e3 / t + 2.91258199e-5 * t + 1.26703442e-1;
    let g = -1.42529332e3 / t - 4.01150431e-5 * t + 1.43972784;
    let b = ((-1.97075738e-11 * t + 1.75359352e-7) * t - 2.50542825e-4) * t - 2.22783266e-2;
    let want = [r * intensity, g * intensity, b * intensity];
    for (c, w) in want.iter().enumerate() {
        let got = p.emission[c] as f64;
        assert!(
            (got - w).abs() < 1e-4 * w.abs().max(1e-3),
            "channel {c}: {got} vs {w}"
        );
    }
    // No temperature: no emission where T = 0 (blackbody intensity 1).
    assert_eq!(
        m.coefficients(0.5, Temperature::Attribute(0.0), None, None)
            .emission,
        Rgb::ZERO
    );
    // Constant emission only where there is density.
    let e = principled(|d| {
        if let MaterialDesc::Principled(Principled {
            emission_strength,
            emission_color,
            ..
        }) = d
        {
            *emission_strength = 2.0;
            *emission_color = Rgb::new(1.0, 0.5, 0.25);
        }
    });
    assert_eq!(
        e.coefficients(0.3, Temperature::Uniform, None, None)
            .emission,
        Rgb::new(2.0, 1.0, 0.5)
    );
    assert_eq!(
        e.coefficients(0.0, Temperature::Uniform, None, None)
            .emission,
        Rgb::ZERO
    );
}

#[test]
fn cycles_fit_is_continuous_and_matches_planck() {
    // Continuous at the segment boundaries.
    for b in [965.0f32, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0] {
        let (lo, hi) = (blackbody_rgb_cycles(b - 0.01), blackbody_rgb_cycles(b));
        assert!(
            (lo - hi).abs().max_element() < 2e-3,
            "jump at {b} K: {lo} vs {hi}"
        );
    }
    // Against Planck's law through the CIE observer, both normalised to
    // luminance 1: the largest channel difference relative to the largest
    // channel, the visible colour error.
    let worst_in = |lo: f32, hi: f32| {
        let mut worst = 0.0f32;
        let mut t = lo;
        while t <= hi {
            let (c, p) = (blackbody_rgb_cycles(t), blackbody_rgb_planck(t));
            let y = 0.2126 * p.x + 0.7152 * p.y + 0.0722 * p.z;
            assert!((y - 1.0).abs() < 1e-3);
            worst = worst.max((c - p).abs().max_element() / p.max_element());
            t += 25.0;
        }
        worst
    };
    let (low, high) = (worst_in(1000.0, 1999.0), worst_in(2000.0, 12000.0));
    eprintln!(
        "Cycles' blackbody fit vs Planck: worst colour difference {:.2} % (1000-2000 K), {:.2} % (2000-12000 K)",
        low * 100.0,
        high * 100.0
    );
    assert!(high < 0.02, "2000-12000 K: {high}");
    assert!(low < 0.07, "1000-2000 K: {low}");
}
