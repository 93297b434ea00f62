//! Deterministic procedural volumes, written as real `.vdb` files by
//! `vdbphoton generate`: the bundled scenes and the tests use them, since
//! users and CI have no network.
//!
//! - `cloud`: fBm value noise (Perlin 1985, "An image synthesizer";
//!   fractional Brownian motion as in Musgrave et al., *Texturing and
//!   Modeling*) modulating a union of soft spheres, in the cube [-1, 1]^3; one
//!   `density` grid in 0..1 whose saturated core becomes tiles.
//! - `plume`: a rising smoke column with fire at its base, laid out as
//!   Blender's Mantaflow caches are (`density`, `flame`, `temperature` float
//!   grids and a `velocity` vec3s grid; a pure-scale transform with index
//!   (0,0,0) at the domain's minimum corner; temperature = 1.5 + 1.5·flame
//!   where flame > 0.01, else 0, as Blender writes it).
//!
//! Every value is a pure function of (seed, voxel), so the output is the same
//! whatever the thread count.

use crate::error::{Error, Result};
use crate::grid::{Grid, GridParts, BRICK_VOXELS};
use crate::vdb::AnyGrid;
use glam::{DAffine3, DVec3, IVec3, Vec3};
use rayon::prelude::*;

/// Largest resolution `generate` accepts (a 2048^3 cloud is ~30 GB dense).
pub const MAX_RES: u32 = 2048;

fn hash3(seed: u64, x: i32, y: i32, z: i32) -> u64 {
    let mut h = seed ^ 0x9E37_79B9_7F4A_7C15;
    for v in [x as u32 as u64, y as u32 as u64, z as u32 as u64] {
        h = (h ^ v).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 31;
    }
    h = h.wrapping_mul(0x94D0_49BB_1331_11EB);
    h ^ (h >> 29)
}

