"""Where two .npy outputs of `meshvox voxelize` (CPU and GPU) differ: for occupancy, how many voxels and which;
for distances, the largest difference in voxels and how many signs disagree. Used by bench/gpu_machine.sh."""

import sys

import numpy as np

a, b = (np.load(f) for f in sys.argv[1:3])
if a.shape != b.shape or a.dtype != b.dtype:
    print(f"shape/dtype {a.shape} {a.dtype} vs {b.shape} {b.dtype}")
elif a.dtype == np.float32:
    h = float(np.abs(a).max()) / 3.0  # band 3: the background is 3 voxels
    d = np.abs(a.astype(np.float64) - b.astype(np.float64)) / h
    signs = int(np.count_nonzero(np.signbit(a) != np.signbit(b)))
    print(f"max {d.max():.3e} voxels, {np.count_nonzero(d)} values differ, {signs} signs differ")
else:
    diff = np.argwhere(a != b)
    only_cpu = int(np.count_nonzero(a & ~b)) if a.dtype == np.bool_ else int(np.count_nonzero((a != 0) & (b == 0)))
    print(f"{len(diff)} voxels differ ({only_cpu} only on the CPU) at {diff[:12].tolist()}")
