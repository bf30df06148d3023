//! The seed's `whereami`: candidates are the cells touching a mesh node within a radius of the point.

use std::collections::HashMap;

use cgcontact::glam::DVec3;
use cgcontact::hex8::{Hex8Map, Kernel, Status};
use cgcontact::{
    Answer, Body, CORNER_OFFSETS, CellId, Error, Hit, Locator, Owners, PointError, Settings,
};
use smallvec::SmallVec;

use crate::common::{BodyRef, Cells, Collect, owners_of, try_in_order};
use crate::seed_newton::seed_eval_loc_coords;

/// How [`NodeRadius`] chooses its search radius.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum RadiusRule {
    /// The minimum node-to-node distance of the deformed mesh over all pairs of nodes of active cells
    /// (of an adaptive body: over the nodes of each level's leaves, one radius per level): the
    /// seed's intent (`Radius.m`). Computed exactly with a grid of buckets, in about O(nodes).
    #[default]
    GlobalMin,
    /// What the seed's `Radius.m` literally returns: its loop overwrites `radius` on every node, so the
    /// result is the **last** node's minimum distance to the others (last in ascending lattice node
    /// order here; of an adaptive body: among each level's leaves' nodes, to the others of them).
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
/// the cells having a deformed node within [`NodeRadius::radius`] of it, found like the seed by a
/// linear scan over **every** node (O(nodes) per point), tried in ascending cell order (what
/// MATLAB's `find(any(ismember(Topology, NodeCell)))` yields); the first inside wins.
///
/// The radius is no bound on how far a point inside a cell can lie from every node of it: even an
/// undeformed lattice with h_z < h_x / 2 loses its cell centres, and a distorted cell loses more
/// (docs/baselines.md counts the misses). Not provably complete.
///
/// **Adaptive bodies**: the nodes of a leaf are its 8 corners (a hanging node is a node of the finer
/// leaves it is a corner of, not of the coarser leaf whose edge or face it lies on). The radius rule
/// is applied to each level apart, over the nodes of that level's leaves, as if they were a uniform
/// body; a leaf is a candidate when one of its corners lies within its level's radius
/// ([`NodeRadius::level_radius`]). The finest leaves' minimum node distance for every leaf would
/// lose most of a coarse leaf's volume: its centre lies √3/2 of its edge from every corner. A fixed
/// radius is the same for every level.
#[derive(Clone, Debug)]
pub struct NodeRadius<'a> {
    cells: Cells<'a>,
    /// Deformed position of each node of a cell relative to the lattice origin, ascending node
    /// order.
    positions: Vec<DVec3>,
    /// How a node's cells are found.
    topology: Topology<'a>,
    /// The search radius of each level (one entry for a uniform body).
    radii: Vec<f64>,
    options: NodeRadiusOptions,
}

/// The cells having each node as a corner.
#[derive(Clone, Debug)]
enum Topology<'a> {
    /// A uniform body and each node's lattice index; a node's cells follow from the lattice, as in
    /// the seed.
    Lattice { body: &'a Body, nodes: Vec<usize> },
    /// An adaptive body: the leaves of node n are `leaves[first[n]..first[n + 1]]`, and `reach[n]`
    /// is the largest radius over them (a node farther from the point is skipped).
    Leaves {
        first: Vec<u32>,
        leaves: Vec<CellId>,
        reach: Vec<f64>,
    },
}

impl<'a> NodeRadius<'a> {
    /// The seed's filter with the global minimum node distance as radius and the exact Newton, over
    /// `body`, a `&Body` or a `&AdaptiveBody`.
    ///
    /// Errors when the settings are out of range.
    pub fn new(body: impl Into<BodyRef<'a>>, settings: Settings) -> Result<Self, Error> {
        Self::with_options(body, settings, NodeRadiusOptions::default())
    }

