//! Where each key of a scene file sits in its text, so errors can name lines.
//!
//! For TOML the positions come from the spans of the `toml::de::DeTable`
//! the scene was parsed into (built before serde consumes it); for JSON from a small lenient scanner (it
//! runs on text serde_json has at least partly accepted and never panics).

use std::ops::Range;

use toml::de::{DeTable, DeValue};

use super::error::PathSeg;

/// One key or array element. Entries form a tree (each names its parent
/// and its own step) rather than each holding its whole path: a scene with
/// a 100,000-element array would otherwise copy 100,000 paths to report
/// one error.
struct Entry {
    parent: Option<usize>,
    seg: PathSeg,
    depth: usize,
    key: Option<Range<usize>>,
    value: Range<usize>,
}

pub(crate) struct SourceMap<'a> {
    text: &'a str,
    entries: Vec<Entry>,
}

impl<'a> SourceMap<'a> {
    /// The map of a TOML document already parsed from `text` (parsing it
    /// again would double the cost of refusing a large scene).
    pub(crate) fn toml(text: &'a str, doc: &DeTable<'_>) -> Self {
        let mut entries = Vec::new();
        walk_toml_table(doc, None, &mut entries);
        SourceMap { text, entries }
    }

    pub(crate) fn json(text: &'a str) -> Self {
        let mut scan = JsonScan {
            s: text.as_bytes(),
            i: 0,
            depth: 0,
            entries: Vec::new(),
        };
        let _ = scan.value(None);
        SourceMap {
            text,
            entries: scan.entries,
        }
    }

    /// 1-based line of a byte offset.
    pub(crate) fn line_of_offset(&self, offset: usize) -> usize {
        line_of_offset(self.text, offset)
    }

    /// Line of the key at `path`, or of its nearest ancestor present in the
    /// file; `None` if no part of the path is in the file.
    pub(crate) fn line_of_path(&self, path: &[PathSeg]) -> Option<usize> {
        (1..=path.len()).rev().find_map(|n| {
            let e =
                self.entries.iter().enumerate().find_map(|(i, e)| {
                    (e.depth == n && self.path_is(i, &path[..n])).then_some(e)
                })?;
            let start = e.key.as_ref().map_or(e.value.start, |k| k.start);
            Some(self.line_of_offset(start))
        })
    }

    /// The deepest key or array element whose key or value contains `offset`.
    pub(crate) fn path_at(&self, offset: usize) -> Vec<PathSeg> {
        let contains = |r: &Range<usize>| r.start <= offset && offset < r.end.max(r.start + 1);
        self.entries
            .iter()
            .enumerate()
            .filter(|(_, e)| contains(&e.value) || e.key.as_ref().is_some_and(contains))
            .max_by_key(|(_, e)| (e.depth, usize::MAX - e.value.len()))
            .map(|(i, _)| self.path_of(i))
            .unwrap_or_default()
    }

    /// The whole path of entry `i`.
    fn path_of(&self, i: usize) -> Vec<PathSeg> {
        let mut path = Vec::with_capacity(self.entries[i].depth);
        let mut at = Some(i);
        while let Some(j) = at {
            path.push(self.entries[j].seg.clone());
            at = self.entries[j].parent;
        }
        path.reverse();
        path
    }

    /// Whether entry `i`'s path is `path` (its depth already matches).
    fn path_is(&self, i: usize, path: &[PathSeg]) -> bool {
        let mut at = Some(i);
        path.iter().rev().all(|seg| {
            let Some(j) = at else { return false };
            at = self.entries[j].parent;
            self.entries[j].seg == *seg
        })
    }
}

pub(crate) fn line_of_offset(text: &str, offset: usize) -> usize {
    let end = offset.min(text.len());
    1 + text.as_bytes()[..end]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
}

/// Byte offset of a 1-based line and column (serde_json convention: column 0
/// means "before the first character").
pub(crate) fn offset_of_line_col(text: &str, line: usize, column: usize) -> usize {
    let line_start = if line <= 1 {
        0
    } else {
        text.match_indices('\n')
            .nth(line - 2)
            .map_or(text.len(), |(i, _)| i + 1)
    };
    (line_start + column.saturating_sub(1)).min(text.len())
}

fn depth_of(out: &[Entry], parent: Option<usize>) -> usize {
    parent.map_or(1, |p| out[p].depth + 1)
}

fn walk_toml_table(table: &DeTable<'_>, parent: Option<usize>, out: &mut Vec<Entry>) {
    for (k, v) in table.iter() {
        out.push(Entry {
            parent,
            seg: PathSeg::Key(k.get_ref().to_string()),
            depth: depth_of(out, parent),
            key: Some(k.span()),
            value: v.span(),
        });
        walk_toml_value(v.get_ref(), out.len() - 1, out);
    }
}

