"""meshvox: exact mesh voxelization on the GPU (WebGPU through wgpu: Vulkan, Metal, DX12) or the CPU.

    >>> import meshvox
    >>> grid = meshvox.voxelize("bunny.obj", 128, mode="solid")
    >>> grid.matrix.shape, grid.matrix.dtype                    # (X, Y, Z) bool, indexed [x, y, z]
    >>> grid.coords()                                         # int32 (N, 3), sorted
    >>> grid.save("bunny.binvox")
    >>> sdf = meshvox.voxelize("bunny.obj", 128, mode="sdf", band=3)
    >>> sdf.distances.shape, sdf.distances.dtype               # (X, Y, Z) float32, negative inside
    >>> sdf.save("bunny.vdb")                                  # an OpenVDB level set

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

__all__ = [
    "VoxelGrid",
    "MeshError",
    "Mesh",
    "Query",
    "voxelize",
    "voxelize_many",
    "voxelize_points",
    "query",
    "Samples",
    "sample",
    "sample_many",
    "batched_coords",
    "load",
    "backends",
]
__version__ = _native.__version__

# Before any GPU is probed: without a runtime directory, Mesa's Vulkan layer would print an alarming line twice
# on every probe (meshvox.gpu::headless_vulkan_setting says why); the CLI sets the same variable.
_setting = _native.headless_vulkan_setting()
if _setting is not None:
    os.environ.setdefault(*_setting)
del _setting

Progress = Callable[[int, int], Any]


class VoxelGrid:
    """A voxel grid: occupancy (``matrix``), where it lies (``origin``, ``pitch``), colours and statistics.

    Voxel ``[x, y, z]`` is the box with minimum corner ``origin + pitch * (x, y, z)``: ``pitch`` is a float for
    cubic voxels, a float64 (3,) array of the x, y and z sizes for others (``size=`` or three ``pitch`` values);
    both broadcast alike in such formulas. Grids compare equal when
    their shape, origin, pitch, voxels and colours are equal, and pickle (for multiprocessing and Dask; a grid
    from ``voxelize`` travels as its bit grid, an eighth of ``matrix``).
    """

    def __init__(
        self,
        matrix: np.ndarray,
        pitch: float | Sequence[float],
        origin: Sequence[float],
        colors: np.ndarray | None = None,
        stats: dict[str, Any] | None = None,
    ) -> None:
        self._matrix: np.ndarray | None = np.asarray(matrix, dtype=bool)
        self._colors: np.ndarray | None = None if colors is None else np.asarray(colors, dtype=np.uint8)
        self._shape: tuple[int, int, int] = tuple(int(n) for n in self._matrix.shape)  # type: ignore[assignment]
        self._words: np.ndarray | None = None
        self._rgba: np.ndarray | None = None
        self.pitch: float | np.ndarray = _pitch_value(pitch)
        self.origin: np.ndarray = np.asarray(origin, dtype=np.float64).reshape(3)
        self.stats: dict[str, Any] = dict(stats or {})
        self.distances: np.ndarray | None = None
        self.background: float | None = None
        self.signed: bool | None = None
        #: A shell's thickness in voxels (``mode="shell"``; else None): ``distances`` is then the field it was cut
        #: from, and ``to_mesh`` gives its walls.
        self.thickness: float | None = None
        self._labels: dict[str, np.ndarray] | None = None
        self._label_values: dict[str, np.ndarray] | None = None

    @classmethod
    def _packed(cls, words, shape, pitch, origin, rgba, stats) -> "VoxelGrid":
        """A grid as the engine made it: the bit grid (uint32 words, rows along x, z-major) and one RGBA per set
        voxel in its storage order; ``matrix`` and ``colors`` are unpacked from them when first asked for."""
        grid = cls.__new__(cls)
        grid._matrix, grid._colors = None, None
        grid._shape = tuple(int(n) for n in shape)
        grid._words, grid._rgba = words, rgba
        grid.pitch, grid.origin = _pitch_value(pitch), np.asarray(origin, dtype=np.float64).reshape(3)
        grid.stats = dict(stats or {})
        grid.distances, grid.background, grid.signed = None, None, None
        grid.thickness = None
        grid._labels, grid._label_values = None, None
        return grid

    def _bits_zyx(self) -> np.ndarray:
        """The bit grid unpacked as bool (Z, Y, X), a view in storage order."""
        nx, ny, nz = self._shape
        rows = np.unpackbits(self._words.view(np.uint8), bitorder="little").reshape(nz, ny, -1)
        return rows[:, :, :nx].view(np.bool_)

    @property
    def matrix(self) -> np.ndarray:
        """bool (X, Y, Z), indexed ``[x, y, z]``: the bytes of ``meshvox voxelize -o grid.npy``."""
        if self._matrix is None:
            self._matrix = np.ascontiguousarray(self._bits_zyx().transpose(2, 1, 0))
        return self._matrix

    @property
    def colors(self) -> np.ndarray | None:
        """uint8 (X, Y, Z, 4) sRGB RGBA of the set voxels (0 elsewhere), or None: the CLI's ``.colors.npy``."""
        if self._colors is None and self._rgba is not None:
            colors = np.zeros(self._shape + (4,), dtype=np.uint8)
            z, y, x = np.nonzero(self._bits_zyx())
            colors[x, y, z] = self._rgba
            self._colors = colors
        return self._colors

    @property
    def labels(self) -> dict[str, np.ndarray] | None:
        """Per-voxel labels asked for with ``attributes=``: a dict from ``"triangle"``, ``"material"`` and ``"node"``
        to int32 (X, Y, Z) arrays, -1 where no voxel is set; or None. ``triangle`` indexes :func:`load`'s faces."""
        if self._labels is None and self._label_values is not None:
            zyx = self._bits_zyx()
            z, y, x = np.nonzero(zyx)
            labels = {}
            for name, values in self._label_values.items():
                dense = np.full(self._shape, -1, dtype=np.int32)
                dense[x, y, z] = values
                labels[name] = dense
            self._labels = labels
        return self._labels

    def __getstate__(self) -> dict[str, Any]:
        # Once unpacked, the matrix is the truth (it may have been edited); before, the bits travel.
        field = {"distances": self.distances, "background": self.background, "signed": self.signed,
                 "thickness": self.thickness, "labels": self._labels, "label_values": self._label_values}
        if self._matrix is None and self._words is not None:
            return {"words": self._words, "rgba": self._rgba, "shape": self._shape, "pitch": self.pitch,
                    "origin": self.origin, "stats": self.stats, **field}
        return {"matrix": self.matrix, "colors": self._colors, "pitch": self.pitch, "origin": self.origin,
                "stats": self.stats, **field}

    def __setstate__(self, state: dict[str, Any]) -> None:
        if "words" in state:
            other = VoxelGrid._packed(state["words"], state["shape"], state["pitch"], state["origin"],
                                      state["rgba"], state["stats"])
        else:
            other = VoxelGrid(state["matrix"], state["pitch"], state["origin"], state["colors"], state["stats"])
        other.distances = state.get("distances")
        other.background, other.signed = state.get("background"), state.get("signed")
        other.thickness = state.get("thickness")
        other._labels, other._label_values = state.get("labels"), state.get("label_values")
        self.__dict__.update(other.__dict__)

    @property
    def shape(self) -> tuple[int, int, int]:
        """Voxels along x, y and z."""
        return self._shape

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
            zyx = self._bits_zyx() if self._matrix is None else self.matrix.transpose(2, 1, 0)
            return np.argwhere(zyx).astype(np.int32)
        raise ValueError(f"order {order!r}: use 'xyz' or 'zyx'")

    @property
    def points(self) -> np.ndarray:
        """World positions of the set voxels' centres, float64 (N, 3), in ``coords()`` order."""
        return self.origin + (self.coords().astype(np.float64) + 0.5) * self.pitch

    def save(
        self,
        path: str | os.PathLike[str],
        *,
        merge: bool = False,
        level: float = 0.0,
        blocks: str | os.PathLike[str] | None = None,
        block: str | None = None,
        palette: str | os.PathLike[str] | None = None,
        dither: bool = False,
    ) -> None:
        """Writes the grid in the format the extension names (``.npy``, ``.binvox``, ``.vox``, ``.vdb`` (OpenVDB),
        ``.nvdb`` (NanoVDB), ``.npz`` (sorted coordinates), ``.glb``, ``.ply``, ``.obj``, ``.stl``, ``.3mf``, ``.schem``,
        ``.litematic``, ``.nbt``, ``.zip`` or ``.mcstructure`` (Minecraft: Sponge v3, Litematica, a structure file up
        to 48³, structure tiles in a datapack, Bedrock's structure file)) with the CLI's writers, atomically. The
        Minecraft formats take ``blocks`` (``"default"`` or a file of ``id,r,g,b[,bedrock]`` lines),
        ``block`` (one block everywhere) and ``dither``; ``.vox`` and the Minecraft formats take ``palette`` (a
        ``.vox`` file, a PNG strip or a text list of colours: each voxel its nearest entry), as the CLI's
        ``--blocks``, ``--block``, ``--palette`` and ``--dither`` do (docs/formats.md). A coloured
        ``.npy`` gets ``.colors.npy`` beside it, a labelled one ``.labels.npy``; labels also go into ``.npz``
        arrays and ``.vdb``/``.nvdb`` int32 grids (the other formats hold none).
        ``merge`` joins coplanar faces of the mesh formats. A distance field (``mode="sdf"``/``"udf"``) is saved
        as ``.npy`` (float32 (X, Y, Z)), ``.npz`` (the band's ``coords`` and ``values``) ``.vdb`` or ``.nvdb`` (a level set),
        as the CLI writes it, or its level set at ``level`` (world units) as a closed mesh (``.ply``, ``.obj``,
        ``.glb``, ``.stl``, ``.3mf``; see :meth:`to_mesh`). A shell (``mode="shell"``) is saved as its voxels, or as
        its walls in the mesh formats. A ``.3mf`` states millimetres (a grid in Python carries no unit; the CLI's
        states the mesh's)."""
        suffix = os.fspath(path).lower().rsplit(".", 1)[-1]
        minecraft = suffix in ("schem", "litematic", "nbt", "zip", "mcstructure")
        if (blocks is not None or block is not None) and not minecraft:
            raise ValueError(
                "blocks= and block= are for Minecraft files: save as .schem, .litematic, .nbt, .zip or .mcstructure"
            )
        if palette is not None and not (minecraft or suffix == "vox"):
            raise ValueError("palette= is for .vox and Minecraft files (.schem, .litematic, .nbt, .zip, .mcstructure)")
        if dither and not (minecraft or palette is not None):
            raise ValueError("dither= is for Minecraft files, and for .vox with palette=")
        if block is not None and (blocks is not None or palette is not None):
            raise ValueError("block= puts one block everywhere: leave out blocks= and palette=")
        walls = self.thickness is not None and os.fspath(path).lower().endswith((".ply", ".obj", ".glb", ".stl", ".3mf"))
        if self.distances is not None and (self.thickness is None or walls):
            distances = np.ascontiguousarray(self.distances, dtype=np.float32)
            background = float(self.background if self.background is not None else np.abs(distances).max())
            _native.save_field(
                os.fspath(path), distances, tuple(self.origin), self.pitch, background, bool(self.signed), float(level),
                self.thickness,
            )
            return
        matrix = np.ascontiguousarray(self.matrix, dtype=np.uint8)
        colors = None if self.colors is None else np.ascontiguousarray(self.colors, dtype=np.uint8)
        labels = [(name, np.ascontiguousarray(a, dtype=np.int32)) for name, a in (self.labels or {}).items()]
        colour_map = (
            None if blocks is None or blocks == "default" else os.fspath(blocks),
            block,
            None if palette is None else os.fspath(palette),
            bool(dither),
        )
        pitch = tuple(float(p) for p in np.broadcast_to(self.pitch, 3))
        _native.save(os.fspath(path), matrix, tuple(self.origin), pitch, colors, merge, labels, colour_map)

    def to_mesh(self, level: float = 0.0, *, trimesh: bool = False) -> Any:
        """A distance field's level set at ``level`` (world units; 0 the surface) as a closed, edge-manifold,
        outward-wound triangle mesh: ``(vertices float64 (V, 3), faces int64 (F, 3))``, or a ``trimesh.Trimesh``
        with ``trimesh=True`` (needs trimesh). Marching tetrahedra over the voxel centres (docs/watertight.md); the
        band must hold the level (voxelize with ``band=`` wider than it), and an unsigned field needs a level above
        0 (the shell around open sheets). A shell's (``mode="shell"``) are its two walls in one closed mesh: the
        surface outward and the level ``-thickness`` voxels inward (``level`` is not used)."""
        if self.distances is None:
            raise ValueError('to_mesh needs a distance field: voxelize with mode="sdf", "udf" or "shell"')
        distances = np.ascontiguousarray(self.distances, dtype=np.float32)
        background = float(self.background if self.background is not None else np.abs(distances).max())
        vertices, faces = _native.level_mesh(
            distances, tuple(self.origin), self.pitch, background, bool(self.signed), float(level), self.thickness
        )
        if trimesh:
            import trimesh as _trimesh

            return _trimesh.Trimesh(vertices, faces, process=False)
        return vertices, faces

    def to_trimesh(self) -> Any:
        """The grid as a ``trimesh.voxel.VoxelGrid`` (needs trimesh): the same voxels at the same places."""
        import trimesh

        return trimesh.voxel.VoxelGrid(trimesh.voxel.encoding.DenseEncoding(self.matrix), transform=self.transform)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, VoxelGrid):
            return NotImplemented
        same_place = np.array_equal(self.pitch, other.pitch) and np.array_equal(self.origin, other.origin)
        if self.shape != other.shape or not same_place or np.shape(self.pitch) != np.shape(other.pitch):
            return False
        if self._matrix is None and other._matrix is None and self._words is not None and other._words is not None:
            same_voxels = np.array_equal(self._words, other._words)
        else:
            same_voxels = np.array_equal(self.matrix, other.matrix)
        a, b = self.colors, other.colors
        da, db = self.distances, other.distances
        if (da is None) != (db is None) or (da is not None and not np.array_equal(da, db)):
            return False
        la, lb = self.labels, other.labels
        if (la is None) != (lb is None) or (la is not None and (la.keys() != lb.keys() or not all(
                np.array_equal(la[k], lb[k]) for k in la))):
            return False
        return same_voxels and ((a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b)))

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return (
            f"VoxelGrid(shape={self.shape}, voxels={len(self.coords())}, pitch={_pitch_text(self.pitch)}, "
            f"origin={tuple(float(o) for o in self.origin)}, colors={self.colors is not None})"
        )


