//! Stopping work cleanly on SIGINT and SIGTERM. The CLI calls [`install`];
//! long loops (the passes, the tiles of a pass, photon tracing) call
//! [`check`] and return [`Error::Interrupted`], so that a render stopped by
//! Ctrl-C or by a farm's scheduler writes nothing partial: outputs are only
//! ever renamed into place whole, so the last complete checkpoint stays
//! valid. A second signal ends the process at once (exit code 130 or 143),
//! unless it comes within a second of the first: a scheduler that signals
//! every process of a job (Slurm on requeue or preemption) and a job
//! script that forwards the signal it got, or a terminal's Ctrl-C reaching
//! a wrapper and the render, deliver one request twice, and the second
//! must not cut short the last checkpoint the first one asked for.

use crate::error::{Error, Result};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

static SIGNAL: OnceLock<Arc<AtomicUsize>> = OnceLock::new();

/// When the first signal came (monotonic nanoseconds, 0: none yet).
static FIRST: AtomicU64 = AtomicU64::new(0);

/// A second signal within this long of the first is the same request.
const SAME_REQUEST_NS: u64 = 1_000_000_000;

/// The monotonic clock in nanoseconds (async-signal-safe).
fn monotonic_ns() -> u64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes the timespec it is given.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut t) };
    (t.tv_sec as u64).saturating_mul(1_000_000_000) + t.tv_nsec as u64
}

/// Catches SIGINT and SIGTERM from now on. Idempotent; errors are ignored
/// (the default handlers then stay, which end the process as before).
pub fn install() {
    if SIGNAL.get().is_some() {
        return;
    }
    let flag = SIGNAL.get_or_init(|| Arc::new(AtomicUsize::new(0)));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        // The first signal is noted; a later one, a second or more after
        // it, exits at once. (Only atomics, the clock and _exit: all
        // async-signal-safe.)
        // SAFETY: the handler does nothing that is not async-signal-safe.
        let _ = unsafe {
            signal_hook::low_level::register(sig, move || {
                let now = monotonic_ns().max(1);
                if let Err(first) =
                    FIRST.compare_exchange(0, now, Ordering::SeqCst, Ordering::SeqCst)
                {
                    if now.saturating_sub(first) >= SAME_REQUEST_NS {
                        signal_hook::low_level::exit(128 + sig);
                    }
                }
            })
        };
        let _ = signal_hook::flag::register_usize(sig, flag.clone(), sig as usize);
    }
}

fn flag_value() -> usize {
    SIGNAL.get().map_or(0, |f| f.load(Ordering::Relaxed))
}

/// The signal that asked to stop, if one did.
pub fn requested() -> Option<i32> {
    match flag_value() {
        0 => None,
        s => Some(s as i32),
    }
}

/// `Err(Interrupted)` once a signal asked to stop.
pub fn check() -> Result<()> {
    match requested() {
        None => Ok(()),
        Some(signal) => Err(Error::Interrupted { signal, kept: None }),
    }
}

/// Whether a stop request lets the pass in progress finish
/// ([`finish_passes`]).
static FINISH_PASSES: AtomicBool = AtomicBool::new(false);

/// While the guard lives, a stop request no longer abandons the pass in
/// progress ([`abandon`] stays false): the render finishes it and writes a
/// last checkpoint and its resume state, so a farm's SIGTERM (Slurm's
/// `--signal`, a preemption) costs no finished work. A second signal still
/// ends the process at once.
pub fn finish_passes() -> FinishPasses {
    FINISH_PASSES.store(true, Ordering::Relaxed);
    FinishPasses(())
}

/// See [`finish_passes`].
pub struct FinishPasses(());

impl Drop for FinishPasses {
    fn drop(&mut self) {
        FINISH_PASSES.store(false, Ordering::Relaxed);
    }
}

/// Whether the work in progress (the tiles of a pass, the photons of a
/// pass) should be dropped now: a stop was asked and passes are not to be
/// finished ([`finish_passes`]).
pub fn abandon() -> bool {
    requested().is_some() && !FINISH_PASSES.load(Ordering::Relaxed)
}

pub use crate::error::signal_name;
