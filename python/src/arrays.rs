//! numpy at the boundary: arguments checked into one clear `TypeError` or `ValueError`
//! naming the argument, and results handed out as read-only views of the Rust data (no
//! copy) where its layout is numpy's.

use crate::errors::{type_error, value_error};
use numpy::ndarray::{ArrayD, ArrayView, Dimension, IxDyn};
use numpy::{Element, PyArray, PyArrayDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// A shape to check against: `None` for any length of that axis.
pub type Shape<'a> = &'a [Option<usize>];

/// Written as numpy prints a shape, with `N`-like names for free axes: `[N, 3]`.
fn describe(shape: Shape, names: &[&str]) -> String {
    let axes: Vec<String> = shape
        .iter()
        .zip(names.iter().chain(std::iter::repeat(&"?")))
        .map(|(axis, name)| axis.map_or_else(|| name.to_string(), |n| n.to_string()))
        .collect();
    format!("[{}]", axes.join(", "))
}

/// `obj` as a numpy array of shape `shape` (axes named `names` in messages), its dtype one
/// of `dtypes` (numpy names); returns the array and its dtype's name.
pub fn checked<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    dtypes: &[&str],
    shape: Shape,
    names: &[&str],
) -> PyResult<(Bound<'py, PyUntypedArray>, String)> {
    let py = obj.py();
    let expected =
        || format!("a numpy array of {} with shape {}", dtypes.join(" or "), describe(shape, names));
    let array = obj
        .downcast::<PyUntypedArray>()
        .map_err(|_| type_error(name, format!("expected {}, got {}", expected(), type_name(obj))))?;
    let dtype = array.dtype().to_string();
    if !dtypes.contains(&dtype.as_str()) {
        return Err(type_error(name, format!("expected {}, got dtype {dtype}", expected())));
    }
    let got = array.shape();
    let fits = got.len() == shape.len() && got.iter().zip(shape).all(|(g, s)| s.is_none_or(|s| s == *g));
    if !fits {
        return Err(value_error(py, name, format!("expected shape {}, got {got:?}", describe(shape, names))));
    }
    if got.iter().product::<usize>() == 0 {
        return Err(value_error(py, name, format!("expected a non-empty array, got shape {got:?}")));
    }
    Ok((array.clone(), dtype))
}

/// The Python type's name of `obj`, for messages.
pub fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "an object".into())
}

/// The values of a checked array as `T`, in C order (one copy; strided arrays allowed).
pub fn values<T: Element + Copy>(array: &Bound<'_, PyUntypedArray>) -> PyResult<Vec<T>> {
    let typed = array.downcast::<PyArrayDyn<T>>()?;
    let readonly = typed.try_readonly()?;
    Ok(readonly.as_array().iter().copied().collect())
}

/// A float array (float32 or float64) as f32 values, each finite.
pub fn floats(obj: &Bound<'_, PyAny>, name: &str, shape: Shape, names: &[&str]) -> PyResult<Vec<f32>> {
    let (array, dtype) = checked(obj, name, &["float32", "float64"], shape, names)?;
    let v: Vec<f32> = match dtype.as_str() {
        "float32" => values::<f32>(&array)?,
        _ => values::<f64>(&array)?.into_iter().map(|v| v as f32).collect(),
    };
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(value_error(
            obj.py(),
            name,
            format!("expected finite values, got {} at flat index {i}", v[i]),
        ));
    }
    Ok(v)
}

/// An integer array (any width, signed or not) as u32 indices below `limit`.
pub fn indices(
    obj: &Bound<'_, PyAny>,
    name: &str,
    shape: Shape,
    names: &[&str],
    limit: usize,
) -> PyResult<Vec<u32>> {
    let ints = ["int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64"];
    let (array, _) = checked(obj, name, &ints, shape, names)?;
    let wide: Vec<i64> = array.call_method1("astype", ("int64",))?.downcast::<PyArrayDyn<i64>>()?.to_vec()?;
    match wide.iter().position(|&i| i < 0 || i as u64 >= limit as u64) {
        Some(i) => Err(value_error(
            obj.py(),
            name,
            format!("index {} at flat position {i} is outside 0..{limit}", wide[i]),
        )),
        None => Ok(wide.into_iter().map(|i| i as u32).collect()),
    }
}

/// A read-only numpy view of `data` with `shape`, kept alive by `owner` (no copy).
///
/// `data` must live inside `owner` and never change while `owner` lives: every caller passes
/// data held by an immutable pyclass (or an `Arc` it holds).
pub fn view<'py, T: Element>(
    owner: &Bound<'py, PyAny>,
    data: &[T],
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    let view = ArrayView::from_shape(IxDyn(shape), data)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(format!("internal error: {e}")))?;
    // SAFETY: `owner` keeps `data` alive and unchanged (see above); the array is made
    // read-only before anyone else sees it.
    let array = unsafe { PyArray::borrow_from_array(&view, owner.clone()) };
    array.call_method("setflags", (), Some(&[("write", false)].into_py_dict(owner.py())?))?;
    Ok(array)
}

/// An owned array handed to numpy (its buffer moves, no copy).
pub fn owned<'py, T: Element, D: Dimension>(
    py: Python<'py>,
    array: numpy::ndarray::Array<T, D>,
) -> Bound<'py, PyArrayDyn<T>> {
    let dynamic: ArrayD<T> = array.into_dyn();
    PyArray::from_owned_array(py, dynamic)
}

use pyo3::types::IntoPyDict;
