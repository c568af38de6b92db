//! `baffle simulate`: the out-of-process CFD worker. Reads a JSON case, runs the
//! embedded solver (baffle-cfd) and writes summary.json, timeseries.csv, .vtu fields
//! and a checkpoint, all atomically. SIGTERM/SIGINT stop it at the end of the current
//! time step with the results so far; `--resume` continues from the checkpoint.
//! `--engine svmultiphysics` hands the same case to svMultiPhysics instead
//! ([`crate::simulate_svmp`]); both engines' results go through [`crate::simulate_report::Report`].

use crate::error::PlanError;
use crate::case;
use baffle_cfd::{simulate_from, CaseSettings, RunMode, SolverState, SteadyProgress};
use serde::{Deserialize, Serialize};
use crate::files::write_atomic;
use crate::progress::{steady_fraction, Cancel, Progress};
use crate::simulate_report::{cycle_end_step, stop_on_signals, Engine, Ending, Output, Report, Row};
use crate::simulate_svmp::{self, SvmpRun};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

documented_settings! {
#[derive(Default)]
pub struct SimulateSettings {
    /// Case file (JSON): mesh, face roles, fluid, inflow, outlet, time stepping, output.
    pub case: PathBuf,
    /// Output directory: summary.json, timeseries.csv, peak.vtu, final.vtu, checkpoint.json
    /// (with --engine svmultiphysics: summary.json, timeseries.csv, peak.vtu, svmultiphysics/).
    /// The .vtu files are in mm like every surface (they overlay the domain without
    /// scaling), with point arrays velocity_m_s (vector), speed_m_s and pressure_mmhg.
    /// summary.json and timeseries.csv give pressures in mmHg, velocities in m/s, flows
    /// in mL/s.
    pub out: PathBuf,
    /// Steady run with the inflow held at Q_peak (overrides time.mode), a quick estimate
    /// of the peak dp. summary.json: q_held_ml_s is the held flow, q_mean_ml_s the case's
    /// mean flow; outlet_mean_pressure_mmhg is R x Q_peak, far above MAP because R = MAP /
    /// Q_mean. dp is unaffected: with rigid walls the outlet pressure only offsets the
    /// pressure field uniformly.
    pub steady: bool,
    /// Quick estimate of the peak dp (overrides time.mode with "quick"): time-accurate
    /// from rest up to the first flow peak of the waveform (about 110-170 steps instead of
    /// 4 cycles); unlike --steady it converges where the peak flow is not steady.
    pub quick: bool,
    /// Stop after this time step (overrides time.steps).
    pub steps: Option<usize>,
    /// Time step (s) (overrides time.dt_s).
    pub dt_s: Option<f64>,
    /// Preconditioner of the linear solves: ilu or two-level (overrides time.preconditioner).
    pub preconditioner: Option<String>,
    /// Time integration of a transient run: backward-euler or generalized-alpha (second
    /// order, as svMultiPhysics; overrides time.time_integration).
    pub time_integration: Option<String>,
    /// Generalized-alpha's spectral radius at infinite time step, 0-1 (default 0.5;
    /// overrides time.rho_inf).
    pub rho_inf: Option<f64>,
    /// Cardiac cycles (overrides time.cycles).
    pub cycles: Option<usize>,
    /// Write fields_<step>.vtu every N steps (overrides output.vtu_every_steps).
    pub vtu_every: Option<usize>,
    /// Continue the run (transient, or with --steady the steady solve) from OUT/checkpoint.json.
    pub resume: bool,
    /// Solver: the embedded one, or svMultiPhysics (exported to OUT/svmultiphysics/ and
    /// run there with mpiexec; needs svmultiphysics or svMultiPhysics, and mpiexec, on PATH).
    pub engine: Engine,
    /// With --engine svmultiphysics: read back the case already exported to
    /// OUT/svmultiphysics/ and run elsewhere (a cluster; the directory copied back in
    /// place), without exporting or running it again. It must be this case's export.
    pub read_back: bool,
    /// MPI processes of an svMultiPhysics run (default: the available cores).
    pub mpi_processes: Option<usize>,
    /// Print Slicer CLI progress tags (<filter-progress>) on stdout (also with
    /// BAFFLE_PROGRESS_TAGS=1). Otherwise: a bar on a terminal, plain lines in a log (stderr).
    pub progress_tags: bool,
    /// Asked after every step of the embedded engine: true stops the run as SIGTERM does
    /// (its results so far written; a library caller's cancel, e.g. `baffle plan`'s). With
    /// a cancel the run installs no signal handlers (the caller's process keeps its own).
    pub cancel: Option<Cancel>,
}
}

