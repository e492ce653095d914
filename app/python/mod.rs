//! The Python binding, `meshvox._native` (feature `python`): a thin client of the engine. The package's Python
//! code (`app/python/meshvox/`) turns what users pass (paths, trimesh meshes, arrays) into a path or a pair of
//! arrays, and the dictionaries returned here into `meshvox.VoxelGrid`s. Every call runs through
//! [`process::run`]: off the GIL, with progress and Ctrl-C, on engines made once per process (and again after a
//! fork). The bit grid moves into numpy as it is; the package unpacks `.matrix` (the `.npy` writer's bytes) from
//! it when first asked for.

mod process;

use crate::engine::{Backend, Engine, EngineError, Job, Request, Voxelized};
use crate::formats::VoxelFormat;
use crate::formats::blocks::BlockSet;
use crate::formats::swatches::Swatches;
use crate::mesh::{self, Aabb, Mesh, MeshError};
use crate::voxel::labels::AttributeSet;
use crate::voxel::{Axis, GridError, Length, Mode, Resolution};
use glam::DVec3;
use numpy::{IntoPyArray, PyArrayMethods, PyReadonlyArray2};
use pyo3::exceptions::{PyMemoryError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

/// The package's exceptions.
mod exceptions {
    pyo3::create_exception!(meshvox, MeshError, pyo3::exceptions::PyValueError, "A mesh file meshvox cannot read.");
}
use exceptions::MeshError as PyMeshError;

/// A mesh as the package hands it over: a path (loaded later, without the GIL), or one already made from arrays.
enum Input {
    Path(PathBuf),
    Mesh(Box<Mesh>),
    /// Another input at an animation's pose (`pose=`).
    Posed(Box<Input>, crate::mesh::rig::Pose),
}

/// What a call asks for, from the keyword arguments of `meshvox.voxelize`: where, and the library's request
/// (the one place the package builds it; each call adds its progress and cancel flag).
type Options = (Backend, Request<'static>, crate::voxel::voids::DrainPlan);

/// A shell's or solid's voids, for printing, as `meshvox.voxelize` hands them over (`drain=` already split into a
/// count and a radius, or points with their radii; lengths as given: `2`, `"2mm"`).
#[derive(FromPyObject, Default)]
#[pyo3(from_item_all)]
struct Voids {
    drain_holes: Option<u32>,
    drain_radius: Option<String>,
    drain_points: Vec<([f64; 3], Option<String>)>,
    fill_pockets: bool,
    up: Option<String>,
    unit: Option<String>,
}

impl Voids {
    /// `request` with these voids, and the drain holes they ask for.
    fn apply(self, request: Request<'static>) -> PyResult<(Request<'static>, crate::voxel::voids::DrainPlan)> {
        use crate::voxel::voids::DrainPlan;
        let length = |text: &str| Length::parse(text).map_err(|e| PyValueError::new_err(format!("drain=: {e}")));
        let plan = match (self.drain_holes, self.drain_points.is_empty()) {
            (Some(0), _) => return Err(PyValueError::new_err("drain=: at least one hole")),
            (Some(holes), _) => {
                DrainPlan::Count { holes, radius: self.drain_radius.as_deref().map(length).transpose()? }
            }
            (None, false) => DrainPlan::At(
                self.drain_points
                    .iter()
                    .map(|(p, r)| Ok((DVec3::from(*p), r.as_deref().map(length).transpose()?)))
                    .collect::<PyResult<_>>()?,
            ),
            (None, true) => DrainPlan::None,
        };
        let up = match self.up.as_deref() {
            None => None,
            Some(name) => Some(
                crate::mesh::UpAxis::from_name(name)
                    .ok_or_else(|| PyValueError::new_err(format!("up '{name}': use y or z")))?,
            ),
        };
        let unit = match self.unit.as_deref() {
            None => None,
            Some(name) => Some(Length::unit(name).map_err(|e| PyValueError::new_err(format!("unit {e}")))?),
        };
        Ok((Request { fill_pockets: self.fill_pockets, up, unit, ..request }, plan))
    }
}

/// Why a call failed, turned into the Python exception users expect ([`into_py_err`]).
enum Failure {
    Mesh(MeshError),
    Engine(EngineError),
    Query(crate::voxel::query::QueryError),
}

fn into_py_err(failure: Failure) -> PyErr {
    match failure {
        // Arrays that make no mesh are the caller's values; a file that makes none is a MeshError.
        Failure::Mesh(e @ MeshError::Arrays { .. }) => PyValueError::new_err(e.to_string()),
        // A pose the file has no animation for is the caller's `pose=`/`animation=`.
        Failure::Mesh(e @ MeshError::Pose { .. }) => PyValueError::new_err(e.to_string()),
        Failure::Mesh(e) => PyMeshError::new_err(e.to_string()),
        // The package's grids are dense and its budget is the default: the CLI's hint (--max-memory, sparse
        // outputs) names nothing a Python caller can change.
        Failure::Engine(EngineError::Grid { mesh, error: error @ GridError::OverBudget { .. }, .. }) => {
            PyMemoryError::new_err(format!("{mesh}: {error}"))
        }
        Failure::Engine(
            e @ (EngineError::Grid { .. }
            | EngineError::Empty { .. }
            | EngineError::Bounds { .. }
            | EngineError::FieldFormat { .. }
            | EngineError::PointCloud { .. }
            | EngineError::Query(_)
            | EngineError::Sample(_)
            | EngineError::FullBandSparse
            | EngineError::Anisotropic { .. }
            | EngineError::Voids(_)
            | EngineError::Level(_)),
        ) => PyValueError::new_err(e.to_string()),
        Failure::Engine(EngineError::Cancelled) => PyRuntimeError::new_err("cancelled"),
        Failure::Engine(e) => PyRuntimeError::new_err(e.to_string()),
        Failure::Query(e) => PyValueError::new_err(e.to_string()),
    }
}

/// A writer's failure as Python reports file errors: a missing folder is a `FileNotFoundError`, a folder that
/// cannot be written a `PermissionError`, both naming the path the caller gave.
fn save_err(path: &std::path::Path, e: crate::formats::FormatError) -> PyErr {
    use crate::formats::FormatError;
    use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyPermissionError};
    let message = format!("{}: {e}", path.display());
    match e {
        FormatError::Io(io) if io.kind() == std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
        FormatError::Io(io) if io.kind() == std::io::ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
        FormatError::Io(_) => PyOSError::new_err(message),
        FormatError::Invalid { .. } | FormatError::TooLarge(_) | FormatError::OneVoxelSize { .. } => {
            PyValueError::new_err(message)
        }
    }
}

/// A path (`str` or `os.PathLike`), a prepared mesh (`meshvox.Mesh`'s), or a `(vertices float64 (V, 3), faces
/// int64 (F, 3))` pair made into a mesh
/// straight from numpy's memory while the GIL is held (no copy of the arrays first: building the mesh is most of
/// what the binding adds to a call).
fn input(source: &Bound<'_, PyAny>) -> PyResult<Input> {
    if let Ok(path) = source.extract::<PathBuf>() {
        return Ok(Input::Path(path));
    }
    if let Ok(prepared) = source.cast::<query::PyPrepared>() {
        return Ok(prepared.get().input());
    }
    let (vertices, faces): (PyReadonlyArray2<'_, f64>, PyReadonlyArray2<'_, i64>) = source.extract()?;
    let (vertices, faces) = (vertices.as_array(), faces.as_array());
    if vertices.ncols() != 3 || faces.ncols() != 3 {
        return Err(PyValueError::new_err(format!(
            "vertices must be (V, 3) and faces (F, 3); got {:?} and {:?}",
            vertices.shape(),
            faces.shape()
        )));
    }
    // The package hands over C-contiguous arrays, read as slices of rows.
    let (Some(v), Some(f)) = (vertices.as_slice(), faces.as_slice()) else {
        return Err(PyValueError::new_err("vertices and faces must be C-contiguous"));
    };
    let (positions, faces): (&[DVec3], &[[i64; 3]]) = (bytemuck::cast_slice(v), bytemuck::cast_slice(f));
    // Its parallel copy runs on the library's pool, made per process (rayon's global pool does not survive a fork).
    let mesh = mesh::from_indexed("arrays", positions, faces);
    let mesh = mesh.map_err(|e| into_py_err(Failure::Mesh(e)))?;
    Ok(Input::Mesh(Box::new(mesh)))
}

impl Input {
    /// The mesh (a file loaded from disk, without the GIL) and the name messages and stats use.
    fn load(self) -> Result<(String, Mesh), Failure> {
        match self {
            Input::Path(path) => {
                let name = path.display().to_string();
                let mesh = mesh::load(&name).map_err(Failure::Mesh)?;
                Ok((name, mesh))
            }
            Input::Mesh(mesh) => Ok(("arrays".to_string(), *mesh)),
            Input::Posed(input, pose) => {
                let (name, mesh) = input.load()?;
                let posed = mesh.posed(&pose).map_err(Failure::Mesh)?;
                Ok((name, posed))
            }
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn options(
    resolution: Option<u32>,
    pitch: Option<&str>,
    size: Option<&str>,
    axis: &str,
    mode: &str,
    backend: &str,
    colour: Option<bool>,
    bounds: Option<([f64; 3], [f64; 3])>,
    band: &str,
    attributes: &str,
    thickness: Option<&str>,
    voids: Option<Voids>,
) -> PyResult<Options> {
    let resolution = match (resolution, pitch, size) {
        (Some(n), None, None) => Resolution::Count(n),
        (None, Some(p), None) => {
            Resolution::parse_voxel_size(p).map_err(|e| PyValueError::new_err(format!("pitch: {e}")))?
        }
        (None, None, Some(s)) => Resolution::parse_size(s).map_err(|e| PyValueError::new_err(format!("size: {e}")))?,
        _ => return Err(PyValueError::new_err("give resolution or pitch, or size (one of them)")),
    };
    let axis = Axis::from_name(axis)
        .ok_or_else(|| PyValueError::new_err(format!("axis '{axis}': use {}", Axis::choices())))?;
    let mode = Mode::from_name(mode)
        .ok_or_else(|| PyValueError::new_err(format!("mode '{mode}': use {}", Mode::choices())))?;
    let thickness = match (thickness, mode == Mode::Shell) {
        (Some(_), false) => return Err(PyValueError::new_err("thickness= is a shell's: use it with mode=\"shell\"")),
        (Some(t), true) => Length::parse(t).map_err(|e| PyValueError::new_err(format!("thickness={t}: {e}")))?,
        (None, _) => Length::Voxels(1.0),
    };
    let band = crate::voxel::distance::Band::parse(band).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let backend = Backend::from_name(backend)
        .ok_or_else(|| PyValueError::new_err(format!("backend '{backend}': use {}", Backend::choices())))?;
    let bounds = bounds.map(|(min, max)| Aabb { min: DVec3::from(min), max: DVec3::from(max) });
    let attributes = AttributeSet::parse(attributes).map_err(PyValueError::new_err)?;
    let request = Request {
        axis,
        colour,
        attributes,
        bounds,
        // The package's VoxelGrid holds the dense bits (`.matrix`).
        grid: crate::voxel::GridKind::Dense,
        band,
        thickness,
        ..Request::new(resolution, mode)
    };
    let (request, drain) = voids.unwrap_or_default().apply(request)?;
    Ok((backend, request, drain))
}

/// One voxelization on this process's engine, inside [`process::run`]'s working thread (or one of
/// `voxelize_many`'s): `progress` as the engine calls it, `cancel` the flag Ctrl-C sets.
fn voxelize_one(
    input: Input,
    (backend, request, drain): &Options,
    progress: &(dyn Fn(usize, usize) + Sync),
    cancel: &AtomicBool,
) -> Result<Voxelized, Failure> {
    let (name, mesh) = input.load()?;
    let (backend, request) = (*backend, Request { drain, progress: Some(progress), cancel: Some(cancel), ..*request });
    let job = Job::plan(&name, &mesh, &request).map_err(Failure::Engine)?;
    // Priced first, as the CLI does: a job the CPU finishes sooner opens (or probes) no GPU. Once this process's
    // engine has a GPU open, its opening is paid and no longer in the price.
    let priced = match process::gpu_open(backend) {
        true => Engine::priced_out_open(backend, &job),
        false => Engine::priced_out(backend, &job),
    };
    let voxelized = match priced {
        Some(cpu) => cpu.run(&job),
        None => process::engine(backend).map_err(Failure::Engine)?.run(&job),
    };
    voxelized.map_err(Failure::Engine)
}

/// The dictionary `meshvox.VoxelGrid` is made from: `words` (the bit grid as it is, uint32, x-rows z-major: `.matrix`
/// is unpacked from it when first asked for, in numpy), `shape`, `rgba` (uint8 (N, 4), one per set voxel in the
/// grid's storage order, or None), `labels` (None, or a dict of int32 (N,) arrays in that order), `origin`, `pitch`, `stats` (the `--stats-json` line) and `notices`. The words
/// move into numpy without a copy, so the call costs the engine's time and little more.
fn to_dict<'py>(py: Python<'py>, result: Voxelized) -> PyResult<Bound<'py, PyDict>> {
    // Requested dense (`.matrix` is the package's grid).
    let grid = result.grid.into_dense().map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    let d = grid.spec.dims;
    let dict = PyDict::new(py);
    dict.set_item("shape", [d.x, d.y, d.z])?;
    dict.set_item("origin", grid.spec.origin.to_array())?;
    match grid.spec.is_cubic() {
        true => dict.set_item("pitch", grid.spec.voxel_size.x)?,
        false => dict.set_item("pitch", grid.spec.voxel_size.to_array())?,
    }
    let stats = serde_json::to_string(&result.report).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    dict.set_item("stats", stats)?;
    // Fallbacks taken on the way (the GPU out of memory, the CPU standing in), for `warnings.warn`.
    dict.set_item("notices", result.notices.iter().map(|n| n.message.clone()).collect::<Vec<_>>())?;
    let rgba = result.colours.map(|c| {
        let n = c.rgba.len();
        c.rgba.into_iter().flatten().collect::<Vec<u8>>().into_pyarray(py).reshape([n, 4])
    });
    dict.set_item("rgba", rgba.transpose()?)?;
    let labels = result.labels.map(|labels| {
        let dict = PyDict::new(py);
        for (attribute, values) in labels.columns {
            dict.set_item(attribute.name(), values.into_pyarray(py))?;
        }
        Ok::<_, PyErr>(dict)
    });
    dict.set_item("labels", labels.transpose()?)?;
    dict.set_item("words", grid.words.into_pyarray(py))?;
    // A shell with drain holes or filled pockets hands over its walls' field (one level set at 0, the holes cut)
    // instead of the field it was cut from, as the CLI writes its walls.
    let walls = match (&result.field, result.shell, &result.hollowing) {
        (Some(field), Some(thickness), Some(h)) if h.reshapes_walls() => {
            Some(crate::voxel::shell::walls_field(field, thickness, h))
        }
        _ => None,
    };
    let field = walls.as_ref().or(result.field.as_ref());
    // A distance field as float32 [x, y, z] over the whole grid, and its background.
    let distances = field.map(|field| {
        let (nx, ny, nz) = (d.x as usize, d.y as usize, d.z as usize);
        let mut values = vec![0f32; nx * ny * nz];
        // On the library's pool (rayon's global pool does not survive a fork).
        field.x_slices(0, &mut values);
        values.into_pyarray(py).reshape([nx, ny, nz])
    });
    dict.set_item("distances", distances.transpose()?)?;
    dict.set_item("background", field.map(|f| f.background()))?;
    dict.set_item("signed", field.map(|f| f.signed))?;
    // A shell's thickness in voxels: its `distances` are the signed field it was cut from, for its walls.
    dict.set_item("thickness", if walls.is_some() { None } else { result.shell })?;
    Ok(dict)
}

/// `meshvox._native.voxelize`: see `meshvox.voxelize`.
#[pyfunction]
#[pyo3(signature = (source, resolution, pitch, axis, mode, backend, colour, bounds, progress, band, attributes, thickness, voids=None, pose=None, size=None))]
#[allow(clippy::too_many_arguments)]
fn voxelize<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    resolution: Option<u32>,
    pitch: Option<&str>,
    axis: &str,
    mode: &str,
    backend: &str,
    colour: Option<bool>,
    bounds: Option<([f64; 3], [f64; 3])>,
    progress: Option<&Bound<'py, PyAny>>,
    band: &str,
    attributes: &str,
    thickness: Option<&str>,
    voids: Option<Voids>,
    pose: Option<(f64, Option<String>)>,
    size: Option<&str>,
) -> PyResult<Bound<'py, PyDict>> {
    let options =
        options(resolution, pitch, size, axis, mode, backend, colour, bounds, band, attributes, thickness, voids)?;
    let input = match pose {
        Some((time, animation)) => Input::Posed(Box::new(input(source)?), crate::mesh::rig::Pose { animation, time }),
        None => input(source)?,
    };
    let result = process::run(py, progress, |control| {
        voxelize_one(input, &options, &|done, total| control.progress(done, total), &control.cancel)
    })?;
    to_dict(py, result.map_err(into_py_err)?)
}

