//! The closest point of a bilinear quad to a point: exact, whatever the quad's distortion.
//!
//! A face of a deformed hexahedron is the bilinear patch
//! S(s, t) = a + b·s + c·t + d·s·t, (s, t) ∈ [−1, 1]², through its corners q0 (−1, −1), q1 (1, −1),
//! q2 (1, 1) and q3 (−1, 1). The minimum of |S − x|² over the closed square lies on one of the
//! four edges (straight segments: a closed form) or at an interior stationary point, found by
//! Newton's method on the gradient. When the function is convex on the square (a certificate
//! below, true of every face that is not strongly twisted near the point), the stationary point
//! is unique and one descent finds it. Otherwise the square is split into quarters (each a
//! bilinear patch again), quarters whose corners' bounding box is farther than the best point so
//! far are dropped, and the rest certified or split again: branch and bound, exact to rounding.

use glam::{DVec2, DVec3};

/// Where on the quad the closest point lies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Locus {
    /// Inside the face (−1 < s, t < 1): the normal is the face's.
    Interior,
    /// On an edge or a corner of the face.
    Boundary,
}

/// The closest point of a quad.
#[derive(Clone, Copy, Debug)]
pub(crate) struct QuadPoint {
    /// Squared distance.
    pub d2: f64,
    /// Face coordinates, in [−1, 1]².
    pub st: DVec2,
    /// The point S(s, t).
    pub point: DVec3,
    pub locus: Locus,
}

/// A bilinear patch in power form.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Patch {
    a: DVec3,
    b: DVec3,
    c: DVec3,
    d: DVec3,
}

/// Newton iterations for one stationary point (quadratic convergence: a handful suffice).
const NEWTON_ITERATIONS: u32 = 40;
/// Depth of the branch and bound (4^8 quarters at most, never reached in practice).
const MAX_DEPTH: u32 = 8;

impl Patch {
    /// The patch through corners `q` (q0 at (−1, −1), q1 (1, −1), q2 (1, 1), q3 (−1, 1)).
    #[inline]
    pub(crate) fn new(q: &[DVec3; 4]) -> Self {
        Self {
            a: 0.25 * (q[0] + q[1] + q[2] + q[3]),
            b: 0.25 * (-q[0] + q[1] + q[2] - q[3]),
            c: 0.25 * (-q[0] - q[1] + q[2] + q[3]),
            d: 0.25 * (q[0] - q[1] + q[2] - q[3]),
        }
    }

    /// S(s, t).
    #[inline]
    pub(crate) fn at(&self, st: DVec2) -> DVec3 {
        self.a + self.b * st.x + self.c * st.y + self.d * (st.x * st.y)
    }

    /// ∂S/∂s × ∂S/∂t at `st`: along the outward normal for faces listed counter-clockwise seen
    /// from outside.
    #[inline]
    pub(crate) fn normal(&self, st: DVec2) -> DVec3 {
        (self.b + self.d * st.y).cross(self.c + self.d * st.x)
    }

    /// The start of the descent: x projected onto the parallelogram a + b·s + c·t (the patch
    /// without its twist), in the square; the centre when that is degenerate. Exact for an
    /// untwisted face, within the twist's order otherwise.
    #[inline]
    fn flat_guess(&self, x: DVec3) -> DVec2 {
        let r = x - self.a;
        let (bb, bc, cc) = (self.b.dot(self.b), self.b.dot(self.c), self.c.dot(self.c));
        let det = bb * cc - bc * bc;
        // (NaN, from a degenerate face, fails the test too.)
        if det.is_nan() || det <= 1e-12 * bb * cc {
            return DVec2::ZERO;
        }
        let (rb, rc) = (r.dot(self.b), r.dot(self.c));
        DVec2::new((cc * rb - bc * rc) / det, (bb * rc - bc * rb) / det)
            .clamp(DVec2::NEG_ONE, DVec2::ONE)
    }

    /// The sub-patch over [s0, s1] × [t0, t1] (itself a bilinear patch), by its corners.
    pub(crate) fn sub(&self, lo: DVec2, hi: DVec2) -> [DVec3; 4] {
        [
            self.at(lo),
            self.at(DVec2::new(hi.x, lo.y)),
            self.at(hi),
            self.at(DVec2::new(lo.x, hi.y)),
        ]
    }

