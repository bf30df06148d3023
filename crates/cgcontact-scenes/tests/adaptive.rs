//! The adaptive scenes against independent answers: levels and balance checked on every pair of
//! touching leaves (boxes on the finest lattice, no tree), the refinement rule recomputed from the
//! leaves' boxes, known (leaf, ξ) found by the adaptive locator, and the uniform scene where the
//! adaptive one has a single level.

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveBody, AdaptiveLocator, LatticeLocator, Leaf, Locator, Settings};
use cgcontact_scenes::{
    AdaptiveScene, LeafCount, LeafDraw, LeafOrder, SphereOnAdaptiveBlock, SphereOnBlock,
    adaptive_block, block_cells_for, indented_block, leaf_box, uniform_twin,
};

/// The coarse seed's block with few points, refined `levels` levels within `radius`.
fn coarse(levels: u8, radius: f64, balanced: bool) -> SphereOnAdaptiveBlock {
    SphereOnAdaptiveBlock {
        levels,
        refine_radius: radius,
        balanced,
        ..SphereOnAdaptiveBlock::refining(SphereOnBlock {
            contact_points: 500,
            known_points: 2_000,
            ..SphereOnBlock::coarse()
        })
    }
}

/// The largest level difference between two leaves that touch (closed boxes meeting by a face, an
/// edge or a corner), over every such pair: boxes on the finest lattice, swept along x.
fn largest_jump(body: &AdaptiveBody) -> u8 {
    let finest = body.finest_level();
    let mut boxes: Vec<([u64; 3], [u64; 3], u8)> = body
        .leaves()
        .iter()
        .map(|leaf| {
            let s = finest - leaf.level;
            let low = leaf.ijk.map(|v| u64::from(v) << s);
            (low, low.map(|v| v + (1 << s)), leaf.level)
        })
        .collect();
    boxes.sort_unstable_by_key(|b| b.0[0]);
    let mut largest = 0;
    for (n, (low, high, level)) in boxes.iter().enumerate() {
        for (other_low, other_high, other_level) in boxes[n + 1..]
            .iter()
            .take_while(|other| other.0[0] <= high[0])
        {
            if (0..3).all(|a| other_low[a] <= high[a] && low[a] <= other_high[a]) {
                largest = largest.max(level.abs_diff(*other_level));
            }
        }
    }
    largest
}

/// Leaves per level, 0 ..= finest.
fn per_level(body: &AdaptiveBody) -> Vec<usize> {
    let mut counts = vec![0; usize::from(body.finest_level()) + 1];
    for leaf in body.leaves() {
        counts[usize::from(leaf.level)] += 1;
    }
    counts
}

/// Every known point is found in its leaf, at its ξ to 1e-12.
fn known_points_are_found(scene: &AdaptiveScene) {
    let locator = AdaptiveLocator::new(&scene.body, Settings::default()).unwrap();
    for k in &scene.known {
        let hit = locator
            .locate(k.x)
            .unwrap()
            .expect("a known point is inside");
        // ξ drawn uniformly: on a face only with probability zero, so the owner is unique.
        assert_eq!(hit.cell, k.cell, "{k:?}");
        let error = (hit.xi - k.xi).abs().max_element();
        assert!(error <= 1e-12, "ξ error {error} at {k:?}");
    }
}

fn distance_to_box(p: DVec3, (low, high): (DVec3, DVec3)) -> f64 {
    (low - p).max(p - high).max(DVec3::ZERO).length()
}

#[test]
fn the_scene_has_the_levels_asked_for() {
    for levels in 0..=3 {
        let scene = coarse(levels, 1.0, true).build("levels").unwrap();
        assert_eq!(scene.body.finest_level(), levels);
        let counts = per_level(&scene.body);
        assert!(counts.iter().all(|&n| n > 0), "{levels} levels: {counts:?}");
    }
}

#[test]
fn levels_grow_toward_the_patch_without_balance() {
    let knobs = coarse(3, 1.0, false);
    let scene = knobs.build("unbalanced").unwrap();
    let patch = knobs.patch_center().unwrap();
    assert_eq!(patch, DVec3::new(2.5, 5.0, 5.0));
    let lattice = *scene.body.lattice();
    for leaf in scene.body.leaves() {
        let d = distance_to_box(patch, leaf_box(&lattice, leaf));
        // A leaf above the finest level was not split: it lies 1 mm or farther from the patch.
        if leaf.level < 3 {
            assert!(d >= 1.0, "{leaf:?} at {d} was not refined");
        }
        // A refined leaf's parent was split: it came within 1 mm.
        if leaf.level > 0 {
            let parent = Leaf::new(leaf.level - 1, leaf.ijk.map(|v| v / 2));
            let d = distance_to_box(patch, leaf_box(&lattice, parent));
            assert!(d < 1.0, "the parent of {leaf:?} at {d} was refined");
        }
    }
}

