//! The trilinear hexahedron: shape functions, map, Jacobian, and the Newton inversion x → ξ.
//!
//! The map of a hexahedron with corners `x_c` (VTK order) is `x(ξ) = Σ N_c(ξ) x_c`,
//! `N_c = (1 + ξ ξ_c)(1 + η η_c)(1 + ζ ζ_c) / 8`. Expanded in monomials it is
//! `a0 + a1 ξ + a2 η + a3 ξη + a4 ζ + a5 ξζ + a6 ηζ + a7 ξηζ`; the 8 vector coefficients are
//! computed once per cell (24 additions, a butterfly), after which one map-and-Jacobian evaluation
//! costs about 20 multiply-adds (separate multiplies and adds: no fused multiply-add, so that
//! every lane type and the scalar kernel round alike). This is what makes one Newton iteration
//! cheap.
//!
//! One source serves both precisions: [`Hex8Map`] (f64, `DVec3`) and [`Hex8Map32`] (f32, glam's SIMD
//! `Vec3A`) are stamped from the same macro. Callers work in a cell's *local frame* (corners relative
//! to the cell's lowest lattice node), so magnitudes are of order h whatever the global coordinates;
//! that is what keeps f32 accurate far from the origin.

use std::ops::{Add, Sub};

use glam::{DVec3, Vec3A};

pub(crate) mod lanes;

/// Newton's safeguards, shared by the scalar kernel and the SIMD lanes (`hex8/lanes.rs`) so that the two
/// loops cannot drift apart: iterates are kept in [−`NEWTON_BOX`, `NEWTON_BOX`]³, a step larger
/// than `LINE_SEARCH_ABOVE` that does not reduce the residual is backtracked, and an iterate
/// moving by less than `EARLY_OUTSIDE_STEP` while more than `EARLY_OUTSIDE_MARGIN` past the inside
/// limit, widened by the rounding allowance, is `Outside` at once. (The lanes test the limit
/// without the allowance and hand such a lane to the scalar kernel, which applies it.)
pub(crate) const NEWTON_BOX: f64 = 4.0;
pub(crate) const LINE_SEARCH_ABOVE: f64 = 1e-3;
pub(crate) const EARLY_OUTSIDE_STEP: f64 = 1e-3;
/// Iterates an early `Outside` may be held back by the rounding allowance before it is taken:
/// Newton converging there needs a few; one that stalls there (with `max_iter` at `u32::MAX`, a
/// hostile-settings test ran for minutes) must still end.
pub(crate) const EARLY_OUTSIDE_HOLDS: u32 = 8;
pub(crate) const EARLY_OUTSIDE_MARGIN: f64 = 1e-2;

/// Sign of each corner's local coordinate, VTK order: corner `c` sits at `CORNER_XI[c]`.
pub const CORNER_XI: [[f64; 3]; 8] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

/// How many times the iteration limit a second Newton run gets, from the cell's centre, where
/// the first reached the limit and the cell may hold the point (see `Hex8Map::invert`).
pub const PATIENT_ITERATIONS: u32 = 16;

/// Trilinear shape functions at `xi`, VTK corner order.
#[inline]
#[must_use]
pub fn shape(xi: DVec3) -> [f64; 8] {
    CORNER_XI.map(|[a, b, c]| (1.0 + a * xi.x) * (1.0 + b * xi.y) * (1.0 + c * xi.z) / 8.0)
}

/// Settings of one Newton inversion, in f64 whatever the precision of the kernel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonOptions {
    /// Stop when the Newton step's largest component is at most this (ξ units).
    pub tol: f64,
    /// Iteration limit.
    pub max_iter: u32,
    /// The result is inside when every |ξ_k| ≤ 1 + `inside_tol`'s component k, up to a
    /// perturbation of the point by `inside_length`.
    pub inside_tol: DVec3,
    /// How far the point and the map may be off by rounding, per component (lengths, the frame's
    /// units): the result is inside when some perturbation δ, |δ_j| ≤ `inside_length`_j, brings
    /// ξ + J⁻¹ δ within `inside_tol`, so that a cell of any shape accepts every point within that
    /// much of it and no more ([`crate::InsideTolerance`]). J is the cell's, at ξ clamped to
    /// [−1, 1]³.
    pub inside_length: DVec3,
    /// Give up (singular) when det J falls to this fraction of the cell's det J at ξ = 0 or below.
    pub det_ratio_min: f64,
}

