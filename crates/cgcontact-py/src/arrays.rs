//! numpy arrays in: rows of three float64 values read in place when the array allows it, any
//! other array-like converted once by numpy.

use std::borrow::Cow;

use cgcontact::glam::DVec3;
use numpy::{PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyTuple;

/// An `(n, 3)` float64 array borrowed from Python (read-only for as long as this lives).
pub struct Rows<'py> {
    array: PyReadonlyArray2<'py, f64>,
}

impl<'py> Rows<'py> {
    /// The rows as vectors: the array's own memory when it is C-contiguous and 8-byte aligned
    /// (always, for arrays numpy allocated), else a copy.
    pub fn vectors(&self) -> PyResult<Cow<'_, [DVec3]>> {
        let flat = self
            .array
            .as_slice()
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        // `DVec3` is three f64 fields in a `repr(C)` struct, so bytemuck checks the length and the
        // alignment and reinterprets the buffer without copying it.
        Ok(match bytemuck::try_cast_slice::<f64, DVec3>(flat) {
            Ok(vectors) => Cow::Borrowed(vectors),
            Err(_) => Cow::Owned(flat.chunks_exact(3).map(DVec3::from_slice).collect()),
        })
    }
}

/// `numpy.ascontiguousarray(obj, dtype)`: the same object when it already is one.
fn contiguous<'py>(obj: &Bound<'py, PyAny>, dtype: &str) -> PyResult<Bound<'py, PyAny>> {
    let numpy = obj.py().import("numpy")?;
    numpy.call_method1("ascontiguousarray", (obj, numpy.getattr(dtype)?))
}

fn shape_of(obj: &Bound<'_, PyAny>) -> String {
    obj.getattr("shape")
        .and_then(|s| s.str().map(|s| s.to_string()))
        .unwrap_or_else(|_| "?".to_owned())
}

/// `what` as an `(n, 3)` float64 array: read in place when it is a C-contiguous float64 array,
/// else converted once. With `single`, a single point of shape `(3,)` is taken as one row; the
/// flag returned says whether it was one.
pub fn rows<'py>(obj: &Bound<'py, PyAny>, what: &str, single: bool) -> PyResult<(Rows<'py>, bool)> {
    if let Ok(array) = obj.extract::<PyReadonlyArray2<'py, f64>>()
        && array.is_c_contiguous()
    {
        return check(Rows { array }, what).map(|r| (r, false));
    }
    let converted = contiguous(obj, "float64")?;
    let ndim: usize = converted.getattr("ndim")?.extract()?;
    let (converted, was_single) = if single && ndim == 1 {
        let shape = PyTuple::new(obj.py(), [1usize, 3])?;
        let reshaped = converted.call_method1("reshape", (shape,)).map_err(|_| {
            PyValueError::new_err(format!(
                "{what} must have shape (3,) or (n, 3), got {}",
                shape_of(&converted)
            ))
        })?;
        (reshaped, true)
    } else {
        (converted, false)
    };
    let array = converted
        .extract::<PyReadonlyArray2<'py, f64>>()
        .map_err(|_| {
            PyValueError::new_err(format!(
                "{what} must have shape (n, 3), got {}",
                shape_of(&converted)
            ))
        })?;
    check(Rows { array }, what).map(|r| (r, was_single))
}

fn check<'py>(rows: Rows<'py>, what: &str) -> PyResult<Rows<'py>> {
    let shape = rows.array.shape();
    if shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{what} must have shape (n, 3), got ({}, {})",
            shape[0], shape[1]
        )));
    }
    Ok(rows)
}

/// The first row of `vectors` with a NaN or infinite value, as an error naming it.
pub fn finite(vectors: &[DVec3], what: &str) -> PyResult<()> {
    match vectors.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(row) => Err(PyValueError::new_err(format!(
            "{what} row {row} (0-based) is not finite: {}",
            vectors[row]
        ))),
    }
}

/// Whether `converted` (an array cast to another dtype) holds the values of `given`: the cast
/// truncated or wrapped nothing.
fn same_values(converted: &Bound<'_, PyAny>, given: &Bound<'_, PyAny>) -> PyResult<bool> {
    let numpy = given.py().import("numpy")?;
    numpy
        .call_method1("array_equal", (converted, given))?
        .extract()
}

/// `what` as an `(n, 8)` int64 array of hexahedra, copied. Values that are not whole numbers
/// (2.5, NaN, or beyond int64) are refused: numpy's conversion would truncate or wrap them into
/// other nodes' numbers.
pub fn hexes(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[i64; 8]>> {
    let numpy = obj.py().import("numpy")?;
    let given = numpy.call_method1("asarray", (obj,))?;
    // NaN and out-of-range floats are refused below; numpy's warning on casting them is noise.
    let kwargs = pyo3::types::PyDict::new(obj.py());
    kwargs.set_item("invalid", "ignore")?;
    let quiet = numpy.call_method("errstate", (), Some(&kwargs))?;
    quiet.call_method0("__enter__")?;
    let converted = contiguous(&given, "int64");
    let none = obj.py().None();
    quiet.call_method1("__exit__", (&none, &none, &none))?;
    let converted = converted?;
    if !same_values(&converted, &given)? {
        return Err(PyValueError::new_err(format!(
            "{what} must hold whole node numbers (an integer array), got dtype {}",
            given.getattr("dtype")?.str()?
        )));
    }
    let array = converted
        .extract::<PyReadonlyArray2<'_, i64>>()
        .ok()
        .filter(|a| a.shape()[1] == 8)
        .ok_or_else(|| {
            PyValueError::new_err(format!(
                "{what} must have shape (n, 8), got {}",
                shape_of(&converted)
            ))
        })?;
    let flat = array
        .as_slice()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(flat
        .chunks_exact(8)
        .map(|c| std::array::from_fn(|k| c[k]))
        .collect())
}

/// `what`, one flag per lattice cell of `counts` ([nx, ny, nz]), as a flat array of booleans (x
/// fastest): a flat array, or one of shape (nz, ny, nx), of booleans or of 0s and 1s. Other
/// shapes of as many values ((nx, ny, nz) would be read transposed) and other values (2 is no
/// flag) are refused.
pub fn flags(obj: &Bound<'_, PyAny>, what: &str, counts: [u32; 3]) -> PyResult<Vec<bool>> {
    let numpy = obj.py().import("numpy")?;
    let given = numpy.call_method1("asarray", (obj,))?;
    let shape: Vec<usize> = given.getattr("shape")?.extract()?;
    let [nx, ny, nz] = counts.map(|n| n as usize);
    let n = nx * ny * nz;
    if shape != [n] && shape != [nz, ny, nx] {
        return Err(PyValueError::new_err(format!(
            "{what} must have shape ({n},) or (nz, ny, nx) = ({nz}, {ny}, {nx}), got {}",
            shape_of(&given)
        )));
    }
    let converted = contiguous(&given, "bool_")?;
    if !same_values(&converted, &given)? {
        return Err(PyValueError::new_err(format!(
            "{what} must hold booleans, or 0s and 1s (dtype {})",
            given.getattr("dtype")?.str()?
        )));
    }
    converted
        .call_method0("ravel")?
        .call_method0("tolist")?
        .extract()
}
