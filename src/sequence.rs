//! Frame sequences: frame numbers in paths and lists of frames.
//!
//! A path names a sequence when it holds a frame pattern: `{frame}` (the
//! number as it is), `{frame:04}` (zero-padded to four digits; `{frame:4}`
//! is the same) or a run of `#` (`fluid_data_####.vdb`, Blender's own
//! spelling: padded to as many digits as there are `#`). Output paths may
//! also hold `{tile}`, the tile index of a `--tile I/N` render.
//!
//! A frame list is what `--frames` takes and Blender's frame ranges
//! write: `25`, `1-40`, `1-40:2` (every second frame), and lists of those
//! separated by commas (`1-3,5,7-20:2`).

use std::path::{Path, PathBuf};

/// Frame numbers are at most this (seven digits, as film frame numbers go).
pub const MAX_FRAME: u32 = 9_999_999;

/// The most frames one list may name: a render of a longer sequence is a
/// mistake in the list (`1-10000000`), not a job.
pub const MAX_FRAMES: usize = 1_000_000;

/// Parses a frame list (`1-40`, `1-3,5,7-20:2`) into ascending frame
/// numbers without repeats.
pub fn parse_frames(s: &str) -> Result<Vec<u32>, String> {
    let bad = |part: &str, why: &str| {
        format!(
            "'{part}' in the frame list '{s}': {why} (expected a frame like 25, a range like 1-40, or a range with a step like 1-40:2, separated by commas)"
        )
    };
    let number = |part: &str, t: &str| -> Result<u32, String> {
        let t = t.trim();
        if t.is_empty() || !t.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad(part, &format!("'{t}' is not a frame number")));
        }
        match t.parse::<u32>() {
            Ok(v) if v <= MAX_FRAME => Ok(v),
            _ => Err(bad(part, &format!("frame numbers go up to {MAX_FRAME}"))),
        }
    };
    if s.trim().is_empty() {
        return Err("the frame list is empty (give e.g. 1-40 or 25)".into());
    }
    let mut ranges = Vec::new();
    let mut count = 0usize;
    for part in s.split(',') {
        let p = part.trim();
        if p.is_empty() {
            return Err(bad(part, "an empty entry"));
        }
        let (range, step) = match p.split_once(':') {
            Some((r, st)) => {
                let st = number(p, st)?;
                if st == 0 {
                    return Err(bad(p, "the step must be at least 1"));
                }
                (r, st)
            }
            None => (p, 1),
        };
        let (a, b) = match range.split_once('-') {
            Some((a, b)) => (number(p, a)?, number(p, b)?),
            None => {
                let a = number(p, range)?;
                (a, a)
            }
        };
        if a > b {
            return Err(bad(p, "the range ends before it starts"));
        }
        count = count.saturating_add(((b - a) / step) as usize + 1);
        if count > MAX_FRAMES {
            return Err(format!(
                "the frame list '{s}' names more than {MAX_FRAMES} frames"
            ));
        }
        ranges.push((a, b, step));
    }
    let mut frames: Vec<u32> = ranges
        .into_iter()
        .flat_map(|(a, b, step)| (a..=b).step_by(step as usize))
        .collect();
    frames.sort_unstable();
    frames.dedup();
    Ok(frames)
}

/// Writes `frames` back as a short list (`1-40`, `1-3,5,7`): runs of
/// consecutive frames become ranges.
pub fn format_frames(frames: &[u32]) -> String {
    let mut out = Vec::new();
    let mut i = 0;
    while i < frames.len() {
        let mut j = i;
        while j + 1 < frames.len() && frames[j + 1] == frames[j] + 1 {
            j += 1;
        }
        out.push(if j == i {
            frames[i].to_string()
        } else {
            format!("{}-{}", frames[i], frames[j])
        });
        i = j + 1;
    }
    out.join(",")
}

/// One placeholder found in a path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Field {
    /// `{frame}`, `{frame:04}` or `####`: the frame, zero-padded to `pad`.
    Frame { pad: usize },
    /// `{tile}`: the tile index.
    Tile,
}

