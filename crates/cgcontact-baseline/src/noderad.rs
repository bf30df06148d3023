//! The seed's `whereami`: candidates are the cells touching a mesh node within a radius of the point.

use std::collections::HashMap;

use cgcontact::glam::DVec3;
use cgcontact::hex8::{Hex8Map, Kernel, Status};
use cgcontact::{
    Answer, Body, CORNER_OFFSETS, CellId, Error, Hit, Locator, Owners, PointError, Settings,
};
use smallvec::SmallVec;

use crate::common::{Cells, Collect, owners_of, try_in_order};
use crate::seed_newton::seed_eval_loc_coords;

/// How [`NodeRadius`] chooses its search radius.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum RadiusRule {
    /// The minimum node-to-node distance of the deformed mesh over all pairs of nodes of active cells:
    /// the seed's intent (`Radius.m`). Computed exactly with a grid of buckets, in about O(nodes).
    #[default]
    GlobalMin,
    /// What the seed's `Radius.m` literally returns: its loop overwrites `radius` on every node, so the
    /// result is the **last** node's minimum distance to the others (last in ascending lattice node
    /// order here).
    SeedLiteral,
    /// A fixed radius in the body's length unit (finite, ≥ 0).
    Fixed(f64),
}

/// Which Newton inverts the candidates of [`NodeRadius`].
///
/// Not to be confused with [`cgcontact::hex8::Inversion`], the outcome of one inversion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Inversion {
    /// The core's kernel with the settings' precision and tolerances, like every other strategy.
    #[default]
    Exact,
    /// The seed's own Newton ([`seed_eval_loc_coords`]): from ξ = 0, stop when the physical residual
    /// is at most 0.1 absolute, inside when every |ξ| ≤ 1; f64 whatever the settings' precision.
    SeedFaithful,
}

/// Options of [`NodeRadius`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NodeRadiusOptions {
    /// How the search radius is chosen.
    pub radius: RadiusRule,
    /// Which Newton inverts the candidates.
    pub inversion: Inversion,
}

/// Candidate cells of one query; spills to the heap only for large radii.
type Candidates = SmallVec<[CellId; 32]>;

/// The seed's filter ("node-radius", `whereami` of the 2019 thesis): the candidates of a point are
/// the active cells having a deformed node within [`NodeRadius::radius`] of it, found like the seed
/// by a linear scan over **every** node (O(nodes) per point), tried in ascending cell order (what
/// MATLAB's `find(any(ismember(Topology, NodeCell)))` yields); the first inside wins.
///
/// The radius is no bound on how far a point inside a cell can lie from every node of it: even an
/// undeformed lattice with h_z < h_x / 2 loses its cell centres, and a distorted cell loses more
/// (docs/baselines.md counts the misses). Not provably complete.
#[derive(Clone, Debug)]
pub struct NodeRadius<'a> {
    cells: Cells<'a>,
    /// Lattice index of each node of an active cell, ascending.
    nodes: Vec<usize>,
    /// Deformed position of each of those nodes relative to the lattice origin.
    positions: Vec<DVec3>,
    radius: f64,
    options: NodeRadiusOptions,
}

impl<'a> NodeRadius<'a> {
    /// The seed's filter with the global minimum node distance as radius and the exact Newton.
    ///
    /// Errors when the settings are out of range.
    pub fn new(body: &'a Body, settings: Settings) -> Result<Self, Error> {
        Self::with_options(body, settings, NodeRadiusOptions::default())
    }

    /// The seed's filter with chosen radius rule and inversion.
    ///
    /// Errors when the settings are out of range or a fixed radius is not finite and non-negative.
    pub fn with_options(
        body: &'a Body,
        settings: Settings,
        options: NodeRadiusOptions,
    ) -> Result<Self, Error> {
        let cells = Cells::new(body, settings)?;
        let lattice = body.lattice();
        let nodes: Vec<usize> = body.nodes().collect();
        let positions: Vec<DVec3> = nodes
            .iter()
            .zip(body.displacements())
            .map(|(&node, &u)| {
                let ijk = lattice
                    .node_ijk(node)
                    .expect("body nodes are lattice nodes");
                lattice.node_position(ijk) - lattice.origin() + u
            })
            .collect();
        let radius = match options.radius {
            RadiusRule::GlobalMin => global_min_distance(&positions),
            RadiusRule::SeedLiteral => last_node_min_distance(&positions),
            RadiusRule::Fixed(r) if r.is_finite() && r >= 0.0 => r,
            RadiusRule::Fixed(r) => {
                return Err(Error::InvalidSettings(format!(
                    "node radius {r} must be finite and ≥ 0"
                )));
            }
        };
        Ok(Self {
            cells,
            nodes,
            positions,
            radius,
            options,
        })
    }

    /// The search radius in force.
    #[must_use]
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The options in force.
    #[must_use]
    pub fn options(&self) -> &NodeRadiusOptions {
        &self.options
    }

    /// The settings in force.
    #[must_use]
    pub fn settings(&self) -> &Settings {
        self.cells.settings()
    }

