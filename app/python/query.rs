//! `meshvox.Mesh`, `meshvox.query`, `meshvox.sample` and `meshvox.sample_many` from Python: a mesh loaded and
//! prepared once ([`Prepared`]: its frame, hierarchy and boundary), exact answers at an array of points, and
//! training samples, computed off the GIL on the library's pool.

use super::{Failure, Input, input, into_py_err, process};
use crate::engine::{Backend, Engine, EngineError, query_backend};
use crate::voxel::query::{Prepared, QueryError, Sign};
use crate::voxel::sample::{Normalize, SampleRequest, Samples};
use glam::DVec3;
use numpy::{IntoPyArray, PyArrayMethods, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::Arc;

/// `meshvox._native.PreparedMesh`: the loaded mesh and what queries need, shared by every call given it (and
/// accepted wherever a mesh is: `voxelize` takes its mesh without loading the file again).
#[pyclass(name = "PreparedMesh", frozen, module = "meshvox._native")]
pub(super) struct PyPrepared {
    prepared: Arc<Prepared>,
}

fn query_err(e: QueryError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

#[pymethods]
impl PyPrepared {
    /// Loads (a path) or takes (arrays) the mesh and prepares it, without the GIL.
    #[new]
    fn new(py: Python<'_>, source: &Bound<'_, PyAny>) -> PyResult<PyPrepared> {
        if let Ok(prepared) = source.cast::<PyPrepared>() {
            return Ok(PyPrepared { prepared: prepared.get().prepared.clone() });
        }
        let input = input(source)?;
        let prepared = process::run(py, None, |_| prepare(input))?.map_err(into_py_err)?;
        Ok(PyPrepared { prepared })
    }

    /// Triangles in the mesh (the faces of `meshvox.load`, in that order).
    #[getter]
    fn triangles(&self) -> usize {
        self.prepared.triangle_count()
    }

    /// Whether the mesh has an open boundary (holes or sheets): its winding number is then not an integer.
    #[getter]
    fn is_open(&self) -> bool {
        self.prepared.is_open()
    }

    /// The mesh's name (its path, or "arrays").
    #[getter]
    fn name(&self) -> String {
        self.prepared.mesh().name.clone()
    }
}

impl PyPrepared {
    /// The mesh for a voxelization.
    pub(super) fn input(&self) -> Input {
        Input::Mesh(Box::new(self.prepared.mesh().clone()))
    }
}

/// The mesh of `input` (a file loaded, or arrays) prepared for queries.
fn prepare(input: Input) -> Result<Arc<Prepared>, Failure> {
    let (_, mesh) = input.load()?;
    Ok(Arc::new(Prepared::new(mesh).map_err(Failure::Query)?))
}

/// The points of a float64 (N, 3) array.
fn points_of(points: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<DVec3>> {
    let view = points.as_array();
    if view.ncols() != 3 {
        return Err(PyValueError::new_err(format!("points must have shape (N, 3), not {:?}", view.shape())));
    }
    let Some(flat) = view.as_slice() else {
        return Err(PyValueError::new_err("points must be C-contiguous"));
    };
    Ok(bytemuck::cast_slice::<f64, DVec3>(flat).to_vec())
}

/// `meshvox._native.winding(mesh, points float64 (N, 3))`: the winding numbers, float32 (N,).
#[pyfunction]
pub(super) fn winding<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyPrepared>,
    points: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, numpy::PyArray1<f32>>> {
    let points = points_of(&points)?;
    let prepared = mesh.get().prepared.clone();
    let values = process::run(py, None, |_| prepared.winding_numbers(&points))?.map_err(query_err)?;
    Ok(values.into_pyarray(py))
}

/// The engine for a query on `backend` (a name), shared with the other calls of this process (`auto` by
/// [`query_backend`]'s rule).
fn query_engine(backend: &str) -> Result<std::sync::Arc<Engine>, Failure> {
    let backend = Backend::from_name(backend).ok_or_else(|| {
        Failure::Engine(EngineError::Query(crate::voxel::query::QueryError::Backend(backend.to_string())))
    })?;
    process::engine(query_backend(backend)).map_err(Failure::Engine)
}

/// `meshvox._native.query(mesh, points float64 (N, 3), sign, backend)`: a dict of numpy arrays (`distance`,
/// `inside`, `closest`, `triangle`, `barycentric`; `inside` None when unsigned) and `backend`, where the nearest
/// triangles were found. The winding numbers' values are [`winding`]'s, asked for when wanted.
#[pyfunction]
#[pyo3(signature = (mesh, points, sign, backend))]
pub(super) fn query<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyPrepared>,
    points: PyReadonlyArray2<'py, f64>,
    sign: &str,
    backend: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let sign = Sign::from_name(sign)
        .ok_or_else(|| PyValueError::new_err(format!("sign '{sign}': use {}", Sign::choices())))?;
    let points = points_of(&points)?;
    let prepared = mesh.get().prepared.clone();
    let queried = process::run(py, None, |_| {
        query_engine(backend)?.query(&prepared, &points, sign, false).map_err(Failure::Engine)
    })?
    .map_err(into_py_err)?;
    let answers = queried.answers;
    let n = points.len();
    let dict = PyDict::new(py);
    dict.set_item("distance", answers.distance.into_pyarray(py))?;
    match answers.inside {
        Some(inside) => dict.set_item("inside", inside.into_pyarray(py))?,
        None => dict.set_item("inside", py.None())?,
    }
    let closest: Vec<f64> = answers.closest.iter().flat_map(|p| p.to_array()).collect();
    dict.set_item("closest", closest.into_pyarray(py).reshape([n, 3])?)?;
    let triangle: Vec<i64> = answers.triangle.iter().map(|&t| i64::from(t)).collect();
    dict.set_item("triangle", triangle.into_pyarray(py))?;
    let barycentric: Vec<f32> = answers.barycentric.iter().flatten().copied().collect();
    dict.set_item("barycentric", barycentric.into_pyarray(py).reshape([n, 3])?)?;
    dict.set_item("evaluations", answers.evaluations)?;
    dict.set_item("backend", queried.backend)?;
    dict.set_item("host_decided", queried.host_decided)?;
    dict.set_item("wait_ms", queried.wait_ms)?;
    dict.set_item("host_work_ms", queried.host_work_ms)?;
    Ok(dict)
}

/// The request of `meshvox.sample`'s keywords.
#[allow(clippy::too_many_arguments)]
fn sample_request(
    uniform: usize,
    surface: usize,
    near: usize,
    sigma: Vec<f64>,
    padding: f64,
    normalize: Option<&str>,
    seed: u64,
) -> PyResult<SampleRequest> {
    let normalize = match normalize {
        None => Normalize::Off,
        Some(name) => Normalize::from_name(name).filter(|n| *n != Normalize::Off).ok_or_else(|| {
            PyValueError::new_err(format!("normalize '{name}': use \"unit-cube\", \"unit-sphere\" or None"))
        })?,
    };
    Ok(SampleRequest { uniform, surface, near, sigma, padding, normalize, seed })
}

/// The dictionary `meshvox.Samples` is made from.
fn samples_dict(py: Python<'_>, (s, backend): (Samples, String)) -> PyResult<Bound<'_, PyDict>> {
    let m = s.points.len();
    let dict = PyDict::new(py);
    let points: Vec<f32> = s.points.iter().flatten().copied().collect();
    dict.set_item("points", points.into_pyarray(py).reshape([m, 3])?)?;
    dict.set_item("sdf", s.sdf.into_pyarray(py))?;
    dict.set_item("occupancy", s.occupancy.into_pyarray(py))?;
    dict.set_item("triangle", s.triangle.into_pyarray(py))?;
    let normal: Vec<f32> = s.normal.iter().flatten().copied().collect();
    dict.set_item("normal", normal.into_pyarray(py).reshape([m, 3])?)?;
    dict.set_item("kind", s.kind.into_pyarray(py))?;
    dict.set_item("scale", s.scale)?;
    dict.set_item("offset", s.offset.to_array())?;
    dict.set_item("backend", backend)?;
    Ok(dict)
}

/// `meshvox._native.sample_many(meshes, ..., workers, progress, backend)`: each mesh (a prepared one, a path or
/// arrays) prepared and sampled on `workers` threads at a time, in input order, the samples' nearest triangles on
/// `backend`; `progress(done, total)` counts meshes. `meshvox.sample` is this with one mesh.
#[pyfunction]
#[pyo3(signature = (meshes, uniform, surface, near, sigma, padding, normalize, seed, workers, progress, backend))]
#[allow(clippy::too_many_arguments)]
pub(super) fn sample_many<'py>(
    py: Python<'py>,
    meshes: Vec<Bound<'py, PyAny>>,
    uniform: usize,
    surface: usize,
    near: usize,
    sigma: Vec<f64>,
    padding: f64,
    normalize: Option<&str>,
    seed: u64,
    workers: Option<usize>,
    progress: Option<&Bound<'py, PyAny>>,
    backend: &str,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let request = sample_request(uniform, surface, near, sigma, padding, normalize, seed)?;
    let engine = query_engine(backend).map_err(into_py_err)?;
    // A prepared mesh is shared as it is; the others are loaded and prepared by the worker that takes them.
    enum Item {
        Ready(Arc<Prepared>),
        Later(Box<Input>),
    }
    let items: Vec<std::sync::Mutex<Option<Item>>> = meshes
        .iter()
        .map(|m| match m.cast::<PyPrepared>() {
            Ok(p) => Ok(Item::Ready(p.get().prepared.clone())),
            Err(_) => input(m).map(|i| Item::Later(Box::new(i))),
        })
        .map(|i| i.map(|i| std::sync::Mutex::new(Some(i))))
        .collect::<PyResult<_>>()?;
    let total = items.len();
    // Each mesh's points already use every core; a few meshes at once keep them busy between meshes.
    let workers = workers.unwrap_or(2).clamp(1, total.max(1));
    let results = process::run(py, progress, |control| {
        control.each(total, workers, |i| {
            let item = items[i].lock().unwrap_or_else(|e| e.into_inner()).take();
            let item = item.filter(|_| !control.cancel.load(std::sync::atomic::Ordering::Relaxed))?;
            let prepared = match item {
                Item::Ready(prepared) => prepared,
                Item::Later(input) => match prepare(*input) {
                    Ok(prepared) => prepared,
                    Err(e) => return Some(Err(e)),
                },
            };
            let sampled = engine.sample(&prepared, &request).map_err(Failure::Engine);
            Some(sampled.map(|(samples, queried)| (samples, queried.backend)))
        })
    })?;
    let mut out = Vec::with_capacity(total);
    for result in results {
        let result = result.ok_or_else(|| pyo3::exceptions::PyRuntimeError::new_err("cancelled"))?;
        out.push(samples_dict(py, result.map_err(into_py_err)?)?);
    }
    Ok(out)
}
