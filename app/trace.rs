//! Where a job's wall time goes, for machines with no profiler at hand (a lent GPU machine has no perf and no
//! Nsight Systems): with `MESHVOX_TRACE=1` in the environment, named spans of host work (waits for the device,
//! copies out of mapped memory, binning, scattering) add up their time, and [`take`] hands the totals of a job to
//! the engine, which prints them to stderr after the job. Without the variable a span costs one relaxed load.
//! Waits for the device are counted always, per thread ([`device_wait`], [`waited_ns`]): a report's `wait_ms`.
//! (This module sits at the bottom with `parallel`: every layer may use it.)

use std::collections::BTreeMap;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU8, Ordering};
use web_time::Instant;

/// 0: not read yet, 1: off, 2: on.
static STATE: AtomicU8 = AtomicU8::new(0);

/// The totals so far: name → (spans, nanoseconds, nanoseconds not waiting for the device).
static TOTALS: Mutex<BTreeMap<&'static str, (u64, u128, u128)>> = Mutex::new(BTreeMap::new());

/// Whether `MESHVOX_TRACE=1` asked for spans (read once per process).
pub fn enabled() -> bool {
    match STATE.load(Ordering::Relaxed) {
        0 => {
            let on = !cfg!(target_arch = "wasm32") && std::env::var("MESHVOX_TRACE").is_ok_and(|v| v == "1");
            STATE.store(if on { 2 } else { 1 }, Ordering::Relaxed);
            on
        }
        state => state == 2,
    }
}

/// A span of host work, timed from here until it is dropped.
pub struct Span {
    name: &'static str,
    since: Instant,
    /// This thread's [`waited_ns`] at the start: a span's host work is its time less the waits inside it.
    waited: u64,
}

/// Starts a span named `name` (nothing when tracing is off).
pub fn span(name: &'static str) -> Option<Span> {
    enabled().then(|| Span { name, since: Instant::now(), waited: waited_ns() })
}

impl Drop for Span {
    fn drop(&mut self) {
        let ns = self.since.elapsed().as_nanos();
        let waited = u128::from(waited_ns().saturating_sub(self.waited));
        if let Ok(mut totals) = TOTALS.lock() {
            let entry = totals.entry(self.name).or_default();
            entry.0 += 1;
            entry.1 += ns;
            entry.2 += ns.saturating_sub(waited);
        }
    }
}

thread_local! {
    /// Nanoseconds this thread has waited for the device ([`device_wait`]), counted whether or not tracing is on.
    static WAITED: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// A wait for the device: a submission (which blocks where the driver runs earlier work first, as lavapipe does)
/// or a poll until work is done. Timed always, into this thread's [`waited_ns`], and as the span "gpu wait" when
/// tracing.
pub struct Wait {
    since: Instant,
    _span: Option<Span>,
}

/// Starts a [`Wait`], ended when dropped.
pub fn device_wait() -> Wait {
    Wait { since: Instant::now(), _span: span("gpu wait") }
}

/// Starts a [`Wait`] for the driver's compiler: a pipeline made on first use (seconds on lavapipe, whose LLVM
/// compiles each one) is the device's set-up, not the job's host work; as the span "compile pipeline".
pub fn driver_compile() -> Wait {
    Wait { since: Instant::now(), _span: span("compile pipeline") }
}

impl Drop for Wait {
    fn drop(&mut self) {
        let ns = self.since.elapsed().as_nanos() as u64;
        WAITED.with(|w| w.set(w.get() + ns));
    }
}

/// Nanoseconds this thread has spent in [`Wait`]s so far: a job takes the difference across its run, so that its
/// host work is its time less its waits for the device.
pub fn waited_ns() -> u64 {
    WAITED.with(|w| w.get())
}

/// The totals since the last call, as one line ("gpu wait 12x 3.1 ms, …", a span that waited for the device
/// adding its host work: "write brick 2x 316.0 ms (host 41.2)"), and empties them; `None` when tracing is off or
/// nothing was timed.
pub fn take() -> Option<String> {
    if !enabled() {
        return None;
    }
    let totals = std::mem::take(&mut *TOTALS.lock().ok()?);
    (!totals.is_empty()).then(|| {
        let parts: Vec<String> =
            totals.iter().map(|(name, (count, ns, host))| describe(name, *count, *ns, *host)).collect();
        parts.join(", ")
    })
}

/// One span's totals as the trace prints them.
fn describe(name: &str, count: u64, ns: u128, host: u128) -> String {
    let ms = |ns: u128| ns as f64 / 1e6;
    if host == ns {
        format!("{name} {count}x {:.3} ms", ms(ns))
    } else {
        format!("{name} {count}x {:.3} ms (host {:.3})", ms(ns), ms(host))
    }
}
