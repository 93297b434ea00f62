//! Scene files: parse a TOML (or JSON) scene into plain description structs
//! and validate them. This is the only module of the renderer that
//! deserialises with serde; it loads no VDB data, renders nothing and
//! knows no integrator (their settings tables stay generic values, which
//! each integrator checks: `crate::integrator::check_settings`).
//!
//! ```no_run
//! use vdbphoton::scene::SceneDesc;
//! let mut scene = SceneDesc::load("scene.toml")?;
//! scene.render.spp = 16; // a CLI override
//! scene.validate()?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The format is documented key by key in `docs/scene.md`.

mod desc;
mod error;
mod input;
mod source_map;
mod validate;

use std::path::Path;

/// Largest scene file read. A scene is a few kilobytes (volumes live in
/// `.vdb` files); parsing costs about 50 bytes of memory and 0.15 µs per
/// byte of TOML (a fuzzed 9.6 MB scene of 100,000 lights took 1.6 s and
/// 450 MB before it was refused), so a file this large is refused unread.
pub const MAX_SCENE_BYTES: u64 = 1 << 20;

pub use desc::{
    affine_from_rows, compose_trs, euler_xyz_deg, BlackbodyFilter, CameraDesc, CameraPose,
    DenoiseQuality, EnvironmentDesc, Lens, LightDesc, MaterialDesc, MeshDesc, MotionBlurDesc,
    Param, Params, PhaseDesc, Principled, RayVisibility, RenderDesc, SceneDesc, SensorFit,
    ShutterPosition, VelocityUnit, VolumeBounds, VolumeDesc, AUTO_INTEGRATOR, AUTO_VIEW_DIRECTION,
};
pub use desc::{ColorInput, PrincipledBsdf, SurfaceDesc, TextureColorSpace};
pub use error::{PathSeg, SceneError, ValidationError};
pub use validate::{MAX_PIXELS, MAX_SHUTTER};

use input::SceneIn;
use source_map::SourceMap;

/// A check of a parsed scene beyond its own rules (see
/// [`SceneDesc::load_with`]).
pub type Check<'a> = &'a dyn Fn(&SceneDesc) -> Result<(), ValidationError>;

/// Syntax of a scene file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SceneFormat {
    Toml,
    Json,
}

impl SceneFormat {
    /// JSON if the file name ends in `.json` (any case), TOML otherwise.
    pub fn from_path(path: &Path) -> SceneFormat {
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("json") => SceneFormat::Json,
            _ => SceneFormat::Toml,
        }
    }
}

impl SceneDesc {
    /// Reads, parses and validates a scene file. Relative paths inside it are
    /// resolved against the file's directory (made absolute). Error messages
    /// start with `path` as given.
    pub fn load(path: impl AsRef<Path>) -> Result<SceneDesc, SceneError> {
        Self::load_with(path, &|_| Ok(()))
    }

    /// Like [`SceneDesc::load`], with one more check of the parsed scene
    /// whose errors point at the scene file's lines as the scene's own do:
    /// the renderer passes the integrators' check of their settings tables
    /// (`crate::integrator::check_settings`), which this module cannot
    /// know.
    pub fn load_with(path: impl AsRef<Path>, check: Check) -> Result<SceneDesc, SceneError> {
        let path = path.as_ref();
        let file = path.display().to_string();
        if path.is_dir() {
            return Err(SceneError::NotAFile { file });
        }
        let read_error = |source| SceneError::Read {
            file: file.clone(),
            source,
        };
        let mut f = std::fs::File::open(path).map_err(read_error)?;
        // Read at most one byte past the limit: the size a file reports
        // (a pipe, a growing file) need not be what it holds.
        let mut bytes = Vec::new();
        std::io::Read::read_to_end(
            &mut std::io::Read::take(&mut f, MAX_SCENE_BYTES + 1),
            &mut bytes,
        )
        .map_err(read_error)?;
        if bytes.len() as u64 > MAX_SCENE_BYTES {
            return Err(SceneError::Parse {
                file,
                line: None,
                message: format!(
                    "the scene file is larger than {} MiB; scenes describe volumes, they do not hold them",
                    MAX_SCENE_BYTES >> 20
                ),
            });
        }
        let text = String::from_utf8(bytes).map_err(|e| {
            let valid = e.utf8_error().valid_up_to();
            let line = 1 + e.as_bytes()[..valid]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
            SceneError::Parse {
                file: file.clone(),
                line: Some(line),
                message: "file is not valid UTF-8 text".to_owned(),
            }
        })?;
        let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
        let base = absolute.parent().unwrap_or(Path::new(""));
        Self::from_str_checked(&text, SceneFormat::from_path(path), base, &file, check)
    }

