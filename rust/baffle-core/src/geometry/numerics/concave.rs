//! Least concave majorant of sampled data: the smallest concave function lying on or
//! above every sample, evaluated at the sample abscissae.
//!
//! Used to turn a noisy profile sampled along a curve into a concave one without
//! ever going below the data.

/// The least concave majorant of (x_i, y_i) at each x_i. `x` must be strictly
/// increasing. Computed as the upper convex hull of the points (monotone-chain scan,
/// O(n)) interpolated linearly between hull vertices.
pub fn least_concave_majorant(x: &[f64], y: &[f64]) -> Result<Vec<f64>, String> {
    super::check_samples("concave majorant", x, y, 0)?;
    let hull = upper_hull(x, y);
    let mut majorant = Vec::with_capacity(x.len());
    for pair in hull.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let slope = (y[b] - y[a]) / (x[b] - x[a]);
        // max with y_i: interpolation rounding must not dip below the data.
        majorant.extend((a..b).map(|i| (y[a] + slope * (x[i] - x[a])).max(y[i])));
    }
    if let Some(&last) = hull.last() {
        majorant.push(y[last]);
    }
    Ok(majorant)
}

/// Indices of the upper hull's vertices, left to right. A point is dropped when it
/// lies on or below the chord from its hull predecessor to the new point.
fn upper_hull(x: &[f64], y: &[f64]) -> Vec<usize> {
    let mut hull: Vec<usize> = Vec::with_capacity(x.len());
    for i in 0..x.len() {
        while hull.len() >= 2 {
            let (a, b) = (hull[hull.len() - 2], hull[hull.len() - 1]);
            // Cross product of (b - a) and (i - a): >= 0 means b is not above chord a-i.
            let cross = (x[b] - x[a]) * (y[i] - y[a]) - (y[b] - y[a]) * (x[i] - x[a]);
            if cross >= 0.0 {
                hull.pop();
            } else {
                break;
            }
        }
        hull.push(i);
    }
    hull
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_concave_majorant(x: &[f64], y: &[f64], majorant: &[f64]) {
        assert_eq!(majorant.len(), y.len());
        for i in 0..y.len() {
            assert!(majorant[i] >= y[i], "below the data at {i}");
        }
        for i in 1..x.len().saturating_sub(1) {
            let left_slope = (majorant[i] - majorant[i - 1]) / (x[i] - x[i - 1]);
            let right_slope = (majorant[i + 1] - majorant[i]) / (x[i + 1] - x[i]);
            assert!(right_slope - left_slope <= 1e-12, "not concave at {i}: {left_slope} then {right_slope}");
        }
    }

    #[test]
    fn concave_input_is_unchanged() {
        let x: Vec<f64> = (0..20).map(|i| (i as f64).powf(1.3)).collect();
        let y: Vec<f64> = x.iter().map(|v| 5.0 - 0.1 * (v - 7.0).powi(2)).collect();
        let majorant = least_concave_majorant(&x, &y).unwrap();
        for i in 0..y.len() {
            assert!((majorant[i] - y[i]).abs() < 1e-12, "changed at {i}");
        }
    }

    #[test]
    fn single_spike_gives_a_tent() {
        let x = [0.0, 1.0, 2.0, 3.0, 4.0, 6.0];
        let y = [0.0, 0.0, 0.0, 6.0, 0.0, 0.0];
        let majorant = least_concave_majorant(&x, &y).unwrap();
        let tent = [0.0, 2.0, 4.0, 6.0, 4.0, 0.0];
        for i in 0..x.len() {
            assert!((majorant[i] - tent[i]).abs() < 1e-12, "at {i}: {} vs {}", majorant[i], tent[i]);
        }
    }

    #[test]
    fn noisy_data_give_a_concave_majorant() {
        let x: Vec<f64> = (0..200).map(|i| 0.1 * i as f64 + 0.03 * ((i * 7) % 5) as f64).collect();
        let y: Vec<f64> = x.iter().enumerate().map(|(i, v)| (0.5 * v).sin() + 0.2 * ((i * 13) % 7) as f64).collect();
        let majorant = least_concave_majorant(&x, &y).unwrap();
        assert_concave_majorant(&x, &y, &majorant);
        // Least: at each x_i the concave hull is the highest chord spanning x_i.
        for i in 0..x.len() {
            let mut highest_chord = y[i];
            for j in 0..i {
                for k in i + 1..x.len() {
                    let chord = y[j] + (y[k] - y[j]) * (x[i] - x[j]) / (x[k] - x[j]);
                    highest_chord = highest_chord.max(chord);
                }
            }
            assert!((majorant[i] - highest_chord).abs() < 1e-12, "at {i}: {} vs {highest_chord}", majorant[i]);
        }
    }

    #[test]
    fn small_and_bad_inputs() {
        assert_eq!(least_concave_majorant(&[], &[]).unwrap(), Vec::<f64>::new());
        assert_eq!(least_concave_majorant(&[1.0], &[2.0]).unwrap(), vec![2.0]);
        assert_eq!(least_concave_majorant(&[1.0, 2.0], &[2.0, -1.0]).unwrap(), vec![2.0, -1.0]);
        assert!(least_concave_majorant(&[0.0, 2.0, 2.0], &[0.0; 3]).unwrap_err().contains("x[2]"));
        assert!(least_concave_majorant(&[0.0, 1.0], &[0.0]).unwrap_err().contains("2 x values"));
        assert!(least_concave_majorant(&[0.0, 1.0], &[0.0, f64::INFINITY]).unwrap_err().contains("point 1"));
    }
}