#[derive(Serialize, Deserialize)]
struct Checkpoint {
    case: PathBuf,
    dt_s: f64,
    n_nodes: usize,
    step: usize,
    time_s: f64,
    velocity_cm_s: Vec<[f64; 3]>,
    pressure_dyn_cm2: Vec<f64>,
    /// Empty in steady checkpoints: a steady iterate is its own previous state.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    previous_velocity_cm_s: Vec<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    previous_pressure_dyn_cm2: Vec<f64>,
    /// Generalized-alpha runs only: the velocity's time derivative (cm/s^2).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    acceleration_cm_s2: Vec<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pressure_rate_dyn_cm2_s: Vec<f64>,
    rows: Vec<Row>,
    wall_time_s: f64,
    /// Steady solves only; absent from transient checkpoints (and from those written
    /// before steady solves could resume).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    steady: Option<SteadyCheckpoint>,
    /// A steady solve's relative residual per iteration so far (its convergence history).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    steady_residuals: Vec<f64>,
}

/// [`SteadyProgress`] as stored: the residual reference and the last relative residual,
/// so a resumed solve takes the same pseudo steps and Newton switch.
#[derive(Clone, Copy, Serialize, Deserialize)]
struct SteadyCheckpoint {
    reference_residual: f64,
    relative_residual: f64,
}

impl From<SteadyProgress> for SteadyCheckpoint {
    fn from(p: SteadyProgress) -> Self {
        SteadyCheckpoint { reference_residual: p.reference_residual, relative_residual: p.relative_residual }
    }
}

impl From<SteadyCheckpoint> for SteadyProgress {
    fn from(p: SteadyCheckpoint) -> Self {
        SteadyProgress { reference_residual: p.reference_residual, relative_residual: p.relative_residual }
    }
}

impl Checkpoint {
    fn of(state: SolverState, case: &Path, dt_s: f64, rows: &[Row], steady_residuals: &[f64], wall_time_s: f64) -> Checkpoint {
        let steady = state.steady.map(SteadyCheckpoint::from);
        // A steady iterate is its own previous state: those fields are not kept.
        let (previous_velocity_cm_s, previous_pressure_dyn_cm2) = match steady {
            Some(_) => (Vec::new(), Vec::new()),
            None => (state.previous_velocity_cm_s, state.previous_pressure_dyn_cm2),
        };
        Checkpoint {
            case: case.to_path_buf(),
            dt_s,
            n_nodes: state.pressure_dyn_cm2.len(),
            step: state.step,
            time_s: state.time_s,
            velocity_cm_s: state.velocity_cm_s,
            pressure_dyn_cm2: state.pressure_dyn_cm2,
            previous_velocity_cm_s,
            previous_pressure_dyn_cm2,
            acceleration_cm_s2: state.acceleration_cm_s2,
            pressure_rate_dyn_cm2_s: state.pressure_rate_dyn_cm2_s,
            rows: rows.to_vec(),
            wall_time_s,
            steady,
            steady_residuals: steady_residuals.to_vec(),
        }
    }

    /// Read OUT/checkpoint.json and check it continues this case: same mesh, same mode
    /// and (transient) the same time step.
    fn read(path: &Path, n_nodes: usize, settings: &CaseSettings) -> Result<Checkpoint, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e} (nothing to resume)", path.display()))?;
        let cp: Checkpoint = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
        let steady = settings.mode == RunMode::Steady;
        match (cp.steady.is_some(), steady) {
            (true, false) => {
                return Err(format!(
                    "{}: the checkpoint is of a steady solve (iteration {}); resume it with --steady, or start the transient run over without --resume",
                    path.display(),
                    cp.step
                ))
            }
            (false, true) => {
                return Err(format!(
                    "{}: the checkpoint is of a transient run (step {}, t = {} s); resume it without --steady, or start the steady solve over without --resume",
                    path.display(),
                    cp.step,
                    cp.time_s
                ))
            }
            _ => {}
        }
        let dt_differs = !steady && (cp.dt_s - settings.dt_s).abs() > 1e-12 * settings.dt_s;
        if cp.n_nodes != n_nodes || dt_differs {
            return Err(format!(
                "{}: checkpoint of {} nodes, dt {} s does not match this case ({n_nodes} nodes, dt {} s)",
                path.display(),
                cp.n_nodes,
                cp.dt_s,
                settings.dt_s
            ));
        }
        Ok(cp)
    }

    /// The solver state to continue from, the rows so far and the wall time so far.
    fn into_start(self) -> (SolverState, Vec<Row>, Vec<f64>, f64) {
        let (previous_velocity_cm_s, previous_pressure_dyn_cm2) = match self.steady {
            Some(_) => (self.velocity_cm_s.clone(), self.pressure_dyn_cm2.clone()),
            None => (self.previous_velocity_cm_s, self.previous_pressure_dyn_cm2),
        };
        let state = SolverState {
            step: self.step,
            time_s: self.time_s,
            velocity_cm_s: self.velocity_cm_s,
            pressure_dyn_cm2: self.pressure_dyn_cm2,
            previous_velocity_cm_s,
            previous_pressure_dyn_cm2,
            acceleration_cm_s2: self.acceleration_cm_s2,
            pressure_rate_dyn_cm2_s: self.pressure_rate_dyn_cm2_s,
            steady: self.steady.map(SteadyProgress::from),
        };
        (state, self.rows, self.steady_residuals, self.wall_time_s)
    }
}

