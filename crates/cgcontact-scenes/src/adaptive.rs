//! The seed's case on an h-adaptive mesh: the block refined by halving under the sphere's contact
//! patch, deformed by the same analytic indentation, hanging nodes filled from their constraints.

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveBody, CellId, Error, Lattice, Leaf};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::field::Indentation;
use crate::known::{KnownPoint, LeafDraw, adaptive_known_points};
use crate::refine::{MAX_REFINED_LEAVES, check_levels, leaf_box, refine_lattice, too_many_leaves};
#[cfg(doc)]
use crate::sphere::indented_block;
use crate::sphere::{JITTER_STREAM, Scene, SphereOnBlock, fibonacci_sphere};

/// Mixed into the seed for the shuffle of [`LeafOrder::Shuffled`].
const ORDER_STREAM: u64 = 0x0dde_4a11;

/// The order of an adaptive scene's leaves (their ids).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum LeafOrder {
    /// By lowest corner on the finest lattice, z then y then x: the uniform body's cell order
    /// when there is one level.
    #[default]
    Sorted,
    /// A random permutation of the sorted order, from the scene's seed: for tests of "leaves in any
    /// order".
    Shuffled,
}

/// A generated adaptive scene: a deformed h-adaptive body (hanging nodes obeying their
/// constraints), the sphere's contact points, and points made from known (leaf, ξ), `cell` the
/// leaf's id.
pub type AdaptiveScene = Scene<AdaptiveBody>;

/// How many leaves [`SphereOnAdaptiveBlock::build`] makes, from
/// [`SphereOnAdaptiveBlock::leaf_count`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LeafCount {
    /// `build` makes `leaves` leaves, the finest of them of level `finest`.
    Exact {
        /// The leaves.
        leaves: u64,
        /// The finest level among them.
        finest: u8,
    },
    /// More than this many (the cap given): the count stopped there.
    MoreThan(u64),
}

/// The refinement rule of [`SphereOnAdaptiveBlock`]: a cell is split when its undeformed box
/// comes within `radius` (strictly) of `patch`.
#[derive(Clone, Copy, Debug)]
struct NearPatch {
    patch: DVec3,
    radius: f64,
}

impl NearPatch {
    /// Whether the cell whose box runs from `low` to `high` is split.
    fn splits(self, low: DVec3, high: DVec3) -> bool {
        (low - self.patch)
            .max(self.patch - high)
            .max(DVec3::ZERO)
            .length()
            < self.radius
    }
}

/// [`SphereOnBlock`] on an h-adaptive mesh: its lattice is the base (level 0), and every cell whose
/// undeformed box comes within `refine_radius` (strictly) of the contact patch's centre (the top
/// face's centre, under the sphere) is halved, level by level down to `levels`, so that levels
/// grow toward the patch.
///
/// The displacement is the uniform scene's field (the same [`crate::Indentation`], sink in units of the
/// base h_z) set on the independent nodes, the hanging ones filled from their constraints
/// ([`AdaptiveBody::update_independent`]); the jitter, drawn for every node in node order, is
/// applied to the independent ones only (up to `jitter` times the spacing of the finest leaf at
/// the node). With `levels` = 0 the scene is the uniform one, node for node and point for point.
#[derive(Clone, Debug, PartialEq)]
pub struct SphereOnAdaptiveBlock {
    /// The uniform scene refined: block, base h, sphere, sink, jitter, points, seed, ...
    pub uniform: SphereOnBlock,
    /// Refinement levels below the base lattice (0 = the uniform scene).
    pub levels: u8,
    /// Cells within this distance of the patch centre are refined (same units as the block).
    pub refine_radius: f64,
    /// 2:1 balance (touching leaves, by face, edge or corner, differ by one level at most), by
    /// splitting coarser neighbours; without it jumps of several levels stay where the radius
    /// makes them.
    pub balanced: bool,
    /// The order of the leaves.
    pub order: LeafOrder,
    /// How the known points pick their leaves.
    pub draw: LeafDraw,
}

impl SphereOnAdaptiveBlock {
    /// The seed's fine block (h = 0.25 mm base) refined 2 levels within 1 mm (the sphere's
    /// radius) of the patch centre, 2:1 balanced, leaves sorted, known points per leaf.
    #[must_use]
    pub fn fine() -> Self {
        Self::refining(SphereOnBlock::fine())
    }

    /// The seed's coarse block (h = 0.5 mm base), refined as [`SphereOnAdaptiveBlock::fine`].
    #[must_use]
    pub fn coarse() -> Self {
        Self::refining(SphereOnBlock::coarse())
    }

