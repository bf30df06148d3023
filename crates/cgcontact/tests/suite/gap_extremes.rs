//! The contact quantities ([`GapFinder`]: signed gap, closest point, normal) on the geometry the
//! locator's extremes sweep: bodies sheared and rotated by [`linear_maps`] (and undeformed), on
//! anisotropic and tiny spacings, near the origin, at 1e5 and at −1e8, uniform and adaptive
//! (level jumps of 1 and 2, a missing base cell, a cavity), f64 and f32. Points on boundary
//! nodes, edges and faces, 1e-9 to 1e-3 of a cell off them on either side, far away and deep
//! inside, against an oracle that shares nothing with the search: the boundary faces found by
//! their definition, each a bilinear quad whose closest point is found by sampling one face
//! coordinate and, for each sample, the closed-form closest point of the straight segment along
//! the other, then bisection on the derivative (both ways round).
//!
//! Every scene prints one `MEASURED` line (`cargo test -p cgcontact --test suite gap_extremes --
//! --nocapture | grep MEASURED`).

use bitvec::prelude::*;
use cgcontact::{
    AdaptiveBody, AdaptiveLocator, Body, CellId, Frame, GapFinder, InsideTolerance, Lattice,
    LatticeLocator, Leaf, Settings, Surface,
};
use glam::{DVec2, DVec3};

use crate::common::{Rng, linear_maps};

type Quad = [DVec3; 4];

/// S(s, t) of the quad through `q` (q0 at (−1, −1), q1 (1, −1), q2 (1, 1), q3 (−1, 1)).
fn at(q: &Quad, s: f64, t: f64) -> DVec3 {
    0.25 * ((1.0 - s) * (1.0 - t) * q[0]
        + (1.0 + s) * (1.0 - t) * q[1]
        + (1.0 + s) * (1.0 + t) * q[2]
        + (1.0 - s) * (1.0 + t) * q[3])
}

/// The unit normal Sₛ × Sₜ at (s, t).
fn normal(q: &Quad, s: f64, t: f64) -> DVec3 {
    let ds = 0.25 * (-(1.0 - t) * q[0] + (1.0 - t) * q[1] + (1.0 + t) * q[2] - (1.0 + t) * q[3]);
    let dt = 0.25 * (-(1.0 - s) * q[0] - (1.0 + s) * q[1] + (1.0 + s) * q[2] + (1.0 - s) * q[3]);
    ds.cross(dt).normalize()
}

