//! numpy arrays in: rows of three float64 values read in place when the array allows it, any
//! other array-like converted once by numpy.

use std::borrow::Cow;
use std::ops::Range;

use cgcontact::glam::DVec3;
use numpy::ndarray::Dimension;
use numpy::{
    Element, PyArray, PyArray2, PyArrayMethods, PyReadonlyArray, PyReadonlyArray1,
    PyReadonlyArray2, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::conversion::FromPyObjectOwned;
use pyo3::exceptions::{PyMemoryError, PyOverflowError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBool, PyBytes, PyList, PyString, PyTuple, PyType};

/// `obj`, the argument `what`, as a `T`, or an error naming the argument and what it must be
/// (`expected`): pyo3 names the argument in a `TypeError` only, not in the `OverflowError` of a
/// negative count ("out of range integral type conversion attempted") or in the `ValueError` of
/// a sequence of another length. A wrong type stays a `TypeError`; a wrong value is a
/// `ValueError`.
pub fn argument<'py, T: FromPyObjectOwned<'py>>(
    obj: &Bound<'py, PyAny>,
    what: &str,
    expected: &str,
) -> PyResult<T> {
    obj.extract::<T>().map_err(|e| {
        let py = obj.py();
        let e: PyErr = e.into();
        let given = obj
            .repr()
            .map_or_else(|_| "?".to_owned(), |r| r.to_string());
        let message = format!("{what} must be {expected}, got {}", clip(&given));
        if e.is_instance_of::<PyTypeError>(py) {
            PyTypeError::new_err(message)
        } else {
            PyValueError::new_err(message)
        }
    })
}

/// [`argument`] for a number or numbers (`counts`, `max_iter`, `threads`, `origin`, `spacing`,
/// `tol`, `dist`), refusing booleans as a `TypeError`: `True` and `False`, numpy's `True_` and
/// `False_`, and numpy arrays of booleans, alone or in a list, tuple or object array. Python and
/// numpy take a boolean for the number 1 or 0, but no count, coordinate or length is meant by it
/// (as booleans are refused in arrays of points and node numbers).
pub fn not_boolean<'py, T: FromPyObjectOwned<'py>>(
    obj: &Bound<'py, PyAny>,
    what: &str,
    expected: &str,
) -> PyResult<T> {
    let elements = if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        Some(obj.try_iter()?)
    } else if dtype_kind(obj)?.as_deref() == Some("O") {
        // `flat`: an object array of any shape, 0-d included, element by element.
        Some(obj.getattr("flat")?.try_iter()?)
    } else {
        None
    };
    let holds = match elements {
        Some(elements) => {
            let mut found = false;
            for element in elements {
                if boolean(&element?)? {
                    found = true;
                    break;
                }
            }
            found
        }
        None => boolean(obj)?,
    };
    if holds {
        let given = obj
            .repr()
            .map_or_else(|_| "?".to_owned(), |r| r.to_string());
        return Err(PyTypeError::new_err(format!(
            "{what} must be {expected}, got {}",
            clip(&given)
        )));
    }
    argument(obj, what, expected)
}

/// Whether `obj` is a boolean: Python's (`True`), numpy's (`numpy.True_`, whose dtype is
/// boolean, but which is no `bool`) or a numpy array of them.
fn boolean(obj: &Bound<'_, PyAny>) -> PyResult<bool> {
    Ok(obj.is_instance_of::<PyBool>() || dtype_kind(obj)?.as_deref() == Some("b"))
}

/// The kind of `obj`'s numpy dtype (`"b"` boolean, `"O"` object...) when `obj` is a numpy array
/// or scalar, else `None`.
fn dtype_kind(obj: &Bound<'_, PyAny>) -> PyResult<Option<String>> {
    static GENERIC: PyOnceLock<Py<PyType>> = PyOnceLock::new();
    let py = obj.py();
    let numpy = obj.is_instance_of::<PyUntypedArray>()
        || obj.is_instance(GENERIC.import(py, "numpy", "generic")?)?;
    if !numpy {
        return Ok(None);
    }
    Ok(Some(obj.getattr("dtype")?.getattr("kind")?.extract()?))
}

