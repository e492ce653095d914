//! The engine's GPU side in a build without the `gpu` feature: the same items as `device.rs`, with no GPU to
//! hold, so that the engine's code reads the same in both builds and carries no `cfg` inside its functions.

use super::{Backend, ColourStage, Engine, EngineError, GridStage, Job, Notice};
use crate::mesh::Shading;
use crate::voxel::cpu::query::NearestTables;
use crate::voxel::cpu::solid::Boundary;
use crate::voxel::distance::{Band, DistanceField};
use crate::voxel::query::{Placed, Proposed};
use crate::voxel::{Grid, GridSpec, VoxelGrid};
use glam::Vec3;

/// There is no GPU in this build: no engine holds one.
pub(super) enum OnGpu {}

/// Nor plans a field's pass for one.
pub(super) enum FieldPlan {}

impl Engine {
    /// Opens `backend` in a build without the GPU: the CPU, or an error for `Gpu`.
    pub fn open(backend: Backend) -> Result<Engine, EngineError> {
        match backend {
            Backend::Gpu => Err(EngineError::NoGpuBuild),
            Backend::Auto | Backend::Cpu => Ok(Engine::cpu(None)),
        }
    }
}

impl OnGpu {
    pub(super) fn label(&self) -> String {
        match *self {}
    }

    pub(super) fn prepare(&self, _: &Job<'_>) {
        match *self {}
    }

    pub(super) fn busy_ms(&self) -> f64 {
        match *self {}
    }

    pub(super) async fn grid(
        &self,
        _: &Job<'_>,
        _: &[[Vec3; 3]],
        _: &mut Vec<Notice>,
    ) -> Result<Option<GridStage>, EngineError> {
        match *self {}
    }

    pub(super) fn field_plan(
        &self,
        _: &[[Vec3; 3]],
        _: GridSpec,
        _: Band,
        _: &mut Vec<Notice>,
    ) -> Result<Option<FieldPlan>, EngineError> {
        match *self {}
    }

    pub(super) async fn field(
        &self,
        _: &[[Vec3; 3]],
        _: FieldPlan,
        _: &mut Option<Grid>,
        _: &mut Vec<Notice>,
    ) -> Result<Option<(DistanceField, (u64, u64))>, EngineError> {
        match *self {}
    }

    pub(super) async fn inside(
        &self,
        _: &[[Vec3; 3]],
        _: GridSpec,
        _: bool,
        _: &mut Vec<Notice>,
    ) -> Result<Option<(Grid, u64, (u64, u64))>, EngineError> {
        match *self {}
    }

    pub(super) async fn colour(
        &self,
        _: &VoxelGrid,
        _: &[[Vec3; 3]],
        _: &Shading,
        _: &mut Vec<Notice>,
    ) -> Result<Option<ColourStage>, EngineError> {
        match *self {}
    }

    #[cfg_attr(target_arch = "wasm32", allow(dead_code))]
    pub(super) async fn nearest(
        &self,
        _: &NearestTables,
        _: Option<&Boundary>,
        _: &Placed,
        _: &mut Vec<Notice>,
    ) -> Result<Option<Proposed>, EngineError> {
        match *self {}
    }
}
