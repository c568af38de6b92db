//! The one writer of a simulate run's timeseries.csv and summary.json, for both engines
//! (the embedded solver in `simulate_cmd`, svMultiPhysics in `simulate_svmp`): the rows
//! an engine reports, how the run ended, and the figures and doubts of its summary.

use crate::case::{self, FlowInputs};
use crate::files::write_atomic;
use crate::run_summary::RunSummary;
use baffle_cfd::hemodynamics::DYN_CM2_PER_MMHG;
use baffle_cfd::{CaseSettings, FlowMesh, RunMode, StepResult};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Engine {
    #[default]
    Embedded,
    Svmultiphysics,
}

/// Rows of checkpoints written before the flag existed: their steps made a fixed number
/// of iterations, never reported unconverged.
fn converged_by_default() -> bool {
    true
}

/// One row of the time series (pressures in mmHg). NaN where an engine does not report
/// a figure at that step (svMultiPhysics: residual, and velocity away from the peak).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct Row {
    pub step: usize,
    pub time_s: f64,
    pub prescribed_inflow_ml_s: f64,
    pub inflow_ml_s: f64,
    pub outflow_ml_s: f64,
    pub max_velocity_m_s: f64,
    pub residual: f64,
    /// Rungs of the solver's retry ladder this step needed (0: none).
    #[serde(default)]
    pub retries: usize,
    /// False when the step's auto Picard loop stopped at its cap still changing.
    #[serde(default = "converged_by_default")]
    pub nonlinear_converged: bool,
    pub face_ids: Vec<i32>,
    pub face_names: Vec<String>,
    pub face_pressure_mmhg: Vec<f64>,
    /// Flux through each face (mL/s; a boundary face's outward normal, a plane's winding
    /// normal). Empty in rows of checkpoints written before it was recorded.
    #[serde(default)]
    pub face_flow_ml_s: Vec<f64>,
}

impl Row {
    pub(crate) fn of(r: &StepResult) -> Row {
        Row {
            step: r.step,
            time_s: r.time_s,
            prescribed_inflow_ml_s: r.prescribed_inflow_ml_s,
            inflow_ml_s: r.inflow_ml_s,
            outflow_ml_s: r.outflow_ml_s,
            max_velocity_m_s: r.max_velocity_cm_s / 100.0,
            residual: r.residual,
            retries: r.retries,
            nonlinear_converged: r.nonlinear_converged,
            face_ids: r.faces.iter().map(|f| f.id).collect(),
            face_names: r.faces.iter().map(|f| f.name.clone()).collect(),
            face_pressure_mmhg: r.faces.iter().map(|f| f.mean_pressure_dyn_cm2 / DYN_CM2_PER_MMHG).collect(),
            face_flow_ml_s: r.faces.iter().map(|f| f.flow_ml_s).collect(),
        }
    }
    /// Face `id`'s value in `values` (one per face of the row; NaN where it has none).
    fn of_face(&self, values: &[f64], id: i32) -> f64 {
        self.face_ids.iter().position(|&f| f == id).and_then(|k| values.get(k).copied()).unwrap_or(f64::NAN)
    }
    fn pressure(&self, id: i32) -> f64 {
        self.of_face(&self.face_pressure_mmhg, id)
    }
    /// The flux through face `id` (NaN where the row has none).
    fn flow(&self, id: i32) -> f64 {
        self.of_face(&self.face_flow_ml_s, id)
    }
}

pub(crate) struct Output<'a> {
    pub dir: &'a Path,
    pub mesh: &'a FlowMesh,
}

impl Output<'_> {
    pub(crate) fn vtu(&self, name: &str, velocity: &[[f64; 3]], pressure: &[f64]) -> Result<(), String> {
        baffle_cfd::vtu::write_solution_vtu(&self.dir.join(name), &self.mesh.points_cm, &self.mesh.tets, velocity, pressure)
            .map_err(|e| e.to_string())
    }
}

/// How a run ended, as summary.json says it.
pub(crate) struct Ending {
    pub status: &'static str,
    pub message: Option<String>,
    pub converged: bool,
}

impl Ending {
    pub fn completed() -> Ending {
        Ending { status: "completed", message: None, converged: true }
    }
}

/// The one writer of timeseries.csv and summary.json, for both engines: what the case
/// asked for, and which engine answered.
pub(crate) struct Report<'a> {
    pub dir: &'a Path,
    pub case: &'a case::Case,
    pub settings: &'a CaseSettings,
    pub flow: &'a FlowInputs,
    pub engine: Engine,
}

