//! Several small voxelizations in one submission ([`GpuVoxelizer::voxelize_group_async`]): a dataset's meshes at
//! 128³ take a tenth of a millisecond of GPU time each, and a run of its own costs each of them five submissions
//! and two waits for the device (set-up, walk, the counters' copy and map, the grid's copy and map), which on a
//! discrete GPU is most of the ~0.7 ms an H100 took per small mesh (bench/RESULTS.md, "seed"). A group records
//! every member's set-up, walk and exact passes into one command buffer and reads every grid, unsure count and
//! pass timing back through one staging buffer and one map.
//!
//! Each member keeps its own buffers and bind groups (`Run::allocate`), so the passes are the single run's,
//! unchanged; what a group may hold is what one slab and one triangle batch hold ([`GpuVoxelizer::groupable`]).
//! A member whose unsure list overflows is decided on the CPU as a single run's would be; a group that fails as
//! a whole (a device error) is run again member by member, so each meets its own error.

use super::readback::{first_word, read_buffers};
use super::run::{Batch, Run, record_set_up, record_walk};
use super::util::scoped;
use super::voxelize::{Attempt, GpuOutput, GpuVoxelizer, Options, SCAN_WG, SETUP_BYTES, TRIANGLE_BYTES, slab_plan};
use super::{Gpu, GpuError};
use crate::voxel::{GridSpec, Mode, VoxelGrid, on_lattice};
use glam::Vec3;

/// The largest dense grid a group member may have: 4 MiB, a 320³ grid (a 128³ grid is 256 KiB). Larger jobs
/// are bounded by their passes and readback, not by the submissions a group saves.
pub const GROUP_GRID_BYTES: u64 = 4 << 20;
/// The most members in one group, and the most grid bytes all of them together.
pub const GROUP_JOBS: usize = 32;
pub const GROUP_BYTES: u64 = 64 << 20;
/// The unsure list of a group member: 2^14 entries (256 KiB instead of a single run's 4 MiB, allocated per
/// member). The bunny at 512 lists 120 tests and a cube at 512 about 2,000; past it the member is decided on the
/// CPU, exactly.
const GROUP_UNSURE: u64 = 1 << 14;

/// One member of a group: grid-space triangles, its grid and what to make.
pub struct GroupJob<'a> {
    pub triangles: &'a [[Vec3; 3]],
    pub spec: GridSpec,
    pub options: Options,
}

impl GpuVoxelizer {
    /// Whether a job may join a group: a dense surface or thin-surface grid read back whole, in one slab and one
    /// triangle batch, no larger than [`GROUP_GRID_BYTES`].
    pub fn groupable(&self, gpu: &Gpu, triangles: usize, spec: GridSpec, options: &Options) -> bool {
        let limit = gpu.max_binding_bytes();
        let one_batch = triangles as u64 <= (limit / SETUP_BYTES).min(limit / TRIANGLE_BYTES);
        let one_slab = slab_plan(gpu, spec, options).is_ok_and(|(_, slabs)| slabs == 1);
        options.read_grid
            && !options.sparse
            && !options.instances
            && options.mode != Mode::Solid
            && options.max_batch_triangles.is_none()
            && spec.byte_size() <= GROUP_GRID_BYTES
            && triangles > 0
            && one_batch
            && one_slab
    }