    /// `uniform` refined with the defaults: 2 levels within the sphere's radius, balanced.
    #[must_use]
    pub fn refining(uniform: SphereOnBlock) -> Self {
        Self {
            refine_radius: uniform.radius,
            uniform,
            levels: 2,
            balanced: true,
            order: LeafOrder::Sorted,
            draw: LeafDraw::PerLeaf,
        }
    }

    /// The centre of the contact patch on the undeformed top face (scaled and offset), the point
    /// the refinement closes in on. Errors when the knobs make no lattice.
    pub fn patch_center(&self) -> Result<DVec3, Error> {
        let (_, field) = self.uniform.lattice_and_field()?;
        Ok(self.rule(&field).patch)
    }

    /// The refinement rule on the scene of `field`: the patch centre and the radius, scaled.
    fn rule(&self, field: &Indentation) -> NearPatch {
        NearPatch {
            patch: DVec3::new(field.center.x, field.center.y, field.top),
            radius: self.refine_radius * self.uniform.scale,
        }
    }

    /// The leaves [`build`](Self::build) makes and the finest level among them, counted without
    /// building the scene (no body, no displacements, no points), stopping once past `cap`:
    /// [`LeafCount::MoreThan`]`(cap)` then.
    ///
    /// The refinement without the 2:1 balance is counted cell by cell, nothing stored: that is
    /// the count unbalanced, and at most the balanced one (balancing only splits more), so that
    /// knobs far beyond `cap` are told at once, however many levels. A balanced refinement within
    /// `cap` is then made as `build` makes it, leaves only (a few bytes each, where a scene takes
    /// hundreds); its count is exact even where the balance takes it past `cap`.
    ///
    /// # Errors
    ///
    /// Where `build`'s refinement fails: the knobs make no lattice, `levels` or the finest
    /// level's lattice are beyond what [`crate::refine_lattice`] takes, or the leaves would be
    /// more than [`MAX_REFINED_LEAVES`].
    pub fn leaf_count(&self, cap: u64) -> Result<LeafCount, Error> {
        let (base, field) = self.uniform.lattice_and_field()?;
        check_levels(&base, self.levels)?;
        let rule = self.rule(&field);
        let limit = cap.min(MAX_REFINED_LEAVES as u64);
        // Past `limit`: refused by the caller's cap, or by `build`'s own.
        let past_limit = || {
            if limit == cap {
                Ok(LeafCount::MoreThan(cap))
            } else {
                Err(too_many_leaves())
            }
        };
        let near = |leaf: Leaf| {
            let (low, high) = leaf_box(&base, leaf);
            rule.splits(low, high)
        };
        // Each split turns a leaf into eight.
        let mut count = base.cell_count() as u64;
        if count > limit {
            return past_limit();
        }
        let mut finest = 0;
        for level in 0..self.levels {
            let h = base.h() * 0.5f64.powi(i32::from(level));
            let n = base
                .cells()
                .map(|n| f64::from(n) * 2f64.powi(i32::from(level)));
            // The cells of the level whose box can be within the radius; NaN and infinite bounds
            // saturate in the casts.
            let range = |a: usize| {
                let from = ((rule.patch[a] - rule.radius - base.origin()[a]) / h[a]).floor() - 1.0;
                let to = ((rule.patch[a] + rule.radius - base.origin()[a]) / h[a]).ceil() + 1.0;
                (from.max(0.0) as u32)..(to.min(n[a]) as u32)
            };
            let mut split = false;
            for k in range(2) {
                for j in range(1) {
                    for i in range(0) {
                        // Split when it and every ancestor are near (each exists, its parent
                        // split).
                        let ijk = [i, j, k];
                        if (0..=level)
                            .rev()
                            .all(|l| near(Leaf::new(l, ijk.map(|v| v >> (level - l)))))
                        {
                            split = true;
                            count += 7;
                            if count > limit {
                                return past_limit();
                            }
                        }
                    }
                }
            }
            if !split {
                break;
            }
            finest = level + 1;
        }
        if !self.balanced {
            return Ok(LeafCount::Exact {
                leaves: count,
                finest,
            });
        }
        // Within `limit` unbalanced, and so the same splits below; a guard all the same, as the
        // leaves are stored: past it no more is split.
        let mut over = false;
        let mut count = base.cell_count() as u64;
        let leaves = refine_lattice(&base, self.levels, true, |leaf, _, _| {
            let split = !over && near(leaf);
            if split && count + 7 > limit {
                over = true;
                return false;
            }
            count += if split { 7 } else { 0 };
            split
        })?;
        if over {
            return past_limit();
        }
        Ok(LeafCount::Exact {
            leaves: leaves.len() as u64,
            finest: leaves.iter().map(|leaf| leaf.level).max().unwrap_or(0),
        })
    }

