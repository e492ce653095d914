//! What the binding keeps per process, and how a call runs: the engines (one per backend, opened on first use)
//! and a rayon pool, both made again in a process forked after they were made (rayon's threads and a GPU device
//! do not survive `fork()`: a child reusing them hangs or corrupts the parent's device), and [`run`], which
//! does a call's work on that pool while the calling thread, without the GIL, waits, reports progress
//! and watches for Ctrl-C.

use crate::engine::{Backend, Engine, EngineError};
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The process's pool and engines, and the process they belong to.
struct State {
    pid: u32,
    pool: Arc<rayon::ThreadPool>,
    engines: Vec<(Backend, Arc<Engine>)>,
}

static STATE: Mutex<Option<State>> = Mutex::new(None);

/// This process's state, made on first use and again after a fork. A forked child's copy of the parent's state
/// is forgotten, not dropped: dropping it would join threads the child does not have and release the parent's
/// device.
fn with_state<T>(f: impl FnOnce(&mut State) -> T) -> T {
    let mut guard = STATE.lock().unwrap_or_else(|e| e.into_inner());
    let pid = std::process::id();
    if guard.as_ref().is_some_and(|s| s.pid != pid) {
        std::mem::forget(guard.take());
    }
    let state = guard.get_or_insert_with(|| State { pid, pool: Arc::new(new_pool()), engines: Vec::new() });
    f(state)
}

fn new_pool() -> rayon::ThreadPool {
    // Building a pool only fails when the OS refuses threads; one thread (the caller's) still works then.
    rayon::ThreadPoolBuilder::new()
        .thread_name(|i| format!("meshvox-{i}"))
        .build()
        .or_else(|_| rayon::ThreadPoolBuilder::new().num_threads(1).build())
        .unwrap_or_else(|e| panic!("no thread for meshvox: {e}"))
}

/// The process's rayon pool.
pub(super) fn pool() -> Arc<rayon::ThreadPool> {
    with_state(|s| s.pool.clone())
}

/// The process's engine for `backend`, opened on first use (for the GPU: adapter, device, pipelines).
pub(super) fn engine(backend: Backend) -> Result<Arc<Engine>, EngineError> {
    if let Some(engine) = with_state(|s| s.engines.iter().find(|(b, _)| *b == backend).map(|(_, e)| e.clone())) {
        return Ok(engine);
    }
    // Opened outside the lock: it can take a while, and other threads may want the pool meanwhile. Two threads
    // opening at once both open; the first one stored is kept.
    let opened = Arc::new(Engine::open(backend)?);
    Ok(with_state(|s| match s.engines.iter().find(|(b, _)| *b == backend) {
        Some((_, e)) => e.clone(),
        None => {
            s.engines.push((backend, opened.clone()));
            opened
        }
    }))
}

/// What the calling thread and the working thread share during [`run`].
#[derive(Default)]
pub(super) struct Control {
    /// Set by the calling thread on Ctrl-C (or a failing progress callback); the work stops at its next check.
    pub cancel: AtomicBool,
    pub done: AtomicUsize,
    pub total: AtomicUsize,
}

impl Control {
    /// The engine's progress callback: records (done, total) for the calling thread to report.
    pub fn progress(&self, done: usize, total: usize) {
        self.total.store(total, Ordering::Relaxed);
        self.done.store(done, Ordering::Relaxed);
    }
}

/// Runs `work` on the process's rayon pool (a job on one of its threads; no thread is started per call) while the
/// calling thread releases the GIL and every 50 ms calls `progress(done, total)` when it changed (from the calling
/// thread, as Python code expects) and checks for signals. On Ctrl-C (or an exception in `progress`) the work is
/// told to stop, waited for, and the exception raised; the engine stays usable. A panic in the work is a
/// `RuntimeError`.
pub(super) fn run<R: Send>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    work: impl FnOnce(&Control) -> R + Send,
) -> PyResult<R> {
    let control = Control::default();
    let pool = pool();
    let (tx, mut rx) = std::sync::mpsc::channel::<std::thread::Result<R>>();
    let mut outcome = None;
    let mut failure = None;
    // The scope ends when the job has: after its result arrived (or its sender was dropped by a panic).
    pool.in_place_scope(|scope| {
        let control = &control;
        scope.spawn(move |_| {
            let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(control)));
            // The receiver may be gone (the caller stopped waiting); nothing to tell then.
            let _ = tx.send(result);
        });
        let mut reported = (usize::MAX, usize::MAX);
        loop {
            let (received, back) = py.detach(move || (rx.recv_timeout(Duration::from_millis(50)), rx));
            rx = back;
            let finished = match received {
                Ok(result) => {
                    outcome = Some(result);
                    true
                }
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => false,
                Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => true,
            };
            let now = (control.done.load(Ordering::Relaxed), control.total.load(Ordering::Relaxed));
            if let Some(callback) = progress
                && now.1 > 0
                && now != reported
                && failure.is_none()
            {
                reported = now;
                if let Err(e) = callback.call1(now) {
                    failure = Some(e);
                }
            }
            if failure.is_none()
                && let Err(e) = py.check_signals()
            {
                failure = Some(e);
            }
            if finished {
                break;
            }
            if failure.is_some() {
                control.cancel.store(true, Ordering::Relaxed);
            }
        }
    });
    match (failure, outcome) {
        (Some(e), _) => Err(e),
        (None, Some(Ok(r))) => Ok(r),
        (None, Some(Err(panic))) => {
            let what = panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("unknown");
            Err(pyo3::exceptions::PyRuntimeError::new_err(format!("meshvox failed inside: {what}")))
        }
        (None, None) => Err(pyo3::exceptions::PyRuntimeError::new_err("meshvox failed inside: no result")),
    }
}
