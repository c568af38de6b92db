//! Inflow waveforms Q(t) in mL/s (= cm^3/s), periodic in time.

use std::f64::consts::PI;
use std::path::Path;

use crate::hemodynamics::PEAK_TO_MEAN_FLOW;
use crate::CfdError;

/// Paper's cardiac period (s).
pub const DEFAULT_PERIOD_S: f64 = 0.682;

#[derive(Clone, Debug, PartialEq)]
pub enum Waveform {
    /// Built-in ventricular ejection: a half-sine systolic ejection and no diastolic
    /// flow. For a half-sine of duration T_s in a period T, Q_peak/Q_mean = pi T / (2 T_s);
    /// the paper's ratio 3.26 gives T_s = 0.3286 s of 0.682 s and a peak at T_s/2 =
    /// 0.164 s, which is the paper's peak time (2.21 s = 3 x 0.682 + 0.164 in cycle 4).
    Ejection { period_s: f64, q_mean_ml_s: f64 },
    /// Tabulated (time, flow) samples over one period, linearly interpolated, periodic.
    Table { times_s: Vec<f64>, flows_ml_s: Vec<f64>, period_s: f64 },
    /// Constant flow (steady runs and tests).
    Constant { q_ml_s: f64 },
}

impl Waveform {
    /// The built-in waveform scaled to the patient's mean flow.
    pub fn default_for_mean(q_mean_ml_s: f64) -> Result<Self, CfdError> {
        if !(q_mean_ml_s.is_finite() && q_mean_ml_s > 0.0) {
            return Err(CfdError::Waveform(format!("mean flow must be positive, got {q_mean_ml_s} mL/s")));
        }
        Ok(Waveform::Ejection { period_s: DEFAULT_PERIOD_S, q_mean_ml_s })
    }

    /// Period in s (infinite for a constant flow).
    pub fn period_s(&self) -> f64 {
        match self {
            Waveform::Ejection { period_s, .. } | Waveform::Table { period_s, .. } => *period_s,
            Waveform::Constant { .. } => f64::INFINITY,
        }
    }

    /// Flow (mL/s) at time t (s).
    pub fn flow_ml_s(&self, time_s: f64) -> f64 {
        match self {
            Waveform::Ejection { period_s, q_mean_ml_s } => {
                let ejection_s = ejection_duration_s(*period_s);
                let t = time_s.rem_euclid(*period_s);
                let peak = PEAK_TO_MEAN_FLOW * q_mean_ml_s;
                if t < ejection_s {
                    peak * (PI * t / ejection_s).sin()
                } else {
                    0.0
                }
            }
            Waveform::Table { times_s, flows_ml_s, period_s } => table_flow(times_s, flows_ml_s, *period_s, time_s),
            Waveform::Constant { q_ml_s } => *q_ml_s,
        }
    }

    /// Mean flow over a period (mL/s), by exact integration of the interpolant.
    pub fn mean_ml_s(&self) -> f64 {
        match self {
            Waveform::Ejection { q_mean_ml_s, .. } => *q_mean_ml_s,
            Waveform::Table { times_s, flows_ml_s, period_s } => {
                let n = times_s.len();
                let mut integral = 0.0;
                for i in 0..n {
                    let (t1, q1) = if i + 1 < n {
                        (times_s[i + 1], flows_ml_s[i + 1])
                    } else {
                        (times_s[0] + period_s, flows_ml_s[0])
                    };
                    integral += 0.5 * (flows_ml_s[i] + q1) * (t1 - times_s[i]);
                }
                integral / period_s
            }
            Waveform::Constant { q_ml_s } => *q_ml_s,
        }
    }

    /// Peak flow (mL/s) and its time in the cycle (s).
    pub fn peak(&self) -> (f64, f64) {
        match self {
            Waveform::Ejection { period_s, q_mean_ml_s } => {
                (PEAK_TO_MEAN_FLOW * q_mean_ml_s, 0.5 * ejection_duration_s(*period_s))
            }
            Waveform::Table { times_s, flows_ml_s, .. } => {
                let (i, q) = flows_ml_s.iter().enumerate().fold((0, f64::NEG_INFINITY), |best, (i, &q)| {
                    if q > best.1 {
                        (i, q)
                    } else {
                        best
                    }
                });
                (q, times_s[i] - times_s[0])
            }
            Waveform::Constant { q_ml_s } => (*q_ml_s, 0.0),
        }
    }

