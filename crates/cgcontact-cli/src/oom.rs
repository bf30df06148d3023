//! Running out of memory ends a run as any other error does: one line on stderr, exit code 2, no
//! temporary file left beside an output, and the folders made for the run removed while empty.
//!
//! Rust's own answer to a failed allocation prints `memory allocation of N bytes failed` and
//! aborts: exit code 134 (SIGABRT), a core dump where they are enabled, and the temporary file of
//! any write in progress left behind. That is what a mesh larger than the memory a run may take
//! got: `cgcontact scene block --cells 100,100,100` writes a 163 MB `mesh.vtu`, and `locate` on
//! it under `ulimit -v 800000` aborted while reading it. The hook the standard library has for
//! this (`std::alloc::set_alloc_error_hook`) is unstable, so the program's allocator is the
//! system's behind [`ExitOnOom`], which sees each failure before the standard library does.
//!
//! The wrapper cannot tell a failure that its caller handles (`Vec::try_reserve`) from one that
//! would abort, so every failure ends the run here. In this program both end it anyway: the
//! library's fallible buffers (a body's, `cgcontact::Error::OutOfMemory`) and the reader's
//! (`read_to_end`, LZMA blocks) are errors the run stops on, with exit code 2; only their
//! message becomes this module's.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// The system allocator, ending the run with exit code 2 when an allocation fails ([`failed`]).
pub struct ExitOnOom;

// SAFETY: every method forwards its arguments unchanged to `System`, whose methods have the same
// contracts, so each requirement the caller meets for `ExitOnOom` it meets for `System`, and each
// pointer `System` returns is returned as it is (memory `ExitOnOom` hands out is `System`'s, and
// goes back to `System`). A null pointer is never returned: [`failed`] does not return. Nothing
// here unwinds: `failed` writes with `let _ =` (no panic on a closed stderr) and ends in
// `exit` or `abort`, neither of which unwinds.
unsafe impl GlobalAlloc for ExitOnOom {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's guarantees for `alloc` (a layout of non-zero size), forwarded.
        let block = unsafe { System.alloc(layout) };
        if block.is_null() {
            failed(layout.size());
        }
        block
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as `alloc`.
        let block = unsafe { System.alloc_zeroed(layout) };
        if block.is_null() {
            failed(layout.size());
        }
        block
    }

    unsafe fn realloc(&self, block: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's guarantees for `realloc` (`block` allocated by this allocator, so
        // by `System`, with `layout`; `new_size` valid for its alignment), forwarded.
        let moved = unsafe { System.realloc(block, layout, new_size) };
        if moved.is_null() {
            failed(new_size);
        }
        moved
    }

    unsafe fn dealloc(&self, block: *mut u8, layout: Layout) {
        // SAFETY: the caller's guarantees for `dealloc` (`block` allocated by this allocator, so
        // by `System`, with `layout`), forwarded.
        unsafe { System.dealloc(block, layout) }
    }
}

/// Set by the first thread whose allocation failed: that thread ends the run.
static FAILING: AtomicBool = AtomicBool::new(false);

thread_local! {
    /// Whether this thread is ending the run in [`failed`]: a second failure there (its cleanup
    /// allocates a little) aborts, since it cannot be handled twice.
    static ENDING: Cell<bool> = const { Cell::new(false) };
}

/// Ends the run after an allocation of `bytes` failed: removes the temporary file of each write in
/// progress (outputs stay as they were, or whole) and the folders made for the run while empty,
/// says so in one line, and exits with code 2, as `main` does on any error. A second thread whose
/// allocation fails meanwhile waits for the first to end the process.
fn failed(bytes: usize) -> ! {
    if ENDING.with(Cell::get) {
        std::process::abort();
    }
    if FAILING.swap(true, Ordering::SeqCst) {
        loop {
            std::thread::sleep(Duration::from_secs(1));
        }
    }
    ENDING.with(|ending| ending.set(true));
    // This thread may hold the list of writes (registering one) or of folders: neither waits.
    let _ = cgcontact_io::abandon_writes_within(Duration::from_millis(200));
    crate::output::try_remove_made_folders();
    let _ = writeln!(
        std::io::stderr(),
        "cgcontact: error: out of memory: {bytes} more bytes ({:.1} MiB) could not be allocated; \
         outputs not yet complete were left as they were",
        bytes as f64 / (1u64 << 20) as f64
    );
    std::process::exit(2);
}
