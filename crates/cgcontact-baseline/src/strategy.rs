//! Every search strategy by name: what the command line's `--strategy`, the tradeoff report and
//! the Python module build, in one place.

use cgcontact::{AdaptiveLocator, Error, LatticeLocator, Locator, Settings};

use crate::{BodyRef, BruteForce, CentroidRadius, Inversion, NodeRadius, NodeRadiusOptions, RTree};

/// A search strategy: the lattice locator (this project) or one of the baselines.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Strategy {
    /// The lattice locator ([`LatticeLocator`], [`AdaptiveLocator`] on an adaptive body).
    Lattice,
    /// FEAVOX's centroid-radius filter ([`CentroidRadius`]).
    Centroid,
    /// The seed's node-radius filter with the exact Newton ([`NodeRadius`]).
    Noderad,
    /// The seed's node-radius filter with the seed's own Newton ([`Inversion::SeedFaithful`]).
    NoderadSeed,
    /// An R-tree over deformed cell bounding boxes ([`RTree`]).
    Rtree,
    /// Every cell: the oracle ([`BruteForce`]).
    Brute,
}

impl Strategy {
    /// Every strategy, in the order the command line lists them.
    pub const ALL: [Self; 6] = [
        Self::Lattice,
        Self::Centroid,
        Self::Noderad,
        Self::NoderadSeed,
        Self::Rtree,
        Self::Brute,
    ];

    /// Its name, as the command line's `--strategy` spells it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Lattice => "lattice",
            Self::Centroid => "centroid",
            Self::Noderad => "noderad",
            Self::NoderadSeed => "noderad-seed",
            Self::Rtree => "rtree",
            Self::Brute => "brute",
        }
    }

    /// The strategy named `name` ([`Strategy::name`]), if any.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// The strategy over `body` with `settings`.
    ///
    /// # Errors
    /// When the strategy refuses the settings or the body (as its `new` does).
    pub fn build<'a>(
        self,
        body: BodyRef<'a>,
        settings: Settings,
    ) -> Result<Box<dyn Locator + 'a>, Error> {
        let node_radius = |inversion| {
            NodeRadius::with_options(
                body,
                settings,
                NodeRadiusOptions {
                    inversion,
                    ..Default::default()
                },
            )
        };
        Ok(match self {
            Self::Lattice => match body {
                BodyRef::Uniform(body) => Box::new(LatticeLocator::new(body, settings)?),
                BodyRef::Adaptive(body) => Box::new(AdaptiveLocator::new(body, settings)?),
            },
            Self::Brute => Box::new(BruteForce::new(body, settings)?),
            Self::Centroid => Box::new(CentroidRadius::new(body, settings)?),
            Self::Noderad => Box::new(node_radius(Inversion::Exact)?),
            Self::NoderadSeed => Box::new(node_radius(Inversion::SeedFaithful)?),
            Self::Rtree => Box::new(RTree::new(body, settings)?),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cgcontact::glam::DVec3;
    use cgcontact::{Body, Lattice};

    #[test]
    fn every_name_comes_back_and_every_strategy_builds_its_own_kind() {
        let body = Body::full(Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 2, 2]).unwrap());
        let mut names = Vec::new();
        for strategy in Strategy::ALL {
            assert_eq!(Strategy::from_name(strategy.name()), Some(strategy));
            let built = strategy
                .build(BodyRef::Uniform(&body), Settings::default())
                .unwrap();
            names.push(built.name().to_owned());
            let hit = built.locate(DVec3::splat(0.5)).unwrap().unwrap();
            assert_eq!(hit.cell.index(), 0, "{}", strategy.name());
        }
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), Strategy::ALL.len(), "{names:?}");
        assert_eq!(Strategy::from_name("noderad_seed"), None);
    }
}
