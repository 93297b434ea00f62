//! Errors. Every [`SceneError`] displays as one line starting with the scene
//! file's name (`scene.toml:14: ...` when the line is known).

use std::fmt;

use thiserror::Error;

/// One step of a key path inside a scene file: a table key or an array index.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum PathSeg {
    Key(String),
    Index(usize),
}

impl From<&str> for PathSeg {
    fn from(k: &str) -> Self {
        PathSeg::Key(k.to_owned())
    }
}

impl From<usize> for PathSeg {
    fn from(i: usize) -> Self {
        PathSeg::Index(i)
    }
}

/// Builds a `Vec<PathSeg>` from keys (`&str`) and indices (`usize`).
macro_rules! kp {
    ($($seg:expr),* $(,)?) => {
        Vec::<$crate::scene::error::PathSeg>::from([$($crate::scene::error::PathSeg::from($seg)),*])
    };
}
pub(crate) use kp;

/// `volume[0].material.anisotropy`.
pub fn dotted(path: &[PathSeg]) -> String {
    let mut s = String::new();
    for seg in path {
        match seg {
            PathSeg::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            PathSeg::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

/// Tables written as `[[name]]`.
const ARRAY_TABLES: [&str; 3] = ["light", "volume", "mesh"];
/// Sub-tables of `[[volume]]` and `[[mesh]]` usually written as
/// `[volume.name]` headers.
const VOLUME_SUBTABLES: [&str; 3] = ["material", "transform", "visibility"];

/// Splits a key path into the TOML section it lives in (`in [render]`,
/// `in [[volume]]`, `in [volume.material]`, `at top level`) and the key
/// within that section (`phase.lobes[1].g`), if any.
pub fn split_path(path: &[PathSeg]) -> (String, Option<String>) {
    let top = match path.first() {
        Some(PathSeg::Key(k)) if path.len() > 1 => k.as_str(),
        _ => {
            return (
                "at top level".to_owned(),
                Some(dotted(path)).filter(|k| !k.is_empty()),
            )
        }
    };
    let (mut section, mut rest) = match &path[1] {
        PathSeg::Index(_) if ARRAY_TABLES.contains(&top) => (format!("[[{top}]]"), &path[2..]),
        _ => (format!("[{top}]"), &path[1..]),
    };
    // `[render.NAME]`: an integrator's settings table.
    if top == "render" && rest.len() > 1 {
        if let PathSeg::Key(sub) = &rest[0] {
            section = format!("[render.{sub}]");
            rest = &rest[1..];
        }
    }
    if (top == "volume" || top == "mesh") && rest.len() > 1 {
        if let PathSeg::Key(sub) = &rest[0] {
            if VOLUME_SUBTABLES.contains(&sub.as_str()) {
                section = format!("[{top}.{sub}]");
                rest = &rest[1..];
            }
        }
    }
    let key = Some(dotted(rest)).filter(|k| !k.is_empty());
    (format!("in {section}"), key)
}

/// `key 'width' in [render]`, `[[volume]]`, ...
pub fn describe(path: &[PathSeg]) -> String {
    match split_path(path) {
        (section, Some(key)) => format!("key '{key}' {section}"),
        (section, None) => section.trim_start_matches("in ").to_owned(),
    }
}

/// A semantic error in a scene description: which key, what is wrong.
/// `path` uses the key names of the scene file.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub struct ValidationError {
    pub path: Vec<PathSeg>,
    pub message: String,
}

impl ValidationError {
    pub fn new(path: Vec<PathSeg>, message: impl Into<String>) -> Self {
        ValidationError {
            path,
            message: message.into(),
        }
    }

    /// The key path as `volume[0].material.anisotropy`.
    pub fn key_path(&self) -> String {
        dotted(&self.path)
    }
}

impl fmt::Display for ValidationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.path.is_empty() {
            f.write_str(&self.message)
        } else {
            write!(f, "{}: {}", describe(&self.path), self.message)
        }
    }
}

fn at_line(line: &Option<usize>) -> String {
    line.map(|l| format!(":{l}")).unwrap_or_default()
}

/// Anything that can go wrong loading a scene.
#[derive(Debug, Error)]
pub enum SceneError {
    /// The file could not be read (missing, permissions, ...).
    #[error("{file}: cannot read scene file: {source}")]
    Read {
        file: String,
        #[source]
        source: std::io::Error,
    },
    /// The path names a directory.
    #[error("{file}: is a directory, not a scene file")]
    NotAFile { file: String },
    /// Malformed TOML/JSON, unknown key, wrong type, missing key.
    #[error("{file}{}: {message}", at_line(.line))]
    Parse {
        file: String,
        line: Option<usize>,
        message: String,
    },
    /// The file parsed but describes an invalid scene.
    #[error("{file}{}: {error}", at_line(.line))]
    Invalid {
        file: String,
        line: Option<usize>,
        error: ValidationError,
    },
}