/// g(s) = the squared distance from `x` to the segment S(s, ·), the segment's parameter of its
/// closest point, and g'(s). At an interior minimizer the residual is normal to the segment, so
/// only the part of ∂S/∂s normal to it counts (its part along the segment would only carry the
/// residual's rounding: on a face sheared 1000 : 1 that alone moved the answer by 1e-10).
fn segment(q: &Quad, x: DVec3, s: f64) -> (f64, f64, f64) {
    let p = 0.5 * ((1.0 - s) * q[0] + (1.0 + s) * q[1]);
    let r = 0.5 * ((1.0 - s) * q[3] + (1.0 + s) * q[2]);
    let e = r - p;
    let ee = e.length_squared();
    let u = if ee > 0.0 {
        ((x - p).dot(e) / ee).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let v = (p - x) + e * u;
    let mut dv = 0.5 * (q[1] - q[0]) + 0.5 * ((q[2] - q[3]) - (q[1] - q[0])) * u;
    if u > 0.0 && u < 1.0 {
        dv -= e * (dv.dot(e) / ee);
    }
    (v.length_squared(), u, 2.0 * v.dot(dv))
}

/// The closest point of the quad with s outside: 64 intervals of s, bisection of g' wherever it
/// turns from − to +. (d², s, t).
fn closest_s(q: &Quad, x: DVec3) -> (f64, f64, f64) {
    const N: usize = 64;
    let mut best = (f64::INFINITY, 0.0, 0.0);
    let mut previous: Option<(f64, f64)> = None;
    for i in 0..=N {
        let s = -1.0 + 2.0 * i as f64 / N as f64;
        let (g, u, dg) = segment(q, x, s);
        if g < best.0 {
            best = (g, s, 2.0 * u - 1.0);
        }
        if let Some((s0, dg0)) = previous
            && dg0 < 0.0
            && dg >= 0.0
        {
            let (mut lo, mut hi) = (s0, s);
            for _ in 0..64 {
                let mid = 0.5 * (lo + hi);
                if segment(q, x, mid).2 < 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            for s in [lo, hi] {
                let (g, u, _) = segment(q, x, s);
                if g < best.0 {
                    best = (g, s, 2.0 * u - 1.0);
                }
            }
        }
        previous = Some((s, dg));
    }
    best
}

/// The closest point of the quad, both ways round. (d², s, t).
fn closest(q: &Quad, x: DVec3) -> (f64, f64, f64) {
    let a = closest_s(q, x);
    let b = closest_s(&[q[0], q[3], q[2], q[1]], x);
    if b.0 < a.0 { (b.0, b.2, b.1) } else { a }
}

/// A boundary face (or a square of one): its quad, outward, and the box of its corners (which
/// holds it).
struct Face {
    q: Quad,
    lo: DVec3,
    hi: DVec3,
}

impl Face {
    /// The quad through `q`, turned to face away from `centre` (its cell's).
    fn new(mut q: Quad, centre: DVec3) -> Self {
        if normal(&q, 0.0, 0.0).dot(at(&q, 0.0, 0.0) - centre) < 0.0 {
            q.swap(1, 3);
        }
        let (lo, hi) = q[1..]
            .iter()
            .fold((q[0], q[0]), |(l, h), &p| (l.min(p), h.max(p)));
        Self { q, lo, hi }
    }

    fn box_distance(&self, x: DVec3) -> f64 {
        (self.lo - x).max(x - self.hi).max(DVec3::ZERO).length()
    }
}

/// The oracle's closest point of the surface to `x`: distance, point, face, (s, t).
fn nearest(faces: &[Face], x: DVec3) -> (f64, DVec3, usize, DVec2) {
    let mut order: Vec<(f64, usize)> = faces
        .iter()
        .enumerate()
        .map(|(i, f)| (f.box_distance(x), i))
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best = (f64::INFINITY, 0, 0.0, 0.0);
    for (bound, i) in order {
        if bound * bound > best.0 {
            break;
        }
        let (d2, s, t) = closest(&faces[i].q, x);
        if d2 < best.0 {
            best = (d2, i, s, t);
        }
    }
    let (d2, i, s, t) = best;
    (d2.sqrt(), at(&faces[i].q, s, t), i, DVec2::new(s, t))
}

/// A cell's deformed corners relative to the lattice's origin: its lowest node's position less
/// the origin (exact: they are close), plus offset × size, plus the displacement.
fn local_corners(base: DVec3, size: DVec3, u: &[DVec3; 8]) -> [DVec3; 8] {
    std::array::from_fn(|c| {
        let o = cgcontact::CORNER_OFFSETS[c];
        base + DVec3::new(f64::from(o[0]), f64::from(o[1]), f64::from(o[2])) * size + u[c]
    })
}

/// The boundary faces of a uniform body (relative to its origin): faces of active cells whose
/// neighbour across is outside the lattice or inactive. With each, its cell's spacing.
fn uniform_faces(body: &Body) -> Vec<(Face, DVec3)> {
    let lattice = body.lattice();
    let n = lattice.cells();
    let mut faces = Vec::new();
    for cell in body.active_cells() {
        let ijk = lattice.cell_ijk(cell).unwrap();
        let base = lattice.node_position(ijk) - lattice.origin();
        let c = local_corners(base, lattice.h(), &body.cell_displacements(cell).unwrap());
        let centre = c.iter().sum::<DVec3>() / 8.0;
        for (f, corners) in cgcontact::gap::FACE_CORNERS.iter().enumerate() {
            let axis = f / 2;
            let across = i64::from(ijk[axis]) + if f % 2 == 1 { 1 } else { -1 };
            let open = across < 0 || across >= i64::from(n[axis]) || {
                let mut other = ijk;
                other[axis] = across as u32;
                !body.is_active(lattice.cell_id(other))
            };
            if open {
                faces.push((Face::new(corners.map(|k| c[k]), centre), lattice.h()));
            }
        }
    }
    faces
}

/// The boundary faces of an adaptive body, by the definition, in finest-level squares: a square
/// of a leaf's face is on the surface when the point just across its centre is in no leaf.
fn adaptive_faces(body: &AdaptiveBody) -> Vec<(Face, DVec3)> {
    let lattice = body.lattice();
    let fine = body.spacing(body.finest_level());
    let mut faces = Vec::new();
    for (id, leaf) in body.leaves().iter().enumerate() {
        let low = body.leaf_origin(leaf);
        let size = body.spacing(leaf.level);
        let u = body.cell_displacements(CellId(id as u32)).unwrap();
        let c = local_corners(low - lattice.origin(), size, &u);
        let centre = c.iter().sum::<DVec3>() / 8.0;
        let trilinear = |xi: DVec3| {
            c.iter()
                .enumerate()
                .map(|(k, &p)| {
                    let o = cgcontact::CORNER_OFFSETS[k];
                    (0..3)
                        .map(|a| 0.5 * (1.0 + if o[a] == 1 { xi[a] } else { -xi[a] }))
                        .product::<f64>()
                        * p
                })
                .sum::<DVec3>()
        };
        let per = 1u32 << (body.finest_level() - leaf.level);
        for f in 0..6 {
            let axis = f / 2;
            let side = if f % 2 == 1 { 1.0 } else { -1.0 };
            let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
            for i in 0..per {
                for j in 0..per {
                    let mut p = low;
                    p[a1] += (f64::from(i) + 0.5) * fine[a1];
                    p[a2] += (f64::from(j) + 0.5) * fine[a2];
                    p[axis] += if side > 0.0 {
                        size[axis] + 0.25 * fine[axis]
                    } else {
                        -0.25 * fine[axis]
                    };
                    let outside = p.cmplt(lattice.origin()).any() || p.cmpgt(lattice.upper()).any();
                    if !outside && body.leaf_at(p).is_some() {
                        continue;
                    }
                    let xi = |di: u32, dj: u32| {
                        let mut xi = DVec3::ZERO;
                        xi[axis] = side;
                        xi[a1] = -1.0 + 2.0 * f64::from(i + di) / f64::from(per);
                        xi[a2] = -1.0 + 2.0 * f64::from(j + dj) / f64::from(per);
                        trilinear(xi)
                    };
                    let q = [xi(0, 0), xi(1, 0), xi(1, 1), xi(0, 1)];
                    faces.push((Face::new(q, centre), size));
                }
            }
        }
    }
    faces
}

/// A point (relative to the origin) and what it was made as.
struct Probe {
    local: DVec3,
    kind: &'static str,
}

/// Points on nodes, edges and faces of some of the boundary faces, 1e-9 to 1e-3 of their cell
/// off them along the face's normal on either side; far points, random points around the body
/// and the centres of a few cells.
fn probes(faces: &[(Face, DVec3)], centres: &[DVec3], rng: &mut Rng) -> Vec<Probe> {
    let mut points = Vec::new();
    let step = (faces.len() / 16).max(1);
    for (face, h) in faces.iter().step_by(step) {
        let q = &face.q;
        let mut a = || 2.0 * rng.uniform(0.0, 1.0) - 1.0;
        let sts = [
            (DVec2::new(-1.0, -1.0), "node"),
            (DVec2::new(1.0, a()), "edge"),
            (DVec2::new(a(), a()), "face"),
            (DVec2::new(1.0 - 1e-9, a()), "face by an edge"),
        ];
        for (st, kind) in sts {
            let on = at(q, st.x, st.y);
            let n = normal(q, st.x, st.y);
            for off in [0.0, 1e-9, -1e-9, 1e-6, -1e-6, 1e-3, -1e-3] {
                points.push(Probe {
                    local: on + n * (off * h.min_element()),
                    kind,
                });
            }
        }
    }
    let (lo, hi) = faces
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(l, h), (f, _)| {
            (l.min(f.lo), h.max(f.hi))
        });
    for i in 0..24 {
        let d = rng.vec(-1.0, 1.0).normalize();
        let local = if i % 2 == 0 {
            0.5 * (lo + hi) + d * (hi - lo).length() * rng.uniform(0.6, 2.0)
        } else {
            lo + (hi - lo) * (rng.vec(-0.2, 1.2))
        };
        points.push(Probe {
            local,
            kind: "far or around",
        });
    }
    points.extend(centres.iter().map(|&local| Probe {
        local,
        kind: "deep",
    }));
    points
}

/// The adaptive body's leaves on a 3 × 3 × 2 base lattice: base cell (1, 1, 1) refined once and
/// its upper child again (level jumps of 1 and 2 on the top surface), base cell (0, 0, 0)
/// refined once without its upper child (a cavity), base cell (2, 2, 1) missing.
fn leaves() -> Vec<Leaf> {
    let mut leaves = Vec::new();
    for k in 0..2 {
        for j in 0..3 {
            for i in 0..3 {
                let base = Leaf::new(0, [i, j, k]);
                match (i, j, k) {
                    (2, 2, 1) => {}
                    (1, 1, 1) => {
                        for (c, child) in base.children().into_iter().enumerate() {
                            if c == 7 {
                                leaves.extend(child.children());
                            } else {
                                leaves.push(child);
                            }
                        }
                    }
                    (0, 0, 0) => leaves.extend(base.children().into_iter().take(7)),
                    _ => leaves.push(base),
                }
            }
        }
    }
    leaves
}

/// What one scene measured.
#[derive(Default)]
struct Measured {
    points: usize,
    answered: usize,
    gap_error: f64,
    off_surface: f64,
    sign: usize,
    inward: usize,
    reconstruction: f64,
}

/// Every point of `probes` against the oracle; asserts the contract and returns the largest
/// errors (relative to `h`, the finest spacing).
#[allow(clippy::too_many_arguments)]
fn sweep<L: Surface>(
    case: &str,
    locator: &L,
    settings: Settings,
    finest: DVec3,
    u_range: (DVec3, DVec3),
    origin: DVec3,
    faces: &[(Face, DVec3)],
    probes: &[Probe],
) -> Measured {
    let h = finest.min_element();
    let (lo, hi) = faces
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(l, h), (f, _)| {
            (l.min(f.lo), h.max(f.hi))
        });
    let finder = GapFinder::new(locator, 0.5 * (hi - lo).length()).unwrap();
    let distance = finder.distance();
    // The data's own rounding: coordinates as large as the origin plus the body's extent.
    let magnitude = (origin.abs() + lo.abs().max(hi.abs())).max_element();
    let rounding = 4.0 * f64::EPSILON * magnitude;
    let tol = 2.0 * rounding + 1e-12 * h;
    // Generously, how far outside a cell the locator may hold a point (its allowance in ξ over
    // the largest deformed cell, and the rounding lengths it carries): beyond, x = c + gap·n.
    let frame = Frame::new(settings.precision, u_range.0, u_range.1, finest);
    let inside = InsideTolerance::with_spacing(&settings, origin, finest, frame.reach());
    let largest_cell = faces
        .iter()
        .map(|(f, _)| (f.hi - f.lo).length())
        .fold(0.0, f64::max)
        * 4.0;
    let faces: Vec<Face> = faces
        .iter()
        .map(|(f, _)| Face {
            q: f.q,
            lo: f.lo,
            hi: f.hi,
        })
        .collect();
    let mut m = Measured::default();
    let points: Vec<DVec3> = probes.iter().map(|p| origin + p.local).collect();
    let mut batched = Vec::new();
    finder.gap_all_into(&points, &mut batched);
    for ((probe, &x), batched) in probes.iter().zip(&points).zip(&batched) {
        m.points += 1;
        let xl = x - origin;
        let (dist, _, _, _) = nearest(&faces, xl);
        let got = finder.gap(x).unwrap();
        assert_eq!(*batched, Ok(got), "{case}: {x} batched");
        if (dist - distance).abs() <= 1e-9 * distance {
            continue;
        }
        let Some(c) = got else {
            assert!(
                dist > distance,
                "{case}: {x} ({}) unanswered at {dist:e}",
                probe.kind
            );
            continue;
        };
        assert!(dist <= distance, "{case}: {x} answered beyond D");
        m.answered += 1;
        let what = format!("{case}: {x} ({}): {c:?}", probe.kind);
        let error = (c.gap.abs() - dist).abs();
        assert!(
            error <= tol,
            "{what}: |gap| off the oracle's {dist:e} by {error:e}"
        );
        m.gap_error = m.gap_error.max(error / h);
        // The closest point lies on the surface.
        let cl = c.point - origin;
        let (off, _, _, _) = nearest(&faces, cl);
        assert!(
            off <= tol,
            "{what}: the closest point is {off:e} off the surface"
        );
        m.off_surface = m.off_surface.max(off / h);
        // The sign is the locator's.
        let held = locator.locate(x).unwrap().is_some();
        if c.gap != 0.0 && (c.gap < 0.0) != held {
            m.sign += 1;
        }
        // The normal: a unit vector, not against every face through c.
        assert!((c.normal.length() - 1.0).abs() < 1e-12, "{what}: |n|");
        let near = off + tol + 1e-9 * h;
        let against_all = faces
            .iter()
            .filter(|f| f.box_distance(cl) <= near)
            .filter_map(|f| {
                let (d2, s, t) = closest(&f.q, cl);
                (d2.sqrt() <= near).then(|| c.normal.dot(normal(&f.q, s, t)))
            })
            .all(|d| d < -1e-3);
        if against_all {
            m.inward += 1;
        }
        // x = c + gap·n, beyond the locator's allowance; within it, to 2|gap|.
        let allowance = 8.0 * (inside.xi() * largest_cell + inside.length(x).element_sum()) + tol;
        let miss = (c.point + c.gap * c.normal - x).length();
        let bound = if c.gap.abs() > allowance {
            tol + 1e-9 * c.gap.abs()
        } else {
            2.0 * c.gap.abs() + tol
        };
        assert!(miss <= bound, "{what}: x − c − gap·n = {miss:e}");
        m.reconstruction = m.reconstruction.max(miss / h);
    }
    m
}