    /// Whether |S − x|² is convex on the whole patch: its Hessian JᵀJ + (r·d)·[[0, 1], [1, 0]]
    /// (r = S − x) is positive definite when the smallest eigenvalue of JᵀJ, at least
    /// |Sₛ × Sₜ|² / (|Sₛ|² + |Sₜ|²), exceeds |r·d|. Over the square,
    /// r·d = (a − x)·d + (b·d)·s + (c·d)·t + (d·d)·s·t, so |r·d| ≤ |(a − x)·d| + |b·d| + |c·d| + |d|²
    /// (small for a point near a face twisted along its normal); Sₛ × Sₜ = b×c + s·(b×d) + t·(d×c)
    /// is affine in (s, t), so |b×c| − |b×d| − |d×c| bounds its length from below.
    fn convex_for(&self, x: DVec3) -> bool {
        let dd = self.d.length_squared();
        if dd == 0.0 {
            // A parallelogram: |S − x|² is a convex quadratic.
            return true;
        }
        let n_low = self.b.cross(self.c).length()
            - self.b.cross(self.d).length()
            - self.d.cross(self.c).length();
        if n_low <= 0.0 {
            return false;
        }
        let d = dd.sqrt();
        let bl = self.b.length() + d;
        let cl = self.c.length() + d;
        let twist = (self.a - x).dot(self.d).abs()
            + self.b.dot(self.d).abs()
            + self.c.dot(self.d).abs()
            + dd;
        // With a margin for rounding: a wrong "convex" would be the only way to miss a minimum.
        n_low * n_low > 1.01 * (bl * bl + cl * cl) * twist
    }

    /// A bound on the rounding of each component of S(s, t) − x as [`Patch::at`] computes it:
    /// a few units in the last place of the largest term.
    #[inline]
    fn rounding(&self, x: DVec3) -> f64 {
        let terms = self.a.abs() + self.b.abs() + self.c.abs() + self.d.abs() + x.abs();
        8.0 * f64::EPSILON * terms.max_element()
    }

    /// Newton's method on ∇|S − x|²/2 from `st`, with backtracking and a projection that keep it
    /// in the square [lo, hi] (a sub-square of [−1, 1]²) and never uphill (beyond the rounding of
    /// |S − x|²): the interior stationary point it converges to, if any (`None` when it stalls
    /// against the border, whose points the edges cover).
    fn descend(&self, x: DVec3, mut st: DVec2, lo: DVec2, hi: DVec2) -> Option<DVec2> {
        let r0 = self.a - x;
        let rounding = self.rounding(x);
        for _ in 0..NEWTON_ITERATIONS {
            let ss = self.b + self.d * st.y;
            let sc = self.c + self.d * st.x;
            let r = r0 + self.b * st.x + self.c * st.y + self.d * (st.x * st.y);
            let g = DVec2::new(r.dot(ss), r.dot(sc));
            let h00 = ss.dot(ss);
            let h11 = sc.dot(sc);
            let h01 = ss.dot(sc);
            let mut h01_full = h01 + r.dot(self.d);
            let mut det = h00 * h11 - h01_full * h01_full;
            if !(det > 0.0 && h00 > 0.0) {
                // Not convex here: a Gauss-Newton step, still a descent direction.
                h01_full = h01;
                det = h00 * h11 - h01 * h01;
                if det.is_nan() || det <= 0.0 {
                    return None;
                }
            }
            let step = DVec2::new(
                -(h11 * g.x - h01_full * g.y) / det,
                -(h00 * g.y - h01_full * g.x) / det,
            );
            // Quadratic convergence: after a step this small the next would be below rounding
            // (and rounding may then make any step look uphill). A step that moves the point by
            // less than its own rounding is converged too, whatever it is in (s, t) (a thin face).
            let shift = (ss * step.x + sc * step.y).abs().max_element();
            if step.abs().max_element() <= 1e-13 || shift <= rounding {
                st = (st + step).clamp(lo, hi);
                // A stationary point strictly inside the whole face (border points are the
                // edges').
                return (st.x.abs() < 1.0 && st.y.abs() < 1.0).then_some(st);
            }
            // Backtracking: the step is a descent direction (the Hessian, or JᵀJ, is positive
            // definite), so some fraction of it, projected onto the square, does not go uphill,
            // unless the minimum of this start is on the square's border (then the edges have it).
            let f0 = r.length_squared();
            // Not uphill, up to the rounding of |S − x|² itself: near the minimum a good step
            // may not lower its rounded value. That rounding is absolute, 2|r|·(S − x's
            // rounding), not relative: for a point 1e-8·h from the face it is 1e-10 of |S − x|²,
            // and a relative slack alone made every step of the last few look uphill, the descent
            // give up a point 1e-12 from the minimum and the face's edge answer instead.
            let slack = f0 * 1e-14 + 4.0 * rounding * f0.sqrt();
            let mut scale = 1.0;
            let next = loop {
                // Where the step leaves the square, its projection onto it: a minimum just inside
                // the border (a point just inside a body, near an edge) is then reached at once,
                // where shortening the step to stay inside crawled towards the border and gave up.
                let next = (st + step * scale).clamp(lo, hi);
                if (self.at(next) - x).length_squared() <= f0 + slack {
                    break next;
                }
                scale *= 0.5;
                if scale < 1.0 / 1024.0 {
                    return None;
                }
            };
            // Held by the border, moving the point less than its rounding: the minimum of this
            // start is on the square's border.
            let held = next != st + step * scale;
            let moved = next - st;
            if held && (ss * moved.x + sc * moved.y).abs().max_element() <= rounding {
                return None;
            }
            st = next;
        }
        None
    }

