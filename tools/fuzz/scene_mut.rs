//! Mutations of scene files (TOML and JSON): keys deleted, duplicated,
//! renamed, added and retyped, extreme numbers, NaN and infinities, huge
//! sizes and arrays, deep nesting, invalid UTF-8, and plain text damage.

use crate::rng::Rng;
use toml::Value;

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Format {
    Toml,
    Json,
}

/// A seed scene, parsed.
pub struct SceneSeed {
    pub name: String,
    pub value: Value,
}

enum Step {
    Key(String),
    Index(usize),
}

fn paths(v: &Value, prefix: &mut Vec<usize>, out: &mut Vec<Vec<usize>>) {
    out.push(prefix.clone());
    let n = match v {
        Value::Table(t) => t.len(),
        Value::Array(a) => a.len(),
        _ => 0,
    };
    for i in 0..n {
        prefix.push(i);
        let child = match v {
            Value::Table(t) => t.iter().nth(i).map(|(_, c)| c),
            Value::Array(a) => a.get(i),
            _ => None,
        };
        if let Some(c) = child {
            paths(c, prefix, out);
        }
        prefix.pop();
    }
}

fn step_of(v: &Value, i: usize) -> Option<Step> {
    match v {
        Value::Table(t) => t.keys().nth(i).map(|k| Step::Key(k.clone())),
        Value::Array(_) => Some(Step::Index(i)),
        _ => None,
    }
}

/// The node at `path` and its parent's step to it.
fn node_mut<'a>(v: &'a mut Value, path: &[usize]) -> Option<&'a mut Value> {
    let mut cur = v;
    for &i in path {
        cur = match step_of(cur, i)? {
            Step::Key(k) => cur.as_table_mut()?.get_mut(&k)?,
            Step::Index(j) => cur.as_array_mut()?.get_mut(j)?,
        };
    }
    Some(cur)
}

fn extreme(rng: &mut Rng) -> Value {
    match rng.below(4) {
        0 => Value::Integer(*rng.pick(&[
            0,
            -1,
            i64::MAX,
            i64::MIN,
            1 << 32,
            (1 << 31) - 1,
            1 << 53,
            4_000_000_000,
            1_000_000_000_000,
        ])),
        _ => Value::Float(*rng.pick(&[
            0.0,
            -0.0,
            -1.0,
            1e-300,
            1e-45,
            5e-324,
            1e6,
            1e12,
            1e30,
            3.4e38,
            1e39,
            1e308,
            -1e308,
            f64::MAX,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ])),
    }
}

fn other_type(rng: &mut Rng, v: &Value) -> Value {
    let options = [
        Value::String("abc".into()),
        Value::String(String::new()),
        Value::Integer(3),
        Value::Float(0.5),
        Value::Boolean(true),
        Value::Array(vec![]),
        Value::Array(vec![Value::Float(1.0), Value::String("x".into())]),
        Value::Table(Default::default()),
    ];
    loop {
        let o = rng.pick(&options).clone();
        if std::mem::discriminant(&o) != std::mem::discriminant(v) || rng.chance(0.1) {
            return o;
        }
    }
}

const KEYS: &[&str] = &[
    "width",
    "height",
    "spp",
    "max_bounces",
    "seed",
    "file",
    "density",
    "density_grid",
    "temperature_grid",
    "flame_grid",
    "color_grid",
    "type",
    "radiance",
    "irradiance",
    "intensity",
    "position",
    "direction",
    "angle",
    "vfov",
    "transform",
    "translate",
    "scale",
    "rotate",
    "matrix",
    "sigma_a",
    "sigma_s",
    "albedo",
    "anisotropy",
    "material",
    "integrator",
    "output",
    "unknown_key",
];