/// `meshvox._native.voxelize_points`: see `meshvox.voxelize_points` (points float64 (N, 3), colours uint8 (N, 4)
/// or None, already checked and converted there).
#[pyfunction]
#[pyo3(signature = (points, colors, resolution, pitch, axis, backend, bounds, progress))]
#[allow(clippy::too_many_arguments)]
fn voxelize_points<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    colors: Option<PyReadonlyArray2<'py, u8>>,
    resolution: Option<u32>,
    pitch: Option<&str>,
    axis: &str,
    backend: &str,
    bounds: Option<([f64; 3], [f64; 3])>,
    progress: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let options = options(resolution, pitch, None, axis, "surface", backend, None, bounds, "3", "", None, None)?;
    let (points, colors) = (points.as_array(), colors.as_ref().map(|c| c.as_array()));
    if points.ncols() != 3 || colors.is_some_and(|c| c.ncols() != 4) {
        return Err(PyValueError::new_err("points must be (N, 3) and colours (N, 4)"));
    }
    let cloud: Vec<DVec3> = points.rows().into_iter().map(|r| DVec3::new(r[0], r[1], r[2])).collect();
    let colours = colors.map_or_else(Vec::new, |c| c.rows().into_iter().map(|r| [r[0], r[1], r[2], r[3]]).collect());
    let mesh = mesh::cloud::from_points("points", cloud, colours).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let result = process::run(py, progress, |control| {
        voxelize_one(
            Input::Mesh(Box::new(mesh)),
            &options,
            &|done, total| control.progress(done, total),
            &control.cancel,
        )
    })?;
    to_dict(py, result.map_err(into_py_err)?)
}

