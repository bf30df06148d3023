//! Settings of a search, with defaults chosen from the measured accuracy/speed trade (docs/).

use glam::DVec3;

use crate::lanes::{Lanes, V3};

use crate::hex8::{Kernel, NewtonOptions};
use crate::{Error, Lattice, Schedule};

/// Floating-point precision of the Newton kernel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Precision {
    /// f64 (`DVec3`): the default, ξ error ≈ 1e-15.
    #[default]
    F64,
    /// f32 in the cell's local frame (glam's SIMD `Vec3A` one point at a time; 8 lanes per AVX2
    /// register in `locate_all`): ξ error ≈ 1e-6, growing as ε₃₂ |u − T| / h with the
    /// displacements' spread about their common translation T, which the kernel takes out
    /// ([`Frame`]): a rigid translation of any size costs nothing, a body rotated or strained over
    /// 1e5 cells loses about 1e-2 of a cell (use f64 there). Its speed-up over f64 depends
    /// on the scene: about 1.5× where the displacements stay in cache, 1.2–1.3× on random-order
    /// points of a large body, whose time goes to waiting on memory (docs/benchmarks.md has the
    /// measured figures).
    F32,
}

/// The frame a precision's kernel works in.
///
/// f32 rounds each displacement by ε₃₂ |u|, so a body moved rigidly by many cells would lose its
/// cells' shape to the rounding. The f32 kernel works on displacements and points shifted by a
/// common translation T instead: the mid-range of the displacements per axis, rounded to whole
/// cells (0 while it is under half a cell, so that bodies moved less answer as before). Its
/// rounding then grows with |u − T| only. The trilinear weights sum to 1, so x(ξ) − T is the map
/// of the corners shifted by T: the same cell and ξ. The shift is applied in f64, before any
/// rounding to f32: corner displacements u − T, points x − T, and T added back to an
/// interpolated displacement. f64 works unshifted. The locators and the baselines share it, so
/// that every strategy agrees on what f32 computes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Frame {
    shift: DVec3,
    /// The largest |u − T| per axis.
    reach: DVec3,
}

impl Frame {
    /// The frame of `precision` for displacements within [`low`, `high`] (per axis) on cells
    /// of spacing `h` (an adaptive body's finest). An empty range (`low` > `high`) gets no shift.
    #[must_use]
    pub fn new(precision: Precision, low: DVec3, high: DVec3, h: DVec3) -> Self {
        let shift = match precision {
            Precision::F64 => DVec3::ZERO,
            Precision::F32 => ((low + high) * 0.5 / h).round() * h,
        };
        let shift = if shift.is_finite() {
            shift
        } else {
            DVec3::ZERO
        };
        Self {
            shift,
            reach: (high - shift).max(shift - low).max(DVec3::ZERO),
        }
    }

    /// [`Frame::new`] for the displacements `u` (one pass over them).
    #[must_use]
    pub fn of_displacements(precision: Precision, u: &[DVec3], h: DVec3) -> Self {
        let (low, high) = u
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(low, high), &u| {
                (low.min(u), high.max(u))
            });
        Self::new(precision, low, high, h)
    }

    /// The common translation T (zero with f64).
    #[must_use]
    pub fn shift(&self) -> DVec3 {
        self.shift
    }

    /// The largest |u − T| per axis: what the kernel's rounding of the displacements grows with
    /// (with f64, the largest |u|), and so what [`InsideTolerance`] is given.
    #[must_use]
    pub fn reach(&self) -> DVec3 {
        self.reach
    }

    /// `f` of corner displacements `u` in the frame of kernel `K`: u − T where it is shifted,
    /// `u` itself (not copied) where it is not.
    #[inline(always)]
    pub fn corners<K: Kernel, R>(&self, u: &[DVec3; 8], f: impl FnOnce(&[DVec3; 8]) -> R) -> R {
        if K::SHIFTED {
            let mut shifted = *u;
            for u in &mut shifted {
                *u -= self.shift;
            }
            f(&shifted)
        } else {
            f(u)
        }
    }

    /// A point `x` in the frame of kernel `K`: x − T where it is shifted.
    #[inline(always)]
    #[must_use]
    pub fn point<K: Kernel>(&self, x: DVec3) -> DVec3 {
        self.point_if(K::SHIFTED, x)
    }

    /// [`Frame::point`] for a kernel known by whether it is `shifted` (the lanes, which name
    /// their precision by their displacements' type, not by a kernel).
    #[inline(always)]
    pub(crate) fn point_if(&self, shifted: bool, x: DVec3) -> DVec3 {
        if shifted { x - self.shift } else { x }
    }

    /// A displacement `v` interpolated in the frame of kernel `K`, back in the body's frame:
    /// v + T where it is shifted.
    #[inline(always)]
    #[must_use]
    pub fn displacement<K: Kernel>(&self, v: DVec3) -> DVec3 {
        if K::SHIFTED { v + self.shift } else { v }
    }
}

