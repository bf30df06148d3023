//! Comparison strategies behind the core's `Locator` trait (filled by issue 3).
#![deny(missing_docs)]
#![forbid(unsafe_code)]
