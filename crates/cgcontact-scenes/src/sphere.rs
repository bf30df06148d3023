//! The seed's case and its generalisations: a block on a lattice, indented by a sphere.

use bitvec::vec::BitVec;
use cgcontact::glam::DVec3;
use cgcontact::{Body, Error, Lattice};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::field::Indentation;
use crate::known::{KnownPoint, known_points};

/// Mixed into the seed for the jitter's random stream (the known points use the seed itself).
pub(crate) const JITTER_STREAM: u64 = 0x6a17_7e12;

/// A generated scene: a deformed body, query points, and the known answers where they exist.
/// `B` is the body: a uniform [`Body`], or an adaptive one ([`crate::AdaptiveScene`]).
#[derive(Clone, Debug)]
pub struct Scene<B = Body> {
    /// Short name ("sphere-fine", "sphere-adaptive", ...).
    pub name: String,
    /// The deformed block.
    pub body: B,
    /// The sphere's contact points (no known answer: check them against the brute-force oracle).
    pub contact_points: Vec<DVec3>,
    /// Points made from known (cell, ξ) in the deformed block (on adaptive bodies, `cell` is the
    /// leaf's id).
    pub known: Vec<KnownPoint>,
    /// The sphere (center, radius), for pictures.
    pub sphere: (DVec3, f64),
}

impl<B> Scene<B> {
    /// Every query point: the contact points, then the known points.
    #[must_use]
    pub fn all_points(&self) -> Vec<DVec3> {
        self.contact_points
            .iter()
            .copied()
            .chain(self.known.iter().map(|k| k.x))
            .collect()
    }
}

/// The seed's case, with every knob a user of the benchmarks asks for.
///
/// A `block` (5 × 10 × 5 mm in the seed) meshed on a lattice of spacing `h`, its top face indented by a
/// sphere of radius `radius` pressed `penetration` below the undeformed top. The block's displacement is
/// an analytic smooth indentation ([`Indentation`]) whose largest sink is `sink_in_h · h_z`; its width
/// grows with the sink so that the cells stay valid. The sphere's surface carries `contact_points`
/// points (a Fibonacci lattice); the part of its cap below the deformed top lies inside the block.
#[derive(Clone, Debug, PartialEq)]
pub struct SphereOnBlock {
    /// Size of the block.
    pub block: DVec3,
    /// Lattice spacing per axis (anisotropic allowed).
    pub h: DVec3,
    /// Sphere radius.
    pub radius: f64,
    /// How far the sphere's lowest point lies below the undeformed top face.
    pub penetration: f64,
    /// Largest sink of the top face, in units of h_z ("displacement amplitude"; up to several h).
    pub sink_in_h: f64,
    /// Random nodal jitter, in units of h per axis (0 = none). Kept to det J > 0 unless `allow_inverted`.
    pub jitter: f64,
    /// Keep inverted cells that the jitter makes (for tests of invalid meshes).
    pub allow_inverted: bool,
    /// Number of points on the sphere.
    pub contact_points: usize,
    /// Number of points made from known (cell, ξ).
    pub known_points: usize,
    /// Every coordinate is offset by this (after scaling).
    pub offset: DVec3,
    /// Every length is multiplied by this.
    pub scale: f64,
    /// Seed of the jitter and the known points.
    pub seed: u64,
}

impl SphereOnBlock {
    /// The seed's fine mesh: 5 × 10 × 5 mm block, h = 0.25 mm (20 × 40 × 20 cells), sphere of radius
    /// 1 mm pressed 0.25 mm in, top sinking 0.45 h, 6,700 contact points and 10,000 known points.
    #[must_use]
    pub fn fine() -> Self {
        Self {
            block: DVec3::new(5.0, 10.0, 5.0),
            h: DVec3::splat(0.25),
            radius: 1.0,
            penetration: 0.25,
            sink_in_h: 0.45,
            jitter: 0.0,
            allow_inverted: false,
            contact_points: 6_700,
            known_points: 10_000,
            offset: DVec3::ZERO,
            scale: 1.0,
            seed: 2019,
        }
    }