/// The sweep (see the module): every scene's gaps, closest points and normals against the
/// oracle. Before the sign was left to the locator within its own allowance (a fixed millionth
/// of the cell, less than f32's inside tolerance and f64's rounding far from the origin), the
/// sign was against the locator's on 7,378 and the normal pointed into the body on 3,081 of
/// these 104,448 points (docs/numerics.md).
#[test]
fn gaps_on_sheared_rotated_anisotropic_and_far_bodies_match_the_oracle() {
    let mut maps = vec![("undeformed", [DVec3::X, DVec3::Y, DVec3::Z])];
    maps.extend(linear_maps());
    let spacings = [
        DVec3::new(4.0, 0.25, 0.002),
        DVec3::new(1.0, 1e-3, 1.0),
        DVec3::splat(1e-6),
    ];
    let origins = [
        DVec3::new(3.0, -2.0, 1.0),
        DVec3::splat(1e5),
        DVec3::splat(-1e8),
    ];
    let mut rng = Rng(0x9a9);
    let (mut scenes, mut total) = (0, 0);
    for (map_name, a) in &maps {
        for h in spacings {
            for origin in origins {
                let field = |x: DVec3| {
                    let r = x - origin;
                    DVec3::new(a[0].dot(r), a[1].dot(r), a[2].dot(r)) - r
                };
                for adaptive in [false, true] {
                    let cells = if adaptive { [3, 3, 2] } else { [3, 3, 3] };
                    // Spacings finer than the coordinates resolve are refused (1e-6 at 1e8).
                    let Ok(lattice) = Lattice::new(origin, h, cells) else {
                        continue;
                    };
                    for (precision, settings) in
                        [("f64", Settings::default()), ("f32", Settings::f32())]
                    {
                        let case = format!(
                            "{map_name} | h {h} | origin {origin} | {} | {precision}",
                            if adaptive { "adaptive" } else { "uniform" }
                        );
                        let m = if adaptive {
                            let mut body = AdaptiveBody::from_leaves(lattice, leaves()).unwrap();
                            body.update_independent(|_, x, u| *u = field(x)).unwrap();
                            let faces = adaptive_faces(&body);
                            let centres: Vec<DVec3> = [0, 9, 20]
                                .iter()
                                .map(|&i| body.point_at(CellId(i), DVec3::ZERO).unwrap() - origin)
                                .collect();
                            let probes = probes(&faces, &centres, &mut rng);
                            let locator = AdaptiveLocator::new(&body, settings).unwrap();
                            let range = range(body.displacements());
                            let finest = body.spacing(body.finest_level());
                            sweep(
                                &case, &locator, settings, finest, range, origin, &faces, &probes,
                            )
                        } else {
                            let mut active = bitvec![1; lattice.cell_count()];
                            for ijk in [[2, 2, 2], [1, 1, 2]] {
                                active.set(lattice.cell_id(ijk).index(), false);
                            }
                            let mut body = Body::undeformed(lattice, active).unwrap();
                            body.update_displacements(|_, x, u| *u = field(x)).unwrap();
                            let faces = uniform_faces(&body);
                            let centres = vec![
                                body.point_at(lattice.cell_id([1, 1, 1]), DVec3::ZERO)
                                    .unwrap()
                                    - origin,
                            ];
                            let probes = probes(&faces, &centres, &mut rng);
                            let locator = LatticeLocator::new(&body, settings).unwrap();
                            let range = range(body.displacements());
                            sweep(&case, &locator, settings, h, range, origin, &faces, &probes)
                        };
                        println!(
                            "MEASURED gaps_on_sheared_rotated_anisotropic_and_far_bodies_match_the_oracle | {case} | points {} | answered {} | max ||gap| − oracle| {:.1e} h | closest point off the surface {:.1e} h | sign ≠ locator {} | normals into the body {} | max |x − c − gap n| {:.1e} h",
                            m.points,
                            m.answered,
                            m.gap_error,
                            m.off_surface,
                            m.sign,
                            m.inward,
                            m.reconstruction
                        );
                        assert_eq!(m.sign, 0, "{case}: gaps whose sign is not the locator's");
                        assert_eq!(m.inward, 0, "{case}: normals into the body");
                        scenes += 1;
                        total += m.points;
                    }
                }
            }
        }
    }
    println!(
        "MEASURED gaps_on_sheared_rotated_anisotropic_and_far_bodies_match_the_oracle | all | scenes {scenes} | points {total}"
    );
}

