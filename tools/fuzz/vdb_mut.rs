//! Mutations of `.vdb` files that aim at what OpenVDB trusts: the fields the
//! header check and the grid walk read (lengths, counts, offsets, flags,
//! Blosc header sizes, masks, origins), truncations at every grid
//! boundary, byte flips and runs, and grid-level edits (grids swapped,
//! duplicated, removed, type names exchanged).

use crate::rng::Rng;
use vdbphoton::vdb::header::{self, GridDescriptor};
use vdbphoton::vdb::{file_fields, Field, FieldKind};

/// A seed file with what the mutations need to know about it.
pub struct Seed {
    pub name: String,
    pub bytes: Vec<u8>,
    pub fields: Vec<Field>,
    pub grids: Vec<GridDescriptor>,
}

impl Seed {
    pub fn new(name: String, bytes: Vec<u8>) -> Seed {
        let fields = file_fields(&bytes);
        let grids = header::parse(&mut &bytes[..], bytes.len() as u64)
            .map(|h| h.grids)
            .unwrap_or_default();
        Seed {
            name,
            bytes,
            fields,
            grids,
        }
    }
    /// Offsets where a grid's pieces begin and end.
    fn boundaries(&self) -> Vec<usize> {
        let mut b = vec![0, 8, 12, 20, 21, 57];
        for g in &self.grids {
            b.push(desc_start(g) as usize);
            b.extend([g.grid_pos, g.block_pos, g.end_pos].map(|x| x as usize));
        }
        b.retain(|&x| x <= self.bytes.len());
        b
    }
}

fn desc_len(g: &GridDescriptor) -> u64 {
    (12 + g.unique_name.len() + g.type_name.len() + g.instance_parent.len() + 24) as u64
}

fn desc_start(g: &GridDescriptor) -> u64 {
    g.grid_pos.saturating_sub(desc_len(g))
}

/// What one mutation did, for the report.
pub type Label = &'static str;

fn value8(rng: &mut Rng, old: i64) -> i64 {
    let random = rng.next_u64() as i64;
    *rng.pick(&[
        0,
        -1,
        1,
        i64::MAX,
        i64::MIN,
        1 << 31,
        1 << 32,
        1 << 62,
        -(1 << 31),
        old.wrapping_add(1),
        old.wrapping_sub(1),
        old.wrapping_add(8),
        old.wrapping_neg(),
        old.wrapping_mul(2),
        old / 2,
        -4096,
        -2048,
        random,
    ])
}

fn value4(rng: &mut Rng, old: u32) -> u32 {
    let random = rng.next_u64() as u32;
    *rng.pick(&[
        0,
        u32::MAX,
        1,
        1 << 31,
        (1 << 31) - 1,
        old.wrapping_add(1),
        old.wrapping_sub(1),
        old.wrapping_mul(2),
        old / 2,
        1 << 16,
        old.wrapping_add(4),
        random,
    ])
}

fn set_field(rng: &mut Rng, b: &mut [u8], f: &Field) {
    let at = f.offset as usize;
    let end = at + f.size as usize;
    if end > b.len() {
        return;
    }
    match (f.kind, f.size) {
        (_, 8) => {
            let old = i64::from_le_bytes(b[at..end].try_into().unwrap());
            b[at..end].copy_from_slice(&value8(rng, old).to_le_bytes());
        }
        (FieldKind::Flags, 4) => {
            let v = if rng.chance(0.2) {
                u32::MAX
            } else {
                rng.below(16) as u32
            };
            b[at..end].copy_from_slice(&v.to_le_bytes());
        }
        (_, 4) => {
            let old = u32::from_le_bytes(b[at..end].try_into().unwrap());
            b[at..end].copy_from_slice(&value4(rng, old).to_le_bytes());
        }
        (FieldKind::NodeMeta, _) => b[at] = *rng.pick(&[0, 1, 2, 3, 4, 5, 6, 7, 0x80, 0xff]),
        (FieldKind::BloscSizes, _) => {
            let w = at + 4 * rng.below(3);
            let old = u32::from_le_bytes(b[w..w + 4].try_into().unwrap());
            b[w..w + 4].copy_from_slice(&value4(rng, old).to_le_bytes());
        }
        (FieldKind::Origin, _) => {
            let c = at + 4 * rng.below(3);
            let old = i32::from_le_bytes(b[c..c + 4].try_into().unwrap());
            let v = *rng.pick(&[
                i32::MAX,
                i32::MIN,
                old.wrapping_add(1),
                old.wrapping_add(4096),
                0,
                -4096,
                i32::MAX & !4095,
            ]);
            b[c..c + 4].copy_from_slice(&v.to_le_bytes());
        }
        (FieldKind::Mask, n) => match rng.below(3) {
            0 => {
                let bit = rng.below(n as usize * 8);
                b[at + bit / 8] ^= 1 << (bit % 8);
            }
            1 => b[at..end].fill(0),
            _ => b[at..end].fill(0xff),
        },
        _ => {
            let i = at + rng.below(f.size as usize);
            b[i] = rng.next_u64() as u8;
        }
    }
}