#[test]
fn balanced_scenes_are_two_to_one() {
    for (levels, radius) in [(2, 1.0), (3, 1.0), (3, 0.3), (4, 0.6)] {
        let scene = coarse(levels, radius, true).build("balanced").unwrap();
        assert_eq!(scene.body.finest_level(), levels);
        assert_eq!(
            largest_jump(&scene.body),
            1,
            "{levels} levels within {radius}"
        );
    }
    let fine = SphereOnAdaptiveBlock {
        uniform: SphereOnBlock {
            known_points: 0,
            contact_points: 0,
            ..SphereOnBlock::fine()
        },
        ..SphereOnAdaptiveBlock::fine()
    };
    let scene = fine.build("fine").unwrap();
    assert_eq!(largest_jump(&scene.body), 1);
}

#[test]
fn unbalanced_scenes_jump_more_than_one_level() {
    for (levels, radius) in [(2, 1.0), (2, 0.3), (3, 0.3)] {
        let scene = coarse(levels, radius, false).build("unbalanced").unwrap();
        assert!(
            largest_jump(&scene.body) >= 2,
            "{levels} levels within {radius}"
        );
    }
}

#[test]
fn balancing_only_adds_refinement() {
    let unbalanced = coarse(3, 0.3, false).build("unbalanced").unwrap();
    let balanced = coarse(3, 0.3, true).build("balanced").unwrap();
    assert!(balanced.body.cell_count() > unbalanced.body.cell_count());
    // Every balanced leaf lies inside an unbalanced one (or is one): refinement, never coarsening.
    let lattice = *balanced.body.lattice();
    for leaf in balanced.body.leaves() {
        let (low, high) = leaf_box(&lattice, leaf);
        let holder = unbalanced
            .body
            .leaf_at((low + high) * 0.5)
            .expect("the same block");
        let coarse = unbalanced
            .body
            .leaves()
            .get(holder.index())
            .expect("a leaf of the body");
        assert!(coarse.level <= leaf.level, "{leaf:?} in {coarse:?}");
    }
}

#[test]
fn hanging_nodes_obey_their_constraints() {
    for balanced in [true, false] {
        for jitter in [0.0, 0.3] {
            let knobs = SphereOnAdaptiveBlock {
                uniform: SphereOnBlock {
                    jitter,
                    ..coarse(3, 0.6, balanced).uniform
                },
                ..coarse(3, 0.6, balanced)
            };
            let scene = knobs.build("hanging").unwrap();
            let report = scene.body.check_constraints(1e-12);
            assert!(report.hanging > 0, "{report:?}");
            assert!(report.holds(), "{report:?}");
            scene.body.validate().unwrap();
        }
    }
}

#[test]
fn the_field_is_the_uniform_scenes_on_independent_nodes() {
    let knobs = coarse(2, 1.0, true);
    let scene = knobs.build("field").unwrap();
    let field = cgcontact_scenes::Indentation {
        center: DVec3::new(2.5, 5.0, 0.0),
        // 0.5 × the sphere's 1 mm radius is wider than 2.5 × the sink (0.225 × 0.5 mm).
        width: 0.5,
        depth: 0.225 * 0.5,
        top: 5.0,
        bottom: 0.0,
    };
    let body = &scene.body;
    for (node, u) in body.displacements().iter().enumerate() {
        if !body.is_hanging(node) {
            let x = body.node_position(node).unwrap();
            assert_eq!(*u, field.displacement(x), "node {node}");
        }
    }
}

#[test]
fn known_points_are_found_in_their_leaves() {
    for (balanced, order, draw, jitter) in [
        (true, LeafOrder::Sorted, LeafDraw::PerLeaf, 0.0),
        (false, LeafOrder::Shuffled, LeafDraw::ByVolume, 0.0),
        (true, LeafOrder::Shuffled, LeafDraw::PerLeaf, 0.3),
        (false, LeafOrder::Sorted, LeafDraw::PerLeaf, 0.3),
    ] {
        let mut knobs = coarse(3, 0.8, balanced);
        knobs.order = order;
        knobs.draw = draw;
        knobs.uniform.jitter = jitter;
        let scene = knobs.build("known").unwrap();
        assert_eq!(scene.known.len(), 2_000);
        known_points_are_found(&scene);
    }
}

