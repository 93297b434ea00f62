//! Stopping work cleanly on SIGINT and SIGTERM. The CLI calls [`install`];
//! long loops (the passes, the tiles of a pass, photon tracing) call
//! [`check`] and return [`Error::Interrupted`], so that a render stopped by
//! Ctrl-C or by a farm's scheduler writes nothing partial: outputs are only
//! ever renamed into place whole, so the last complete checkpoint stays
//! valid. A second signal ends the process at once (exit code 130 or 143).

use crate::error::{Error, Result};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

static SIGNAL: OnceLock<Arc<AtomicUsize>> = OnceLock::new();

/// Catches SIGINT and SIGTERM from now on. Idempotent; errors are ignored
/// (the default handlers then stay, which end the process as before).
pub fn install() {
    if SIGNAL.get().is_some() {
        return;
    }
    let flag = SIGNAL.get_or_init(|| Arc::new(AtomicUsize::new(0)));
    let armed = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        // Registered first, so it sees `armed` as the previous signal left
        // it: the first signal only arms it, a second one exits at once.
        let _ = signal_hook::flag::register_conditional_shutdown(sig, 128 + sig, armed.clone());
        let _ = signal_hook::flag::register(sig, armed.clone());
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
        Some(signal) => Err(Error::Interrupted { signal }),
    }
}

pub use crate::error::signal_name;
