//! The seed's filters' failure modes, characterised against the brute-force oracle: on generated
//! scenes (mild, distorted, undeformed but anisotropic) count each strategy's misses, wrong cells,
//! false hits and ξ errors, and check the counts are exactly those docs/baselines.md reports, so the
//! documentation cannot drift from the code.
//!
//! Reproduce (and print the table to paste into the docs):
//! `cargo test -p cgcontact-baseline --test suite seed_filters_failure_counts -- --nocapture`

use crate::common;

use crate::common::Spec;
use cgcontact::glam::DVec3;
use cgcontact::{Body, LatticeLocator, Locator, Settings};
use cgcontact_baseline::{
    BruteForce, CentroidRadius, Inversion, NodeRadius, NodeRadiusOptions, RTree, RadiusRule,
};

const DOC: &str = include_str!("../../../../docs/baselines.md");
const BEGIN: &str = "<!-- baseline-counts:begin -->";
const END: &str = "<!-- baseline-counts:end -->";

/// Points per kind (volume, shared face/edge/node, ±1e-9 h boundary, in the box; plus a tenth far).
const POINTS_PER_KIND: usize = 400;

fn scenes() -> [(&'static str, Spec); 3] {
    let base = Spec {
        origin: DVec3::new(0.0, 0.0, 0.0),
        h: DVec3::splat(0.25),
        cells: [12, 10, 8],
        amplitude: 0.3,
        jitter: 0.0,
        holes: 0.0,
        seed: 2019,
    };
    [
        ("mild", base),
        (
            "distorted",
            Spec {
                amplitude: 2.0,
                jitter: 0.25,
                holes: 0.1,
                seed: 2020,
                ..base
            },
        ),
        (
            "anisotropic",
            Spec {
                h: DVec3::new(0.25, 0.25, 0.1),
                amplitude: 0.0,
                seed: 2021,
                ..base
            },
        ),
    ]
}

/// One row of the table: how `strategy` fares against the oracle on `points`.
fn row(
    scene: &str,
    label: &str,
    strategy: &dyn Locator,
    oracle: &[cgcontact::Owners],
    points: &[DVec3],
) -> Vec<String> {
    let (mut located, mut missed, mut wrong, mut false_hit, mut xi_off, mut inversions) =
        (0, 0, 0, 0, 0, 0u64);
    for (&x, owners) in points.iter().zip(oracle) {
        let Some(hit) = strategy.locate(x).expect("finite point") else {
            missed += usize::from(!owners.is_empty());
            continue;
        };
        located += 1;
        inversions += u64::from(hit.inversions);
        match owners.iter().find(|o| o.cell == hit.cell) {
            Some(owner) => xi_off += usize::from((owner.xi - hit.xi).abs().max_element() > 1e-6),
            None if owners.is_empty() => false_hit += 1,
            None => wrong += 1,
        }
    }
    [scene, label]
        .into_iter()
        .map(String::from)
        .chain([points.len(), located, missed, wrong, false_hit, xi_off].map(|n| n.to_string()))
        .chain([inversions.to_string()])
        .collect()
}

fn measured() -> Vec<Vec<String>> {
    let settings = Settings::default();
    let mut rows = Vec::new();
    for (scene, spec) in scenes() {
        let body: Body = common::body(&spec);
        let points: Vec<DVec3> = common::points(&body, POINTS_PER_KIND, spec.seed + 1)
            .into_iter()
            .map(|(x, _)| x)
            .collect();
        let brute = BruteForce::new(&body, settings).expect("valid settings");
        let oracle: Vec<cgcontact::Owners> = points
            .iter()
            .map(|&x| brute.locate_owners(x).expect("finite point"))
            .collect();
        let noderad = |radius, inversion| {
            NodeRadius::with_options(&body, settings, NodeRadiusOptions { radius, inversion })
                .expect("valid settings")
        };
        let strategies: Vec<(&str, Box<dyn Locator + '_>)> = vec![
            (
                "centroid, 1.0 × half-diagonal",
                Box::new(CentroidRadius::new(&body, settings).expect("valid")),
            ),
            (
                "centroid, 0.75 × half-diagonal",
                Box::new(CentroidRadius::with_factor(&body, settings, 0.75).expect("valid")),
            ),
            (
                "noderad, global min, exact Newton",
                Box::new(noderad(RadiusRule::GlobalMin, Inversion::Exact)),
            ),
            (
                "noderad, seed-literal radius, exact Newton",
                Box::new(noderad(RadiusRule::SeedLiteral, Inversion::Exact)),
            ),
            (
                "noderad, global min, seed Newton",
                Box::new(noderad(RadiusRule::GlobalMin, Inversion::SeedFaithful)),
            ),
            (
                "noderad, seed-literal radius, seed Newton",
                Box::new(noderad(RadiusRule::SeedLiteral, Inversion::SeedFaithful)),
            ),
            (
                "rtree",
                Box::new(RTree::new(&body, settings).expect("valid")),
            ),
            (
                "lattice",
                Box::new(LatticeLocator::new(&body, settings).expect("valid")),
            ),
        ];
        println!(
            "{scene}: centroid radius {:.4}, node radius global {:.4}, seed-literal {:.4}, u_max {:.4}",
            CentroidRadius::new(&body, settings)
                .expect("valid")
                .radius(),
            noderad(RadiusRule::GlobalMin, Inversion::Exact).radius(),
            noderad(RadiusRule::SeedLiteral, Inversion::Exact).radius(),
            body.max_displacement().max_element(),
        );
        for (label, strategy) in &strategies {
            rows.push(row(scene, label, strategy.as_ref(), &oracle, &points));
        }
    }
    rows
}

/// The rows of the marked table in docs/baselines.md (header and separator skipped).
fn documented() -> Vec<Vec<String>> {
    let start = DOC
        .find(BEGIN)
        .expect("docs/baselines.md has the begin marker")
        + BEGIN.len();
    let end = DOC.find(END).expect("docs/baselines.md has the end marker");
    DOC[start..end]
        .lines()
        .filter(|line| line.trim_start().starts_with('|'))
        .skip(2)
        .map(|line| {
            line.trim()
                .trim_matches('|')
                .split('|')
                .map(|cell| cell.trim().to_string())
                .collect()
        })
        .collect()
}

fn markdown(rows: &[Vec<String>]) -> String {
    let mut out = String::from(
        "| scene | strategy | points | located | missed | wrong cell | false hit | ξ off > 1e-6 | inversions (located points) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for row in rows {
        out += &format!("| {} |\n", row.join(" | "));
    }
    out
}

#[test]
fn failure_counts_match_the_docs() {
    let rows = measured();
    let table = markdown(&rows);
    println!("{table}");
    assert_eq!(
        rows,
        documented(),
        "docs/baselines.md is out of date; the measured table is:\n{table}"
    );
    // The oracle-agreeing strategies never fail; the table's point is the seed filters' failures.
    for row in rows.iter().filter(|r| r[1] == "rtree" || r[1] == "lattice") {
        assert_eq!(&row[4..8], ["0", "0", "0", "0"], "{row:?}");
    }
}

/// A single cell with corner 6 pulled out along the diagonal: the point near that corner lies farther
/// from the centroid than the cell's (and the body's) largest half-diagonal, so the centroid filter
/// with its default radius misses it while brute force finds it.
#[test]
fn centroid_radius_misses_a_point_near_a_stretched_corner() {
    use cgcontact::Lattice;
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [1, 1, 1]).unwrap();
    let mut body = Body::full(lattice);
    let far = lattice.node_index([1, 1, 1]);
    body.update_displacements(|node, _, u| {
        if node == far {
            *u = DVec3::splat(0.5)
        }
    })
    .unwrap();
    body.validate().unwrap();
    let settings = Settings::default();
    let x = common::point_at(&body, cgcontact::CellId(0), DVec3::splat(0.95));
    let filter = CentroidRadius::new(&body, settings).unwrap();
    let centroid = body
        .corners(cgcontact::CellId(0))
        .unwrap()
        .iter()
        .sum::<DVec3>()
        / 8.0;
    assert!(
        x.distance(centroid) > filter.radius(),
        "the point lies beyond the radius"
    );
    assert!(
        BruteForce::new(&body, settings)
            .unwrap()
            .locate(x)
            .unwrap()
            .is_some()
    );
    assert_eq!(filter.locate(x).unwrap(), None);
    // A larger radius finds it again.
    assert!(
        CentroidRadius::with_factor(&body, settings, 1.5)
            .unwrap()
            .locate(x)
            .unwrap()
            .is_some()
    );
}

