"""meshvox: exact mesh voxelization on the GPU (WebGPU through wgpu: Vulkan, Metal, DX12) or the CPU.

    >>> import meshvox
    >>> grid = meshvox.voxelize("bunny.obj", 128, mode="solid")
    >>> grid.matrix.shape, grid.matrix.dtype                    # (X, Y, Z) bool, indexed [x, y, z]
    >>> grid.coords()                                         # int32 (N, 3), sorted
    >>> grid.save("bunny.binvox")

The grid is the one ``meshvox voxelize`` writes for the same arguments (the `.npy` of the CLI is ``.matrix``
byte for byte). See docs/python.md.
"""

from __future__ import annotations

import json
import os
import warnings
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from . import _native
from ._native import MeshError

__all__ = ["VoxelGrid", "MeshError", "voxelize", "voxelize_many", "batched_coords", "load", "backends"]
__version__ = _native.__version__

Progress = Callable[[int, int], Any]


class VoxelGrid:
    """A voxel grid: occupancy (``matrix``), where it lies (``origin``, ``pitch``), colours and statistics.

    Voxel ``[x, y, z]`` is the cube with minimum corner ``origin + pitch * (x, y, z)``. Grids compare equal when
    their shape, origin, pitch, voxels and colours are equal, and pickle (for multiprocessing and Dask).
    """

    def __init__(
        self,
        matrix: np.ndarray,
        pitch: float,
        origin: Sequence[float],
        colors: np.ndarray | None = None,
        stats: dict[str, Any] | None = None,
    ) -> None:
        self.matrix: np.ndarray = np.asarray(matrix, dtype=bool)
        self.pitch: float = float(pitch)
        self.origin: np.ndarray = np.asarray(origin, dtype=np.float64).reshape(3)
        self.colors: np.ndarray | None = None if colors is None else np.asarray(colors, dtype=np.uint8)
        self.stats: dict[str, Any] = dict(stats or {})

    @property
    def shape(self) -> tuple[int, int, int]:
        """Voxels along x, y and z."""
        return tuple(int(n) for n in self.matrix.shape)  # type: ignore[return-value]

    @property
    def transform(self) -> np.ndarray:
        """4x4 float64: homogeneous voxel index to the world position of that voxel's centre (trimesh's convention)."""
        t = np.eye(4)
        t[:3, :3] *= self.pitch
        t[:3, 3] = self.origin + 0.5 * self.pitch
        return t

    def coords(self, order: str = "xyz") -> np.ndarray:
        """The set voxels' indices, int32 (N, 3), sorted: by x, then y, then z for ``"xyz"``; ``"zyx"`` gives
        (z, y, x) rows sorted by z, then y, then x (spconv's layout)."""
        if order == "xyz":
            return np.argwhere(self.matrix).astype(np.int32)
        if order == "zyx":
            return np.argwhere(self.matrix.transpose(2, 1, 0)).astype(np.int32)
        raise ValueError(f"order {order!r}: use 'xyz' or 'zyx'")

    @property
    def points(self) -> np.ndarray:
        """World positions of the set voxels' centres, float64 (N, 3), in ``coords()`` order."""
        return self.origin + (self.coords().astype(np.float64) + 0.5) * self.pitch

    def save(self, path: str | os.PathLike[str], *, merge: bool = False) -> None:
        """Writes the grid in the format the extension names (``.npy``, ``.binvox``, ``.vox``, ``.glb``, ``.ply``,
        ``.obj``) with the CLI's writers, atomically; a coloured ``.npy`` gets ``.colors.npy`` beside it.
        ``merge`` joins coplanar faces of the mesh formats."""
        matrix = np.ascontiguousarray(self.matrix, dtype=np.uint8)
        colors = None if self.colors is None else np.ascontiguousarray(self.colors, dtype=np.uint8)
        _native.save(os.fspath(path), matrix, tuple(self.origin), self.pitch, colors, merge)

    def to_trimesh(self) -> Any:
        """The grid as a ``trimesh.voxel.VoxelGrid`` (needs trimesh): the same voxels at the same places."""
        import trimesh

        return trimesh.voxel.VoxelGrid(trimesh.voxel.encoding.DenseEncoding(self.matrix), transform=self.transform)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, VoxelGrid):
            return NotImplemented
        same_colors = (self.colors is None and other.colors is None) or (
            self.colors is not None and other.colors is not None and np.array_equal(self.colors, other.colors)
        )
        return (
            self.shape == other.shape
            and self.pitch == other.pitch
            and np.array_equal(self.origin, other.origin)
            and np.array_equal(self.matrix, other.matrix)
            and same_colors
        )

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return (
            f"VoxelGrid(shape={self.shape}, voxels={int(self.matrix.sum())}, pitch={self.pitch:g}, "
            f"origin={tuple(float(o) for o in self.origin)}, colors={self.colors is not None})"
        )


