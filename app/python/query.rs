//! `meshvox.Mesh` and `meshvox.query` from Python: a mesh loaded and prepared once ([`Prepared`]: its frame,
//! hierarchy and boundary), and exact answers at an array of points, computed off the GIL on the library's pool.

use super::{Failure, Input, input, into_py_err, process};
use crate::mesh::Mesh;
use crate::voxel::query::{Prepared, QueryError, Sign};
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
    pub(super) mesh: Arc<Mesh>,
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
            let p = prepared.get();
            return Ok(PyPrepared { mesh: p.mesh.clone(), prepared: p.prepared.clone() });
        }
        let input = input(source)?;
        let made = process::run(py, None, |_| {
            let (_, mesh) = input.load()?;
            let prepared = Prepared::new(&mesh).map_err(Failure::Query)?;
            Ok::<_, Failure>((mesh, prepared))
        })?;
        let (mesh, prepared) = made.map_err(into_py_err)?;
        Ok(PyPrepared { mesh: Arc::new(mesh), prepared: Arc::new(prepared) })
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
        self.mesh.name.clone()
    }
}

impl PyPrepared {
    /// The mesh for a voxelization.
    pub(super) fn input(&self) -> Input {
        Input::Mesh((*self.mesh).clone())
    }
}

/// `meshvox._native.query(mesh, points float64 (N, 3), sign)`: a dict of numpy arrays (`distance`, `winding`,
/// `inside`, `closest`, `triangle`, `barycentric`; `winding` and `inside` None when unsigned).
#[pyfunction]
#[pyo3(signature = (mesh, points, sign))]
pub(super) fn query<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyPrepared>,
    points: PyReadonlyArray2<'py, f64>,
    sign: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let sign = Sign::from_name(sign)
        .ok_or_else(|| PyValueError::new_err(format!("sign '{sign}': use {}", Sign::choices())))?;
    let view = points.as_array();
    if view.ncols() != 3 {
        return Err(PyValueError::new_err(format!("points must have shape (N, 3), not {:?}", view.shape())));
    }
    let Some(flat) = view.as_slice() else {
        return Err(PyValueError::new_err("points must be C-contiguous"));
    };
    let points: Vec<DVec3> = bytemuck::cast_slice::<f64, DVec3>(flat).to_vec();
    let prepared = mesh.get().prepared.clone();
    let answers = process::run(py, None, |_| prepared.query(&points, sign))?.map_err(query_err)?;
    let n = points.len();
    let dict = PyDict::new(py);
    dict.set_item("distance", answers.distance.into_pyarray(py))?;
    match (answers.winding, answers.inside) {
        (Some(w), Some(i)) => {
            dict.set_item("winding", w.into_pyarray(py))?;
            dict.set_item("inside", i.into_pyarray(py))?;
        }
        _ => {
            dict.set_item("winding", py.None())?;
            dict.set_item("inside", py.None())?;
        }
    }
    let closest: Vec<f64> = answers.closest.iter().flat_map(|p| p.to_array()).collect();
    dict.set_item("closest", closest.into_pyarray(py).reshape([n, 3])?)?;
    let triangle: Vec<i64> = answers.triangle.iter().map(|&t| i64::from(t)).collect();
    dict.set_item("triangle", triangle.into_pyarray(py))?;
    let barycentric: Vec<f32> = answers.barycentric.iter().flatten().copied().collect();
    dict.set_item("barycentric", barycentric.into_pyarray(py).reshape([n, 3])?)?;
    dict.set_item("evaluations", answers.evaluations)?;
    Ok(dict)
}
