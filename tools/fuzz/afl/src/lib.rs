//! What the AFL++ targets share: how an input's first byte picks the scene
//! format.

use vdbphoton::scene::SceneFormat;

/// The scene format an input's first byte picks (even: TOML, odd: JSON)
/// and the bytes after it; `None` for an empty input.
pub fn format_and_rest(data: &[u8]) -> Option<(SceneFormat, &[u8])> {
    let (&first, rest) = data.split_first()?;
    let format = if first % 2 == 0 {
        SceneFormat::Toml
    } else {
        SceneFormat::Json
    };
    Some((format, rest))
}