/// The node radius is the exact global minimum over all pairs of deformed nodes of active cells, and
/// the seed-literal one is the last node's minimum distance to the others.
#[test]
fn node_radius_rules_on_a_distorted_body() {
    let (_, spec) = scenes()[1];
    let body = common::body(&spec);
    let lattice = body.lattice();
    let positions: Vec<DVec3> = body
        .nodes()
        .zip(body.displacements())
        .map(|(node, &u)| lattice.node_position(lattice.node_ijk(node).unwrap()) + u)
        .collect();
    let mut global = f64::INFINITY;
    for (i, p) in positions.iter().enumerate() {
        for q in &positions[i + 1..] {
            global = global.min(p.distance(*q));
        }
    }
    let (last, others) = positions.split_last().unwrap();
    let literal = others
        .iter()
        .map(|p| p.distance(*last))
        .fold(f64::INFINITY, f64::min);
    let radius = |rule| {
        NodeRadius::with_options(
            &body,
            Settings::default(),
            NodeRadiusOptions {
                radius: rule,
                ..Default::default()
            },
        )
        .unwrap()
        .radius()
    };
    // Positions here are global and the locator's are relative to the lattice origin (0 here).
    assert_eq!(radius(RadiusRule::GlobalMin), global);
    assert_eq!(radius(RadiusRule::SeedLiteral), literal);
    assert_eq!(radius(RadiusRule::Fixed(0.3)), 0.3);
    let bad = NodeRadiusOptions {
        radius: RadiusRule::Fixed(f64::NAN),
        ..Default::default()
    };
    assert!(NodeRadius::with_options(&body, Settings::default(), bad).is_err());
    assert!(CentroidRadius::with_factor(&body, Settings::default(), 0.0).is_err());
    assert!(CentroidRadius::with_radius(&body, Settings::default(), -1.0).is_err());
}
