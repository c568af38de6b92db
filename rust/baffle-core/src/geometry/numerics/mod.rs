//! Numerical building blocks shared by the design steps: best-fit planes (PCA),
//! closed cubic splines for the suture curve, PCHIP curves for the seam, thin-plate
//! splines for the baffle surface, and the least concave majorant used to keep an
//! area profile well behaved.
//!
//! Every constructor validates its input and returns `Result<_, String>` whose
//! message names the offending value or index.

pub mod concave;
pub mod pca;
pub mod pchip;
pub mod spline;
pub mod tps;

pub use concave::least_concave_majorant;
pub use pca::{best_fit_plane, best_fit_plane_checked, polygon_area_2d, polygon_vector_area, Plane};
pub use pchip::{CurveSample, Pchip, PchipCurve3};
pub use spline::ClosedSpline;
pub use tps::{ThinPlateSpline, TpsSolver};

/// Checks samples (x_i, y_i) of a function of x: as many x as y, at least `min_points`,
/// all finite, x strictly increasing. The message starts with `what` and names the
/// offending count or index.
fn check_samples(what: &str, x: &[f64], y: &[f64], min_points: usize) -> Result<(), String> {
    if x.len() != y.len() {
        return Err(format!("{what}: {} x values but {} y values", x.len(), y.len()));
    }
    if x.len() < min_points {
        return Err(format!("{what} needs at least {min_points} points, got {}", x.len()));
    }
    if let Some(i) = (0..x.len()).find(|&i| !x[i].is_finite() || !y[i].is_finite()) {
        return Err(format!("{what}: point {i} is not finite (x = {}, y = {})", x[i], y[i]));
    }
    if let Some(i) = (1..x.len()).find(|&i| x[i] <= x[i - 1]) {
        return Err(format!("{what}: x must be strictly increasing, but x[{i}] = {} <= x[{}] = {}", x[i], i - 1, x[i - 1]));
    }
    Ok(())
}

/// Nodes and weights of the 8-point Gauss-Legendre rule on [-1, 1] (exact for
/// polynomials up to degree 15; the speed |C'(t)| of a cubic is the square root of
/// a quartic, which this integrates to ~1e-10 relative on one spline segment).
const GAUSS_LEGENDRE_8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
    (-0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (-0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
];

/// Integral of `f` over [a, b] by 8-point Gauss-Legendre (signed: negative if b < a).
pub(crate) fn gauss_legendre_8(f: impl Fn(f64) -> f64, a: f64, b: f64) -> f64 {
    let half = 0.5 * (b - a);
    let mid = 0.5 * (a + b);
    half * GAUSS_LEGENDRE_8.iter().map(|&(x, w)| w * f(mid + half * x)).sum::<f64>()
}

/// Solve `g(x) = target` for x in [lo, hi] where g is increasing with derivative
/// `dg` >= 0, by Newton steps kept inside a shrinking bracket (bisection when a
/// step leaves it). Used to invert arc length. Assumes g(lo) <= target <= g(hi).
pub(crate) fn invert_increasing(
    g: impl Fn(f64) -> f64,
    dg: impl Fn(f64) -> f64,
    target: f64,
    mut lo: f64,
    mut hi: f64,
    abs_tol: f64,
) -> f64 {
    let mut x = 0.5 * (lo + hi);
    for _ in 0..100 {
        let residual = g(x) - target;
        if residual.abs() <= abs_tol {
            return x;
        }
        if residual > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        let slope = dg(x);
        let newton = x - residual / slope;
        x = if slope > 0.0 && newton > lo && newton < hi { newton } else { 0.5 * (lo + hi) };
        if hi - lo <= f64::EPSILON * hi.abs().max(lo.abs()).max(1.0) {
            return x;
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_8_is_exact_for_degree_15() {
        let integral = gauss_legendre_8(|x| x.powi(15) + 3.0 * x.powi(14), 0.0, 2.0);
        let exact = 2f64.powi(16) / 16.0 + 3.0 * 2f64.powi(15) / 15.0;
        assert!((integral - exact).abs() < 1e-9 * exact, "{integral} vs {exact}");
    }

    #[test]
    fn invert_increasing_finds_cube_root() {
        let x = invert_increasing(|x| x * x * x, |x| 3.0 * x * x, 2.0, 0.0, 2.0, 1e-14);
        assert!((x - 2f64.cbrt()).abs() < 1e-12, "{x}");
    }
}
pub mod random;