/// One grid of a file, as pieces to lay out again.
#[derive(Clone)]
struct Piece {
    unique_name: String,
    type_name: String,
    parent: String,
    data: Vec<u8>,
    block_rel: Option<u64>,
}

fn pieces(s: &Seed, b: &[u8]) -> Option<(Vec<u8>, Vec<Piece>)> {
    let first = s.grids.first()?;
    let prefix = b
        .get(..(desc_start(first) as usize).checked_sub(4)?)?
        .to_vec();
    let mut out = Vec::new();
    for g in &s.grids {
        out.push(Piece {
            unique_name: g.unique_name.clone(),
            type_name: g.type_name.clone(),
            parent: g.instance_parent.clone(),
            data: b.get(g.grid_pos as usize..g.end_pos as usize)?.to_vec(),
            block_rel: g
                .instance_parent
                .is_empty()
                .then(|| g.block_pos - g.grid_pos),
        });
    }
    Some((prefix, out))
}

fn layout(prefix: &[u8], grids: &[Piece]) -> Vec<u8> {
    let mut b = prefix.to_vec();
    b.extend((grids.len() as i32).to_le_bytes());
    for g in grids {
        for s in [&g.unique_name, &g.type_name, &g.parent] {
            b.extend((s.len() as u32).to_le_bytes());
            b.extend(s.as_bytes());
        }
        let start = b.len() as i64 + 24;
        let block = g.block_rel.map_or(0, |r| start + r as i64);
        let end = start + g.data.len() as i64;
        for v in [start, block, end] {
            b.extend(v.to_le_bytes());
        }
        b.extend(&g.data);
    }
    b
}

/// Grid-level edits; `None` when the file has too few grids for it.
fn restructure(rng: &mut Rng, s: &Seed, b: &[u8]) -> Option<(Vec<u8>, Label)> {
    let (prefix, mut g) = pieces(s, b)?;
    let n = g.len();
    let label = match rng.below(6) {
        0 if n >= 2 => {
            let (i, j) = (rng.below(n), rng.below(n));
            g.swap(i, j);
            "grids swapped"
        }
        1 => {
            let i = rng.below(n);
            let mut d = g[i].clone();
            if rng.chance(0.5) {
                d.unique_name.push_str("\u{1e}1");
            }
            g.insert(rng.below(n + 1), d);
            "grid duplicated"
        }
        2 => {
            g.remove(rng.below(n));
            "grid removed"
        }
        3 if n >= 2 => {
            let (i, j) = (rng.below(n), rng.below(n));
            let t = g[i].type_name.clone();
            g[i].type_name = std::mem::replace(&mut g[j].type_name, t);
            "type names exchanged"
        }
        4 => {
            let i = rng.below(n);
            let t = &mut g[i].type_name;
            *t = match t.strip_suffix("_HalfFloat") {
                Some(base) => base.to_string(),
                None => format!("{t}_HalfFloat"),
            };
            "half-float flag toggled"
        }
        _ => {
            let i = rng.below(n);
            g[i].type_name = rng
                .pick(&[
                    "Tree_float_5_4_3",
                    "Tree_double_5_4_3",
                    "Tree_vec3s_5_4_3",
                    "Tree_int32_5_4_3",
                    "Tree_bool_5_4_3",
                    "Tree_float_5_4_3_HalfFloat",
                    "Tree_vec3s_5_4_3_HalfFloat",
                ])
                .to_string();
            "type name replaced"
        }
    };
    Some((layout(&prefix, &g), label))
}

