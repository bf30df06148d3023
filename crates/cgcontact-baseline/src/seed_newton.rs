//! **The seed's Newton** (`EvalLocCoords3D` of the 2019 thesis), kept only so that the trade report
//! can show what its loose stopping test costs. The project's own inversion is the core's
//! [`cgcontact::hex8`] kernel; nothing else in this crate uses this function.

use cgcontact::glam::{DMat3, DVec3};
use cgcontact::hex8::{Hex8Map, Inversion, Status};

/// The seed's stopping test: the physical residual norm |x − x(ξ)| at most this, **absolute**, in the
/// body's length unit (`Tol = 10e-2` in the seed, i.e. 0.1 mm on its 0.25 mm elements).
pub const SEED_TOL: f64 = 0.1;

/// The iteration guard the seed lacked (its loop never ends on a diverging Newton).
pub const SEED_MAX_ITER: u32 = 100;

/// The seed's `EvalLocCoords3D`: Newton from ξ = 0, full steps ξ ← ξ + J⁻¹ (x − x(ξ)), stopping as soon
/// as |x − x(ξ)| ≤ [`SEED_TOL`] with no test on the step; the point is inside when every |ξ_k| ≤ 1 (no
/// tolerance). `x` and `map` share one frame (use the cell's local frame).
///
/// Differences from the seed, all guards: after [`SEED_MAX_ITER`] iterations the result is
/// [`Status::NotConverged`]; a zero or non-finite det J, or a non-finite iterate, is
/// [`Status::Singular`] (the seed would divide by zero, and then accept NaN as "inside" because
/// `abs(NaN) > 1` is false). The seed's `round(I*Res, 14)` is omitted (it only hides MATLAB noise).
#[must_use]
pub fn seed_eval_loc_coords(map: &Hex8Map, x: DVec3) -> Inversion {
    let mut xi = DVec3::ZERO;
    let (mut fx, mut jac) = map.map_and_jacobian(xi);
    let mut residual = x - fx;
    let mut iterations = 0;
    let finish = |status, xi, iterations, residual: DVec3| Inversion {
        status,
        xi,
        iterations,
        residual: residual.length(),
    };
    // Stop only on a residual known to be within the tolerance: a NaN one (a point or a map with
    // a NaN) iterates, and ends Singular (`residual > SEED_TOL` let it out at ξ = 0, inside).
    loop {
        let converged = residual.length() <= SEED_TOL;
        if converged {
            break;
        }
        if iterations == SEED_MAX_ITER {
            return finish(Status::NotConverged, xi, iterations, residual);
        }
        let j = DMat3::from_cols(jac[0], jac[1], jac[2]);
        let det = j.determinant();
        if !(det.is_finite() && det != 0.0) {
            return finish(Status::Singular, xi, iterations, residual);
        }
        xi += j.inverse() * residual;
        iterations += 1;
        if !xi.is_finite() {
            return finish(Status::Singular, xi, iterations, residual);
        }
        (fx, jac) = map.map_and_jacobian(xi);
        residual = x - fx;
    }
    let status = if xi.abs().max_element() <= 1.0 {
        Status::Inside
    } else {
        Status::Outside
    };
    finish(status, xi, iterations, residual)
}

#[cfg(test)]
mod tests {
    use super::*;
    use cgcontact::hex8::Kernel;

    /// A NaN point, or a map with a NaN corner, made a NaN residual, which `residual > tol`
    /// let out of the loop at ξ = 0: `Inside`, the answer the guards exist to prevent. It is
    /// `Singular` now; a finite point in the same cell is still found at its ξ.
    #[test]
    fn a_nan_point_or_corner_is_singular_not_inside() {
        let mut u = [DVec3::ZERO; 8];
        u[6] = DVec3::splat(0.2);
        let map = Hex8Map::lattice_cell(DVec3::ONE, &u);
        for x in [DVec3::NAN, DVec3::new(0.5, f64::NAN, 0.5)] {
            let inversion = seed_eval_loc_coords(&map, x);
            assert_eq!(inversion.status, Status::Singular, "{x}: {inversion:?}");
        }
        u[3].y = f64::NAN;
        let broken = Hex8Map::lattice_cell(DVec3::ONE, &u);
        let inversion = seed_eval_loc_coords(&broken, DVec3::splat(0.5));
        assert_eq!(inversion.status, Status::Singular, "{inversion:?}");
        // The known point: ξ = (0.3, −0.4, 0.5) maps to x; 0.2 of a cell beyond tolerance
        // from the centre, so the seed iterates and lands within 0.1 of it.
        let xi = DVec3::new(0.3, -0.4, 0.5);
        let found = seed_eval_loc_coords(&map, map.map(xi));
        assert_eq!(found.status, Status::Inside);
        assert!(found.residual <= SEED_TOL);
    }

    #[test]
    fn stops_at_the_loose_tolerance() {
        // A unit cube: x(ξ) is affine, so one full step lands exactly; the centre needs none.
        let map = Hex8Map::lattice_cell(DVec3::ONE, &[DVec3::ZERO; 8]);
        let centre = seed_eval_loc_coords(&map, DVec3::splat(0.5));
        assert_eq!((centre.status, centre.iterations), (Status::Inside, 0));
        // 0.05 from the centre: within the seed's 0.1, so ξ stays 0 (an error of 0.1 in ξ).
        let near = seed_eval_loc_coords(&map, DVec3::new(0.55, 0.5, 0.5));
        assert_eq!((near.status, near.xi), (Status::Inside, DVec3::ZERO));
        // Beyond the tolerance the full step is exact here, so a point outside is outside.
        let outside = seed_eval_loc_coords(&map, DVec3::new(1.05, 0.5, 0.5));
        assert_eq!(outside.status, Status::Outside);
        // A 0.1-wide cell spans [0, 0.1]³: a point 0.02 beyond its face is 0.07 from its centre, within
        // the seed's tolerance at ξ = 0, so the seed calls it inside.
        let small = Hex8Map::lattice_cell(DVec3::splat(0.1), &[DVec3::ZERO; 8]);
        let wrong = seed_eval_loc_coords(&small, DVec3::new(0.12, 0.05, 0.05));
        assert_eq!((wrong.status, wrong.xi), (Status::Inside, DVec3::ZERO));
    }

    #[test]
    fn degenerate_cell_is_singular() {
        let flat = Hex8Map::lattice_cell(DVec3::new(1.0, 1.0, 0.0), &[DVec3::ZERO; 8]);
        assert_eq!(
            seed_eval_loc_coords(&flat, DVec3::new(0.5, 0.5, 1.0)).status,
            Status::Singular
        );
    }
}
