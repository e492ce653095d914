//! What the binding keeps per process, and how a call runs.
//!
//! The engines (one per backend) are opened on first use, each exactly once however many threads ask at the same
//! moment (the others wait for the one opening it), `auto` and `gpu` on one device, and opened again in a process
//! forked after that: a GPU device does not survive `fork()`, and a child reusing the parent's would hang or
//! corrupt it. The data-parallel loops run on the library's pool ([`crate::parallel`]), per process in the same way.
//!
//! [`run`] does a call's work on a thread started for it (not a rayon worker: the work waits for the GPU's turn,
//! which a worker must never do, see [`crate::parallel`]) while the calling thread, without the GIL, waits,
//! reports progress and watches for Ctrl-C. Concurrent calls from Python threads each have their own such
//! thread; they take turns on the GPU and share the pool for their loops.

use crate::engine::{Backend, Engine, EngineError};
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

/// Engines opened so far, behind the lock their opening holds.
type Slot = Arc<Mutex<Vec<(Backend, Arc<Engine>)>>>;

/// The process's engines, and the process they belong to: the CPU's apart, so that a CPU call never waits for a
/// device being opened; `auto` and `gpu` together, so that the second of them opened shares the first one's
/// device ([`Engine::with_backend`]).
struct State {
    pid: u32,
    cpu: Slot,
    gpu: Slot,
}

static STATE: Mutex<Option<State>> = Mutex::new(None);

/// The slot of `backend`'s engine in this process, made on first use. A forked child's copy of the parent's state
/// is forgotten, not dropped: dropping it would release the parent's device (and a slot the parent was opening
/// stays locked in the child).
fn slot(backend: Backend) -> Slot {
    let mut guard = STATE.lock().unwrap_or_else(PoisonError::into_inner);
    let pid = std::process::id();
    if guard.as_ref().is_some_and(|s| s.pid != pid) {
        std::mem::forget(guard.take());
    }
    let state = guard.get_or_insert_with(|| State { pid, cpu: Slot::default(), gpu: Slot::default() });
    match backend {
        Backend::Cpu => state.cpu.clone(),
        Backend::Auto | Backend::Gpu => state.gpu.clone(),
    }
}

/// The process's engine for `backend`, opened on first use (for the GPU: adapter, device, pipelines) while its
/// slot is held, so that threads asking meanwhile wait for that engine rather than open their own: one device per
/// process. A failed opening stores nothing, and the next call tries again.
pub(super) fn engine(backend: Backend) -> Result<Arc<Engine>, EngineError> {
    let slot = slot(backend);
    let mut engines = slot.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some((_, engine)) = engines.iter().find(|(b, _)| *b == backend) {
        return Ok(engine.clone());
    }
    let sibling = engines.iter().find_map(|(_, engine)| engine.with_backend(backend));
    let engine = Arc::new(match sibling {
        Some(engine) => engine,
        None => Engine::open(backend)?,
    });
    engines.push((backend, engine.clone()));
    Ok(engine)
}

/// Whether this process has a GPU open where `backend`'s engine would use it (`auto` shares `gpu`'s device), so that
/// a job on it pays no opening. Nothing is opened here.
pub(super) fn gpu_open(backend: Backend) -> bool {
    let slot = slot(backend);
    let engines = slot.lock().unwrap_or_else(PoisonError::into_inner);
    engines.iter().any(|(_, engine)| engine.uses_gpu())
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

    /// `job(i)` for `i` in `0..total` on `workers` threads of the library's work queue, each result in its slot
    /// (`None` where the job gave none: cancelled), the progress counting finished jobs.
    pub fn each<T: Send>(
        &self,
        total: usize,
        workers: usize,
        job: impl Fn(usize) -> Option<T> + Sync,
    ) -> Vec<Option<T>> {
        let mut slots: Vec<Option<T>> = (0..total).map(|_| None).collect();
        let mut done = 0;
        let finished = crate::engine::work_queue(total, workers, job, |i, result| {
            slots[i] = result;
            done += 1;
            self.progress(done, total);
            Ok::<(), std::convert::Infallible>(())
        });
        let Ok(()) = finished;
        slots
    }
}

/// Runs `work` on a thread of its own while the calling thread releases the GIL and every 50 ms calls
/// `progress(done, total)` when it changed (from the calling thread, as Python code expects) and checks for
/// signals. On Ctrl-C (or an exception in `progress`) the work is told to stop, waited for, and the exception
/// raised; the engine stays usable. A panic in the work is a `RuntimeError`.
pub(super) fn run<R: Send>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    work: impl FnOnce(&Control) -> R + Send,
) -> PyResult<R> {
    let control = Control::default();
    let (tx, mut rx) = std::sync::mpsc::channel::<std::thread::Result<R>>();
    let mut outcome = None;
    let mut failure = None;
    // The scope ends when the work has: after its result arrived (or its sender was dropped by a panic).
    let started: std::io::Result<()> = std::thread::scope(|scope| {
        let control = &control;
        let spawned = std::thread::Builder::new().name("meshvox-call".into()).spawn_scoped(scope, move || {
            let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(control)));
            // The receiver may be gone (the caller stopped waiting); nothing to tell then.
            let _ = tx.send(result);
        });
        // The work's thread is joined when the scope ends.
        spawned?;
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
        Ok(())
    });
    if let Err(e) = started {
        return Err(pyo3::exceptions::PyRuntimeError::new_err(format!("meshvox could not start a thread: {e}")));
    }
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
