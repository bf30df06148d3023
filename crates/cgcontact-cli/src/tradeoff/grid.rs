//! The grid of configurations the report measures: one [`ConfigId`] per strategy with its settings.

use cgcontact::{CandidateOrder, Settings};

use crate::run::StrategyName;

/// One configuration of the report. Its label is typed once, in [`ConfigId::label`]; everything else
/// (the targets, the plot's legend, the report's list of configurations) names it by variant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum ConfigId {
    LatticeDefault,
    LatticeTol1e6,
    LatticeTol1e14,
    LatticeMaxIter3,
    LatticeInside0,
    LatticeInside1e6,
    LatticeUndeformedOrder,
    LatticeF32,
    LatticeF32Tol1e3,
    Rtree,
    Centroid,
    NoderadExact,
    NoderadSeed,
    Brute,
}

impl ConfigId {
    /// The name of the configuration in the table, the legend and the list of configurations.
    #[must_use]
    pub(super) fn label(self) -> &'static str {
        match self {
            Self::LatticeDefault => "lattice f64 (default)",
            Self::LatticeTol1e6 => "lattice f64 tol 1e-6",
            Self::LatticeTol1e14 => "lattice f64 tol 1e-14",
            Self::LatticeMaxIter3 => "lattice f64 max_iter 3",
            Self::LatticeInside0 => "lattice f64 inside 0",
            Self::LatticeInside1e6 => "lattice f64 inside 1e-6",
            Self::LatticeUndeformedOrder => "lattice f64 undeformed order",
            Self::LatticeF32 => "lattice f32 (Settings::f32)",
            Self::LatticeF32Tol1e3 => "lattice f32 tol 1e-3",
            Self::Rtree => "rtree f64",
            Self::Centroid => "centroid f64",
            Self::NoderadExact => "noderad exact f64",
            Self::NoderadSeed => "noderad seed-faithful",
            Self::Brute => "brute f64",
        }
    }
}

/// One strategy with its settings.
#[derive(Clone, Copy, Debug)]
pub(super) struct Config {
    pub(super) id: ConfigId,
    pub(super) strategy: StrategyName,
    pub(super) settings: Settings,
}

/// The grid of configurations, in the order of the table and the plot's numbers: the lattice
/// locator's settings, then every baseline at defaults.
pub(super) fn configs() -> Vec<Config> {
    let d = Settings::default();
    let lattice = |id, settings| Config {
        id,
        strategy: StrategyName::Lattice,
        settings,
    };
    let baseline = |id, strategy| Config {
        id,
        strategy,
        settings: d,
    };
    vec![
        lattice(ConfigId::LatticeDefault, d),
        lattice(
            ConfigId::LatticeTol1e6,
            Settings {
                newton_tol: 1e-6,
                ..d
            },
        ),
        lattice(
            ConfigId::LatticeTol1e14,
            Settings {
                newton_tol: 1e-14,
                ..d
            },
        ),
        lattice(ConfigId::LatticeMaxIter3, Settings { max_iter: 3, ..d }),
        lattice(
            ConfigId::LatticeInside0,
            Settings {
                inside_tol: 0.0,
                ..d
            },
        ),
        lattice(
            ConfigId::LatticeInside1e6,
            Settings {
                inside_tol: 1e-6,
                ..d
            },
        ),
        lattice(
            ConfigId::LatticeUndeformedOrder,
            Settings {
                order: CandidateOrder::Undeformed,
                ..d
            },
        ),
        lattice(ConfigId::LatticeF32, Settings::f32()),
        lattice(
            ConfigId::LatticeF32Tol1e3,
            Settings {
                newton_tol: 1e-3,
                ..Settings::f32()
            },
        ),
        baseline(ConfigId::Rtree, StrategyName::Rtree),
        baseline(ConfigId::Centroid, StrategyName::Centroid),
        baseline(ConfigId::NoderadExact, StrategyName::Noderad),
        baseline(ConfigId::NoderadSeed, StrategyName::NoderadSeed),
        baseline(ConfigId::Brute, StrategyName::Brute),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows are found by id: an id listed twice would hide one of its rows.
    #[test]
    fn every_id_is_listed_once_with_its_own_label() {
        let configs = configs();
        for (k, config) in configs.iter().enumerate() {
            for other in &configs[k + 1..] {
                assert_ne!(config.id, other.id, "{:?} listed twice", config.id);
                assert_ne!(
                    config.id.label(),
                    other.id.label(),
                    "{:?} and {:?} share a label",
                    config.id,
                    other.id
                );
            }
        }
    }

    /// The label says the strategy and the precision that the configuration runs.
    #[test]
    fn lattice_labels_name_their_precision() {
        for config in configs() {
            let label = config.id.label();
            if config.strategy == StrategyName::Lattice {
                let precision = match config.settings.precision {
                    cgcontact::Precision::F64 => "lattice f64",
                    cgcontact::Precision::F32 => "lattice f32",
                };
                assert!(label.starts_with(precision), "{label}");
            } else {
                assert!(!label.starts_with("lattice"), "{label}");
            }
        }
    }
}