/// A tree mutation of `v`; returns what it did.
fn tree_mutation(rng: &mut Rng, v: &mut Value) -> &'static str {
    let mut all = Vec::new();
    paths(v, &mut Vec::new(), &mut all);
    let path = rng.pick(&all).clone();
    let r = rng.below(100);
    if r < 18 && !path.is_empty() {
        // Delete the node from its parent.
        let (last, parent) = path.split_last().unwrap();
        if let Some(p) = node_mut(v, parent) {
            match step_of(p, *last) {
                Some(Step::Key(k)) => drop(p.as_table_mut().and_then(|t| t.remove(&k))),
                Some(Step::Index(i)) => drop(p.as_array_mut().map(|a| a.remove(i))),
                None => {}
            }
        }
        return "key deleted";
    }
    let Some(node) = node_mut(v, &path) else {
        return "none";
    };
    if r < 40 {
        *node = extreme(rng);
        "extreme number"
    } else if r < 55 {
        let o = other_type(rng, node);
        *node = o;
        "retyped"
    } else if r < 65 {
        if let Value::Table(t) = node {
            t.insert(rng.pick(KEYS).to_string(), extreme(rng));
            "key added"
        } else {
            *node = Value::String("x".repeat(*rng.pick(&[0, 1, 300, 1 << 20])));
            "long string"
        }
    } else if r < 75 {
        if let Value::Array(a) = node {
            if let Some(first) = a.first().cloned() {
                let n = *rng.pick(&[2, 10, 1000, 100_000]);
                a.extend(std::iter::repeat_n(first, n));
                return "array lengthened";
            }
        }
        *node = Value::Array(vec![Value::Float(1.0); *rng.pick(&[0, 2, 4, 16])]);
        "wrong-length array"
    } else if r < 85 {
        if let Value::Table(t) = node {
            if let Some(k) = t.keys().nth(rng.below(t.len())).cloned() {
                let val = t.remove(&k).unwrap();
                let mut nk = k.clone();
                nk.push(*rng.pick(&['s', '_', 'x']));
                t.insert(nk, val);
                return "key renamed";
            }
        }
        "none"
    } else {
        // Huge sizes and counts where they mean something.
        let keys = [
            ("render", "width"),
            ("render", "height"),
            ("render", "spp"),
            ("render", "max_bounces"),
        ];
        let (t, k) = *rng.pick(&keys);
        if let Some(tab) = v
            .as_table_mut()
            .and_then(|r| r.get_mut(t))
            .and_then(|x| x.as_table_mut())
        {
            tab.insert(
                k.into(),
                Value::Integer(*rng.pick(&[0, 1 << 20, 1 << 31, 1 << 40, i64::MAX])),
            );
        }
        "huge size"
    }
}

/// Serialises a tree; `None` if the format cannot hold it.
fn serialise(v: &Value, format: Format) -> Option<String> {
    match format {
        Format::Toml => toml::to_string(v).ok(),
        Format::Json => serde_json::to_string_pretty(v).ok(),
    }
}

fn deep(format: Format, depth: usize) -> String {
    match format {
        Format::Toml => format!("deep = {}1{}\n", "[".repeat(depth), "]".repeat(depth)),
        Format::Json => format!("{}1{}", "[".repeat(depth), "]".repeat(depth)),
    }
}

