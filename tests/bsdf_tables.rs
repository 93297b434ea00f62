//! The generator of the GGX albedo tables in `src/bsdf/tables_data.rs`
//! (read by `vdbphoton::bsdf::tables`), and the checks that the committed
//! tables are its output and agree with the ones Cycles 5.0 ships.
//!
//! Each entry means what Cycles' `app/cycles_precompute.cpp` means by it:
//! an average over the visible normals h of a GGX lobe seen from wo
//! (Heitz 2018), where a normal whose mirror direction falls below the
//! horizon counts 0 (Cycles' sampler returns no direction there):
//! - E(r, μ): the mean of G₂/G₁ = (1 + Λo)/(1 + Λo + Λi), i.e. ∫ f cos dωi
//!   with F = 1 (`ggx_E`); E_avg(r) = ∫₀¹ 2μ E dμ (`ggx_Eavg`);
//! - s(r, μ, z): the mean of the Fresnel interpolation factor s(wo·h), for
//!   the dielectric curve of η(z) = ior_from_F0(z⁴) (`ggx_gen_schlick_ior_s`)
//!   or (1 − wo·h)^p, p = 5(1 − z)/z (`ggx_gen_schlick_s`, slices 7 and 8).
//!
//! Cycles estimates them with 2²⁰ to 2²⁶ Sobol samples in f32; we
//! integrate in f64 by the deterministic quadrature of
//! `tests/common/quad.rs`, which follows the lobe at any α and grades its
//! nodes towards the horizon's cuts. The cells' parameters are
//! Cycles' own f32 values (clamps at 10⁻⁴ and 0.99, α = r² in f32, the
//! mirror below α² = 2·10⁻¹⁰).
//!
//! Regenerate with
//! `cargo test --release --test bsdf_tables -- --ignored regenerate`
//! (about two minutes on two cores).

mod common;

use common::quad::{ggx_d, ggx_lambda, Quad};
use glam::DVec3;
use rayon::prelude::*;
use vdbphoton::bsdf::tables;

/// The mean over the visible normals of a GGX lobe of roughness `alpha`
/// seen at `mu` of g(wo·h, G₂/G₁), 0 where the reflection is below the
/// horizon: ∫ g · G₁(wo) D(h) / (4μ) dωi, the visible normals' density
/// (G₁(wo) (wo·h) D(h)/μ) carried to wi.
fn vndf_mean(q: &Quad, alpha: f64, mu: f64, g: &dyn Fn(f64, f64) -> f64) -> f64 {
    if alpha * alpha <= 2e-10 {
        // Cycles' mirror: h = n, weight 1.
        return g(mu, 1.0);
    }
    let wo = DVec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let lo = ggx_lambda(alpha, mu);
    q.reflected(alpha, mu, &|h, wi| {
        let li = ggx_lambda(alpha, wi.z);
        ggx_d(alpha, h) / (4.0 * mu * (1.0 + lo)) * g(wo.dot(h), (1.0 + lo) / (1.0 + lo + li))
    })
}

/// Cycles' table coordinates: i/(n − 1) in f32, clamped.
fn axis(i: usize, n: usize, lo: f32, hi: f32) -> f32 {
    (i as f32 / (n - 1) as f32).clamp(lo, hi)
}

/// α = r², in f32 as Cycles computes it, held in [0, 1].
fn alpha_of(rough: f32) -> f64 {
    (rough * rough).clamp(0.0, 1.0) as f64
}

/// Cycles' `ior_parametrization`: ior_from_F0(z⁴), in f32.
fn ior_of(z: f32) -> f32 {
    let f0 = (z * z) * (z * z);
    let s = f0.clamp(0.0, 0.99).sqrt();
    (1.0 + s) / (1.0 - s)
}

/// Unpolarised dielectric Fresnel (Born & Wolf), f64.
fn fresnel(cos_i: f64, eta: f64) -> f64 {
    let c = cos_i.abs();
    let g2 = eta * eta - 1.0 + c * c;
    if g2 <= 0.0 {
        return 1.0;
    }
    let g = g2.sqrt();
    let a = (g - c) / (g + c);
    let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    0.5 * a * a * (1.0 + b * b)
}

fn e_cell(q: &Quad, rough: f32, mu: f32) -> f64 {
    vndf_mean(q, alpha_of(rough), mu as f64, &|_, g2g1| g2g1)
}

