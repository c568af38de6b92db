//! Step 7, the amplitude envelope [paper 2.4.5]: the least concave majorant of the
//! per-section amplitudes over centerline arc length. It is one-sided (never below
//! the raw amplitude, so no section loses area) and concave, so the baffle bulges
//! smoothly in one sweep from the VSD to the aorta instead of following every
//! section's own need.

use crate::error::DesignError;
use crate::geometry::numerics::least_concave_majorant;

/// Regularized amplitudes alpha_reg(s) >= alpha(s), concave in s.
pub fn regularize_amplitudes(s_mm: &[f64], alpha_mm: &[f64]) -> Result<Vec<f64>, DesignError> {
    least_concave_majorant(s_mm, alpha_mm).map_err(|m| DesignError::numerical("amplitude envelope", m))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn envelope_bridges_a_dip_and_never_undercuts() {
        let s = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5];
        let a = [0.0, 1.0, 0.2, 1.2, 0.4, 0.0];
        let r = regularize_amplitudes(&s, &a).unwrap();
        for i in 0..s.len() {
            assert!(r[i] >= a[i] - 1e-12);
        }
        // The dip at s = 1 is filled by the chord from (0.5, 1.0) to (1.5, 1.2).
        assert!((r[2] - 1.1).abs() < 1e-12, "{}", r[2]);
    }
}
