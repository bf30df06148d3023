//! Meshes whose hexahedra have several sizes: dyadic refinements of one lattice, recognised as
//! an [`AdaptiveBody`]. A mesh whose cells all have one size stays a uniform body
//! ([`HexMesh::to_lattice`]): [`HexMesh::to_body`] chooses.
//!
//! Detection: the coarsest cells' edges give the base spacing, each cell's edges its level (the
//! base halved l times, equally on every axis), the finest level's spacing is refined from the
//! extent of the nodes (as the uniform detection does), and the base lattice's origin is placed
//! so that the coarsest cells sit on it. Every node of a cell must then be a node of the finest
//! lattice, every cell's lowest corner a node of its own level's lattice, and no two cells may
//! cover the same region. Cells and nodes may come in any order; a leaf's id is its input index.

use std::collections::HashMap;

use bitvec::vec::BitVec;
use cgcontact::adaptive::{ConstraintReport, MAX_LEVEL};
use cgcontact::{AdaptiveBody, CORNER_OFFSETS, CellId, Lattice, Leaf};
use glam::DVec3;

use crate::mesh::{
    F32_ROUNDING_SLACK, LatticeMesh, ROUNDING_SLACK, Rounding, STEP, all_f32, beyond_rounding,
    coordinate_slack, merge_displacements,
};
use crate::{CellMap, ErrorKind, HexMesh, LATTICE_TOLERANCE};

/// Ratio of the largest to the smallest cell edge (on some axis) above which a mesh is read as
/// adaptive: between 1.5 (a malformed cell of a uniform mesh, reported as such) and 2 (one level).
const LEVEL_RATIO: f64 = 1.75;

/// A mesh read from a file and recognised as an adaptive body.
#[derive(Clone, Debug)]
pub struct AdaptiveMesh {
    /// The body: base lattice, leaves (in input cell order), displacements.
    pub body: AdaptiveBody,
    /// Input cell order ↔ leaf ids: the identity (a leaf's id is its input index).
    pub cells: CellMap,
    /// Number of nodes in the input (used by cells or not).
    pub point_count: usize,
    /// Whether the input carried a displacement array (otherwise the body is undeformed).
    pub has_displacement: bool,
    /// How the hanging nodes' displacements, as read, obey their constraints (within
    /// `constraint_tolerance_by_axis`): the body keeps them as read.
    pub constraints: ConstraintReport,
    /// The tolerance of `constraints` per axis, length units: 1e-9 of the finest spacing along
    /// that axis plus the rounding of the largest displacement.
    pub constraint_tolerance_by_axis: DVec3,
    /// The smallest of `constraint_tolerance_by_axis` (the shortest axis's), for messages that
    /// give one number.
    pub constraint_tolerance: f64,
    /// How far each node of the body (slot order) lies from its lattice position, where some
    /// node lies off it by more than f64 rounding, as [`crate::LatticeMesh::node_offsets`]: the
    /// body's displacements include them. `None` where every node is at its lattice position to
    /// f64 rounding.
    pub node_offsets: Option<Vec<DVec3>>,
}

/// A mesh read from a file: a uniform lattice body or an adaptive one.
// One value per file read, held for the whole run: boxing the larger variant would save nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum MeshBody {
    /// Every cell one lattice cell.
    Uniform(LatticeMesh),
    /// Cells of several refinement levels.
    Adaptive(AdaptiveMesh),
}

