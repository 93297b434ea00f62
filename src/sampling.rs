//! Random numbers and the warps that turn them into directions.
//!
//! [`Rng`] is a counter-based stream keyed by (domain, seed, stream, index):
//! a camera sample uses (Camera, seed, pixel, sample), a photon (Photon,
//! seed, pass, photon index), so results never depend on which thread ran
//! what, and the [`Domain`] tag keeps the streams of different uses apart
//! even where their numbers coincide (pixel 7, sample 3 and pass 7, photon 3).

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// SplitMix64's finaliser (Steele, Lea & Flood 2014): a bijective 64-bit
/// mix with good avalanche, used to derive stream states from keys.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The van der Corput radical inverse of `i` in base 2, in [0, 1): any
/// 2^m consecutive indices from a multiple of 2^m fall one in each of 2^m
/// equal strata.
#[inline]
pub fn radical_inverse_2(i: u32) -> f32 {
    (i.reverse_bits() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// What a random stream is used for. Mixed into every key, so that two uses
/// never draw the same numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Domain {
    /// Camera paths and camera-ray marches: (seed, pixel, sample).
    Camera,
    /// Photon paths: (seed, pass, photon).
    Photon,
    /// Per-pass choices shared by a whole pass: (seed, pass, 0).
    Pass,
    /// A camera sample's time within the shutter: (seed, pixel, sample).
    /// A stream of its own, so that a still frame draws exactly the numbers
    /// it drew before motion blur existed.
    Time,
    /// The march for the denoiser's guides (`crate::integrator::guide`):
    /// (seed, pixel, sample).
    Guide,
    /// Tests, benchmarks and tools.
    Test,
}

impl Domain {
    /// A distinct odd constant per domain.
    fn tag(self) -> u64 {
        match self {
            Domain::Camera => 0x243F_6A88_85A3_08D3,
            Domain::Photon => 0xA409_3822_299F_31D1,
            Domain::Pass => 0x082E_FA98_EC4E_6C89,
            Domain::Test => 0x4528_21E6_38D0_1377,
            Domain::Time => 0xBE54_66CF_34E9_0C6D,
            Domain::Guide => 0xC0AC_29B7_C97C_50DD,
        }
    }
}

/// PCG32 (O'Neill 2014) seeded from hashed keys: a deterministic stream per
/// (domain, seed, stream, index).
#[derive(Debug, Clone)]
pub struct Rng {
    state: u64,
    inc: u64,
    /// The stratified prefix of a camera sample's stream, when it has one
    /// ([`Rng::stratified`]).
    qmc: Option<Qmc>,
}

/// A camera sample's first [`QMC_DIMS`] numbers: pairs of dimensions from
/// an Owen-scrambled, index-shuffled Sobol (0, 2)-sequence (Burley 2020,
/// "Practical Hash-based Owen Scrambling"; pbrt-v4's `PaddedSobolSampler`
/// pads pairs the same way), so that a pixel's samples stratify the pixel,
/// the first light sample and the first BSDF sample whatever their number.
#[derive(Debug, Clone, Copy)]
struct Qmc {
    /// The sample's index among its pixel's, bits reversed.
    index_reversed: u32,
    /// The pixel's scrambling seed.
    seed: u32,
    /// The next dimension.
    dim: u32,
    /// The second number of the pair the last even dimension drew.
    pending: u32,
}

/// Dimensions drawn from the stratified sequence; the stream goes on with
/// PCG after them.
pub const QMC_DIMS: u32 = 8;

#[inline]
fn hash32(mut x: u32) -> u32 {
    // lowbias32 (Wellons).
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// Laine & Karras' hash-based permutation, the core of Burley's nested
/// uniform scramble.
#[inline]
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// Sobol's second dimension at `i` with its bits reversed (a 32-bit
/// fraction read from its least significant bit): linear over GF(2) in the
/// bits of `i`, as the dimension itself, so four byte tables give it. The
/// first dimension, van der Corput's, is `i` reversed.
///
/// Reversed because Burley's nested uniform scramble of a fraction `v` is
/// `rev(LK(rev(v)))` ([`laine_karras`] on its bits, most significant
/// first): a scrambled point is then one permutation and one reversal of
/// what the tables give, and the van der Corput fraction of a shuffled
/// index `i` (`rev(i)`) is scrambled as `rev(LK(i))`, no reversal on the
/// way in (two reversals saved out of four, in the camera samples' hot
/// path).
#[inline]
fn sobol1_reversed(i: u32) -> u32 {
    let t = &SOBOL1_REVERSED;
    t[0][(i & 255) as usize]
        ^ t[1][((i >> 8) & 255) as usize]
        ^ t[2][((i >> 16) & 255) as usize]
        ^ t[3][(i >> 24) as usize]
}

/// Sobol's second dimension of each byte of the index at each of its four
/// places, bits reversed: direction numbers v_0 = 2^31, v_k = v_(k−1) ^
/// (v_(k−1) >> 1).
static SOBOL1_REVERSED: [[u32; 256]; 4] = sobol1_tables();

const fn sobol1_tables() -> [[u32; 256]; 4] {
    let mut v = [0u32; 32];
    v[0] = 1 << 31;
    let mut k = 1;
    while k < 32 {
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        k += 1;
    }
    let mut t = [[0u32; 256]; 4];
    let mut place = 0;
    while place < 4 {
        let mut b = 0;
        while b < 256 {
            let mut y = 0u32;
            let mut bit = 0;
            while bit < 8 {
                if b & (1 << bit) != 0 {
                    y ^= v[place * 8 + bit];
                }
                bit += 1;
            }
            t[place][b] = y.reverse_bits();
            b += 1;
        }
        place += 1;
    }
    t
}

impl Rng {
    pub fn new(domain: Domain, seed: u64, stream: u64, index: u64) -> Self {
        let seed = mix64(seed ^ mix64(domain.tag()));
        let a = mix64(seed ^ mix64(stream.wrapping_add(0x9E37_79B9_7F4A_7C15)));
        let b = mix64(a ^ mix64(index.wrapping_mul(0xD1B5_4A32_D192_ED03).wrapping_add(1)));
        let mut r = Rng {
            state: 0,
            inc: (mix64(b ^ 0x5851_F42D_4C95_7F2D) << 1) | 1,
            qmc: None,
        };
        r.next_u32();
        r.state = r.state.wrapping_add(b);
        r.next_u32();
        r
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// This stream with its first [`QMC_DIMS`] numbers stratified over
    /// the samples of one pixel: `index` is the sample's number in its
    /// pixel, `pixel` the pixel's stream (with the seed, it picks the
    /// scramble).
    pub fn stratified(mut self, seed: u64, pixel: u64, index: u64) -> Self {
        let s = mix64(seed ^ mix64(pixel ^ 0x6A09_E667_F3BC_C909));
        self.qmc = Some(Qmc {
            index_reversed: (index as u32).reverse_bits(),
            seed: (s ^ (s >> 32)) as u32,
            dim: 0,
            pending: 0,
        });
        self
    }

    /// The next stratified number, while the prefix lasts.
    #[inline]
    fn next_qmc(&mut self) -> Option<f32> {
        let q = self.qmc.as_mut()?;
        if q.dim >= QMC_DIMS {
            self.qmc = None;
            return None;
        }
        let v = if q.dim % 2 == 0 {
            // Each pair shuffles the samples' order by a scramble of its
            // own, so that pairs do not correlate (padding).
            let seed = hash32(q.seed ^ hash32((q.dim / 2).wrapping_add(0x9e37_79b9)));
            // The sample's index, shuffled: Owen-scrambled as a fraction.
            let i = laine_karras(q.index_reversed, seed).reverse_bits();
            q.pending = laine_karras(sobol1_reversed(i), hash32(seed ^ 0x02e5_be93)).reverse_bits();
            laine_karras(i, hash32(seed ^ 0x68bc_21eb)).reverse_bits()
        } else {
            q.pending
        };
        q.dim += 1;
        Some((v >> 8) as f32 * (1.0 / (1u32 << 24) as f32))
    }

    /// Uniform in [0, 1): 24 random bits, so never 1.0.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        if self.qmc.is_some() {
            if let Some(v) = self.next_qmc() {
                return v;
            }
        }
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// Two uniform numbers; in a stratified prefix, a pair of dimensions
    /// of its own (an odd dimension is skipped to start one).
    #[inline]
    pub fn next_vec2(&mut self) -> Vec2 {
        if let Some(q) = self.qmc.as_mut() {
            q.dim += q.dim % 2;
        }
        Vec2::new(self.next_f32(), self.next_f32())
    }
}

/// Russian roulette (Arvo & Kirk 1990) on a throughput or a photon's power,
/// the one place every estimator plays it: when the largest channel of
/// `beta` is below `threshold`, it survives with probability
/// max/`threshold` and is divided by that probability (so its largest
/// channel becomes `threshold`); otherwise it is left alone. Unbiased, and
/// it keeps weights bounded by `threshold`. Returns false (and zeroes
/// `beta`) when the path ends, also when `beta` is already zero or not a
/// number.
#[inline]
pub fn roulette(beta: &mut Vec3, threshold: f32, rng: &mut Rng) -> bool {
    let m = beta.max_element();
    if m.is_nan() || m <= 0.0 {
        *beta = Vec3::ZERO;
        return false;
    }
    if m < threshold {
        let survive = m / threshold;
        if rng.next_f32() >= survive {
            *beta = Vec3::ZERO;
            return false;
        }
        *beta /= survive;
    }
    true
}

/// Two unit vectors completing `n` (unit) to an orthonormal basis, without
/// branches on the sign (Duff et al. 2017, "Building an Orthonormal Basis,
/// Revisited").
#[inline]
pub fn coordinate_system(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// `sin θ, cos θ, φ` in the frame (t, b, n).
#[inline]
pub fn spherical_direction(
    sin_theta: f32,
    cos_theta: f32,
    phi: f32,
    frame: (Vec3, Vec3, Vec3),
) -> Vec3 {
    let (s, c) = phi.sin_cos();
    frame.0 * (sin_theta * c) + frame.1 * (sin_theta * s) + frame.2 * cos_theta
}

#[inline]
pub fn sample_uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

#[inline]
pub fn uniform_sphere_pdf() -> f32 {
    1.0 / (4.0 * PI)
}

/// Uniform direction in the cone of half-angle acos(`cos_max`) around +Z.
#[inline]
pub fn sample_uniform_cone(u: Vec2, cos_max: f32) -> Vec3 {
    let cos_theta = (1.0 - u.x) + u.x * cos_max;
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = u.y * 2.0 * PI;
    Vec3::new(phi.cos() * sin_theta, phi.sin() * sin_theta, cos_theta)
}

#[inline]
pub fn uniform_cone_pdf(cos_max: f32) -> f32 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

/// Concentric map of the square to the unit disk (Shirley & Chiu 1997).
pub fn sample_uniform_disk_concentric(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, PI / 4.0 * (o.y / o.x))
    } else {
        (o.y, PI / 2.0 - PI / 4.0 * (o.x / o.y))
    };
    Vec2::new(theta.cos(), theta.sin()) * r
}

/// Cosine-weighted direction on the hemisphere around +Z (Malley's
/// method: the concentric disk lifted onto the hemisphere; pbrt-v4
/// `SampleCosineHemisphere`): density cos θ / π.
#[inline]
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = sample_uniform_disk_concentric(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Veach's power heuristic with β = 2.
#[inline]
pub fn power_heuristic(nf: u32, f_pdf: f32, ng: u32, g_pdf: f32) -> f32 {
    let f = nf as f32 * f_pdf;
    let g = ng as f32 * g_pdf;
    if f.is_infinite() {
        return 1.0;
    }
    if f == 0.0 && g == 0.0 {
        return 0.0;
    }
    (f * f) / (f * f + g * g)
}

/// A piecewise-constant density on [0, 1) (pbrt-v4 §A.4.1).
#[derive(Debug, Clone)]
pub struct Distribution1D {
    func: Vec<f32>,
    cdf: Vec<f32>,
    integral: f32,
}

impl Distribution1D {
    /// `f` must be non-negative; an all-zero `f` becomes uniform.
    pub fn new(f: &[f32]) -> Self {
        let n = f.len().max(1);
        let mut func: Vec<f32> = f.iter().map(|v| v.max(0.0)).collect();
        if func.is_empty() {
            func.push(0.0);
        }
        let mut cdf = vec![0.0f32; n + 1];
        for i in 0..n {
            cdf[i + 1] = cdf[i] + func[i] / n as f32;
        }
        let integral = cdf[n];
        if integral <= 0.0 {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
            func.iter_mut().for_each(|v| *v = 1.0);
        } else {
            cdf.iter_mut().for_each(|c| *c /= integral);
        }
        Self {
            func,
            cdf,
            integral: integral.max(0.0),
        }
    }

    pub fn count(&self) -> usize {
        self.func.len()
    }

    /// The integral of the (clamped) function over [0, 1).
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// A sample in [0, 1), its density, and its bin.
    pub fn sample_continuous(&self, u: f32) -> (f32, f32, usize) {
        let n = self.func.len();
        // Last bin whose cdf start is ≤ u.
        let i = self
            .cdf
            .partition_point(|&c| c <= u)
            .saturating_sub(1)
            .min(n - 1);
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 {
            (u - self.cdf[i]) / width
        } else {
            0.5
        };
        let pdf = if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        };
        (
            ((i as f32 + du.clamp(0.0, 1.0)) / n as f32).min(1.0 - f32::EPSILON),
            pdf,
            i,
        )
    }

    /// Density at `x` ∈ [0, 1).
    pub fn pdf(&self, x: f32) -> f32 {
        let n = self.func.len();
        let i = ((x * n as f32) as usize).min(n - 1);
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }
}

/// A piecewise-constant density on [0, 1)², sampled by its marginal over
/// rows then the conditional within the row (pbrt-v4 §A.5).
#[derive(Debug, Clone)]
pub struct Distribution2D {
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// `f` row-major, `width` x `height` (row 0 at v = 0).
    pub fn new(f: &[f32], width: usize, height: usize) -> Self {
        let rows: Vec<Distribution1D> = (0..height)
            .map(|y| Distribution1D::new(&f[y * width..(y + 1) * width]))
            .collect();
        let marginal = Distribution1D::new(&rows.iter().map(|r| r.integral()).collect::<Vec<_>>());
        Self { rows, marginal }
    }

    /// (u, v) and the density with respect to area on [0, 1)².
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (v, pdf_v, row) = self.marginal.sample_continuous(u.y);
        let (x, pdf_u, _) = self.rows[row].sample_continuous(u.x);
        (Vec2::new(x, v), pdf_u * pdf_v)
    }

    pub fn pdf(&self, uv: Vec2) -> f32 {
        let n = self.rows.len();
        let row = ((uv.y * n as f32) as usize).min(n - 1);
        self.marginal.pdf(uv.y) * self.rows[row].pdf(uv.x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixel(seed: u64, pixel: u64, index: u64) -> Rng {
        Rng::new(Domain::Test, seed, pixel, index).stratified(seed, pixel, index)
    }

    /// The first 2^k samples of a pixel are a (0, 2)-net in each pair of
    /// stratified dimensions: every elementary interval of area 2^−k
    /// (2^a x 2^(k−a) cells, for every a) holds exactly one point. Fails
    /// if a pair's dimensions are scrambled with the same index shuffle as
    /// another's but different orders, or the index shuffle is not a
    /// permutation of each aligned block.
    #[test]
    fn each_pair_of_dimensions_is_a_0_2_net() {
        for (seed, px) in [(0u64, 0u64), (7, 12345), (3, 99)] {
            for k in [2u32, 4, 6, 8] {
                let n = 1u32 << k;
                let pts: Vec<Vec<f32>> = (0..n)
                    .map(|i| {
                        let mut r = pixel(seed, px, i as u64);
                        (0..QMC_DIMS).map(|_| r.next_f32()).collect()
                    })
                    .collect();
                for pair in 0..(QMC_DIMS / 2) as usize {
                    for a in 0..=k {
                        let (cx, cy) = (1u32 << a, 1u32 << (k - a));
                        let mut seen = vec![0u32; n as usize];
                        for p in &pts {
                            let x = (p[2 * pair] * cx as f32) as u32;
                            let y = (p[2 * pair + 1] * cy as f32) as u32;
                            seen[(y * cx + x) as usize] += 1;
                        }
                        assert!(
                            seen.iter().all(|&c| c == 1),
                            "seed {seed} pixel {px}, {n} samples, pair {pair}, {cx} x {cy}: {seen:?}"
                        );
                    }
                }
            }
        }
    }

    /// Over many pixels (each its own scramble), one sample's stratified
    /// numbers are uniform and pairs independent: a chi-square test of the
    /// 16 x 16 histogram of dimensions (0, 1), (1, 2) across pairs, and
    /// (0, 2) across pairs, at 1e-3. Fails if the scramble's seed does not
    /// change with the pixel (all pixels would share one point).
    #[test]
    fn across_pixels_the_numbers_are_uniform_and_pairs_independent() {
        let n = 64_000usize;
        for (i, j) in [(0usize, 1usize), (1, 2), (0, 2), (3, 6)] {
            let mut h = vec![0f64; 256];
            for p in 0..n {
                let mut r = pixel(5, p as u64, 3);
                let v: Vec<f32> = (0..QMC_DIMS).map(|_| r.next_f32()).collect();
                let (x, y) = ((v[i] * 16.0) as usize, (v[j] * 16.0) as usize);
                h[y * 16 + x] += 1.0;
            }
            let e = n as f64 / 256.0;
            let stat: f64 = h.iter().map(|o| (o - e) * (o - e) / e).sum();
            // 255 degrees of freedom: p = 1e-3 at about 330.
            assert!(stat < 330.0, "dimensions {i}, {j}: chi-square {stat}");
        }
    }

    /// `next_vec2` starts a pair of its own after an odd number of draws,
    /// and the stream goes on with PCG after the stratified prefix.
    #[test]
    fn vec2_aligns_to_a_pair_and_the_prefix_ends() {
        let mut a = pixel(1, 2, 3);
        let mut b = pixel(1, 2, 3);
        a.next_f32();
        let va = a.next_vec2();
        let (_, _) = (b.next_f32(), b.next_f32());
        let vb = Vec2::new(b.next_f32(), b.next_f32());
        assert_eq!(va, vb);
        let mut c = pixel(1, 2, 3);
        let mut plain = Rng::new(Domain::Test, 1, 2, 3);
        for _ in 0..QMC_DIMS {
            c.next_f32();
        }
        assert_eq!(c.next_f32(), plain.next_f32());
    }
}