/// Order in which the lattice locator tries candidate cells.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CandidateOrder {
    /// Start at the cell holding x − ũ (ũ the displacement interpolated at x on the undeformed lattice),
    /// then rings of growing Chebyshev distance around it. One inversion for most points.
    #[default]
    Predicted,
    /// Start at the cell holding x itself (ignores the displacement), then rings around it.
    Undeformed,
}

/// Settings of a search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Kernel precision.
    pub precision: Precision,
    /// Newton stops when its step is at most this (ξ units). Convergence is quadratic, so the error of
    /// the result is far below this.
    pub newton_tol: f64,
    /// Newton iteration limit per candidate cell, on the common path: a run that reaches it runs
    /// once more from the cell's centre, with [`crate::hex8::PATIENT_ITERATIONS`] times the limit
    /// where the cell may hold the point. The limit bounds the work; it never turns a slow
    /// convergence into "in no cell".
    pub max_iter: u32,
    /// A point is inside when every |ξ_k| ≤ 1 + `inside_tol` + a rounding allowance that grows with the
    /// size of the coordinates relative to the cell's edge along axis k (see docs/numerics.md).
    pub inside_tol: f64,
    /// Candidate order of the lattice locator.
    pub order: CandidateOrder,
    /// The order in which the batched queries visit their points (the answers do not depend on
    /// it).
    pub schedule: Schedule,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            precision: Precision::F64,
            newton_tol: Self::NEWTON_TOL,
            max_iter: Self::MAX_ITER,
            inside_tol: Self::INSIDE_TOL,
            order: CandidateOrder::Predicted,
            schedule: Schedule::Auto,
        }
    }
}

impl Settings {
    /// Default Newton tolerance on the step, ξ units (f64): the knee of the measured trade
    /// (docs/tradeoff.md).
    pub const NEWTON_TOL: f64 = 1e-10;
    /// Default Newton iteration limit per candidate cell.
    pub const MAX_ITER: u32 = 20;
    /// Default inside tolerance, ξ units (f64).
    pub const INSIDE_TOL: f64 = 1e-12;
    /// Default Newton tolerance of [`Settings::f32`].
    pub const NEWTON_TOL_F32: f64 = 1e-5;
    /// Default inside tolerance of [`Settings::f32`].
    pub const INSIDE_TOL_F32: f64 = 1e-6;
    /// The largest inside tolerance, ξ units: a point up to 5 % of a cell beyond a face. The
    /// searches' filters widen by 2τ of a cell's extent for an inversion accepting |ξ_k| ≤ 1 + τ,
    /// which leaves the cell's hull by up to ((1 + τ)³ − 1)/2 of it: covered only while τ stays
    /// below about 0.3 (docs/numerics.md).
    pub const MAX_INSIDE_TOL: f64 = 0.1;

    /// Defaults for f32: a Newton tolerance and inside tolerance suited to single precision.
    #[must_use]
    pub fn f32() -> Self {
        Self {
            precision: Precision::F32,
            newton_tol: Self::NEWTON_TOL_F32,
            inside_tol: Self::INSIDE_TOL_F32,
            ..Self::default()
        }
    }

    /// The smallest spacing (per axis, of a body's finest cells) the f32 kernel resolves: a
    /// cell's Jacobian determinant, about (h/2)³, and its reciprocal stay normal f32 numbers,
    /// with room for cells squeezed or stretched a thousandfold. Beyond, the f32 kernel found no
    /// point at all inside cells of spacing 1e-13 or 1e14 (every strategy, since they share it).
    /// f64 takes every spacing a [`Lattice`] accepts.
    pub const F32_MIN_SPACING: f64 = 1e-11;
    /// See [`Settings::F32_MIN_SPACING`].
    pub const F32_MAX_SPACING: f64 = 1e11;

    /// Check ranges: the Newton tolerance finite and positive, the inside tolerance in
    /// [0, [`Settings::MAX_INSIDE_TOL`]], at least one iteration.
    pub fn validate(&self) -> Result<(), Error> {
        if !(self.newton_tol.is_finite() && self.newton_tol > 0.0) {
            return Err(Error::InvalidSettings(format!(
                "Newton tolerance {} must be finite and > 0",
                self.newton_tol
            )));
        }
        if !(self.inside_tol >= 0.0 && self.inside_tol <= Self::MAX_INSIDE_TOL) {
            return Err(Error::InvalidSettings(format!(
                "inside tolerance {} must lie in [0, {}]",
                self.inside_tol,
                Self::MAX_INSIDE_TOL
            )));
        }
        if self.max_iter == 0 {
            return Err(Error::InvalidSettings(
                "the iteration limit must be at least 1".into(),
            ));
        }
        Ok(())
    }