impl AdaptiveMesh {
    /// What is wrong with the hanging nodes as read, for the mesh read from `path`: how many
    /// break their constraint by more than [`AdaptiveMesh::constraint_tolerance_by_axis`], and the
    /// worst one's position and offset; `None` when every one obeys it.
    #[must_use]
    pub fn constraint_problem(&self, path: &std::path::Path) -> Option<String> {
        let report = self.constraints;
        let (false, Some((node, by))) = (report.holds(), report.worst) else {
            return None;
        };
        let position = self.body.node_position(node).unwrap_or_default();
        Some(format!(
            "{}: {} of {} hanging nodes break their constraint by more than {}; the worst, at {}, by {by:.3e}: the deformed mesh gaps or overlaps there",
            path.display(),
            report.violating,
            report.hanging,
            {
                let t = self.constraint_tolerance_by_axis;
                if t.x == t.y && t.y == t.z {
                    format!("{:.1e}", t.x)
                } else {
                    format!("[{:.1e}, {:.1e}, {:.1e}] along x, y, z", t.x, t.y, t.z)
                }
            },
            position,
        ))
    }
}

impl MeshBody {
    /// Input cell order ↔ the body's cell ids.
    #[must_use]
    pub fn cells(&self) -> &CellMap {
        match self {
            Self::Uniform(m) => &m.cells,
            Self::Adaptive(m) => &m.cells,
        }
    }

    /// Whether the input carried a displacement array.
    #[must_use]
    pub fn has_displacement(&self) -> bool {
        match self {
            Self::Uniform(m) => m.has_displacement,
            Self::Adaptive(m) => m.has_displacement,
        }
    }
}

/// Edge lengths of a cell along its own axes (corner 0 to corners 1, 3 and 4).
fn edges(points: &[DVec3], cell: &[u32; 8]) -> [f64; 3] {
    [0, 1, 2].map(|a| (points[cell[STEP[a]] as usize][a] - points[cell[0] as usize][a]).abs())
}

/// [`edges`] of cell `c`, or the error naming the first corner of 1, 3 and 4 that does not
/// advance along its axis (a flat or collapsed cell, or corners out of VTK order): such a cell
/// would otherwise be blamed on another cell, or measured with an edge of 0.
fn checked_edges(points: &[DVec3], c: usize, cell: &[u32; 8]) -> Result<[f64; 3], ErrorKind> {
    let e = edges(points, cell);
    match (0..3).find(|&a| e[a] == 0.0) {
        Some(a) => Err(ErrorKind::FlatCell {
            cell: c,
            corner: STEP[a],
            axis: ["x", "y", "z"][a],
        }),
        None => Ok(e),
    }
}

impl HexMesh {
    /// Recognise the mesh as a uniform lattice body ([`HexMesh::to_lattice`]) when its cells have
    /// one size, else as an adaptive body of dyadic refinements ([`HexMesh::to_adaptive`]).
    pub fn to_body(&self) -> Result<MeshBody, ErrorKind> {
        if self.cells.is_empty() {
            return Err(ErrorKind::NoCells);
        }
        let used = self.used_nodes()?;
        let several = self
            .several_sizes()
            .map_err(|e| self.imprecise_before_detection(e, &used))?;
        if several {
            Ok(MeshBody::Adaptive(
                self.detect_rounded(&used, |rounding| self.adaptive_with(&used, rounding))?,
            ))
        } else {
            Ok(MeshBody::Uniform(self.to_lattice()?))
        }
    }

    /// Whether the cells have several sizes (an adaptive mesh), or the error naming the first cell
    /// with an edge that does not advance ([`checked_edges`]). The cells' nodes must be in range
    /// ([`HexMesh::used_nodes`]).
    fn several_sizes(&self) -> Result<bool, ErrorKind> {
        let mut low = [f64::INFINITY; 3];
        let mut high = [0.0f64; 3];
        for (c, cell) in self.cells.iter().enumerate() {
            let e = checked_edges(&self.points, c, cell)?;
            for a in 0..3 {
                low[a] = low[a].min(e[a]);
                high[a] = high[a].max(e[a]);
            }
        }
        Ok((0..3).any(|a| high[a] > LEVEL_RATIO * low[a]))
    }

