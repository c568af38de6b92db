//! The Fourier series svMultiPhysics fits to a `Temporal_values_file_path` file, computed
//! and evaluated exactly as its `fft` / `ifft` (Code/Source/solver/fft.cpp) do, so the
//! exporter can pick the number of modes that reproduces our waveform.
//!
//! svMultiPhysics' fit of samples (t_i, q_i), i = 0..np-1:
//! - `ti = t_0`, period `T = t_{np-1} - t_0` (so the file must repeat the first sample one
//!   period later to describe a periodic waveform);
//! - the linear trend `qi + qs (t - ti)` with `qi = q_0`, `qs = (q_{np-1} - q_0) / T` is
//!   removed, leaving a periodic remainder r(t) that is piecewise linear between samples;
//! - mode n = 0 is the mean of r (trapezoidal integral / T); for n >= 1 the exact Fourier
//!   integrals of the piecewise-linear r:
//!   `re_n = T / (2 pi^2 n^2) sum_i s_i (cos k_{i+1} - cos k_i)`,
//!   `im_n = -T / (2 pi^2 n^2) sum_i s_i (sin k_{i+1} - sin k_i)`,
//!   with slopes `s_i = (r_{i+1} - r_i) / (t_{i+1} - t_i)` and `k_i = 2 pi n (t_i - ti) / T`;
//! - evaluation at time t: `tau = fmod(t - ti, T)`,
//!   `q(t) = qi + qs tau + sum_{n < modes} (re_n cos(2 pi n tau / T) - im_n sin(2 pi n tau / T))`.
//!
//! The "modes" number of the file header counts n = 0 .. modes-1 (the mean included).

use std::f64::consts::PI;

use crate::SvmpError;

/// A fitted series: the trend and the coefficients of modes 0..modes().
#[derive(Clone, Debug, PartialEq)]
pub struct FourierSeries {
    pub t_initial_s: f64,
    pub period_s: f64,
    pub value_initial: f64,
    pub slope_per_s: f64,
    pub real: Vec<f64>,
    pub imag: Vec<f64>,
}

impl FourierSeries {
    pub fn modes(&self) -> usize {
        self.real.len()
    }

    /// The series value at `time_s`, as svMultiPhysics' `ifft` computes it.
    pub fn evaluate(&self, time_s: f64) -> f64 {
        self.evaluate_modes(time_s, self.modes())
    }

    /// The value using only the first `modes` coefficients.
    pub fn evaluate_modes(&self, time_s: f64, modes: usize) -> f64 {
        // C's fmod and Rust's % agree: the sign follows the dividend.
        let tau = (time_s - self.t_initial_s) % self.period_s;
        let omega = 2.0 * PI / self.period_s;
        let mut value = self.value_initial + tau * self.slope_per_s;
        for n in 0..modes.min(self.modes()) {
            let k = tau * omega * n as f64;
            value += self.real[n] * k.cos() - self.imag[n] * k.sin();
        }
        value
    }
}

/// Fit `modes` Fourier modes to samples as svMultiPhysics' `fft` does. Needs at least
/// two samples with strictly increasing times.
pub fn fit(times_s: &[f64], values: &[f64], modes: usize) -> Result<FourierSeries, SvmpError> {
    check_samples(times_s, values)?;
    if modes == 0 {
        return Err(SvmpError::InvalidCase("a Fourier fit needs at least 1 mode".into()));
    }
    let np = times_s.len();
    let t_initial_s = times_s[0];
    let period_s = times_s[np - 1] - t_initial_s;
    let value_initial = values[0];
    let slope_per_s = (values[np - 1] - values[0]) / period_s;
    let t: Vec<f64> = times_s.iter().map(|ti| ti - t_initial_s).collect();
    let r: Vec<f64> = t.iter().zip(values).map(|(ti, q)| q - value_initial - slope_per_s * ti).collect();
    let (real, imag) = (0..modes).map(|n| mode_coefficients(&t, &r, period_s, n)).unzip();
    Ok(FourierSeries { t_initial_s, period_s, value_initial, slope_per_s, real, imag })
}

fn check_samples(times_s: &[f64], values: &[f64]) -> Result<(), SvmpError> {
    if times_s.len() != values.len() || times_s.len() < 2 {
        return Err(SvmpError::InvalidCase(format!(
            "a Fourier fit needs at least 2 (time, value) samples of equal count, got {} times and {} values",
            times_s.len(),
            values.len()
        )));
    }
    if let Some(i) = times_s.windows(2).position(|w| !(w[1] > w[0])) {
        return Err(SvmpError::InvalidCase(format!(
            "sample times must increase: sample {} at {} s follows {} s",
            i + 1,
            times_s[i + 1],
            times_s[i]
        )));
    }
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(SvmpError::InvalidCase(format!("sample {i} has a non-finite value {}", values[i])));
    }
    Ok(())
}

