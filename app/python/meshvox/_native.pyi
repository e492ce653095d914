# Type stubs of the compiled part of meshvox (app/python/mod.rs); the public API is meshvox/__init__.py.
from typing import Any, Callable, Sequence

import numpy as np

__version__: str

class MeshError(ValueError): ...

_Source = str | tuple[np.ndarray, np.ndarray] | PreparedMesh
_Bounds = tuple[tuple[float, float, float], tuple[float, float, float]] | None

def voxelize(
    source: _Source,
    resolution: int | None,
    pitch: float | None,
    axis: str,
    mode: str,
    backend: str,
    colour: bool | None,
    bounds: _Bounds,
    progress: Callable[[int, int], Any] | None,
    band: str,
    attributes: str,
    thickness: str | None,
    voids: dict[str, Any] | None = None,
    pose: tuple[float, str | None] | None = None,
) -> dict[str, Any]: ...
def voxelize_many(
    sources: Sequence[_Source],
    resolution: int | None,
    pitch: float | None,
    axis: str,
    mode: str,
    backend: str,
    colour: bool | None,
    bounds: _Bounds,
    progress: Callable[[int, int], Any] | None,
    workers: int | None,
    band: str,
    attributes: str,
    thickness: str | None,
    voids: dict[str, Any] | None = None,
) -> list[dict[str, Any]]: ...
def voxelize_points(
    points: np.ndarray,
    colors: np.ndarray | None,
    resolution: int | None,
    pitch: float | None,
    axis: str,
    backend: str,
    bounds: _Bounds,
    progress: Callable[[int, int], Any] | None,
) -> dict[str, Any]: ...
def load(path: str) -> tuple[np.ndarray, np.ndarray]: ...
def backends() -> dict[str, Any]: ...
def devices_opened() -> int: ...
def headless_vulkan_setting() -> tuple[str, str] | None: ...
def save(
    path: str,
    matrix: np.ndarray,
    origin: tuple[float, float, float],
    pitch: float,
    colors: np.ndarray | None,
    merge: bool,
    labels: list[tuple[str, np.ndarray]],
) -> None: ...
def save_field(
    path: str,
    distances: np.ndarray,
    origin: tuple[float, float, float],
    pitch: float,
    background: float,
    signed: bool,
    level: float,
    thickness: float | None = None,
) -> None: ...
def level_mesh(
    distances: np.ndarray,
    origin: tuple[float, float, float],
    pitch: float,
    background: float,
    signed: bool,
    level: float,
    thickness: float | None = None,
) -> tuple[np.ndarray, np.ndarray]: ...

class PreparedMesh:
    def __init__(self, source: _Source | PreparedMesh) -> None: ...
    @property
    def triangles(self) -> int: ...
    @property
    def is_open(self) -> bool: ...
    @property
    def name(self) -> str: ...

def query(mesh: PreparedMesh, points: np.ndarray, sign: str, backend: str) -> dict[str, Any]: ...
def winding(mesh: PreparedMesh, points: np.ndarray) -> np.ndarray: ...
def sample_many(
    meshes: Sequence[_Source],
    uniform: int,
    surface: int,
    near: int,
    sigma: list[float],
    padding: float,
    normalize: str | None,
    seed: int,
    workers: int | None,
    progress: Callable[[int, int], Any] | None,
    backend: str,
) -> list[dict[str, Any]]: ...