impl Report<'_> {
    pub(crate) fn csv(&self, rows: &[Row]) -> Result<(), String> {
        let mut text = String::from("step,time_s,prescribed_inflow_ml_s,inflow_ml_s,outflow_ml_s,max_velocity_m_s,residual");
        let faces = rows.first().map_or(&[][..], |r| &r.face_names[..]);
        for name in faces {
            text.push_str(&format!(",p_{name}_mmhg"));
        }
        for name in faces {
            text.push_str(&format!(",q_{name}_ml_s"));
        }
        text.push('\n');
        for r in rows {
            text.push_str(&format!(
                "{},{},{},{},{},{},{}",
                r.step, r.time_s, r.prescribed_inflow_ml_s, r.inflow_ml_s, r.outflow_ml_s, r.max_velocity_m_s, r.residual
            ));
            for p in &r.face_pressure_mmhg {
                text.push_str(&format!(",{p}"));
            }
            // A row resumed from an older checkpoint has no fluxes: NaN keeps the CSV square.
            for k in 0..r.face_pressure_mmhg.len() {
                text.push_str(&format!(",{}", r.face_flow_ml_s.get(k).copied().unwrap_or(f64::NAN)));
            }
            text.push('\n');
        }
        write_atomic(&self.dir.join("timeseries.csv"), text.as_bytes())
    }

    /// Write timeseries.csv and summary.json; returns the summary as it is read back.
    /// `steady_residuals`: a steady solve's relative residual per iteration (empty otherwise).
    pub(crate) fn write(&self, rows: &[Row], ending: &Ending, steady_residuals: &[f64], wall_time_s: f64) -> Result<RunSummary, String> {
        let (json, summary) = summary_json(self, rows, ending, steady_residuals, wall_time_s)?;
        self.csv(rows)?;
        let text = serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?;
        write_atomic(&self.dir.join("summary.json"), text.as_bytes())?;
        Ok(summary)
    }

    /// The one-line account of a run.
    pub(crate) fn summary_line(&self, summary: &RunSummary, rows: usize, rows_this_run: usize, wall_time_s: f64) -> String {
        let (a, b) = dp_faces(self.case);
        let number = |v: Option<f64>| v.unwrap_or(f64::NAN);
        // An unconverged solve's numbers are not presented as a plain result.
        let converged = if summary.converged { "" } else { " (NOT CONVERGED)" };
        format!(
            "{}{converged} {rows} steps ({rows_this_run} this run): dp {:.3} mmHg (faces {a} - {b}), v_max {:.3} m/s, Q_peak {:.2} mL/s, {:.1} s; wrote {}",
            summary.status,
            number(summary.dp_peak_mmhg),
            number(summary.max_velocity_m_s),
            number(summary.q_peak_ml_s),
            wall_time_s,
            self.dir.display()
        )
    }
}

/// dp = p(plane 1) - p(plane 2), or p(inlet) - p(first outlet).
fn dp_faces(case: &case::Case) -> (i32, i32) {
    match case.faces.planes[..] {
        [a, b] => (a, b),
        _ => (case.faces.inlet, case.faces.outlets[0]),
    }
}

/// summary.json, with why its dp cannot be trusted (`doubts`, empty when it can), the
/// run's own verdict on it and the threshold it is judged against (so a front end reads
/// them instead of judging again: the plan adds its mesh study's and design's doubts), and
/// its figures as the verdict and the report read them back (so a field they need and
/// this writer lacks fails every run, not only a later reader's).
fn summary_json(report: &Report, rows: &[Row], ending: &Ending, steady_residuals: &[f64], wall_time_s: f64) -> Result<(serde_json::Value, RunSummary), String> {
    let mut json = summary_figures(report, rows, ending, wall_time_s);
    if !steady_residuals.is_empty() {
        json["steady_relative_residuals"] = serde_json::json!(steady_residuals);
    }
    let summary = RunSummary::deserialize(&json).map_err(|e| format!("{}: summary.json as written: {e}", report.dir.display()))?;
    let doubts = crate::verdict::run_doubts(&summary);
    json["verdict"] = serde_json::json!(crate::verdict::Verdict::of(summary.dp_peak_mmhg.unwrap_or(f64::NAN), doubts.clone()).key());
    json["dp_threshold_mmhg"] = serde_json::json!(crate::verdict::DP_THRESHOLD_MMHG);
    json["doubts"] = serde_json::json!(doubts);
    Ok((json, summary))
}