    /// Offers the interior stationary point reached from the centre of [lo, hi] to `best`.
    fn offer_interior(&self, x: DVec3, lo: DVec2, hi: DVec2, best: &mut QuadPoint) {
        if let Some(st) = self.descend(x, 0.5 * (lo + hi), lo, hi) {
            let point = self.at(st);
            let d2 = (point - x).length_squared();
            if d2 < best.d2 {
                *best = QuadPoint {
                    d2,
                    st,
                    point,
                    locus: Locus::Interior,
                };
            }
        }
    }

    /// Branch and bound over [lo, hi]: quarters farther than `best` are dropped, convex ones
    /// descended, the rest split.
    fn search(&self, x: DVec3, lo: DVec2, hi: DVec2, depth: u32, best: &mut QuadPoint) {
        let corners = self.sub(lo, hi);
        let (mut low, mut high) = (corners[0], corners[0]);
        for &q in &corners[1..] {
            low = low.min(q);
            high = high.max(q);
        }
        if box_distance2(x, low, high) > best.d2 {
            return;
        }
        if depth == MAX_DEPTH || Patch::new(&corners).convex_for(x) {
            self.offer_interior(x, lo, hi, best);
            return;
        }
        let mid = 0.5 * (lo + hi);
        for (l, h) in [
            (lo, mid),
            (DVec2::new(mid.x, lo.y), DVec2::new(hi.x, mid.y)),
            (DVec2::new(lo.x, mid.y), DVec2::new(mid.x, hi.y)),
            (mid, hi),
        ] {
            self.search(x, l, h, depth + 1, best);
        }
    }
}

/// Squared distance from `x` to the box [low, high] (0 inside).
#[inline]
pub(crate) fn box_distance2(x: DVec3, low: DVec3, high: DVec3) -> f64 {
    (low - x).max(x - high).max(DVec3::ZERO).length_squared()
}

