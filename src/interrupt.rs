//! Cooperative interruption of long work: when Python receives Ctrl-C while Rust works (the bindings poll its
//! signals, python/interrupt.rs), they `request` a stop; the long loops (the adding-doubling solve, transport_fit,
//! the renderer's rows) poll `requested` and return `Error::Interrupted` when they skipped any work for it (each loop
//! remembers that itself: the request may be withdrawn before it returns), which the bindings raise as
//! KeyboardInterrupt. Nothing interrupted is cached: a table is written only once it is complete. The request is the
//! process's: work running at the same time in other threads stops too (and raises KeyboardInterrupt there).

use crate::error::{Error, Result};
use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Asks every long computation to stop.
pub fn request() {
    REQUESTED.store(true, Ordering::Relaxed);
}

/// Withdraws the request (once the interrupted work has returned).
pub fn clear() {
    REQUESTED.store(false, Ordering::Relaxed);
}

/// Whether a stop is requested.
#[inline]
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}

/// Err(Interrupted) when a stop is requested.
#[inline]
pub fn check() -> Result<()> {
    if requested() {
        Err(Error::Interrupted)
    } else {
        Ok(())
    }
}