def _pitch_value(pitch: Any) -> float | np.ndarray:
    """A grid's pitch as ``VoxelGrid`` keeps it: a float, or float64 (3,) where the three sizes differ."""
    a = np.asarray(pitch, dtype=np.float64)
    if a.ndim == 0 or (a.shape == (3,) and a[0] == a[1] == a[2]):
        return float(a.reshape(-1)[0])
    if a.shape != (3,):
        raise ValueError(f"pitch: one size or three (x, y, z), not shape {a.shape}")
    return a


def _pitch_text(pitch: float | np.ndarray) -> str:
    return f"{pitch:g}" if isinstance(pitch, float) else "(" + ", ".join(f"{p:g}" for p in pitch) + ")"


def _pitch_arg(pitch: Any) -> str | None:
    """``pitch=`` as the engine parses it: one number or three in the mesh's units, or a string with units
    (``"0.05mm"``, ``"0.05mm,0.05mm,0.03mm"``). ``repr`` keeps every float's digits."""
    if pitch is None or isinstance(pitch, str):
        return pitch
    values = np.asarray(pitch, dtype=np.float64).reshape(-1)
    if values.size not in (1, 3):
        raise ValueError(f"pitch: one size or three (x, y, z), not {values.size}")
    return ",".join(repr(float(v)) for v in values)


