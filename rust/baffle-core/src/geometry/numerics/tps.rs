//! Thin-plate spline from a 2D parameter domain to 3D points.
//!
//! The paper maps the planar parameter domain of the seam (its best-fit-plane
//! projection) to the 3D baffle: landmarks are the seam points (and any interior
//! control points), and the spline fills in the surface with minimal bending energy.

use crate::geometry::mesh::Vec3;
use nalgebra::DMatrix;
use rayon::prelude::*;

/// f(p) = sum_i w_i U(|p - p_i|) + a_0 + a_1 u + a_2 v with U(r) = r^2 ln r, one
/// such function per output coordinate.
#[derive(Clone, Debug)]
pub struct ThinPlateSpline {
    landmarks: Vec<(f64, f64)>,
    /// Kernel weight of each landmark (mm per kernel unit), per output coordinate.
    weights: Vec<Vec3>,
    /// Affine part: constant, u coefficient, v coefficient.
    affine: [Vec3; 3],
}

/// U(r) = r^2 ln r written as r^2 ln(r^2) / 2 (no square root), with U(0) = 0.
fn kernel(du: f64, dv: f64) -> f64 {
    let r2 = du * du + dv * dv;
    if r2 > 0.0 {
        0.5 * r2 * r2.ln()
    } else {
        0.0
    }
}

/// The factorized TPS system for fixed landmark parameters: fitting new values at
/// the same parameters (as the design's correction rounds do) reuses the LU.
#[derive(Clone, Debug)]
pub struct TpsSolver {
    landmarks: Vec<(f64, f64)>,
    lu: nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>,
}

impl TpsSolver {
    /// Factor [K + lambda I, P; P^T, 0] for `params`. `regularization` (lambda >= 0) is
    /// added to the kernel diagonal: 0 interpolates exactly, larger values smooth.
    pub fn new(params: &[(f64, f64)], regularization: f64) -> Result<Self, String> {
        validate_parameters(params, regularization)?;
        let lu = build_system(params, regularization).lu();
        Ok(TpsSolver { landmarks: params.to_vec(), lu })
    }

    /// The spline through `values` at the factored parameters (three coordinates at once).
    pub fn fit(&self, values: &[Vec3]) -> Result<ThinPlateSpline, String> {
        let n = self.landmarks.len();
        validate_values(&self.landmarks, values)?;
        let mut rhs = DMatrix::zeros(n + 3, 3);
        for (i, v) in values.iter().enumerate() {
            for c in 0..3 {
                rhs[(i, c)] = v[c];
            }
        }
        let solution = self.lu.solve(&rhs).ok_or_else(|| {
            format!("thin-plate spline: the {n}-landmark system is singular (landmarks nearly collinear or repeated?)")
        })?;
        if solution.iter().any(|x| !x.is_finite()) {
            return Err(format!("thin-plate spline: the {n}-landmark system is numerically singular"));
        }
        let row = |r: usize| Vec3::new(solution[(r, 0)], solution[(r, 1)], solution[(r, 2)]);
        Ok(ThinPlateSpline {
            landmarks: self.landmarks.clone(),
            weights: (0..n).map(row).collect(),
            affine: [row(n), row(n + 1), row(n + 2)],
        })
    }
}

impl ThinPlateSpline {
    /// Fit to `values` at `params` (see [`TpsSolver`] to fit several value sets).
    pub fn fit(params: &[(f64, f64)], values: &[Vec3], regularization: f64) -> Result<Self, String> {
        validate_values(params, values)?;
        TpsSolver::new(params, regularization)?.fit(values)
    }

    /// The 3D point (mm) at parameter (u, v).
    pub fn eval(&self, (u, v): (f64, f64)) -> Vec3 {
        let bending: Vec3 =
            self.landmarks.iter().zip(&self.weights).map(|(&(lu, lv), w)| kernel(u - lu, v - lv) * w).sum();
        bending + self.affine[0] + u * self.affine[1] + v * self.affine[2]
    }

    /// `eval` at many parameters, in parallel.
    pub fn eval_many(&self, params: &[(f64, f64)]) -> Vec<Vec3> {
        params.par_iter().map(|&p| self.eval(p)).collect()
    }

