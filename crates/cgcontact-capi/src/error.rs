//! Error codes, the thread-local last-error message, and the guard that keeps panics on the Rust
//! side of the boundary.

use std::any::Any;
use std::cell::RefCell;
use std::ffi::{CString, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};

use cgcontact::glam::DVec3;

/// What a call returns: `CGC_ERROR_OK` (0) on success, else why it failed. The message of the last
/// failure on the calling thread is `cgc_last_error()`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CgcError {
    /// Success.
    Ok = 0,
    /// A required pointer argument was NULL.
    NullPointer = 1,
    /// An argument is out of its range: a setting, a flag, an index, a misaligned array, an empty body.
    InvalidArgument = 2,
    /// An array's length does not match what the body or the call needs.
    LengthMismatch = 3,
    /// A NaN or infinite value in a lattice, node coordinates or displacements (nothing was changed).
    NonFinite = 4,
    /// The nodes and cells given are not a lattice body: off-lattice nodes, a cell that is not one
    /// lattice cube in VTK corner order (on an adaptive mesh: a cell whose size is no level's, or
    /// not aligned to its level's lattice), duplicate or overlapping cells, coinciding nodes that
    /// disagree.
    NotLattice = 5,
    /// Some query points have a NaN or infinite coordinate. Every output is still written: those
    /// points have status `CGC_POINT_NON_FINITE`, the others their answers.
    NonFinitePoint = 6,
    /// A bug in cgcontact (a Rust panic, caught at the boundary). Please report the message.
    Panic = 7,
    /// Displacements of an adaptive body whose hanging nodes break their constraint (the deformed
    /// mesh would gap or overlap): the message names how many, the worst node and by how much.
    /// Nothing was changed. Pass `CGC_FILL_HANGING` to have the hanging nodes filled instead.
    HangingConstraint = 8,
}

/// A failed call: its code and message.
#[derive(Debug)]
pub(crate) struct Failure {
    pub code: CgcError,
    pub message: String,
}

impl Failure {
    pub(crate) fn new(code: CgcError, message: impl Into<String>) -> Self {
        Self {
            code,
            message: message.into(),
        }
    }
}

impl From<cgcontact::Error> for Failure {
    fn from(e: cgcontact::Error) -> Self {
        let code = match e {
            cgcontact::Error::LengthMismatch { .. } => CgcError::LengthMismatch,
            cgcontact::Error::NonFiniteDisplacement { .. } => CgcError::NonFinite,
            _ => CgcError::InvalidArgument,
        };
        Self::new(code, e.to_string())
    }
}

impl From<cgcontact_io::ErrorKind> for Failure {
    fn from(e: cgcontact_io::ErrorKind) -> Self {
        use cgcontact_io::ErrorKind as K;
        let code = match e {
            K::NonFiniteNode { .. } | K::NonFiniteDisplacement { .. } => CgcError::NonFinite,
            K::MissingNode { .. } | K::NoCells | K::Empty | K::Topology(_) => {
                CgcError::InvalidArgument
            }
            K::Mismatch(_) => CgcError::LengthMismatch,
            K::Core(ref core) => Failure::from(core.clone()).code,
            _ => CgcError::NotLattice,
        };
        Self::new(code, e.to_string())
    }
}

/// A number for a message, as the CSV files write it ([`cgcontact_io::Num`]): as `{}` writes it,
/// but with an exponent outside [1e-4, 1e16) (1e300, not the 301 digits `{}` gives; 1e-300, not
/// 300 zeros).
pub(crate) fn number(v: f64) -> String {
    cgcontact_io::Num(v).to_string()
}

/// A vector for a message, each component as [`number`] writes it: "[1e300, NaN, 0.5]".
pub(crate) fn shown(v: DVec3) -> String {
    let [x, y, z] = v.to_array().map(number);
    format!("[{x}, {y}, {z}]")
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

/// What `cgc_last_error` answers on a thread whose storage is being destroyed (a call from an
/// `atexit` handler or a thread-local destructor), where no message can be kept.
const NO_STORAGE: &std::ffi::CStr =
    c"the message is lost: the calling thread's storage is being destroyed (a call at exit)";

/// Records `message` as this thread's last error (interior NUL bytes, which no message of ours
/// holds, are dropped rather than truncating it). On a thread whose storage is being destroyed
/// the message is dropped: the call still returns its code.
pub(crate) fn set_last_error(message: &str) {
    let text = CString::new(message.replace('\0', "")).unwrap_or_default();
    let _ = LAST_ERROR.try_with(|last| {
        if let Ok(mut last) = last.try_borrow_mut() {
            *last = text;
        }
    });
}

/// The message of the last failed call on the calling thread, or "" when none failed yet. The
/// string belongs to the library and stays valid until the next failing call on this thread.
/// Thread-safe: each thread has its own message. Calls made while the thread's storage is being
/// destroyed (from an `atexit` handler or a thread-local destructor) still return their codes,
/// but their messages are lost: a fixed message says so.
#[unsafe(no_mangle)]
pub extern "C" fn cgc_last_error() -> *const c_char {
    catch_unwind(|| {
        LAST_ERROR
            .try_with(|last| last.borrow().as_ptr())
            .unwrap_or(NO_STORAGE.as_ptr())
    })
    .unwrap_or(c"".as_ptr())
}

/// Runs the body of an entry point: a panic becomes `CgcError::Panic`, an error its code, and either
/// sets the thread's last-error message. Nothing unwinds into the caller.
pub(crate) fn guard(f: impl FnOnce() -> Result<(), Failure>) -> CgcError {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(())) => CgcError::Ok,
        Ok(Err(failure)) => {
            set_last_error(&failure.message);
            failure.code
        }
        Err(payload) => {
            set_last_error(&format!(
                "internal error in cgcontact (please report): {}",
                panic_message(payload.as_ref())
            ));
            CgcError::Panic
        }
    }
}

/// The text of a panic's payload.
fn panic_message(payload: &(dyn Any + Send)) -> &str {
    if let Some(s) = payload.downcast_ref::<&str>() {
        s
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s
    } else {
        "a panic without a message"
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::CStr;

    fn last() -> String {
        // SAFETY: cgc_last_error returns a NUL-terminated string owned by this thread.
        unsafe { CStr::from_ptr(cgc_last_error()) }
            .to_string_lossy()
            .into_owned()
    }

    #[test]
    fn a_panic_becomes_an_error_code_with_its_message() {
        let code = guard(|| panic!("boom {}", 7));
        assert_eq!(code, CgcError::Panic);
        assert!(last().contains("boom 7"), "{}", last());
    }

    #[test]
    fn messages_are_per_thread() {
        guard(|| Err(Failure::new(CgcError::InvalidArgument, "here")));
        std::thread::spawn(|| assert_eq!(last(), ""))
            .join()
            .unwrap();
        assert_eq!(last(), "here");
    }
}