    /// The same shape scaled to a new mean flow.
    pub fn scaled_to_mean(&self, q_mean_ml_s: f64) -> Result<Self, CfdError> {
        let mean = self.mean_ml_s();
        if !(mean.abs() > 0.0 && q_mean_ml_s.is_finite()) {
            return Err(CfdError::Waveform(format!("cannot scale a waveform of mean {mean} mL/s to {q_mean_ml_s}")));
        }
        let factor = q_mean_ml_s / mean;
        Ok(match self {
            Waveform::Ejection { period_s, .. } => Waveform::Ejection { period_s: *period_s, q_mean_ml_s },
            Waveform::Table { times_s, flows_ml_s, period_s } => Waveform::Table {
                times_s: times_s.clone(),
                flows_ml_s: flows_ml_s.iter().map(|q| q * factor).collect(),
                period_s: *period_s,
            },
            Waveform::Constant { .. } => Waveform::Constant { q_ml_s: q_mean_ml_s },
        })
    }

    /// Read a flow file: lines "time flow" (whitespace or comma separated, '#'
    /// comments), or svMultiPhysics' `.flx` form whose first line is "n_points
    /// n_fourier_modes". svMultiPhysics prescribes flux along the outward normal, so
    /// inflow there is negative: a file whose mean is negative is negated. The period
    /// is last time - first time when the last flow repeats the first, else the
    /// samples are taken as evenly spaced over the period (one more step after the last).
    pub fn read(path: &Path) -> Result<Self, CfdError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| CfdError::Io { path: path.display().to_string(), message: e.to_string() })?;
        Self::parse(&text).map_err(|e| match e {
            CfdError::Waveform(m) => CfdError::Io { path: path.display().to_string(), message: m },
            other => other,
        })
    }

    /// Parse the text of a flow file (see [`Waveform::read`]).
    pub fn parse(text: &str) -> Result<Self, CfdError> {
        let rows = numeric_rows(text)?;
        let rows = strip_flx_header(rows);
        if rows.len() < 2 {
            return Err(CfdError::Waveform(format!("need at least 2 (time, flow) rows, found {}", rows.len())));
        }
        let mut times_s: Vec<f64> = rows.iter().map(|r| r[0]).collect();
        let mut flows_ml_s: Vec<f64> = rows.iter().map(|r| r[1]).collect();
        for (i, w) in times_s.windows(2).enumerate() {
            if !(w[1] > w[0]) {
                return Err(CfdError::Waveform(format!("times must increase: row {} has {} after {}", i + 2, w[1], w[0])));
            }
        }
        let n = times_s.len();
        let closes = (flows_ml_s[n - 1] - flows_ml_s[0]).abs() <= 1e-9 * flows_ml_s.iter().fold(1.0, |m, q| q.abs().max(m));
        let period_s = if closes {
            times_s.pop();
            flows_ml_s.pop();
            times_s_last(&rows) - rows[0][0]
        } else {
            (times_s[n - 1] - times_s[0]) * n as f64 / (n - 1) as f64
        };
        let mut waveform = Waveform::Table { times_s, flows_ml_s, period_s };
        if waveform.mean_ml_s() < 0.0 {
            if let Waveform::Table { flows_ml_s, .. } = &mut waveform {
                flows_ml_s.iter_mut().for_each(|q| *q = -*q);
            }
        }
        Ok(waveform)
    }
}

fn times_s_last(rows: &[[f64; 2]]) -> f64 {
    rows[rows.len() - 1][0]
}

/// T_s such that a half-sine ejection has Q_peak / Q_mean = PEAK_TO_MEAN_FLOW.
pub fn ejection_duration_s(period_s: f64) -> f64 {
    PI * period_s / (2.0 * PEAK_TO_MEAN_FLOW)
}

fn table_flow(times_s: &[f64], flows_ml_s: &[f64], period_s: f64, time_s: f64) -> f64 {
    let t = times_s[0] + (time_s - times_s[0]).rem_euclid(period_s);
    let i = times_s.partition_point(|&ti| ti <= t).max(1) - 1;
    let (t1, q1) = if i + 1 < times_s.len() {
        (times_s[i + 1], flows_ml_s[i + 1])
    } else {
        (times_s[0] + period_s, flows_ml_s[0])
    };
    let w = (t - times_s[i]) / (t1 - times_s[i]);
    flows_ml_s[i] * (1.0 - w) + q1 * w
}