def _size_arg(size: Any) -> str | None:
    """``size=(40, None, 30)`` (None or ``"auto"`` keeps proportions) or ``"40,auto,30"``, as the engine parses it."""
    if size is None or isinstance(size, str):
        return size
    parts = list(size)
    if len(parts) != 3:
        raise ValueError(f"size: three counts (x, y, z; None for auto), not {len(parts)}")
    return ",".join("auto" if p is None or p == "auto" else str(int(p)) for p in parts)


def _source(mesh: Any) -> Any:
    """A path as str, a prepared mesh, or (float64 (V, 3), int64 (F, 3)) arrays, from what users pass."""
    if isinstance(mesh, Mesh):
        return mesh._native
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
    if f.dtype.kind == "u" and f.size and f.max() > np.iinfo(np.int64).max:
        raise ValueError("a face index is out of range")
    return np.ascontiguousarray(v, dtype=np.float64), np.ascontiguousarray(f, dtype=np.int64)


def _bounds(bounds: Any) -> tuple[tuple[float, float, float], tuple[float, float, float]] | None:
    if bounds is None:
        return None
    lo, hi = (np.asarray(b, dtype=np.float64).reshape(3) for b in bounds)
    return (tuple(lo), tuple(hi))  # type: ignore[return-value]


def _attributes(attributes: Sequence[str]) -> str:
    if isinstance(attributes, str):
        attributes = attributes.split(",")
    return ",".join(attributes)