fn walk_toml_value(value: &DeValue<'_>, me: usize, out: &mut Vec<Entry>) {
    match value {
        DeValue::Table(t) => walk_toml_table(t, Some(me), out),
        DeValue::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                out.push(Entry {
                    parent: Some(me),
                    seg: PathSeg::Index(i),
                    depth: out[me].depth + 1,
                    key: None,
                    value: item.span(),
                });
                walk_toml_value(item.get_ref(), out.len() - 1, out);
            }
        }
        _ => {}
    }
}

struct JsonScan<'a> {
    s: &'a [u8],
    i: usize,
    depth: usize,
    entries: Vec<Entry>,
}

impl JsonScan<'_> {
    const MAX_DEPTH: usize = 256;

    fn peek(&self) -> Option<u8> {
        self.s.get(self.i).copied()
    }

    fn ws(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\n' | b'\r')) {
            self.i += 1;
        }
    }

    fn eat(&mut self, c: u8) -> Option<()> {
        self.ws();
        (self.peek()? == c).then(|| self.i += 1)
    }

    /// Parses one value; records an entry for every object member and array
    /// element. Returns `None` on malformed input (entries of unfinished
    /// containers then extend to the end of the text).
    fn value(&mut self, me: Option<usize>) -> Option<()> {
        self.ws();
        match self.peek()? {
            b'{' => self.container(me, b'}', true),
            b'[' => self.container(me, b']', false),
            b'"' => self.string().map(drop),
            _ => {
                let start = self.i;
                while let Some(c) = self.peek() {
                    if matches!(c, b',' | b']' | b'}' | b':' | b' ' | b'\t' | b'\n' | b'\r') {
                        break;
                    }
                    self.i += 1;
                }
                (self.i > start).then_some(())
            }
        }
    }

    fn container(&mut self, parent: Option<usize>, close: u8, object: bool) -> Option<()> {
        if self.depth >= Self::MAX_DEPTH {
            return None;
        }
        self.depth += 1;
        self.i += 1;
        self.ws();
        if self.peek() == Some(close) {
            self.i += 1;
            self.depth -= 1;
            return Some(());
        }
        let mut index = 0;
        loop {
            self.ws();
            let (seg, key) = if object {
                let start = self.i;
                let name = self.string()?;
                let span = start..self.i;
                self.eat(b':')?;
                (PathSeg::Key(name), Some(span))
            } else {
                index += 1;
                (PathSeg::Index(index - 1), None)
            };
            self.ws();
            let start = self.i;
            // Pushed before its value is scanned, so that the value's own
            // entries can name it; its end is set after.
            let me = self.entries.len();
            self.entries.push(Entry {
                parent,
                seg,
                depth: depth_of(&self.entries, parent),
                key,
                value: start..self.s.len(),
            });
            let ok = self.value(Some(me));
            if ok.is_some() {
                self.entries[me].value.end = self.i;
            }
            ok?;
            self.ws();
            match self.peek()? {
                b',' => self.i += 1,
                c if c == close => {
                    self.i += 1;
                    self.depth -= 1;
                    return Some(());
                }
                _ => return None,
            }
        }
    }

    /// A JSON string starting at `self.i`, decoded (escapes handled leniently).
    fn string(&mut self) -> Option<String> {
        if self.peek()? != b'"' {
            return None;
        }
        self.i += 1;
        let mut out = Vec::new();
        loop {
            let c = self.peek()?;
            self.i += 1;
            match c {
                b'"' => return Some(String::from_utf8_lossy(&out).into_owned()),
                b'\\' => {
                    let e = self.peek()?;
                    self.i += 1;
                    match e {
                        b'n' => out.push(b'\n'),
                        b't' => out.push(b'\t'),
                        b'r' => out.push(b'\r'),
                        b'b' => out.push(8),
                        b'f' => out.push(12),
                        b'u' => {
                            let hex = self.s.get(self.i..self.i + 4)?;
                            self.i += 4;
                            let code = std::str::from_utf8(hex)
                                .ok()
                                .and_then(|h| u32::from_str_radix(h, 16).ok())
                                .and_then(char::from_u32)
                                .unwrap_or(char::REPLACEMENT_CHARACTER);
                            let mut buf = [0u8; 4];
                            out.extend_from_slice(code.encode_utf8(&mut buf).as_bytes());
                        }
                        other => out.push(other),
                    }
                }
                other => out.push(other),
            }
        }
    }
}