fn e_avg_cell(q: &Quad, rough: f32) -> f64 {
    // ∫₀¹ 2μ E dμ, Gauss–Legendre in μ.
    let gl = common::quad::gauss_legendre(48);
    gl.iter()
        .map(|(x, w)| {
            let mu = 0.5 * (x + 1.0);
            0.5 * w * 2.0 * mu * vndf_mean(q, alpha_of(rough), mu, &|_, g2g1| g2g1)
        })
        .sum()
}

fn s_ior_cell(q: &Quad, rough: f32, mu: f32, z: f32) -> f64 {
    let eta = ior_of(z) as f64;
    let f0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
    vndf_mean(q, alpha_of(rough), mu as f64, &|cos_hi, _| {
        let f = fresnel(cos_hi, eta);
        ((f - f0) / (1.0 - f0)).clamp(0.0, 1.0)
    })
}

fn s_exp_cell(q: &Quad, rough: f32, mu: f32, z: f32) -> f64 {
    let p = 5.0 * ((1.0 - z) / z) as f64;
    vndf_mean(q, alpha_of(rough), mu as f64, &|cos_hi, _| {
        (1.0 - cos_hi).clamp(0.0, 1.0).powf(p)
    })
}

const E: usize = tables::E_SIZE;
const S: usize = tables::S_SIZE;

fn e_entry(q: &Quad, i: usize) -> f64 {
    let (x, y) = (i % E, i / E);
    e_cell(q, axis(x, E, 1e-4, 1.0), axis(y, E, 1e-4, 1.0))
}

fn e_avg_entry(q: &Quad, x: usize) -> f64 {
    e_avg_cell(q, axis(x, E, 1e-4, 1.0))
}

fn s_ior_entry(q: &Quad, i: usize) -> f64 {
    let (x, y, z) = (i % S, (i / S) % S, i / (S * S));
    s_ior_cell(
        q,
        axis(x, S, 1e-4, 1.0),
        axis(y, S, 1e-4, 1.0),
        axis(z, S, 1e-4, 0.99),
    )
}

/// The two slices of `ggx_gen_schlick_s` Cycles reads at z = 0.5.
fn s5_entry(q: &Quad, i: usize) -> f64 {
    let (x, y, k) = (i % S, (i / S) % S, i / (S * S));
    s_exp_cell(
        q,
        axis(x, S, 1e-4, 1.0),
        axis(y, S, 1e-4, 1.0),
        axis(7 + k, S, 1e-4, 0.99),
    )
}

fn saturate(v: f64) -> f32 {
    v.clamp(0.0, 1.0) as f32
}

fn format_table(name: &str, doc: &str, values: &[f32], row: usize) -> String {
    let mut s = format!(
        "{doc}#[rustfmt::skip]\npub static {name}: [f32; {}] = [\n",
        values.len()
    );
    for chunk in values.chunks(row) {
        s.push_str("    ");
        let items: Vec<String> = chunk.iter().map(|v| format!("{v:?}")).collect();
        s.push_str(&items.join(", "));
        s.push_str(",\n");
    }
    s.push_str("];\n");
    s
}

#[test]
#[ignore = "rewrites src/bsdf/tables_data.rs: cargo test --release --test bsdf_tables -- --ignored regenerate"]
fn regenerate() {
    let q = Quad::standard();
    let e: Vec<f32> = (0..E * E)
        .into_par_iter()
        .map(|i| saturate(e_entry(&q, i)))
        .collect();
    let e_avg: Vec<f32> = (0..E)
        .into_par_iter()
        .map(|x| saturate(e_avg_entry(&q, x)))
        .collect();
    let s_ior: Vec<f32> = (0..S * S * S)
        .into_par_iter()
        .map(|i| saturate(s_ior_entry(&q, i)))
        .collect();
    let s5: Vec<f32> = (0..2 * S * S)
        .into_par_iter()
        .map(|i| saturate(s5_entry(&q, i)))
        .collect();
    let mut out = String::from(
        "//! GGX albedo tables (meaning, layout and provenance in `tables.rs`).\n\
         //! Generated by `cargo test --release --test bsdf_tables -- --ignored\n\
         //! regenerate`; do not edit.\n\n",
    );
    out += &format_table("GGX_E", "/// E(r, μ) at [μ index × 32 + r index].\n", &e, E);
    out += "\n";
    out += &format_table("GGX_E_AVG", "/// E_avg(r).\n", &e_avg, 8);
    out += "\n";
    out += &format_table(
        "GGX_IOR_S",
        "/// s(r, μ, z) of the dielectric curve at [z × 256 + μ × 16 + r].\n",
        &s_ior,
        S,
    );
    out += "\n";
    out += &format_table(
        "GGX_SCHLICK5_S",
        "/// s(r, μ) of (1 − cos)^p, p = 40/7 then 35/8, at [slice × 256 + μ × 16 + r].\n",
        &s5,
        S,
    );
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/src/bsdf/tables_data.rs");
    std::fs::write(path, out).unwrap();
}

