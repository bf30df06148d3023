//! The report's scenes and their reference answers, each obtained independently of the locators.

use anyhow::{Result, anyhow, bail};
use cgcontact::glam::DVec3;
use cgcontact::hex8::{Hex8Map, Kernel, NewtonOptions};
use cgcontact::{AdaptiveBody, Body, CellId, Locator, Settings};
use cgcontact_baseline::{BodyRef, BruteForce};
use cgcontact_scenes::{SphereOnAdaptiveBlock, SphereOnBlock, indented_block};

/// The expected answer for one point.
#[derive(Clone, Copy, Debug)]
pub(super) struct Reference {
    pub(super) cell: CellId,
    pub(super) xi: DVec3,
}

/// A scene's body: uniform or adaptive.
pub(super) enum SceneBody {
    Uniform(Body),
    Adaptive(AdaptiveBody),
}

impl SceneBody {
    pub(super) fn as_ref(&self) -> BodyRef<'_> {
        match self {
            Self::Uniform(b) => b.into(),
            Self::Adaptive(b) => b.into(),
        }
    }

    /// Cells searched: active cells or leaves.
    pub(super) fn cell_count(&self) -> usize {
        self.as_ref().cell_count()
    }

    /// The smallest cell edge.
    pub(super) fn h_min(&self) -> f64 {
        match self {
            Self::Uniform(b) => b.lattice().h().min_element(),
            Self::Adaptive(b) => b.spacing(b.finest_level()).min_element(),
        }
    }

    /// A cell's trilinear map in its local frame, and that frame's origin.
    pub(super) fn cell_map(&self, cell: CellId) -> Option<(Hex8Map, DVec3)> {
        match self {
            Self::Uniform(b) => b.cell_map(cell),
            Self::Adaptive(b) => b.cell_map(cell),
        }
    }
}

/// A scene of the report: a body, its query points and their expected answers (`None`: outside).
pub(super) struct TradeScene {
    pub(super) name: &'static str,
    pub(super) what: String,
    pub(super) body: SceneBody,
    pub(super) points: Vec<DVec3>,
    pub(super) reference: Vec<Option<Reference>>,
}

impl TradeScene {
    fn from_known(name: &'static str, what: String, scene: cgcontact_scenes::Scene) -> Self {
        Self::known_in(name, what, SceneBody::Uniform(scene.body), &scene.known)
    }

    fn known_in(
        name: &'static str,
        what: String,
        body: SceneBody,
        known: &[cgcontact_scenes::KnownPoint],
    ) -> Self {
        let points = known.iter().map(|k| k.x).collect();
        let reference = known
            .iter()
            .map(|k| {
                Some(Reference {
                    cell: k.cell,
                    xi: k.xi,
                })
            })
            .collect();
        Self {
            name,
            what,
            body,
            points,
            reference,
        }
    }
}