/// `text` cut to about 80 characters, for an error message.
fn clip(text: &str) -> String {
    match text.char_indices().nth(80) {
        None => text.to_owned(),
        Some((end, _)) => format!("{}...", &text[..end]),
    }
}

/// An error numpy raised reading the argument `what` (a ragged list, a string that is no
/// number), naming it; its type is kept, but for an `OverflowError` (a Python int too large for
/// a float64 or an int64: `10**400`), which becomes a `ValueError` as any other value out of
/// range. Any other error (`MemoryError`, `KeyboardInterrupt`) passes unchanged.
fn naming(py: Python<'_>, e: PyErr, what: &str) -> PyErr {
    let message = format!("{what} cannot be read as a numeric array: {}", e.value(py));
    let named = if e.is_instance_of::<PyTypeError>(py) {
        PyTypeError::new_err(message)
    } else if e.is_instance_of::<PyValueError>(py) || e.is_instance_of::<PyOverflowError>(py) {
        PyValueError::new_err(message)
    } else {
        return e;
    };
    named.set_cause(py, Some(e));
    named
}

/// `obj` as a numpy array (`numpy.asarray`), numpy's errors naming the argument `what`.
fn as_array<'py>(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<Bound<'py, PyAny>> {
    let py = obj.py();
    py.import("numpy")?
        .call_method1("asarray", (obj,))
        .map_err(|e| naming(py, e, what))
}

/// A vector for an error message: each value as Rust's `Debug` writes it, short however large
/// (`1e300`, where `Display` writes 301 digits).
pub fn show(v: DVec3) -> String {
    format!("[{:?}, {:?}, {:?}]", v.x, v.y, v.z)
}

/// `array`, the argument `what`, borrowed for reading, or an error when a call running in another
/// thread is writing to it (an `out` array of a query that released the GIL): numpy's
/// `extract` of a read-only array unwraps that borrow, and the panic reached Python as a
/// `PanicException`, which `except Exception` does not catch.
fn readonly<'py, T: Element, D: Dimension>(
    array: &Bound<'py, PyArray<T, D>>,
    what: &str,
) -> PyResult<PyReadonlyArray<'py, T, D>> {
    array.try_readonly().map_err(|_| {
        PyValueError::new_err(format!(
            "{what}: another call is writing to this array (an out array of a query running in \
             another thread); give each call arrays of its own"
        ))
    })
}

/// An `(n, 3)` float64 array borrowed from Python (read-only for as long as this lives).
pub struct Rows<'py> {
    array: PyReadonlyArray2<'py, f64>,
}

impl<'py> Rows<'py> {
    /// The bytes of the array the rows are read from ([`extent`]).
    pub fn extent(&self) -> Range<usize> {
        extent(&self.array)
    }

    /// The rows as vectors, in the array's own memory (`rows` gives C-contiguous, aligned arrays
    /// only); a copy if bytemuck would refuse the cast.
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

/// The addresses of the bytes `array`'s elements lie in, from its lowest byte to one past its
/// highest, whatever its strides (numpy's `may_share_memory` bounds); empty for an array of no
/// element. Two arrays whose extents are disjoint share no memory, whatever Python objects own it:
/// numpy's borrow flags, which rust-numpy checks, only see arrays of one base object, so a view of
/// a `bytearray` and one of a `memoryview` of it pass them.
pub fn extent<T: Element, D: Dimension>(array: &Bound<'_, PyArray<T, D>>) -> Range<usize> {
    let start = array.data() as usize;
    if array.is_empty() {
        return start..start;
    }
    let (mut low, mut high) = (0isize, 0isize);
    for (&n, &stride) in array.shape().iter().zip(array.strides()) {
        // An array numpy made spans at most isize::MAX bytes.
        let span = stride.saturating_mul(n as isize - 1);
        if span < 0 {
            low = low.saturating_add(span);
        } else {
            high = high.saturating_add(span);
        }
    }
    let item = size_of::<T>() as isize;
    start.saturating_add_signed(low)..start.saturating_add_signed(high.saturating_add(item))
}

/// Whether two extents share a byte (an empty one shares none).
pub fn overlap(a: &Range<usize>, b: &Range<usize>) -> bool {
    !a.is_empty() && !b.is_empty() && a.start < b.end && b.start < a.end
}

/// `obj` as a C-contiguous, aligned array of `dtype`: the same object when it already is one
/// (`numpy.require(obj, dtype, "CA")`). numpy's `ascontiguousarray` keeps a misaligned array (a
/// view at an odd offset of a byte buffer), whose slice would be undefined behaviour in Rust.
fn contiguous<'py>(obj: &Bound<'py, PyAny>, dtype: &str) -> PyResult<Bound<'py, PyAny>> {
    let numpy = obj.py().import("numpy")?;
    numpy.call_method1("require", (obj, numpy.getattr(dtype)?, "CA"))
}

