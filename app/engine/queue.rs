//! The work queue the engine's many-mesh clients share (`meshvox batch`, the Python binding's `voxelize_many`):
//! worker threads that each take the next index when done with the last, so parsing and writing on some overlap
//! a voxelization on another (the engine gives the GPU to one request at a time), and results that come back to
//! the calling thread as they finish.

use std::sync::atomic::{AtomicUsize, Ordering};

/// The workers a many-mesh client runs when the user names no number: one per core on the CPU; with a GPU
/// (`gpu`), twice that and at least four, since a worker waiting for the device holds no core, and the small grids
/// of several waiting workers are made in one submission (`gpu/group.rs`) while others parse and write.
pub fn default_workers(gpu: bool) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if gpu { (2 * cores).max(4) } else { cores }
}

/// Runs `job(k)` for every `k` in `0..count` on `workers` threads and hands each result to `take(k, result)` on
/// the calling thread, in the order they finish. Results wait in a channel of two per worker, so a slow `take`
/// holds the workers back instead of letting results pile up. When `take` fails, the workers stop after the job
/// they are on and the error is returned.
pub fn work_queue<T: Send, E>(
    count: usize,
    workers: usize,
    job: impl Fn(usize) -> T + Sync,
    mut take: impl FnMut(usize, T) -> Result<(), E>,
) -> Result<(), E> {
    let workers = workers.max(1);
    let next = AtomicUsize::new(0);
    let (tx, rx) = std::sync::mpsc::sync_channel::<(usize, T)>(2 * workers);
    std::thread::scope(|scope| {
        for _ in 0..workers {
            let (tx, next, job) = (tx.clone(), &next, &job);
            scope.spawn(move || {
                loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    // A receiver that is gone (`take` failed) ends the worker too.
                    if k >= count || tx.send((k, job(k))).is_err() {
                        break;
                    }
                }
            });
        }
        drop(tx);
        for (k, result) in rx {
            take(k, result)?;
        }
        Ok(())
    })
}