def _source(mesh: Any) -> Any:
    """A path as str, or (float64 (V, 3), int64 (F, 3)) arrays, from what users pass."""
    if isinstance(mesh, (str, os.PathLike)):
        return os.fspath(mesh)
    module = type(mesh).__module__
    if module.startswith("trimesh"):
        if type(mesh).__name__ == "Scene":
            mesh = mesh.to_mesh() if hasattr(mesh, "to_mesh") else mesh.dump(concatenate=True)
        return _arrays(mesh.vertices, mesh.faces)
    if isinstance(mesh, (tuple, list)) and len(mesh) == 2:
        return _arrays(mesh[0], mesh[1])
    raise TypeError(
        f"mesh must be a path, a trimesh.Trimesh or Scene, or a (vertices, faces) pair; got {type(mesh).__name__}"
    )


def _arrays(vertices: Any, faces: Any) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.dtype.kind != "f":
        raise ValueError(f"vertices must be float32 or float64, not {v.dtype}")
    if f.dtype.kind not in "iu":
        raise ValueError(f"faces must be integers, not {f.dtype}")
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vertices must have shape (V, 3), not {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must have shape (F, 3), not {f.shape}")
    if len(f) == 0:
        raise ValueError("faces is empty: there is nothing to voxelize")
    if not np.isfinite(v).all():
        row = int(np.argwhere(~np.isfinite(v))[0][0])
        raise ValueError(f"vertex {row} has a NaN or infinite coordinate")
    if f.dtype.kind == "u" and f.size and f.max() > np.iinfo(np.int64).max:
        raise ValueError("a face index is out of range")
    return np.ascontiguousarray(v, dtype=np.float64), np.ascontiguousarray(f, dtype=np.int64)


def _bounds(bounds: Any) -> tuple[tuple[float, float, float], tuple[float, float, float]] | None:
    if bounds is None:
        return None
    lo, hi = (np.asarray(b, dtype=np.float64).reshape(3) for b in bounds)
    return (tuple(lo), tuple(hi))  # type: ignore[return-value]


def _grid(out: dict[str, Any]) -> VoxelGrid:
    for notice in out["notices"]:
        warnings.warn(f"meshvox: {notice}", RuntimeWarning, stacklevel=3)
    matrix = out["matrix"].view(np.bool_)
    return VoxelGrid(matrix, out["pitch"], out["origin"], out["colors"], json.loads(out["stats"]))


def voxelize(
    mesh: Any,
    resolution: int | None = None,
    *,
    pitch: float | None = None,
    axis: str = "longest",
    mode: str = "surface",
    backend: str = "auto",
    colour: bool | None = None,
    bounds: Any = None,
    progress: Progress | None = None,
) -> VoxelGrid:
    """Voxelizes ``mesh`` (a path to an OBJ, glTF/GLB, STL or PLY file, a ``trimesh.Trimesh`` or ``Scene``, or a
    ``(vertices, faces)`` pair) into a grid of ``resolution`` voxels along ``axis`` (or voxels of edge ``pitch``).

    ``mode``: ``"surface"`` (every voxel a triangle touches), ``"solid"`` (plus the inside, by the generalized
    winding number: right on open meshes) or ``"surface6"`` (the thin surface). ``backend``: ``"auto"`` (the GPU
    where it pays, else the CPU), ``"gpu"`` or ``"cpu"``. ``colour``: ``None`` colours the voxels when the mesh
    has colours, ``False`` never. ``bounds=(min, max)`` fixes the grid's world box, so that a dataset shares one
    frame. ``progress(done, total)`` is called from this thread now and then. The GIL is released meanwhile, and
    Ctrl-C stops the work.
    """
    out = _native.voxelize(
        _source(mesh), resolution, pitch, axis, mode, backend, colour, _bounds(bounds), progress
    )
    return _grid(out)


def voxelize_many(
    meshes: Iterable[Any],
    resolution: int | None = None,
    *,
    workers: int | None = None,
    pitch: float | None = None,
    axis: str = "longest",
    mode: str = "surface",
    backend: str = "auto",
    colour: bool | None = None,
    bounds: Any = None,
    progress: Progress | None = None,
) -> list[VoxelGrid]:
    """Voxelizes many meshes with one engine on ``workers`` threads (default: one per core), as ``meshvox batch``
    does; returns the grids in input order. ``progress(done, total)`` counts meshes."""
    sources = [_source(m) for m in meshes]
    outs = _native.voxelize_many(
        sources, resolution, pitch, axis, mode, backend, colour, _bounds(bounds), progress, workers
    )
    return [_grid(o) for o in outs]


def batched_coords(grids: Sequence[VoxelGrid], order: str = "xyz") -> np.ndarray:
    """The grids' voxel coordinates stacked as int32 (N, 4) with the batch index first (MinkowskiEngine,
    torchsparse >= 2.1, spconv)."""
    parts = []
    for i, g in enumerate(grids):
        c = g.coords(order)
        parts.append(np.column_stack([np.full(len(c), i, dtype=np.int32), c]))
    if not parts:
        return np.zeros((0, 4), dtype=np.int32)
    return np.concatenate(parts).astype(np.int32, copy=False)


def load(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray]:
    """A mesh file's triangles as (vertices float64 (V, 3), faces int64 (F, 3)), in world space with the file's
    node transforms applied (equal positions shared)."""
    return _native.load(os.fspath(path))


def backends() -> dict[str, Any]:
    """What ``backend="auto"`` picks on this machine and why: ``{"auto": "gpu"|"cpu", "backend": label,
    "notes": [...], "threads": n}``. Opens the GPU device if it has not been opened yet."""
    return _native.backends()