fn numeric_rows(text: &str) -> Result<Vec<Vec<f64>>, CfdError> {
    let mut rows = Vec::new();
    for (line_no, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let fields: Result<Vec<f64>, _> =
            line.split(|c: char| c == ',' || c.is_whitespace()).filter(|f| !f.is_empty()).map(str::parse).collect();
        let fields = fields.map_err(|_| CfdError::Waveform(format!("line {}: not numbers: '{line}'", line_no + 1)))?;
        if fields.len() != 2 || fields.iter().any(|v| !v.is_finite()) {
            return Err(CfdError::Waveform(format!("line {}: expected 2 finite numbers (time, flow): '{line}'", line_no + 1)));
        }
        rows.push(fields);
    }
    Ok(rows)
}

/// Drop a `.flx` header "n_points n_modes" (two integers, n_points = rows that follow).
fn strip_flx_header(rows: Vec<Vec<f64>>) -> Vec<[f64; 2]> {
    let is_header = rows.first().is_some_and(|r| {
        r[0].fract() == 0.0 && r[1].fract() == 0.0 && r[0] as usize == rows.len() - 1 && r[1] >= 1.0
    });
    rows.into_iter().skip(usize::from(is_header)).map(|r| [r[0], r[1]]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_data::{patients_json, table4_hemodynamics, table_value};

    #[test]
    fn default_waveform_matches_table4_peaks() {
        let Some(json) = patients_json() else { return };
        for patient in ["p2", "p3"] {
            let v = |key: &str| table_value(&json, patient, key);
            let h = table4_hemodynamics(&json, patient);
            let w = Waveform::default_for_mean(h.q_mean_ml_s).unwrap();
            // Sampled, not the closed form: integrate and search the curve itself.
            let n = 68_200;
            let dt = DEFAULT_PERIOD_S / n as f64;
            let samples: Vec<f64> = (0..n).map(|i| w.flow_ml_s(i as f64 * dt)).collect();
            let mean = samples.iter().sum::<f64>() / n as f64;
            let (i_peak, peak) = samples.iter().enumerate().fold((0, 0.0), |b, (i, &q)| if q > b.1 { (i, q) } else { b });
            assert!((mean - h.q_mean_ml_s).abs() < 1e-3 * h.q_mean_ml_s, "{patient}: mean {mean}");
            assert!((peak - v("q_peak_ml_s")).abs() < 0.01 * v("q_peak_ml_s"), "{patient}: peak {peak}");
            assert!((i_peak as f64 * dt - 0.164).abs() < 1e-3, "{patient}: peak time {}", i_peak as f64 * dt);
            // Periodic: cycle 4 peaks at the paper's 2.21 s.
            let t4 = 3.0 * DEFAULT_PERIOD_S + i_peak as f64 * dt;
            assert!((t4 - table_value(&json, "common", "peak_time_in_cycle4_s")).abs() < 1e-3 * 2.21 + 0.001);
            assert!((w.flow_ml_s(t4) - peak).abs() < 1e-9 * peak);
        }
    }

    #[test]
    fn two_column_file_is_periodic_and_scalable() {
        let w = Waveform::parse("# t q\n0, 0\n0.1, 10\n0.2 0\n").unwrap();
        assert_eq!(w.period_s(), 0.2);
        assert!((w.flow_ml_s(0.05) - 5.0).abs() < 1e-12);
        assert!((w.flow_ml_s(0.25) - 5.0).abs() < 1e-12);
        assert!((w.mean_ml_s() - 5.0).abs() < 1e-12);
        let s = w.scaled_to_mean(20.0).unwrap();
        assert!((s.flow_ml_s(0.1) - 40.0).abs() < 1e-12);
        assert_eq!(s.peak(), (40.0, 0.1));
    }

    #[test]
    fn flx_file_with_header_and_negative_inflow() {
        let w = Waveform::parse("4 64\n0.0 -1.0\n0.1 -3.0\n0.2 -2.0\n0.3 -1.0\n").unwrap();
        assert!((w.period_s() - 0.3).abs() < 1e-12);
        assert!((w.flow_ml_s(0.1) - 3.0).abs() < 1e-12);
        assert!(w.mean_ml_s() > 0.0);
    }

    #[test]
    fn bad_flow_files_are_named() {
        assert!(Waveform::parse("0 1\n").unwrap_err().to_string().contains("at least 2"));
        assert!(Waveform::parse("0 1\n0 2\n").unwrap_err().to_string().contains("increase"));
        assert!(Waveform::parse("0 1\nzero 2\n").unwrap_err().to_string().contains("line 2"));
        let missing = Waveform::read(Path::new("/nonexistent/flow.flx")).unwrap_err().to_string();
        assert!(missing.contains("/nonexistent/flow.flx"), "{missing}");
    }
}
