//! Queries and training samples through the engine (`meshvox query`, `meshvox sample`, `batch --sample`, Python's
//! `query`, `sample` and `sample_many`): on a GPU engine the nearest triangles come from the GPU
//! (`shaders/query.wgsl`), and so do the sides where its certified f32 can be sure of them, the host deciding the
//! rest with exact predicates; on the CPU engine both are the CPU's ([`Prepared::query`]). The answers are the same
//! either way (docs/training.md): the nearest triangle is the first in the mesh at the least distance, and the side
//! is the exact one. Native only: the page asks no queries.

use super::{Backend, Engine, EngineError, Notice, ms};
use crate::voxel::query::{Answers, Prepared, Sign};
use crate::voxel::sample::{SampleRequest, Samples, draw};
use glam::DVec3;
use web_time::Instant;

/// The backend a query opens: `auto` is the CPU, whatever the count of points (a client asks before opening, so that
/// `auto` opens no device). Why: the CPU confirms every triangle the GPU proposes with its own
/// walk, and decides the signs and the f64 answers, so a GPU adds its search to the CPU's work rather than taking
/// it away. Measured on an H200 with 16 host threads, 1M points: the bunny at 1.32M points/s through the GPU against
/// 1.76M on the CPU, Spot at 2.14M against 2.71M (bench/RESULTS.md). `gpu` stays for those who ask.
pub fn query_backend(backend: Backend) -> Backend {
    match backend {
        Backend::Auto => Backend::Cpu,
        other => other,
    }
}

/// A query's answers, and where they were made.
pub struct Queried {
    pub answers: Answers,
    /// Where the nearest triangles were found, as a report's `backend` says it.
    pub backend: String,
    /// Milliseconds the GPU's search took (its turn included), where it ran.
    pub gpu_ms: Option<f64>,
    /// Points whose nearest triangle the host searched for (the GPU could not prove that only its triangle's
    /// neighbours can be nearer) or whose side it decided (the GPU's bounds left it open, or it decides none: a
    /// winding number's value asked for, GL). Every other point's triangle is settled on the host among the GPU's
    /// and its neighbours, by the CPU's f32 and tie rule ([`Prepared::query_found`]); all points on the CPU.
    pub host_decided: u64,
    /// Milliseconds the calling thread waited for the GPU's search after its own work (the signs) was done, less
    /// the search thread's own host work (ordering the points, uploads, taking the answers); `None` on the CPU.
    pub wait_ms: Option<f64>,
    /// The query's time less `wait_ms`: the host's own work (placing the points, the sides the GPU did not
    /// decide, settling or searching for each triangle, the f64 answers).
    pub host_work_ms: f64,
    /// What happened on the way (the CPU standing in for the GPU).
    pub notices: Vec<Notice>,
}

impl Engine {
    /// The answers at `points` (world space), as [`Prepared::query`] gives them, on this engine's backend.
    pub fn query(
        &self,
        prepared: &Prepared,
        points: &[DVec3],
        sign: Sign,
        winding: bool,
    ) -> Result<Queried, EngineError> {
        let start = Instant::now();
        let Some(on) = &self.gpu else {
            let answers = prepared.query(points, sign, winding).map_err(EngineError::Query)?;
            let host_decided = points.len() as u64;
            let (backend, host_work_ms) = (self.cpu_label(), ms(start));
            let notices = Vec::new();
            return Ok(Queried { answers, backend, gpu_ms: None, host_decided, wait_ms: None, host_work_ms, notices });
        };
        self.blocking(|| {
            let span = crate::trace::span("query: place points");
            let placed = prepared.place(points).map_err(EngineError::Query)?;
            drop(span);
            let span = crate::trace::span("query: tables");
            let tables = prepared.nearest_tables();
            drop(span);
            let device_sides = prepared.device_sides(sign, winding);
            let mut notices = Vec::new();
            // The GPU searches on a thread of its own while this one decides the signs on the library's pool where
            // the GPU does not (winding numbers' values, which the host sums to their tolerance).
            let (found, sides, gpu_ms) = std::thread::scope(|scope| {
                let search = scope.spawn(|| {
                    let (t, waited) = (Instant::now(), crate::trace::waited_ns());
                    let found = pollster::block_on(on.nearest(tables, device_sides, &placed, &mut notices));
                    // The search thread's own work (ordering the points, uploads, taking the answers) is the
                    // host's too: only its waits for the device are waits.
                    let own = ms(t) - (crate::trace::waited_ns() - waited) as f64 / 1e6;
                    (found, ms(t), own)
                });
                let sides = device_sides.is_none().then(|| prepared.sides(&placed, sign, winding));
                let waiting = Instant::now();
                let (found, gpu_ms, own) = search.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic));
                (found, sides, (gpu_ms, (ms(waiting) - own).max(0.0)))
            });
            let (gpu_ms, wait_ms) = gpu_ms;
            let found = found?;
            let backend = match &found {
                Some(_) => self.label(),
                None => self.cpu_label(),
            };
            let proposed = found.unwrap_or_default();
            let span = crate::trace::span("query: settle and answer");
            let (answers, host_decided) = prepared.query_found(points, &placed, &proposed, sides, sign, winding);
            drop(span);
            let host_work_ms = ms(start) - wait_ms;
            if let Some(spans) = crate::trace::take() {
                let n = points.len();
                eprintln!(
                    "trace: query of {n} points: host work {host_work_ms:.1} ms, waits for the device {wait_ms:.1} ms; {spans}"
                );
            }
            let wait_ms = Some(wait_ms);
            Ok(Queried { answers, backend, gpu_ms: Some(gpu_ms), host_decided, wait_ms, host_work_ms, notices })
        })
    }

    /// The samples of `request` around the prepared mesh: drawn on the CPU (the same points for a seed on every
    /// backend), their signed distances from [`Engine::query`].
    pub fn sample(&self, prepared: &Prepared, request: &SampleRequest) -> Result<(Samples, Queried), EngineError> {
        let drawn = draw(prepared, request)?;
        let mut queried = self.query(prepared, &drawn.points, Sign::Winding, false)?;
        let answers = std::mem::take(&mut queried.answers);
        Ok((drawn.finish(answers), queried))
    }
}