/// The displacements' range per axis.
fn range(u: &[DVec3]) -> (DVec3, DVec3) {
    u.iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(l, h), &u| {
            (l.min(u), h.max(u))
        })
}

/// A sparse body (a few cells far apart on a 10⁹-cell lattice, kept in hash maps): the search
/// boxes of a long distance hold hundreds of millions of lattice cells and a few of the body's.
/// Gaps, closest points and normals match the oracle, f64 and f32. The search walked every
/// lattice cell of its box before, for minutes per point.
#[test]
fn gaps_on_a_sparse_body_with_cells_far_apart_match_the_oracle() {
    let origin = DVec3::new(-40.0, 12.5, 3.0);
    let h = DVec3::new(0.5, 0.25, 0.4);
    let lattice = Lattice::new(origin, h, [1000; 3]).unwrap();
    let cells: Vec<CellId> = [[10, 20, 30], [11, 20, 30], [11, 21, 30], [900, 950, 990]]
        .into_iter()
        .chain([[500, 10, 700], [500, 10, 701]])
        .map(|ijk| lattice.cell_id(ijk))
        .collect();
    let mut body = Body::from_cells(lattice, cells).unwrap();
    body.update_displacements(|_, x, u| {
        let r = (x - origin) / h;
        *u = DVec3::new(0.2 * (0.01 * r.y).sin(), 0.1 * (0.02 * r.z).cos(), 0.05) * h;
    })
    .unwrap();
    let faces = uniform_faces(&body);
    let centres = vec![
        body.point_at(CellId(cells_of(&body)[0]), DVec3::ZERO)
            .unwrap()
            - origin,
    ];
    let mut rng = Rng(0x5a5);
    let probes = probes(&faces, &centres, &mut rng);
    for settings in [Settings::default(), Settings::f32()] {
        let locator = LatticeLocator::new(&body, settings).unwrap();
        let range = range(body.displacements());
        let m = sweep(
            "sparse", &locator, settings, h, range, origin, &faces, &probes,
        );
        assert!(m.answered > 100, "{} answered", m.answered);
        assert_eq!(m.sign, 0, "gaps whose sign is not the locator's");
        assert_eq!(m.inward, 0, "normals into the body");
    }
}