#[test]
fn leaves_drawn_per_leaf_or_by_volume() {
    let mut knobs = coarse(2, 1.0, true);
    knobs.uniform.known_points = 20_000;
    let per_leaf = knobs.build("per-leaf").unwrap();
    knobs.draw = LeafDraw::ByVolume;
    let by_volume = knobs.build("by-volume").unwrap();
    let body = &per_leaf.body;
    let level_of = |k: &cgcontact_scenes::KnownPoint| {
        body.leaves()
            .get(k.cell.index())
            .expect("a leaf of the body")
            .level
    };
    let share = |points: &[cgcontact_scenes::KnownPoint]| {
        points.iter().filter(|k| level_of(k) == 2).count() as f64 / points.len() as f64
    };
    // Expected shares of the finest level: its leaves' share, or its volume's share.
    let counts = per_level(body);
    let leaves = body.cell_count() as f64;
    let volume: f64 = (0..3)
        .map(|l| counts[l] as f64 * 8f64.powi(2 - l as i32))
        .sum();
    let expected = [counts[2] as f64 / leaves, counts[2] as f64 / volume];
    for (points, expected) in [
        (&per_leaf.known, expected[0]),
        (&by_volume.known, expected[1]),
    ] {
        let sigma = (expected * (1.0 - expected) / points.len() as f64).sqrt();
        let got = share(points);
        assert!((got - expected).abs() < 5.0 * sigma, "{got} vs {expected}");
    }
    // The two draws differ enough for the check to tell them apart.
    assert!(expected[0] > 0.2 && expected[1] < 0.05, "{expected:?}");
}

#[test]
fn the_same_seed_makes_the_same_scene() {
    let mut knobs = coarse(3, 0.8, false);
    knobs.uniform.jitter = 0.3;
    knobs.order = LeafOrder::Shuffled;
    let a = knobs.build("a").unwrap();
    let b = knobs.build("b").unwrap();
    assert_eq!(a.body.leaves(), b.body.leaves());
    assert_eq!(a.body.displacements(), b.body.displacements());
    assert_eq!(a.known, b.known);
    assert_eq!(a.contact_points, b.contact_points);
    knobs.uniform.seed += 1;
    let c = knobs.build("c").unwrap();
    assert_ne!(a.body.leaves(), c.body.leaves());
    assert_ne!(a.body.displacements(), c.body.displacements());
    assert_ne!(a.known, c.known);
}

#[test]
fn shuffled_leaves_are_the_sorted_ones_in_another_order() {
    let sorted = coarse(3, 0.8, true).build("sorted").unwrap();
    let mut knobs = coarse(3, 0.8, true);
    knobs.order = LeafOrder::Shuffled;
    let shuffled = knobs.build("shuffled").unwrap();
    let ordered = sorted.body.leaves().to_vec();
    // Sorted: lowest corners on the finest lattice ascending, z then y then x.
    let corner = |leaf: &Leaf| {
        let q = leaf.ijk.map(|v| v << (3 - leaf.level));
        [q[2], q[1], q[0]]
    };
    assert!(ordered.windows(2).all(|w| corner(&w[0]) < corner(&w[1])));
    assert_ne!(shuffled.body.leaves().to_vec(), ordered);
    let mut again = shuffled.body.leaves().to_vec();
    again.sort_unstable_by_key(corner);
    assert_eq!(again, ordered);
    // Nodes are numbered by position, whatever the leaves' order: the same displacements.
    assert_eq!(shuffled.body.displacements(), sorted.body.displacements());
}

#[test]
fn one_level_is_the_uniform_scene() {
    let uniform = SphereOnBlock {
        jitter: 0.3,
        known_points: 1_000,
        contact_points: 100,
        ..SphereOnBlock::coarse()
    };
    let flat = SphereOnAdaptiveBlock {
        levels: 0,
        ..SphereOnAdaptiveBlock::refining(uniform.clone())
    }
    .build("flat")
    .unwrap();
    let scene = uniform.build("uniform").unwrap();
    assert_eq!(flat.body.cell_count(), scene.body.lattice().cell_count());
    assert_eq!(flat.body.displacements(), scene.body.displacements());
    assert_eq!(flat.known, scene.known);
    assert_eq!(flat.contact_points, scene.contact_points);
    assert_eq!(flat.sphere, scene.sphere);
}