    /// Parses and validates scene text; relative paths are resolved against
    /// `base_dir`. Error messages start with `<string>`.
    pub fn from_str(
        text: &str,
        format: SceneFormat,
        base_dir: impl AsRef<Path>,
    ) -> Result<SceneDesc, SceneError> {
        Self::from_str_named(text, format, base_dir, "<string>")
    }

    /// Like [`SceneDesc::from_str`], with `name` heading error messages.
    pub fn from_str_named(
        text: &str,
        format: SceneFormat,
        base_dir: impl AsRef<Path>,
        name: &str,
    ) -> Result<SceneDesc, SceneError> {
        Self::from_str_checked(text, format, base_dir, name, &|_| Ok(()))
    }

    /// Like [`SceneDesc::from_str_named`], with one more check (as
    /// [`SceneDesc::load_with`]).
    pub fn from_str_checked(
        text: &str,
        format: SceneFormat,
        base_dir: impl AsRef<Path>,
        name: &str,
        check: Check,
    ) -> Result<SceneDesc, SceneError> {
        let (input, toml_map) = match format {
            SceneFormat::Toml => {
                let (input, map) = parse_toml(text, name)?;
                (input, Some(map))
            }
            SceneFormat::Json => (parse_json(text, name)?, None),
        };
        let flat = input.render.flat_photon_keys();
        let invalid = |mut error: ValidationError| {
            // A deprecated flat key's error names it where it was written.
            if let [PathSeg::Key(r), PathSeg::Key(t), PathSeg::Key(k)] = &error.path[..] {
                if r == "render" && t == "photon" && flat.contains(&k.as_str()) {
                    error.path = vec![PathSeg::Key(r.clone()), PathSeg::Key(k.clone())];
                }
            }
            let json_map;
            let map = match &toml_map {
                Some(map) => map,
                None => {
                    json_map = SourceMap::json(text);
                    &json_map
                }
            };
            SceneError::Invalid {
                file: name.to_owned(),
                line: map.line_of_path(&error.path),
                error,
            }
        };
        let desc = input.into_desc(base_dir.as_ref()).map_err(invalid)?;
        desc.validate().map_err(invalid)?;
        check(&desc).map_err(invalid)?;
        Ok(desc)
    }
}

fn one_line(s: &str) -> String {
    s.trim().replace(['\n', '\r'], " ")
}