    /// [`Settings::validate`], and that the kernel of this precision resolves cells of spacing
    /// `h` (a body's lattice's, or an adaptive body's finest level's): with f32, every component
    /// within [[`Settings::F32_MIN_SPACING`], [`Settings::F32_MAX_SPACING`]]. Every locator
    /// checks it when it is built.
    pub fn validate_for(&self, h: DVec3) -> Result<(), Error> {
        self.validate()?;
        let in_range = h.cmpge(DVec3::splat(Self::F32_MIN_SPACING)).all()
            && h.cmple(DVec3::splat(Self::F32_MAX_SPACING)).all();
        if self.precision == Precision::F32 && !in_range {
            return Err(Error::InvalidSettings(format!(
                "the f32 kernel cannot resolve cells of spacing {:?}: each must lie in [{:e}, \
                 {:e}] (a cell's Jacobian determinant would under- or overflow f32); use f64",
                h.to_array(),
                Self::F32_MIN_SPACING,
                Self::F32_MAX_SPACING
            )));
        }
        Ok(())
    }

    /// The Newton options these settings give, before any per-point rounding allowance.
    #[must_use]
    pub fn newton(&self) -> NewtonOptions {
        NewtonOptions {
            tol: self.newton_tol,
            max_iter: self.max_iter,
            inside_tol: DVec3::splat(self.inside_tol),
            ..NewtonOptions::default()
        }
    }

    /// Inside tolerance (ξ units, per axis) for a query at `x` on `lattice` whose displacements
    /// reach `u_max` per component, in an *undeformed* cell of the lattice: the setting plus the
    /// rounding carried by the data, `16 ε_kernel + 8 ε₆₄ max(|x_k|, |origin_k|) / h_k +
    /// 8 ε_kernel u_max_k / h_k` along axis k. In a deformed cell the rounding is carried into ξ
    /// through that cell's J⁻¹ instead ([`InsideTolerance`]).
    #[must_use]
    pub fn inside_tolerance(&self, lattice: &Lattice, u_max: DVec3, x: DVec3) -> DVec3 {
        InsideTolerance::new(self, lattice, u_max).at(x)
    }

    /// Machine epsilon of the kernel's precision.
    #[must_use]
    pub fn epsilon(&self) -> f64 {
        match self.precision {
            Precision::F64 => f64::EPSILON,
            Precision::F32 => f32::EPSILON as f64,
        }
    }
}

/// What every locator and strategy calls inside, with its per-body constants computed once.
///
/// A point x is inside a cell when the Newton inversion converges to a ξ that some perturbation
/// δ of x, |δ_j| ≤ L_j, brings within 1 + t on every axis, to first order (`ξ + J⁻¹ δ` in
/// [−1 − t, 1 + t]³):
/// - `t` (ξ units, [`InsideTolerance::xi`]) is the setting plus the kernel's own rounding of ξ,
///   16 ε_kernel;
/// - `L` (a length per component, [`InsideTolerance::length`]) is how far x and the cell's map
///   may be off by rounding: a point given on a face of a cell far from the origin is only known
///   to ε₆₄ |x_j| in component j (the lattice's origin counts too: a cell's corners are computed
///   from it), and the kernel rounds the displacements at its own precision, so
///   `L_j = 4 ε₆₄ max(|x_j|, |origin_j|) + 4 ε_kernel u_max_j`.
///
/// J is the cell's Jacobian at the point of the closed cell nearest the converged ξ (ξ clamped
/// to [−1, 1]³). In an undeformed cell that is |ξ_k| ≤ 1 + t + 2 L_k / h_k, so closed cells stay
/// closed at any offset and no more, whatever the anisotropy (with the smallest spacing on every axis, a point 5e-4 h outside a face of a
/// 1000 : 1 cell at 1e9 was found inside). In a sheared or rotated cell a rounding along one
/// axis moves ξ along another: with 2 L_k / h_k alone, nodes of a 4 × 0.25 × 0.002 lattice at
/// 1e5 sheared by x += 10 z lost some of their owners. A coarse leaf of an adaptive body gets its
/// own, smaller allowance the same way, from its own J.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InsideTolerance {
    /// The setting plus 16 ε_kernel (ξ units).
    xi: f64,
    /// 4 ε_kernel u_max_j: the kernel's rounding of the displacements (a length per component).
    kernel: DVec3,
    /// |origin_j| of the lattice.
    origin: DVec3,
    /// The spacing these constants were made with (the finest, on an adaptive body).
    h: DVec3,
    /// 4 / its smallest component: the filters' ξ per unit of rounding length (twice 2 / h:
    /// the kernel accepts a point within L plus its second-order terms, at most L again).
    per_length: f64,
}