/// `meshvox._native.voxelize_many`: the meshes on `workers` threads sharing one engine, through the work queue
/// `meshvox batch` uses, in input order; `progress(done, total)` counts meshes.
#[pyfunction]
#[pyo3(signature = (sources, resolution, pitch, axis, mode, backend, colour, bounds, progress, workers, band, attributes, thickness, voids=None, size=None))]
#[allow(clippy::too_many_arguments)]
fn voxelize_many<'py>(
    py: Python<'py>,
    sources: Vec<Bound<'py, PyAny>>,
    resolution: Option<u32>,
    pitch: Option<&str>,
    axis: &str,
    mode: &str,
    backend: &str,
    colour: Option<bool>,
    bounds: Option<([f64; 3], [f64; 3])>,
    progress: Option<&Bound<'py, PyAny>>,
    workers: Option<usize>,
    band: &str,
    attributes: &str,
    thickness: Option<&str>,
    voids: Option<Voids>,
    size: Option<&str>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let options =
        options(resolution, pitch, size, axis, mode, backend, colour, bounds, band, attributes, thickness, voids)?;
    let inputs: Vec<std::sync::Mutex<Option<Input>>> =
        sources.iter().map(|s| input(s).map(|i| std::sync::Mutex::new(Some(i)))).collect::<PyResult<_>>()?;
    let total = inputs.len();
    // The CPU's default unless the GPU is asked for by name (`auto` prices small jobs out to the CPU).
    let workers = workers.unwrap_or_else(|| crate::engine::default_workers(backend == "gpu")).clamp(1, total.max(1));
    let results = process::run(py, progress, |control| {
        // Each mesh's own progress is not reported: the count of finished meshes is.
        let quiet = |_: usize, _: usize| {};
        // On the queue's own threads, not rayon workers: a voxelization waits for the GPU's turn.
        control.each(total, workers, |i| {
            let taken = inputs[i].lock().unwrap_or_else(|e| e.into_inner()).take();
            let input = taken.filter(|_| !control.cancel.load(Ordering::Relaxed))?;
            Some(voxelize_one(input, &options, &quiet, &control.cancel))
        })
    })?;
    let mut out = Vec::with_capacity(total);
    for result in results {
        let result = result.ok_or_else(|| PyRuntimeError::new_err("cancelled"))?;
        out.push(to_dict(py, result.map_err(into_py_err)?)?);
    }
    Ok(out)
}

