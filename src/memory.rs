//! How much memory work may still take: what the machine has available
//! now (Linux's `MemAvailable`), or, under a `--max-memory` limit, what is
//! left of it beside what the process already holds. Checked before the
//! large allocations (a grid's tree, a render's film and photon map), so a
//! input that cannot fit is refused with a message instead of ending in the
//! kernel's out-of-memory killer.

use std::sync::atomic::{AtomicU64, Ordering};

/// The `--max-memory` limit in bytes; 0: none.
static LIMIT: AtomicU64 = AtomicU64::new(0);

/// Sets the process's memory limit (`None`: the machine's available
/// memory is the only bound).
pub fn set_limit(bytes: Option<u64>) {
    LIMIT.store(bytes.unwrap_or(0), Ordering::Relaxed);
}

/// The `--max-memory` limit, if one is set.
pub fn limit() -> Option<u64> {
    match LIMIT.load(Ordering::Relaxed) {
        0 => None,
        l => Some(l),
    }
}

/// A field of a `/proc` file in bytes (the kernel writes kiB).
fn proc_kib(file: &str, field: &str) -> Option<u64> {
    let text = std::fs::read_to_string(file).ok()?;
    let line = text.lines().find(|l| l.starts_with(field))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Bytes of memory the machine has available now, when it can be read.
pub fn available() -> Option<u64> {
    proc_kib("/proc/meminfo", "MemAvailable:")
}

/// Bytes the process holds in memory now, when it can be read.
pub fn resident() -> Option<u64> {
    proc_kib("/proc/self/status", "VmRSS:")
}

/// Bytes a new allocation may take now: the available memory, and under
/// a limit no more than the limit minus what the process already holds.
pub fn budget() -> Option<u64> {
    let avail = available();
    match limit() {
        Some(l) => {
            let left = l.saturating_sub(resident().unwrap_or(0));
            Some(avail.map_or(left, |a| a.min(left)))
        }
        None => avail,
    }
}
