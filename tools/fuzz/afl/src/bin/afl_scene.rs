//! AFL++ target: the scene parser and validator, in process. The first
//! byte picks the format (even: TOML, odd: JSON), the rest is the scene
//! text. A crash, an abort or a panic is a finding; a refusal is fine, and
//! so is an accepted scene, unless a number in it is not finite (what
//! `vdbfuzz` calls a wrong accept).

use vdbphoton::scene::SceneDesc;

/// `Debug` text with its quoted strings removed, so that a file named
/// `info.vdb` is not taken for an infinite number.
fn without_strings(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let (mut quoted, mut escaped) = (false, false);
    for c in s.chars() {
        if quoted {
            match (escaped, c) {
                (true, _) => escaped = false,
                (false, '\\') => escaped = true,
                (false, '"') => quoted = false,
                _ => {}
            }
        } else if c == '"' {
            quoted = true;
        } else {
            out.push(c);
        }
    }
    out
}

fn main() {
    afl::fuzz!(|data: &[u8]| {
        let Some((format, rest)) = vdbphoton_afl::format_and_rest(data) else {
            return;
        };
        // `SceneDesc::load` refuses text that is not UTF-8 before parsing.
        let Ok(text) = std::str::from_utf8(rest) else {
            return;
        };
        if let Ok(s) = SceneDesc::from_str_named(text, format, ".", "input") {
            let numbers = without_strings(&format!("{s:?}"));
            let bad = numbers
                .split(|c: char| !c.is_ascii_alphanumeric())
                .any(|w| w == "NaN" || w == "inf");
            assert!(!bad, "accepted a scene with a non-finite number: {s:?}");
        }
    });
}