/// Entries spread over each table, edges included.
fn spot_indices(len: usize, row: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (0..len).step_by(len / 23 + 1).collect();
    v.extend([0, row - 1, len - row, len - 1, len / 2 + row / 3]);
    v.sort();
    v.dedup();
    v
}

/// The committed tables are this generator's output: entries spread over
/// each table (edges included) recomputed here agree to the 7 decimals
/// written. Fails when the generator or the file is changed without the
/// other (checked by editing one entry of the file, and by changing the
/// generator's clamp of μ to 10⁻³).
#[test]
fn committed_tables_are_the_generators_output() {
    let q = Quad::standard();
    let check = |name: &str, table: &[f32], idx: Vec<usize>, f: &dyn Fn(usize) -> f64| {
        for i in idx {
            let want = saturate(f(i));
            assert!(
                (table[i] - want).abs() < 2e-6,
                "{name}[{i}]: committed {} but the generator gives {want}",
                table[i]
            );
        }
    };
    check("GGX_E", &tables::GGX_E, spot_indices(E * E, E), &|i| {
        e_entry(&q, i)
    });
    check(
        "GGX_E_AVG",
        &tables::GGX_E_AVG,
        vec![0, 1, 9, 20, 31],
        &|i| e_avg_entry(&q, i),
    );
    check(
        "GGX_IOR_S",
        &tables::GGX_IOR_S,
        spot_indices(S * S * S, S),
        &|i| s_ior_entry(&q, i),
    );
    check(
        "GGX_SCHLICK5_S",
        &tables::GGX_SCHLICK5_S,
        spot_indices(2 * S * S, S),
        &|i| s5_entry(&q, i),
    );
}

/// The quadrature has converged: twice the nodes and finer grading along
/// φ, four times the scan along t and twice the Gauss–Legendre order
/// change no entry by more than 2·10⁻⁶ (tried on the hardest cells:
/// grazing μ, where the horizon and the viewer's terminator cut the
/// visible normals, and the narrowest regular lobe). Ungraded, the rule
/// missed E(1, 10⁻⁴) by 4·10⁻⁵ (along t) and 8·10⁻⁵ (a uniform φ).
#[test]
fn quadrature_has_converged() {
    let (a, b) = (Quad::standard(), Quad::new(16, 192, 24));
    for (rough, mu) in [
        (1.0f32, 1e-4f32),
        (1.0, 0.1),
        (0.5, 0.02),
        (1.0 / 31.0, 1e-4),
    ] {
        let (x, y) = (e_cell(&a, rough, mu), e_cell(&b, rough, mu));
        assert!((x - y).abs() < 2e-6, "E({rough}, {mu}): {x} vs {y}");
        let (x, y) = (
            s_ior_cell(&a, rough, mu, 0.45),
            s_ior_cell(&b, rough, mu, 0.45),
        );
        assert!((x - y).abs() < 2e-6, "s({rough}, {mu}): {x} vs {y}");
    }
}