/// Whether an array's data pointer is aligned for its element type: numpy allocates aligned
/// arrays, but a view into a byte buffer (`numpy.frombuffer(b, offset=1)`) need not be.
fn aligned<T, D>(array: &Bound<'_, PyArray<T, D>>) -> bool {
    array.data().is_aligned()
}

fn shape_of(obj: &Bound<'_, PyAny>) -> String {
    obj.getattr("shape")
        .and_then(|s| s.str().map(|s| s.to_string()))
        .unwrap_or_else(|_| "?".to_owned())
}

/// An error when `obj` is a numpy masked array with masked values: numpy's conversions, and
/// reading its buffer in place, would take the values under the mask as data.
pub fn refuse_masked(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<()> {
    static MASKED_ARRAY: PyOnceLock<Py<PyType>> = PyOnceLock::new();
    let py = obj.py();
    if !obj.is_instance(MASKED_ARRAY.import(py, "numpy.ma", "MaskedArray")?)? {
        return Ok(());
    }
    let mask = py
        .import("numpy.ma")?
        .call_method1("getmaskarray", (obj,))?;
    if mask.call_method0("any")?.extract()? {
        return Err(PyValueError::new_err(format!(
            "{what} is a masked array with masked values: fill them (numpy.ma.filled) or drop \
             them, since the values under the mask would be read as data"
        )));
    }
    Ok(())
}

/// An error when `given` (a numpy array) holds values that are not real numbers: complex values
/// (whose imaginary part numpy's float conversion drops with only a warning), dates and times,
/// booleans (numpy would read them as 0 and 1), and text (numpy would parse it: an unread file's
/// columns), as an array of that dtype or as elements of an object array. `expected` says what
/// the argument `what` must hold ("real numbers", "integers"); with `flags` (`active`), booleans
/// are what it holds, and pass.
fn refuse_unreal(
    given: &Bound<'_, PyAny>,
    what: &str,
    expected: &str,
    flags: bool,
) -> PyResult<()> {
    let dtype = given.getattr("dtype")?;
    let kind: String = dtype.getattr("kind")?.extract()?;
    if matches!(kind.as_str(), "c" | "M" | "m" | "V" | "U" | "S") || (kind == "b" && !flags) {
        return Err(PyValueError::new_err(format!(
            "{what} must hold {expected}, got dtype {}",
            dtype.str()?
        )));
    }
    if kind == "O"
        && let Some((index, element)) = unreal_element(given, flags)?
    {
        let shown = element
            .repr()
            .map_or_else(|_| "?".to_owned(), |r| r.to_string());
        return Err(PyValueError::new_err(format!(
            "{what} must hold {expected}, got dtype object holding {} {} at {index:?}",
            element.get_type().name()?,
            clip(&shown)
        )));
    }
    Ok(())
}

/// The first element of the object array `given` (its index and itself) that numpy's numeric
/// conversion would take without a word but that is no real number: text (parsed: "3" becomes
/// 3), a boolean (read as 0 or 1), a complex number, None (read as NaN, which a point's error
/// then showed as a NaN the caller never wrote) or a numpy date or time (read as a count of its
/// unit since 1970). Other objects (a dict, a `datetime.date`) numpy refuses itself, naming the
/// argument through [`naming`]; numbers of any real kind pass, and booleans with `flags`.
fn unreal_element<'py>(
    given: &Bound<'py, PyAny>,
    flags: bool,
) -> PyResult<Option<(Vec<usize>, Bound<'py, PyAny>)>> {
    let py = given.py();
    let numpy = py.import("numpy")?;
    let numbers = py.import("numbers")?;
    let (complex, real) = (numbers.getattr("Complex")?, numbers.getattr("Real")?);
    let mut refused = vec![
        py.get_type::<PyString>().into_any(),
        py.get_type::<PyBytes>().into_any(),
        py.None().into_bound(py).get_type().into_any(),
        numpy.getattr("datetime64")?,
        numpy.getattr("timedelta64")?,
    ];
    if !flags {
        refused.extend([py.get_type::<PyBool>().into_any(), numpy.getattr("bool_")?]);
    }
    let refused = PyTuple::new(py, refused)?;
    for (k, element) in given.getattr("flat")?.try_iter()?.enumerate() {
        let element = element?;
        if element.is_instance(&refused)?
            || (element.is_instance(&complex)? && !element.is_instance(&real)?)
        {
            let index = numpy
                .call_method1("unravel_index", (k, given.getattr("shape")?))?
                .try_iter()?
                .map(|i| i?.extract::<usize>())
                .collect::<PyResult<Vec<usize>>>()?;
            return Ok(Some((index, element)));
        }
    }
    Ok(None)
}