fn summary_figures(report: &Report, rows: &[Row], ending: &Ending, wall_time_s: f64) -> serde_json::Value {
    let (case, settings, flow) = (report.case, report.settings, report.flow);
    let (a, b) = dp_faces(case);
    let outlet = case.faces.outlets[0];
    let steady = settings.mode == RunMode::Steady;
    let quick = case::is_quick(case);
    let period_steps = if steady { 0 } else { (flow.period_s / settings.dt_s).round() as usize };
    // The last complete cycle run (or all steps when less than one cycle was run).
    let last_step = rows.last().map_or(0, |r| r.step);
    let cycle: Vec<&Row> = if steady || period_steps == 0 || last_step < period_steps {
        rows.iter().collect()
    } else {
        // Cycle k ends at the step nearest k periods (a period need not be a whole number
        // of steps: p3's 0.4918 s is 491.8 steps, and the solver's 4 cycles are 1967).
        let cycles_done = ((last_step as f64 + 0.5) * settings.dt_s / flow.period_s).floor() as usize;
        let (start, end) = (cycle_end_step(cycles_done - 1, flow.period_s, settings.dt_s), cycle_end_step(cycles_done, flow.period_s, settings.dt_s));
        rows.iter().filter(|r| r.step > start && r.step <= end).collect()
    };
    let peak = cycle.iter().copied().max_by(|x, y| x.prescribed_inflow_ml_s.total_cmp(&y.prescribed_inflow_ml_s));
    let mean = |f: &dyn Fn(&Row) -> f64| if cycle.is_empty() { f64::NAN } else { cycle.iter().map(|r| f(r)).sum::<f64>() / cycle.len() as f64 };
    let inflow_sum: f64 = cycle.iter().map(|r| r.inflow_ml_s).sum();
    let outflow_sum: f64 = cycle.iter().map(|r| r.outflow_ml_s).sum();
    let periodicity = if steady || quick { None } else { periodicity_nrmsd(rows, period_steps, case.faces.inlet, outlet) };
    let f = |v: f64| if v.is_finite() { serde_json::json!(v) } else { serde_json::Value::Null };
    let engine = match report.engine {
        Engine::Embedded => "embedded",
        Engine::Svmultiphysics => "svmultiphysics",
    };
    serde_json::json!({
        "engine": engine,
        "status": ending.status,
        "message": ending.message,
        "mode": if steady { "steady" } else if quick { case::QUICK_MODE } else { "transient" },
        "converged": ending.converged,
        "steps_done": rows.len(),
        // Transient: the steps of all the case's cycles (a run stopped short of them has no
        // final cycle); quick: the steps to the first flow peak.
        "steps_planned": (!steady).then(|| if quick { case::first_peak_step(settings) } else { cycle_end_step(settings.cycles, flow.period_s, settings.dt_s) }),
        "retried_steps": rows.iter().filter(|r| r.retries > 0).count(),
        // Steps whose auto Picard loop stopped at its cap (time.nonlinear_iterations "auto").
        "unconverged_nonlinear_steps": rows.iter().filter(|r| !r.nonlinear_converged).count(),
        "last_step": last_step,
        "last_time_s": rows.last().map(|r| r.time_s),
        "peak_time_s": peak.map(|r| r.time_s),
        "dp_faces": [a, b],
        "dp_peak_mmhg": peak.map(|r| f(r.pressure(a) - r.pressure(b))),
        "plane_flows_at_peak": peak.map_or(Vec::new(), |r| plane_flows(case, r)),
        "max_velocity_m_s": peak.map(|r| f(r.max_velocity_m_s)),
        "max_velocity_run_m_s": f(rows.iter().map(|r| r.max_velocity_m_s).fold(f64::NAN, f64::max)),
        // Steady: the flow is held at Q_peak; that measured flow is q_held_ml_s, and
        // q_mean_ml_s stays the case's mean flow (over a cycle it would be Q_peak).
        "q_mean_ml_s": f(if steady { flow.q_mean_ml_s } else { mean(&|r| r.inflow_ml_s) }),
        "q_held_ml_s": steady.then(|| f(mean(&|r| r.inflow_ml_s))),
        "q_peak_ml_s": peak.map(|r| f(r.inflow_ml_s)),
        "outlet_mean_pressure_mmhg": f(mean(&|r| r.pressure(outlet))),
        "mass_imbalance": f((inflow_sum - outflow_sum).abs() / inflow_sum.abs()),
        "periodicity_nrmsd": periodicity.map(f),
        "wall_time_s": wall_time_s,
        "inputs": {
            "q_mean_ml_s": flow.q_mean_ml_s,
            "q_peak_ml_s": flow.q_peak_ml_s,
            "peak_time_in_cycle_s": flow.peak_time_in_cycle_s,
            "period_s": f(flow.period_s),
            "resistance_dyn_s_cm5": flow.resistance_dyn_s_cm5,
            "map_mmhg": flow.map_mmhg,
            "dt_s": settings.dt_s,
            "cycles": settings.cycles,
            "nonlinear_iterations": (!steady).then(|| match settings.nonlinear() {
                baffle_cfd::NonlinearIterations::Fixed(n) => serde_json::json!(n),
                baffle_cfd::NonlinearIterations::Auto { cap } => serde_json::json!({ "auto": { "cap": cap, "tolerance": settings.nonlinear_tolerance } }),
            }),
            "time_integration": (!steady).then(|| settings.time_integration.name()),
            "rho_inf": match settings.time_integration {
                baffle_cfd::TimeIntegration::GeneralizedAlpha { rho_inf } if !steady => Some(rho_inf),
                _ => None,
            },
            "density_g_cm3": settings.density_g_cm3,
            "viscosity_g_cm_s": settings.viscosity_g_cm_s,
            "steady_tolerance": steady.then_some(settings.steady_tolerance),
            "steady_max_iterations": steady.then_some(settings.steady_max_iterations),
        },
    })
}