/// Build the scenes; the sphere's reference is brute force in f64 on `pool`.
pub(super) fn scenes(quick: bool, pool: &rayon::ThreadPool) -> Result<Vec<TradeScene>> {
    let h8 = DVec3::splat(0.125);
    let (known, block_points, small, big) = if quick {
        (400, 4_000, [5, 10, 5], [10, 20, 10])
    } else {
        (10_000, 1_000_000, [10, 20, 10], [40, 80, 40])
    };
    let base = if quick {
        SphereOnBlock {
            contact_points: 600,
            ..SphereOnBlock::coarse()
        }
    } else {
        SphereOnBlock::fine()
    };
    let mesh = if quick { "coarse" } else { "fine" };
    let cells = |c: [u32; 3]| c[0] * c[1] * c[2];
    let mut out = vec![
        TradeScene::from_known(
            "fine",
            format!("the seed's {mesh} block, {known} known points"),
            SphereOnBlock {
                contact_points: 0,
                known_points: known,
                ..base.clone()
            }
            .build("fine")?,
        ),
        TradeScene::from_known(
            "fine-jitter",
            format!("{mesh} block + nodal jitter ±0.3 h, {known} known points"),
            SphereOnBlock {
                contact_points: 0,
                known_points: known,
                jitter: 0.3,
                ..base.clone()
            }
            .build("fine-jitter")?,
        ),
        TradeScene::from_known(
            "block-small",
            format!(
                "indented block {}×{}×{} = {} cells (h 0.125), {block_points} known points",
                small[0],
                small[1],
                small[2],
                cells(small)
            ),
            indented_block(small, h8, block_points, 11)?,
        ),
        TradeScene::from_known(
            "block-big",
            format!(
                "indented block {}×{}×{} = {} cells (h 0.125), {block_points} known points",
                big[0],
                big[1],
                big[2],
                cells(big)
            ),
            indented_block(big, h8, block_points, 11)?,
        ),
    ];

    // The sphere's contact points: most lie outside the block; brute force (f64) says which do not.
    let sphere = SphereOnBlock {
        known_points: 0,
        ..base.clone()
    }
    .build("sphere")?;
    let oracle = BruteForce::new(&sphere.body, Settings::default())?;
    let answers = pool.install(|| oracle.locate_all(&sphere.contact_points));
    let reference = answers
        .iter()
        .map(|a| {
            a.map(|hit| {
                hit.map(|h| Reference {
                    cell: h.cell,
                    xi: h.xi,
                })
            })
        })
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| anyhow!("sphere point refused by brute force: {e}"))?;
    out.push(TradeScene {
        name: "sphere",
        what: format!(
            "the seed's case: {} sphere contact points on the {mesh} block ({} inside), reference brute force f64",
            sphere.contact_points.len(),
            reference.iter().flatten().count()
        ),
        body: SceneBody::Uniform(sphere.body),
        points: sphere.contact_points,
        reference,
    });

    // The seed's block refined by halving under the sphere (2 levels, 2:1 balanced): hanging
    // nodes, leaves of three sizes; known points drawn per leaf, so most lie in the finest ones.
    let adaptive = SphereOnAdaptiveBlock::refining(SphereOnBlock {
        contact_points: 0,
        known_points: known,
        ..base.clone()
    })
    .build("adaptive")?;
    let levels: Vec<usize> = (0..=adaptive.body.finest_level())
        .map(|l| {
            adaptive
                .body
                .leaves()
                .iter()
                .filter(|leaf| leaf.level == l)
                .count()
        })
        .collect();
    out.push(TradeScene::known_in(
        "adaptive",
        format!(
            "{mesh} block refined 2 levels under the sphere ({} leaves per level 0/1/2, {} hanging nodes), {known} known points",
            levels
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join("/"),
            adaptive.body.hanging_nodes().count()
        ),
        SceneBody::Adaptive(adaptive.body),
        &adaptive.known,
    ));

    // Far from the origin: every coordinate offset by 1e6. Rounding the generated points to f64 at
    // that magnitude moves them by ~1e-10, i.e. ~1e-9 in ξ on 0.25 cells: the reference ξ is the f64
    // inversion of the rounded point in its known cell, in that cell's local frame (exact there).
    let far = SphereOnBlock {
        contact_points: 0,
        known_points: known,
        offset: DVec3::splat(1e6),
        ..base
    }
    .build("far")?;
    let mut far = TradeScene::from_known(
        "far",
        format!(
            "{mesh} block offset by 1e6 in every coordinate, {known} known points (reference ξ: the rounded point re-inverted in f64 in its cell's local frame)"
        ),
        far,
    );
    let tight = NewtonOptions {
        tol: 1e-16,
        max_iter: 50,
        inside_tol: DVec3::splat(1e-6),
        ..NewtonOptions::default()
    };
    for (x, reference) in far.points.iter().zip(&mut far.reference) {
        let Some(r) = reference else { continue };
        let Some((map, origin)) = far.body.cell_map(r.cell) else {
            bail!("far scene: known cell {} is not an active cell", r.cell);
        };
        r.xi = map.invert_f64(*x - origin, r.xi, &tight).xi;
    }
    out.push(far);
    Ok(out)
}
