//! Cycle-to-cycle periodicity of a transient run (issue #4's `periodicity_nrmsd`).

/// Normalized RMS difference of the last two complete cycles of `values`, a quantity
/// sampled at steps 1, 2, ... (e.g. the inlet-outlet pressure difference):
/// RMS(cycle N - cycle N-1) / range(cycle N). None with fewer than two complete cycles.
/// A value of 0.01 means the last cycle repeats the one before within 1% of its swing.
pub fn periodicity_nrmsd(values: &[f64], period_steps: usize) -> Option<f64> {
    if period_steps == 0 || values.len() < 2 * period_steps {
        return None;
    }
    let end = values.len() - values.len() % period_steps;
    let last = &values[end - period_steps..end];
    let previous = &values[end - 2 * period_steps..end - period_steps];
    let max = last.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let min = last.iter().cloned().fold(f64::INFINITY, f64::min);
    let rms = (last.iter().zip(previous).map(|(a, b)| (a - b).powi(2)).sum::<f64>() / period_steps as f64).sqrt();
    let range = max - min;
    Some(if range > 0.0 { rms / range } else { rms })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_repeating_signal_is_periodic_and_a_decaying_one_is_not() {
        let n = 50;
        let wave = |k: usize| (2.0 * std::f64::consts::PI * k as f64 / n as f64).sin();
        let repeating: Vec<f64> = (1..=3 * n + 7).map(wave).collect();
        assert!(periodicity_nrmsd(&repeating, n).unwrap() < 1e-12);
        // A transient decaying with time constant of one period: cycle 3 vs 2 differs
        // by (1 - 1/e) e^-2 of the start value; the swing of cycle 3 is ~2.
        let decaying: Vec<f64> = (1..=3 * n).map(|k| wave(k) + (-(k as f64) / n as f64).exp()).collect();
        let d = periodicity_nrmsd(&decaying, n).unwrap();
        assert!(d > 0.02 && d < 0.1, "{d}");
        assert_eq!(periodicity_nrmsd(&repeating[..2 * n - 1], n), None);
        assert_eq!(periodicity_nrmsd(&repeating, 0), None);
    }
}