impl NewtonOptions {
    /// Checks that every value is one the kernel can use: `tol`, each component of `inside_tol`
    /// and of `inside_length` finite and ≥ 0, `det_ratio_min` in [0, 1). (`max_iter` may be any
    /// count; with 0 no iteration runs and the inversion ends [`Status::NotConverged`].)
    ///
    /// Out of range, the answers are wrong: no ξ lies within a NaN inside tolerance (a cell's
    /// centre comes out `Outside`), every converged ξ within an infinite one, and a determinant
    /// floor of 1 calls a cube `Singular`. [`Hex8Map::invert`] refuses them (it panics). The
    /// options that [`crate::Settings`] and [`crate::InsideTolerance`] make are always in range.
    ///
    /// ```
    /// use cgcontact::hex8::NewtonOptions;
    /// assert!(NewtonOptions::default().validate().is_ok());
    /// let bad = NewtonOptions { tol: f64::NAN, ..NewtonOptions::default() };
    /// assert!(bad.validate().is_err());
    /// ```
    pub fn validate(&self) -> Result<(), crate::Error> {
        let length = |v: f64| v.is_finite() && v >= 0.0;
        let fault = if !length(self.tol) {
            Some(format!(
                "Newton tolerance {} must be finite and >= 0",
                self.tol
            ))
        } else if !self.inside_tol.to_array().into_iter().all(length) {
            Some(format!(
                "inside tolerance {:?} must be finite and >= 0 on every axis",
                self.inside_tol.to_array()
            ))
        } else if !self.inside_length.to_array().into_iter().all(length) {
            Some(format!(
                "inside length {:?} must be finite and >= 0 on every axis",
                self.inside_length.to_array()
            ))
        } else if !(self.det_ratio_min >= 0.0 && self.det_ratio_min < 1.0) {
            Some(format!(
                "determinant ratio floor {} must lie in [0, 1)",
                self.det_ratio_min
            ))
        } else {
            None
        };
        fault.map_or(Ok(()), |f| Err(crate::Error::InvalidSettings(f)))
    }

    /// [`Self::validate`]'s test alone, without a branch per value (every inversion asks it).
    #[inline(always)]
    fn in_range(&self) -> bool {
        let length = |v: f64| (0.0..f64::INFINITY).contains(&v);
        let lengths = |v: DVec3| length(v.x) & length(v.y) & length(v.z);
        length(self.tol)
            & lengths(self.inside_tol)
            & lengths(self.inside_length)
            & (0.0..1.0).contains(&self.det_ratio_min)
    }
}

/// The panic of an inversion asked with options out of range (out of line: the check's branch
/// is never taken by the locators, whose options are in range by construction).
#[cold]
#[inline(never)]
#[track_caller]
fn options_out_of_range(options: &NewtonOptions) -> ! {
    match options.validate() {
        Err(error) => panic!("Hex8Map::invert: {error} (see NewtonOptions::validate)"),
        Ok(()) => unreachable!("NewtonOptions::in_range and validate disagree on {options:?}"),
    }
}

impl Default for NewtonOptions {
    fn default() -> Self {
        Self {
            tol: crate::Settings::NEWTON_TOL,
            max_iter: crate::Settings::MAX_ITER,
            inside_tol: DVec3::splat(crate::Settings::INSIDE_TOL),
            inside_length: DVec3::ZERO,
            det_ratio_min: 1e-12,
        }
    }
}

/// How an inversion ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// Converged with every |ξ_k| ≤ 1 + inside tolerance.
    Inside,
    /// Converged (or clearly converging) to a ξ outside the cell.
    Outside,
    /// The iteration limit was reached first.
    NotConverged,
    /// det J fell to the floor (degenerate or inverted cell around the iterate), or a value was not finite.
    Singular,
}

/// The outcome of a Newton inversion, reported in f64 whatever the kernel's precision.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inversion {
    /// How it ended. Only [`Status::Inside`] means the point is in the cell.
    pub status: Status,
    /// The last iterate.
    pub xi: DVec3,
    /// Newton iterations done.
    pub iterations: u32,
    /// Physical residual |x − x(ξ)| at the last iterate (local-frame units, i.e. lengths).
    pub residual: f64,
}

/// A hex8 kernel of one precision, seen through f64 at its boundary so that locators can be written
/// once for both precisions.
pub trait Kernel: Copy + Send + Sync {
    /// Whether this kernel works in a frame shifted by the locator's common translation
    /// ([`crate::LatticeLocator::frame_shift`]): f32, whose rounding of each displacement grows
    /// with its size, so that a rigid translation costs no precision. False for f64.
    const SHIFTED: bool;
    /// The map of a lattice cell of spacing `h` whose corners are displaced by `u` (VTK order),
    /// in the cell's local frame (lowest undeformed node at the origin).
    fn lattice_cell(h: DVec3, u: &[DVec3; 8]) -> Self;
    /// The trilinear interpolation of corner displacements `u` alone (no lattice part): evaluate it
    /// with [`Kernel::map_f64`], then turn it into the cell's map with [`Kernel::add_lattice`], so a
    /// caller that interpolated u in a cell reuses the work.
    fn displacement_map(u: &[DVec3; 8]) -> Self;
    /// Add the undeformed part of a lattice cell of spacing `h`, h (1 + ξ) / 2 per axis.
    fn add_lattice(&mut self, h: DVec3);
    /// x(ξ), in f64 at the boundary.
    fn map_f64(&self, xi: DVec3) -> DVec3;
    /// The map of a hexahedron with arbitrary corners (VTK order), already in a local frame.
    fn from_corners(corners: &[DVec3; 8]) -> Self;
    /// Newton inversion of `x` (same frame as the corners) starting from `xi0` (clamped to [−1, 1]³).
    fn invert_f64(&self, x: DVec3, xi0: DVec3, options: &NewtonOptions) -> Inversion;
}

