//! `baffle simulate --engine svmultiphysics`: the case exported as `baffle export-svmp`
//! writes it (into OUT/svmultiphysics/), run there by svMultiPhysics out of process, and
//! its outputs (`B_NS_*.txt`, the peak `result_*.vtu`) read back into the same rows, and
//! so the same timeseries.csv and summary.json, as the embedded engine's.

use crate::svmp_case::{check_returned_case, export_to, inflow_line};
use crate::progress::Progress;
use crate::simulate_report::{stop_on_signals, Ending, Output, Report, Row};
use baffle_cfd::hemodynamics::DYN_CM2_PER_MMHG;
use baffle_cfd::{FlowMesh, RunMode};
use baffle_svmp::{find_engine, read_results, run_case, PeakFields, SvmpError, SvmpSummary};
use std::path::Path;
use std::sync::atomic::Ordering;
use std::time::Instant;

/// Where the svMultiPhysics case goes, under the output directory.
pub const CASE_DIR: &str = "svmultiphysics";

/// What an svMultiPhysics run takes from `baffle simulate`'s options: where it writes, its
/// MPI processes, and the embedded engine's own options (refused when given).
pub struct SvmpRun<'a> {
    pub out: &'a Path,
    pub mpi_processes: Option<usize>,
    pub resume: bool,
    pub vtu_every: Option<usize>,
    /// Read back a case exported to OUT/svmultiphysics/ and run elsewhere (no export, no run).
    pub read_back: bool,
}

pub(crate) fn run(args: &SvmpRun, report: &Report, output: &Output, start: Instant, progress: &Progress) -> Result<(), String> {
    refuse_embedded_only_options(args)?;
    let case_dir = args.out.join(CASE_DIR);
    // A case run elsewhere and returned must be this case's export (its time steps known).
    let (mut ending, exported_steps) = match args.read_back {
        true => (Ending::completed(), Some(check_returned_case(&case_dir, report.case, output.mesh, report.settings)?.n_time_steps)),
        false => (export_and_run(args, &case_dir, report, output, progress)?, None),
    };
    let rows = match read_results(&case_dir) {
        Ok(summary) => {
            if let Some(ended_early) = exported_steps.and_then(|n| unfinished(&summary, n)) {
                ending = ended_early;
            }
            engine_convergence(&mut ending, &summary);
            rows_of(&summary, report, output, progress)?
        }
        Err(e) => {
            // Nothing to read back (a run stopped or failed early): say both, keep the case.
            // A completed run without readable results has failed.
            let before = ending.message.take().map_or(String::new(), |m| format!("{m}; "));
            let status = if ending.status == "completed" { "failed" } else { ending.status };
            ending = Ending { status, message: Some(format!("{before}no results read back: {e}")), converged: false };
            Vec::new()
        }
    };
    let wall = start.elapsed().as_secs_f64();
    let summary = report.write(&rows, &ending, &[], wall)?;
    progress.say(&report.summary_line(&summary, rows.len(), rows.len(), wall));
    match ending.status {
        "completed" => Ok(()),
        _ => Err(ending.message.unwrap_or_default()),
    }
}

/// Export the case to `case_dir` and run svMultiPhysics there; how the run ended.
fn export_and_run(args: &SvmpRun, case_dir: &Path, report: &Report, output: &Output, progress: &Progress) -> Result<Ending, String> {
    let processes = args.mpi_processes.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let exported = export_to(case_dir, report.case, output.mesh, report.settings, processes)?;
    progress.say(&inflow_line(&exported));
    let engine = find_engine().map_err(|e| {
        format!(
            "{e}; the exported case is ready in {}: run its run.sh where svMultiPhysics is installed, bring the directory back there and read it with --read-back",
            case_dir.display()
        )
    })?;
    let stop = stop_on_signals()?;
    let run = run_case(&engine, case_dir, &mut |fraction, message| {
        progress.report(fraction, "svMultiPhysics", message);
        !stop.load(Ordering::SeqCst)
    });
    progress.finish(None);
    ending_of(&run, stop.load(Ordering::SeqCst), case_dir)
}

/// The engine's own convergence verdict joins the summary: a run whose log shows a step
/// stopped at the Newton cap or a linear solve short of its tolerance is not converged,
/// and says why; a run with no log to judge by says that.
fn engine_convergence(ending: &mut Ending, summary: &SvmpSummary) {
    let notes: Vec<&str> = summary.warnings.iter().map(String::as_str).filter(|w| w.contains("svMultiPhysics") || w.contains("convergence")).collect();
    if summary.converged != Some(true) {
        ending.converged = false;
    }
    if !notes.is_empty() {
        let before = ending.message.take().map_or(String::new(), |m| format!("{m}; "));
        ending.message = Some(format!("{before}{}", notes.join("; ")));
    }
}