/// (re_n, im_n) of the detrended samples `r` at times `t` (starting at 0).
fn mode_coefficients(t: &[f64], r: &[f64], period_s: f64, n: usize) -> (f64, f64) {
    let nf = n as f64;
    let (mut re, mut im) = (0.0, 0.0);
    for i in 0..t.len() - 1 {
        if n == 0 {
            re += 0.5 * (t[i + 1] - t[i]) * (r[i + 1] + r[i]);
        } else {
            let ko = 2.0 * PI * nf * t[i] / period_s;
            let kn = 2.0 * PI * nf * t[i + 1] / period_s;
            let s = (r[i + 1] - r[i]) / (t[i + 1] - t[i]);
            re += s * (kn.cos() - ko.cos());
            im -= s * (kn.sin() - ko.sin());
        }
    }
    if n == 0 {
        (re / period_s, 0.0)
    } else {
        let scale = 0.5 * period_s / (PI * PI * nf * nf);
        (re * scale, im * scale)
    }
}

/// The fewest modes (at most `max_modes`) whose series is within `tolerance` of
/// `target(t)` at every check time, the fitted series truncated to them, and the
/// largest deviation. Errs naming the best deviation found if none is close enough.
pub fn fit_within(
    times_s: &[f64],
    values: &[f64],
    check_times_s: &[f64],
    target: impl Fn(f64) -> f64,
    tolerance: f64,
    max_modes: usize,
) -> Result<(FourierSeries, f64), SvmpError> {
    let mut series = fit(times_s, values, max_modes)?;
    let targets: Vec<f64> = check_times_s.iter().map(|&t| target(t)).collect();
    let mut sums: Vec<f64> =
        check_times_s.iter().map(|&t| series.evaluate_modes(t, 0)).collect();
    let mut best = f64::INFINITY;
    for n in 0..max_modes {
        add_mode(&series, n, check_times_s, &mut sums);
        let deviation = sums.iter().zip(&targets).map(|(s, q)| (s - q).abs()).fold(0.0, f64::max);
        best = best.min(deviation);
        if deviation <= tolerance {
            series.real.truncate(n + 1);
            series.imag.truncate(n + 1);
            return Ok((series, deviation));
        }
    }
    Err(SvmpError::InvalidCase(format!(
        "no Fourier fit of up to {max_modes} modes is within {tolerance:e} of the waveform; the best deviates by {best:e}"
    )))
}

fn add_mode(series: &FourierSeries, n: usize, times_s: &[f64], sums: &mut [f64]) {
    let omega = 2.0 * PI / series.period_s;
    for (sum, &t) in sums.iter_mut().zip(times_s) {
        let k = ((t - series.t_initial_s) % series.period_s) * omega * n as f64;
        *sum += series.real[n] * k.cos() - series.imag[n] * k.sin();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_cosine_is_recovered_exactly_at_its_samples_and_nearly_between() {
        let period = 0.8;
        let f = |t: f64| 3.0 + 2.0 * (2.0 * PI * t / period).cos();
        let times: Vec<f64> = (0..=400).map(|i| i as f64 * period / 400.0).collect();
        let values: Vec<f64> = times.iter().map(|&t| f(t)).collect();
        let s = fit(&times, &values, 4).unwrap();
        // Trend removed: q_0 = q_end, so no slope; mean 3 lives in qi + re_0.
        assert_eq!(s.slope_per_s, 0.0);
        assert!((s.value_initial + s.real[0] - 3.0).abs() < 1e-4, "{s:?}");
        assert!((s.real[1] - 2.0).abs() < 1e-3 && s.imag[1].abs() < 1e-9, "{s:?}");
        assert!(s.real[2].abs() < 1e-4 && s.real[3].abs() < 1e-4, "{s:?}");
        for t in [0.0, 0.13, 0.4, 0.77, 0.8 + 0.13] {
            assert!((s.evaluate(t) - f(t)).abs() < 1e-3, "t {t}: {} vs {}", s.evaluate(t), f(t));
        }
    }

    #[test]
    fn trend_is_kept_for_non_periodic_samples() {
        let s = fit(&[1.0, 2.0, 3.0], &[0.0, 1.0, 2.0], 3).unwrap();
        assert_eq!((s.t_initial_s, s.period_s, s.value_initial, s.slope_per_s), (1.0, 2.0, 0.0, 1.0));
        assert!(s.real.iter().chain(&s.imag).all(|c| c.abs() < 1e-15), "{s:?}");
        assert!((s.evaluate(2.5) - 1.5).abs() < 1e-15);
    }

    #[test]
    fn bad_samples_are_named() {
        assert!(fit(&[0.0], &[1.0], 2).unwrap_err().to_string().contains("at least 2"));
        assert!(fit(&[0.0, 0.0], &[1.0, 2.0], 2).unwrap_err().to_string().contains("increase"));
        let e = fit_within(&[0.0, 0.5, 1.0], &[0.0, 1.0, 0.0], &[0.25], |_| 10.0, 1e-3, 4).unwrap_err();
        assert!(e.to_string().contains("no Fourier fit of up to 4 modes"), "{e}");
    }
}
