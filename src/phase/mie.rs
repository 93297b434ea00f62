//! Cycles' Mie phase function for water droplets: a mixture of a
//! Henyey–Greenstein and a Draine lobe fitted to Lorenz–Mie theory as a
//! function of the droplet diameter d (µm), by Jendersie & d'Eon 2023, "An
//! Approximate Mie Scattering Function for Fog and Cloud Rendering"
//! (SIGGRAPH 2023 Talks; the fits are in its supplemental document).
//!
//! p = (1 − w_D)·HG(g_HG) + w_D·Draine(g_D, α).
//!
//! Cycles 5.0 (`kernel/closure/volume_util.h`,
//! `phase_mie_fitted_parameters`; `kernel/svm/closure.h`,
//! `svm_alloc_closure_volume_scatter`, case `CLOSURE_VOLUME_MIE_ID`)
//! clamps d to ≥ 0 only (Blender's Diameter socket offers 0 to 50; the
//! last fit runs on past 50) and allocates the two lobes as two closures
//! weighted 1 − w_D and w_D, each set up (and clamped) as the node's own
//! HG and Draine closures are; a path picks one by weight and evaluates
//! their weighted sum, which is this mixture, sampled exactly.

/// The fitted lobes for droplets of diameter `d` µm, as Cycles computes them
/// (the paper's equations as numbered in Cycles' comments).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MieFit {
    pub g_hg: f32,
    pub g_d: f32,
    pub alpha: f32,
    pub w_d: f32,
}

pub fn mie_fit(d: f32) -> MieFit {
    let d = if d.is_nan() { 0.0 } else { d.max(0.0) as f64 };
    let (g_hg, g_d, alpha, w_d) = if d <= 0.1 {
        // Eqs. 11–14: tiny droplets, nearly Rayleigh.
        (
            13.8 * d * d,
            1.1456 * d * (9.29044 * d).sin(),
            250.0,
            0.252977 - 312.983 * d.powf(4.3),
        )
    } else if d < 1.5 {
        // Eqs. 15–18.
        let ln_d = d.ln();
        let a = (ln_d - 0.238604) * (ln_d + 1.00667);
        let b = 0.507522 - 0.15677 * ln_d;
        let c = 1.19692 * (a / b).cos() + 1.37932 * ln_d + 0.0625835;
        (
            0.862 - 0.143 * ln_d * ln_d,
            0.379685 * c.cos() + 0.344213,
            250.0,
            0.146209 * (3.38707 * ln_d + 2.11193).cos() + 0.316072 + 0.0778917 * ln_d,
        )
    } else if d < 5.0 {
        // Eqs. 19–22.
        let ln_d = d.ln();
        let ln_ln_d = ln_d.ln();
        (
            0.0604931 * ln_ln_d + 0.940256,
            0.500411 - 0.081287 / (-2.0 * ln_d + ln_d.tan() + 1.27551),
            7.30354 * ln_d + 6.31675,
            0.026914 * (ln_d - (5.68947 * (ln_ln_d - 0.0292149)).cos()) + 0.3764,
        )
    } else {
        // Eqs. 7–10: cloud and fog droplets, 5 to 50 µm.
        (
            (-0.0990567 / (d - 1.67154)).exp(),
            (-2.20679 / (d + 3.91029) - 0.428934).exp(),
            (3.62489 - 8.29288 / (d + 5.52825)).exp(),
            (-0.599085 / (d - 0.641583) - 0.665888).exp(),
        )
    };
    MieFit {
        g_hg: g_hg as f32,
        g_d: g_d as f32,
        alpha: alpha as f32,
        w_d: w_d as f32,
    }
}