fn cells_of(body: &Body) -> Vec<u32> {
    body.active_cells().map(|c| c.0).collect()
}

/// On lattice spacings of 1e78 and more, or 1e-80 and less, gaps came out wrong without a word
/// (an audit: `scene block --cells 2,3,4 --h 1e78`, then `locate --gap`: 141 of 258 gaps off,
/// by up to 14 %; at 1e-79 the gaps held but 246 normals did not): the closest point of a face
/// multiplies four of its lengths, which overflowed or underflowed, and a normal's squared
/// length two. The same body and points at each spacing must answer as the unit body does,
/// scaled.
#[test]
fn gaps_at_extreme_spacings_are_those_of_the_unit_body_scaled() {
    let cells = [2, 3, 4];
    // A smooth field in cell units, up to a fifth of a cell.
    let field = |p: DVec3| {
        DVec3::new(
            0.05 * p.y * p.z,
            -0.04 * p.x * p.x,
            0.2 * (0.7 * p.x + 0.3 * p.y).sin(),
        )
    };
    let build = |h: f64| {
        let lattice = Lattice::new(DVec3::ZERO, DVec3::splat(h), cells).unwrap();
        let mut body = Body::undeformed(lattice, bitvec![1; lattice.cell_count()]).unwrap();
        body.update_displacements(|_, x, u| *u = field(x / h) * h)
            .unwrap();
        body
    };
    let mut rng = Rng(0x5ca1e);
    let points: Vec<DVec3> = (0..400)
        .map(|_| {
            DVec3::new(
                rng.uniform(-0.8, 2.8),
                rng.uniform(-0.8, 3.8),
                rng.uniform(-0.8, 4.8),
            )
        })
        .collect();
    let d = 0.7;
    let answers = |h: f64| {
        let body = build(h);
        let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
        let finder = GapFinder::new(&locator, d * h).unwrap();
        points
            .iter()
            .map(|&p| finder.gap(p * h))
            .collect::<Vec<_>>()
    };
    let unit = answers(1.0);
    let answered = unit.iter().filter(|a| matches!(a, Ok(Some(_)))).count();
    assert!(
        answered > 100,
        "only {answered} points within D of the unit body"
    );
    for h in [1e78, 1e90, 1e99, 1e-80, 1e-90, 1e-99] {
        for (i, (want, got)) in unit.iter().zip(answers(h)).enumerate() {
            let x = points[i];
            match (want, &got) {
                (Ok(None), Ok(None)) => {}
                (Ok(Some(w)), Ok(Some(g))) => {
                    let what = format!("h {h:e}, point {i} {x}: {w:?} against {g:?}");
                    assert!((g.gap / h - w.gap).abs() <= 1e-12, "{what}: gap");
                    assert!((g.point / h - w.point).length() <= 1e-11, "{what}: point");
                    assert!((g.normal - w.normal).length() <= 1e-9, "{what}: normal");
                    // On an edge or a corner, the faces meeting there tie: rounding, which
                    // differs from scale to scale, may pick another.
                    if w.interior {
                        assert_eq!(g.face, w.face, "{what}: face");
                    }
                }
                // Only a point at D, to rounding, may be answered at one scale and not another.
                (Ok(Some(w)), Ok(None)) | (Ok(None), Ok(Some(w))) => {
                    let gap = if matches!(want, Ok(Some(_))) {
                        w.gap
                    } else {
                        w.gap / h
                    };
                    assert!(
                        (gap.abs() - d).abs() <= 1e-9,
                        "h {h:e}, point {i} {x}: {want:?} against {got:?}"
                    );
                }
                _ => panic!("h {h:e}, point {i} {x}: {want:?} against {got:?}"),
            }
        }
    }
}