    /// The seed's filter with chosen radius rule and inversion.
    ///
    /// Errors when the settings are out of range or a fixed radius is not finite and non-negative.
    pub fn with_options(
        body: impl Into<BodyRef<'a>>,
        settings: Settings,
        options: NodeRadiusOptions,
    ) -> Result<Self, Error> {
        let body = body.into();
        let cells = Cells::new(body, settings)?;
        let rule = |positions: &[DVec3]| match options.radius {
            RadiusRule::GlobalMin => Ok(global_min_distance(positions)),
            RadiusRule::SeedLiteral => Ok(last_node_min_distance(positions)),
            RadiusRule::Fixed(r) if r.is_finite() && r >= 0.0 => Ok(r),
            RadiusRule::Fixed(r) => Err(Error::InvalidSettings(format!(
                "node radius {r} must be finite and ≥ 0"
            ))),
        };
        let (positions, topology, radii) = match body {
            BodyRef::Uniform(body) => {
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
                let radii = vec![rule(&positions)?];
                (positions, Topology::Lattice { body, nodes }, radii)
            }
            BodyRef::Adaptive(adaptive) => {
                let levels = usize::from(adaptive.finest_level()) + 1;
                let nodes = adaptive.node_count();
                let mut positions = vec![DVec3::ZERO; nodes];
                // Which levels' leaves have each node as a corner (bit l: level l), and how many.
                let mut node_levels = vec![0u32; nodes];
                let mut first = vec![0u32; nodes + 1];
                for cell in body.cells() {
                    let corners = cells.origin_relative_corners(cell);
                    let level = body.level_of(cell);
                    let corner_nodes = adaptive
                        .cell_nodes(cell)
                        .expect("cells come from the body's leaves");
                    for (&node, position) in corner_nodes.iter().zip(corners) {
                        positions[node] = position;
                        node_levels[node] |= 1 << level;
                        first[node + 1] += 1;
                    }
                }
                for n in 0..nodes {
                    first[n + 1] += first[n];
                }
                let mut leaves = vec![CellId(0); first[nodes] as usize];
                let mut next = first.clone();
                for cell in body.cells() {
                    for node in adaptive
                        .cell_nodes(cell)
                        .expect("cells come from the body's leaves")
                    {
                        leaves[next[node] as usize] = cell;
                        next[node] += 1;
                    }
                }
                let mut radii = vec![0.0; levels];
                for (level, radius) in radii.iter_mut().enumerate() {
                    let of_level: Vec<DVec3> = (0..nodes)
                        .filter(|&n| node_levels[n] & (1 << level) != 0)
                        .map(|n| positions[n])
                        .collect();
                    if !of_level.is_empty() {
                        *radius = rule(&of_level)?;
                    }
                }
                let reach = node_levels
                    .iter()
                    .map(|&bits| {
                        (0..levels)
                            .filter(|&l| bits & (1 << l) != 0)
                            .map(|l| radii[l])
                            .fold(0.0, f64::max)
                    })
                    .collect();
                (
                    positions,
                    Topology::Leaves {
                        first,
                        leaves,
                        reach,
                    },
                    radii,
                )
            }
        };
        Ok(Self {
            cells,
            positions,
            topology,
            radii,
            options,
        })
    }

    /// The largest search radius in force (the radius of every cell of a uniform body).
    #[must_use]
    pub fn radius(&self) -> f64 {
        self.radii.iter().copied().fold(0.0, f64::max)
    }

