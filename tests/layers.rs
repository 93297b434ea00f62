//! The library's layers, as ARCHITECTURE.md draws them ("Layers"): every
//! `crate::` path in a module may only name a module of its own layer or a
//! lower one, and no two files import each other, directly or round a
//! circle. Read from the source as a newcomer reads it: the paths after
//! `crate::` and `super::` in code (comments and `#[cfg(test)]` tails left
//! out), each resolved to the deepest module file it names.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Lowest first. A module imports from its own layer or those above it in
/// this list, never from one below.
const LAYERS: &[(&str, &[&str])] = &[
    (
        "core",
        &[
            "error",
            "atomic",
            "memory",
            "interrupt",
            "stats",
            "sampling",
            "ray",
            "units",
        ],
    ),
    ("data", &["grid", "image", "sequence", "scene", "denoise"]),
    ("files", &["vdb", "generate", "mesh"]),
    (
        "optics",
        &[
            "phase", "light", "medium", "camera", "shape", "bsdf", "surface",
        ],
    ),
    ("world", &["world", "tracking"]),
    ("transport", &["photon", "film"]),
    ("integrators", &["integrator"]),
    (
        "orchestration",
        &[
            "render",
            "frames",
            "merge",
            "quicklook",
            "inspect",
            "export",
        ],
    ),
];

fn layer_of(module: &str) -> Option<usize> {
    LAYERS.iter().position(|(_, ms)| ms.contains(&module))
}

/// Every `.rs` file under `dir`, relative to `root`.
fn rust_files(root: &Path, dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            // The command line is a client of the library, not a layer.
            if p.file_name().is_some_and(|n| n == "bin") {
                continue;
            }
            rust_files(root, &p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p.strip_prefix(root).unwrap().to_path_buf());
        }
    }
}

/// The module path of a file: `integrator/mod.rs` → [integrator].
fn module_of(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .with_extension("")
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
        parts.pop();
    }
    parts
}

/// The code of a file: line comments (and so doc comments) removed, and
/// everything from the first `#[cfg(test)]` on (unit tests may reach
/// anywhere).
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]") {
        Some(i) => &text[..i],
        None => text,
    };
    text.lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The module paths after each `prefix` (`crate::`, `super::`) in `code`.
