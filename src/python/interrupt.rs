//! Long work that Ctrl-C can stop: it runs on a thread of its own with the GIL released while the calling thread
//! polls Python's signals; on a signal the work is asked to stop (src/interrupt.rs) and the signal's exception
//! (KeyboardInterrupt) is raised once it has.

use crate::error::Result;
use pyo3::prelude::*;
use std::sync::mpsc::{channel, RecvTimeoutError};
use std::time::Duration;

/// How often the calling thread looks at Python's signals.
const POLL: Duration = Duration::from_millis(50);

/// `work`'s result, or the exception of a signal that arrived meanwhile (after `work` has stopped); a panic of
/// `work` (a bug) is a RuntimeError, not a crash. The cache's warnings of the work are issued once it is done.
pub fn interruptible<T: Send>(py: Python<'_>, work: impl FnOnce() -> Result<T> + Send) -> PyResult<T> {
    let out = run(py, work);
    super::warn_pending(py);
    out
}

fn run<T: Send>(py: Python<'_>, work: impl FnOnce() -> Result<T> + Send) -> PyResult<T> {
    let (tx, mut rx) = channel();
    std::thread::scope(|scope| {
        scope.spawn(move || {
            let _ = tx.send(std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)));
        });
        loop {
            let (back, received) = py.detach(move || {
                let r = rx.recv_timeout(POLL);
                (rx, r)
            });
            rx = back;
            match received {
                Ok(Ok(result)) => return result.map_err(PyErr::from),
                Ok(Err(_)) | Err(RecvTimeoutError::Disconnected) => {
                    return Err(pyo3::exceptions::PyRuntimeError::new_err("lamina's worker thread failed (a bug)"))
                }
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(signal) = py.check_signals() {
                        crate::interrupt::request();
                        let _ = py.detach(move || rx.recv());
                        crate::interrupt::clear();
                        return Err(signal);
                    }
                }
            }
        }
    })
}
