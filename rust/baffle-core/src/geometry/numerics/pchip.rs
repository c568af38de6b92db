//! Piecewise cubic Hermite interpolation (PCHIP), matching
//! `scipy.interpolate.PchipInterpolator`, and a 3D curve built from three of them.
//!
//! The paper's reference implementation uses scipy's PCHIP to interpolate the seam
//! between suture points; it never overshoots the data, so the seam stays on the
//! side of the wall the points are on. Same derivative rules here so results match.

use super::{gauss_legendre_8, invert_increasing};
use crate::geometry::mesh::Vec3;
use std::ops::{Div, Sub};

/// 1D monotonicity-preserving cubic interpolant y(x).
#[derive(Clone, Debug)]
pub struct Pchip {
    x: Vec<f64>,
    y: Vec<f64>,
    /// dy/dx at each knot (Fritsch-Carlson as scipy computes it).
    slopes: Vec<f64>,
}

impl Pchip {
    /// Interpolant through (x_i, y_i); x strictly increasing, at least 2 points.
    pub fn new(x: &[f64], y: &[f64]) -> Result<Self, String> {
        super::check_samples("PCHIP", x, y, 2)?;
        Ok(Pchip { x: x.to_vec(), y: y.to_vec(), slopes: knot_slopes(x, y) })
    }

    /// The cubic Hermite interpolant with the given dy/dx at each knot.
    pub fn with_slopes(x: &[f64], y: &[f64], slopes: &[f64]) -> Result<Self, String> {
        let mut p = Self::new(x, y)?;
        if slopes.len() != x.len() || slopes.iter().any(|d| !d.is_finite()) {
            return Err(format!("Hermite interpolant: {} finite slopes needed, got {slopes:?}", x.len()));
        }
        p.slopes = slopes.to_vec();
        Ok(p)
    }

    /// The derivative dy/dx chosen at each knot.
    pub fn knot_derivatives(&self) -> &[f64] {
        &self.slopes
    }

    /// Interpolated value; outside [x_0, x_last] the end cubic is extended (as scipy does).
    pub fn eval(&self, x: f64) -> f64 {
        let (k, h, s) = self.locate(x);
        let (s2, s3) = (s * s, s * s * s);
        (2.0 * s3 - 3.0 * s2 + 1.0) * self.y[k]
            + (s3 - 2.0 * s2 + s) * h * self.slopes[k]
            + (-2.0 * s3 + 3.0 * s2) * self.y[k + 1]
            + (s3 - s2) * h * self.slopes[k + 1]
    }

    /// Analytic dy/dx of the interpolant.
    pub fn derivative(&self, x: f64) -> f64 {
        let (k, h, s) = self.locate(x);
        let s2 = s * s;
        (6.0 * s2 - 6.0 * s) * (self.y[k] - self.y[k + 1]) / h
            + (3.0 * s2 - 4.0 * s + 1.0) * self.slopes[k]
            + (3.0 * s2 - 2.0 * s) * self.slopes[k + 1]
    }

    /// Interval index k (x in [x_k, x_k+1], clamped to the end intervals), its width,
    /// and the normalised position s = (x - x_k) / h.
    fn locate(&self, x: f64) -> (usize, f64, f64) {
        let last_interval = self.x.len() - 2;
        let k = self.x.partition_point(|&knot| knot <= x).saturating_sub(1).min(last_interval);
        let h = self.x[k + 1] - self.x[k];
        (k, h, (x - self.x[k]) / h)
    }
}