    /// At most the bytes that [`HexMesh::to_body`] and then [`crate::CallerBody::mesh`] allocate,
    /// every allocation counted as though none were freed: a bound on the address space they take
    /// whatever the allocator reuses, for a binding to ask for before it builds, since a failed
    /// allocation there aborts the process. Measured with a counting allocator on blocks of 64,000
    /// to 4.5 M cells: up to 105 bytes a node and 36 a cell for cells of one size, 54 a node and
    /// 495 a cell for a block half refined once; rounded up here, plus 1 MiB for the allocator's
    /// own overhead. A mesh that detection refuses early (a node out of range) counts as uniform.
    #[must_use]
    pub fn build_bytes(&self) -> usize {
        let (nodes, cells) = (self.points.len(), self.cells.len());
        let several = self.used_nodes().is_ok() && self.several_sizes().unwrap_or(false);
        let (per_node, per_cell) = if several { (64, 512) } else { (112, 40) };
        nodes
            .saturating_mul(per_node)
            .saturating_add(cells.saturating_mul(per_cell))
            .saturating_add(1 << 20)
    }

    /// Recognise the mesh as an adaptive body (see the module docs). A mesh of one level makes a
    /// one-level adaptive body.
    pub fn to_adaptive(&self) -> Result<AdaptiveMesh, ErrorKind> {
        if self.cells.is_empty() {
            return Err(ErrorKind::NoCells);
        }
        let used = self.used_nodes()?;
        self.detect_rounded(&used, |rounding| self.adaptive_with(&used, rounding))
    }

    /// `leaves` (one per input cell) without the ghost copies ([`HexMesh::ghosts`]) of a leaf that
    /// another input cell holds: a copy of a leaf not flagged, or a later copy when all are
    /// flagged. With the input cell of each leaf kept (`None`: every one, in input order) and the
    /// map of input cells to leaves, a dropped copy mapped to the leaf it copies.
    fn without_ghost_copies(&self, leaves: Vec<Leaf>) -> (Vec<Leaf>, Option<Vec<u32>>, CellMap) {
        if self.ghosts.is_empty() {
            let cells = CellMap::identity(leaves.len());
            return (leaves, None, cells);
        }
        let ghost = |c: usize| self.ghosts.binary_search(&(c as u32)).is_ok();
        // The input cell each leaf is read as: the first copy not flagged, else the first copy.
        let mut kept_as: HashMap<Leaf, u32> = HashMap::with_capacity(self.ghosts.len());
        for (c, leaf) in leaves.iter().enumerate() {
            if ghost(c) {
                kept_as.entry(*leaf).or_insert(c as u32);
            }
        }
        for (c, leaf) in leaves.iter().enumerate() {
            if !ghost(c)
                && let Some(at) = kept_as.get_mut(leaf)
                && ghost(*at as usize)
            {
                *at = c as u32;
            }
        }
        let keep = |c: usize| !ghost(c) || kept_as.get(&leaves[c]) == Some(&(c as u32));
        let input_of_leaf: Vec<u32> = (0..leaves.len())
            .filter(|&c| keep(c))
            .map(|c| c as u32)
            .collect();
        let mut leaf_of_input = vec![CellId(u32::MAX); leaves.len()];
        for (leaf, &c) in input_of_leaf.iter().enumerate() {
            leaf_of_input[c as usize] = CellId(leaf as u32);
        }
        for c in 0..leaves.len() {
            if !keep(c) {
                leaf_of_input[c] = leaf_of_input[kept_as[&leaves[c]] as usize];
            }
        }
        let kept: Vec<Leaf> = input_of_leaf.iter().map(|&c| leaves[c as usize]).collect();
        let cells = CellMap::with_ghosts(leaf_of_input, kept.len(), &self.ghosts)
            .expect("one copy of each leaf answers, the others are ghosts");
        (kept, Some(input_of_leaf), cells)
    }

