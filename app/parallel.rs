//! The process's pool for the library's data-parallel loops, and how a call that blocks stays off rayon's
//! workers.
//!
//! Every function that starts parallel work (a `par_iter`, a parallel sort) wraps it in [`install`]: on a rayon
//! worker the loop stays in that worker's pool; from any other thread it runs on meshvox's own pool, made on
//! first use with as many threads as rayon's global pool, and made again in a process forked after that (rayon's
//! threads do not survive `fork()`: a child's first loop on the parent's pool would wait forever). That pool runs
//! nothing but these loops, which block on nothing but their own joins.
//!
//! Why a pool of its own: a rayon worker must never block on something that another job of its pool may hold
//! (the GPU's turn, a device poll, a channel). While it waits in a `join` it runs other jobs of its pool on the
//! same stack, and a job that then waits for what a frame below it holds can never return to release it; a worker
//! blocked outright leaves its pool one thread short, and a pool whose workers all wait on a call that needs the
//! pool never gets one back. So the engine's blocking calls go through [`off_workers`] (on a worker the call runs
//! on a thread of its own while the worker waits), and the loops of every call, wherever it was made, run on a
//! pool none of whose threads ever waits on a call: a call holding the GPU's turn always finishes. (This module
//! sits at the bottom with `memory`: every layer may use it.)

// The library writes `crate::parallel::prelude::*` and `parallel::join` for rayon's: natively rayon's own; in the
// page (wasm32: one thread, no pool to make) the same calls done in order (`sequential`), so that its wasm carries
// no thread pool, job queue or parallel sort.
#[cfg(not(target_arch = "wasm32"))]
pub mod buckets;
#[cfg(target_arch = "wasm32")]
mod sequential;
#[cfg(not(target_arch = "wasm32"))]
pub use rayon::{current_num_threads, current_thread_index, join, prelude};
#[cfg(target_arch = "wasm32")]
pub use sequential::{current_num_threads, current_thread_index, join, prelude};

#[cfg(not(target_arch = "wasm32"))]
use std::sync::Arc;
use std::sync::{Mutex, PoisonError};

/// The pool and the process it was made in.
#[cfg(not(target_arch = "wasm32"))]
static POOL: Mutex<Option<(u32, Arc<rayon::ThreadPool>)>> = Mutex::new(None);

/// This process's pool, made on first use (`None` where the OS gives no thread: the loops then run where rayon
/// puts them). A pool left by the process this one was forked from is forgotten, not dropped: dropping it would
/// signal threads the child does not have.
#[cfg(not(target_arch = "wasm32"))]
fn pool() -> Option<Arc<rayon::ThreadPool>> {
    let mut slot = POOL.lock().unwrap_or_else(PoisonError::into_inner);
    let pid = std::process::id();
    if let Some(stale) = slot.take_if(|(owner, _)| *owner != pid) {
        std::mem::forget(stale);
    }
    if slot.is_none() {
        // As many threads as the global pool (RAYON_NUM_THREADS, or a program's own `build_global`).
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(rayon::current_num_threads())
            .thread_name(|i| format!("meshvox-{i}"))
            .build()
            .ok()?;
        *slot = Some((pid, Arc::new(pool)));
    }
    slot.as_ref().map(|(_, pool)| pool.clone())
}

/// Runs `f`, which starts parallel work: directly on a rayon worker (its loops stay in that worker's pool), else
/// on this process's pool. `f` must block on nothing but its own parallel work.
#[cfg(not(target_arch = "wasm32"))]
pub fn install<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    if rayon::current_thread_index().is_some() {
        return f();
    }
    match pool() {
        Some(pool) => pool.install(f),
        None => f(),
    }
}

/// Runs `f` (the page has one thread).
#[cfg(target_arch = "wasm32")]
pub fn install<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    f()
}

/// The number of threads [`install`]'s loops run on from here, for reports and for cutting work into pieces.
#[cfg(not(target_arch = "wasm32"))]
pub fn threads() -> usize {
    if rayon::current_thread_index().is_some() {
        return rayon::current_num_threads();
    }
    pool().map_or_else(rayon::current_num_threads, |pool| pool.current_num_threads())
}

/// One (the page's thread).
#[cfg(target_arch = "wasm32")]
pub fn threads() -> usize {
    1
}

/// Runs `f`, which may block (the GPU's turn, a device poll, a channel), so that no rayon worker blocks in it
/// while jobs of its pool may be waiting under it: off a worker, directly; on a worker, on a thread of its own
/// (named `meshvox-call`; its loops go to this process's pool) while the worker waits for it. Where the OS
/// refuses a thread, `f` runs on the worker after all. A panic in `f` resumes on the calling thread.
pub fn off_workers<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    if current_thread_index().is_none() {
        return f();
    }
    // Taken by whichever thread runs it: the new one, or this one if there is none.
    let slot = Mutex::new(Some(f));
    let take = || slot.lock().unwrap_or_else(PoisonError::into_inner).take();
    let result = std::thread::scope(|scope| {
        let spawned =
            std::thread::Builder::new().name("meshvox-call".into()).spawn_scoped(scope, || take().map(|f| f()));
        match spawned {
            Ok(call) => call.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
            Err(_) => take().map(|f| f()),
        }
    });
    result.unwrap_or_else(|| unreachable!("the call is taken once, by the thread that runs it"))
}

/// Progress from a parallel loop, a few hundred calls at most: `progress(done, total)` once at the start, then
/// whenever the units done cross a multiple of `total / calls` (from whichever thread crosses it), and once more
/// with everything done at [`Ticker::finish`].
pub struct Ticker<'a> {
    done: std::sync::atomic::AtomicUsize,
    every: usize,
    total: usize,
    progress: &'a (dyn Fn(usize, usize) + Sync),
}

impl<'a> Ticker<'a> {
    /// Starts counting `total` units, about `calls` reports in all.
    pub fn new(total: usize, calls: usize, progress: &'a (dyn Fn(usize, usize) + Sync)) -> Ticker<'a> {
        progress(0, total);
        let every = total.div_ceil(calls.max(1)).max(1);
        Ticker { done: std::sync::atomic::AtomicUsize::new(0), every, total, progress }
    }

    /// Counts `n` more units done.
    pub fn add(&self, n: usize) {
        let before = self.done.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
        if (before + n) / self.every != before / self.every {
            (self.progress)(before + n, self.total);
        }
    }

    /// Says that everything is done, whatever `every` divides.
    pub fn finish(&self) {
        (self.progress)(self.total, self.total);
    }
}
