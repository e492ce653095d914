// Helpers every compute module joins, first (the `*_WGSL` constants in app/gpu/ join the files at build time), so
// each is written once: the dot product in one order of operations (the CPU's `dot3` in app/voxel/cpu/common.rs
// keeps the same order, so the two round alike) and the flat index of an invocation in a 2D dispatch. Nothing here
// reads a binding, so every module can join it.

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

// The invocation's index in a dispatch of `groups` workgroups of `size` invocations laid out in 2D (a dispatch is
// at most 65535 groups along x, so large ones wrap onto y).
fn linear_id(wid: vec3<u32>, lid: vec3<u32>, groups: vec3<u32>, size: u32) -> u32 {
    return (wid.y * groups.x + wid.x) * size + lid.x;
}

// The thread's index in a dispatch by global id, `row_threads` threads per row along x.
fn thread_index(gid: vec3<u32>, row_threads: u32) -> u32 {
    return gid.x + gid.y * row_threads;
}

// Whether the invocation's loops were cut short. llvmpipe (lavapipe, and GL on llvmpipe) ends every loop of an
// invocation without a word once its loops have run 65,535 passes in all (gallivm's loop limiter: one count shared
// by every loop of the shader, per 8 lanes), so a long walk's later loops each stop after one pass and what it
// wrote is wrong. A loop of two passes that stopped after one tells. `zero` is a runtime 0 of a wide range (a grid
// size shifted right by 16), so that no compiler can bound the passes and unroll the loop away (a precaution: GL's
// llvmpipe missed two of the bunny's cut groups with either range; the groups also check their walk's end). Hardware
// drivers have no such limit: there it is never true.
fn loops_were_cut(zero: u32) -> bool {
    var passes = 0u;
    loop {
        passes += 1u;
        if passes >= 2u + zero {
            break;
        }
    }
    return passes < 2u;
}
