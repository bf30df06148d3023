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
    /// Newton iteration limit per candidate cell.
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

    /// Check ranges: tolerances finite and non-negative, at least one iteration.
    pub fn validate(&self) -> Result<(), Error> {
        if !(self.newton_tol.is_finite() && self.newton_tol > 0.0) {
            return Err(Error::InvalidSettings(format!(
                "Newton tolerance {} must be finite and > 0",
                self.newton_tol
            )));
        }
        if !(self.inside_tol.is_finite() && self.inside_tol >= 0.0) {
            return Err(Error::InvalidSettings(format!(
                "inside tolerance {} must be finite and ≥ 0",
                self.inside_tol
            )));
        }
        if self.max_iter == 0 {
            return Err(Error::InvalidSettings(
                "the iteration limit must be at least 1".into(),
            ));
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

    /// Inside tolerance (ξ units, per axis) for a query at `x` on `lattice` with largest
    /// displacement component `u_max`: the setting plus the rounding carried by the data. A point
    /// given on a face of a cell far from the origin is only known to `eps · |x|`, and the kernel
    /// rounds at its own precision, so the allowance along axis k is
    /// `8 ε₆₄ max(|x|∞, |origin|∞) / h_k + 8 ε_kernel (2 + u_max / h_k)` (the lattice's origin
    /// counts too: a cell's corners are computed from it). Closed cells stay closed at any offset,
    /// and no more, whatever the anisotropy: with the smallest spacing on every axis, a point
    /// 5e-4 h outside a face of a 1000 : 1 cell at 1e9 was found inside. Every strategy uses this,
    /// so that they agree on what "inside" means.
    #[must_use]
    pub fn inside_tolerance(&self, lattice: &Lattice, u_max: f64, x: DVec3) -> DVec3 {
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

/// [`Settings::inside_tolerance`] with its per-body constants computed once, so that a query costs
/// one multiply-add and no division.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InsideTolerance {
    /// The setting plus the kernel's allowance, per axis.
    base: DVec3,
    /// The part of `base` that does not depend on the spacing: the setting plus 16 ε_kernel.
    fixed: DVec3,
    /// 8 ε₆₄ / h_k.
    per_magnitude: DVec3,
    /// |origin|∞ of the lattice.
    origin_magnitude: f64,
}

impl InsideTolerance {
    /// The constants of [`Settings::inside_tolerance`] for a body on `lattice` with `u_max`.
    #[must_use]
    pub fn new(settings: &Settings, lattice: &Lattice, u_max: f64) -> Self {
        Self::with_spacing(settings, lattice.origin(), lattice.h(), u_max)
    }

    /// The same constants for a body whose lattice starts at `origin` and whose smallest cell
    /// edges are `h` per axis (an adaptive body's finest spacing).
    #[must_use]
    pub fn with_spacing(settings: &Settings, origin: DVec3, h: DVec3, u_max: f64) -> Self {
        let eps = 8.0 * settings.epsilon();
        Self {
            base: h
                .to_array()
                .map(|h| settings.inside_tol + eps * (2.0 + u_max / h))
                .into(),
            fixed: DVec3::splat(settings.inside_tol + eps * 2.0),
            per_magnitude: h.to_array().map(|h| 8.0 * f64::EPSILON / h).into(),
            origin_magnitude: origin.abs().max_element(),
        }
    }

    /// `tol`, a tolerance [`InsideTolerance::at`] gave, for a cell whose edges are 1/`ratio` times
    /// the spacing these constants were made with: an adaptive body's leaf of level `level` has
    /// `ratio` 2^(level − finest) ≤ 1, a power of two. The allowance's terms in 1/h (the rounding
    /// of x and of the displacements, measured in the cell's ξ) shrink by `ratio`; the setting and
    /// the kernel's own rounding do not. With the finest spacing's tolerance on every leaf, a point
    /// 3e-7 outside a level-0 leaf at x = 1e5 beside a level-15 one was found inside it (ξ clamped
    /// to 1, residual 0). Unchanged at `ratio` 1.
    #[inline]
    #[must_use]
    pub fn for_cell(&self, tol: DVec3, ratio: f64) -> DVec3 {
        if ratio < 1.0 {
            self.fixed + (tol - self.fixed) * ratio
        } else {
            tol
        }
    }

    /// [`InsideTolerance::for_cell`] for an adaptive body's leaf of `level` when these constants
    /// were made with the spacing of its `finest` level: `ratio` 2^(level − finest).
    #[inline]
    #[must_use]
    pub fn for_leaf(&self, tol: DVec3, level: u8, finest: u8) -> DVec3 {
        self.for_cell(tol, 0.5f64.powi(i32::from(finest - level)))
    }

    /// [`InsideTolerance::for_cell`] in lanes, each lane with its cell's `ratio`: the same
    /// operations.
    #[inline(always)]
    pub(crate) fn for_cells<D: Lanes<S = f64>>(&self, tol: V3<D>, ratio: D) -> V3<D> {
        let finer = ratio.lt(D::splat(1.0));
        let scaled = |t: D, fixed: f64| {
            let fixed = D::splat(fixed);
            D::select(finer, fixed + (t - fixed) * ratio, t)
        };
        V3 {
            x: scaled(tol.x, self.fixed.x),
            y: scaled(tol.y, self.fixed.y),
            z: scaled(tol.z, self.fixed.z),
        }
    }

    /// The inside tolerance (ξ units, per axis) for a query at `x`.
    #[inline]
    #[must_use]
    pub fn at(&self, x: DVec3) -> DVec3 {
        let magnitude = x.abs().max_element().max(self.origin_magnitude);
        self.base + self.per_magnitude * magnitude
    }

    /// [`InsideTolerance::at`] from |x|∞, in lanes (the batched search).
    #[inline(always)]
    pub(crate) fn at_magnitude<D: Lanes<S = f64>>(&self, magnitude: D) -> V3<D> {
        let magnitude = magnitude.max(D::splat(self.origin_magnitude));
        V3 {
            x: D::splat(self.base.x) + D::splat(self.per_magnitude.x) * magnitude,
            y: D::splat(self.base.y) + D::splat(self.per_magnitude.y) * magnitude,
            z: D::splat(self.base.z) + D::splat(self.per_magnitude.z) * magnitude,
        }
    }
}
