//! numpy ⇄ nalgebra, and Python values ⇄ JSON values (for the serde configurations).

use crate::error::to_py;
use nalgebra::{Isometry3, Matrix3, Matrix4, Matrix6, Point3};
use numpy::ndarray::{Array1, Array2, Array3, ArrayView2};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

/// Rows of an `(N, 3)` array as points (read in place: any strides, no copy of the array).
pub fn points_from(array: &PyReadonlyArray2<'_, f64>, what: &str) -> PyResult<Vec<Point3<f64>>> {
    let view: ArrayView2<f64> = array.as_array();
    if view.ncols() != 3 {
        return Err(to_py(format!(
            "{what} must have shape (N, 3), got {:?}",
            view.shape()
        )));
    }
    Ok(view
        .rows()
        .into_iter()
        .map(|r| Point3::new(r[0], r[1], r[2]))
        .collect())
}

/// An `(N, 3, 3)` array as matrices.
pub fn matrices3_from(
    array: &PyReadonlyArray3<'_, f64>,
    what: &str,
) -> PyResult<Vec<Matrix3<f64>>> {
    let view = array.as_array();
    if view.shape()[1..] != [3, 3] {
        return Err(to_py(format!(
            "{what} must have shape (N, 3, 3), got {:?}",
            view.shape()
        )));
    }
    Ok(view
        .outer_iter()
        .map(|m| Matrix3::from_fn(|r, c| m[[r, c]]))
        .collect())
}

/// A `(4, 4)` homogeneous matrix as a rigid transform (refused when it is not one).
pub fn isometry_from(array: &PyReadonlyArray2<'_, f64>, what: &str) -> PyResult<Isometry3<f64>> {
    let view = array.as_array();
    if view.shape() != [4, 4] {
        return Err(to_py(format!(
            "{what} must have shape (4, 4), got {:?}",
            view.shape()
        )));
    }
    let m = Matrix4::from_fn(|r, c| view[[r, c]]);
    segloc_maps::isometry_from_matrix(&m).map_err(|e| to_py(format!("{what}: {e}")))
}

/// Points as an `(N, 3)` array (numpy owns the buffer written here: no second copy).
pub fn points_to<'py>(
    py: Python<'py>,
    points: impl ExactSizeIterator<Item = Point3<f64>>,
) -> Bound<'py, PyArray2<f64>> {
    let n = points.len();
    let flat: Vec<f64> = points.flat_map(|p| [p.x, p.y, p.z]).collect();
    Array2::from_shape_vec((n, 3), flat)
        .expect("n × 3 values")
        .into_pyarray(py)
}

/// Values as an `(N,)` array.
pub fn vector_to<'py>(py: Python<'py>, values: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    Array1::from_vec(values).into_pyarray(py)
}

/// Matrices as an `(N, R, C)` array.
pub fn stack_to<'py, const R: usize, const C: usize>(
    py: Python<'py>,
    matrices: &[nalgebra::SMatrix<f64, R, C>],
) -> Bound<'py, PyArray3<f64>> {
    let flat: Vec<f64> = matrices
        .iter()
        .flat_map(|m| (0..R).flat_map(move |r| (0..C).map(move |c| m[(r, c)])))
        .collect();
    Array3::from_shape_vec((matrices.len(), R, C), flat)
        .expect("n × r × c values")
        .into_pyarray(py)
}

/// A matrix as an `(R, C)` array.
pub fn matrix_to<'py, const R: usize, const C: usize>(
    py: Python<'py>,
    m: &nalgebra::SMatrix<f64, R, C>,
) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((R, C), |(r, c)| m[(r, c)]).into_pyarray(py)
}

/// A rigid transform as its `(4, 4)` homogeneous matrix.
pub fn isometry_to<'py>(py: Python<'py>, t: &Isometry3<f64>) -> Bound<'py, PyArray2<f64>> {
    let m: Matrix4<f64> = t.to_homogeneous();
    matrix_to(py, &m)
}

/// A 6 × 6 matrix as a `(6, 6)` array.
pub fn matrix6_to<'py>(py: Python<'py>, m: &Matrix6<f64>) -> Bound<'py, PyArray2<f64>> {
    matrix_to(py, m)
}

/// A JSON value as Python objects (dicts, lists, floats, ints, strings, None).
pub fn json_to_py<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    use serde_json::Value;
    Ok(match value {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_u64(), n.as_f64()) {
            (Some(i), _, _) => i.into_pyobject(py)?.into_any(),
            (_, Some(u), _) => u.into_pyobject(py)?.into_any(),
            (_, _, Some(f)) => PyFloat::new(py, f).into_any(),
            _ => py.None().into_bound(py),
        },
        Value::String(s) => PyString::new(py, s).into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(json_to_py(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, v) in map {
                dict.set_item(k, json_to_py(py, v)?)?;
            }
            dict.into_any()
        }
    })
}

/// Python objects (dicts with str keys, lists / tuples, numbers, str, bool, None) as JSON.
pub fn py_to_json(value: &Bound<'_, PyAny>) -> PyResult<serde_json::Value> {
    use serde_json::Value;
    if value.is_none() {
        Ok(Value::Null)
    } else if let Ok(b) = value.cast::<PyBool>() {
        Ok(Value::Bool(b.is_true()))
    } else if value.is_instance_of::<PyInt>() {
        let i: i64 = value.extract()?;
        Ok(Value::from(i))
    } else if let Ok(f) = value.cast::<PyFloat>() {
        Ok(serde_json::Number::from_f64(f.value())
            .map(Value::Number)
            .unwrap_or(Value::Null))
    } else if let Ok(s) = value.cast::<PyString>() {
        Ok(Value::String(s.extract::<String>()?))
    } else if let Ok(d) = value.cast::<PyDict>() {
        let mut map = serde_json::Map::new();
        for (k, v) in d.iter() {
            map.insert(k.extract::<String>()?, py_to_json(&v)?);
        }
        Ok(Value::Object(map))
    } else if value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>() {
        let items: Vec<Bound<'_, PyAny>> = value.extract()?;
        Ok(Value::Array(
            items.iter().map(py_to_json).collect::<PyResult<_>>()?,
        ))
    } else {
        Err(to_py(format!(
            "cannot use {} in a configuration",
            value.get_type().name()?
        )))
    }
}

/// A configuration from keyword arguments: every section a dict of fields; fields not
/// given keep their defaults (the configurations are `#[serde(default)]`).
pub fn config_from<T: serde::de::DeserializeOwned>(
    what: &str,
    fields: Option<&Bound<'_, PyDict>>,
) -> PyResult<T> {
    let value = match fields {
        Some(d) => py_to_json(d.as_any())?,
        None => serde_json::Value::Object(Default::default()),
    };
    serde_json::from_value(value).map_err(|e| to_py(format!("{what}: {e}")))
}
