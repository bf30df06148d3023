//! # cgcontact-baseline
//!
//! Every strategy the lattice locator ([`cgcontact::LatticeLocator`]) is measured against, behind the
//! same [`Locator`](cgcontact::Locator) trait, so that one benchmark and one test harness treat them
//! all alike. All of them invert candidates with the core's hex8 kernel ([`cgcontact::hex8`]) in the
//! candidate cell's local frame, with the allowances of
//! [`InsideTolerance`](cgcontact::InsideTolerance), so they agree with the lattice locator on
//! what "inside" means; only [`Inversion::SeedFaithful`] uses the seed's own
//! Newton ([`seed_eval_loc_coords`]).
//!
//! Every strategy searches a uniform [`Body`](cgcontact::Body) or an h-adaptive
//! [`AdaptiveBody`](cgcontact::AdaptiveBody) ([`BodyRef`]: constructors take either reference). Cells
//! are lattice [`CellId`](cgcontact::CellId)s of a uniform body's active cells, or an adaptive body's
//! leaf ids (position in [`AdaptiveBody::leaves`](cgcontact::AdaptiveBody::leaves)), as
//! [`AdaptiveLocator`](cgcontact::AdaptiveLocator) reports them; on an adaptive body the inside
//! tolerance is the adaptive locator's (from the finest spacing). The filters' radii are per
//! refinement level (the uniform rule applied to each level's leaves); docs/baselines.md says how.
//!
//! | strategy | [`Locator::name`](cgcontact::Locator::name) | candidates of a point | order tried | complete? | cost per point |
//! |---|---|---|---|---|---|
//! | [`BruteForce`] | `brute` | every cell (active cell or leaf) | ascending cell | yes (the test oracle) | O(cells) inversions |
//! | [`CentroidRadius`] (FEAVOX's original filter) | `centroid` | cells whose deformed centroid is within a radius (default: largest deformed half-diagonal of the cell's level) | nearest centroid first | no | O(cells) distances |
//! | [`NodeRadius`] (the seed's `whereami`) | `noderad`, `noderad-seed` | cells having a deformed corner within the minimum node distance of the cell's level ([`RadiusRule`]) | ascending cell | no | O(nodes) distances |
//! | [`RTree`] (rstar over deformed cell boxes) | `rtree` | cells whose widened bounding box holds the point | ascending cell | yes | O(log cells) + a few inversions |
//!
//! Where strategies answer one cell for a point shared by several (a face, edge or node), brute force
//! and the R-tree answer the lowest cell id among the owners; `locate_owners` gives all of them.
//! docs/baselines.md counts where the seed's filters miss or pick a wrong cell.
//!
//! ```
//! use cgcontact::glam::DVec3;
//! use cgcontact::{Body, Lattice, LatticeLocator, Locator, Settings};
//! use cgcontact_baseline::{BruteForce, CentroidRadius, Inversion, NodeRadius, NodeRadiusOptions, RTree};
//!
//! let lattice = Lattice::new(DVec3::ZERO, DVec3::splat(0.25), [4, 4, 4])?;
//! let mut body = Body::full(lattice);
//! body.update_displacements(|_node, x, u| *u = DVec3::new(0.0, 0.0, -0.05 * x.z * x.x))?;
//! let settings = Settings::default();
//!
//! let seed = NodeRadiusOptions { inversion: Inversion::SeedFaithful, ..Default::default() };
//! let strategies: Vec<Box<dyn Locator + '_>> = vec![
//!     Box::new(LatticeLocator::new(&body, settings)?),
//!     Box::new(BruteForce::new(&body, settings)?),
//!     Box::new(CentroidRadius::new(&body, settings)?),
//!     Box::new(NodeRadius::new(&body, settings)?),
//!     Box::new(NodeRadius::with_options(&body, settings, seed)?),
//!     Box::new(RTree::new(&body, settings)?),
//! ];
//! let x = DVec3::new(0.6, 0.3, 0.2);
//! for strategy in &strategies {
//!     let hit = strategy.locate(x).expect("finite point").expect("inside the body");
//!     println!("{:>12}: {} at ξ = {:.3} after {} inversion(s)", strategy.name(), hit.cell, hit.xi, hit.inversions);
//! }
//! let exact = strategies[1].locate(x).unwrap().unwrap();
//! assert_eq!(strategies[5].locate(x).unwrap().unwrap().cell, exact.cell);
//! # Ok::<(), cgcontact::Error>(())
//! ```
#![deny(missing_docs)]
#![forbid(unsafe_code)]

mod brute;
mod centroid;
mod common;
mod noderad;
mod rtree;
mod seed_newton;
mod strategy;

pub use brute::BruteForce;
pub use centroid::CentroidRadius;
pub use common::BodyRef;
pub use noderad::{Inversion, NodeRadius, NodeRadiusOptions, RadiusRule};
pub use rtree::RTree;
pub use seed_newton::{SEED_MAX_ITER, SEED_TOL, seed_eval_loc_coords};
pub use strategy::Strategy;
