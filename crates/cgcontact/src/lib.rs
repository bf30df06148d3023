//! # cgcontact
//!
//! Contact search for the Cartesian grid Finite Element Method (cgFEM): given points and a body meshed
//! on a cartesian lattice of hexahedra and then deformed, find **which deformed hexahedron holds each
//! point and at which local coordinates ξ ∈ [−1, 1]³**.
//!
//! | piece | what it is |
//! |---|---|
//! | [`Lattice`] | origin, spacing, cell counts; all index arithmetic (nothing stored per node) |
//! | [`Body`] | a lattice, its active cells and one displacement per node of an active cell, in memory that grows with the cells, not the lattice |
//! | [`hex8`] | trilinear map, Jacobian and the safeguarded Newton inversion, in f64 and f32 from one source |
//! | [`LatticeLocator`] | hashes a point to its lattice cell and inverts only the few neighbours that can hold it; complete for any valid mesh |
//! | [`Locator`] | the trait every strategy implements (the baselines crate adds the seed's filters, an R-tree and brute force) |
//! | [`Settings`] | precision, Newton tolerance, iteration limit, inside tolerance, candidate order, [`Schedule`] of the batched queries |
//!
//! ```
//! use cgcontact::{Body, Lattice, LatticeLocator, Locator, Settings};
//! use glam::DVec3;
//!
//! // A 4 × 4 × 4 block of 0.25-wide cells, squeezed a little along z.
//! let lattice = Lattice::new(DVec3::ZERO, DVec3::splat(0.25), [4, 4, 4])?;
//! let mut body = Body::full(lattice);
//! body.update_displacements(|_node, x, u| *u = DVec3::new(0.0, 0.0, -0.05 * x.z * x.x))?;
//!
//! let locator = LatticeLocator::new(&body, Settings::default())?;
//! let hit = locator.locate(DVec3::new(0.6, 0.3, 0.2)).expect("finite point").expect("inside");
//! println!("{} at ξ = {}", hit.cell, hit.xi);
//! assert!(hit.xi.abs().max_element() <= 1.0);
//!
//! // Between solver iterations: update displacements in place, rebuild the (cheap) locator.
//! body.update_displacements(|_node, x, u| *u = DVec3::new(0.0, 0.0, -0.08 * x.z * x.x))?;
//! let answers = LatticeLocator::new(&body, Settings::default())?.locate_all(&[DVec3::splat(0.5), DVec3::splat(9.0)]);
//! assert!(answers[0].unwrap().is_some() && answers[1].unwrap().is_none());
//! # Ok::<(), cgcontact::Error>(())
//! ```
#![deny(missing_docs)]
#![deny(unsafe_code)]

pub mod adaptive;
mod body;
mod error;
pub mod gap;
pub mod hex8;
mod idmap;
mod lanes;
mod lattice;
mod locate;
mod memory;
mod reach;
mod schedule;
mod settings;

pub use adaptive::{AdaptiveBody, AdaptiveLocator, Leaf};
pub use body::Body;
pub use error::{Error, MAX_DISPLACEMENT, PointError};
pub use gap::{Contact, Face, GapAnswer, GapFinder, Surface};
pub use glam;
pub use lattice::{CORNER_OFFSETS, CellId, Lattice};
pub use locate::{Answer, Hit, LatticeLocator, Locator, Owners};
pub use schedule::Schedule;
pub use settings::{CandidateOrder, Frame, InsideTolerance, Precision, Settings};

/// The README's examples, compiled and run as doctests so that it cannot drift from the code.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
struct ReadmeDoctests;