/// The monomial coefficients (1, ξ, η, ξη, ζ, ξζ, ηζ, ξηζ) of the trilinear map with corners `c` (VTK
/// order); `eighth(v)` is v / 8. A Haar butterfly along ξ, η, ζ in turn, (lo, hi) → (hi + lo, hi − lo),
/// written out (binary corner b = VTK corner with bit 0: +ξ, bit 1: +η, bit 2: +ζ) so that it inlines
/// without copies; the three halvings are one scaling at the end. Generic, so that the scalar kernels
/// and the batched lanes (`hex8/lanes.rs`) run the same operations in the same order: that is what makes
/// their answers bitwise equal.
#[inline(always)]
pub(crate) fn monomials<T>(c: &[T; 8], eighth: impl Fn(T) -> T) -> [T; 8]
where
    T: Copy + Add<Output = T> + Sub<Output = T>,
{
    let (s01, d01) = (c[1] + c[0], c[1] - c[0]);
    let (s32, d32) = (c[2] + c[3], c[2] - c[3]);
    let (s45, d45) = (c[5] + c[4], c[5] - c[4]);
    let (s76, d76) = (c[6] + c[7], c[6] - c[7]);
    let (lo0, lo1, lo2, lo3) = (s32 + s01, d32 + d01, s32 - s01, d32 - d01);
    let (hi0, hi1, hi2, hi3) = (s76 + s45, d76 + d45, s76 - s45, d76 - d45);
    [
        eighth(hi0 + lo0),
        eighth(hi1 + lo1),
        eighth(hi2 + lo2),
        eighth(hi3 + lo3),
        eighth(hi0 - lo0),
        eighth(hi1 - lo1),
        eighth(hi2 - lo2),
        eighth(hi3 - lo3),
    ]
}

/// x(ξ) from monomial coefficients `a`; `scale(v, s)` is v times the scalar s (shared like
/// [`monomials`]).
#[inline(always)]
pub(crate) fn map<T, S>(a: &[T; 8], x: S, y: S, z: S, scale: impl Fn(T, S) -> T) -> T
where
    T: Copy + Add<Output = T>,
    S: Copy,
{
    let lower = a[0] + scale(a[1], x) + scale(a[2] + scale(a[3], x), y);
    let upper = a[4] + scale(a[5], x) + scale(a[6] + scale(a[7], x), y);
    lower + scale(upper, z)
}

/// x(ξ) and the columns of J = ∂x/∂ξ from monomial coefficients `a` (shared like [`monomials`]).
#[inline(always)]
pub(crate) fn map_and_jacobian<T, S>(
    a: &[T; 8],
    x: S,
    y: S,
    z: S,
    scale: impl Fn(T, S) -> T,
) -> (T, [T; 3])
where
    T: Copy + Add<Output = T>,
    S: Copy,
{
    let d_xi = a[1] + scale(a[3], y) + scale(a[5] + scale(a[7], y), z);
    let d_eta = a[2] + scale(a[3], x) + scale(a[6] + scale(a[7], x), z);
    let lower = a[0] + scale(a[1], x) + scale(a[2] + scale(a[3], x), y);
    let upper = a[4] + scale(a[5], x) + scale(a[6] + scale(a[7], x), y);
    (lower + scale(upper, z), [d_xi, d_eta, upper])
}