    /// Build the scene. Errors when the knobs make no lattice or too many leaves
    /// ([`crate::refine_lattice`]), or, without `allow_inverted`, when the indentation or the
    /// jitter leaves an inverted leaf.
    pub fn build(&self, name: &str) -> Result<AdaptiveScene, Error> {
        let knobs = &self.uniform;
        let (lattice, field) = knobs.lattice_and_field()?;
        let s = knobs.scale;
        let rule = self.rule(&field);
        let mut leaves = refine_lattice(&lattice, self.levels, self.balanced, |_, low, high| {
            rule.splits(low, high)
        })?;
        if self.order == LeafOrder::Shuffled {
            leaves.shuffle(&mut ChaCha8Rng::seed_from_u64(knobs.seed ^ ORDER_STREAM));
        }
        let mut body = AdaptiveBody::from_leaves(lattice, leaves)?;
        body.update_independent(|_, x, u| *u = field.displacement(x))?;
        if !knobs.allow_inverted {
            body.validate()?;
        }
        if knobs.jitter > 0.0 {
            self.apply_jitter(&mut body)?;
        }
        let center = knobs.sphere_center(&field);
        let contact_points = fibonacci_sphere(center, knobs.radius * s, knobs.contact_points);
        let known = adaptive_known_points(&body, knobs.known_points, self.draw, knobs.seed);
        Ok(AdaptiveScene {
            name: name.to_owned(),
            body,
            contact_points,
            known,
            sphere: (center, knobs.radius * s),
        })
    }

    /// Random jitter on the independent nodes, hanging ones filled after. Unless inverted leaves
    /// are allowed, the jitter of every independent node an inverted leaf depends on (its corners,
    /// or the parents of its hanging corners) is halved until none is left.
    fn apply_jitter(&self, body: &mut AdaptiveBody) -> Result<(), Error> {
        let knobs = &self.uniform;
        let mut rng = ChaCha8Rng::seed_from_u64(knobs.seed ^ JITTER_STREAM);
        // A node's scale is the finest leaf it is a corner of: that leaf must survive the jitter.
        let mut node_level = vec![0u8; body.node_count()];
        for (id, leaf) in body.leaves().iter().enumerate() {
            let nodes = body.cell_nodes(CellId(id as u32)).expect("a leaf id");
            for node in nodes {
                node_level[node] = node_level[node].max(leaf.level);
            }
        }
        let smooth = body.displacements().to_vec();
        let mut jitter: Vec<DVec3> = node_level
            .iter()
            .map(|&level| {
                let r = DVec3::new(
                    rng.random_range(-1.0..=1.0),
                    rng.random_range(-1.0..=1.0),
                    rng.random_range(-1.0..=1.0),
                );
                r * body.spacing(level) * knobs.jitter
            })
            .collect();
        for _round in 0..60 {
            body.update_independent(|node, _, u| *u = smooth[node] + jitter[node])?;
            let inverted = body.inverted_cells();
            if knobs.allow_inverted || inverted.is_empty() {
                return Ok(());
            }
            for (cell, _) in inverted {
                for node in body.cell_nodes(cell).expect("inverted cells are leaves") {
                    match body.constraint(node) {
                        Some(parents) => parents.iter().for_each(|&(p, _)| jitter[p] *= 0.5),
                        None => jitter[node] *= 0.5,
                    }
                }
            }
        }
        body.validate()
    }
}

/// An indented block of `cells` base cells of spacing `h` refined `levels` levels within
/// `refine_radius` of the top face's centre (2:1 balanced), with `points` known points drawn per
/// leaf: the scalable adaptive scene of the benchmarks. The sink and the sphere are
/// [`crate::indented_block`]'s; there are no contact points.
///
/// Pair it with a uniform block of about as many cells through [`block_cells_for`].
pub fn adaptive_block(
    cells: [u32; 3],
    h: DVec3,
    levels: u8,
    refine_radius: f64,
    points: usize,
    seed: u64,
) -> Result<AdaptiveScene, Error> {
    let block = h * DVec3::new(
        f64::from(cells[0]),
        f64::from(cells[1]),
        f64::from(cells[2]),
    );
    let uniform = SphereOnBlock {
        block,
        h,
        radius: 0.2 * block.min_element(),
        contact_points: 0,
        known_points: points,
        seed,
        ..SphereOnBlock::fine()
    };
    let scene = SphereOnAdaptiveBlock {
        levels,
        refine_radius,
        ..SphereOnAdaptiveBlock::refining(uniform)
    };
    scene.build(&format!(
        "adaptive-{}x{}x{}-l{levels}",
        cells[0], cells[1], cells[2]
    ))
}