def _grid(out: dict[str, Any]) -> VoxelGrid:
    for notice in out["notices"]:
        warnings.warn(f"meshvox: {notice}", RuntimeWarning, stacklevel=3)
    stats = json.loads(out["stats"])
    grid = VoxelGrid._packed(out["words"], out["shape"], out["pitch"], out["origin"], out["rgba"], stats)
    grid.distances, grid.background, grid.signed = out["distances"], out["background"], out["signed"]
    grid.thickness = out["thickness"]
    grid._label_values = out["labels"]
    return grid


def voxelize(
    mesh: Any,
    resolution: int | None = None,
    *,
    pitch: float | Sequence[float] | str | None = None,
    size: Sequence[int | None] | str | None = None,
    axis: str = "longest",
    mode: str = "surface",
    backend: str = "auto",
    colour: bool | None = None,
    bounds: Any = None,
    progress: Progress | None = None,
    band: float | str = 3,
    attributes: Sequence[str] = (),
    thickness: float | str | None = None,
    drain: Any = None,
    fill_pockets: bool = False,
    up: str | None = None,
    unit: str | None = None,
    pose: float | None = None,
    animation: str | int | None = None,
) -> VoxelGrid:
    """Voxelizes ``mesh`` (a path to an OBJ, glTF/GLB, STL or PLY file, a ``trimesh.Trimesh`` or ``Scene``, or a
    ``(vertices, faces)`` pair) into a grid of ``resolution`` voxels along ``axis``, or voxels of edge ``pitch``
    (one size, three for voxels that are not cubes, or a string with units: ``"0.05mm,0.05mm,0.03mm"``, in the
    world whose unit is ``unit``), or ``size=(x, y, z)`` voxels, each a count or ``None`` (auto: the model's
    proportions kept). Voxels that are not cubes make surfaces and solids (``pitch`` is then a (3,) array); the
    distance fields and shells measure in cubes and refuse them.

    ``mode``: ``"surface"`` (every voxel a triangle touches), ``"solid"`` (plus the inside, by the generalized
    winding number: right on open meshes), ``"surface6"`` (the thin surface), or a distance field: ``"sdf"``
    (signed, negative inside) or ``"udf"`` (unsigned), exact within ``band`` voxels of the surface (``"full"``:
    every voxel) and ``±band`` voxels beyond, in ``.distances`` (float32 (X, Y, Z), world units) beside the
    surface's voxels in ``.matrix``; or ``"shell"``: the voxels whose centre is inside within ``thickness`` voxels
    of the surface (default 1; 1 or more holds water), with the signed field it was cut from in ``.distances`` and its walls
    from :meth:`VoxelGrid.to_mesh`. ``backend``: ``"auto"`` (the GPU
    where it pays, else the CPU), ``"gpu"`` or ``"cpu"``. ``colour``: ``None`` colours the voxels when the mesh
    has colours, ``False`` never. ``bounds=(min, max)`` fixes the grid's world box, so that a dataset shares one
    frame. ``attributes`` (any of ``"triangle"``, ``"material"``, ``"node"``) adds per-voxel labels in
    ``.labels``: each voxel's nearest triangle among those touching it, that triangle's material and its glTF node
    or OBJ object. ``progress(done, total)`` is called from this thread now and then. The GIL is released meanwhile, and
    Ctrl-C stops the work.

    For printing (``mode="shell"`` or ``"solid"``; docs/printing.md): ``thickness`` is voxels as a number, or a
    length with a unit (``"2mm"``, ``"0.5cm"``, ``"0.1in"``) in the mesh's world, whose unit is ``unit`` (``"mm"``,
    ``"cm"``, ``"m"``, ``"in"``, ``"ft"``; default metres for glTF, millimetres otherwise). ``drain=N`` cuts N
    drain holes per void on its lowest layers along ``up`` (``"y"`` or ``"z"``; default by the file's convention),
    ``drain=[(x, y, z), (x, y, z, r)]`` one through each world point (``r`` the radius, default 2 voxels; a
    number is voxels, a string may have a unit). ``stats["pockets"]`` lists the voids left sealed (``voxels``,
    ``volume``, ``point``), ``stats["drains"]`` the holes; ``fill_pockets=True`` fills the pockets. A shell with
    holes or filled pockets has its walls' field in ``.distances`` (below 0 within the walls, the holes cut), so
    :meth:`VoxelGrid.to_mesh` and saving as a mesh give the walls with the holes.

    An animated glTF file (skins, morph targets, node animation) is voxelized at its rest pose, or at ``pose``
    seconds of ``animation`` (its name or index; default the first), as the CLI's ``--pose`` and ``--animation``
    (docs/formats.md).
    """
    if animation is not None and pose is None:
        raise ValueError("animation= names the animation pose= plays: give pose= too")
    posed = None if pose is None else (float(pose), None if animation is None else str(animation))
    out = _native.voxelize(
        _source(mesh), resolution, _pitch_arg(pitch), axis, mode, backend, colour, _bounds(bounds), progress,
        str(band), _attributes(attributes), _length(thickness), _voids(drain, fill_pockets, up, unit), posed,
        _size_arg(size),
    )
    return _grid(out)


