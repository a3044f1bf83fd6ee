//! Long calls: the work runs on a thread of its own with the GIL released, while the calling
//! thread waits in short slices, each time checking Python's signals (Ctrl-C) and handing
//! the progress to the caller's callback. The library's [`Progress`] hook is where the work
//! learns that it was cancelled: its next report unwinds it.
//!
//! On Ctrl-C the call raises `KeyboardInterrupt` at once; the abandoned work stops at its
//! next progress report (every pass of a synthesis, every stage and block of an analysis)
//! and frees what it held. Only the calling thread touches Python.

use crate::errors;
use btfsynth::progress::Progress;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// How often the waiting thread looks at signals and progress.
const POLL: Duration = Duration::from_millis(50);

/// Works still running, cancelled ones included (see [`running`]).
static RUNNING: AtomicUsize = AtomicUsize::new(0);

/// The payload a cancelled work unwinds with; not a bug, so no panic message is printed
/// (`resume_unwind` skips the panic hook).
struct Cancelled;

/// What the work reports, read by the waiting thread.
#[derive(Default)]
struct Shared {
    cancelled: AtomicBool,
    done: AtomicU64,
    stage: Mutex<Stage>,
}

#[derive(Clone, Default, PartialEq)]
struct Stage {
    name: String,
    total: u64,
    /// Counts the stages started, so that two stages of one name are told apart.
    number: u64,
    /// Stages finished since the waiting thread last looked: (name, total).
    finished: Vec<(String, u64)>,
}

/// The [`Progress`] the library reports to.
pub struct Hook(Arc<Shared>);

impl Hook {
    fn check(&self) {
        if self.0.cancelled.load(Ordering::Relaxed) {
            std::panic::resume_unwind(Box::new(Cancelled));
        }
    }
}

impl Progress for Hook {
    fn start(&self, stage: &str, total: u64) {
        self.check();
        if let Ok(mut s) = self.0.stage.lock() {
            s.name = stage.to_string();
            s.total = total;
            s.number += 1;
        }
        self.0.done.store(0, Ordering::Relaxed);
    }

    fn advance(&self, units: u64) {
        self.check();
        self.0.done.fetch_add(units, Ordering::Relaxed);
    }

    fn finish(&self) {
        self.check();
        if let Ok(mut s) = self.0.stage.lock() {
            let finished = (s.name.clone(), s.total);
            s.finished.push(finished);
            s.number += 1;
            s.name.clear();
        }
    }
}

/// Calls `callback(done, total, stage)` for what happened since `last`.
fn report(py: Python<'_>, callback: &PyObject, shared: &Shared, last: &mut (u64, u64)) -> PyResult<()> {
    let (finished, current) = match shared.stage.lock() {
        Ok(mut s) => (std::mem::take(&mut s.finished), (s.name.clone(), s.total, s.number)),
        Err(_) => return Ok(()),
    };
    for (name, total) in finished {
        callback.call1(py, (total, total, name))?;
    }
    let (name, total, number) = current;
    let done = shared.done.load(Ordering::Relaxed).min(total);
    if !name.is_empty() && (number, done) != *last {
        callback.call1(py, (done, total, name))?;
        *last = (number, done);
    }
    Ok(())
}

/// Runs `work` off the GIL (see the module documentation) and returns its result; a
/// library error becomes its `btfsynth` exception, a bug in the library an `InternalError`.
pub fn run<T: Send + 'static>(
    py: Python<'_>,
    progress: Option<&PyObject>,
    work: impl FnOnce(&dyn Progress) -> btfsynth::Result<T> + Send + 'static,
) -> PyResult<T> {
    let shared = Arc::new(Shared::default());
    let hook = Hook(shared.clone());
    let (send, receive) = mpsc::channel();
    RUNNING.fetch_add(1, Ordering::SeqCst);
    let spawned = std::thread::Builder::new().name("btfsynth".into()).spawn(move || {
        let result = std::panic::catch_unwind(AssertUnwindSafe(|| work(&hook)));
        RUNNING.fetch_sub(1, Ordering::SeqCst);
        // The caller may have gone (Ctrl-C): then nobody wants the result.
        let _ = send.send(result);
    });
    if let Err(e) = spawned {
        RUNNING.fetch_sub(1, Ordering::SeqCst);
        return Err(PyRuntimeError::new_err(format!("cannot start a thread: {e}")));
    }
    let mut last = (0, 0);
    let cancel = |e: PyErr| {
        shared.cancelled.store(true, Ordering::Relaxed);
        e
    };
    let mut receive = Some(receive);
    loop {
        // The receiver goes into the GIL-free closure and back (it may be sent, not shared).
        let (received, back) = match receive.take() {
            Some(r) => py.allow_threads(move || (r.recv_timeout(POLL), r)),
            None => return Err(internal(py, Box::new("the work's channel was lost"))),
        };
        receive = Some(back);
        if let Some(callback) = progress {
            report(py, callback, &shared, &mut last).map_err(cancel)?;
        }
        match received {
            Ok(Ok(result)) => return result.map_err(|e| errors::to_py(py, e)),
            Ok(Err(panic)) => return Err(internal(py, panic)),
            Err(RecvTimeoutError::Timeout) => py.check_signals().map_err(cancel)?,
            Err(RecvTimeoutError::Disconnected) => {
                return Err(internal(py, Box::new("the work ended without a result")))
            }
        }
    }
}

/// A panic of the library (a bug) as `btfsynth.InternalError`, with its message.
fn internal(py: Python<'_>, panic: Box<dyn std::any::Any + Send>) -> PyErr {
    let message = match (panic.downcast_ref::<&str>(), panic.downcast_ref::<String>()) {
        (Some(s), _) => s.to_string(),
        (_, Some(s)) => s.clone(),
        _ if panic.is::<Cancelled>() => "cancelled".to_string(),
        _ => "a panic without a message".to_string(),
    };
    errors::to_py(py, btfsynth::Error::internal(message))
}

/// How many long calls are still running, abandoned (cancelled) ones included: a test
/// watches a cancelled one stop.
#[pyfunction]
#[pyo3(name = "_running")]
pub fn running() -> usize {
    RUNNING.load(Ordering::SeqCst)
}
