//! Scene generators with known answers: bodies on a lattice, analytic displacement fields (no
//! finite-element solve: only what a scene needs), and query points built from known (cell, ξ).
//!
//! ```
//! use cgcontact::{LatticeLocator, Locator, Settings};
//! use cgcontact_scenes::SphereOnBlock;
//!
//! let scene = SphereOnBlock { known_points: 100, ..SphereOnBlock::coarse() }.build("sphere-coarse")?;
//! let locator = LatticeLocator::new(&scene.body, Settings::default())?;
//! for k in &scene.known {
//!     assert_eq!(locator.locate(k.x).unwrap().unwrap().cell, k.cell);
//! }
//! # Ok::<(), cgcontact::Error>(())
//! ```
#![deny(missing_docs)]
#![forbid(unsafe_code)]

mod field;
mod known;
mod sphere;

pub use field::Indentation;
pub use known::{KnownPoint, known_points};
pub use sphere::{Scene, SphereOnBlock, fibonacci_sphere, indented_block};