def _length(value: Any) -> str | None:
    """A length as the engine parses it: a number (voxels) or a string with a unit."""
    if value is None:
        return None
    if isinstance(value, str):
        return value
    return repr(float(value))


def _voids(drain: Any, fill_pockets: bool, up: str | None, unit: str | None) -> dict[str, Any]:
    """``drain=``, ``fill_pockets=``, ``up=`` and ``unit=`` as the engine takes them."""
    voids: dict[str, Any] = {"drain_holes": None, "drain_radius": None, "drain_points": [],
                             "fill_pockets": bool(fill_pockets), "up": up, "unit": unit}
    if drain is None or drain is False:
        return voids
    if isinstance(drain, (int, np.integer)) and not isinstance(drain, bool):
        voids["drain_holes"] = int(drain)
        return voids
    for point in drain:
        p = list(point)
        if len(p) not in (3, 4):
            raise ValueError(f"drain=: each point is (x, y, z) or (x, y, z, r), not {point!r}")
        voids["drain_points"].append(((float(p[0]), float(p[1]), float(p[2])), _length(p[3]) if len(p) == 4 else None))
    return voids


def voxelize_many(
    meshes: Iterable[Any],
    resolution: int | None = None,
    *,
    workers: int | None = None,
    pitch: float | Sequence[float] | str | None = None,
    size: Sequence[int | None] | str | None = None,
    axis: str = "longest",
    mode: str = "surface",
    backend: str = "auto",
    colour: bool | None = None,
    bounds: Any = None,
    progress: Progress | None = None,
    band: float | str = 3,
    attributes: Sequence[str] = (),
    thickness: float | str | None = None,
    drain: Any = None,
    fill_pockets: bool = False,
    up: str | None = None,
    unit: str | None = None,
) -> list[VoxelGrid]:
    """Voxelizes many meshes with one engine on ``workers`` threads (default: one per core), as ``meshvox batch``
    does; returns the grids in input order. ``progress(done, total)`` counts meshes."""
    sources = [_source(m) for m in meshes]
    outs = _native.voxelize_many(
        sources, resolution, _pitch_arg(pitch), axis, mode, backend, colour, _bounds(bounds), progress, workers,
        str(band), _attributes(attributes), _length(thickness), _voids(drain, fill_pockets, up, unit),
        _size_arg(size),
    )
    return [_grid(o) for o in outs]