/// The scene and where each of its keys sits (for later errors).
fn parse_toml<'a>(text: &'a str, name: &str) -> Result<(SceneIn, SourceMap<'a>), SceneError> {
    let parse_error = |line, message: String| SceneError::Parse {
        file: name.to_owned(),
        line,
        message: one_line(&message),
    };
    // Parsed once: the syntax check's table is what serde reads (a second
    // parse of a large scene costs more than the rest of a refusal).
    let table = match toml::de::DeTable::parse(text) {
        Ok(table) => table,
        Err(e) => {
            let line = e.span().map(|s| source_map::line_of_offset(text, s.start));
            let near = e
                .span()
                .and_then(|s| text.get(s))
                .filter(|s| !s.trim().is_empty() && s.len() <= 40 && !s.contains('\n'));
            let message = match near {
                Some(near) => format!("invalid TOML: {} (at '{near}')", e.message()),
                None => format!("invalid TOML: {}", e.message()),
            };
            return Err(parse_error(line, message));
        }
    };
    let map = SourceMap::toml(text, table.get_ref());
    let serde_error = |e: toml::de::Error| {
        let (path, line) = match e.span() {
            Some(span) => (
                map.path_at(span.start),
                Some(map.line_of_offset(span.start)),
            ),
            None => (Vec::new(), None),
        };
        parse_error(line, error::rewrite_serde_message(e.message(), &path))
    };
    // The tables inside [render] are integrators' settings, whose names
    // only the integrators know: read apart, each as a table of values.
    let mut table = table;
    let mut tables = Vec::new();
    if let Some(render) = table.get_mut().get_mut("render") {
        if let toml::de::DeValue::Table(render) = render.get_mut() {
            let names: Vec<String> = render
                .iter()
                .filter(|(_, v)| v.get_ref().is_table())
                .map(|(k, _)| k.get_ref().to_string())
                .collect();
            for name in names {
                if let Some(value) = render.remove(name.as_str()) {
                    tables.push((name, value));
                }
            }
        }
    }
    let mut input: SceneIn = serde::Deserialize::deserialize(toml::de::Deserializer::from(table))
        .map_err(serde_error)?;
    for (name, value) in tables {
        let params: input::ParamsIn =
            serde::Deserialize::deserialize(toml::de::ValueDeserializer::from(value))
                .map_err(serde_error)?;
        input.render.tables.insert(name, params);
    }
    Ok((input, map))
}

fn parse_json(text: &str, name: &str) -> Result<SceneIn, SceneError> {
    if text.trim().is_empty() {
        return Ok(SceneIn::default());
    }
    if !text.trim_start().starts_with('{') {
        let start = text.len() - text.trim_start().len();
        return Err(SceneError::Parse {
            file: name.to_owned(),
            line: Some(source_map::line_of_offset(text, start)),
            message: "invalid JSON scene: the top level must be an object { ... }".to_owned(),
        });
    }
    // The objects inside "render" are integrators' settings (as for TOML):
    // read apart. Scenes without any keep serde_json's positions.
    if let Ok(serde_json::Value::Object(mut top)) = serde_json::from_str::<serde_json::Value>(text)
    {
        if let Some(serde_json::Value::Object(render)) = top.get_mut("render") {
            let names: Vec<String> = render
                .iter()
                .filter(|(_, v)| v.is_object())
                .map(|(k, _)| k.clone())
                .collect();
            if !names.is_empty() {
                let data_error = |e: serde_json::Error, path: &[PathSeg]| SceneError::Parse {
                    file: name.to_owned(),
                    line: None,
                    message: one_line(&error::rewrite_serde_message(&e.to_string(), path)),
                };
                let mut tables = Vec::new();
                for n in names {
                    if let Some(v) = render.remove(&n) {
                        let params: input::ParamsIn = serde_json::from_value(v).map_err(|e| {
                            data_error(e, &[PathSeg::Key("render".into()), PathSeg::Key(n.clone())])
                        })?;
                        tables.push((n, params));
                    }
                }
                let mut input: SceneIn = serde_json::from_value(serde_json::Value::Object(top))
                    .map_err(|e| data_error(e, &[]))?;
                input.render.tables.extend(tables);
                return Ok(input);
            }
        }
    }
    serde_json::from_str(text).map_err(|e| {
        let full = e.to_string();
        let suffix = format!(" at line {} column {}", e.line(), e.column());
        let msg = full.strip_suffix(&suffix).unwrap_or(&full);
        let line = (e.line() > 0).then_some(e.line());
        let message = match e.classify() {
            serde_json::error::Category::Data => {
                let map = SourceMap::json(text);
                let offset = source_map::offset_of_line_col(text, e.line(), e.column());
                error::rewrite_serde_message(msg, &map.path_at(offset))
            }
            _ => format!("invalid JSON: {msg} (column {})", e.column()),
        };
        SceneError::Parse {
            file: name.to_owned(),
            line,
            message: one_line(&message),
        }
    })
}