    /// Candidate cells of `x`, ascending: a linear scan over every node, like the seed's `NodeRad`.
    fn candidates(&self, x: DVec3) -> Candidates {
        let lattice = self.cells.lattice();
        let counts = lattice.cells();
        let p = x - lattice.origin();
        let mut found = Candidates::new();
        for (&node, position) in self.nodes.iter().zip(&self.positions) {
            if position.distance(p) > self.radius {
                continue;
            }
            let ijk = lattice
                .node_ijk(node)
                .expect("body nodes are lattice nodes");
            for offset in CORNER_OFFSETS {
                // The cells having this node as their corner `offset`.
                let cell_ijk: [u32; 3] = std::array::from_fn(|a| ijk[a].wrapping_sub(offset[a]));
                if (0..3).all(|a| cell_ijk[a] < counts[a]) {
                    let cell = lattice.cell_id(cell_ijk);
                    if self.cells.body().is_active(cell) {
                        found.push(cell);
                    }
                }
            }
        }
        found.sort_unstable();
        found.dedup();
        found
    }

    fn search(&self, x: DVec3, collect: &mut Collect<'_>) -> Answer {
        let options = self.cells.options(x)?;
        let candidates = self.candidates(x);
        Ok(match self.options.inversion {
            Inversion::Exact => self.cells.search(x, &options, candidates, collect),
            Inversion::SeedFaithful => {
                try_in_order(candidates, collect, |cell| self.invert_seed(cell, x))
            }
        })
    }

    /// The seed's Newton on `cell`, in the cell's local frame.
    fn invert_seed(&self, cell: CellId, x: DVec3) -> Option<Hit> {
        let (_, low, u) = self.cells.local(cell);
        let map = Hex8Map::lattice_cell(self.cells.lattice().h(), &u);
        let inversion = seed_eval_loc_coords(&map, x - low);
        (inversion.status == Status::Inside).then_some(Hit {
            cell,
            xi: inversion.xi,
            iterations: inversion.iterations,
            residual: inversion.residual,
            inversions: 0,
        })
    }
}

impl Locator for NodeRadius<'_> {
    fn name(&self) -> &str {
        match self.options.inversion {
            Inversion::Exact => "noderad",
            Inversion::SeedFaithful => "noderad-seed",
        }
    }

    fn locate(&self, x: DVec3) -> Answer {
        self.search(x, &mut Collect::First)
    }

    fn locate_owners(&self, x: DVec3) -> Result<Owners, PointError> {
        owners_of(|collect| self.search(x, collect).map(drop))
    }
}

/// The seed's `Radius.m` as written: the last node's minimum distance to the others.
fn last_node_min_distance(positions: &[DVec3]) -> f64 {
    match positions.split_last() {
        Some((last, others)) if !others.is_empty() => others
            .iter()
            .map(|p| p.distance(*last))
            .fold(f64::INFINITY, f64::min),
        _ => 0.0,
    }
}

/// The minimum distance over all pairs of `positions` (exact; 0 for fewer than two).
///
/// Buckets of side `d0`, any pair's distance (the first two points'), shrunk to the smallest distance
/// seen between consecutive points (in lattice order these are mostly lattice neighbours, so `d0` is of
/// the order of the answer and buckets hold few points). Every pair closer than `d0` lies in
/// neighbouring buckets, so scanning the 27 neighbours of each bucket finds the minimum.
fn global_min_distance(positions: &[DVec3]) -> f64 {
    if positions.len() < 2 {
        return 0.0;
    }
    let d0 = positions
        .windows(2)
        .map(|w| w[0].distance(w[1]))
        .fold(f64::INFINITY, f64::min);
    // Coincident nodes (or a non-finite distance, which valid bodies never have) end the search.
    if d0.is_nan() || d0 <= 0.0 {
        return d0.max(0.0);
    }
    let key = |p: DVec3| (p / d0).floor().as_i64vec3().to_array();
    let mut buckets: HashMap<[i64; 3], Vec<u32>> = HashMap::with_capacity(positions.len());
    for (i, &p) in positions.iter().enumerate() {
        buckets.entry(key(p)).or_default().push(i as u32);
    }
    let mut best = d0;
    for (i, &p) in positions.iter().enumerate() {
        let [kx, ky, kz] = key(p);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let Some(bucket) = buckets.get(&[kx + dx, ky + dy, kz + dz]) else {
                        continue;
                    };
                    for &j in bucket {
                        if (j as usize) > i {
                            best = best.min(p.distance(positions[j as usize]));
                        }
                    }
                }
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// O(n²) reference.
    fn all_pairs(positions: &[DVec3]) -> f64 {
        let mut best = f64::INFINITY;
        for (i, p) in positions.iter().enumerate() {
            for q in &positions[i + 1..] {
                best = best.min(p.distance(*q));
            }
        }
        best
    }

    #[test]
    fn global_min_equals_all_pairs() {
        // A scrambled cloud with one close pair far apart in index order.
        let mut positions: Vec<DVec3> = (0..400u32)
            .map(|i| {
                let f = f64::from(i);
                DVec3::new(
                    (f * 0.618_033).fract() * 7.0,
                    (f * 0.414_213).fract() * 5.0,
                    (f * 0.732_050).fract() * 3.0,
                )
            })
            .collect();
        positions[17] = positions[311] + DVec3::new(1e-3, -2e-3, 5e-4);
        assert_eq!(global_min_distance(&positions), all_pairs(&positions));
        assert_eq!(global_min_distance(&positions[..1]), 0.0);
    }

    #[test]
    fn seed_literal_is_the_last_nodes_minimum() {
        let positions = [DVec3::ZERO, DVec3::X * 0.1, DVec3::X * 5.0];
        assert_eq!(last_node_min_distance(&positions), 4.9);
        assert_eq!(global_min_distance(&positions), 0.1);
    }
}