fn lattice(seed: u64, x: i32, y: i32, z: i32) -> f32 {
    (hash3(seed, x, y, z) >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
}

/// Value noise in [-1, 1] with quintic interpolation between lattice values.
pub fn value_noise(seed: u64, p: Vec3) -> f32 {
    let f = p.floor();
    let i = f.as_ivec3();
    let t = p - f;
    let s = t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let l = |a: f32, b: f32, w: f32| a + (b - a) * w;
    let v = |dx, dy, dz| lattice(seed, i.x + dx, i.y + dy, i.z + dz);
    let x00 = l(v(0, 0, 0), v(1, 0, 0), s.x);
    let x10 = l(v(0, 1, 0), v(1, 1, 0), s.x);
    let x01 = l(v(0, 0, 1), v(1, 0, 1), s.x);
    let x11 = l(v(0, 1, 1), v(1, 1, 1), s.x);
    l(l(x00, x10, s.y), l(x01, x11, s.y), s.z)
}

/// Fractional Brownian motion: `octaves` of value noise, lacunarity 2,
/// gain 0.5, normalised to [-1, 1].
pub fn fbm(seed: u64, p: Vec3, octaves: u32) -> f32 {
    let (mut sum, mut amp, mut norm, mut q) = (0.0, 1.0, 0.0, p);
    for o in 0..octaves {
        sum += amp * value_noise(seed.wrapping_add(o as u64 * 7919), q);
        norm += amp;
        amp *= 0.5;
        q = q * 2.0 + Vec3::splat(17.13);
    }
    sum / norm
}

fn check_res(res: u32) -> Result<()> {
    if !(8..=MAX_RES).contains(&res) {
        return Err(Error::Argument(format!(
            "--res {res} is out of range (8 to {MAX_RES})"
        )));
    }
    Ok(())
}

/// A generated brick: origin, then per channel its 512 values and mask.
type Block<const N: usize> = (IVec3, [Vec<f32>; N], [[u64; 8]; N]);

/// Evaluates `f(index) -> values` over the 8^3 blocks of `lo..hi` (voxel
/// index box, `lo` and `hi + 1` multiples of 8), skipping blocks that `skip`
/// rules out, keeping bricks with a nonzero voxel. Voxels with a nonzero
/// value are active. Returns one `GridParts` per output channel group.
fn fill_blocks<const N: usize, F, S>(lo: IVec3, hi: IVec3, skip: S, f: F) -> Vec<Block<N>>
where
    F: Fn(IVec3) -> [f32; N] + Sync,
    S: Fn(IVec3) -> bool + Sync,
{
    let b_lo: IVec3 = lo >> 3;
    let b_hi: IVec3 = hi >> 3;
    let dims = b_hi - b_lo + 1;
    let count = (dims.x * dims.y * dims.z) as usize;
    (0..count)
        .into_par_iter()
        .filter_map(|n| {
            let n = n as i32;
            let b = b_lo + IVec3::new(n / (dims.y * dims.z), (n / dims.z) % dims.y, n % dims.z);
            let origin = b << 3;
            if skip(origin) {
                return None;
            }
            let mut vals: [Vec<f32>; N] = std::array::from_fn(|_| vec![0.0; BRICK_VOXELS]);
            let mut masks = [[0u64; 8]; N];
            let mut any = false;
            for v in 0..BRICK_VOXELS {
                let ijk =
                    origin + IVec3::new((v >> 6) as i32, ((v >> 3) & 7) as i32, (v & 7) as i32);
                let out = f(ijk);
                for c in 0..N {
                    if out[c] != 0.0 {
                        vals[c][v] = out[c];
                        masks[c][v >> 6] |= 1 << (v & 63);
                        any = true;
                    }
                }
            }
            any.then_some((origin, vals, masks))
        })
        .collect()
}

fn parts_for_channel<const N: usize>(
    name: &str,
    xf: DAffine3,
    blocks: &[Block<N>],
    c: usize,
) -> GridParts<f32> {
    let mut p = GridParts::new(name, 0.0, xf);
    for (o, vals, masks) in blocks {
        if masks[c].iter().any(|&w| w != 0) {
            p.brick_origins.push(*o);
            p.values.extend_from_slice(&vals[c]);
            p.masks.push(masks[c]);
        }
    }
    p
}

/// A cloud: one `density` grid in the cube [-1, 1]^3 at `res` voxels along
/// an edge (voxel size 2/res, index -res/2 .. res/2-1, voxel centres at
/// (i + 0.5)·2/res).
pub fn cloud(res: u32, seed: u64) -> Result<Grid<f32>> {
    check_res(res)?;
    let res = (res / 8 * 8).max(8) as i32;
    let vs = 2.0 / res as f64;
    let xf = DAffine3::from_scale_rotation_translation(
        DVec3::splat(vs),
        glam::DQuat::IDENTITY,
        DVec3::splat(vs * 0.5),
    );
    // A few soft spheres, placed by the seed.
    let spheres: Vec<(Vec3, f32)> = (0..6)
        .map(|i| {
            let r = |k| (hash3(seed, i, k, 99) >> 40) as f32 / (1u64 << 24) as f32;
            let c = Vec3::new(r(0) - 0.5, r(1) - 0.5, (r(2) - 0.5) * 0.5) * 0.6;
            let rad = 0.3 + 0.25 * r(3);
            (c, rad)
        })
        .collect();
    let shape = |p: Vec3| {
        spheres
            .iter()
            .map(|(c, r)| 1.0 - (p - *c).length() / r)
            .fold(f32::MIN, f32::max)
    };
    let world = |ijk: IVec3| (ijk.as_vec3() + 0.5) * vs as f32;
    let density = |p: Vec3| {
        let n = fbm(seed, p * 3.0, 5);
        ((shape(p) + 0.3 * n - 0.1) * 6.0).clamp(0.0, 1.0)
    };
    let half = res / 2;
    let lo = IVec3::splat(-half);
    let hi = IVec3::splat(half - 1);
    // shape is 4-Lipschitz (radii ≥ 0.25) and |0.3 n| ≤ 0.3.
    let half_diag = (3.0f32).sqrt() * 4.0 * vs as f32;
    let skip = |o: IVec3| {
        let c = world(o + 4) - 0.5 * vs as f32;
        shape(c) + 4.0 * half_diag + 0.3 - 0.1 <= 0.0
    };
    let blocks = fill_blocks::<1, _, _>(lo, hi, skip, |ijk| [density(world(ijk))]);
    let mut parts = parts_for_channel("density", xf, &blocks, 0);
    parts.prune();
    Grid::from_parts(parts)
}

/// A plume: `density`, `flame`, `temperature` and `velocity` grids over a
/// Blender-like domain of 2.5 x 2.5 x 4.5 units, `res` voxels along z.
pub fn plume(res: u32, seed: u64) -> Result<Vec<AnyGrid>> {
    check_res(res)?;
    let nz = res as i32;
    let nxy = ((res as f64) * 2.5 / 4.5).round().max(4.0) as i32;
    let vs = 4.5 / res as f64;
    let xf = DAffine3::from_scale(DVec3::splat(vs));
    let z0 = 0.5f32;
    let fields = |ijk: IVec3| -> [f32; 6] {
        let p = ijk.as_vec3() * vs as f32;
        let h = p.z - z0;
        if !(-0.15..=3.9).contains(&h) {
            return [0.0; 6];
        }
        // The axis wanders with height; the column widens as it rises.
        let wander = Vec3::new(
            fbm(seed, Vec3::new(0.0, 0.0, p.z * 0.8), 3),
            fbm(seed ^ 1, Vec3::new(0.0, 0.0, p.z * 0.8), 3),
            0.0,
        ) * (0.25 * h.max(0.0));
        let axis = Vec3::new(1.25, 1.25, p.z) + wander;
        let rho = (p - axis).truncate().length();
        let r = 0.22 + 0.18 * h.max(0.0);
        let n = fbm(seed ^ 2, p * 3.5 - Vec3::new(0.0, 0.0, 1.0), 4);
        let top_fade = (1.0 - (h / 3.9).powi(2)).max(0.0);
        let base_fade = ((h + 0.15) / 0.3).clamp(0.0, 1.0);
        let core = (-(rho / r).powi(2) * 2.0).exp();
        let mut density = (core * (0.75 + 0.5 * n) * top_fade * base_fade * 1.2).clamp(0.0, 1.0);
        if density < 0.01 {
            density = 0.0;
        }
        let mut flame = if (0.0..1.2).contains(&h) {
            ((1.0 - h / 1.2) * (-(rho / (0.6 * r)).powi(2)).exp() * (0.8 + 0.6 * n)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        if flame < 0.005 {
            flame = 0.0;
        }
        let temperature = if flame > 0.01 { 1.5 + 1.5 * flame } else { 0.0 };
        let (vx, vy, vz) = if density > 0.0 {
            let d = (p - axis).truncate();
            (-d.y * 0.8, d.x * 0.8, 1.0 + 0.5 * core)
        } else {
            (0.0, 0.0, 0.0)
        };
        [density, flame, temperature, vx, vy, vz]
    };
    let lo = IVec3::ZERO;
    let hi = IVec3::new(nxy, nxy, nz) - 1;
    let hi = ((hi >> 3) << 3) + 7;
    let inside = |ijk: IVec3| ijk.cmplt(IVec3::new(nxy, nxy, nz)).all();
    let blocks = fill_blocks::<6, _, _>(
        lo,
        hi,
        |_| false,
        |ijk| {
            if inside(ijk) {
                fields(ijk)
            } else {
                [0.0; 6]
            }
        },
    );
    let mut grids = Vec::new();
    for (c, name) in ["density", "flame", "temperature"].iter().enumerate() {
        let p = parts_for_channel(name, xf, &blocks, c);
        grids.push(AnyGrid::Float(Grid::from_parts(p)?));
    }
    // velocity: a vec3s grid active where any component is nonzero.
    let mut v = GridParts::<Vec3>::new("velocity", Vec3::ZERO, xf);
    v.class = "staggered".into();
    for (o, vals, masks) in &blocks {
        let mut mask = [0u64; 8];
        for m in &masks[3..6] {
            for (w, word) in mask.iter_mut().enumerate() {
                *word |= m[w];
            }
        }
        if mask.iter().any(|&w| w != 0) {
            v.brick_origins.push(*o);
            v.masks.push(mask);
            v.values
                .extend((0..BRICK_VOXELS).map(|i| Vec3::new(vals[3][i], vals[4][i], vals[5][i])));
        }
    }
    grids.insert(0, AnyGrid::Vec3(Grid::from_parts(v)?));
    Ok(grids)
}