    pub fn num_landmarks(&self) -> usize {
        self.landmarks.len()
    }
}

fn validate_values(params: &[(f64, f64)], values: &[Vec3]) -> Result<(), String> {
    if params.len() != values.len() {
        return Err(format!("thin-plate spline: {} parameters but {} values", params.len(), values.len()));
    }
    if let Some(i) = (0..values.len()).find(|&i| !values[i].iter().all(|c| c.is_finite())) {
        return Err(format!("thin-plate spline: landmark {i} is not finite ({:?} -> {:?})", params[i], values[i]));
    }
    Ok(())
}

fn validate_parameters(params: &[(f64, f64)], regularization: f64) -> Result<(), String> {
    if params.len() < 3 {
        return Err(format!("thin-plate spline needs at least 3 landmarks, got {}", params.len()));
    }
    if !(regularization.is_finite() && regularization >= 0.0) {
        return Err(format!("thin-plate spline: regularization must be finite and >= 0, got {regularization}"));
    }
    if let Some(i) = (0..params.len()).find(|&i| !(params[i].0.is_finite() && params[i].1.is_finite())) {
        return Err(format!("thin-plate spline: landmark {i} is not finite ({:?})", params[i]));
    }
    let extent = parameter_extent(params);
    if let Some((i, j)) = find_duplicate(params, 1e-12 * extent) {
        return Err(format!(
            "thin-plate spline: landmarks {i} and {j} have the same parameter {:?}; remove one",
            params[i]
        ));
    }
    if spans_area(params, extent) {
        Ok(())
    } else {
        Err(format!("thin-plate spline: all {} landmark parameters are collinear", params.len()))
    }
}

/// Largest coordinate range of the parameters (scale for the tolerances).
fn parameter_extent(params: &[(f64, f64)]) -> f64 {
    let (mut min_u, mut max_u, mut min_v, mut max_v) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(u, v) in params {
        (min_u, max_u, min_v, max_v) = (min_u.min(u), max_u.max(u), min_v.min(v), max_v.max(v));
    }
    (max_u - min_u).max(max_v - min_v)
}

/// First pair of parameters closer than `tolerance` in both coordinates, by a sweep
/// over u-sorted order (n log n).
fn find_duplicate(params: &[(f64, f64)], tolerance: f64) -> Option<(usize, usize)> {
    let mut order: Vec<usize> = (0..params.len()).collect();
    order.sort_by(|&a, &b| params[a].0.total_cmp(&params[b].0));
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if params[j].0 - params[i].0 > tolerance {
                break;
            }
            if (params[j].1 - params[i].1).abs() <= tolerance {
                return Some((i.min(j), i.max(j)));
            }
        }
    }
    None
}

/// Whether the parameters span a 2D region: the triangle with the two farthest-apart
/// points found from the first one has non-negligible area with some third point.
fn spans_area(params: &[(f64, f64)], extent: f64) -> bool {
    let p0 = params[0];
    let distance2 = |p: (f64, f64), q: (f64, f64)| (p.0 - q.0).powi(2) + (p.1 - q.1).powi(2);
    let farthest = |from: (f64, f64)| {
        params.iter().copied().max_by(|&a, &b| distance2(a, from).total_cmp(&distance2(b, from))).unwrap_or(from)
    };
    let a = farthest(p0);
    let b = farthest(a);
    let cross = |p: (f64, f64)| ((b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)).abs();
    params.iter().any(|&p| cross(p) > 1e-10 * extent * extent)
}

/// The (n+3) x (n+3) TPS system matrix.
fn build_system(params: &[(f64, f64)], regularization: f64) -> DMatrix<f64> {
    let n = params.len();
    DMatrix::from_fn(n + 3, n + 3, |r, c| match (r < n, c < n) {
        (true, true) if r == c => regularization,
        (true, true) => kernel(params[r].0 - params[c].0, params[r].1 - params[c].1),
        (true, false) => affine_basis(params[r], c - n),
        (false, true) => affine_basis(params[c], r - n),
        (false, false) => 0.0,
    })
}