/// Vertices (float64 (V, 3)) and faces (int64 (F, 3)).
type IndexedArrays<'py> = (Bound<'py, numpy::PyArray2<f64>>, Bound<'py, numpy::PyArray2<i64>>);

/// `meshvox.load`: a file's triangles as shared vertices (float64 (V, 3), world space, node transforms applied)
/// and faces (int64 (F, 3)).
#[pyfunction]
fn load<'py>(py: Python<'py>, path: PathBuf) -> PyResult<IndexedArrays<'py>> {
    let loaded = process::run(py, None, |_| Input::Path(path).load().map(|(_, m)| mesh::to_indexed(&m)))?;
    let (positions, faces) = loaded.map_err(into_py_err)?;
    let v: Vec<f64> = positions.iter().flat_map(|p| p.to_array()).collect();
    let f: Vec<i64> = faces.iter().flat_map(|t| t.map(i64::from)).collect();
    let (nv, nf) = (positions.len(), faces.len());
    Ok((v.into_pyarray(py).reshape([nv, 3])?, f.into_pyarray(py).reshape([nf, 3])?))
}

/// `meshvox.backends`: where `auto` voxelizes on this machine and why, and what the GPU is.
#[pyfunction]
fn backends(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let opened = process::run(py, None, |_| process::engine(Backend::Auto))?;
    let engine = opened.map_err(|e| into_py_err(Failure::Engine(e)))?;
    let (label, notices) = (engine.label(), engine.notices());
    let dict = PyDict::new(py);
    dict.set_item("auto", if engine.uses_gpu() { Backend::Gpu } else { Backend::Cpu }.name())?;
    dict.set_item("backend", &label)?;
    dict.set_item("notes", notices.iter().map(|n| n.message.clone()).collect::<Vec<_>>())?;
    dict.set_item("threads", crate::parallel::threads())?;
    Ok(dict)
}

