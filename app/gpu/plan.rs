//! How a sparse run (`gpu/sparse.rs`) is cut: [`SparsePlan`] sizes the bricks of the grid and the one buffer each
//! brick's leaf table and slots share, and gives the shader's parameters for a brick. Apart from the run, which
//! holds a plan, and the chain, which reads it.

use super::Gpu;
use super::voxelize::{Options, Params, uses_leaves};
use crate::voxel::GridSpec;
use crate::voxel::cpu::leaves::SLOT_WORDS;
use crate::voxel::sparse::Brick;

/// How a sparse run is cut: the bricks, and the one buffer each brick's table and slots share.
pub(crate) struct SparsePlan {
    pub(super) bricks: Vec<Brick>,
    /// Words of the largest brick's table; the slots start after it.
    pub(super) slot_base: u32,
    /// Slots the buffer holds.
    pub(super) slots: u32,
    pub(super) buffer_bytes: u64,
    /// Whether the table may hold entries (a brick cut after its slots ran out leaves some): the next brick
    /// clears it whole. `finish_leaves` clears the entries of the slots it finishes.
    pub(super) dirty: bool,
}

/// The most leaves a brick's table may have (16 M leaves, a 2048³ box): the table's clear, after a brick that ran
/// out of slots, stays short.
const MAX_TABLE: u64 = 1 << 24;

impl SparsePlan {
    /// The plan of a run that [`uses_leaves`](super::voxelize::uses_leaves): bricks whose table is an eighth of one binding (or of
    /// `max_slab_bytes`, which the tests lower to force many bricks), the rest of the binding for slots.
    pub(super) fn for_run(gpu: &Gpu, spec: GridSpec, options: &Options) -> Option<SparsePlan> {
        if !uses_leaves(gpu, options) {
            return None;
        }
        let limit = options.max_slab_bytes.unwrap_or(u64::MAX).min(gpu.max_binding_bytes());
        let words = (limit / 4).min(u32::MAX as u64);
        let (_, bricks) = Brick::tiling(spec.dims, (words / 8).clamp(1, MAX_TABLE));
        let table = bricks.iter().map(Brick::leaves).max().unwrap_or(1);
        let slot_base = table.next_multiple_of(64);
        // A slot for every leaf of a small table; an eighth of a large one (a surface crosses a few percent of a
        // brick's leaves: the bunny at 2048, 225 k of 12.9 M), so a dense grid on a large adapter does not take a
        // gigabyte of slots. A brick with more leaves than slots is cut and run again.
        let wanted = table.min((table / 8).max(1 << 16));
        let slots = (words.saturating_sub(slot_base) / SLOT_WORDS as u64).clamp(1, wanted);
        let buffer_bytes = (slot_base + slots * SLOT_WORDS as u64) * 4;
        Some(SparsePlan { bricks, slot_base: slot_base as u32, slots: slots as u32, buffer_bytes, dirty: false })
    }

    /// The shader's parameters for a batch of `tri_count` of `brick`'s triangles (`block_count` scan blocks).
    pub(super) fn params(
        &self,
        spec: GridSpec,
        brick: Brick,
        (tri_count, block_count): (u32, u32),
        wpr: u32,
        scale: f32,
    ) -> Params {
        Params {
            dims: spec.dims.to_array(),
            tri_count,
            words_per_row: wpr,
            slab_z0: brick.lo.z,
            slab_z1: brick.hi.z,
            block_count,
            lattice_scale: scale,
            table_leaves: brick.leaves() as u32,
            slot_base: self.slot_base,
            slots: self.slots,
            brick_lo: brick.lo.to_array(),
            _pad_lo: 0,
            brick_hi: brick.hi.to_array(),
            _pad_hi: 0,
        }
    }
}