def voxelize_points(
    points: Any,
    resolution: int | None = None,
    *,
    pitch: float | Sequence[float] | str | None = None,
    colors: Any = None,
    axis: str = "longest",
    backend: str = "auto",
    bounds: Any = None,
    progress: Progress | None = None,
) -> VoxelGrid:
    """Voxelizes a point cloud (array-like (N, 3), world coordinates): each point sets the voxel it falls in,
    ``floor((p - origin) / pitch)`` (Open3D's ``VoxelGrid.create_from_point_cloud`` rule) on meshvox's grid
    convention, ``resolution`` voxels along ``axis`` of the points' box (or of ``bounds``), or voxels of edge
    ``pitch``. ``colors`` (N, 3) or (N, 4), uint8 sRGB or floats in 0..1, colour each voxel by the mean of its
    points'. Files (``.ply`` without faces, ``.xyz``, ``.pts``, ``.npy``, ``.npz``) go through :func:`voxelize`."""
    p = np.asarray(points)
    if p.ndim != 2 or p.shape[1] != 3 or p.dtype.kind not in "fiu":
        raise ValueError(f"points must be numbers of shape (N, 3), not {p.dtype} {p.shape}")
    c = None
    if colors is not None:
        c = np.asarray(colors)
        if c.ndim != 2 or c.shape[0] != len(p) or c.shape[1] not in (3, 4):
            raise ValueError(f"colors must have shape ({len(p)}, 3) or ({len(p)}, 4), not {c.shape}")
        if c.dtype.kind == "f":
            c = np.round(np.clip(np.nan_to_num(c), 0, 1) * 255)
        c = c.astype(np.uint8)
        if c.shape[1] == 3:
            c = np.concatenate([c, np.full((len(c), 1), 255, np.uint8)], axis=1)
        c = np.ascontiguousarray(c)
    out = _native.voxelize_points(
        np.ascontiguousarray(p, dtype=np.float64), c, resolution, _pitch_arg(pitch), axis, backend, _bounds(bounds),
        progress,
    )
    return _grid(out)


