//! A run's summary.json as the verdict, the plan's report and the sweep read it back: the
//! figures its one writer (`simulate_report`) puts there, typed, so a renamed or missing
//! field is an error naming the file and the field, not a blank figure or a lost doubt.

use serde::Deserialize;
use std::path::Path;

/// The figures of summary.json that are read back (pressures in mmHg, velocities in m/s,
/// flows in mL/s). `Option` where the writer puts null: no value of that kind (a steady
/// run's planned steps), or none that was finite; a field missing from the file is an
/// error all the same.
#[derive(Clone, Debug, PartialEq, Deserialize)]
pub struct RunSummary {
    /// "completed", or how the run ended otherwise ("stopped", "failed").
    pub status: String,
    #[serde(deserialize_with = "crate::files::nullable")]
    pub message: Option<String>,
    /// "steady", "transient" or [`crate::case::QUICK_MODE`].
    pub mode: String,
    pub converged: bool,
    /// Steps whose auto Picard loop stopped at its cap.
    pub unconverged_nonlinear_steps: usize,
    pub last_step: usize,
    /// The steps of the run as planned (null for a steady run).
    #[serde(deserialize_with = "crate::files::nullable")]
    pub steps_planned: Option<usize>,
    #[serde(deserialize_with = "crate::files::nullable")]
    pub peak_time_s: Option<f64>,
    #[serde(deserialize_with = "crate::files::nullable")]
    pub dp_peak_mmhg: Option<f64>,
    #[serde(deserialize_with = "crate::files::nullable")]
    pub max_velocity_m_s: Option<f64>,
    #[serde(deserialize_with = "crate::files::nullable")]
    pub q_peak_ml_s: Option<f64>,
    #[serde(deserialize_with = "crate::files::nullable")]
    pub mass_imbalance: Option<f64>,
    /// Null for a steady or quick run, and for a transient one with fewer than two cycles.
    #[serde(deserialize_with = "crate::files::nullable")]
    pub periodicity_nrmsd: Option<f64>,
    /// A steady solve's relative residual per iteration; absent from other runs' summaries.
    #[serde(default)]
    pub steady_relative_residuals: Vec<Option<f64>>,
    pub inputs: RunInputs,
}

/// What the run's case asked for (summary.json `inputs`).
#[derive(Clone, Debug, PartialEq, Deserialize)]
pub struct RunInputs {
    /// The case's mean flow (null only if it was not finite).
    #[serde(deserialize_with = "crate::files::nullable")]
    pub q_mean_ml_s: Option<f64>,
    #[serde(deserialize_with = "crate::files::nullable")]
    pub period_s: Option<f64>,
    /// A steady solve's residual target (null for other runs).
    #[serde(deserialize_with = "crate::files::nullable")]
    pub steady_tolerance: Option<f64>,
}

impl RunSummary {
    pub fn is_steady(&self) -> bool {
        self.mode == "steady"
    }

    pub fn is_quick(&self) -> bool {
        self.mode == crate::case::QUICK_MODE
    }
}

/// `value`, or an error naming the file `path` it came from and its key: for a figure
/// without which the reader cannot go on.
pub fn required(value: Option<f64>, key: &str, path: &Path) -> Result<f64, String> {
    value.filter(|v| v.is_finite()).ok_or_else(|| format!("{}: no finite {key}", path.display()))
}

/// A completed run of `mode` that gave every figure (for the crate's tests to alter).
#[cfg(test)]
pub(crate) fn completed_run(mode: &str) -> RunSummary {
    let steady = mode == "steady";
    RunSummary {
        status: "completed".into(),
        message: None,
        mode: mode.into(),
        converged: true,
        unconverged_nonlinear_steps: 0,
        last_step: if steady { 0 } else { 109 },
        steps_planned: (!steady).then_some(109),
        peak_time_s: Some(0.109),
        dp_peak_mmhg: Some(1.47),
        max_velocity_m_s: Some(1.5),
        q_peak_ml_s: Some(36.0),
        mass_imbalance: Some(1e-5),
        periodicity_nrmsd: None,
        steady_relative_residuals: Vec::new(),
        inputs: RunInputs { q_mean_ml_s: Some(12.0), period_s: Some(0.682), steady_tolerance: steady.then_some(1e-6) },
    }
}