/// A returned run whose outputs stop before the last exported time step did not finish.
fn unfinished(summary: &SvmpSummary, exported_steps: usize) -> Option<Ending> {
    let last = summary.steps.last().map_or(0, |r| r.step);
    (last < exported_steps).then(|| Ending {
        status: "failed",
        message: Some(format!("the returned outputs end at time step {last} of {exported_steps}: the run did not finish")),
        converged: false,
    })
}

/// Options that steer the embedded solver's own loop; svMultiPhysics takes its run from
/// solver.xml and always starts over.
fn refuse_embedded_only_options(args: &SvmpRun) -> Result<(), String> {
    let given = [("--resume", args.resume), ("--vtu-every", args.vtu_every.is_some())];
    match given.iter().find(|(_, set)| *set) {
        Some((option, _)) => Err(format!(
            "{option} applies to the embedded engine only; svMultiPhysics always starts from rest (time.steps / --steps stops it early)"
        )),
        None => Ok(()),
    }
}

/// The summary's status from how the run went: a signal (ours, or Ctrl-C reaching
/// mpiexec too) is a stop, a solver failure is a failure; other errors end the command.
fn ending_of<T>(run: &Result<T, SvmpError>, signalled: bool, case_dir: &Path) -> Result<Ending, String> {
    let stopped = |at: String| Ending {
        status: "stopped",
        message: Some(format!("stopped by signal {at}; the svMultiPhysics case is in {}", case_dir.display())),
        converged: false,
    };
    match run {
        Ok(_) => Ok(Ending::completed()),
        Err(SvmpError::Cancelled { step }) => Ok(stopped(format!("at svMultiPhysics step {step}"))),
        Err(SvmpError::RunFailed { .. }) if signalled => Ok(stopped("while svMultiPhysics ran".into())),
        Err(e @ SvmpError::RunFailed { .. }) => Ok(Ending { status: "failed", message: Some(e.to_string()), converged: false }),
        Err(e) => Err(e.to_string()),
    }
}

/// The read-back steps as time-series rows, named as the embedded engine names the faces;
/// the peak fields also become peak.vtu and that step's maximum velocity.
fn rows_of(summary: &SvmpSummary, report: &Report, output: &Output, progress: &Progress) -> Result<Vec<Row>, String> {
    for warning in &summary.warnings {
        progress.note(&format!("baffle: warning: {warning}"));
    }
    let settings = report.settings;
    let prescribed = |time_s: f64| match settings.mode {
        RunMode::Steady => report.flow.q_peak_ml_s,
        RunMode::Transient => settings.inflow.flow_ml_s(time_s),
    };
    let peak_velocity_m_s = match &summary.peak_fields {
        Some(fields) => Some((fields.step, write_peak_fields(fields, output)?)),
        None => None,
    };
    let mut rows = Vec::with_capacity(summary.steps.len());
    for step in &summary.steps {
        let face_names = step.faces.iter().map(|f| face_name(output.mesh, f.id)).collect::<Result<_, _>>()?;
        rows.push(Row {
            step: step.step,
            time_s: step.time_s,
            prescribed_inflow_ml_s: prescribed(step.time_s),
            inflow_ml_s: step.inflow_ml_s,
            outflow_ml_s: step.outflow_ml_s,
            max_velocity_m_s: peak_velocity_m_s.filter(|(s, _)| *s == step.step).map_or(f64::NAN, |(_, v)| v),
            residual: f64::NAN,
            retries: 0,
            nonlinear_converged: step.convergence.map_or(true, |c| c.nonlinear_converged),
            face_ids: step.faces.iter().map(|f| f.id).collect(),
            face_names,
            face_pressure_mmhg: step.faces.iter().map(|f| f.mean_pressure_dyn_cm2 / DYN_CM2_PER_MMHG).collect(),
            face_flow_ml_s: step.faces.iter().map(|f| f.flow_ml_s).collect(),
        });
    }
    Ok(rows)
}

fn face_name(mesh: &FlowMesh, id: i32) -> Result<String, String> {
    let face = mesh.faces.iter().find(|f| f.id == id);
    face.map(|f| f.name.clone()).ok_or_else(|| format!("svMultiPhysics reported face {id}, which the mesh does not have"))
}

/// Write the peak fields as peak.vtu (as the embedded engine does); returns their
/// largest speed (m/s).
fn write_peak_fields(fields: &PeakFields, output: &Output) -> Result<f64, String> {
    let n = output.mesh.points_cm.len();
    if fields.velocity_cm_s.len() != n {
        return Err(format!("{}: {} nodes, the case's mesh has {n}", fields.file.display(), fields.velocity_cm_s.len()));
    }
    output.vtu("peak.vtu", &fields.velocity_cm_s, &fields.pressure_dyn_cm2)?;
    let speed = |v: &[f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    Ok(fields.velocity_cm_s.iter().map(speed).fold(0.0, f64::max) / 100.0)
}