/// Splits a path into text and placeholders. `{...}` that starts with
/// `frame` or `tile` but is not one of the forms above is an error, so a
/// typo never silently becomes part of a file name; other braces are
/// text.
fn fields(s: &str) -> Result<Vec<(Option<Field>, &str)>, String> {
    let mut out = Vec::new();
    let mut rest = s;
    while !rest.is_empty() {
        let brace = rest.find('{');
        let hash = rest.find('#');
        let at = match (brace, hash) {
            (Some(a), Some(b)) => a.min(b),
            (Some(a), None) => a,
            (None, Some(b)) => b,
            (None, None) => {
                out.push((None, rest));
                break;
            }
        };
        if at > 0 {
            out.push((None, &rest[..at]));
            rest = &rest[at..];
            continue;
        }
        if rest.starts_with('#') {
            let n = rest.bytes().take_while(|&b| b == b'#').count();
            out.push((Some(Field::Frame { pad: n }), &rest[..n]));
            rest = &rest[n..];
            continue;
        }
        // At a '{'.
        let Some(close) = rest.find('}') else {
            out.push((None, rest));
            break;
        };
        let inner = &rest[1..close];
        let field = if inner == "frame" {
            Some(Field::Frame { pad: 0 })
        } else if let Some(spec) = inner.strip_prefix("frame:") {
            let digits = spec.strip_prefix('0').unwrap_or(spec);
            match digits.parse::<usize>() {
                Ok(p) if (1..=10).contains(&p) && !digits.starts_with('+') => {
                    Some(Field::Frame { pad: p })
                }
                _ => {
                    return Err(format!(
                        "'{{{inner}}}' in '{s}' is not a frame pattern: write {{frame}}, {{frame:04}} (zero-padded to 4 digits) or ####"
                    ))
                }
            }
        } else if inner == "tile" {
            Some(Field::Tile)
        } else if inner.starts_with("frame") || inner.starts_with("tile") {
            return Err(format!(
                "'{{{inner}}}' in '{s}' is not a pattern: write {{frame}}, {{frame:04}}, #### or {{tile}}"
            ));
        } else {
            None
        };
        out.push((field, &rest[..=close]));
        rest = &rest[close + 1..];
    }
    Ok(out)
}

/// A path as the user wrote it, with frame and tile placeholders.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PathPattern {
    text: String,
    has_frame: bool,
    has_tile: bool,
}

impl PathPattern {
    /// Reads the placeholders of `path`; an unknown `{frame...}` form is an
    /// error naming it. A path that is not UTF-8 holds no pattern.
    pub fn new(path: &Path) -> Result<Self, String> {
        let Some(text) = path.to_str() else {
            return Ok(Self {
                text: String::new(),
                has_frame: false,
                has_tile: false,
            });
        };
        let f = fields(text)?;
        Ok(Self {
            text: text.to_string(),
            has_frame: f
                .iter()
                .any(|(k, _)| matches!(k, Some(Field::Frame { .. }))),
            has_tile: f.iter().any(|(k, _)| matches!(k, Some(Field::Tile))),
        })
    }

    /// Whether the path names a frame sequence.
    pub fn has_frame(&self) -> bool {
        self.has_frame
    }

    /// Whether the path holds `{tile}`.
    pub fn has_tile(&self) -> bool {
        self.has_tile
    }

    /// The path of `frame` (and `tile`). A placeholder with no value to put
    /// in is kept as it is.
    pub fn expand(&self, frame: Option<u32>, tile: Option<u32>) -> PathBuf {
        let Ok(f) = fields(&self.text) else {
            return PathBuf::from(&self.text);
        };
        let mut s = String::with_capacity(self.text.len() + 8);
        for (field, text) in f {
            match (field, frame, tile) {
                (Some(Field::Frame { pad }), Some(fr), _) => {
                    s.push_str(&format!("{fr:0pad$}"));
                }
                (Some(Field::Tile), _, Some(t)) => s.push_str(&t.to_string()),
                _ => s.push_str(text),
            }
        }
        PathBuf::from(s)
    }

    /// The frames of the sequence whose files exist, ascending: the frame
    /// numbers read back from the names in the pattern's folder. Only the
    /// file name may hold the frame for this (a frame in a folder name is
    /// not searched).
    pub fn existing_frames(&self) -> Vec<u32> {
        let path = Path::new(&self.text);
        let (Some(dir), Some(name)) = (path.parent(), path.file_name().and_then(|n| n.to_str()))
        else {
            return Vec::new();
        };
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        let Ok(f) = fields(name) else {
            return Vec::new();
        };
        let Ok(entries) = std::fs::read_dir(dir) else {
            return Vec::new();
        };
        let mut frames: Vec<u32> = entries
            .filter_map(|e| e.ok())
            .filter_map(|e| e.file_name().to_str().and_then(|n| match_frame(&f, n)))
            .collect();
        frames.sort_unstable();
        frames.dedup();
        frames
    }
}