/// A few entries of the tables Cycles 5.0 ships (`src/scene/shader.tables`
/// at tag v5.0.0, printed there to 6 decimals): ours agree within their
/// printing and Monte Carlo noise. Over every entry
/// ([`cycles_tables_agree`]): `ggx_E` max 9.5·10⁻⁷ (mean 2.9·10⁻⁷),
/// `ggx_Eavg` 6.6·10⁻⁷, `ggx_gen_schlick_ior_s` 1.2·10⁻⁵ (mean
/// 6.4·10⁻⁷), the two `ggx_gen_schlick_s` slices 1.4·10⁻⁵ (mean
/// 1.1·10⁻⁶). The grading of the quadrature matters here: without it
/// E(1, 10⁻⁴) was 0.999121 against Cycles' 0.999079.
#[test]
fn tables_agree_with_cycles_at_spot_entries() {
    let cases: [(&str, &[f32], usize, f32, f32); 14] = [
        ("ggx_E", &tables::GGX_E, 31, 0.999079, 2e-6),
        ("ggx_E", &tables::GGX_E, 176, 0.858015, 2e-6),
        ("ggx_E", &tables::GGX_E, 511, 0.457779, 2e-6),
        ("ggx_E", &tables::GGX_E, 665, 0.584055, 2e-6),
        ("ggx_E", &tables::GGX_E, 1000, 0.995072, 2e-6),
        ("ggx_Eavg", &tables::GGX_E_AVG, 8, 0.985805, 2e-6),
        ("ggx_Eavg", &tables::GGX_E_AVG, 20, 0.761345, 2e-6),
        ("ggx_Eavg", &tables::GGX_E_AVG, 31, 0.409137, 2e-6),
        (
            "ggx_gen_schlick_ior_s",
            &tables::GGX_IOR_S,
            1589,
            0.20894,
            3e-5,
        ),
        (
            "ggx_gen_schlick_ior_s",
            &tables::GGX_IOR_S,
            1960,
            0.017455,
            3e-5,
        ),
        (
            "ggx_gen_schlick_ior_s",
            &tables::GGX_IOR_S,
            1023,
            0.00014,
            3e-5,
        ),
        (
            "ggx_gen_schlick_ior_s",
            &tables::GGX_IOR_S,
            3084,
            0.009968,
            3e-5,
        ),
        // Slices 7 and 8 of ggx_gen_schlick_s are our slices 0 and 1.
        (
            "ggx_gen_schlick_s",
            &tables::GGX_SCHLICK5_S,
            1833 - 7 * 256,
            0.087755,
            3e-5,
        ),
        (
            "ggx_gen_schlick_s",
            &tables::GGX_SCHLICK5_S,
            2196 - 7 * 256,
            0.020434,
            3e-5,
        ),
    ];
    for (name, table, i, cycles, tol) in cases {
        assert!(
            (table[i] - cycles).abs() < tol,
            "{name}[{i}]: ours {} Cycles {cycles}",
            table[i]
        );
    }
}

/// Reads a table `table_NAME[...] = { ... };` from Cycles'
/// `scene/shader.tables`.
fn cycles_table(text: &str, name: &str) -> Vec<f32> {
    let start = text
        .find(&format!("table_{name}["))
        .unwrap_or_else(|| panic!("no table {name}"));
    let open = start + text[start..].find('{').unwrap();
    let close = open + text[open..].find('}').unwrap();
    text[open + 1..close]
        .split(',')
        .map(|s| s.trim().trim_end_matches('f'))
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect()
}

/// Our tables against the ones Cycles 5.0 ships, every entry: give the
/// path of Cycles' `src/scene/shader.tables` (tag v5.0.0) in
/// `CYCLES_SHADER_TABLES`. Prints the largest and mean differences.
#[test]
#[ignore = "needs Cycles' shader.tables: CYCLES_SHADER_TABLES=PATH cargo test --test bsdf_tables -- --ignored cycles"]
fn cycles_tables_agree() {
    let path = std::env::var("CYCLES_SHADER_TABLES").expect("CYCLES_SHADER_TABLES");
    let text = std::fs::read_to_string(path).unwrap();
    let s5_cycles: Vec<f32> =
        cycles_table(&text, "ggx_gen_schlick_s")[7 * S * S..9 * S * S].to_vec();
    for (name, ours, theirs, row) in [
        ("ggx_E", &tables::GGX_E[..], cycles_table(&text, "ggx_E"), E),
        (
            "ggx_Eavg",
            &tables::GGX_E_AVG[..],
            cycles_table(&text, "ggx_Eavg"),
            E,
        ),
        (
            "ggx_gen_schlick_ior_s",
            &tables::GGX_IOR_S[..],
            cycles_table(&text, "ggx_gen_schlick_ior_s"),
            S,
        ),
        (
            "ggx_gen_schlick_s[7..9]",
            &tables::GGX_SCHLICK5_S[..],
            s5_cycles,
            S,
        ),
    ] {
        assert_eq!(ours.len(), theirs.len(), "{name}");
        let (mut worst, mut at, mut sum) = (0.0f32, 0, 0.0f64);
        for (i, (a, b)) in ours.iter().zip(&theirs).enumerate() {
            let d = (a - b).abs();
            sum += d as f64;
            if d > worst {
                worst = d;
                at = i;
            }
        }
        eprintln!(
            "{name}: max |ours - Cycles| {worst:.2e} at [{at}] (x {}, y {}, z {}: {} vs {}), mean {:.2e}",
            at % row,
            (at / row) % row,
            at / (row * row),
            ours[at],
            theirs[at],
            sum / ours.len() as f64
        );
    }
}