impl SceneError {
    /// The 1-based line the error refers to, when known.
    pub fn line(&self) -> Option<usize> {
        match self {
            SceneError::Parse { line, .. } | SceneError::Invalid { line, .. } => *line,
            _ => None,
        }
    }
}

/// Backtick-quoted names in a serde message tail (`expected one of `a`, `b``).
fn ticked(s: &str) -> Vec<&str> {
    s.split('`').skip(1).step_by(2).collect()
}

/// The first backticked name and what follows it.
fn first_ticked(s: &str) -> Option<(&str, &str)> {
    let (name, tail) = s.split_once('`')?;
    Some((name, tail))
}

fn expected(tail: &str) -> String {
    let names = ticked(tail);
    if names.is_empty() {
        "nothing".to_owned()
    } else {
        names.join(", ")
    }
}

/// The expected name closest to a misspelt `name`, if one is close: at
/// most two edits away (a third of the name for short names), or `name`
/// with a trailing `s` (`lights`).
fn closest<'a>(name: &str, expected: &[&'a str]) -> Option<&'a str> {
    fn distance(a: &str, b: &str) -> usize {
        let b: Vec<char> = b.chars().collect();
        let mut row: Vec<usize> = (0..=b.len()).collect();
        for (i, ca) in a.chars().enumerate() {
            let mut prev = row[0];
            row[0] = i + 1;
            for j in 0..b.len() {
                let cur = row[j + 1];
                row[j + 1] = (prev + usize::from(ca != b[j]))
                    .min(row[j] + 1)
                    .min(cur + 1);
                prev = cur;
            }
        }
        row[b.len()]
    }
    let limit = (name.chars().count() / 3).clamp(1, 2);
    expected
        .iter()
        .map(|e| (distance(name, e), *e))
        .filter(|(d, _)| *d <= limit)
        .min_by_key(|(d, _)| *d)
        .map(|(_, e)| e)
}

fn with_key(path: &[PathSeg], key: &str) -> Vec<PathSeg> {
    let mut full = path.to_vec();
    if full.last() != Some(&PathSeg::Key(key.to_owned())) {
        full.push(PathSeg::Key(key.to_owned()));
    }
    full
}

/// Rewrites a serde data error (`unknown field `x`, expected ...`) at `path`
/// (the innermost key or table containing the error position) into this
/// crate's wording, naming the key and its section.
pub(crate) fn rewrite_serde_message(msg: &str, path: &[PathSeg]) -> String {
    let msg = msg.replace(['\n', '\r'], " ");
    if let Some((name, tail)) = msg.strip_prefix("unknown field `").and_then(first_ticked) {
        let close = closest(name, &ticked(tail));
        // A misspelt top-level table (`[[lights]]`): the error points into
        // the table itself.
        if path.len() > 1 && path.first() == Some(&PathSeg::Key(name.to_owned())) {
            let (open, end) = match path.get(1) {
                Some(PathSeg::Index(_)) => ("[[", "]]"),
                _ => ("[", "]"),
            };
            let table = format!("{open}{name}{end}");
            let hint = close
                .map(|c| format!("; did you mean {open}{c}{end}?"))
                .unwrap_or_default();
            return format!(
                "unknown table {table} (expected one of: {}{hint})",
                expected(tail)
            );
        }
        let hint = close
            .map(|c| format!("; did you mean '{c}'?"))
            .unwrap_or_default();
        let (section, key) = split_path(&with_key(path, name));
        let key = key.unwrap_or_else(|| name.to_owned());
        return format!(
            "unknown key '{key}' {section} (expected one of: {}{hint})",
            expected(tail)
        );
    }
    if let Some((value, tail)) = msg.strip_prefix("unknown variant `").and_then(first_ticked) {
        return format!(
            "unknown value '{value}' for {} (expected one of: {})",
            describe(path),
            expected(tail)
        );
    }
    for (prefix, what) in [
        ("missing field `", "missing key"),
        ("duplicate field `", "duplicate key"),
    ] {
        if let Some((name, _)) = msg.strip_prefix(prefix).and_then(first_ticked) {
            let (section, key) = split_path(&with_key(path, name));
            let key = key.unwrap_or_else(|| name.to_owned());
            return format!("{what} '{key}' {section}");
        }
    }
    if let [PathSeg::Key(k)] = path {
        if ARRAY_TABLES.contains(&k.as_str()) && msg.ends_with("expected a sequence") {
            return format!("key '{k}' at top level: {msg} (write [[{k}]] with double brackets)");
        }
    }
    if path.is_empty() {
        msg
    } else {
        format!("{}: {msg}", describe(path))
    }
}

impl From<SceneError> for crate::error::Error {
    fn from(e: SceneError) -> Self {
        crate::error::Error::Scene(e.to_string())
    }
}
