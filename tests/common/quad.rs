//! Quadrature over the directions a GGX lobe reflects into, for the BSDF
//! tests and the albedo tables' generator (`tests/bsdf_tables.rs`):
//! deterministic, in f64, accurate however narrow the lobe and however
//! grazing the viewer.
//!
//! The integral over wi runs over the half vectors h, wi = 2(wo·h)h − wo,
//! dωi = 4 (wo·h) dωh, in coordinates (t, φ) with the half vector's polar
//! angle at tan θh = α tan(πt/2). There the projected GGX distribution is
//! D(h) cos θh dωh = sin(πt)/4 dt dφ at every α (with T = tan(πt/2):
//! D = 1/(π α² cos⁴θh (1 + T²)²) and dθh = α (π/2) (1 + T²) cos²θh dt),
//! so a lobe of that α is smooth in (t, φ). Along t the horizon's cut
//! (wi.z = 0, and wo·h = 0) is located by bisection and the valid pieces
//! integrated by Gauss–Legendre, graded towards the cut where G₂ falls to
//! 0 within a width of about μ; along φ by Gauss–Legendre over the half
//! circle (the integrand must be even in φ), graded from both sides
//! towards φ = π/2, where a grazing viewer's visible normals change within
//! a width of μ (past π/2 the normals facing wo shrink to a cone of
//! tan θh ≈ μ/|cos φ|; before it their mirror directions fall below the
//! horizon from θh ≈ 45° on). Without the grading a uniform rule
//! resolves those features only to O(μ).
#![allow(dead_code)]

use glam::DVec3;
use std::f64::consts::PI;

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_n).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-15 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// GGX's D at a unit half vector.
pub fn ggx_d(alpha: f64, h: DVec3) -> f64 {
    let a2 = alpha * alpha;
    let s2 = h.x * h.x + h.y * h.y;
    let den = s2 + a2 * h.z * h.z;
    a2 / (PI * den * den)
}

/// Smith's Λ for GGX at a direction of cosine `cos`.
pub fn ggx_lambda(alpha: f64, cos: f64) -> f64 {
    let tan2 = (1.0 / (cos * cos) - 1.0).max(0.0);
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

pub struct Quad {
    /// Nodes and weights over φ ∈ [0, π] (the other half by symmetry).
    phi: Vec<(f64, f64)>,
    /// Intervals of the scan along t.
    n_t: usize,
    gl: Vec<(f64, f64)>,
}

impl Quad {
    /// `n_gl`-point Gauss–Legendre on each piece; `levels` pieces a side
    /// of φ = π/2, each a quarter of the last; `n_t` scan intervals in t.
    pub fn new(levels: i32, n_t: usize, n_gl: usize) -> Self {
        let mut phi = Vec::new();
        let mut piece = |a: f64, b: f64| {
            let (m, r) = (0.5 * (a + b), 0.5 * (b - a).abs());
            for (x, w) in gauss_legendre(n_gl) {
                phi.push((m + r * x, w * r));
            }
        };
        let h = 0.5 * PI;
        for side in [-1.0, 1.0] {
            let mut far = h;
            for k in 1..=levels {
                let near = h * 0.25f64.powi(k);
                piece(h + side * near, h + side * far);
                far = near;
            }
            piece(h, h + side * far);
        }
        Quad {
            phi,
            n_t,
            gl: gauss_legendre(n_gl),
        }
    }

    /// What the albedo tables are made with (converged to 10⁻⁶:
    /// `tests/bsdf_tables.rs`, `quadrature_has_converged`).
    pub fn standard() -> Self {
        Quad::new(11, 48, 12)
    }

    /// ∫ g(h, wi) dωi over the wi above the horizon reflected about the
    /// half vectors h (wo·h > 0) of a GGX lobe of roughness `alpha` (α²
    /// above Cycles' mirror threshold), seen from wo = (√(1 − μ²), 0, μ).
    /// `g` must be even in the y components and smooth where the lobe is
    /// (the quadrature follows D).
    pub fn reflected(&self, alpha: f64, mu: f64, g: &dyn Fn(DVec3, DVec3) -> f64) -> f64 {
        let wo = DVec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
        let mut total = 0.0;
        for &(phi, phi_weight) in &self.phi {
            let (sp, cp) = phi.sin_cos();
            let at = |t: f64| {
                let th = (alpha * (0.5 * PI * t).tan()).atan();
                let (st, ct) = th.sin_cos();
                let h = DVec3::new(st * cp, st * sp, ct);
                let woh = wo.dot(h);
                (h, woh, 2.0 * woh * h - wo)
            };
            let valid = |t: f64| {
                let (_, woh, wi) = at(t);
                woh > 0.0 && wi.z > 0.0
            };
            let f = |t: f64| {
                let (h, woh, wi) = at(t);
                if woh <= 0.0 || wi.z <= 0.0 {
                    return 0.0;
                }
                // dωi = 4 (wo·h) dωh, dωh = sin(πt) / (4 D cos θh) dt dφ.
                woh * (PI * t).sin() / (ggx_d(alpha, h) * h.z) * g(h, wi)
            };
            let integrate = |a: f64, b: f64| {
                let (lo, hi) = (a.min(b), a.max(b));
                let (m, r) = (0.5 * (lo + hi), 0.5 * (hi - lo));
                self.gl.iter().map(|(x, w)| w * f(m + r * x)).sum::<f64>() * r
            };
            let mut line = 0.0;
            let mut t0 = 0.0;
            let mut v0 = valid(t0);
            for k in 1..=self.n_t {
                let t1 = k as f64 / self.n_t as f64;
                let v1 = valid(t1);
                if v0 == v1 {
                    if v0 {
                        line += integrate(t0, t1);
                    }
                } else {
                    let (mut a, mut b) = (t0, t1);
                    for _ in 0..60 {
                        let c = 0.5 * (a + b);
                        if valid(c) == v0 {
                            a = c;
                        } else {
                            b = c;
                        }
                    }
                    let (far, cut) = if v0 { (t0, a) } else { (t1, b) };
                    let mut d = far - cut;
                    for _ in 0..12 {
                        line += integrate(cut + 0.25 * d, cut + d);
                        d *= 0.25;
                    }
                    line += integrate(cut, cut + d);
                }
                t0 = t1;
                v0 = v1;
            }
            total += line * phi_weight;
        }
        // Both halves of the circle.
        2.0 * total
    }
}