/// Sign as numpy's `np.sign`: 0 for zero (f64::signum gives 1 for +0).
fn sign(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// The knot spacings h_k and the secants (v_(k+1) - v_k) / h_k of `values` at `knots`
/// (numbers for [`knot_slopes`], points for [`vector_knot_velocities`]).
fn secants<T: Copy + Sub<Output = T> + Div<f64, Output = T>>(knots: &[f64], values: &[T]) -> (Vec<f64>, Vec<T>) {
    let h: Vec<f64> = knots.windows(2).map(|w| w[1] - w[0]).collect();
    let secant = (0..values.len() - 1).map(|k| (values[k + 1] - values[k]) / h[k]).collect();
    (h, secant)
}

/// Knot derivatives by scipy's `_find_derivatives`: interior knots take the weighted
/// harmonic mean of the neighbouring secant slopes (0 at a local extremum or flat
/// part), end knots the shape-preserving 3-point formula; 2 points give the line.
fn knot_slopes(x: &[f64], y: &[f64]) -> Vec<f64> {
    let n = x.len();
    let (h, m) = secants(x, y);
    if n == 2 {
        return vec![m[0], m[0]];
    }
    let mut slopes = vec![0.0; n];
    for k in 1..n - 1 {
        let (m_left, m_right) = (m[k - 1], m[k]);
        if sign(m_left) != sign(m_right) || m_left == 0.0 || m_right == 0.0 {
            continue; // local extremum or flat: 0 keeps the interpolant monotone
        }
        let w1 = 2.0 * h[k] + h[k - 1];
        let w2 = h[k] + 2.0 * h[k - 1];
        slopes[k] = (w1 + w2) / (w1 / m_left + w2 / m_right);
    }
    slopes[0] = end_slope(h[0], h[1], m[0], m[1]);
    slopes[n - 1] = end_slope(h[n - 2], h[n - 3], m[n - 2], m[n - 3]);
    slopes
}

/// scipy's `_edge_case`: one-sided 3-point estimate, set to 0 if it points against
/// the end secant, limited to 3 m0 when the data turn (Fritsch-Carlson bound).
fn end_slope(h0: f64, h1: f64, m0: f64, m1: f64) -> f64 {
    let d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1);
    if sign(d) != sign(m0) {
        0.0
    } else if sign(m0) != sign(m1) && d.abs() > 3.0 * m0.abs() {
        3.0 * m0
    } else {
        d
    }
}

/// Knot velocities of [`PchipCurve3::rotation_invariant`] (chord-length knots, so each
/// chord's velocity d_k is its unit direction).
fn vector_knot_velocities(points: &[Vec3], knots: &[f64]) -> Vec<Vec3> {
    let n = points.len();
    let (h, d) = secants(knots, points);
    if n == 2 {
        return vec![d[0], d[0]];
    }
    let end = |h0: f64, h1: f64, d0: Vec3, d1: Vec3| ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1);
    let mut velocities = vec![end(h[0], h[1], d[0], d[1])];
    for k in 1..n - 1 {
        let (w_in, w_out) = (2.0 * h[k] + h[k - 1], h[k] + 2.0 * h[k - 1]);
        velocities.push((w_in * d[k - 1] + w_out * d[k]) / (w_in + w_out));
    }
    velocities.push(end(h[n - 2], h[n - 3], d[n - 2], d[n - 3]));
    velocities
}

/// One sample of a curve: parameter, arc length from the start of the sampled
/// range (mm), position and unit tangent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurveSample {
    pub t: f64,
    pub s_mm: f64,
    pub point: Vec3,
    pub unit_tangent: Vec3,
}

/// A 3D curve through points, parameterised by cumulative chord length t (mm), each
/// coordinate a cubic Hermite interpolant of t.
///
/// [`PchipCurve3::new`] takes each coordinate's slopes by PCHIP's rule, which limits
/// every coordinate on its own, so that curve depends on the frame the coordinates are
/// taken in; [`PchipCurve3::rotation_invariant`] applies PCHIP's weights to the chord
/// vectors instead, and turns with the points under any rigid motion.
#[derive(Clone, Debug)]
pub struct PchipCurve3 {
    points: Vec<Vec3>,
    knots: Vec<f64>,
    coordinates: [Pchip; 3],
}