/// The flux through each measurement plane at the peak row and its fraction of the inflow.
/// The flow is incompressible, so every plane across the domain carries the inflow; the
/// nodal velocity field of P1 elements with pressure stabilization carries less, by the
/// share of the flux the stabilization term holds (the weak continuity equation conserves
/// the sum, and the inflow and outflow still balance). It is not dp's error: on a 5-ring
/// Poiseuille tube whose dp is within 0.02 % of Hagen-Poiseuille the planes carry 97.5 %
/// (`baffle-cli` simulate tests), and at a sharp annulus it stays the same on a finer mesh
/// (docs/cfd.md).
fn plane_flows(case: &case::Case, peak: &Row) -> Vec<serde_json::Value> {
    let finite = |v: f64| v.is_finite().then_some(v);
    case.faces
        .planes
        .iter()
        .map(|&id| {
            let q = peak.flow(id);
            serde_json::json!({ "face": id, "flow_ml_s": finite(q), "fraction_of_inflow": finite(q.abs() / peak.inflow_ml_s) })
        })
        .collect()
}

/// The time step at which cycle k ends: the one nearest k periods, as the solver counts
/// a run's steps (round(cycles x period / dt)).
pub(crate) fn cycle_end_step(k: usize, period_s: f64, dt_s: f64) -> usize {
    (k as f64 * period_s / dt_s).round() as usize
}

/// Cycle N-1 vs N of the inlet-outlet pressure difference ([`baffle_cfd::periodicity_nrmsd`]).
/// Rows are placed by step number (step k at index k-1), so the cycles are those of the
/// run's time axis whatever rows a resume carried over; None when a step of the last two
/// complete cycles is missing.
fn periodicity_nrmsd(rows: &[Row], period_steps: usize, inlet: i32, outlet: i32) -> Option<f64> {
    let mut dp = vec![f64::NAN; rows.iter().map(|r| r.step).max().unwrap_or(0)];
    for r in rows.iter().filter(|r| r.step >= 1) {
        dp[r.step - 1] = r.pressure(inlet) - r.pressure(outlet);
    }
    baffle_cfd::periodicity_nrmsd(&dp, period_steps).filter(|v| v.is_finite())
}

/// A flag raised by SIGTERM or SIGINT (instead of dying), so a run stops between steps
/// with its results so far.
pub(crate) fn stop_on_signals() -> Result<Arc<AtomicBool>, String> {
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGTERM, signal_hook::consts::SIGINT] {
        signal_hook::flag::register(signal, Arc::clone(&stop)).map_err(|e| format!("cannot install signal handler: {e}"))?;
    }
    Ok(stop)
}