macro_rules! stamp_hex8 {
    ($(#[$doc:meta])* $name:ident, $S:ty, $V:ty, $shifted:expr, $to_v:expr, $from_v:expr) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub struct $name {
            /// Monomial coefficients, binary order: 1, ξ, η, ξη, ζ, ξζ, ηζ, ξηζ.
            a: [$V; 8],
        }

        impl $name {
            /// The map of a hexahedron with corners `corners` (VTK order).
            #[inline(always)]
            #[must_use]
            pub fn new(corners: &[$V; 8]) -> Self {
                Self {
                    a: monomials(corners, |v: $V| v * 0.125),
                }
            }

            /// x(ξ).
            #[inline]
            #[must_use]
            pub fn map(&self, xi: $V) -> $V {
                map(&self.a, xi.x, xi.y, xi.z, |v: $V, s: $S| v * s)
            }

            /// x(ξ) and the columns of J = ∂x/∂ξ.
            #[inline]
            #[must_use]
            pub fn map_and_jacobian(&self, xi: $V) -> ($V, [$V; 3]) {
                map_and_jacobian(&self.a, xi.x, xi.y, xi.z, |v: $V, s: $S| v * s)
            }

            /// The magnitude, per component, of the numbers the residual x − x(ξ) is computed from
            /// (same for every iterate, so computed once per inversion).
            #[inline]
            fn magnitude(&self, x: $V) -> $V {
                let a = &self.a;
                x.abs() + a[0].abs() + (a[1].abs() + a[2].abs() + a[4].abs())
            }

            /// The rounding noise of a Newton step: 16 ε max_k Σ_j |J⁻¹_kj| `magnitude`_j, the
            /// residual's rounding (per component, that of the numbers it is computed from) carried
            /// through J⁻¹. A step this small carries no information: stopping there is what keeps
            /// an ill-conditioned cell (a crushed corner) from ending `NotConverged` at the right
            /// answer. Per component, because one magnitude for all three (the largest) made the
            /// noise of an anisotropic cell's coarse axis, or of a large displacement along it,
            /// stop Newton far from the answer on its fine axis. `adjugate` holds the rows of
            /// adj(J), `inv_det` is 1 / det J.
            #[inline]
            fn step_noise(magnitude: $V, adjugate: [$V; 3], inv_det: $S) -> $S {
                let m = magnitude;
                let weighted = |row: &$V| {
                    let t = row.abs();
                    t.x * m.x + t.y * m.y + t.z * m.z
                };
                let inverse_norm = adjugate.iter().map(weighted).fold(0.0, <$S>::max) * inv_det.abs();
                16.0 * <$S>::EPSILON * inverse_norm
            }

            /// Whether `xi` is inside the cell up to rounding: whether some perturbation δ of the
            /// point, |δ_j| ≤ `length_j`, brings it within `inside` on every axis, to first order:
            /// ξ + J⁻¹ δ in the box [−`inside`, `inside`]. That is, ξ lies in the Minkowski sum of
            /// the box and the parallelepiped J⁻¹ [−L, L]³: a zonotope of 6 generators (the box's
            /// half-edges, and J⁻¹'s columns times L_j), tested on the normals of its faces, the
            /// cross products of pairs of generators. (The box's own pairs give the per-axis bound
            /// |ξ_k| ≤ inside_k + Σ_j |J⁻¹_kj| L_j; alone, it accepted points up to cond(J) L
            /// away from a crushed corner, 1e-6 beyond one of det ratio 1e-5 in f32.)
            ///
            /// J is the cell's own at the point of the closed cell nearest `xi` (ξ clamped to
            /// [−1, 1]³), not its extrapolation's, which turns singular beyond a crushed corner. No
            /// allowance where det J ≤ 0 there. Called only for a converged ξ beyond `inside`.
            #[cold]
            fn within_allowance(&self, xi: $V, inside: $V, length: $V) -> bool {
                let (rows, det) = self.adjugate_at(xi.clamp(<$V>::splat(-1.0), <$V>::splat(1.0)));
                Self::in_zonotope(xi, inside, length, rows, det)
            }

            /// [`Self::within_allowance`] for the ξ where Newton converged, whose `residual`
            /// x − x(ξ) is known, with the allowance widened by what the first-order test leaves
            /// out (a length per component):
            /// - the residual itself: Newton may stop on a step down to the rounding noise of a
            ///   large coordinate (`step_noise`), whose last step leaves the other components a
            ///   little short of their own, far smaller rounding;
            /// - the map's curvature over the allowance: ξ is moved back into the cell by J⁻¹ at
            ///   the nearest point of the closed cell, while the map bends between there and ξ by
            ///   up to `curvature`_j · |Δξ|∞², |Δξ| at most the first-order reach R (a bound on
            ///   ξ's distance to the cell that the test accepts). Four times that: the bend, and
            ///   J's change between the two points times their distance.
            ///
            /// Both are second order in the rounding: nothing near the origin, where L is a few
            /// ε. Without them, far from the origin with a large coordinate rounding along one
            /// axis, a point on a node of a deformed cell was refused: Newton stopped beyond the
            /// node's corner of the box along J⁻¹'s column for that axis, but not exactly along
            /// it, and the other axes' allowances, a few ε, could not make up the difference (a
            /// cell of h = 1 translated by 1e12, lattice and brute force alike). The widening is
            /// at most the largest first-order length L, so a point accepted lies within 2 L of
            /// the cell (to first order), what the filters widen by
            /// (`InsideTolerance::tau`), and a crushed cell's allowance at most doubles.
            #[cold]
            fn converged_within_allowance(&self, xi: $V, inside: $V, length: $V, residual: $V) -> bool {
                let (rows, det) = self.adjugate_at(xi.clamp(<$V>::splat(-1.0), <$V>::splat(1.0)));
                if det.is_nan() || det <= 0.0 {
                    return false;
                }
                let first = length + residual.abs();
                let reach = 2.0 * rows.iter().map(|row| row.abs().dot(first)).fold(0.0, <$S>::max) / det;
                let a = &self.a;
                let curvature = a[3].abs() + a[5].abs() + a[6].abs() + 4.0 * a[7].abs();
                // An infinite reach (J nearly singular there) bends nothing.
                let bend = if reach.is_finite() {
                    curvature * (4.0 * reach * reach)
                } else {
                    <$V>::splat(0.0)
                };
                // At most the largest first-order length: the filters widen by twice that.
                let widen = (residual.abs() + bend).min(<$V>::splat(length.max_element()));
                Self::in_zonotope(xi, inside, length + widen, rows, det)
            }

            /// The zonotope test of [`Self::within_allowance`], given the rows of adj(J) and det J
            /// at the nearest point of the closed cell.
            #[inline]
            fn in_zonotope(xi: $V, inside: $V, length: $V, [k0, k1, k2]: [$V; 3], det: $S) -> bool {
                // NaN fails too: only a cell known to be valid there gets the allowance.
                if det.is_nan() || det <= 0.0 {
                    return false;
                }
                // J⁻¹'s column j is adj(J)'s (the rows k) over det J.
                let scale = length / det;
                let generators = [
                    <$V>::new(inside.x, 0.0, 0.0),
                    <$V>::new(0.0, inside.y, 0.0),
                    <$V>::new(0.0, 0.0, inside.z),
                    <$V>::new(k0.x, k1.x, k2.x) * scale.x,
                    <$V>::new(k0.y, k1.y, k2.y) * scale.y,
                    <$V>::new(k0.z, k1.z, k2.z) * scale.z,
                ];
                for (i, &a) in generators.iter().enumerate() {
                    for &b in &generators[i + 1..] {
                        let normal = a.cross(b);
                        let reach: $S = generators.iter().map(|&g| normal.dot(g).abs()).sum();
                        // A zero normal (parallel generators) bounds nothing: 0 ≤ 0.
                        let within = normal.dot(xi).abs() <= reach;
                        if !within {
                            return false;
                        }
                    }
                }
                true
            }

            /// Whether `xi`, beyond `inside` on some axis, is beyond the rounding allowance too:
            /// [`Self::within_allowance`]'s answer, the one the final inside test gives, so that
            /// the early `Outside` never refuses a point that test would hold. The zonotope's
            /// bounding box, |ξ_k| ≤ `inside`_k + Σ_j |J⁻¹_kj| `length`_j, is tried first: it
            /// costs one Jacobian, and a point far outside fails it. (Without the allowance, a
            /// node at 1.5e9 with h = 1e-3 lost 4 of its 7 owners: Newton stopped at
            /// ξ ≈ −1.0125, 1e-2 beyond the face but within the allowance.)
            #[inline]
            fn beyond_allowance(&self, xi: $V, inside: $V, length: $V) -> bool {
                let ([k0, k1, k2], det) =
                    self.adjugate_at(xi.clamp(<$V>::splat(-1.0), <$V>::splat(1.0)));
                // No allowance where the cell is not known to be valid (as in `within_allowance`).
                if det.is_nan() || det <= 0.0 {
                    return true;
                }
                let reach =
                    <$V>::new(k0.abs().dot(length), k1.abs().dot(length), k2.abs().dot(length)) / det;
                xi.abs().cmpgt(inside + reach).any() || !self.within_allowance(xi, inside, length)
            }

            /// The rows of adj(J) at `xi` (the columns' cross products: row k of J⁻¹ is row k
            /// over det J) and det J.
            #[inline]
            fn adjugate_at(&self, xi: $V) -> ([$V; 3], $S) {
                let (_, [c0, c1, c2]) = self.map_and_jacobian(xi);
                let k0 = c1.cross(c2);
                ([k0, c2.cross(c0), c0.cross(c1)], c0.dot(k0))
            }

            /// How far (in ξ, the largest over the axes) perturbations of the point of at most
            /// `length_j` per component move ξ through J⁻¹ at the cell's centre:
            /// max_k Σ_j |J⁻¹_kj| length_j. Infinite where det J ≤ 0 there (or NaN).
            #[must_use]
            pub fn rounding_share(&self, length: $V) -> $S {
                let (rows, det) = self.adjugate_at(<$V>::splat(0.0));
                if det.is_nan() || det <= 0.0 {
                    return <$S>::INFINITY;
                }
                rows.iter().map(|row| row.abs().dot(length)).fold(0.0, <$S>::max) / det
            }

            /// det J at ξ = 0, the scale of the cell's volume (volume / 8).
            #[inline]
            #[must_use]
            pub fn det_at_center(&self) -> $S {
                self.a[1].dot(self.a[2].cross(self.a[4]))
            }

            /// Newton inversion of `x` starting from `xi0` (clamped to [−1, 1]³).
            ///
            /// Safeguards, chosen so that it never loops forever and never calls a NaN inside:
            /// an iteration limit; a det J floor relative to the cell's own scale; iterates kept in
            /// [−4, 4]³ (the trilinear extrapolation far outside a cell is meaningless); a backtracking
            /// line search on |residual| for steps larger than 1e-3 (distorted cells), which costs
            /// nothing when the full step already reduces the residual; and an early `Outside` once the
            /// iterate is converging (step < 1e-3) to a point clearly (1e-2) outside the cell and
            /// its rounding allowance (`NewtonOptions::inside_length`).
            ///
            /// When the iteration limit is reached from `xi0`, Newton starts once more from the
            /// cell's centre (`iterations` then counts both runs). In a strongly sheared cell, some
            /// starts creep toward a root near a corner (7.5 % of a grid of starts in one cell of
            /// an anisotropic mesh took more than 20 iterations, some more than 60), while the
            /// centre converged in 5: a point on that corner was reported in no cell.
            ///
            /// Where the cell may hold the point (`may_hold`: within its corners' box), that run
            /// has [`PATIENT_ITERATIONS`] times the limit: the limit bounds the common path's
            /// work, and must not turn a slow convergence into "in no cell". With a limit of 1
            /// or 2, the lattice locator said so of 54 of 81 points made inside a smoothly
            /// deformed block; brute force, which retried so, found them all.
            ///
            /// # Panics
            /// When `options` are out of range ([`NewtonOptions::validate`]: a NaN, negative or
            /// infinite tolerance, a determinant floor outside [0, 1)), with which the answer
            /// would be wrong.
            #[must_use]
            #[inline]
            pub fn invert(&self, x: $V, xi0: $V, options: &NewtonOptions) -> Inversion {
                if !options.in_range() {
                    options_out_of_range(options);
                }
                let first = self.invert_from(x, xi0, options);
                if first.status != Status::NotConverged {
                    return first;
                }
                let centre = <$V>::splat(0.0);
                let patient = self.may_hold(x, options);
                if !patient && xi0.clamp(<$V>::splat(-1.0), <$V>::splat(1.0)) == centre {
                    return first;
                }
                let limit = if patient {
                    options.max_iter.saturating_mul(PATIENT_ITERATIONS)
                } else {
                    options.max_iter
                };
                let again = self.invert_from(x, centre, &NewtonOptions { max_iter: limit, ..*options });
                Inversion {
                    iterations: first.iterations.saturating_add(again.iterations),
                    ..again
                }
            }

            /// Whether the cell may hold `x`: `x` within the box of its 8 corners, widened by the
            /// inside tolerance's share of the box, the rounding allowance and the coordinates'
            /// rounding. The cell (the trilinear image of [−1, 1]³) lies in its corners' convex
            /// hull, so a point beyond that box is in no cell's reach: Newton's slow runs there
            /// (far from a distorted cell) get no second, longer one.
            #[cold]
            fn may_hold(&self, x: $V, options: &NewtonOptions) -> bool {
                let mut low = <$V>::splat(<$S>::INFINITY);
                let mut high = <$V>::splat(<$S>::NEG_INFINITY);
                for c in CORNER_XI {
                    let corner = self.map(<$V>::new(c[0] as $S, c[1] as $S, c[2] as $S));
                    low = low.min(corner);
                    high = high.max(corner);
                }
                let tol = $to_v(options.inside_tol).max_element() + 1e-3;
                let widen = (high - low) * tol
                    + $to_v(options.inside_length)
                    + self.magnitude(x) * (64.0 * <$S>::EPSILON);
                x.cmpge(low - widen).all() && x.cmple(high + widen).all()
            }

            /// One Newton run of [`Self::invert`], from `xi0` (clamped to [−1, 1]³).
            #[inline]
            fn invert_from(&self, x: $V, xi0: $V, options: &NewtonOptions) -> Inversion {
                // The same values in f64 and f32: each is exact or rounds as its literal would.
                const BOX: $S = NEWTON_BOX as $S;
                const LINE_SEARCH_ABOVE: $S = crate::hex8::LINE_SEARCH_ABOVE as $S;
                const EARLY_OUTSIDE_STEP: $S = crate::hex8::EARLY_OUTSIDE_STEP as $S;
                const EARLY_OUTSIDE_MARGIN: $S = crate::hex8::EARLY_OUTSIDE_MARGIN as $S;
                let tol = options.tol as $S;
                let inside = <$V>::splat(1.0) + $to_v(options.inside_tol);
                let inside_length = $to_v(options.inside_length);
                let det_floor = options.det_ratio_min as $S * self.det_at_center().abs();
                let magnitude = self.magnitude(x);
                let mut xi = xi0.clamp(<$V>::splat(-1.0), <$V>::splat(1.0));
                // Residual and Jacobian at an iterate.
                let evaluate = |xi: $V| {
                    let (fx, jac) = self.map_and_jacobian(xi);
                    (x - fx, jac)
                };
                let (mut r, mut jac) = evaluate(xi);
                // Iterates held back from the early `Outside` by the rounding allowance: at most
                // `EARLY_OUTSIDE_HOLDS`, so that a run that stalls there (it never reaches the
                // convergence test) still ends, whatever `max_iter` says.
                let mut held = 0u32;
                let mut rr = r.dot(r);
                let finish = |status, xi: $V, iterations, rr: $S| Inversion {
                    status,
                    xi: $from_v(xi),
                    iterations,
                    residual: (rr as f64).sqrt(),
                };
                for iteration in 1..=options.max_iter {
                    let [c0, c1, c2] = jac;
                    let k0 = c1.cross(c2);
                    let det = c0.dot(k0);
                    // NaN fails too: only a determinant known to exceed the floor is usable.
                    if det.is_nan() || det <= det_floor {
                        return finish(Status::Singular, xi, iteration - 1, rr);
                    }
                    // One division, three multiplications: J⁻¹ r by the adjugate (rows are the
                    // columns' cross products).
                    let (k1, k2) = (c2.cross(c0), c0.cross(c1));
                    let inv_det = det.recip();
                    let delta = <$V>::new(k0.dot(r), k1.dot(r), k2.dot(r)) * inv_det;
                    let size = delta.abs().max_element();
                    if size <= tol || size <= Self::step_noise(magnitude, [k0, k1, k2], inv_det) {
                        // Converged: the step is below tolerance, and convergence is quadratic, so the
                        // error after it is of order size²; or the step is down to the rounding noise
                        // of this precision (ill-conditioned J), below which no iteration can go.
                        // Only the residual is evaluated (no Jacobian).
                        xi += delta;
                        r = x - self.map(xi);
                        rr = r.dot(r);
                        let status = if !xi.is_finite() || !rr.is_finite() {
                            Status::Singular
                        } else if xi.abs().cmple(inside).all()
                            || self.converged_within_allowance(xi, inside, inside_length, r)
                        {
                            Status::Inside
                        } else {
                            Status::Outside
                        };
                        return finish(status, xi, iteration, rr);
                    }
                    let mut step = delta;
                    let mut trial = (xi + step).clamp(<$V>::splat(-BOX), <$V>::splat(BOX));
                    let (mut r_trial, mut jac_trial) = evaluate(trial);
                    let mut rr_trial = r_trial.dot(r_trial);
                    let mut halvings = 0;
                    while rr_trial > rr && step.abs().max_element() > LINE_SEARCH_ABOVE && halvings < 10 {
                        step *= 0.5;
                        halvings += 1;
                        trial = (xi + step).clamp(<$V>::splat(-BOX), <$V>::splat(BOX));
                        (r_trial, jac_trial) = evaluate(trial);
                        rr_trial = r_trial.dot(r_trial);
                    }
                    let moved = (trial - xi).abs().max_element();
                    xi = trial;
                    jac = jac_trial;
                    r = r_trial;
                    rr = rr_trial;
                    if !xi.is_finite() || !rr.is_finite() {
                        return finish(Status::Singular, xi, iteration, rr);
                    }
                    let beyond = xi.abs().cmpgt(inside + EARLY_OUTSIDE_MARGIN).any();
                    if moved < EARLY_OUTSIDE_STEP && beyond {
                        if held >= EARLY_OUTSIDE_HOLDS
                            || self.beyond_allowance(xi, inside + EARLY_OUTSIDE_MARGIN, inside_length)
                        {
                            return finish(Status::Outside, xi, iteration, rr);
                        }
                        held += 1;
                    }
                }
                finish(Status::NotConverged, xi, options.max_iter, rr)
            }
        }

        impl Kernel for $name {
            const SHIFTED: bool = $shifted;

            #[inline]
            fn lattice_cell(h: DVec3, u: &[DVec3; 8]) -> Self {
                let mut map = Self::displacement_map(u);
                map.add_lattice(h);
                map
            }

            #[inline]
            fn displacement_map(u: &[DVec3; 8]) -> Self {
                // A loop, not `array::map`, which costs a copy through MaybeUninit on the hot path.
                let mut corners = [<$V>::ZERO; 8];
                for (c, &u) in corners.iter_mut().zip(u) {
                    *c = $to_v(u);
                }
                Self::new(&corners)
            }

            #[inline]
            fn add_lattice(&mut self, h: DVec3) {
                let half = $to_v(h * 0.5);
                self.a[0] += half;
                self.a[1] += <$V>::new(half.x, 0.0, 0.0);
                self.a[2] += <$V>::new(0.0, half.y, 0.0);
                self.a[4] += <$V>::new(0.0, 0.0, half.z);
            }

            #[inline]
            fn map_f64(&self, xi: DVec3) -> DVec3 {
                $from_v(self.map($to_v(xi)))
            }

            #[inline]
            fn from_corners(corners: &[DVec3; 8]) -> Self {
                Self::new(&corners.map($to_v))
            }

            #[inline]
            fn invert_f64(&self, x: DVec3, xi0: DVec3, options: &NewtonOptions) -> Inversion {
                self.invert($to_v(x), $to_v(xi0), options)
            }
        }
    };
}