/// The uniform twin of `adaptive_block(base, h, ..)` (its scene `adaptive`): the same block under
/// the same indentation (its sink in lengths, not in the twin's spacing) meshed by a uniform
/// lattice of `twin` cells, and `adaptive`'s known points carried over, each made in the twin
/// from its undeformed place (cell and ξ computed there), so both bodies answer points spread
/// alike over the same deformed block. What an adaptive body's speed is compared with when the
/// problem, not only the cell count, is the same: [`indented_block`] of as many cells sinks by
/// its own spacing and draws its points per cell, away from the indentation, where the
/// adaptive scene draws them per leaf, under it.
///
/// # Errors
/// When `base`, `h` and `twin` make no lattice, or a known point's leaf is not one of
/// `adaptive`'s.
pub fn uniform_twin(
    base: [u32; 3],
    h: DVec3,
    twin: [u32; 3],
    adaptive: &AdaptiveScene,
) -> Result<Scene, Error> {
    let counts = |c: [u32; 3]| DVec3::from(c.map(f64::from));
    let block = h * counts(base);
    let twin_h = block / counts(twin);
    let fine = SphereOnBlock::fine();
    let knobs = SphereOnBlock {
        block,
        h: twin_h,
        radius: 0.2 * block.min_element(),
        sink_in_h: fine.sink_in_h * h.z / twin_h.z,
        contact_points: 0,
        known_points: 0,
        ..fine
    };
    let mut scene = knobs.build(&format!("twin-{}x{}x{}", twin[0], twin[1], twin[2]))?;
    let body = &adaptive.body;
    let lattice = *scene.body.lattice();
    scene.known = adaptive
        .known
        .iter()
        .map(|k| {
            let leaf = body.leaves().get(k.cell.index()).ok_or_else(|| {
                Error::InvalidLattice(format!("known leaf {} is not a leaf", k.cell.index()))
            })?;
            let at = body.leaf_origin(leaf) + body.spacing(leaf.level) * (k.xi + 1.0) * 0.5;
            let t = (at - lattice.origin()) / lattice.h();
            let ijk = lattice.clamped_cell(t);
            let xi = ((t - counts(ijk)) * 2.0 - 1.0).clamp(DVec3::NEG_ONE, DVec3::ONE);
            let cell = lattice.cell_id(ijk);
            let x = scene.body.point_at(cell, xi).ok_or_else(|| {
                Error::InvalidLattice(format!("twin cell {} is inactive", cell.index()))
            })?;
            Ok(KnownPoint { x, cell, xi })
        })
        .collect::<Result<_, Error>>()?;
    Ok(scene)
}

/// The smallest body with hanging nodes: two unit base cells along x, the second refined once
/// (5 hanging nodes on the face they share), undeformed but for the first hanging node, moved `by`
/// along x off its constraint: what the readers' constraint check must report.
///
/// # Errors
/// When `by` is not finite.
pub fn hanging_node_moved(by: f64) -> Result<AdaptiveBody, Error> {
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 1, 1])?;
    let mut leaves = vec![Leaf::new(0, [0, 0, 0])];
    leaves.extend(Leaf::new(0, [1, 0, 0]).children());
    let mut body = AdaptiveBody::from_leaves(lattice, leaves)?;
    let mut u = vec![DVec3::ZERO; body.node_count()];
    if let Some(node) = body.hanging_nodes().next() {
        u[node].x = by;
    }
    body.set_displacements(&u)?;
    Ok(body)
}

/// Cells per axis of a block shaped like `shape` (its aspect ratio) with about `count` cells, at
/// least one per axis: the uniform block to compare an adaptive one of `count` leaves with.
#[must_use]
pub fn block_cells_for(count: usize, shape: DVec3) -> [u32; 3] {
    let unit = (count as f64 / (shape.x * shape.y * shape.z)).cbrt();
    (shape * unit)
        .round()
        .max(DVec3::ONE)
        .to_array()
        .map(|n| n.min(f64::from(u32::MAX)) as u32)
}
