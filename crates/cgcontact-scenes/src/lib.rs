//! Scene generators with known answers: bodies on a lattice, analytic displacement fields (no
//! finite-element solve: only what a scene needs), and query points built from known (cell, ξ).
//!
//! | item | what |
//! |---|---|
//! | [`SphereOnBlock`] → [`Scene`] | the seed's block indented by a sphere, uniform lattice, every knob |
//! | [`SphereOnAdaptiveBlock`] → [`AdaptiveScene`] | the same block refined by halving under the contact patch (levels, radius, 2:1 balanced or not), hanging nodes filled from their constraints |
//! | [`SphereOnAdaptiveBlock::leaf_count`] → [`LeafCount`] | the leaves an adaptive scene would have, counted without building it |
//! | [`indented_block`], [`adaptive_block`], [`block_cells_for`], [`uniform_twin`] | scalable uniform and adaptive blocks for benchmarks, a uniform block as large as an adaptive one, and one answering the same problem |
//! | [`refine_lattice`] | the leaves of any refinement of a lattice by a split predicate, balanced or not |
//! | [`known_points`], [`adaptive_known_points`] | points made from known (cell, ξ): per cell, per leaf or by volume ([`LeafDraw`]) |
//! | [`Indentation`], [`fibonacci_sphere`] | the analytic field and the sphere's contact points |
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
//!
//! The adaptive scene: the coarse block refined two levels under the sphere, each known point
//! found in its leaf.
//!
//! ```
//! use cgcontact::{AdaptiveLocator, Locator, Settings};
//! use cgcontact_scenes::{SphereOnAdaptiveBlock, SphereOnBlock};
//!
//! let knobs = SphereOnAdaptiveBlock {
//!     levels: 2,
//!     balanced: true,
//!     ..SphereOnAdaptiveBlock::refining(SphereOnBlock { known_points: 100, ..SphereOnBlock::coarse() })
//! };
//! let scene = knobs.build("sphere-adaptive")?;
//! assert_eq!(scene.body.finest_level(), 2);
//! assert!(scene.body.check_constraints(1e-12).holds());
//! let locator = AdaptiveLocator::new(&scene.body, Settings::default())?;
//! for k in &scene.known {
//!     assert_eq!(locator.locate(k.x).unwrap().unwrap().cell, k.cell);
//! }
//! # Ok::<(), cgcontact::Error>(())
//! ```
#![deny(missing_docs)]
#![forbid(unsafe_code)]

mod adaptive;
mod field;
mod known;
mod refine;
mod sphere;

pub use adaptive::{
    AdaptiveScene, LeafCount, LeafOrder, SphereOnAdaptiveBlock, adaptive_block, block_cells_for,
    hanging_node_moved, uniform_twin,
};
pub use field::Indentation;
pub use known::{KnownPoint, LeafDraw, adaptive_known_points, known_points};
pub use refine::{MAX_REFINED_LEAVES, leaf_box, refine_lattice};
pub use sphere::{Scene, SphereOnBlock, fibonacci_sphere, indented_block};