class Mesh:
    """A mesh loaded and prepared once for :func:`query` (its spatial index and open boundary), accepted wherever
    a mesh is (``voxelize``, ``voxelize_many``, ``query``) without loading the file again.

        >>> bunny = meshvox.Mesh("bunny.obj")
        >>> bunny.triangles, bunny.is_open                        # (69451, True)
        >>> q = meshvox.query(bunny, points)                      # reuses the index
    """

    def __init__(self, mesh: Any) -> None:
        self._native = mesh._native if isinstance(mesh, Mesh) else _native.PreparedMesh(_source(mesh))

    @property
    def triangles(self) -> int:
        """The number of triangles (the faces of :func:`load`, in that order)."""
        return int(self._native.triangles)

    @property
    def is_open(self) -> bool:
        """Whether the mesh has holes or open sheets (its winding number is then not an integer)."""
        return bool(self._native.is_open)

    @property
    def name(self) -> str:
        return str(self._native.name)

    def __repr__(self) -> str:
        return f"meshvox.Mesh({self.name!r}, triangles={self.triangles}, open={self.is_open})"


class Query:
    """What :func:`query` answers, one entry per point.

    ``distance`` float32 (N,): world distance to the nearest triangle, negative inside with ``sign="winding"``;
    ``inside`` bool (N,): winding number at least 1/2 (None unsigned); ``winding`` float32 (N,): the generalized
    winding number, within 1e-4 (None unsigned; computed when first read: beside a mesh's holes its value costs
    more than the inside); ``closest`` float64 (N, 3): the nearest point on the mesh; ``triangle`` int64 (N,): its
    triangle, an index into :func:`load`'s faces; ``barycentric`` float32 (N, 3): its weights in that triangle.
    """

    distance: np.ndarray
    inside: np.ndarray | None
    closest: np.ndarray
    triangle: np.ndarray
    barycentric: np.ndarray
    #: Where the nearest triangles were found ("cpu (N threads)" or "gpu: ADAPTER").
    backend: str
    #: Points whose nearest triangle or sign the host decided or confirmed (every point today).
    host_decided: int
    #: On a GPU, milliseconds the host waited for the search after its own work; None on the CPU.
    wait_ms: float | None
    #: The query's milliseconds less ``wait_ms``: the host's own work.
    host_work_ms: float

    def __init__(self, out: dict[str, Any], mesh: Mesh, points: np.ndarray) -> None:
        for name in ("distance", "inside", "closest", "triangle", "barycentric"):
            setattr(self, name, out[name])
        self.evaluations = int(out["evaluations"])
        self.backend = str(out["backend"])
        self.host_decided = int(out["host_decided"])
        self.wait_ms = None if out["wait_ms"] is None else float(out["wait_ms"])
        self.host_work_ms = float(out["host_work_ms"])
        self._mesh, self._points = mesh, points
        self._winding: np.ndarray | None = None

    @property
    def winding(self) -> np.ndarray | None:
        """The generalized winding number at each point (float32, within 1e-4), computed when first read."""
        if self.inside is None:
            return None
        if self._winding is None:
            self._winding = _native.winding(self._mesh._native, self._points)
        return self._winding

    def __len__(self) -> int:
        return len(self.distance)

    def __repr__(self) -> str:
        signed = self.inside is not None
        inside = f", {int(self.inside.sum())} inside" if signed else ""  # type: ignore[union-attr]
        return f"meshvox.Query({len(self)} points{inside})"


def query(mesh: Any, points: Any, *, sign: str = "winding", backend: str = "auto") -> Query:
    """Exact answers at ``points`` (array-like (N, 3), world coordinates) about ``mesh`` (a path, a
    ``(vertices, faces)`` pair, a trimesh, or a :class:`Mesh`, which keeps its index for the next call): the
    distance to the nearest triangle, signed by the generalized winding number with ``sign="winding"`` (negative
    inside; right on open, cracked and self-intersecting meshes), the winding number, the nearest point, its
    triangle and barycentric coordinates. See :class:`Query` and docs/training.md for what "exact" means here.

    ``backend``: where the nearest triangles are found: ``"gpu"``, ``"cpu"``, or ``"auto"`` (the CPU: on an
    H200 the GPU's search did not beat it, docs/training.md). The signs are decided on the CPU with exact
    predicates on every backend, and every backend gives the same answers; ``.backend`` says where they were
    made. The GIL is released meanwhile.
    """
    if backend not in ("auto", "cpu", "gpu"):
        raise ValueError(f"backend '{backend}': use auto, gpu or cpu")
    prepared = mesh if isinstance(mesh, Mesh) else Mesh(mesh)
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), not {p.shape}")
    p = np.ascontiguousarray(p)
    return Query(_native.query(prepared._native, p, sign, backend), prepared, p)


