//! Reading and writing VTK meshes and CSV points/results (filled by issue 4).
#![deny(missing_docs)]
#![forbid(unsafe_code)]