/// `meshvox._native.devices_opened`: how many GPU devices this process has opened so far (meshvox's own, not a
/// client's such as the viewer's). The binding opens at most one, however many threads call at once and whichever
/// of `gpu` and `auto` they ask for: the tests count devices with this, not log lines.
#[pyfunction]
fn devices_opened() -> usize {
    crate::gpu::devices_opened()
}

/// `meshvox._native.headless_vulkan_setting`: the `(name, value)` the package puts in `os.environ` when it is
/// imported, so that probing for a GPU prints nothing where there is no `XDG_RUNTIME_DIR`
/// ([`crate::gpu::headless_vulkan_setting`]); `None` where nothing is needed.
#[pyfunction]
fn headless_vulkan_setting() -> Option<(&'static str, &'static str)> {
    crate::gpu::headless_vulkan_setting()
}

/// `VoxelGrid.save`: writes a grid (from its `.matrix`, origin, pitch, colours and labels) in the format its
/// extension names, atomically (a temporary file beside it, renamed into place); for `.npy` the `.colors.npy` and
/// `.labels.npy` beside it, as the CLI writes them. Labels go only where the format holds them.
#[pyfunction]
#[pyo3(signature = (path, matrix, origin, pitch, colors, merge, labels, colour_map))]
#[allow(clippy::too_many_arguments)]
fn save(
    py: Python<'_>,
    path: PathBuf,
    matrix: numpy::PyReadonlyArray3<'_, u8>,
    origin: [f64; 3],
    pitch: [f64; 3],
    colors: Option<numpy::PyReadonlyArray4<'_, u8>>,
    merge: bool,
    labels: Vec<(String, numpy::PyReadonlyArray3<'_, i32>)>,
    colour_map: (Option<PathBuf>, Option<String>, Option<PathBuf>, bool),
) -> PyResult<()> {
    let (blocks, block, palette, dither) = colour_map;
    let blocks = match (block, blocks) {
        (Some(id), _) => Some(BlockSet::single(&id).map_err(|e| PyValueError::new_err(e.to_string()))?),
        (None, Some(file)) => {
            let what = format!("blocks='{}'", file.display());
            let bytes =
                crate::mesh::read_setting_file(&file, &what).map_err(|e| PyValueError::new_err(e.to_string()))?;
            let text =
                String::from_utf8(bytes).map_err(|_| PyValueError::new_err(format!("{what}: not UTF-8 text")))?;
            Some(BlockSet::parse(&text, &what).map_err(|e| PyValueError::new_err(e.to_string()))?)
        }
        (None, None) => None,
    };
    let palette = match palette {
        Some(file) => {
            let what = format!("palette='{}'", file.display());
            let bytes =
                crate::mesh::read_setting_file(&file, &what).map_err(|e| PyValueError::new_err(e.to_string()))?;
            Some(Swatches::read_palette(&bytes, &what).map_err(|e| PyValueError::new_err(e.to_string()))?)
        }
        None => None,
    };
    let format = VoxelFormat::from_extension(&path).ok_or_else(|| {
        PyValueError::new_err(format!("{}: unknown output format (use {})", path.display(), VoxelFormat::choices()))
    })?;
    let grid = from_matrix::grid(&matrix.as_array(), origin, pitch)?;
    format.check_fits(&grid.spec).map_err(|e| save_err(&path, e))?;
    let colours = colors.map(|c| from_matrix::colours(&grid, &c.as_array())).transpose()?;
    let views: Vec<_> = labels.iter().map(|(name, values)| (name.clone(), values.as_array())).collect();
    let labels = (!views.is_empty()).then(|| from_matrix::labels(&grid, &views)).transpose()?;
    let labels = labels.filter(|_| format.holds_labels());
    let options = crate::formats::WriteOptions {
        merge,
        labels: labels.as_ref(),
        blocks: blocks.as_ref(),
        palette: palette.as_ref(),
        dither,
        name: path.file_stem().and_then(|s| s.to_str()),
        ..Default::default()
    };
    let written = process::run(py, None, |_| from_matrix::write(&path, format, &grid, colours.as_ref(), &options))?;
    written.map_err(|e| save_err(&path, e))
}

/// `VoxelGrid.save` of a distance field: its float32 `[x, y, z]` values (background `background` world units)
/// written as `.npy`, `.npz` (the band), `.vdb` (a level set), or its level set at `level` as a mesh, with the
/// CLI's writers, atomically; with `thickness` (voxels), the walls of the shell cut from it as a mesh.
#[pyfunction]
#[pyo3(signature = (path, distances, origin, pitch, background, signed, level, thickness=None))]
#[allow(clippy::too_many_arguments)]
fn save_field(
    py: Python<'_>,
    path: PathBuf,
    distances: numpy::PyReadonlyArray3<'_, f32>,
    origin: [f64; 3],
    pitch: f64,
    background: f32,
    signed: bool,
    level: f64,
    thickness: Option<f32>,
) -> PyResult<()> {
    let format = VoxelFormat::from_extension(&path).filter(|f| f.holds_field() || f.is_mesh()).ok_or_else(|| {
        PyValueError::new_err(format!(
            "{}: a distance field is saved as {}, or its level set as {}",
            path.display(),
            VoxelFormat::listed(VoxelFormat::holds_field),
            VoxelFormat::listed(VoxelFormat::is_mesh)
        ))
    })?;
    let (spec, values) = from_matrix::field_values(&distances.as_array(), origin, pitch, background)?;
    let written = process::run(py, None, |_| {
        let field = crate::voxel::distance::DistanceField::from_dense(spec, &values, background, signed);
        crate::formats::atomic::write_atomically(&path, |out| match format {
            // The level set, or the shell's walls, made first and written as a mesh (as the engine writes them).
            VoxelFormat::Mesh(format) => {
                // A grid from Python carries no unit: a .3mf states millimetres, as slicers read STL.
                let name = path.file_stem().and_then(|s| s.to_str()).unwrap_or("model");
                let target = crate::engine::FieldMesh { format, unit: crate::formats::DEFAULT_UNIT, name };
                crate::engine::write_field_mesh(&field, thickness, level, None, &|_, _| {}, target, out)
            }
            _ if thickness.is_some() => Err(std::io::Error::other(format!(
                "a shell's walls are written as {}",
                VoxelFormat::listed(VoxelFormat::is_mesh)
            ))
            .into()),
            _ => crate::formats::write_field(&field, format, out),
        })
    })?;
    written.map(|_| ()).map_err(|e| save_err(&path, e))
}

/// `meshvox._native.level_mesh(distances, origin, pitch, background, signed, level, thickness=None)`: the field's
/// level set ([`crate::voxel::contour`]), or with `thickness` (voxels) the walls of the shell cut from it
/// ([`crate::voxel::shell::shell_mesh`]), as (vertices float64 (V, 3), faces int64 (F, 3)).
#[pyfunction]
#[pyo3(signature = (distances, origin, pitch, background, signed, level, thickness=None))]
#[allow(clippy::too_many_arguments)]
fn level_mesh<'py>(
    py: Python<'py>,
    distances: numpy::PyReadonlyArray3<'py, f32>,
    origin: [f64; 3],
    pitch: f64,
    background: f32,
    signed: bool,
    level: f64,
    thickness: Option<f32>,
) -> PyResult<IndexedArrays<'py>> {
    use numpy::IntoPyArray;
    let (spec, values) = from_matrix::field_values(&distances.as_array(), origin, pitch, background)?;
    let mesh = process::run(py, None, |_| {
        let field = crate::voxel::distance::DistanceField::from_dense(spec, &values, background, signed);
        match thickness {
            Some(thickness) => crate::voxel::shell::shell_mesh(&field, thickness),
            None => crate::voxel::contour::level_mesh(&field, level),
        }
    })?
    .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let (v, f) = (mesh.vertices.len(), mesh.faces.len());
    let vertices: Vec<f64> = mesh.vertices.iter().flat_map(|p| p.to_array()).collect();
    let faces: Vec<i64> = mesh.faces.iter().flatten().map(|&i| i64::from(i)).collect();
    Ok((vertices.into_pyarray(py).reshape([v, 3])?, faces.into_pyarray(py).reshape([f, 3])?))
}