impl InsideTolerance {
    /// The constants for a body on `lattice` whose displacements reach `u_max` per component in
    /// the kernel's frame.
    #[must_use]
    pub fn new(settings: &Settings, lattice: &Lattice, u_max: DVec3) -> Self {
        Self::with_spacing(settings, lattice.origin(), lattice.h(), u_max)
    }

    /// The same constants for a body whose lattice starts at `origin` and whose smallest cell
    /// edges are `h` per axis (an adaptive body's finest spacing): the filters widen by the
    /// allowance of an undeformed cell of that spacing, the largest of any cell's.
    #[must_use]
    pub fn with_spacing(settings: &Settings, origin: DVec3, h: DVec3, u_max: DVec3) -> Self {
        Self {
            xi: settings.inside_tol + 16.0 * settings.epsilon(),
            kernel: 4.0 * settings.epsilon() * u_max.abs(),
            origin: origin.abs(),
            h,
            per_length: 4.0 / h.min_element(),
        }
    }

    /// These constants with `length` (per component) added to the rounding length
    /// ([`InsideTolerance::length`]): an adaptive body's seam ([`crate::AdaptiveBody::seam`]),
    /// how far its hanging nodes may lie off the faces they hang on.
    #[must_use]
    pub fn with_added_length(mut self, length: DVec3) -> Self {
        self.kernel += length.abs();
        self
    }

    /// The allowance in ξ units, the same on every axis: the setting plus the kernel's rounding.
    #[inline]
    #[must_use]
    pub fn xi(&self) -> f64 {
        self.xi
    }

    /// The rounding length L (per component) for a query at `x`.
    #[inline]
    #[must_use]
    pub fn length(&self, x: DVec3) -> DVec3 {
        self.kernel + 4.0 * f64::EPSILON * x.abs().max(self.origin)
    }

    /// [`InsideTolerance::length`] in lanes (the batched search): the same operations.
    #[inline(always)]
    pub(crate) fn length_lanes<D: Lanes<S = f64>>(&self, x: V3<D>) -> V3<D> {
        let splat = V3::<D>::splat;
        splat(self.kernel)
            + x.abs()
                .max(splat(self.origin))
                .scale(D::splat(4.0 * f64::EPSILON))
    }

    /// The Newton options of `settings` with the ξ allowance above, for a query of length 0 (a
    /// locator's base, completed per point).
    #[must_use]
    pub fn newton(&self, settings: &Settings) -> NewtonOptions {
        NewtonOptions {
            inside_tol: DVec3::splat(self.xi),
            ..settings.newton()
        }
    }

    /// The Newton options of `settings` for a query at `x`: both allowances above.
    #[must_use]
    pub fn options(&self, settings: &Settings, x: DVec3) -> NewtonOptions {
        NewtonOptions {
            inside_length: self.length(x),
            ..self.newton(settings)
        }
    }

    /// The allowance (ξ units, per axis) for a query at `x` in an undeformed cell of spacing `h`:
    /// `t + 2 L_k / h_k`.
    #[inline]
    #[must_use]
    pub fn undeformed(&self, x: DVec3, h: DVec3) -> DVec3 {
        DVec3::splat(self.xi) + 2.0 * self.length(x) / h
    }

    /// The allowance (ξ units, per axis) for a query at `x` in an undeformed cell of the spacing
    /// these constants were made with ([`Settings::inside_tolerance`]).
    #[inline]
    #[must_use]
    pub fn at(&self, x: DVec3) -> DVec3 {
        self.undeformed(x, self.h)
    }

    /// What the filters widen by for a point of rounding length `length`, ξ units: `t` plus
    /// twice the largest L_j times the largest 2 / h_k (the kernel accepts a point within L_j
    /// of a cell plus second-order terms of at most the largest L_j), at least every component
    /// of [`InsideTolerance::at`].
    #[inline(always)]
    pub(crate) fn tau(&self, length: DVec3) -> f64 {
        self.xi + self.per_length * length.max_element()
    }

    /// [`InsideTolerance::tau`] in lanes: the same operations.
    #[inline(always)]
    pub(crate) fn tau_lanes<D: Lanes<S = f64>>(&self, length: V3<D>) -> D {
        D::splat(self.xi) + D::splat(self.per_length) * length.max_element()
    }
}