fn paths_after(code: &str, prefix: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let mut rest = code;
    while let Some(i) = rest.find(prefix) {
        let before = rest[..i].chars().last();
        rest = &rest[i + prefix.len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let mut segs = Vec::new();
        let mut s = rest;
        loop {
            let end = s
                .find(|c: char| !(c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_'))
                .unwrap_or(s.len());
            if end == 0 {
                break;
            }
            segs.push(s[..end].to_string());
            match s[end..].strip_prefix("::") {
                Some(t) => s = t,
                None => break,
            }
        }
        if !segs.is_empty() {
            out.push(segs);
        }
    }
    out
}

struct Graph {
    /// File → the files it imports.
    edges: BTreeMap<PathBuf, BTreeSet<PathBuf>>,
}

fn graph() -> Graph {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&root, &root, &mut files);
    // The library's modules are those lib.rs declares (build.rs's helper
    // beside them is not one).
    let lib = std::fs::read_to_string(root.join("lib.rs")).unwrap();
    let declared: BTreeSet<String> = lib
        .lines()
        .filter_map(|l| {
            l.trim()
                .strip_prefix("pub mod ")
                .or(l.trim().strip_prefix("mod "))
        })
        .map(|m| m.trim_end_matches(';').trim().to_string())
        .collect();
    files.retain(|f| f == Path::new("lib.rs") || declared.contains(&top(f)));
    let modules: BTreeMap<Vec<String>, PathBuf> =
        files.iter().map(|f| (module_of(f), f.clone())).collect();
    let resolve = |path: &[String]| {
        (1..=path.len())
            .rev()
            .find_map(|n| modules.get(&path[..n]).cloned())
    };
    let mut edges = BTreeMap::new();
    for f in &files {
        if f == Path::new("lib.rs") {
            continue;
        }
        let code = code_of(&std::fs::read_to_string(root.join(f)).unwrap());
        let me = module_of(f);
        let mut to = BTreeSet::new();
        for p in paths_after(&code, "crate::") {
            to.extend(resolve(&p));
        }
        for p in paths_after(&code, "super::") {
            let mut full = me[..me.len().saturating_sub(1)].to_vec();
            full.extend(p);
            to.extend(resolve(&full));
        }
        to.remove(f);
        to.remove(Path::new("lib.rs"));
        edges.insert(f.clone(), to);
    }
    Graph { edges }
}

fn top(f: &Path) -> String {
    module_of(f).first().cloned().unwrap_or_default()
}

#[test]
fn every_module_has_a_layer() {
    let g = graph();
    let missing: BTreeSet<String> = g
        .edges
        .keys()
        .map(|f| top(f))
        .filter(|m| layer_of(m).is_none())
        .collect();
    assert!(
        missing.is_empty(),
        "modules without a layer (add them to LAYERS here and to ARCHITECTURE.md): {missing:?}"
    );
}

#[test]
fn imports_go_down_the_layers() {
    let g = graph();
    let mut wrong = Vec::new();
    for (f, to) in &g.edges {
        let (Some(la), a) = (layer_of(&top(f)), top(f)) else {
            continue;
        };
        for t in to {
            let b = top(t);
            if let Some(lb) = layer_of(&b) {
                if lb > la {
                    wrong.push(format!(
                        "{} ({}) imports {} ({}), a higher layer",
                        f.display(),
                        LAYERS[la].0,
                        t.display(),
                        LAYERS[lb].0
                    ));
                }
            }
            let _ = &a;
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// No circle of imports between files (Tarjan's strongly connected
/// components; a parent module's `mod.rs` naming its own children's items
/// through relative paths is not an import here).
#[test]
fn no_import_circles() {
    let g = graph();
    let nodes: Vec<&PathBuf> = g.edges.keys().collect();
    let index_of: BTreeMap<&PathBuf, usize> =
        nodes.iter().enumerate().map(|(i, n)| (*n, i)).collect();
    let adj: Vec<Vec<usize>> = nodes
        .iter()
        .map(|n| {
            g.edges[*n]
                .iter()
                .filter_map(|t| index_of.get(t).copied())
                .collect()
        })
        .collect();
    // Iterative Tarjan.
    let n = nodes.len();
    let (mut index, mut low) = (vec![usize::MAX; n], vec![0; n]);
    let (mut on, mut stack, mut next) = (vec![false; n], Vec::new(), 0);
    let mut circles = Vec::new();
    for s in 0..n {
        if index[s] != usize::MAX {
            continue;
        }
        let mut work = vec![(s, 0usize)];
        while let Some(&mut (v, ref mut k)) = work.last_mut() {
            if *k == 0 {
                index[v] = next;
                low[v] = next;
                next += 1;
                stack.push(v);
                on[v] = true;
            }
            if let Some(&w) = adj[v].get(*k) {
                *k += 1;
                if index[w] == usize::MAX {
                    work.push((w, 0));
                } else if on[w] {
                    low[v] = low[v].min(index[w]);
                }
                continue;
            }
            work.pop();
            if let Some(&(u, _)) = work.last() {
                low[u] = low[u].min(low[v]);
            }
            if low[v] == index[v] {
                let mut comp = Vec::new();
                loop {
                    let w = stack.pop().unwrap();
                    on[w] = false;
                    comp.push(nodes[w].display().to_string());
                    if w == v {
                        break;
                    }
                }
                if comp.len() > 1 {
                    comp.sort();
                    circles.push(comp.join(" <-> "));
                }
            }
        }
    }
    assert!(
        circles.is_empty(),
        "import circles:\n{}",
        circles.join("\n")
    );
}

/// The checker finds what it should: a file that names a higher layer,
/// and a circle, in a made-up source.
#[test]
fn the_checker_sees_imports() {
    let code = code_of(
        "use crate::render::passes::tiles; // crate::frames in a comment\n\
         fn f() { crate::image::Image::new(); super::x::y(); }\n\
         #[cfg(test)]\nmod tests { use crate::merge; }",
    );
    let c: Vec<String> = paths_after(&code, "crate::")
        .iter()
        .map(|p| p.join("::"))
        .collect();
    assert_eq!(c, ["render::passes::tiles", "image"]);
    assert_eq!(paths_after(&code, "super::"), [vec!["x", "y"]]);
    assert!(layer_of("render") > layer_of("integrator"));
    assert!(layer_of("scene") < layer_of("medium"));
}