class Samples:
    """Training samples from :func:`sample`, in the order uniform, surface, near (by ``sigma``).

    ``points`` float32 (M, 3) in the normalised frame; ``sdf`` float32 (M,): the exact signed distance in the
    frame's units, negative inside (generalized winding number at least 1/2); ``occupancy`` bool (M,);
    ``triangle`` int64 (M,): a surface point's triangle (an index into :func:`load`'s faces), -1 for the others;
    ``normal`` float32 (M, 3): its triangle's unit normal, zero for the others; ``kind`` uint8 (M,): 0 uniform, 1
    surface, 2 + k near with ``sigma[k]``; ``scale`` and ``offset``: frame = (world - offset) * scale.
    """

    points: np.ndarray
    sdf: np.ndarray
    occupancy: np.ndarray
    triangle: np.ndarray
    normal: np.ndarray
    kind: np.ndarray
    scale: float
    offset: np.ndarray
    #: Where the distances' nearest triangles were found, as :attr:`Query.backend`.
    backend: str

    def __init__(self, out: dict[str, Any]) -> None:
        for name in ("points", "sdf", "occupancy", "triangle", "normal", "kind"):
            setattr(self, name, out[name])
        self.scale = float(out["scale"])
        self.offset = np.asarray(out["offset"], dtype=np.float64)
        self.backend = str(out["backend"])

    def to_world(self, points: np.ndarray | None = None) -> np.ndarray:
        """``points`` (default: the samples') mapped back to the mesh's coordinates, float64."""
        p = self.points if points is None else np.asarray(points)
        return p.astype(np.float64) / self.scale + self.offset

    def __len__(self) -> int:
        return len(self.points)

    def __repr__(self) -> str:
        return f"meshvox.Samples({len(self)} points, {int(self.occupancy.sum())} inside, scale={self.scale:.6g})"


def _sample_args(
    uniform: int, surface: int, near: int, sigma: Any, padding: float, normalize: str | None, seed: int
) -> tuple[Any, ...]:
    sigmas = [float(s) for s in (sigma if isinstance(sigma, (tuple, list, np.ndarray)) else [sigma])]
    counts = [int(uniform), int(surface), int(near)]
    if min(counts) < 0:
        raise ValueError(f"sample counts must be at least 0, not {counts}")
    if sum(counts) == 0:
        raise ValueError("nothing to sample: give uniform=, surface= and/or near= a count")
    return (*counts, sigmas, float(padding), normalize, int(seed))


def sample(
    mesh: Any,
    *,
    uniform: int = 0,
    surface: int = 0,
    near: int = 0,
    sigma: float | Sequence[float] = (0.005, 0.05),
    padding: float = 0.1,
    normalize: str | None = "unit-cube",
    seed: int = 0,
    backend: str = "auto",
) -> Samples:
    """Training samples for DeepSDF / Occupancy-Networks style learning: ``uniform`` points in the cube around
    the mesh (side ``1 + padding`` times its longest side), ``surface`` points on it (area-weighted, with their
    triangle and normal) and ``near`` points on it moved by a Gaussian of each width in ``sigma`` (an equal share
    each, in the frame's units), each with its exact signed distance and occupancy (the generalized winding number:
    right on open and self-intersecting meshes).

    ``normalize``: ``"unit-cube"`` (the bounding box centred, its longest side 1), ``"unit-sphere"`` (centred,
    the farthest vertex at 1) or ``None`` (world coordinates); see :class:`Samples` for mapping back. The same
    ``seed`` gives the same samples on every machine, backend and thread count. ``backend``: where the
    distances' nearest triangles are found, as in :func:`query`.
    """
    prepared = mesh if isinstance(mesh, Mesh) else Mesh(mesh)
    args = _sample_args(uniform, surface, near, sigma, padding, normalize, seed)
    return Samples(_native.sample_many([prepared._native], *args, 1, None, backend)[0])


def sample_many(
    meshes: Iterable[Any],
    *,
    workers: int | None = None,
    progress: Progress | None = None,
    uniform: int = 0,
    surface: int = 0,
    near: int = 0,
    sigma: float | Sequence[float] = (0.005, 0.05),
    padding: float = 0.1,
    normalize: str | None = "unit-cube",
    seed: int = 0,
    backend: str = "auto",
) -> list[Samples]:
    """:func:`sample` for a dataset: each mesh (path, arrays, trimesh or :class:`Mesh`) loaded, prepared and
    sampled on ``workers`` threads at a time (default 2; each mesh's points already use every core), the same
    ``seed`` for each, in input order. ``progress(done, total)`` counts meshes."""
    sources = [m._native if isinstance(m, Mesh) else _source(m) for m in meshes]
    args = _sample_args(uniform, surface, near, sigma, padding, normalize, seed)
    return [Samples(out) for out in _native.sample_many(sources, *args, workers, progress, backend)]


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
