//! The crate's error type. Every message is one line that names the file (and
//! the grid, where there is one) and says what is wrong in a user's words.

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused: missing file, permissions, a directory.
    #[error("cannot read '{}': {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Something is wrong with a file as a whole.
    #[error("'{}': {message}", path.display())]
    File { path: PathBuf, message: String },
    /// Something is wrong with one grid of a file.
    #[error("'{}', grid '{grid}': {message}", path.display())]
    Grid {
        path: PathBuf,
        grid: String,
        message: String,
    },
    /// Reading or writing an image (`crate::image::ImageError`'s message:
    /// it converts into this).
    #[error("{0}")]
    Image(String),
    /// A scene file that cannot be used (the scene module's message:
    /// `crate::scene::SceneError` converts into this, so that this core
    /// type knows nothing of scenes).
    #[error("{0}")]
    Scene(String),
    /// A command-line argument or option out of range.
    #[error("{0}")]
    Argument(String),
    /// Data built in memory that does not make a valid grid.
    #[error("invalid grid: {0}")]
    InvalidGrid(String),
    /// The work was stopped by a signal (SIGINT, SIGTERM) before it
    /// finished; nothing partial was written (an earlier checkpoint stays,
    /// `kept` says which when there is one).
    #[error("interrupted by {}: {}", signal_name(*signal), kept.as_deref().unwrap_or("nothing written"))]
    Interrupted { signal: i32, kept: Option<String> },
    /// An error with where it happened (`scene.toml, [[volume]] 2`).
    #[error("{context}: {source}")]
    Context { context: String, source: Box<Error> },
}

impl Error {
    /// The process exit code for this error: 128 + the signal for an
    /// interruption (130 for SIGINT, 143 for SIGTERM, as shells report
    /// them), 1 otherwise.
    pub fn exit_code(&self) -> u8 {
        match self {
            Error::Interrupted { signal, .. } => (128 + *signal).clamp(0, 255) as u8,
            Error::Context { source, .. } => source.exit_code(),
            _ => 1,
        }
    }

    /// This error with `context` in front (an interruption stays as it
    /// is: it is not about any input).
    pub fn context(self, context: impl Into<String>) -> Error {
        match self {
            e @ Error::Interrupted { .. } => e,
            e => Error::Context {
                context: context.into(),
                source: Box::new(e),
            },
        }
    }

    /// Whether this is an interruption by a signal (possibly with context).
    pub fn is_interrupt(&self) -> bool {
        match self {
            Error::Interrupted { .. } => true,
            Error::Context { source, .. } => source.is_interrupt(),
            _ => false,
        }
    }
}

impl Error {
    pub fn file(path: &Path, message: impl Into<String>) -> Self {
        Error::File {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
    pub fn grid(path: &Path, grid: &str, message: impl Into<String>) -> Self {
        Error::Grid {
            path: path.to_path_buf(),
            grid: grid.to_string(),
            message: message.into(),
        }
    }
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Error::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// "SIGINT", "SIGTERM" or "signal N".
pub fn signal_name(signal: i32) -> String {
    match signal {
        2 => "SIGINT".into(),
        15 => "SIGTERM".into(),
        s => format!("signal {s}"),
    }
}