stamp_hex8!(
    /// The trilinear map of one hexahedron in f64 (`DVec3`).
    Hex8Map, f64, DVec3, false, |v: DVec3| v, |v: DVec3| v
);
stamp_hex8!(
    /// The trilinear map of one hexahedron in f32 (glam's SIMD `Vec3A`); use it in a local frame.
    Hex8Map32, f32, Vec3A, true, |v: DVec3| v.as_vec3a(), |v: Vec3A| v.as_dvec3()
);

/// Smallest Jacobian determinant over the 8 corners of a hexahedron (corners in VTK order).
///
/// At a corner, J's columns are the three edges leaving it (halved), so this is the classic
/// corner-validity test: a cell with a non-positive value is inverted or degenerate there. NaN
/// when some corner's determinant is NaN (a corner not finite, or a product that overflowed):
/// such a cell is not known to be valid.
#[must_use]
pub fn min_corner_det(corners: &[DVec3; 8]) -> f64 {
    let map = Hex8Map::new(corners);
    CORNER_XI
        .iter()
        .map(|&xi| map.map_and_jacobian(DVec3::from_array(xi)).1)
        .map(|[c0, c1, c2]| c0.dot(c1.cross(c2)))
        // Not `f64::min`, which skips NaN: a cell with a NaN corner determinant was then judged
        // by its other corners, and passed.
        .fold(f64::INFINITY, |low, det| {
            if low.is_nan() || det.is_nan() {
                f64::NAN
            } else {
                low.min(det)
            }
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A distorted hexahedron: unit cube corners moved by up to 0.2.
    fn distorted() -> [DVec3; 8] {
        let jitter = [
            [0.1, -0.05, 0.02],
            [-0.2, 0.1, 0.0],
            [0.05, 0.15, -0.1],
            [0.0, -0.1, 0.2],
            [0.1, 0.1, -0.1],
            [-0.05, 0.0, 0.15],
            [0.2, -0.2, 0.1],
            [-0.1, 0.05, 0.0],
        ];
        std::array::from_fn(|c| {
            let o = CORNER_XI[c].map(|s| (s + 1.0) / 2.0);
            DVec3::from_array(o) + DVec3::from_array(jitter[c])
        })
    }

    #[test]
    fn map_matches_shape_functions() {
        let corners = distorted();
        let map = Hex8Map::new(&corners);
        for xi in [
            DVec3::ZERO,
            DVec3::new(0.3, -0.7, 0.9),
            DVec3::new(-1.0, 1.0, 0.25),
        ] {
            let n = shape(xi);
            let by_shape: DVec3 = (0..8).map(|c| corners[c] * n[c]).sum();
            assert!((map.map(xi) - by_shape).length() < 1e-15);
        }
        for c in 0..8 {
            let at = map.map(DVec3::from_array(CORNER_XI[c]));
            assert!((at - corners[c]).length() < 1e-15, "corner {c}");
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let map = Hex8Map::new(&distorted());
        let xi = DVec3::new(0.2, -0.4, 0.6);
        let (_, jac) = map.map_and_jacobian(xi);
        let eps = 1e-6;
        for (axis, column) in jac.iter().enumerate() {
            let mut e = DVec3::ZERO;
            e[axis] = eps;
            let fd = (map.map(xi + e) - map.map(xi - e)) / (2.0 * eps);
            assert!((fd - *column).length() < 1e-9, "axis {axis}");
        }
    }

    #[test]
    fn newton_recovers_known_xi() {
        let map = Hex8Map::new(&distorted());
        let options = NewtonOptions::default();
        for xi in [
            DVec3::ZERO,
            DVec3::new(0.9, -0.99, 0.5),
            DVec3::new(-1.0, 1.0, -1.0),
        ] {
            let inv = map.invert(map.map(xi), DVec3::ZERO, &options);
            assert_eq!(inv.status, Status::Inside);
            assert!(
                (inv.xi - xi).abs().max_element() < 1e-12,
                "{:?} vs {xi}",
                inv.xi
            );
            assert!(inv.iterations <= 8);
        }
        let outside = map.invert(map.map(DVec3::new(1.5, 0.0, 0.0)), DVec3::ZERO, &options);
        assert_eq!(outside.status, Status::Outside);
    }

    #[test]
    fn f32_kernel_agrees() {
        let corners = distorted();
        let map = Hex8Map32::from_corners(&corners);
        let xi = DVec3::new(0.3, 0.2, -0.8);
        let x = Hex8Map::new(&corners).map(xi);
        let inv = map.invert_f64(
            x,
            DVec3::ZERO,
            &NewtonOptions {
                tol: 1e-5,
                inside_tol: DVec3::splat(1e-6),
                ..Default::default()
            },
        );
        assert_eq!(inv.status, Status::Inside);
        assert!((inv.xi - xi).abs().max_element() < 1e-5);
    }

    #[test]
    fn degenerate_cell_is_singular_not_nan() {
        // All corners on one plane: det J = 0 everywhere.
        let flat = distorted().map(|c| DVec3::new(c.x, c.y, 0.0));
        let inv = Hex8Map::new(&flat).invert(
            DVec3::new(0.5, 0.5, 0.0),
            DVec3::ZERO,
            &NewtonOptions::default(),
        );
        assert_eq!(inv.status, Status::Singular);
        let nan =
            Hex8Map::new(&distorted()).invert(DVec3::NAN, DVec3::ZERO, &NewtonOptions::default());
        assert_ne!(nan.status, Status::Inside);
        assert!(min_corner_det(&flat).abs() < 1e-15);
        assert!(min_corner_det(&distorted()) > 0.0);
    }

    /// `min_corner_det` folded with `f64::min`, which skips NaN: a cell with one corner NaN
    /// (NaN determinants at the four corners next to it) got the smallest of the others, 0.125
    /// for a unit cube, and passed as valid. It is NaN now, which every caller counts as not
    /// valid; each finite corner's determinant is checked against the cube's edges.
    #[test]
    fn a_nan_corner_is_no_valid_cell() {
        let cube: [DVec3; 8] = crate::CORNER_OFFSETS
            .map(|[a, b, c]| DVec3::new(f64::from(a), f64::from(b), f64::from(c)));
        assert_eq!(min_corner_det(&cube), 0.125);
        for corner in 0..8 {
            for bad in [f64::NAN, f64::INFINITY] {
                let mut broken = cube;
                broken[corner].y = bad;
                let det = min_corner_det(&broken);
                assert!(
                    det.is_nan() || det <= 0.0,
                    "corner {corner} at {bad}: {det}"
                );
            }
        }
    }

    /// The rounding allowance is a physical distance, however thin the cell: a sliver (its x and
    /// y edges 1e-6 apart in angle) accepts a point L/2 beyond its acute edge and not one 1000 L
    /// beyond. The per-axis bound |ξ_k| ≤ 1 + t + Σ_j |J⁻¹_kj| L_j (the bounding box of the
    /// exact region) accepted both: J⁻¹'s rows are 1e6 long there.
    #[test]
    fn the_rounding_allowance_is_a_distance_even_in_a_sliver() {
        let (x_edge, y_edge, z_edge) = (DVec3::X, DVec3::new(1.0, 1e-6, 0.0), DVec3::Z);
        let corners: [DVec3; 8] = std::array::from_fn(|c| {
            let [i, j, k] = CORNER_XI[c].map(|s| (s + 1.0) / 2.0);
            x_edge * i + y_edge * j + z_edge * k
        });
        let map = Hex8Map::new(&corners);
        let length = 1e-9;
        let options = NewtonOptions {
            inside_length: DVec3::splat(length),
            ..Default::default()
        };
        // Beyond the edge ξ_x = ξ_y = 1 (at ξ_z = 0), along x_edge + y_edge: ξ = (1 + d, 1 + d, 0).
        let edge = (x_edge + y_edge) + 0.5 * z_edge;
        let out = (x_edge + y_edge).normalize();
        for (distance, inside) in [(0.5 * length, true), (1000.0 * length, false)] {
            let inversion = map.invert(edge + out * distance, DVec3::ZERO, &options);
            assert!(
                inversion.xi.x > 1.0 && inversion.xi.y > 1.0,
                "{inversion:?}"
            );
            let expected = if inside {
                Status::Inside
            } else {
                Status::Outside
            };
            assert_eq!(
                inversion.status, expected,
                "{distance:e} beyond: {inversion:?}"
            );
        }
    }
}