    /// The seed's coarse mesh: the same block with h = 0.5 mm (10 × 20 × 10 cells).
    #[must_use]
    pub fn coarse() -> Self {
        Self {
            h: DVec3::splat(0.5),
            sink_in_h: 0.225,
            ..Self::fine()
        }
    }

    /// The lattice (scaled and offset) and the indentation field of these knobs: what the uniform
    /// and the adaptive scenes share. Errors when the knobs make no lattice.
    pub(crate) fn lattice_and_field(&self) -> Result<(Lattice, Indentation), Error> {
        let s = self.scale;
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::InvalidLattice(format!(
                "scale {s} must be finite and positive"
            )));
        }
        let h = self.h * s;
        let counts = (self.block / self.h).round();
        if !(counts.is_finite() && counts.min_element() >= 1.0 && counts.max_element() < 1e6) {
            return Err(Error::InvalidLattice(format!(
                "block {} with spacing {} makes no lattice",
                self.block, self.h
            )));
        }
        let cells = [counts.x as u32, counts.y as u32, counts.z as u32];
        let lattice = Lattice::new(self.offset, h, cells)?;
        let upper = lattice.upper();
        let sink = self.sink_in_h * h.z;
        // A width of 2.5 sinks keeps the largest slope of the field near 0.3 (valid cells); never
        // narrower than half the sphere's radius, the contact patch's scale.
        let field = Indentation {
            center: (lattice.origin() + upper) * 0.5,
            width: (0.5 * self.radius * s).max(2.5 * sink),
            depth: sink,
            top: upper.z,
            bottom: lattice.origin().z,
        };
        Ok((lattice, field))
    }

    /// The sphere's center over the indentation `field`, scaled and offset.
    pub(crate) fn sphere_center(&self, field: &Indentation) -> DVec3 {
        let s = self.scale;
        DVec3::new(
            field.center.x,
            field.center.y,
            field.top + self.radius * s - self.penetration * s,
        )
    }

    /// Build the scene. Errors when the knobs make no lattice (e.g. a non-positive spacing) or, without
    /// `allow_inverted`, when the indentation alone inverts cells (too large a sink for the spacing).
    pub fn build(&self, name: &str) -> Result<Scene, Error> {
        let (lattice, field) = self.lattice_and_field()?;
        let s = self.scale;
        let mut body = Body::undeformed(lattice, BitVec::repeat(true, lattice.cell_count()))?;
        body.update_displacements(|_, x, u| *u = field.displacement(x))?;
        if !self.allow_inverted {
            body.validate()?;
        }
        if self.jitter > 0.0 {
            self.apply_jitter(&mut body)?;
        }
        let center = self.sphere_center(&field);
        let contact_points = fibonacci_sphere(center, self.radius * s, self.contact_points);
        let known = known_points(&body, self.known_points, self.seed);
        Ok(Scene {
            name: name.to_owned(),
            body,
            contact_points,
            known,
            sphere: (center, self.radius * s),
        })
    }

    /// Random nodal jitter of up to `jitter` h per axis. Unless inverted cells are allowed, the jitter of
    /// every node of an inverted cell is halved until none is left (deterministic, a few rounds).
    fn apply_jitter(&self, body: &mut Body) -> Result<(), Error> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ JITTER_STREAM);
        let h = body.lattice().h();
        let smooth = body.displacements().to_vec();
        let mut jitter: Vec<DVec3> = (0..smooth.len())
            .map(|_| {
                let r = DVec3::new(
                    rng.random_range(-1.0..=1.0),
                    rng.random_range(-1.0..=1.0),
                    rng.random_range(-1.0..=1.0),
                );
                r * h * self.jitter
            })
            .collect();
        let node_slots: Vec<usize> = body.nodes().collect();
        for _round in 0..60 {
            let u: Vec<DVec3> = smooth.iter().zip(&jitter).map(|(a, b)| *a + *b).collect();
            body.set_displacements(&u)?;
            let inverted = body.inverted_cells();
            if self.allow_inverted || inverted.is_empty() {
                return Ok(());
            }
            let lattice = *body.lattice();
            for (cell, _) in inverted {
                let ijk = lattice
                    .cell_ijk(cell)
                    .expect("inverted cells are lattice cells");
                for node in lattice.corner_nodes(ijk) {
                    if let Ok(slot) = node_slots.binary_search(&node) {
                        jitter[slot] *= 0.5;
                    }
                }
            }
        }
        body.validate()
    }
}