    /// Voxelizes every job, in one submission where there are several and all may join a group (else one after
    /// another, as [`GpuVoxelizer::voxelize_async`] does). Each result is the one a single run gives.
    pub async fn voxelize_group_async(&self, gpu: &Gpu, jobs: &[GroupJob<'_>]) -> Vec<Result<GpuOutput, GpuError>> {
        let grouped = jobs.len() > 1
            && !cfg!(target_arch = "wasm32")
            && jobs.iter().all(|j| self.groupable(gpu, j.triangles.len(), j.spec, &j.options));
        if grouped && let Ok(attempts) = self.run_group(gpu, jobs).await {
            let mut outputs = Vec::with_capacity(jobs.len());
            for (job, attempt) in jobs.iter().zip(attempts) {
                outputs.push(match attempt {
                    Attempt::Done(output) => Ok(output),
                    Attempt::Overflow => self.decide_on_cpu(gpu, job.triangles, job.spec, &job.options).await,
                });
            }
            return outputs;
        }
        let mut outputs = Vec::with_capacity(jobs.len());
        for job in jobs {
            outputs.push(self.voxelize_async(gpu, job.triangles, job.spec, &job.options).await);
        }
        outputs
    }

    /// The group's passes in one command buffer, its results through one map.
    async fn run_group(&self, gpu: &Gpu, jobs: &[GroupJob<'_>]) -> Result<Vec<Attempt>, GpuError> {
        gpu.check()?;
        let mut members = Vec::with_capacity(jobs.len());
        for job in jobs {
            members.push(on_lattice(job.triangles, job.spec.dims)?);
        }
        let options: Vec<Options> = jobs
            .iter()
            .map(|j| {
                let max_unsure = Some(j.options.max_unsure.map_or(GROUP_UNSURE, |n| n.min(GROUP_UNSURE)));
                Options { dense_from_leaves: Some(false), max_unsure, ..j.options.clone() }
            })
            .collect();
        let mut runs = Vec::with_capacity(jobs.len());
        for ((job, (triangles, lattice)), options) in jobs.iter().zip(&members).zip(&options) {
            runs.push(Run::allocate(self, gpu, triangles, job.spec, *lattice, options).await?);
        }
        let timed = scoped(&gpu.device, || {
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            let timed: Vec<u64> =
                runs.iter_mut().zip(&members).map(|(run, (tris, _))| run.encode_member(&mut encoder, tris)).collect();
            super::util::submit(&gpu.queue, encoder.finish());
            Ok(timed)
        })
        .await?;
        read_back_group(gpu, &mut runs, &timed).await
    }
}

impl Run<'_> {
    /// Uploads the member's triangles and parameters and records its set-up, walk and exact passes (the single
    /// run's `set_up_batch` and `encode_slab`, over its one slab) into `encoder`. Returns the bytes of its pass
    /// times to read back.
    fn encode_member(&mut self, encoder: &mut wgpu::CommandEncoder, triangles: &[[Vec3; 3]]) -> u64 {
        let tri_count = triangles.len() as u32;
        let batch = Batch { tri_count, block_count: tri_count.div_ceil(SCAN_WG) };
        let params = self.params(batch, 0, self.spec.dims.z);
        let (walk, exact) = self.walk_and_exact();
        let (gpu, v) = (self.gpu, self.v);
        self.traffic.upload += std::mem::size_of_val(triangles) as u64;
        let (b, timer) = (&self.buffers, &mut self.timer);
        // Both writes land before the group's one submission, and the member's set-up and walk read the same
        // parameters (the set-up ignores the slab).
        gpu.queue.write_buffer(&b.triangles, 0, bytemuck::cast_slice(triangles));
        gpu.queue.write_buffer(&b.params, 0, bytemuck::bytes_of(&params));
        record_set_up(v, b, encoder, timer, batch);
        record_walk(v, b, encoder, timer, (walk, exact));
        self.timer.as_mut().map_or(0, |t| t.resolve(encoder))
    }
}

/// Every member's grid, unsure count and pass times through one staging buffer and one map; each member's
/// output, or `Overflow` where its unsure list did.
async fn read_back_group(gpu: &Gpu, runs: &mut [Run<'_>], timed: &[u64]) -> Result<Vec<Attempt>, GpuError> {
    let mut ranges = Vec::new();
    for (run, &timed) in runs.iter().zip(timed) {
        let b = &run.buffers;
        ranges.push((&b.slab, 0, run.spec.byte_size()));
        ranges.push((&b.unsure_count, 0, 4));
        if let Some(t) = run.timer.as_ref().filter(|_| timed > 0) {
            ranges.push((t.resolved(), 0, timed));
        }
    }
    let parts = read_buffers(&gpu.device, &gpu.queue, &ranges).await?;
    let mut parts = parts.into_iter();
    let members = runs.len();
    let mut attempts = Vec::with_capacity(members);
    for (run, &timed) in runs.iter_mut().zip(timed) {
        let bytes = parts.next().unwrap_or_default();
        let listed = first_word(&parts.next().unwrap_or_default()).unwrap_or(0);
        let times = if timed > 0 { parts.next() } else { None };
        run.traffic.readback += run.spec.byte_size() + 4 + timed;
        if listed as u64 > run.unsure_entries {
            attempts.push(Attempt::Overflow);
            continue;
        }
        let grid = VoxelGrid::from_words(run.spec, bytemuck::pod_collect_to_vec::<u8, u32>(&bytes));
        let gpu_ms = match (run.timer.as_mut(), times) {
            (Some(t), Some(times)) => Some(t.finish(&gpu.queue, &times)),
            _ => None,
        };
        attempts.push(Attempt::Done(GpuOutput {
            grid: Some(grid),
            sparse: None,
            instances: None,
            gpu_ms: gpu.timestamps.then_some(gpu_ms.unwrap_or(0.0)),
            slabs: 1,
            batches: 1,
            exact_tests: Some(listed as u64),
            decided_on_cpu: false,
            rows_on_host: 0,
            inside_on_host: false,
            host_decided: 0,
            traffic: run.traffic,
            group: members as u32,
            voxels: None,
        }));
    }
    Ok(attempts)
}