/// The frame number a file name holds where `f` has its frame field, if
/// the rest of the name matches.
fn match_frame(f: &[(Option<Field>, &str)], name: &str) -> Option<u32> {
    let mut rest = name;
    let mut frame = None;
    for (field, text) in f {
        match field {
            Some(Field::Frame { pad }) => {
                let n = rest.bytes().take_while(|b| b.is_ascii_digit()).count();
                if n == 0 || n < *pad {
                    return None;
                }
                let v: u32 = rest[..n].parse().ok()?;
                if frame.is_some_and(|f| f != v) {
                    return None;
                }
                frame = Some(v);
                rest = &rest[n..];
            }
            _ => rest = rest.strip_prefix(text)?,
        }
    }
    if rest.is_empty() {
        frame
    } else {
        None
    }
}

/// The seed of `frame` in a render seeded `seed`: neighbouring frames get
/// unrelated noise, and a frame rendered alone gets the seed it gets in a
/// sequence.
pub fn frame_seed(seed: u64, frame: u32) -> u64 {
    crate::sampling::mix64(seed ^ crate::sampling::mix64(0x6672_616d_6500_0000 | frame as u64))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_lists() {
        assert_eq!(parse_frames("25").unwrap(), vec![25]);
        assert_eq!(parse_frames("1-4").unwrap(), vec![1, 2, 3, 4]);
        assert_eq!(
            parse_frames("1-3,5,7-13:2").unwrap(),
            vec![1, 2, 3, 5, 7, 9, 11, 13]
        );
        assert_eq!(parse_frames(" 3 , 1-2, 2 ").unwrap(), vec![1, 2, 3]);
        assert_eq!(parse_frames("1001-1003").unwrap(), vec![1001, 1002, 1003]);
        for bad in [
            "",
            "1-",
            "-3",
            "a",
            "3-1",
            "1-4:0",
            "1,,2",
            "1-9999999999",
            "1.5",
        ] {
            assert!(parse_frames(bad).is_err(), "{bad}");
        }
        assert!(parse_frames("0-9999999").unwrap_err().contains("more than"));
        assert_eq!(format_frames(&[1, 2, 3, 5, 7, 8]), "1-3,5,7-8");
    }

    #[test]
    fn patterns() {
        let p = |s: &str| PathPattern::new(Path::new(s)).unwrap();
        assert!(!p("cloud.vdb").has_frame());
        assert_eq!(
            p("c/fluid_data_####.vdb").expand(Some(25), None),
            PathBuf::from("c/fluid_data_0025.vdb")
        );
        assert_eq!(
            p("f_{frame:04}.exr").expand(Some(7), None),
            PathBuf::from("f_0007.exr")
        );
        assert_eq!(
            p("f_{frame:4}.exr").expand(Some(12345), None),
            PathBuf::from("f_12345.exr")
        );
        assert_eq!(
            p("f_{frame}_t{tile}.exr").expand(Some(3), Some(2)),
            PathBuf::from("f_3_t2.exr")
        );
        assert_eq!(
            p("{x}/f.exr").expand(Some(3), None),
            PathBuf::from("{x}/f.exr")
        );
        assert!(p("f_{frame}.exr").has_frame() && !p("f_{frame}.exr").has_tile());
        for bad in [
            "f_{frame:x}.vdb",
            "f_{frames}.vdb",
            "f_{frame:}.vdb",
            "f_{tiles}.exr",
        ] {
            assert!(PathPattern::new(Path::new(bad)).is_err(), "{bad}");
        }
    }

    #[test]
    fn existing_frames_are_read_back_from_names() {
        let d = tempfile::tempdir().unwrap();
        for n in [
            "fluid_data_0001.vdb",
            "fluid_data_0003.vdb",
            "fluid_data_12.vdb",
            "other.vdb",
        ] {
            std::fs::write(d.path().join(n), b"").unwrap();
        }
        let p = PathPattern::new(&d.path().join("fluid_data_####.vdb")).unwrap();
        assert_eq!(p.existing_frames(), vec![1, 3]);
        let p = PathPattern::new(&d.path().join("fluid_data_{frame}.vdb")).unwrap();
        assert_eq!(p.existing_frames(), vec![1, 3, 12]);
    }

    #[test]
    fn frame_seeds_differ_and_repeat() {
        assert_ne!(frame_seed(0, 1), frame_seed(0, 2));
        assert_ne!(frame_seed(0, 1), frame_seed(1, 1));
        assert_eq!(frame_seed(5, 9), frame_seed(5, 9));
    }
}
