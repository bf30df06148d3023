//! Calls made while the calling thread's storage is being torn down (a C program's `atexit`
//! handler, a `pthread_key_create` destructor, a C++ `thread_local` destructor): a failure there
//! is still an error code, never an abort. Its own test binary, since a regression aborts the
//! process rather than failing one test.

use std::ffi::CStr;
use std::ptr;
use std::sync::atomic::{AtomicI32, Ordering};

use cgcontact_capi::*;

/// The code of the call made from the destructor, and whether it had a message (-1: not run).
static CODE: AtomicI32 = AtomicI32::new(-1);
static HAS_MESSAGE: AtomicI32 = AtomicI32::new(-1);

/// Makes a failing call when dropped, that is when the thread's storage is destroyed.
struct FailOnDrop;

impl Drop for FailOnDrop {
    fn drop(&mut self) {
        let (mut cell, mut xi) = (0i64, [0.0; 3]);
        // SAFETY: a NULL locator is what is tested; the outputs hold one point's answer.
        let code = unsafe {
            cgc_locate(
                ptr::null(),
                ptr::null(),
                0,
                &mut cell,
                xi.as_mut_ptr(),
                ptr::null_mut(),
            )
        };
        CODE.store(code as i32, Ordering::SeqCst);
        // SAFETY: cgc_last_error returns a NUL-terminated string owned by the library.
        let message = unsafe { CStr::from_ptr(cgc_last_error()) };
        HAS_MESSAGE.store(i32::from(!message.is_empty()), Ordering::SeqCst);
    }
}

thread_local! {
    static LATE: FailOnDrop = const { FailOnDrop };
}

/// The library's last-error message was stored in thread-local storage that is destroyed before
/// destructors registered earlier run: recording the failure panicked outside the panic guard,
/// and a panic cannot unwind out of an `extern "C"` function, so the process aborted.
#[test]
fn a_failure_while_the_thread_exits_is_an_error_code() {
    std::thread::spawn(|| {
        // Registered first, so destroyed after the library's message (destructors run last
        // registered first).
        LATE.with(|_| {});
        // SAFETY: cgc_last_error takes no argument; a failing call makes the library's storage.
        unsafe {
            assert_eq!(
                cgc_body_node_count(ptr::null(), ptr::null_mut()),
                CgcError::NullPointer
            );
            assert!(!CStr::from_ptr(cgc_last_error()).is_empty());
        }
    })
    .join()
    .unwrap();
    assert_eq!(CODE.load(Ordering::SeqCst), CgcError::NullPointer as i32);
    assert_eq!(HAS_MESSAGE.load(Ordering::SeqCst), 1, "no message");
}