/// `what` as an `(n, 3)` float64 array: read in place when it is a C-contiguous, aligned float64
/// array, else converted once (from any real dtype: complex values, dates and masked values are
/// refused, not reinterpreted). With `single`, a single point of shape `(3,)` is taken as one
/// row; the flag returned says whether it was one.
pub fn rows<'py>(obj: &Bound<'py, PyAny>, what: &str, single: bool) -> PyResult<(Rows<'py>, bool)> {
    refuse_masked(obj, what)?;
    if let Ok(array) = obj.cast::<PyArray2<f64>>()
        && array.is_c_contiguous()
        && aligned(array)
    {
        let array = readonly(array, what)?;
        return check(Rows { array }, what).map(|r| (r, false));
    }
    let given = as_array(obj, what)?;
    let shape: Vec<usize> = given.getattr("shape")?.extract()?;
    let was_single = single && shape == [3];
    // No points as `numpy.array([])` gives them (shape (0,)): as (0, 3).
    let empty = shape == [0];
    if !(was_single || empty || (shape.len() == 2 && shape[1] == 3)) {
        let wanted = if single { "(3,) or (n, 3)" } else { "(n, 3)" };
        return Err(PyValueError::new_err(format!(
            "{what} must have shape {wanted}, got {}",
            shape_of(&given)
        )));
    }
    refuse_unreal(&given, what, "real numbers", false)?;
    let converted = contiguous(&given, "float64").map_err(|e| naming(obj.py(), e, what))?;
    let converted = if was_single || empty {
        let shape = PyTuple::new(obj.py(), [usize::from(was_single), 3])?;
        converted.call_method1("reshape", (shape,))?
    } else {
        converted
    };
    let array = converted.cast::<PyArray2<f64>>().map_err(|_| {
        PyValueError::new_err(format!(
            "{what} must have shape (n, 3), got {}",
            shape_of(&converted)
        ))
    })?;
    // The same array as `obj` (or a view of it) when it needed no conversion.
    let array = readonly(array, what)?;
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
            show(vectors[row])
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

/// `what`, an `(m, 8)` array of hexahedra, as node numbers each below `nodes`, copied (once, into
/// memory allocated fallibly: a failed allocation would abort the interpreter). Values that are
/// not whole numbers (2.5, NaN, or beyond int64) are refused: numpy's conversion would truncate
/// or wrap them into other nodes' numbers.
pub fn hexes(obj: &Bound<'_, PyAny>, what: &str, nodes: usize) -> PyResult<Vec<[u32; 8]>> {
    refuse_masked(obj, what)?;
    let numpy = obj.py().import("numpy")?;
    let given = as_array(obj, what)?;
    // Booleans would be nodes 0 and 1, text parsed: both pass the whole-number check below.
    refuse_unreal(&given, what, "integers", false)?;
    // NaN and out-of-range floats are refused below; numpy's warning on casting them is noise.
    let kwargs = pyo3::types::PyDict::new(obj.py());
    kwargs.set_item("invalid", "ignore")?;
    let quiet = numpy.call_method("errstate", (), Some(&kwargs))?;
    quiet.call_method0("__enter__")?;
    let converted = contiguous(&given, "int64");
    let none = obj.py().None();
    quiet.call_method1("__exit__", (&none, &none, &none))?;
    let converted = converted.map_err(|e| naming(obj.py(), e, what))?;
    if !same_values(&converted, &given)? {
        return Err(PyValueError::new_err(format!(
            "{what} must hold whole node numbers (an integer array), got dtype {}",
            given.getattr("dtype")?.str()?
        )));
    }
    let array = converted
        .cast::<PyArray2<i64>>()
        .ok()
        .filter(|a| a.shape()[1] == 8)
        .ok_or_else(|| {
            PyValueError::new_err(format!(
                "{what} must have shape (n, 8), got {}",
                shape_of(&converted)
            ))
        })?;
    let array = readonly(array, what)?;
    let flat = array
        .as_slice()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let rows = flat.len() / 8;
    let mut cells = Vec::new();
    cells.try_reserve_exact(rows).map_err(|_| {
        PyMemoryError::new_err(format!("{what}: {rows} hexahedra do not fit in memory"))
    })?;
    for (c, corners) in flat.chunks_exact(8).enumerate() {
        let mut cell = [0u32; 8];
        for (k, &node) in corners.iter().enumerate() {
            cell[k] = u32::try_from(node)
                .ok()
                .filter(|&i| (i as usize) < nodes)
                .ok_or_else(|| {
                    PyValueError::new_err(format!(
                        "{what} row {c} corner {k}: node {node} is not one of the {nodes} nodes (numbered from 0)"
                    ))
                })?;
        }
        cells.push(cell);
    }
    Ok(cells)
}

/// `what`, one flag per lattice cell of `counts` ([nx, ny, nz]), as the numbers of the cells it
/// flags, ascending (x fastest): a flat array, or one of shape (nz, ny, nx), of booleans or of 0s
/// and 1s. Other shapes of as many values ((nx, ny, nz) would be read transposed) and other values
/// (2 is no flag) are refused. numpy finds the flagged cells: a list of one Python bool per
/// lattice cell took 8 bytes a cell more than the flags (a 400^3 lattice: 576 MB and 1.7 s, now
/// 88 MB and 0.24 s), where a sparse body on a large lattice is meant to cost its few cells.
pub fn flags(obj: &Bound<'_, PyAny>, what: &str, counts: [u32; 3]) -> PyResult<Vec<u32>> {
    refuse_masked(obj, what)?;
    let numpy = obj.py().import("numpy")?;
    let given = as_array(obj, what)?;
    let shape: Vec<usize> = given.getattr("shape")?.extract()?;
    let [nx, ny, nz] = counts.map(|n| n as usize);
    let n = nx * ny * nz;
    if shape != [n] && shape != [nz, ny, nx] {
        return Err(PyValueError::new_err(format!(
            "{what} must have shape ({n},) or (nz, ny, nx) = ({nz}, {ny}, {nx}), got {}",
            shape_of(&given)
        )));
    }
    // Complex values (1+0j passes the check below), dates, times and text, as `points` refuses
    // them.
    refuse_unreal(&given, what, "booleans, or 0s and 1s", true)?;
    let converted = contiguous(&given, "bool_").map_err(|e| naming(obj.py(), e, what))?;
    if !same_values(&converted, &given)? {
        return Err(PyValueError::new_err(format!(
            "{what} must hold booleans, or 0s and 1s (dtype {})",
            given.getattr("dtype")?.str()?
        )));
    }
    // A lattice's cells are numbered below 2^32 (`Lattice::new` refuses more nodes).
    let cells = numpy
        .call_method1("flatnonzero", (converted,))?
        .call_method1("astype", (numpy.getattr("uint32")?,))?;
    let cells = cells.extract::<PyReadonlyArray1<'_, u32>>()?;
    let cells = cells
        .as_slice()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    // Copied fallibly: a failed allocation would abort the interpreter.
    let mut flagged = Vec::new();
    flagged.try_reserve_exact(cells.len()).map_err(|_| {
        PyMemoryError::new_err(format!(
            "{what}: the {} cells flagged do not fit in memory",
            cells.len()
        ))
    })?;
    flagged.extend_from_slice(cells);
    Ok(flagged)
}