    /// [`HexMesh::to_adaptive`] for the coordinates' `rounding`.
    fn adaptive_with(&self, used: &BitVec, rounding: Rounding) -> Result<AdaptiveMesh, ErrorKind> {
        self.check_ghosts()?;
        if let Some(u) = &self.displacement
            && u.len() != self.points.len()
        {
            return Err(ErrorKind::Mismatch(format!(
                "{} displacements for {} nodes",
                u.len(),
                self.points.len()
            )));
        }
        if self.cells.len() >= 1 << 31 {
            return Err(ErrorKind::Topology(format!(
                "{} cells exceed the 2^31 an adaptive body indexes",
                self.cells.len()
            )));
        }
        // Levels from the edges, against the coarsest cells'.
        let cell_edges: Vec<[f64; 3]> = self
            .cells
            .iter()
            .enumerate()
            .map(|(c, cell)| checked_edges(&self.points, c, cell))
            .collect::<Result<_, _>>()?;
        // Every cell has the lattice's shape (edges in the ratio of its spacings); a cell of
        // another shape is named before its edges set the base spacing, which is the largest edge
        // per axis (a cell stretched along x had made every other cell look wrong). The shape
        // is the median one, within a quarter: loose enough for coordinates' rounding (each edge
        // may be off by up to a twentieth below), tight enough for a cell doubled along an axis;
        // the exact checks per cell follow.
        let shape = |e: &[f64; 3]| [e[1] / e[0], e[2] / e[0]];
        let median = |k: usize| {
            let mut v: Vec<f64> = cell_edges.iter().map(|e| shape(e)[k]).collect();
            let mid = v.len() / 2;
            *v.select_nth_unstable_by(mid, f64::total_cmp).1
        };
        let typical = [median(0), median(1)];
        let odd = cell_edges.iter().position(|e| {
            let s = shape(e);
            (0..2).any(|k| (s[k] - typical[k]).abs() > 0.25 * typical[k])
        });
        // How far cell c's edges may be from their size, relative: 1e-6 plus the rounding of the
        // coordinates (far from the origin a tiny cell's edge carries |x| ε; coordinates all
        // 32-bit floats, or printed with few digits, round by more), at most a twentieth.
        let relative_slack = |c: usize, expected: f64| {
            let magnitude = self.points[self.cells[c][0] as usize].abs().max_element();
            1e-6 + (4.0 * rounding.slack_at(magnitude) / expected).min(1.0 / 20.0)
        };
        // The cells whose x edge is the median cell's times a power of two: the others cannot
        // set the base spacing, or a cell 1.5 times the coarsest would have made every other
        // cell look wrong, and the first listed was named.
        let reference = {
            let mut order: Vec<usize> = (0..cell_edges.len()).collect();
            let mid = order.len() / 2;
            *order
                .select_nth_unstable_by(mid, |&p, &q| cell_edges[p][0].total_cmp(&cell_edges[q][0]))
                .1
        };
        let dyadic = |c: usize| {
            let ratio = cell_edges[c][0] / cell_edges[reference][0];
            let off = (ratio / ratio.log2().round().exp2() - 1.0).abs();
            off <= relative_slack(c, cell_edges[c][0])
                + relative_slack(reference, cell_edges[reference][0])
        };
        let mut base = [0.0f64; 3];
        for (c, e) in cell_edges.iter().enumerate() {
            if Some(c) != odd && dyadic(c) {
                for a in 0..3 {
                    base[a] = base[a].max(e[a]);
                }
            }
        }
        if let Some(cell) = odd {
            return Err(ErrorKind::CellSize {
                cell,
                edges: cell_edges[cell],
                base,
            });
        }
        let mut levels = Vec::with_capacity(self.cells.len());
        for (c, e) in cell_edges.iter().enumerate() {
            let bad = || ErrorKind::CellSize {
                cell: c,
                edges: *e,
                base,
            };
            let ratio = base[0] / e[0];
            if !(ratio.is_finite() && ratio >= 1.0) {
                return Err(bad());
            }
            let level = ratio.log2().round();
            if level > f64::from(MAX_LEVEL) {
                // A whole number of halvings, only too many: say so.
                let scale = 0.5f64.powf(level);
                if (0..3).all(|a| (e[a] - base[a] * scale).abs() <= 1e-6 * base[a] * scale) {
                    return Err(ErrorKind::TooDeep {
                        cell: c,
                        edges: *e,
                        base,
                        level: level as u32,
                        max: MAX_LEVEL,
                    });
                }
                return Err(bad());
            }
            let scale = 0.5f64.powi(level as i32);
            // Within `relative_slack` of the expected size: far tighter than a level apart. The
            // lattice checks below are the exact ones.
            if (0..3).any(|a| {
                let expected = base[a] * scale;
                (e[a] - expected).abs() > relative_slack(c, expected) * expected
            }) {
                return Err(bad());
            }
            levels.push(level as u8);
        }
        let finest = levels.iter().copied().max().unwrap_or(0);
        let steps = 1u64 << finest;

        // The finest lattice's spacing from the extent, as the uniform detection does, and the base
        // origin placed so that a coarsest cell sits on the base lattice.
        let mut origin = [0.0; 3];
        let mut h_fine = [0.0; 3];
        let mut counts = [0u32; 3];
        let axis_name = ["x", "y", "z"];
        for a in 0..3 {
            let estimate = base[a] / steps as f64;
            let (low, high) = self.axis_planes(used, a, 0.5 * estimate)?;
            let n = ((high - low) / estimate).round();
            if n >= f64::from(1u32 << 21) {
                return Err(ErrorKind::Degenerate(format!(
                    "the nodes span {} along {}: {n} cells of the finest level (edge {estimate}), \
                     more than the 2^21 - 1 per axis an adaptive body's finest lattice holds",
                    high - low,
                    axis_name[a]
                )));
            }
            if n.is_nan() || n < 1.0 {
                return Err(ErrorKind::Degenerate(format!(
                    "the nodes span {} along {} for a finest edge of {estimate}",
                    high - low,
                    axis_name[a]
                )));
            }
            // The extent's spacing, more precise than one cell's edge; but when it is not a whole
            // number of the edges' finest spacing (a cell off its level's lattice stretched the
            // extent), the edges' own, so that the node found off the lattice is the one at
            // fault and the spacing reported is the mesh's.
            let from_extent = (high - low) / n;
            let h = if (from_extent - estimate).abs() <= 1e-3 * estimate {
                from_extent
            } else {
                estimate
            };
            // The base lattice's phase: the offset from the lowest plane, in finest steps modulo
            // a base cell, that most level-0 cells' corner 0 have (ties: the smallest), so that a
            // misaligned level-0 cell is the one named wherever it is listed. Brought to a
            // multiple of the base spacing by moving the origin down.
            let mut phases: HashMap<i64, usize> = HashMap::new();
            for (c, &level) in levels.iter().enumerate() {
                if level == 0 {
                    let corner = self.points[self.cells[c][0] as usize][a];
                    let r = ((corner - low) / h).round() as i64;
                    *phases.entry(r.rem_euclid(steps as i64)).or_default() += 1;
                }
            }
            let phase = phases
                .into_iter()
                .max_by_key(|&(phase, count)| (count, std::cmp::Reverse(phase)))
                .map_or(0, |(phase, _)| phase);
            let k = (-phase).rem_euclid(steps as i64) as u64;
            origin[a] = low - k as f64 * h;
            h_fine[a] = h;
            counts[a] = (n as u64 + k).div_ceil(steps) as u32;
        }
        let h_base = DVec3::from_array(h_fine) * steps as f64;
        let lattice = Lattice::new(DVec3::from_array(origin), h_base, counts)?;
        let origin = lattice.origin();
        let h_fine = DVec3::from_array(h_fine);

        // Every used node on the finest lattice.
        let limit = counts.map(|n| u64::from(n) * steps);
        let magnitude = origin.abs().max(lattice.upper().abs());
        let tol = LATTICE_TOLERANCE * h_fine + coordinate_slack(rounding, magnitude, h_fine);
        let mut q = vec![[u32::MAX; 3]; self.points.len()];
        for n in used.iter_ones() {
            let p = self.points[n];
            let t = (p - origin) / h_fine;
            let i = t.round();
            let inside = (0..3).all(|a| i[a] >= 0.0 && i[a] <= limit[a] as f64);
            if !inside {
                return Err(ErrorKind::OutsideLattice {
                    node: n,
                    position: p.to_array(),
                    origin: origin.to_array(),
                    h: h_fine.to_array(),
                    nodes: limit.map(|v| (v + 1).min(u64::from(u32::MAX)) as u32),
                    index: i.to_array(),
                });
            }
            if (p - (origin + i * h_fine)).abs().cmpgt(tol).any() {
                return Err(ErrorKind::OffLattice {
                    node: n,
                    position: p.to_array(),
                    origin: origin.to_array(),
                    h: h_fine.to_array(),
                    offset: (t - i).to_array(),
                });
            }
            q[n] = [i.x as u32, i.y as u32, i.z as u32];
        }

        // Every cell one leaf: aligned to its level's lattice, corners in VTK order.
        let mut leaves = Vec::with_capacity(self.cells.len());
        for (c, cell) in self.cells.iter().enumerate() {
            let level = levels[c];
            let s = 1u32 << (finest - level);
            let low = q[cell[0] as usize];
            if low.iter().any(|&v| v % s != 0) {
                return Err(ErrorKind::NotAligned {
                    cell: c,
                    level,
                    position: self.points[cell[0] as usize].to_array(),
                    origin: origin.to_array(),
                    h: (h_base * 0.5f64.powi(i32::from(level))).to_array(),
                });
            }
            for (corner, offset) in CORNER_OFFSETS.iter().enumerate() {
                let found = q[cell[corner] as usize].map(i64::from);
                let expected: [i64; 3] =
                    std::array::from_fn(|a| i64::from(low[a]) + i64::from(offset[a] * s));
                if found != expected {
                    return Err(ErrorKind::NotLatticeCell {
                        cell: c,
                        corner,
                        node: cell[corner] as usize,
                        found,
                        expected,
                    });
                }
            }
            leaves.push(Leaf::new(level, low.map(|v| v / s)));
        }
        // Ghost copies of a leaf are read as that leaf: the body keeps one of each.
        let (leaves, input_of_leaf, cells) = self.without_ghost_copies(leaves);
        let mut body = AdaptiveBody::from_leaves(lattice, leaves).map_err(|e| match e {
            cgcontact::Error::OverlappingCells { cell, other } => ErrorKind::OverlappingCells {
                first: input_of_leaf
                    .as_ref()
                    .map_or(other.index(), |i| i[other.index()] as usize),
                second: input_of_leaf
                    .as_ref()
                    .map_or(cell.index(), |i| i[cell.index()] as usize),
            },
            e => ErrorKind::Core(e),
        })?;

        // Displacements: each body node from the input nodes at it (which must agree).
        // Per axis: an offset is a share of the cell's edge along its own axis (on a 1 : 1e-3
        // lattice the shortest axis's tolerance warned of offsets of 1e-12 of a cell along x,
        // as VTK's legacy ASCII writer leaves at its 11 digits).
        let mut constraint_tolerance = LATTICE_TOLERANCE * h_fine;
        if let Some(u) = &self.displacement {
            let by_node: Vec<(usize, usize)> = used
                .iter_ones()
                .map(|n| {
                    let node = body
                        .node_at_finest(q[n])
                        .expect("a corner of a cell is a node of the body");
                    (node, n)
                })
                .collect();
            // Copies agree to 1e-9 of the finest spacing (on its shortest axis), as hanging
            // nodes their constraints: that is the scale of the finest leaves' ξ.
            let values = merge_displacements(by_node, u, LATTICE_TOLERANCE * h_fine.min_element())?;
            debug_assert_eq!(values.len(), body.node_count());
            body.set_displacements(&values)?;
            // Displacements all 32-bit floats: a hanging node's value and its constraint differ
            // by their rounding.
            let slack = if all_f32(u) {
                F32_ROUNDING_SLACK
            } else {
                ROUNDING_SLACK
            };
            constraint_tolerance += DVec3::splat(slack * body.max_displacement().max_element());
        }
        let constraints = body.check_constraints_per_axis(constraint_tolerance);
        let node_offsets = self.add_lattice_offsets(&mut body, used, &q)?;
        // The file's mesh is conforming only to its rounding: a hanging node's coordinates (each
        // within `tol` of its lattice position, or it was refused) and displacement (within
        // `constraint_tolerance` of its constraint where it holds) put it off the coarse face
        // by up to their sum, 3e-8 of a base cell for float coordinates at a spacing of 0.1.
        // Points at it or on the fine faces beside it, as the file has them, lay that far
        // outside the coarse leaf and lost it as an owner: the locator's allowance takes the
        // seam, beyond f64 rounding, at most that bound (a node that breaks its constraint by
        // more is warned about, not covered).
        let seam = body.constraint_offsets();
        if beyond_rounding(seam, magnitude) {
            body.set_seam(seam.min(constraint_tolerance + 2.0 * tol))?;
        }
        Ok(AdaptiveMesh {
            constraints,
            constraint_tolerance_by_axis: constraint_tolerance,
            constraint_tolerance: constraint_tolerance.min_element(),
            body,
            cells,
            point_count: self.points.len(),
            has_displacement: self.displacement.is_some(),
            node_offsets,
        })
    }

