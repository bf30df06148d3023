//! Scene generators with known answers: bodies on a lattice, analytic displacement fields (no
//! finite-element solve: only what a scene needs), and query points built from known (cell, ξ).
#![deny(missing_docs)]
#![forbid(unsafe_code)]

mod field;
mod known;

pub use field::Indentation;
pub use known::{KnownPoint, known_points};
