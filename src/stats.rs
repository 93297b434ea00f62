//! Per-thread counters of the work tracking does, for benchmarks and tests:
//! tentative collisions, evaluations of the media, real collisions.

use std::cell::Cell;

thread_local! {
    static TENTATIVE: Cell<u64> = const { Cell::new(0) };
    static LOOKUPS: Cell<u64> = const { Cell::new(0) };
    static REAL: Cell<u64> = const { Cell::new(0) };
}

/// Tracking statistics of one thread.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// Tentative collisions sampled (delta and ratio tracking).
    pub tentative: u64,
    /// Evaluations of the media (each reads every grid of the volumes).
    pub lookups: u64,
    /// Real collisions (scattering events, weighted absorption included).
    pub real: u64,
}

/// The counters of the calling thread; reading resets them.
pub fn take_counters() -> Counters {
    Counters {
        tentative: TENTATIVE.with(|c| c.replace(0)),
        lookups: LOOKUPS.with(|c| c.replace(0)),
        real: REAL.with(|c| c.replace(0)),
    }
}

#[inline]
fn bump(c: &'static std::thread::LocalKey<Cell<u64>>) {
    c.with(|c| c.set(c.get() + 1));
}

#[inline]
pub(crate) fn count_tentative() {
    bump(&TENTATIVE);
}

#[inline]
pub(crate) fn count_lookup() {
    bump(&LOOKUPS);
}

#[inline]
pub(crate) fn count_real() {
    bump(&REAL);
}