/// The affine basis functions 1, u, v at a parameter.
fn affine_basis((u, v): (f64, f64), which: usize) -> f64 {
    match which {
        0 => 1.0,
        1 => u,
        _ => v,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Scattered landmarks on a disc of radius 10 (a golden-angle spiral) with a curved
    /// 3D target, like a seam with interior control points.
    fn landmarks(n: usize) -> (Vec<(f64, f64)>, Vec<Vec3>) {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let params: Vec<(f64, f64)> = (0..n)
            .map(|i| {
                let r = 10.0 * ((i as f64 + 0.5) / n as f64).sqrt();
                let a = golden * i as f64;
                (r * a.cos(), r * a.sin())
            })
            .collect();
        let values =
            params.iter().map(|&(u, v)| Vec3::new(u, v, 0.05 * (u * u - 0.5 * v * v) + (0.3 * u).sin())).collect();
        (params, values)
    }

    #[test]
    fn interpolates_landmarks_exactly_without_regularization() {
        let (params, values) = landmarks(120);
        let tps = ThinPlateSpline::fit(&params, &values, 0.0).unwrap();
        let fitted = tps.eval_many(&params);
        for (i, (f, v)) in fitted.iter().zip(&values).enumerate() {
            assert!((f - v).norm() < 1e-9, "landmark {i}: {}", (f - v).norm());
        }
    }

    #[test]
    fn regularization_smooths_instead_of_interpolating() {
        let (params, values) = landmarks(60);
        let tps = ThinPlateSpline::fit(&params, &values, 10.0).unwrap();
        let worst = params.iter().zip(&values).map(|(&p, v)| (tps.eval(p) - v).norm()).fold(0.0, f64::max);
        assert!(worst > 1e-6, "lambda > 0 no longer interpolates ({worst})");
    }

    #[test]
    fn reproduces_an_affine_map_exactly() {
        let (params, _) = landmarks(40);
        let affine = |(u, v): (f64, f64)| Vec3::new(2.0 + 0.5 * u - v, -1.0 + 3.0 * v, 0.25 * u + 0.75 * v + 4.0);
        let values: Vec<Vec3> = params.iter().map(|&p| affine(p)).collect();
        let tps = ThinPlateSpline::fit(&params, &values, 0.0).unwrap();
        for p in [(0.0, 0.0), (3.3, -7.1), (15.0, 20.0)] {
            assert!((tps.eval(p) - affine(p)).norm() < 1e-9, "at {p:?}");
        }
    }

    #[test]
    fn duplicate_collinear_and_malformed_landmarks_are_rejected() {
        let (mut params, values) = landmarks(20);
        params[13] = params[4];
        let err = ThinPlateSpline::fit(&params, &values, 0.0).unwrap_err();
        assert!(err.contains("landmarks 4 and 13"), "{err}");
        let line: Vec<(f64, f64)> = (0..5).map(|i| (i as f64, 2.0 * i as f64)).collect();
        let err = ThinPlateSpline::fit(&line, &values[..5], 0.0).unwrap_err();
        assert!(err.contains("collinear"), "{err}");
        assert!(ThinPlateSpline::fit(&line[..2], &values[..2], 0.0).unwrap_err().contains("at least 3"));
        assert!(ThinPlateSpline::fit(&line, &values[..4], 0.0).unwrap_err().contains("5 parameters but 4"));
        let (params, values) = landmarks(10);
        assert!(ThinPlateSpline::fit(&params, &values, -1.0).unwrap_err().contains("regularization"));
    }

    /// Release-mode timing: `cargo test --release -- --ignored --nocapture tps_fit_time`.
    #[test]
    #[ignore]
    fn tps_fit_time() {
        for n in [400, 1500] {
            let (params, values) = landmarks(n);
            let start = std::time::Instant::now();
            let tps = ThinPlateSpline::fit(&params, &values, 0.0).unwrap();
            let elapsed_ms = start.elapsed().as_secs_f64() * 1e3;
            println!("TPS fit with {n} landmarks: {elapsed_ms:.1} ms");
            assert!((tps.eval(params[7]) - values[7]).norm() < 1e-6);
            if n == 400 && !cfg!(debug_assertions) {
                assert!(elapsed_ms < 100.0, "400-landmark fit took {elapsed_ms:.1} ms");
            }
        }
    }
}
