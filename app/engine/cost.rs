//! `auto`'s choice of backend for one job, made from what the job will cost before anything is paid for it: an
//! adapter probe, a device and its pipelines take 0.1–0.4 s (measured: 96–172 ms on an H100 with the driver's
//! shader cache warm, 2.1 s cold; 300–400 ms on lavapipe), which a small job on the CPU never recovers.
//!
//! The model is two sums of measured rates (bench/RESULTS.md, "auto"), both on the host clock:
//! - the CPU: per triangle set up and walked, per surface voxel written, per grid byte cleared and filled,
//!   divided among the threads; distance fields and solids as multiples of the surface;
//! - the GPU: opening it, then reading the grid back to the host (what bounds a whole GPU run: on an H200 the
//!   bunny's compute passes take 0.6 ms at 1024, the whole run 10.7 ms, nearly all of it the host grid's first
//!   touch; a solid still reads its dense slabs back).
//!
//! `auto` takes the CPU when its estimate is the smaller, without probing, and says so in `backend`.

use super::Job;
use crate::voxel::Mode;

/// One thread's time per triangle of the walk (set-up, narrowing, first touches): ~1.1 µs for small triangles.
const CPU_NS_PER_TRIANGLE: f64 = 1100.0;
/// One thread's time per surface voxel set: ~26 ns (Suzanne at 1024: 2.6 M voxels in 33.5 ms on 2 threads).
const CPU_NS_PER_VOXEL: f64 = 26.0;
/// Clearing and filling the dense grid, per byte, on one thread.
const CPU_NS_PER_GRID_BYTE: f64 = 0.2;
/// The solid fill's time per voxel of the grid (it visits every row), on one thread.
const CPU_NS_PER_SOLID_VOXEL: f64 = 0.5;
/// Surface voxels per voxel² of surface area (the conservative surface is about 1.5 voxels thick).
const VOXELS_PER_AREA: f64 = 1.5;
/// Opening a GPU: adapter, device and pipelines, with the driver's shader cache warm.
const GPU_OPEN_MS: f64 = 150.0;
/// A run's fixed host steps and round trips on an open GPU: the bunny at 512 took 4.1 ms on an H200's machine, 1.2
/// of them its grid's bytes.
const GPU_RUN_MS: f64 = 3.0;
/// Reading a dense solid's or field's slabs back and assembling them on the host, per byte: ~1.9 ns on lavapipe
/// since the grid is streamed through two reused staging buffers (0.2 s for the bunny's 103 MB at 1024; it was
/// 2.9 ns there and on the H100 with a staging buffer and a copy of the grid's size), mostly the first touch of the
/// host grid's pages.
const GPU_NS_PER_GRID_BYTE: f64 = 2.0;
/// A surface grid made from leaves on a hardware GPU, per byte of the grid: only the leaves cross the bus, and the
/// host scatters them on all its threads (the bunny on an H200's machine: 10.7 ms for 99 MB at 1024, 69 ms for 788
/// MB at 2048). `auto` prices only hardware adapters: it declines a software one, whose grids keep the slab path.
const GPU_NS_PER_SURFACE_BYTE: f64 = 0.1;

/// The two estimates, in milliseconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Costs {
    pub cpu_ms: f64,
    pub gpu_ms: f64,
    pub threads: usize,
    /// The GPU is open already (a client that keeps its engine, as Python does): `gpu_ms` leaves its opening out.
    pub open: bool,
}

impl Job<'_> {
    /// The estimated wall time of `self` on `threads` CPU threads and on a GPU opened for it.
    pub fn costs(&self, threads: usize) -> Costs {
        let voxels = VOXELS_PER_AREA * self.area / self.spec.face_area();
        let bytes = self.spec.byte_size() as f64;
        let surface = self.triangles() as f64 * CPU_NS_PER_TRIANGLE + voxels * CPU_NS_PER_VOXEL;
        let work = match self.request.mode {
            Mode::Surface | Mode::Surface6 => surface,
            // The fill visits every row of the grid: a few times the surface's work on the meshes measured.
            Mode::Solid => 3.0 * surface + bytes * 8.0 * CPU_NS_PER_SOLID_VOXEL,
            // Distance fields: 15–25x the surface as whole jobs (the bunny, the teapot and the knot at 512, sign
            // and values included, on the 2-core box; bench/RESULTS.md "auto").
            // A shell is the signed field's work, cut afterwards.
            Mode::Sdf | Mode::Udf | Mode::Shell => 20.0 * surface,
        };
        let cpu_ms = (work / threads.max(1) as f64 + bytes * CPU_NS_PER_GRID_BYTE) / 1e6;
        let per_byte = match self.request.mode {
            Mode::Surface | Mode::Surface6 => GPU_NS_PER_SURFACE_BYTE,
            _ => GPU_NS_PER_GRID_BYTE,
        };
        let gpu_ms = GPU_OPEN_MS + GPU_RUN_MS + bytes * per_byte / 1e6;
        Costs { cpu_ms, gpu_ms, threads, open: false }
    }
}

impl Costs {
    /// The estimates where the GPU is open already: its opening is paid. Why it matters: on an H200's machine the
    /// bunny's surface at 1024 takes 8.3 ms on the open GPU against 32.5 ms on 16 CPU threads, while the opening
    /// (86–164 ms) made every such job the CPU's.
    pub fn opened(self) -> Costs {
        Costs { gpu_ms: self.gpu_ms - GPU_OPEN_MS, open: true, ..self }
    }

    /// Why `auto` takes the CPU, or `None` where a GPU may pay for itself.
    pub fn cpu_reason(&self) -> Option<String> {
        (self.cpu_ms <= self.gpu_ms).then(|| {
            format!(
                "auto: ~{} ms on {} CPU threads, under the ~{} ms a GPU takes to {}",
                round(self.cpu_ms),
                self.threads,
                round(self.gpu_ms),
                if self.open { "read back (open already)" } else { "open and read back" }
            )
        })
    }

    /// Why `auto` opened a GPU for the job: the two estimates, for `backend`.
    pub fn gpu_reason(&self) -> String {
        format!(
            "auto: ~{} ms on the GPU, under the ~{} ms of {} CPU threads",
            round(self.gpu_ms),
            round(self.cpu_ms),
            self.threads
        )
    }
}

fn round(ms: f64) -> String {
    if ms < 10.0 { format!("{ms:.1}") } else { format!("{}", ms.round() as u64) }
}
