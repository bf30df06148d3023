//! Python bindings of cgcontact: contact search on cartesian hexahedral lattices, numpy in and
//! numpy out.
//!
//! The module `cgcontact` holds `Body`, `Locator` and `read_mesh`; `cgcontact.pyi` documents
//! them for Python. Built with maturin as an abi3 wheel (`pip install ./crates/cgcontact-py`)
//! and tested with pytest (`tests/`), outside the Rust workspace.

#![forbid(unsafe_code)]

mod arrays;
mod body;
mod locator;

use std::ffi::CString;

use cgcontact_io::{DEFAULT_DISPLACEMENT, DisplacementArray, ErrorKind, MeshBody, read_hex_mesh};
use pyo3::exceptions::{PyIsADirectoryError, PyOSError, PyUserWarning, PyValueError};
use pyo3::prelude::*;

use crate::body::{PyBody, value_error};
use crate::locator::PyLocator;

/// Reads a VTK mesh of hexahedra (legacy .vtk or XML .vtu) whose nodes lie on a cartesian
/// lattice, or whose cells are dyadic refinements of one, as `cgcontact locate --mesh` does.
/// `displacement` names the point-data array of displacements: by default "displacement" if
/// the file has one (else the body is undeformed); another name must be in the file; None reads
/// the mesh undeformed. Cells are numbered by their place in the file and `set_displacements`
/// takes one row per node of the file. An adaptive mesh whose hanging nodes break their
/// constraint gives a warning, or a ValueError with `strict`. A file the operating system
/// refuses (missing, unreadable, a folder) raises the OSError of its errno (FileNotFoundError,
/// PermissionError, IsADirectoryError...); a file that is not a usable mesh, a ValueError.
#[pyfunction]
#[pyo3(
    signature = (path, displacement = Some(DEFAULT_DISPLACEMENT.to_owned()), strict = false),
    // The default as Python writes it: pyo3 shows a default it cannot evaluate as `...`.
    text_signature = "(path, displacement='displacement', strict=False)"
)]
fn read_mesh(
    py: Python<'_>,
    path: std::path::PathBuf,
    displacement: Option<String>,
    strict: bool,
) -> PyResult<PyBody> {
    let array = match displacement {
        None => DisplacementArray::Ignore,
        Some(name) if name == DEFAULT_DISPLACEMENT => DisplacementArray::Default,
        Some(name) => DisplacementArray::Named(name),
    };
    let (mesh, found) = py
        .detach(|| {
            let mesh = read_hex_mesh(&path, &array)?;
            let found = mesh.to_body().map_err(|e| e.in_file(&path))?;
            Ok::<_, cgcontact_io::IoError>((mesh, found))
        })
        .map_err(read_error)?;
    // The command line's message and per-axis tolerance, word for word.
    if let MeshBody::Adaptive(adaptive) = &found
        && let Some(message) = adaptive.constraint_problem(&path)
    {
        if strict {
            return Err(PyValueError::new_err(message));
        }
        let message = CString::new(message).unwrap_or_default();
        PyErr::warn(py, &py.get_type::<PyUserWarning>(), &message, 1)?;
    }
    Ok(PyBody::from_mesh(&mesh, found))
}

/// A mesh that cannot be read: an OSError where the operating system refused the file (Python
/// picks its subclass from the errno: FileNotFoundError, PermissionError, IsADirectoryError...,
/// with `errno`, `strerror` and `filename` set), else a ValueError with the command line's message.
fn read_error(e: cgcontact_io::IoError) -> PyErr {
    let ErrorKind::Io(io) = e.kind() else {
        return value_error(e);
    };
    let path = e.path().as_os_str().to_os_string();
    if let Some(errno) = io.raw_os_error() {
        let words = std::io::Error::from_raw_os_error(errno).to_string();
        let words = words
            .strip_suffix(&format!(" (os error {errno})"))
            .unwrap_or(&words)
            .to_owned();
        return PyOSError::new_err((errno, words, path));
    }
    // A folder is refused by the reader before the system is asked to read it; Python's `open`
    // says EISDIR (21 on Linux, macOS and Windows' C runtime).
    if io.kind() == std::io::ErrorKind::IsADirectory {
        const EISDIR: i32 = 21;
        return PyIsADirectoryError::new_err((EISDIR, "Is a directory", path));
    }
    value_error(e)
}

/// The address of the first value the bindings read for `points`: the array's own buffer when
/// it is read in place (a C-contiguous float64 array), else that of the converted copy. For tests
/// that check an array is not copied.
#[pyfunction]
fn _data_address(points: &Bound<'_, PyAny>) -> PyResult<usize> {
    let (rows, _) = arrays::rows(points, "points", false)?;
    let vectors = rows.vectors()?;
    Ok(vectors.as_ptr() as usize)
}

/// Contact search on cartesian hexahedral lattices: numpy in, numpy out.
///
/// Find the hexahedron of a deformed body holding each point and its local coordinates xi in
/// [-1, 1]^3 (VTK corner 0 at (-1, -1, -1)), every cell holding a point, and signed gaps to the
/// body's deformed boundary surface. Queries release the GIL; C-contiguous, aligned float64
/// (n, 3) arrays are read in place (do not write to them from another thread while a call
/// runs), anything else array-like is converted once; an empty list is no points. Complex,
/// boolean (but for `Body`'s `active` flags), text, date and time arrays, object arrays holding
/// text, booleans, complex numbers, None or numpy dates and times, and masked arrays with masked
/// values, raise ValueError rather than being cast, as do Python ints beyond float64 (or, for
/// `hexes`, int64). Errors name the argument at fault.
///
/// `Body` holds a deformed body (`Body(origin, spacing, counts)`, `Body.from_hexes` or
/// `read_mesh`); `Locator(body)` searches it. `cgcontact.pyi` gives every signature.
#[pymodule]
fn cgcontact(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyBody>()?;
    m.add_class::<PyLocator>()?;
    m.add_function(wrap_pyfunction!(read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(_data_address, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