/// The closest point of segment p → q to `x`, as (parameter in [0, 1], point).
#[inline]
fn on_segment(x: DVec3, p: DVec3, q: DVec3) -> (f64, DVec3) {
    let e = q - p;
    let ee = e.length_squared();
    let u = if ee > 0.0 {
        ((x - p).dot(e) / ee).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (u, p + e * u)
}

/// The closest point of the quad with corners `q` to `x` (exact to rounding; see the module).
#[cfg(test)]
fn closest(x: DVec3, q: &[DVec3; 4]) -> QuadPoint {
    closest_below(x, q, f64::INFINITY).expect("every quad has a point closer than infinity")
}

/// [`closest`], or `None` when no point of the quad is within squared distance `bound` (the
/// search is then cut short).
///
/// The convexity certificate and the descent's determinant multiply four lengths of the face:
/// on a lattice spacing of 1e78 they overflowed, on 1e-80 they underflowed, and gaps came out
/// wrong (`gaps_at_extreme_spacings_are_those_of_the_unit_body_scaled`). A quad whose extent is
/// beyond 2^±64 is therefore measured scaled by a power of two, which is exact: the answer is
/// the unscaled one's to rounding, and between those extents nothing changes, bit for bit.
pub(crate) fn closest_below(x: DVec3, q: &[DVec3; 4], bound: f64) -> Option<QuadPoint> {
    let extent = q[1..]
        .iter()
        .fold(0.0f64, |m, &p| m.max((p - q[0]).abs().max_element()));
    let Some(k) = scale_exponent(extent) else {
        return closest_below_unscaled(x, q, bound);
    };
    let s = 2f64.powi(k);
    let scaled = closest_below_unscaled(x * s, &q.map(|p| p * s), bound * s * s)?;
    let (back, back2) = (2f64.powi(-k), 2f64.powi(-2 * k));
    let d2 = scaled.d2 * back2;
    (d2 <= bound).then_some(QuadPoint {
        d2,
        point: scaled.point * back,
        ..scaled
    })
}

/// The power of two to scale lengths of magnitude `extent` by so that products of four of them
/// stay within f64's range, `None` when they do already (or the extent is 0 or not finite).
pub(crate) fn scale_exponent(extent: f64) -> Option<i32> {
    const LIMIT: f64 = 18_446_744_073_709_551_616.0; // 2^64
    if !extent.is_finite() || extent == 0.0 || (1.0 / LIMIT..=LIMIT).contains(&extent) {
        return None;
    }
    // −⌊log2 extent⌋, from the exponent bits (the extent is normal: at least 2^−1022 for any
    // lattice spacing of at least 1e-100).
    let exponent = ((extent.to_bits() >> 52) & 0x7ff) as i32 - 1023;
    Some(-exponent)
}

/// A unit vector along `n`, or zero: [`DVec3::normalize_or_zero`], with `n` first scaled by a
/// power of two (exactly) when its squared length would overflow or underflow (a face normal
/// is a product of two lengths: 1e156 on a spacing of 1e78).
#[inline]
pub(crate) fn unit(n: DVec3) -> DVec3 {
    match scale_exponent(n.abs().max_element()) {
        Some(k) => (n * 2f64.powi(k)).normalize_or_zero(),
        None => n.normalize_or_zero(),
    }
}

/// [`closest_below`] without the scaling.
fn closest_below_unscaled(x: DVec3, q: &[DVec3; 4], bound: f64) -> Option<QuadPoint> {
    let patch = Patch::new(q);
    let (lo, hi) = (DVec2::NEG_ONE, DVec2::ONE);
    let convex = patch.convex_for(x);
    if convex {
        // A stationary point of a convex function is its minimum: the edges need no look.
        if let Some(st) = patch.descend(x, patch.flat_guess(x), lo, hi) {
            let point = patch.at(st);
            let d2 = (point - x).length_squared();
            return (d2 <= bound).then_some(QuadPoint {
                d2,
                st,
                point,
                locus: Locus::Interior,
            });
        }
    }
    let mut best = QuadPoint {
        d2: f64::INFINITY,
        st: DVec2::ZERO,
        point: q[0],
        locus: Locus::Boundary,
    };
    // The edges, each a straight segment: from corner, to corner, and their face coordinates.
    let edges = [
        (0, 1, DVec2::new(-1.0, -1.0), DVec2::new(1.0, -1.0)),
        (1, 2, DVec2::new(1.0, -1.0), DVec2::new(1.0, 1.0)),
        (3, 2, DVec2::new(-1.0, 1.0), DVec2::new(1.0, 1.0)),
        (0, 3, DVec2::new(-1.0, -1.0), DVec2::new(-1.0, 1.0)),
    ];
    for (p, e, from, to) in edges {
        let (u, point) = on_segment(x, q[p], q[e]);
        let d2 = (point - x).length_squared();
        if d2 < best.d2 {
            best = QuadPoint {
                d2,
                st: from + (to - from) * u,
                point,
                locus: Locus::Boundary,
            };
        }
    }
    // Convex without an interior stationary point found, or not convex: the branch and bound
    // (quarters farther than the edges' best are dropped at once). The descent from the flat
    // guess alone could stall short of an interior minimum (backtracking defeated by rounding
    // near it), and the edges then gave a far point: a face 0.0024 away was answered 0.22.
    patch.search(x, lo, hi, 0, &mut best);
    (best.d2 <= bound).then_some(best)
}

/// The closest point to `x` of the surface `at` over [−1, 1]², by brute force: the best of an
/// (n + 1)² grid, then a pattern search (8 directions, halving the step) down to 1e-15. The
/// tests' oracle, sharing nothing with the search above.
#[cfg(test)]
pub(crate) fn grid_oracle(x: DVec3, at: impl Fn(DVec2) -> DVec3, n: u32) -> (f64, DVec2) {
    let mut best = (f64::INFINITY, DVec2::ZERO);
    for i in 0..=n {
        for j in 0..=n {
            let st = DVec2::new(
                -1.0 + 2.0 * f64::from(i) / f64::from(n),
                -1.0 + 2.0 * f64::from(j) / f64::from(n),
            );
            let d2 = (at(st) - x).length_squared();
            if d2 < best.0 {
                best = (d2, st);
            }
        }
    }
    let (mut d2, mut st) = best;
    let mut step = 2.0 / f64::from(n);
    while step > 1e-15 {
        let mut improved = false;
        for dir in [
            DVec2::X,
            -DVec2::X,
            DVec2::Y,
            -DVec2::Y,
            DVec2::ONE,
            -DVec2::ONE,
            DVec2::new(1.0, -1.0),
            DVec2::new(-1.0, 1.0),
        ] {
            let cand = (st + dir * step).clamp(DVec2::NEG_ONE, DVec2::ONE);
            let c2 = (at(cand) - x).length_squared();
            if c2 < d2 {
                (d2, st) = (c2, cand);
                improved = true;
            }
        }
        if !improved {
            step *= 0.5;
        }
    }
    (d2, st)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An independent answer: the best of a dense grid of the patch, polished by a pattern
    /// search (no Newton, no certificate, no edges' closed form).
    fn oracle(x: DVec3, q: &[DVec3; 4]) -> (f64, DVec2) {
        let patch = Patch::new(q);
        grid_oracle(x, |st| patch.at(st), 200)
    }

    /// The top face of a cell deformed by a few per cent (found by a sweep against a brute-force
    /// distance): the descent from the flat guess stalled short of the interior minimum, 0.0024
    /// away, and the edges gave 0.22 on the far side. The branch and bound now runs whenever the
    /// descent finds no interior point.
    #[test]
    fn a_stalled_descent_still_finds_the_interior_minimum() {
        let q = [
            DVec3::new(0.0 + 0.05781349112503158, 1.0, 0.0),
            DVec3::new(1.0 + 0.05781349112503158, 1.0, -0.018),
            DVec3::new(
                1.0 + 0.044742312730603216,
                1.0 + 0.04589053123706931,
                1.0 + 0.036557845609540895,
            ),
            DVec3::new(0.044742312730603216, 1.06, 1.0545578456095409),
        ];
        let x = DVec3::new(0.2721516826520029, 1.039278682670109, 0.6801891300234523);
        let found = closest(x, &q);
        let (d2, _) = oracle(x, &q);
        assert!(
            (found.d2.sqrt() - d2.sqrt()).abs() < 1e-9,
            "{} against {}",
            found.d2.sqrt(),
            d2.sqrt()
        );
    }

    fn unit_square() -> [DVec3; 4] {
        [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ]
    }

    #[test]
    fn flat_square_interior_edges_and_corners() {
        let q = unit_square();
        // Above the middle: interior, distance 2.
        let p = closest(DVec3::new(0.25, 0.75, 2.0), &q);
        assert_eq!(p.locus, Locus::Interior);
        assert!((p.d2 - 4.0).abs() < 1e-14);
        assert!((p.point - DVec3::new(0.25, 0.75, 0.0)).length() < 1e-15);
        assert!((p.st - DVec2::new(-0.5, 0.5)).length() < 1e-15);
        // Beside an edge.
        let p = closest(DVec3::new(0.5, -1.0, 1.0), &q);
        assert_eq!(p.locus, Locus::Boundary);
        assert!((p.point - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-15);
        assert!((p.d2 - 2.0).abs() < 1e-14);
        // Beyond a corner.
        let p = closest(DVec3::new(2.0, 3.0, -1.0), &q);
        assert_eq!(p.point, q[2]);
        assert_eq!(p.st, DVec2::ONE);
        // On the face: distance 0.
        let p = closest(DVec3::new(0.3, 0.6, 0.0), &q);
        assert!(p.d2 < 1e-30);
    }

    #[test]
    fn normal_points_along_s_cross_t() {
        let patch = Patch::new(&unit_square());
        let n = patch.normal(DVec2::ZERO);
        assert!(n.x.abs() < 1e-15 && n.y.abs() < 1e-15 && n.z > 0.0);
    }

    /// A twisted quad (a saddle) and a point on its concave side, where |S − x|² has two local
    /// minima inside the face: the closest point must be the lower one, as the oracle says.
    #[test]
    fn saddle_with_two_candidate_roots() {
        // z = k s t: a hyperbolic paraboloid.
        let k = 1.0;
        let q = [
            DVec3::new(-1.0, -1.0, k),
            DVec3::new(1.0, -1.0, -k),
            DVec3::new(1.0, 1.0, k),
            DVec3::new(-1.0, 1.0, -k),
        ];
        let mut several = 0;
        for (i, x) in [
            DVec3::new(0.05, 0.0, 1.5),
            DVec3::new(0.0, 0.02, 2.0),
            DVec3::new(0.3, 0.2, 1.2),
            DVec3::new(-0.1, 0.05, -1.7),
            DVec3::new(0.0, 0.0, 3.0),
        ]
        .into_iter()
        .enumerate()
        {
            let patch = Patch::new(&q);
            if !patch.convex_for(x) {
                several += 1;
            }
            let got = closest(x, &q);
            let (d2, _) = oracle(x, &q);
            assert!(
                (got.d2.sqrt() - d2.sqrt()).abs() < 1e-10,
                "point {i}: {} against oracle {}",
                got.d2.sqrt(),
                d2.sqrt()
            );
            assert!(((got.point - x).length_squared() - got.d2).abs() < 1e-12);
        }
        assert!(several > 0, "the scene must exercise the branch and bound");
        // Two local minima inside the face, on either side of the saddle: one descent from the
        // centre cannot know which is lower.
        let x = DVec3::new(0.05, 0.0, 1.5);
        let patch = Patch::new(&q);
        let roots: Vec<f64> = [DVec2::splat(0.5), DVec2::splat(-0.5)]
            .into_iter()
            .filter_map(|start| patch.descend(x, start, DVec2::NEG_ONE, DVec2::ONE))
            .map(|st| (patch.at(st) - x).length_squared())
            .collect();
        assert_eq!(roots.len(), 2);
        assert!((roots[0] - roots[1]).abs() > 1e-6, "{roots:?}");
        let got = closest(x, &q);
        assert!((got.d2 - roots[0].min(roots[1])).abs() < 1e-12);
    }

    /// Random distorted quads and points around them, against the oracle.
    #[test]
    fn random_quads_match_the_oracle() {
        let mut seed = 0x1234_5678_9abc_def0_u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for case in 0..300 {
            let distortion = if case % 3 == 0 { 0.6 } else { 0.1 };
            let mut q = unit_square();
            for c in &mut q {
                *c += DVec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * distortion;
            }
            let x = DVec3::new(next() * 2.0 - 0.5, next() * 2.0 - 0.5, next() * 1.6 - 0.8);
            let got = closest(x, &q);
            let (d2, _) = oracle(x, &q);
            assert!(
                got.d2.sqrt() <= d2.sqrt() + 1e-10,
                "case {case}: {} worse than the oracle's {}",
                got.d2.sqrt(),
                d2.sqrt()
            );
            assert!(
                got.d2.sqrt() >= d2.sqrt() - 1e-9,
                "case {case}: {} below the oracle's {}: not a point of the quad",
                got.d2.sqrt(),
                d2.sqrt()
            );
            let patch = Patch::new(&q);
            assert!((patch.at(got.st) - got.point).length() < 1e-14);
        }
    }

    #[test]
    fn degenerate_quads() {
        // Two corners merged (a triangle) and a quad collapsed to a segment.
        let mut q = unit_square();
        q[2] = q[1];
        let x = DVec3::new(0.9, 0.9, 0.1);
        let (d2, _) = oracle(x, &q);
        assert!((closest(x, &q).d2.sqrt() - d2.sqrt()).abs() < 1e-10);
        let q = [DVec3::ZERO, DVec3::X, DVec3::X, DVec3::ZERO];
        let p = closest(DVec3::new(0.5, 1.0, 0.0), &q);
        assert!((p.d2 - 1.0).abs() < 1e-14);
    }

    #[test]
    fn bound_cuts_far_quads() {
        let q = unit_square();
        assert!(closest_below(DVec3::new(0.5, 0.5, 2.0), &q, 3.9).is_none());
        assert!(closest_below(DVec3::new(0.5, 0.5, 2.0), &q, 4.0 + 1e-12).is_some());
    }
}