#[test]
fn inverted_leaves_only_when_asked() {
    let mut wild = coarse(2, 1.0, true);
    wild.uniform.jitter = 0.9;
    wild.uniform.known_points = 0;
    wild.build("kept-valid").unwrap().body.validate().unwrap();
    wild.uniform.allow_inverted = true;
    let inverted = wild.build("inverted").unwrap();
    assert!(!inverted.body.inverted_cells().is_empty());
    assert!(inverted.body.check_constraints(1e-12).holds());
}

#[test]
fn the_contact_patch_is_inside_as_in_the_uniform_scene() {
    let scene = coarse(2, 1.0, true).build("contact").unwrap();
    let locator = AdaptiveLocator::new(&scene.body, Settings::default()).unwrap();
    let uniform = SphereOnBlock {
        contact_points: 500,
        known_points: 0,
        ..SphereOnBlock::coarse()
    }
    .build("uniform")
    .unwrap();
    let uniform_locator = LatticeLocator::new(&uniform.body, Settings::default()).unwrap();
    assert_eq!(scene.contact_points, uniform.contact_points);
    let inside =
        |found: &dyn Fn(DVec3) -> bool| scene.contact_points.iter().filter(|&&x| found(x)).count();
    let adaptive = inside(&|x| locator.locate(x).unwrap().is_some());
    let flat = inside(&|x| uniform_locator.locate(x).unwrap().is_some());
    // The same field, interpolated on finer cells: nearly the same cap inside.
    assert!(adaptive > 10, "{adaptive} points inside");
    assert!(
        adaptive.abs_diff(flat) <= flat / 5 + 2,
        "{adaptive} vs {flat}"
    );
}

/// `leaf_count` counts, without building, the leaves `build` makes: checked against the built
/// scene's leaves and finest level, balanced and not, on the coarse spacing, a spacing of another
/// size per axis, and a scaled and moved block; and past a cap just below the count it stops.
#[test]
fn leaf_count_is_the_built_scenes() {
    let knobs =
        |h: DVec3, scale: f64, levels: u8, radius: f64, balanced: bool| SphereOnAdaptiveBlock {
            levels,
            refine_radius: radius,
            balanced,
            ..SphereOnAdaptiveBlock::refining(SphereOnBlock {
                h,
                scale,
                offset: DVec3::new(-3.0, 1.5, 20.0),
                contact_points: 0,
                known_points: 0,
                ..SphereOnBlock::coarse()
            })
        };
    let mut settings = Vec::new();
    for (h, scale) in [
        (DVec3::splat(0.5), 1.0),
        (DVec3::new(0.5, 0.25, 1.0), 1.0),
        (DVec3::splat(0.5), 2.5),
    ] {
        for levels in 0..=2 {
            for radius in [0.0, 0.7, 1.5] {
                settings.push((h, scale, levels, radius));
            }
        }
        settings.push((h, scale, 3, 0.4));
    }
    for (h, scale, levels, radius) in settings {
        let mut unbalanced_leaves = 0;
        for balanced in [false, true] {
            let scene = knobs(h, scale, levels, radius, balanced);
            let what = format!("h {h}, scale {scale}, {levels} levels within {radius}, {balanced}");
            let built = scene.build("counted").unwrap();
            let leaves = built.body.cell_count() as u64;
            let count = scene.leaf_count(u64::MAX).unwrap();
            assert_eq!(
                count,
                LeafCount::Exact {
                    leaves,
                    finest: built.body.finest_level()
                },
                "{what}"
            );
            assert_eq!(scene.leaf_count(leaves).unwrap(), count, "{what}");
            if !balanced {
                unbalanced_leaves = leaves;
            }
            // Balanced too, the count stops on passing the unbalanced one, before any balance.
            let cap = unbalanced_leaves - 1;
            let stopped = scene.leaf_count(cap).unwrap();
            assert_eq!(stopped, LeafCount::MoreThan(cap), "{what}");
        }
    }
}

#[test]
fn bad_knobs_are_errors() {
    assert!(coarse(21, 1.0, true).build("deep").is_err());
    let mut knobs = coarse(2, 1.0, true);
    knobs.uniform.h = DVec3::ZERO;
    assert!(knobs.build("flat").is_err());
    // Refining the whole 2,000-cell block 8 levels would make 3 · 10^10 leaves.
    assert!(coarse(8, 1e3, true).build("huge").is_err());
    // A radius that reaches nothing refines nothing.
    let none = coarse(3, f64::NAN, true).build("nan").unwrap();
    assert_eq!(none.body.finest_level(), 0);
}