/// A mutated copy of `s` (one to three mutations), with what was done.
pub fn mutate(rng: &mut Rng, s: &Seed, others: &[Seed]) -> (Vec<u8>, Vec<Label>) {
    let mut b = s.bytes.clone();
    let mut labels = Vec::new();
    let rounds = 1 + rng.below(3);
    for _ in 0..rounds {
        let r = rng.below(100);
        let label = if r < 42 && !s.fields.is_empty() {
            // Prefer the fields OpenVDB trusts most.
            let f = if rng.chance(0.5) {
                let hot: Vec<&Field> = s
                    .fields
                    .iter()
                    .filter(|f| {
                        matches!(
                            f.kind,
                            FieldKind::BlockLength | FieldKind::BloscSizes | FieldKind::NodeMeta
                        )
                    })
                    .collect();
                if hot.is_empty() {
                    rng.pick(&s.fields)
                } else {
                    *rng.pick(&hot)
                }
            } else {
                rng.pick(&s.fields)
            };
            set_field(rng, &mut b, f);
            match f.kind {
                FieldKind::BlockLength => "block length",
                FieldKind::BloscSizes => "Blosc header size",
                FieldKind::NodeMeta => "node metadata byte",
                FieldKind::Count => "count",
                FieldKind::Length => "length",
                FieldKind::Offset => "grid offset",
                FieldKind::Flags => "compression flags",
                FieldKind::Mask => "mask",
                FieldKind::Origin => "origin",
            }
        } else if r < 52 {
            match restructure(rng, s, &b) {
                Some((nb, l)) => {
                    b = nb;
                    l
                }
                None => continue,
            }
        } else if r < 66 {
            let bounds = s.boundaries();
            let at = if rng.chance(0.8) {
                let x = *rng.pick(&bounds) as i64 + *rng.pick(&[0i64, 0, 1, -1, 4, -8, 64]);
                x.clamp(0, b.len() as i64) as usize
            } else {
                rng.below(b.len() + 1)
            };
            b.truncate(at);
            "truncated"
        } else if r < 82 {
            for _ in 0..1 + rng.below(16) {
                if b.is_empty() {
                    break;
                }
                let i = rng.below(b.len());
                if rng.chance(0.5) {
                    b[i] ^= 1 << rng.below(8);
                } else {
                    b[i] = rng.next_u64() as u8;
                }
            }
            "bytes flipped"
        } else if r < 94 && !b.is_empty() {
            let i = rng.below(b.len());
            let len = (1 + rng.below(256)).min(b.len() - i);
            match rng.below(4) {
                0 => {
                    b[i..i + len].fill(0);
                    "run zeroed"
                }
                1 => {
                    let run = b[i..i + len].to_vec();
                    let j = rng.below(b.len() + 1);
                    b.splice(j..j, run);
                    "run duplicated"
                }
                2 => {
                    b.drain(i..i + len);
                    "run deleted"
                }
                _ => {
                    b[i..i + len].fill(0xff);
                    "run set to 0xff"
                }
            }
        } else if !others.is_empty() && !b.is_empty() {
            // Splice: a piece of another file over this one.
            let o = &rng.pick(others).bytes;
            if o.is_empty() {
                continue;
            }
            let i = rng.below(o.len());
            let len = (1 + rng.below(4096)).min(o.len() - i);
            let j = rng.below(b.len());
            let end = (j + len).min(b.len());
            b.splice(j..end, o[i..i + len].iter().copied());
            "spliced from another file"
        } else {
            continue;
        };
        labels.push(label);
    }
    (b, labels)
}