/// `n` points spread evenly over a sphere (a Fibonacci lattice), deterministic.
#[must_use]
pub fn fibonacci_sphere(center: DVec3, radius: f64, n: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            center + radius * DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// An indented block of `cells` cells of spacing `h` with `points` known points: the scalable scene of
/// the benchmarks (e.g. 40 × 80 × 40 = 128,000 cells with 1 M points). The top sinks by 0.45 h_z.
pub fn indented_block(cells: [u32; 3], h: DVec3, points: usize, seed: u64) -> Result<Scene, Error> {
    let block = h * DVec3::new(cells[0] as f64, cells[1] as f64, cells[2] as f64);
    let scene = SphereOnBlock {
        block,
        h,
        radius: 0.2 * block.min_element(),
        contact_points: 0,
        known_points: points,
        seed,
        ..SphereOnBlock::fine()
    };
    scene.build(&format!("block-{}x{}x{}", cells[0], cells[1], cells[2]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use cgcontact::{LatticeLocator, Locator, Settings};

    #[test]
    fn the_seeds_case_has_a_few_hundred_points_in_the_block() {
        let scene = SphereOnBlock::fine().build("sphere-fine").unwrap();
        assert_eq!(scene.body.lattice().cells(), [20, 40, 20]);
        assert_eq!(scene.contact_points.len(), 6_700);
        let locator = LatticeLocator::new(&scene.body, Settings::default()).unwrap();
        let inside = scene
            .contact_points
            .iter()
            .filter(|&&x| locator.locate(x).unwrap().is_some())
            .count();
        assert!((100..1_000).contains(&inside), "{inside} points inside");
        let sink = locator.max_displacement().z / 0.25;
        assert!((sink - 0.45).abs() < 1e-9, "sink {sink} h");
    }

    #[test]
    fn knobs_keep_cells_valid_and_answers_known() {
        let knobs = SphereOnBlock {
            h: DVec3::new(0.25, 0.5, 0.125),
            sink_in_h: 3.0,
            jitter: 0.3,
            offset: DVec3::splat(1e6),
            scale: 1e-3,
            contact_points: 100,
            known_points: 500,
            ..SphereOnBlock::coarse()
        };
        let scene = knobs.build("knobs").unwrap();
        scene.body.validate().unwrap();
        let locator = LatticeLocator::new(&scene.body, Settings::default()).unwrap();
        // The points themselves are only known to eps·|x| = eps·(offset / h) in ξ units.
        let bound = 4.0 * f64::EPSILON * 1e6 / scene.body.lattice().h().min_element();
        for k in &scene.known {
            let hit = locator.locate(k.x).unwrap().expect("known point found");
            // ξ drawn uniformly: on a face only with probability zero, so the owner is unique.
            assert_eq!(hit.cell, k.cell);
            assert!(
                (hit.xi - k.xi).abs().max_element() < bound,
                "{} > {bound}",
                hit.xi - k.xi
            );
        }
    }

    #[test]
    fn inverted_cells_only_when_asked() {
        let wild = SphereOnBlock {
            jitter: 0.9,
            known_points: 0,
            ..SphereOnBlock::coarse()
        };
        wild.build("kept-valid").unwrap().body.validate().unwrap();
        let inverted = SphereOnBlock {
            allow_inverted: true,
            ..wild
        }
        .build("inverted")
        .unwrap();
        assert!(!inverted.body.inverted_cells().is_empty());
    }
}