mod from_matrix;
mod query;

/// How messages name a setting in Python: its keyword (`pitch` for the voxel size), `band=` alone, with a value
/// `band="full"` or `thickness=2`. The one place the Python package spells settings ([`crate::names::Setting`]).
fn keyword(setting: crate::names::Setting, value: Option<&str>) -> String {
    let word = match setting {
        crate::names::Setting::VoxelSize => "pitch",
        other => other.word(),
    };
    match value {
        None => format!("{word}="),
        Some(value) if value.parse::<f64>().is_ok() => format!("{word}={value}"),
        Some(value) => format!("{word}=\"{value}\""),
    }
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    crate::names::spell_settings_with(keyword);
    m.add("MeshError", m.py().get_type::<PyMeshError>())?;
    m.add_function(wrap_pyfunction!(voxelize, m)?)?;
    m.add_function(wrap_pyfunction!(voxelize_many, m)?)?;
    m.add_function(wrap_pyfunction!(voxelize_points, m)?)?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(backends, m)?)?;
    m.add_function(wrap_pyfunction!(devices_opened, m)?)?;
    m.add_function(wrap_pyfunction!(headless_vulkan_setting, m)?)?;
    m.add_function(wrap_pyfunction!(save, m)?)?;
    m.add_function(wrap_pyfunction!(save_field, m)?)?;
    m.add_function(wrap_pyfunction!(level_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(query::query, m)?)?;
    m.add_function(wrap_pyfunction!(query::winding, m)?)?;
    m.add_function(wrap_pyfunction!(query::sample_many, m)?)?;
    m.add_class::<query::PyPrepared>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