    /// Adds to each node's displacement how far the file has it from its lattice position (the
    /// first input node at it; `q` every used node's finest-lattice coordinates), when one is
    /// beyond f64 rounding ([`beyond_rounding`]), so that the deformed nodes are the file's, as
    /// [`HexMesh::to_lattice`] does for uniform meshes: VTK's
    /// default float points lie up to 6e-8 of a cell off the lattice, and dropping that moved
    /// the faces off the file's (points on shared nodes and faces lost owners). A hanging node
    /// keeps its own offset too, as the file has it, so that every leaf is the file's: a point
    /// made from a leaf's corners as the file holds them is in that leaf. The hanging node then
    /// lies off the coarse face by its coordinates' rounding (6e-8 of a cell for floats at a
    /// spacing of 0.1): the file's own mesh is conforming only to that rounding. Interpolating
    /// its offset instead kept the mesh conforming but moved the fine leaves off the file's, and
    /// a tenth of the points made on their faces were in no leaf. Returns the offsets added
    /// (slot order), `None` when every one is within f64 rounding and none was added.
    fn add_lattice_offsets(
        &self,
        body: &mut AdaptiveBody,
        used: &BitVec,
        q: &[[u32; 3]],
    ) -> Result<Option<Vec<DVec3>>, ErrorKind> {
        let mut offsets = vec![DVec3::ZERO; body.node_count()];
        let mut set: BitVec = BitVec::repeat(false, offsets.len());
        for n in used.iter_ones() {
            let node = body
                .node_at_finest(q[n])
                .expect("a corner of a cell is a node of the body");
            if !set.replace(node, true) {
                let position = body
                    .node_position(node)
                    .expect("a node of the body has a position");
                offsets[node] = self.points[n] - position;
            }
        }
        let lattice = body.lattice();
        let magnitude = lattice.origin().abs().max(lattice.upper().abs());
        if !offsets.iter().any(|&o| beyond_rounding(o, magnitude)) {
            return Ok(None);
        }
        let sum: Vec<DVec3> = (body.displacements().iter())
            .zip(&offsets)
            .map(|(u, o)| *u + *o)
            .collect();
        body.set_displacements(&sum)?;
        Ok(Some(offsets))
    }
}