#[test]
fn the_bench_block_is_mostly_finest_leaves() {
    // The coarse seed's block refined two levels within 2 mm of the patch.
    let scene = adaptive_block([10, 20, 10], DVec3::splat(0.5), 2, 2.0, 10_000, 7).unwrap();
    let counts = per_level(&scene.body);
    let leaves = scene.body.cell_count();
    assert!(2 * counts[2] > leaves, "{counts:?}");
    assert!(largest_jump(&scene.body) <= 1);
    known_points_are_found(&scene);
    let cells = block_cells_for(leaves, DVec3::new(1.0, 2.0, 1.0));
    let uniform: usize = cells.iter().map(|&n| n as usize).product();
    assert!(
        uniform.abs_diff(leaves) * 10 < leaves,
        "{cells:?} for {leaves}"
    );
}

#[test]
fn large_jitter_ends_valid_and_conforming() {
    // Nearly a cell of jitter inverts leaves of every level; halving ends with none, and the
    // hanging nodes still follow their parents.
    for seed in 0..6 {
        for balanced in [true, false] {
            let mut knobs = coarse(3, 0.8, balanced);
            knobs.uniform.jitter = 0.95;
            knobs.uniform.known_points = 0;
            knobs.uniform.seed = seed;
            let scene = knobs.build("wild").unwrap();
            scene.body.validate().unwrap();
            assert!(scene.body.check_constraints(1e-12).holds());
        }
    }
}

/// The uniform twin answers the adaptive scene's problem: each known point made at the same
/// undeformed place, found at its (cell, ξ) by the lattice locator, and displaced alike (both
/// bodies interpolate the same indentation, so the deformed points differ by the interpolation
/// error only, far below the sink).
#[test]
fn the_uniform_twin_carries_the_same_points_under_the_same_indentation() {
    let (base, h) = ([10, 20, 10], DVec3::splat(0.5));
    let adaptive = adaptive_block(base, h, 2, 1.5, 3_000, 11).unwrap();
    let twin_cells = block_cells_for(adaptive.body.cell_count(), DVec3::new(1.0, 2.0, 1.0));
    let twin = uniform_twin(base, h, twin_cells, &adaptive).unwrap();
    assert_eq!(twin.body.lattice().cells(), twin_cells);
    assert_eq!(twin.known.len(), adaptive.known.len());
    let sink = AdaptiveLocator::new(&adaptive.body, Settings::default())
        .unwrap()
        .max_displacement()
        .z;
    let locator = LatticeLocator::new(&twin.body, Settings::default()).unwrap();
    let twin_sink = locator.max_displacement().z;
    assert!(
        (twin_sink - sink).abs() < 0.05 * sink,
        "{twin_sink} against {sink}"
    );
    let (lattice, body) = (twin.body.lattice(), &adaptive.body);
    let mut moved = 0;
    for (t, a) in twin.known.iter().zip(&adaptive.known) {
        let ijk = lattice.cell_ijk(t.cell).unwrap().map(f64::from);
        let at_twin = lattice.origin() + lattice.h() * (DVec3::from(ijk) + (t.xi + 1.0) * 0.5);
        let leaf = body.leaves().get(a.cell.index()).unwrap();
        let at = body.leaf_origin(leaf) + body.spacing(leaf.level) * (a.xi + 1.0) * 0.5;
        assert!(
            (at_twin - at).abs().max_element() < 1e-12,
            "{at_twin} against {at}"
        );
        assert!((t.x - a.x).length() < 0.1 * sink, "{} against {}", t.x, a.x);
        moved += usize::from((t.x - at).length() > 0.1 * sink);
        let hit = locator
            .locate(t.x)
            .unwrap()
            .expect("a known point is found");
        assert!((hit.xi - t.xi).abs().max_element() < 1e-9 || hit.cell != t.cell);
        let x = twin.body.point_at(hit.cell, hit.xi).unwrap();
        assert!((x - t.x).length() < 1e-12, "{x} against {}", t.x);
    }
    // The points crowd under the indentation, as the adaptive scene draws them per leaf: far more
    // of them move than of the points of a block drawn per cell.
    let spread = indented_block(twin_cells, lattice.h(), 3_000, 11).unwrap();
    let spread_moved = spread
        .known
        .iter()
        .filter(|k| {
            let ijk = DVec3::from(lattice.cell_ijk(k.cell).unwrap().map(f64::from));
            let at = lattice.origin() + lattice.h() * (ijk + (k.xi + 1.0) * 0.5);
            (k.x - at).length() > 0.1 * sink
        })
        .count();
    assert!(
        moved > 4 * spread_moved,
        "{moved} against {spread_moved} moved"
    );
}
