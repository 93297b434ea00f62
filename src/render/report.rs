//! What a render tells whoever runs it (progress, warnings, checkpoints,
//! files written, frames of a sequence), and what it did: the types the
//! CLI, the Blender add-on's progress stream and the farm scripts read,
//! with no rendering in them.

use crate::error::Error;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Where a render is.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    /// Share of the work done, 0 to 1.
    pub fraction: f64,
    /// Seconds since the render's first pass started.
    pub elapsed: f64,
    /// Seconds still to go, when it can be told.
    pub eta: Option<f64>,
    /// Passes finished.
    pub passes: u32,
}

/// What a render tells whoever runs it. Called from worker threads.
pub trait Reporter: Sync {
    /// Something the user should know (a grid that has no effect, ...).
    fn warning(&self, _message: &str) {}
    /// Progress within the render, after every tile.
    fn progress(&self, _p: Progress) {}
    /// A checkpoint was written.
    fn checkpoint(&self, _path: &Path, _passes: u32) {}
    /// The render goes on from the state at `state`, which holds `passes`
    /// passes that took `seconds`.
    fn resumed(&self, _state: &Path, _passes: u32, _seconds: f64) {}
    /// A finished render wrote this file (the EXR, then the preview).
    fn saved(&self, _path: &Path) {}
    /// Frame `frame`, the `index`-th of `count`, starts.
    fn frame_started(&self, _frame: u32, _index: usize, _count: usize) {}
    /// Frame `frame` ended after `seconds`.
    fn frame_done(&self, _frame: u32, _outcome: &FrameOutcome, _seconds: f64) {}
}

/// A reporter that reports nothing.
pub struct Silent;
impl Reporter for Silent {}

/// What a finished render did.
#[derive(Debug, Clone)]
pub struct Summary {
    pub integrator: &'static str,
    pub passes: u32,
    /// Camera samples per pixel.
    pub spp: u32,
    pub width: u32,
    pub height: u32,
    pub threads: usize,
    pub load_seconds: f64,
    pub render_seconds: f64,
    pub write_seconds: f64,
    /// The files written: the EXR, then the preview if any.
    pub outputs: Vec<PathBuf>,
}

/// How one frame ended.
#[derive(Debug)]
pub enum FrameOutcome {
    Written(Summary),
    /// Its EXR existed (`--skip-existing`).
    Skipped(PathBuf),
    Failed(Error),
}

/// Keeps the last message of a progress bar from interleaving: a
/// convenience for reporters that print from worker threads.
pub struct Throttle {
    last: Mutex<Option<Instant>>,
    every: Duration,
}

impl Throttle {
    pub fn new(every: Duration) -> Self {
        Self {
            last: Mutex::new(None),
            every,
        }
    }
    /// True at most once per interval (and always when `force`).
    pub fn ready(&self, force: bool) -> bool {
        let mut l = self.last.lock().unwrap_or_else(|e| e.into_inner());
        let now = Instant::now();
        if force || l.is_none_or(|t| now - t >= self.every) {
            *l = Some(now);
            true
        } else {
            false
        }
    }
}
