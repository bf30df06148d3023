//! The lane Newton: W trilinear maps inverted at once, one lane per point, with the scalar
//! kernel's operations in its order and its safeguard constants (`super::NEWTON_BOX` and the
//! rest), so that a lane's answer is bitwise the scalar [`super::Hex8Map`]'s.
//!
//! Every lane that leaves the common path (a singular Jacobian, a line search, an early or late
//! `Outside`, a non-finite value, the iteration limit) is marked, and `locate/batched.rs` answers
//! its point with the scalar search from scratch. The early `Outside` here leaves out the
//! rounding allowance on purpose: the scalar kernel, redoing the lane, applies it, so a point
//! within the allowance is held alike by both paths.

use glam::DVec3;

use crate::hex8::{self, NewtonOptions};
use crate::lanes::{Lanes, MAX_W, Real, V3};

/// W trilinear maps: monomial coefficients 1, ξ, η, ξη, ζ, ξζ, ηζ, ξηζ (as [`crate::hex8::Hex8Map`]).
#[derive(Clone, Copy)]
pub(crate) struct Maps<V> {
    pub a: [V3<V>; 8],
}

impl<V: Lanes> Maps<V> {
    /// The maps of W hexahedra whose corner `c` in lane `l` is `node(l, c)`.
    #[inline(always)]
    pub fn from_nodes<'n>(node: impl Fn(usize, usize) -> &'n V::Node) -> Self
    where
        V::Node: 'n,
    {
        // Written out: `array::from_fn`'s closure is not inlined into the caller's AVX2 context, and
        // a loop over a zeroed array costs a memset call.
        let corner = |c: usize| V::transpose(|l| node(l, c));
        Self::new(&[
            corner(0),
            corner(1),
            corner(2),
            corner(3),
            corner(4),
            corner(5),
            corner(6),
            corner(7),
        ])
    }

    /// The maps of W hexahedra with corners `c` (VTK order): `Hex8Map::new`'s butterfly, the same code.
    #[inline(always)]
    pub fn new(c: &[V3<V>; 8]) -> Self {
        let eighth = V::splat(V::S::of(0.125));
        Self {
            a: hex8::monomials(c, |v: V3<V>| v.scale(eighth)),
        }
    }

    /// `Kernel::add_lattice`: the undeformed part h (1 + ξ) / 2 per axis (zeros added too, as there).
    #[inline(always)]
    pub fn add_lattice(&mut self, h: DVec3) {
        self.add_lattice_lanes(V3::splat(h * 0.5));
    }

    /// [`Maps::add_lattice`] with each lane's own half spacing `half` (cells of several sizes:
    /// the leaves of an adaptive body).
    #[inline(always)]
    pub fn add_lattice_lanes(&mut self, half: V3<V>) {
        let (hx, hy, hz) = (half.x, half.y, half.z);
        let zero = V::splat(V::S::of(0.0));
        let a = &mut self.a;
        a[0] = a[0]
            + V3 {
                x: hx,
                y: hy,
                z: hz,
            };
        a[1] = a[1]
            + V3 {
                x: hx,
                y: zero,
                z: zero,
            };
        a[2] = a[2]
            + V3 {
                x: zero,
                y: hy,
                z: zero,
            };
        a[4] = a[4]
            + V3 {
                x: zero,
                y: zero,
                z: hz,
            };
    }

    /// x(ξ) and the columns of J: `Hex8Map::map_and_jacobian`, the same code.
    #[inline(always)]
    pub fn map_and_jacobian(&self, xi: V3<V>) -> (V3<V>, [V3<V>; 3]) {
        hex8::map_and_jacobian(&self.a, xi.x, xi.y, xi.z, V3::scale)
    }

    /// x(ξ): `Hex8Map::map`, the same code.
    #[inline(always)]
    pub fn map(&self, xi: V3<V>) -> V3<V> {
        hex8::map(&self.a, xi.x, xi.y, xi.z, V3::scale)
    }

    /// `Hex8Map::magnitude`.
    #[inline(always)]
    fn magnitude(&self, x: V3<V>) -> V3<V> {
        let a = &self.a;
        x.abs() + a[0].abs() + (a[1].abs() + a[2].abs() + a[4].abs())
    }

    /// `Hex8Map::step_noise`.
    #[inline(always)]
    fn step_noise(&self, m: V3<V>, k: [V3<V>; 3], inv_det: V) -> V {
        let zero = V::splat(V::S::of(0.0));
        let inverse_norm = zero
            .max(weighted(k[0], m))
            .max(weighted(k[1], m))
            .max(weighted(k[2], m))
            * inv_det.abs();
        V::splat(V::S::of(16.0)) * V::splat(V::EPSILON) * inverse_norm
    }

    /// `Hex8Map::det_at_center`.
    #[inline(always)]
    fn det_at_center(&self) -> V {
        self.a[1].dot(self.a[2].cross(self.a[4]))
    }

    /// The common path of `Hex8Map::invert` for W points at once: plain Newton steps, no line search.
    /// `inside` is 1 + the inside tolerance's ξ part, per axis: a lane converged beyond it ends
    /// here not `Inside`, and the scalar kernel, redoing it, adds the rounding allowance carried
    /// through J⁻¹ (`NewtonOptions::inside_length`). Those are points within that allowance of a
    /// face, and this keeps the lanes' loop as short as it was: computing the allowance in lanes
    /// cost 2 % more instructions on the `big` block. Lanes with `take` unset are ignored.
    /// Returns, per lane, the final ξ, |residual|², the iterations and whether the lane ended
    /// `Inside` on the common path (the scalar kernel then gives exactly this answer); a lane not
    /// `Inside` must be redone.
    #[inline(always)]
    pub fn invert(
        &self,
        x: V3<V>,
        xi0: V3<V>,
        inside: V3<V>,
        take: V::Mask,
        options: &NewtonOptions,
    ) -> (V3<V>, V, [u32; MAX_W], u32) {
        let tol = V::splat(V::S::of(options.tol));
        let det_floor = V::splat(V::S::of(options.det_ratio_min)) * self.det_at_center().abs();
        // The scalar kernel's safeguards (`hex8`), so that both loops take the same decisions.
        let line_search_above = V::splat(V::S::of(hex8::LINE_SEARCH_ABOVE));
        let early_outside_step = V::splat(V::S::of(hex8::EARLY_OUTSIDE_STEP));
        let margin = V::splat(V::S::of(hex8::EARLY_OUTSIDE_MARGIN));
        let early_outside = V3 {
            x: inside.x + margin,
            y: inside.y + margin,
            z: inside.z + margin,
        };
        let (low, high) = (V::S::of(-hex8::NEWTON_BOX), V::S::of(hex8::NEWTON_BOX));
        let magnitude = self.magnitude(x);
        let mut xi = xi0.clamp(V::S::of(-1.0), V::S::of(1.0));
        let (fx, mut jac) = self.map_and_jacobian(xi);
        let mut r = x - fx;
        let mut rr = r.dot(r);
        let mut pending = take;
        let mut found = V::mask_from_bits(0);
        let mut iterations = [0u32; MAX_W];
        for iteration in 1..=options.max_iter {
            let [c0, c1, c2] = jac;
            let k0 = c1.cross(c2);
            let det = c0.dot(k0);
            let singular = det.is_nan() | det.le(det_floor);
            let (k1, k2) = (c2.cross(c0), c0.cross(c1));
            let inv_det = det.recip();
            let delta = V3 {
                x: k0.dot(r),
                y: k1.dot(r),
                z: k2.dot(r),
            }
            .scale(inv_det);
            let size = delta.abs().max_element();
            let converged =
                size.le(tol) | size.le(self.step_noise(magnitude, [k0, k1, k2], inv_det));
            // The converged lanes take the full step; the others the step clamped to the box.
            let sum = xi + delta;
            let trial = V3::select(converged, sum, sum.clamp(low, high));
            let (f_trial, jac_trial) = self.map_and_jacobian(trial);
            let r_trial = x - f_trial;
            let rr_trial = r_trial.dot(r_trial);
            let finite = trial.is_finite() & rr_trial.is_finite() & delta.is_finite();
            let far = trial.abs();
            let within = far.x.le(inside.x) & far.y.le(inside.y) & far.z.le(inside.z);
            // Converged: Inside, or (Outside / not finite) left to the scalar search.
            let inside_now = pending & !singular & converged & finite & within;
            // Not converged: a step the scalar kernel would shorten (line search), a non-finite value
            // or an early Outside all leave the common path.
            let line_search = rr_trial.gt(rr) & size.gt(line_search_above);
            let moved = (trial - xi).abs().max_element();
            let beyond =
                far.x.gt(early_outside.x) | far.y.gt(early_outside.y) | far.z.gt(early_outside.z);
            let early_out = moved.lt(early_outside_step) & beyond;
            let go_on = pending & !(converged | singular | line_search | early_out) & finite;
            let keep = inside_now | go_on;
            xi = V3::select(keep, trial, xi);
            rr = V::select(keep, rr_trial, rr);
            r = V3::select(go_on, r_trial, r);
            jac = [
                V3::select(go_on, jac_trial[0], jac[0]),
                V3::select(go_on, jac_trial[1], jac[1]),
                V3::select(go_on, jac_trial[2], jac[2]),
            ];
            let now = V::bits(inside_now);
            for (l, iterations) in iterations.iter_mut().enumerate().take(V::W) {
                if now & (1 << l) != 0 {
                    *iterations = iteration;
                }
            }
            found = found | inside_now;
            pending = go_on;
            if !V::any(pending) {
                break;
            }
        }
        (xi, rr, iterations, V::bits(found))
    }
}

/// Σ_j |row_j| m_j, in the order `Hex8Map::step_noise` adds it: a plain function, always
/// inlined (as a closure it was called out of line in the adaptive lanes, 28 % more instructions).
#[inline(always)]
fn weighted<V: Lanes>(row: V3<V>, m: V3<V>) -> V {
    let t = row.abs();
    t.x * m.x + t.y * m.y + t.z * m.z
}
