//! Regression: `Hex8Map::invert` (public, low-level) took its `NewtonOptions` as given, and
//! options out of range gave wrong answers without a word. At the unit cube's centre: a NaN
//! inside tolerance on one axis answered `Outside` (no ξ is within a NaN), an infinite one
//! answers every converged point `Inside`, wherever it is, and a determinant floor of 1 or more
//! answered `Singular`, in f64 and f32. Now `NewtonOptions::validate` names the value, and
//! `invert` panics on options out of range rather than answer.

use cgcontact::hex8::{Hex8Map, Hex8Map32, NewtonOptions, Status};
use cgcontact::{CORNER_OFFSETS, Error};
use glam::{DVec3, Vec3A};

fn unit_cell() -> [DVec3; 8] {
    CORNER_OFFSETS.map(|o| DVec3::new(f64::from(o[0]), f64::from(o[1]), f64::from(o[2])))
}

/// Every way out of range, each with the word its message must carry.
fn out_of_range() -> Vec<(NewtonOptions, &'static str)> {
    let ok = NewtonOptions::default();
    let mut cases = Vec::new();
    for bad in [f64::NAN, -1e-12, f64::INFINITY] {
        cases.push((NewtonOptions { tol: bad, ..ok }, "Newton tolerance"));
        for axis in 0..3 {
            let mut v = ok.inside_tol;
            v[axis] = bad;
            cases.push((
                NewtonOptions {
                    inside_tol: v,
                    ..ok
                },
                "inside tolerance",
            ));
            let mut v = ok.inside_length;
            v[axis] = bad;
            cases.push((
                NewtonOptions {
                    inside_length: v,
                    ..ok
                },
                "inside length",
            ));
        }
    }
    for bad in [f64::NAN, -0.5, 1.0, f64::INFINITY] {
        cases.push((
            NewtonOptions {
                det_ratio_min: bad,
                ..ok
            },
            "determinant ratio",
        ));
    }
    cases
}

#[test]
fn options_out_of_range_are_named() {
    let ok = NewtonOptions::default();
    assert_eq!(ok.validate(), Ok(()));
    // In range at the edges: zero tolerances, no iterations, any limit.
    for edge in [
        NewtonOptions {
            tol: 0.0,
            inside_tol: DVec3::ZERO,
            det_ratio_min: 0.0,
            ..ok
        },
        NewtonOptions { max_iter: 0, ..ok },
        NewtonOptions {
            max_iter: u32::MAX,
            ..ok
        },
    ] {
        assert_eq!(edge.validate(), Ok(()), "{edge:?}");
    }
    for (options, word) in out_of_range() {
        match options.validate() {
            Err(Error::InvalidSettings(message)) => {
                assert!(message.contains(word), "{options:?}: {message}");
            }
            other => panic!("{options:?}: {other:?}"),
        }
    }
}

#[test]
fn invert_refuses_options_out_of_range_in_both_precisions() {
    let corners = unit_cell();
    let map = Hex8Map::new(&corners);
    let map32 = Hex8Map32::new(&corners.map(|c| c.as_vec3a()));
    let centre = DVec3::splat(0.5);
    for (options, word) in out_of_range() {
        let f64_run = std::panic::catch_unwind(|| map.invert(centre, DVec3::ZERO, &options));
        let f32_run =
            std::panic::catch_unwind(|| map32.invert(centre.as_vec3a(), Vec3A::ZERO, &options));
        for (what, run) in [
            ("f64", f64_run.map(|i| i.status)),
            ("f32", f32_run.map(|i| i.status)),
        ] {
            let message = match run {
                Ok(status) => panic!("{what} {options:?}: answered {status:?}"),
                Err(payload) => payload
                    .downcast_ref::<String>()
                    .cloned()
                    .unwrap_or_default(),
            };
            assert!(message.contains(word), "{what} {options:?}: {message}");
        }
    }
    // In range: the centre is found, at ξ = 0.
    let inside = map.invert(centre, DVec3::ZERO, &NewtonOptions::default());
    assert_eq!(inside.status, Status::Inside);
    assert!(inside.xi.abs().max_element() < 1e-15);
}