impl PchipCurve3 {
    /// Curve through `points` (at least 2, consecutive ones distinct), one PCHIP per
    /// coordinate of the input frame.
    pub fn new(points: &[Vec3]) -> Result<Self, String> {
        if points.len() < 2 {
            return Err(format!("PCHIP curve needs at least 2 points, got {}", points.len()));
        }
        if let Some(i) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(format!("PCHIP curve: point {i} has a non-finite coordinate {:?}", points[i]));
        }
        let mut knots = vec![0.0];
        for i in 1..points.len() {
            let chord = (points[i] - points[i - 1]).norm();
            if chord == 0.0 {
                return Err(format!(
                    "PCHIP curve: points {} and {i} coincide ({:?}); remove the duplicate",
                    i - 1,
                    points[i]
                ));
            }
            knots.push(knots[i - 1] + chord);
        }
        let coordinate = |c: usize| {
            let values: Vec<f64> = points.iter().map(|p| p[c]).collect();
            Pchip::new(&knots, &values)
        };
        let coordinates = [coordinate(0)?, coordinate(1)?, coordinate(2)?];
        Ok(PchipCurve3 { points: points.to_vec(), knots, coordinates })
    }

    /// Curve through `points` whose velocity dC/dt at each knot is PCHIP's rule applied
    /// to the chord vectors rather than to each coordinate: at an interior knot the mean
    /// of the two neighbouring unit chord directions with scipy's PCHIP weights
    /// (2 h_k + h_k-1 on the incoming, h_k + 2 h_k-1 on the outgoing chord), at an end
    /// the same one-sided 3-point formula. Only vector sums of the points enter, so
    /// the curve turns and moves with them; the per-coordinate rule's sign tests and
    /// harmonic means do not commute with a rotation.
    pub fn rotation_invariant(points: &[Vec3]) -> Result<Self, String> {
        let mut curve = Self::new(points)?;
        let velocities = vector_knot_velocities(points, &curve.knots);
        for c in 0..3 {
            let values: Vec<f64> = points.iter().map(|p| p[c]).collect();
            let slopes: Vec<f64> = velocities.iter().map(|v| v[c]).collect();
            curve.coordinates[c] = Pchip::with_slopes(&curve.knots, &values, &slopes)?;
        }
        Ok(curve)
    }

    pub fn num_points(&self) -> usize {
        self.points.len()
    }

    /// Parameter of the last point: the polyline length through the points (mm).
    pub fn total_parameter(&self) -> f64 {
        self.knots[self.knots.len() - 1]
    }

    /// The knot t_i of input point `i` (cumulative chord length, mm).
    /// Panics if `i >= num_points()`, like slice indexing.
    pub fn parameter_of_point(&self, i: usize) -> f64 {
        self.knots[i]
    }

    /// Point at parameter t (extrapolated with the end cubics outside the knots).
    pub fn eval(&self, t: f64) -> Vec3 {
        Vec3::new(self.coordinates[0].eval(t), self.coordinates[1].eval(t), self.coordinates[2].eval(t))
    }

    /// dC/dt (analytic).
    pub fn derivative(&self, t: f64) -> Vec3 {
        Vec3::new(
            self.coordinates[0].derivative(t),
            self.coordinates[1].derivative(t),
            self.coordinates[2].derivative(t),
        )
    }

    /// Unit tangent in the direction of increasing t. Where PCHIP's derivative
    /// vanishes (every coordinate flat or extremal at a knot) the direction of the
    /// chord through the neighbouring points is used instead.
    pub fn tangent(&self, t: f64) -> Vec3 {
        let derivative = self.derivative(t);
        // |dC/dt| is about 1 under chord-length parameterisation, so this is relative.
        if derivative.norm() > 1e-9 {
            return derivative.normalize();
        }
        let last = self.points.len() - 1;
        let k = self.knots.partition_point(|&knot| knot <= t).saturating_sub(1).min(last);
        let at_knot = (t - self.knots[k]).abs() <= 1e-12 * self.total_parameter();
        let (from, to) = if at_knot { (k.saturating_sub(1), (k + 1).min(last)) } else { (k, (k + 1).min(last)) };
        (self.points[to] - self.points[from]).normalize()
    }

    /// Arc length (mm) from t0 to t1, negative if t1 < t0. Integrated piecewise between
    /// knots (the curve is only C1 there) with Gauss-Legendre on two halves of each piece.
    pub fn arc_length(&self, t0: f64, t1: f64) -> f64 {
        let (lo, hi) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
        let length: f64 = self.pieces_between(lo, hi).iter().map(|&(a, b)| self.piece_arc_length(a, b)).sum();
        if t0 <= t1 {
            length
        } else {
            -length
        }
    }

    /// Samples from t0 to t1 (t0 <= t1, both within the knots) every `spacing_mm` of arc
    /// length: s = 0 at t0, spacing_mm, 2 spacing_mm, ..., and then t1 itself as the last
    /// sample, so the last gap is in (1e-6 spacing_mm, spacing_mm]. t0 == t1 gives the
    /// single sample at t0.
    pub fn sample_by_arclength(&self, t0: f64, t1: f64, spacing_mm: f64) -> Result<Vec<CurveSample>, String> {
        self.check_sampling_range(t0, t1, spacing_mm)?;
        let pieces = self.pieces_between(t0, t1);
        let piece_lengths: Vec<f64> = pieces.iter().map(|&(a, b)| self.piece_arc_length(a, b)).collect();
        let total_mm: f64 = piece_lengths.iter().sum();
        if total_mm / spacing_mm > 1e7 {
            return Err(format!(
                "PCHIP curve: spacing {spacing_mm} mm over {total_mm:.3} mm would give more than 1e7 samples"
            ));
        }
        let mut samples = Vec::with_capacity((total_mm / spacing_mm) as usize + 2);
        let (mut piece, mut piece_start_mm) = (0, 0.0);
        let mut s_mm = 0.0;
        while s_mm < total_mm - 1e-6 * spacing_mm {
            // Targets increase, so the containing piece only moves forward.
            while piece + 1 < pieces.len() && piece_start_mm + piece_lengths[piece] <= s_mm {
                piece_start_mm += piece_lengths[piece];
                piece += 1;
            }
            let t = self.invert_piece_arc_length(pieces[piece], s_mm - piece_start_mm, piece_lengths[piece]);
            samples.push(self.sample(t, s_mm));
            s_mm = samples.len() as f64 * spacing_mm;
        }
        samples.push(self.sample(t1, total_mm));
        Ok(samples)
    }

    fn check_sampling_range(&self, t0: f64, t1: f64, spacing_mm: f64) -> Result<(), String> {
        if !(spacing_mm.is_finite() && spacing_mm > 0.0) {
            return Err(format!("PCHIP curve: sample spacing must be a positive length, got {spacing_mm} mm"));
        }
        let slack = 1e-9 * self.total_parameter();
        let (first, last) = (self.knots[0] - slack, self.total_parameter() + slack);
        for (name, t) in [("t0", t0), ("t1", t1)] {
            if !(t >= first && t <= last) {
                return Err(format!(
                    "PCHIP curve: {name} = {t} is outside the curve's parameter range [0, {}]",
                    self.total_parameter()
                ));
            }
        }
        if t1 < t0 {
            return Err(format!("PCHIP curve: sampling needs t0 <= t1, got t0 = {t0}, t1 = {t1}"));
        }
        Ok(())
    }

    fn sample(&self, t: f64, s_mm: f64) -> CurveSample {
        CurveSample { t, s_mm, point: self.eval(t), unit_tangent: self.tangent(t) }
    }

    /// [lo, hi] split at the knots strictly inside it (each piece is one cubic).
    fn pieces_between(&self, lo: f64, hi: f64) -> Vec<(f64, f64)> {
        let mut cuts = vec![lo];
        cuts.extend(self.knots.iter().copied().filter(|&k| k > lo && k < hi));
        cuts.push(hi);
        cuts.windows(2).map(|w| (w[0], w[1])).collect()
    }

    fn speed(&self, t: f64) -> f64 {
        self.derivative(t).norm()
    }

    fn piece_arc_length(&self, a: f64, b: f64) -> f64 {
        let mid = 0.5 * (a + b);
        gauss_legendre_8(|t| self.speed(t), a, mid) + gauss_legendre_8(|t| self.speed(t), mid, b)
    }

    /// Parameter in piece (a, b) at arc length `s_mm` from a.
    fn invert_piece_arc_length(&self, (a, b): (f64, f64), s_mm: f64, piece_length_mm: f64) -> f64 {
        if s_mm <= 0.0 {
            return a;
        }
        if s_mm >= piece_length_mm {
            return b;
        }
        let tolerance_mm = 1e-12 * self.total_parameter().max(1.0);
        invert_increasing(|t| self.piece_arc_length(a, t), |t| self.speed(t), s_mm, a, b, tolerance_mm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const X: [f64; 5] = [0.0, 1.0, 3.0, 4.0, 7.0];
    const Y: [f64; 5] = [0.0, 2.0, 3.0, 0.0, 1.0];

    #[test]
    fn knot_derivatives_match_hand_computation() {
        // h = [1, 2, 1, 3], secants m = [2, 0.5, -3, 1/3].
        // d1: w1 = 2*2+1 = 5, w2 = 2+2*1 = 4, 9/d = 5/2 + 4/0.5 -> d = 6/7.
        // d2, d3: secants change sign (local max 3, local min 0) -> 0.
        // d0 = ((2*1+2)*2 - 1*0.5)/3 = 2.5 (same sign as m0, no turn).
        // d4 = ((2*3+1)/3 - 3*(-3))/4 = 34/12, data turn and 34/12 > 3*(1/3) -> 3 m = 1.
        let pchip = Pchip::new(&X, &Y).unwrap();
        let expected = [2.5, 6.0 / 7.0, 0.0, 0.0, 1.0];
        for (k, (&d, e)) in pchip.knot_derivatives().iter().zip(expected).enumerate() {
            assert!((d - e).abs() < 1e-14, "knot {k}: {d} vs {e}");
        }
        // Values from scipy.interpolate.PchipInterpolator on the same data.
        let scipy = [
            (0.5, 1.2053571428571428, 2.1607142857142856),
            (2.0, 2.7142857142857144, 0.5357142857142857),
            (5.5, 0.125, 0.25),
        ];
        for (x, value, slope) in scipy {
            assert!((pchip.eval(x) - value).abs() < 1e-13, "value at {x}");
            assert!((pchip.derivative(x) - slope).abs() < 1e-13, "slope at {x}");
        }
    }

    #[test]
    fn end_slope_is_zeroed_when_it_points_against_the_data() {
        // d0 = ((2+1)*1 - 1*4)/2 = -0.5, opposite to m0 = 1 -> 0; d1 = 6/(3/1 + 3/4) = 1.6;
        // d2 = (3*4 - 1)/2 = 5.5.
        let pchip = Pchip::new(&[0.0, 1.0, 2.0], &[0.0, 1.0, 5.0]).unwrap();
        let expected = [0.0, 1.6, 5.5];
        for (k, (&d, e)) in pchip.knot_derivatives().iter().zip(expected).enumerate() {
            assert!((d - e).abs() < 1e-14, "knot {k}: {d} vs {e}");
        }
    }

    #[test]
    fn analytic_derivative_matches_finite_differences_and_is_zero_at_extrema() {
        let pchip = Pchip::new(&X, &Y).unwrap();
        for x in [0.3, 1.7, 2.9, 3.5, 6.2] {
            let numeric = (pchip.eval(x + 1e-6) - pchip.eval(x - 1e-6)) / 2e-6;
            assert!((pchip.derivative(x) - numeric).abs() < 1e-7, "at {x}");
        }
        assert_eq!(pchip.derivative(3.0), 0.0, "local maximum of the data");
        assert_eq!(pchip.derivative(4.0), 0.0, "local minimum of the data");
        assert!((0..=300).all(|i| pchip.eval(1.0 + 2.0 * i as f64 / 300.0) <= 3.0 + 1e-12), "no overshoot");
    }

    #[test]
    fn monotone_data_give_a_monotone_interpolant() {
        let x = [0.0, 0.5, 0.7, 2.0, 2.1, 5.0];
        let y = [0.0, 0.1, 3.0, 3.05, 8.0, 8.0];
        let pchip = Pchip::new(&x, &y).unwrap();
        let values: Vec<f64> = (0..=5000).map(|i| pchip.eval(5.0 * i as f64 / 5000.0)).collect();
        assert!(values.windows(2).all(|w| w[1] >= w[0] - 1e-12));
    }

    #[test]
    fn linear_data_and_two_points_reproduce_the_line() {
        let x = [0.0, 0.3, 1.0, 2.5, 4.0];
        let y: Vec<f64> = x.iter().map(|v| 2.0 - 1.5 * v).collect();
        let pchip = Pchip::new(&x, &y).unwrap();
        for i in 0..=100 {
            let v = 4.0 * i as f64 / 100.0;
            assert!((pchip.eval(v) - (2.0 - 1.5 * v)).abs() < 1e-13);
            assert!((pchip.derivative(v) + 1.5).abs() < 1e-13);
        }
        let two = Pchip::new(&[0.0, 2.0], &[1.0, 5.0]).unwrap();
        assert_eq!([two.eval(1.0), two.eval(-1.0), two.eval(3.0)], [3.0, -1.0, 7.0]);
    }

    #[test]
    fn bad_input_is_rejected_by_index() {
        assert!(Pchip::new(&[0.0, 1.0, 1.0], &[0.0; 3]).unwrap_err().contains("x[2]"));
        assert!(Pchip::new(&[0.0, 1.0], &[0.0; 3]).unwrap_err().contains("2 x values"));
        assert!(Pchip::new(&[0.0], &[0.0]).unwrap_err().contains("at least 2"));
        assert!(Pchip::new(&[0.0, f64::NAN], &[0.0; 2]).unwrap_err().contains("point 1"));
        let points = [Vec3::zeros(), Vec3::x(), Vec3::x()];
        assert!(PchipCurve3::new(&points).unwrap_err().contains("points 1 and 2"));
    }

    fn polyline() -> Vec<Vec3> {
        vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(3.0, 4.0, 0.0), Vec3::new(3.0, 4.0, 2.0), Vec3::new(5.0, 5.0, 4.0)]
    }

    #[test]
    fn straight_polyline_arc_length_is_its_length() {
        let direction = Vec3::new(1.0, -2.0, 2.0) / 3.0;
        let offsets = [0.0, 0.5, 2.0, 2.2, 7.0];
        let points: Vec<Vec3> = offsets.iter().map(|&d| Vec3::new(1.0, 1.0, 1.0) + d * direction).collect();
        let curve = PchipCurve3::new(&points).unwrap();
        assert!((curve.arc_length(0.0, curve.total_parameter()) - 7.0).abs() < 1e-12);
        assert!((curve.arc_length(1.0, 3.0) - 2.0).abs() < 1e-12);
        assert!((curve.arc_length(3.0, 1.0) + 2.0).abs() < 1e-12);
        assert!((curve.tangent(4.0) - direction).norm() < 1e-12);
    }

    #[test]
    fn curve_interpolates_points_at_their_knots() {
        let points = polyline();
        let curve = PchipCurve3::new(&points).unwrap();
        assert_eq!(curve.parameter_of_point(1), 5.0);
        assert_eq!(curve.parameter_of_point(2), 7.0);
        for (i, p) in points.iter().enumerate() {
            assert!((curve.eval(curve.parameter_of_point(i)) - p).norm() < 1e-12, "point {i}");
        }
    }

    #[test]
    fn tangent_falls_back_to_the_chord_where_the_derivative_vanishes() {
        // At point 1 the curve turns back in x and y and z is flat: PCHIP gives d = 0.
        let points = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(2.0, 2.0, 0.0), Vec3::new(1.0, 0.0, 0.0)];
        let curve = PchipCurve3::new(&points).unwrap();
        let t = curve.parameter_of_point(1);
        assert!(curve.derivative(t).norm() < 1e-12);
        assert!((curve.tangent(t) - Vec3::x()).norm() < 1e-12);
    }

    #[test]
    fn samples_are_evenly_spaced_in_arc_length_and_end_at_t1() {
        let curve = PchipCurve3::new(&polyline()).unwrap();
        let (t0, t1) = (1.3, curve.total_parameter() - 0.4);
        let samples = curve.sample_by_arclength(t0, t1, 0.5).unwrap();
        assert_eq!(samples[0].t, t0);
        assert_eq!(samples[0].s_mm, 0.0);
        let last = samples.last().unwrap();
        assert_eq!(last.t, t1);
        assert!((last.s_mm - curve.arc_length(t0, t1)).abs() < 1e-12);
        for (k, pair) in samples.windows(2).enumerate() {
            let gap = curve.arc_length(pair[0].t, pair[1].t);
            if k + 2 < samples.len() {
                assert!((gap - 0.5).abs() < 1e-9, "gap {k}: {gap}");
            } else {
                assert!(gap > 0.0 && gap <= 0.5 + 1e-9, "last gap {gap}");
            }
            assert!((pair[0].point - curve.eval(pair[0].t)).norm() < 1e-15);
            assert!((pair[0].unit_tangent.norm() - 1.0).abs() < 1e-12);
        }
        assert_eq!(curve.sample_by_arclength(2.0, 2.0, 0.5).unwrap().len(), 1);
    }

    #[test]
    fn sampling_rejects_bad_ranges_and_spacing() {
        let curve = PchipCurve3::new(&polyline()).unwrap();
        assert!(curve.sample_by_arclength(0.0, 1.0, 0.0).unwrap_err().contains("spacing"));
        assert!(curve.sample_by_arclength(0.0, 1.0, f64::NAN).unwrap_err().contains("spacing"));
        assert!(curve.sample_by_arclength(-1.0, 1.0, 0.1).unwrap_err().contains("t0 = -1"));
        assert!(curve.sample_by_arclength(0.0, 99.0, 0.1).unwrap_err().contains("t1 = 99"));
        assert!(curve.sample_by_arclength(2.0, 1.0, 0.1).unwrap_err().contains("t0 <= t1"));
    }

    /// A rotation about an oblique axis and a shift, as a scanner may place the scene.
    fn move_point(p: Vec3) -> Vec3 {
        let rotation = nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(Vec3::new(0.3, -0.5, 0.8)), 0.65);
        rotation * p + Vec3::new(35.0, -180.0, 1200.0)
    }

    #[test]
    fn the_vector_rule_turns_with_the_points_and_the_per_coordinate_rule_does_not() {
        let points = polyline();
        let moved: Vec<Vec3> = points.iter().map(|&p| move_point(p)).collect();
        let gap = |a: &PchipCurve3, b: &PchipCurve3| {
            (0..=40).map(|i| a.total_parameter() * i as f64 / 40.0).map(|t| (move_point(a.eval(t)) - b.eval(t)).norm()).fold(0.0, f64::max)
        };
        let (here, there) = (PchipCurve3::rotation_invariant(&points).unwrap(), PchipCurve3::rotation_invariant(&moved).unwrap());
        assert!(gap(&here, &there) < 1e-9, "{}", gap(&here, &there));
        // The control: scipy's per-coordinate PCHIP on the same points changes shape.
        let (here, there) = (PchipCurve3::new(&points).unwrap(), PchipCurve3::new(&moved).unwrap());
        assert!(gap(&here, &there) > 1e-3, "{}", gap(&here, &there));
    }

    #[test]
    fn vector_knot_velocities_follow_the_chords() {
        // Collinear equal chords: every velocity is the chord direction, the curve the line.
        let line = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, 2.0, 0.0), Vec3::new(3.0, 3.0, 0.0)];
        let curve = PchipCurve3::rotation_invariant(&line).unwrap();
        let direction = Vec3::new(1.0, 1.0, 0.0).normalize();
        for i in 0..=30 {
            let t = curve.total_parameter() * i as f64 / 30.0;
            assert!((curve.derivative(t) - direction).norm() < 1e-12);
        }
        // A right-angle corner with chords 1 and 2: PCHIP's weights (2*2+1, 2+2*1) / 9.
        let corner = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 2.0, 0.0)];
        let v = PchipCurve3::rotation_invariant(&corner).unwrap().derivative(1.0);
        assert!((v - Vec3::new(5.0 / 9.0, 4.0 / 9.0, 0.0)).norm() < 1e-12, "{v:?}");
    }
}