fn text_mutation(rng: &mut Rng, text: Vec<u8>, format: Format) -> (Vec<u8>, &'static str) {
    let mut t = text;
    match rng.below(7) {
        0 => {
            // A line duplicated (a duplicate key, or a duplicate table).
            let s = String::from_utf8_lossy(&t).into_owned();
            let lines: Vec<&str> = s.lines().collect();
            if lines.is_empty() {
                return (t, "none");
            }
            let i = rng.below(lines.len());
            let mut out: Vec<&str> = lines.clone();
            out.insert(i, lines[i]);
            (out.join("\n").into_bytes(), "line duplicated")
        }
        1 => {
            for _ in 0..1 + rng.below(4) {
                let i = rng.below(t.len() + 1);
                let b = *rng.pick(&[0xff, 0xfe, 0xc0, 0x80, 0xed, 0xf4]);
                t.insert(i, b);
            }
            (t, "invalid UTF-8")
        }
        2 => {
            let depth = *rng.pick(&[64, 200, 2_000, 100_000, 1_000_000]);
            let d = deep(format, depth);
            match format {
                Format::Toml => {
                    let mut out = d.into_bytes();
                    out.extend(t);
                    (out, "deep nesting")
                }
                Format::Json => {
                    // As the value of a new first key.
                    let s = String::from_utf8_lossy(&t).into_owned();
                    let body = s.trim_start().strip_prefix('{').unwrap_or(&s).to_string();
                    (
                        format!("{{\"deep\": {d}, {body}").into_bytes(),
                        "deep nesting",
                    )
                }
            }
        }
        3 => {
            let n = rng.below(t.len() + 1);
            t.truncate(n);
            (t, "truncated")
        }
        4 => {
            for _ in 0..1 + rng.below(8) {
                if t.is_empty() {
                    break;
                }
                let i = rng.below(t.len());
                t[i] = *rng.pick(b"[]{}=,\"'.-+e0123456789 \n#xnaif");
            }
            (t, "characters changed")
        }
        5 => {
            // Non-finite literals where numbers are (TOML has them; JSON
            // does not, but some parsers accept them).
            let s = String::from_utf8_lossy(&t).into_owned();
            let lit = *rng.pick(&["nan", "inf", "-inf", "NaN", "Infinity", "1e999", "-1e999"]);
            let mut out = String::new();
            let mut replaced = false;
            for tok in s.split_inclusive([',', '[', ' ']) {
                let trimmed = tok.trim_end_matches([',', '[', ' ']);
                if !replaced && trimmed.parse::<f64>().is_ok() && rng.chance(0.3) {
                    out.push_str(lit);
                    out.push_str(&tok[trimmed.len()..]);
                    replaced = true;
                } else {
                    out.push_str(tok);
                }
            }
            (out.into_bytes(), "non-finite literal")
        }
        _ => {
            let i = rng.below(t.len() + 1);
            let j = (i + rng.below(64)).min(t.len());
            t.drain(i..j);
            (t, "run deleted")
        }
    }
}

/// A mutated scene from `seed` in `format`, with what was done. `vdb`
/// replaces every volume's file name (for renders of a mutated VDB).
pub fn mutate(
    rng: &mut Rng,
    seed: &SceneSeed,
    format: Format,
    vdb: Option<&str>,
) -> (Vec<u8>, Vec<&'static str>) {
    let mut v = seed.value.clone();
    if let Some(name) = vdb {
        if let Some(vols) = v.get_mut("volume").and_then(|x| x.as_array_mut()) {
            for vol in vols {
                if let Some(t) = vol.as_table_mut() {
                    t.insert("file".into(), Value::String(name.into()));
                }
            }
        }
    }
    let mut labels = Vec::new();
    let rounds = rng.below(4);
    for _ in 0..rounds {
        labels.push(tree_mutation(rng, &mut v));
    }
    let text = serialise(&v, format)
        .or_else(|| serialise(&seed.value, format))
        .unwrap_or_default()
        .into_bytes();
    if rounds == 0 || rng.chance(0.35) {
        let (t, l) = text_mutation(rng, text, format);
        labels.push(l);
        return (t, labels);
    }
    (text, labels)
}

/// Parses a seed scene file.
pub fn load_seed(path: &std::path::Path) -> Option<SceneSeed> {
    let text = std::fs::read_to_string(path).ok()?;
    let value = if path.extension().is_some_and(|e| e == "json") {
        serde_json::from_str::<Value>(&text).ok()?
    } else {
        toml::from_str::<Value>(&text).ok()?
    };
    Some(SceneSeed {
        name: path.display().to_string(),
        value,
    })
}