// The checkpoint is the embedded engine's own file.
impl Output<'_> {
    fn checkpoint(&self, cp: &Checkpoint) -> Result<(), String> {
        let text = serde_json::to_string(cp).map_err(|e| e.to_string())?;
        write_atomic(&self.dir.join("checkpoint.json"), text.as_bytes())
    }
}

/// `baffle simulate` showing its progress and saying its summary on `progress` (a stage
/// of `baffle plan`, or the whole command; --progress-tags is the caller's to apply).
pub fn run_simulate(args: &SimulateSettings, progress: &Progress) -> Result<(), PlanError> {
    simulate(args, progress).map_err(PlanError::Simulate)
}

/// The run of `args`: its fields, time series, summary and checkpoints written.
fn simulate(args: &SimulateSettings, progress: &Progress) -> Result<(), String> {
    let start = Instant::now();
    // Refused before the case and its mesh are read: nothing of them is needed to say so.
    if args.read_back && args.engine != Engine::Svmultiphysics {
        return Err("--read-back reads an svMultiPhysics run: give --engine svmultiphysics".into());
    }
    let mut case = case::read_case(&args.case)?;
    if args.steady {
        case.time.mode = "steady".into();
    }
    if args.quick {
        case.time.mode = case::QUICK_MODE.into();
    }
    if let Some(n) = args.steps {
        case.time.steps = Some(n);
    }
    if let Some(dt) = args.dt_s {
        case.time.dt_s = dt;
    }
    if let Some(c) = args.cycles {
        case.time.cycles = c;
    }
    if let Some(p) = &args.preconditioner {
        case.time.preconditioner = Some(p.clone());
    }
    if let Some(v) = &args.time_integration {
        case.time.time_integration = Some(v.clone());
        // Switching to backward Euler drops the case's generalized-alpha rho_inf.
        if v == "backward-euler" && args.rho_inf.is_none() {
            case.time.rho_inf = None;
        }
    }
    if let Some(v) = args.rho_inf {
        case.time.rho_inf = Some(v);
    }
    if let Some(v) = args.vtu_every {
        case.output.vtu_every_steps = v;
    }
    let (settings, flow) = case::settings(&case)?;
    let steady = settings.mode == RunMode::Steady;
    let mesh = case::load_mesh(&case)?;
    std::fs::create_dir_all(&args.out).map_err(|e| format!("{}: {e}", args.out.display()))?;
    let output = Output { dir: &args.out, mesh: &mesh };
    let report = Report { dir: &args.out, case: &case, settings: &settings, flow: &flow, engine: args.engine };
    let quick = case::is_quick(&case);
    if args.engine == Engine::Svmultiphysics {
        let svmp = SvmpRun { out: &args.out, mpi_processes: args.mpi_processes, resume: args.resume, vtu_every: args.vtu_every, read_back: args.read_back };
        return simulate_svmp::run(&svmp, &report, &output, start, progress);
    }

    let (mut rows, start_state, mut residuals, previous_wall) = if args.resume {
        let (state, rows, residuals, wall) = Checkpoint::read(&args.out.join("checkpoint.json"), mesh.points_cm.len(), &settings)?.into_start();
        (rows, Some(state), residuals, wall)
    } else {
        (Vec::new(), None, Vec::new(), 0.0)
    };

    // A library caller stops the run with its cancel: its process's signal handlers stay its own.
    let stop = match args.cancel {
        Some(_) => Arc::new(AtomicBool::new(false)),
        None => stop_on_signals()?,
    };
    // A quick run stops at the first flow peak unless told otherwise.
    let step_limit = case.time.steps.or(quick.then(|| case::first_peak_step(&settings))).filter(|_| !steady);
    let period_steps = (flow.period_s / settings.dt_s).round();
    let peak_step_in_cycle = (flow.peak_time_in_cycle_s / settings.dt_s).round();
    let n_steps = if steady { settings.steady_max_iterations } else { step_limit.unwrap_or(cycle_end_step(settings.cycles, flow.period_s, settings.dt_s)) };
    let cp_every = case.output.checkpoint_every_steps;
    let vtu_every = case.output.vtu_every_steps;
    let mut io_error: Option<String> = None;
    let mut signalled = false;
    let mut limit_reached = false;
    let first_row = rows.len();
    // A steady solve's residual can rise for a while: the bar never moves back.
    let mut shown_fraction = 0.0f64;

    let result = simulate_from(&mesh, &settings, start_state.as_ref(), &mut |view| {
        let fraction = if steady {
            steady_fraction(view.relative_residual(), settings.steady_tolerance, view.step, settings.steady_max_iterations)
        } else {
            view.step as f64 / n_steps.max(1) as f64
        };
        shown_fraction = shown_fraction.max(fraction);
        residuals.extend(view.relative_residual());
        let fraction = shown_fraction;
        progress.report(fraction, if steady { "steady solve" } else { "time steps" }, view.message);
        if let Some(r) = view.result {
            rows.push(Row::of(r));
            let step = view.step;
            let io = || -> Result<(), String> {
                let at_peak = period_steps > 0.0 && ((step as f64) % period_steps - peak_step_in_cycle).abs() < 0.5;
                let interval = vtu_every > 0 && step % vtu_every == 0;
                if at_peak || interval {
                    let (v, p) = view.fields();
                    if at_peak {
                        output.vtu("peak.vtu", &v, &p)?;
                    }
                    if interval {
                        output.vtu(&format!("fields_{step:06}.vtu"), &v, &p)?;
                    }
                }
                Ok(())
            };
            if let Err(e) = io() {
                io_error = Some(e);
                return false;
            }
        }
        signalled = stop.load(Ordering::SeqCst) || args.cancel.as_ref().is_some_and(|cancel| cancel());
        limit_reached = step_limit.is_some_and(|n| view.step >= n);
        let stopping = signalled || limit_reached;
        // Steady iterations have no rows yet (the solve reports its final iterate only).
        if stopping || (cp_every > 0 && view.step % cp_every == 0) {
            if let Some(state) = view.state() {
                let cp = Checkpoint::of(state, &args.case, settings.dt_s, &rows, &residuals, previous_wall + start.elapsed().as_secs_f64());
                let written = output.checkpoint(&cp).and_then(|_| if steady { Ok(()) } else { report.csv(&rows) });
                if let Err(e) = written {
                    io_error = Some(e);
                    return false;
                }
            }
        }
        !stopping
    });
    let wall = previous_wall + start.elapsed().as_secs_f64();
    if let Some(e) = io_error {
        progress.finish(None);
        return Err(e);
    }
    let run = match result {
        Ok(run) => run,
        Err(e) => {
            progress.finish(None);
            // Divergence or linear-solver failure: keep the steps done, name the failure.
            report.write(&rows, &Ending { status: "failed", message: Some(e.to_string()), converged: false }, &residuals, wall)?;
            let flags = if matches!(e, baffle_cfd::CfdError::StepFailed { .. }) {
                " (here: --dt-s, \"max_linear_iterations\" in the case's \"time\", or --engine svmultiphysics)"
            } else {
                ""
            };
            return Err(format!("{e}{flags}; results of the {} steps before it in {}", rows.len(), args.out.display()));
        }
    };
    if steady {
        rows = run.summary.steps.iter().map(Row::of).collect();
        output.vtu("peak.vtu", &run.summary.velocity_cm_s, &run.summary.pressure_dyn_cm2)?;
    }
    output.vtu("final.vtu", &run.summary.velocity_cm_s, &run.summary.pressure_dyn_cm2)?;
    // A steady solve stops at an iteration, always at the peak time.
    let at = |t: f64| match (&run.state, steady) {
        (Some(state), true) => format!("steady iteration {}", state.step),
        _ => format!("t = {t:.4} s"),
    };
    let resume = if steady { "--resume --steady" } else { "--resume" };
    // A full bar at the iteration cap is not success: the bar's line says which it was.
    let unconverged = steady && !run.summary.converged && run.cancelled_at_s.is_none();
    let note = unconverged.then(|| {
        format!(
            "steady solve stopped at its iteration cap ({}) without reaching the residual target {:.0e}: the result is not converged",
            settings.steady_max_iterations, settings.steady_tolerance
        )
    });
    progress.finish(note.as_deref());
    let (status, message) = match (run.cancelled_at_s, signalled) {
        (Some(t), true) => ("stopped", Some(format!("stopped by signal after {}; continue with {resume}", at(t)))),
        (Some(_), false) if limit_reached && quick => ("completed", None),
        (Some(_), false) if limit_reached => ("completed", Some(format!("step limit {} reached", n_steps))),
        (Some(t), false) => ("stopped", Some(format!("stopped at {}", at(t)))),
        (None, _) => ("completed", None),
    };
    let message = message.or(note);
    let summary = report.write(&rows, &Ending { status, message: message.clone(), converged: run.summary.converged }, &residuals, wall)?;
    progress.say(&report.summary_line(&summary, rows.len(), rows.len() - first_row.min(rows.len()), wall));
    if status == "stopped" {
        return Err(message.unwrap_or_default());
    }
    Ok(())
}