    /// The search radius of the cells of `level` (0 where the body has no cell of that level),
    /// `None` beyond the finest level.
    #[must_use]
    pub fn level_radius(&self, level: u8) -> Option<f64> {
        self.radii.get(usize::from(level)).copied()
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
        let p = x - lattice.origin();
        let mut found = Candidates::new();
        match &self.topology {
            Topology::Lattice { body, nodes } => {
                let radius = self.radii[0];
                let counts = lattice.cells();
                for (&node, position) in nodes.iter().zip(&self.positions) {
                    if position.distance(p) > radius {
                        continue;
                    }
                    let ijk = lattice
                        .node_ijk(node)
                        .expect("body nodes are lattice nodes");
                    for offset in CORNER_OFFSETS {
                        // The cells having this node as their corner `offset`.
                        let cell_ijk: [u32; 3] =
                            std::array::from_fn(|a| ijk[a].wrapping_sub(offset[a]));
                        if (0..3).all(|a| cell_ijk[a] < counts[a]) {
                            let cell = lattice.cell_id(cell_ijk);
                            if body.is_active(cell) {
                                found.push(cell);
                            }
                        }
                    }
                }
            }
            Topology::Leaves {
                first,
                leaves,
                reach,
            } => {
                let body = self.cells.body();
                for (node, position) in self.positions.iter().enumerate() {
                    let distance = position.distance(p);
                    if distance > reach[node] {
                        continue;
                    }
                    let of_node = &leaves[first[node] as usize..first[node + 1] as usize];
                    for &cell in of_node {
                        if distance <= self.radii[usize::from(body.level_of(cell))] {
                            found.push(cell);
                        }
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
        let (low, h, u) = self.cells.local(cell);
        let map = Hex8Map::lattice_cell(h, &u);
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
/// Buckets of side 1.5 `d0`, `d0` the smallest distance between consecutive points (in lattice
/// order these are mostly lattice neighbours, so `d0` is of the order of the answer and buckets
/// hold few points). Every pair closer than `d0` lies in neighbouring buckets, so scanning the 27
/// neighbours of each bucket finds the minimum. The side is at least 2^-40 of the points' extent:
/// bucket keys stay far below 2^53, where f64 counts every bucket, and i64's range (two nodes
/// 1e-7 apart beside one moved 1e13 away made keys of 1e20, which saturated, and overflowed).
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
    let (low, high) = positions
        .iter()
        .fold((positions[0], positions[0]), |(l, h), &p| {
            (l.min(p), h.max(p))
        });
    // A pair closer than d0 is at most 2/3 of a bucket apart per axis: the roundings of the keys
    // (2^-52 of at most 2^40 buckets) cannot put it two buckets apart.
    let side = 1.5 * d0.max((high - low).max_element() * 2f64.powi(-40));
    let key = |p: DVec3| ((p - low) / side).floor().as_i64vec3().to_array();
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

    /// Two nodes 1e-7 apart and one moved 1e13 away (both within the body's limits): the
    /// bucket key of the far node, 1e20 buckets out, saturated at i64::MAX and its neighbour
    /// `key + 1` overflowed (a panic where overflow is checked, a wrong bucket elsewhere).
    #[test]
    fn far_nodes_beside_a_close_pair_keep_the_exact_minimum() {
        use cgcontact::{Body, Lattice};
        let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 1, 1]).unwrap();
        let mut body = Body::full(lattice);
        body.update_displacements(|node, _, u| match node {
            1 => *u = DVec3::new(-1.0 + 1e-7, 0.0, 0.0),
            5 => *u = DVec3::splat(1e13),
            11 => *u = DVec3::new(-1e13, 0.0, 0.0),
            _ => {}
        })
        .unwrap();
        let filter = NodeRadius::new(&body, Settings::default()).unwrap();
        assert_eq!(filter.radius(), all_pairs(&filter.positions));
        assert!(filter.radius() > 0.0 && filter.radius() < 2e-7);
        // Every node far out on both sides, a pair among them close.
        let mut far: Vec<DVec3> = (0..50)
            .map(|i| DVec3::new(1e14 * f64::from(i) - 2.5e15, 3e13, -7e13))
            .collect();
        far[31] = far[7] + DVec3::new(0.0, 1e-3, 0.0);
        assert_eq!(global_min_distance(&far), all_pairs(&far));
    }

    #[test]
    fn seed_literal_is_the_last_nodes_minimum() {
        let positions = [DVec3::ZERO, DVec3::X * 0.1, DVec3::X * 5.0];
        assert_eq!(last_node_min_distance(&positions), 4.9);
        assert_eq!(global_min_distance(&positions), 0.1);
    }
}
