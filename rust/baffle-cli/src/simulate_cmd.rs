//! `baffle simulate`: the out-of-process CFD worker. Reads a JSON case, runs the
//! embedded solver (baffle-cfd) and writes summary.json, timeseries.csv, .vtu fields
//! and a checkpoint, all atomically. SIGTERM/SIGINT stop it at the end of the current
//! time step with the results so far; `--resume` continues from the checkpoint.

use crate::case::{self, FlowInputs};
use baffle_cfd::hemodynamics::DYN_CM2_PER_MMHG;
use baffle_cfd::{simulate_from, CaseSettings, FlowMesh, RunMode, SolverState, StepResult};
use clap::Args;
use serde::{Deserialize, Serialize};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
#[command(after_help = format!("Example case (relative paths are relative to the case file):\n{}", case::EXAMPLE))]
pub struct SimulateArgs {
    /// Case file (JSON): mesh, face roles, fluid, inflow, outlet, time stepping, output.
    case: PathBuf,
    /// Output directory: summary.json, timeseries.csv, peak.vtu, final.vtu, checkpoint.json.
    #[arg(long)]
    out: PathBuf,
    /// Steady run with the inflow fixed at Q_peak (overrides time.mode).
    #[arg(long)]
    steady: bool,
    /// Stop after this time step (overrides time.steps).
    #[arg(long)]
    steps: Option<usize>,
    /// Time step (s) (overrides time.dt_s).
    #[arg(long)]
    dt_s: Option<f64>,
    /// Cardiac cycles (overrides time.cycles).
    #[arg(long)]
    cycles: Option<usize>,
    /// Write fields_<step>.vtu every N steps (overrides output.vtu_every_steps).
    #[arg(long)]
    vtu_every: Option<usize>,
    /// Continue the transient run from OUT/checkpoint.json.
    #[arg(long)]
    resume: bool,
}

/// One row of the time series (pressures in mmHg).
#[derive(Clone, Debug, Serialize, Deserialize)]
struct Row {
    step: usize,
    time_s: f64,
    prescribed_inflow_ml_s: f64,
    inflow_ml_s: f64,
    outflow_ml_s: f64,
    max_velocity_m_s: f64,
    residual: f64,
    face_ids: Vec<i32>,
    face_names: Vec<String>,
    face_pressure_mmhg: Vec<f64>,
}

impl Row {
    fn of(r: &StepResult) -> Row {
        Row {
            step: r.step,
            time_s: r.time_s,
            prescribed_inflow_ml_s: r.prescribed_inflow_ml_s,
            inflow_ml_s: r.inflow_ml_s,
            outflow_ml_s: r.outflow_ml_s,
            max_velocity_m_s: r.max_velocity_cm_s / 100.0,
            residual: r.residual,
            face_ids: r.faces.iter().map(|f| f.id).collect(),
            face_names: r.faces.iter().map(|f| f.name.clone()).collect(),
            face_pressure_mmhg: r.faces.iter().map(|f| f.mean_pressure_dyn_cm2 / DYN_CM2_PER_MMHG).collect(),
        }
    }
    fn pressure(&self, id: i32) -> f64 {
        self.face_ids.iter().position(|&f| f == id).map_or(f64::NAN, |k| self.face_pressure_mmhg[k])
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
    previous_velocity_cm_s: Vec<[f64; 3]>,
    previous_pressure_dyn_cm2: Vec<f64>,
    rows: Vec<Row>,
    wall_time_s: f64,
}

/// Write `bytes` to `path` via a temporary name in the same directory, then rename.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    let result = (|| -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        format!("{}: {e}", path.display())
    })
}

struct Output<'a> {
    dir: &'a Path,
    mesh: &'a FlowMesh,
}

impl Output<'_> {
    fn vtu(&self, name: &str, velocity: &[[f64; 3]], pressure: &[f64]) -> Result<(), String> {
        baffle_cfd::vtu::write_solution_vtu(&self.dir.join(name), &self.mesh.points_cm, &self.mesh.tets, velocity, pressure)
            .map_err(|e| e.to_string())
    }

    fn csv(&self, rows: &[Row]) -> Result<(), String> {
        let mut text = String::from("step,time_s,prescribed_inflow_ml_s,inflow_ml_s,outflow_ml_s,max_velocity_m_s,residual");
        if let Some(r) = rows.first() {
            for name in &r.face_names {
                text.push_str(&format!(",p_{name}_mmhg"));
            }
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
            text.push('\n');
        }
        write_atomic(&self.dir.join("timeseries.csv"), text.as_bytes())
    }

    fn checkpoint(&self, cp: &Checkpoint) -> Result<(), String> {
        let text = serde_json::to_string(cp).map_err(|e| e.to_string())?;
        write_atomic(&self.dir.join("checkpoint.json"), text.as_bytes())
    }
}

/// dp = p(plane 1) - p(plane 2), or p(inlet) - p(first outlet).
fn dp_faces(case: &case::Case) -> (i32, i32) {
    match case.faces.planes[..] {
        [a, b] => (a, b),
        _ => (case.faces.inlet, case.faces.outlets[0]),
    }
}

fn summary_json(
    case: &case::Case,
    settings: &CaseSettings,
    flow: &FlowInputs,
    rows: &[Row],
    status: &str,
    message: Option<String>,
    converged: bool,
    wall_time_s: f64,
) -> serde_json::Value {
    let (a, b) = dp_faces(case);
    let outlet = case.faces.outlets[0];
    let steady = settings.mode == RunMode::Steady;
    let period_steps = if steady { 0 } else { (flow.period_s / settings.dt_s).round() as usize };
    // The last complete cycle run (or all steps when less than one cycle was run).
    let last_step = rows.last().map_or(0, |r| r.step);
    let cycle: Vec<&Row> = if steady || period_steps == 0 || last_step < period_steps {
        rows.iter().collect()
    } else {
        let end = last_step - last_step % period_steps;
        rows.iter().filter(|r| r.step > end - period_steps && r.step <= end).collect()
    };
    let peak = cycle.iter().copied().max_by(|x, y| x.prescribed_inflow_ml_s.total_cmp(&y.prescribed_inflow_ml_s));
    let mean = |f: &dyn Fn(&Row) -> f64| if cycle.is_empty() { f64::NAN } else { cycle.iter().map(|r| f(r)).sum::<f64>() / cycle.len() as f64 };
    let inflow_sum: f64 = cycle.iter().map(|r| r.inflow_ml_s).sum();
    let outflow_sum: f64 = cycle.iter().map(|r| r.outflow_ml_s).sum();
    // Cycle N-1 vs N of the inlet-outlet pressure difference: RMS difference over the range.
    let periodicity = (!steady && period_steps > 0 && last_step >= 2 * period_steps).then(|| {
        let end = last_step - last_step % period_steps;
        let dp = |step: usize| rows.iter().find(|r| r.step == step).map(|r| r.pressure(case.faces.inlet) - r.pressure(outlet));
        let last: Vec<f64> = (end - period_steps + 1..=end).filter_map(dp).collect();
        let previous: Vec<f64> = (end - 2 * period_steps + 1..=end - period_steps).filter_map(dp).collect();
        let range = last.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - last.iter().cloned().fold(f64::INFINITY, f64::min);
        let rms = (last.iter().zip(&previous).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / last.len().max(1) as f64).sqrt();
        if range > 0.0 { rms / range } else { rms }
    });
    let f = |v: f64| if v.is_finite() { serde_json::json!(v) } else { serde_json::Value::Null };
    serde_json::json!({
        "status": status,
        "message": message,
        "mode": if steady { "steady" } else { "transient" },
        "converged": converged,
        "steps_done": rows.len(),
        "last_step": last_step,
        "last_time_s": rows.last().map(|r| r.time_s),
        "peak_time_s": peak.map(|r| r.time_s),
        "dp_faces": [a, b],
        "dp_peak_mmhg": peak.map(|r| f(r.pressure(a) - r.pressure(b))),
        "max_velocity_m_s": peak.map(|r| f(r.max_velocity_m_s)),
        "max_velocity_run_m_s": f(rows.iter().map(|r| r.max_velocity_m_s).fold(f64::NAN, f64::max)),
        "q_mean_ml_s": f(mean(&|r| r.inflow_ml_s)),
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
            "density_g_cm3": settings.density_g_cm3,
            "viscosity_g_cm_s": settings.viscosity_g_cm_s,
        },
    })
}

struct Progress {
    bar: bool,
    start: Instant,
    /// The part of the progress range this run fills (a stage of `baffle plan`); None: no tags.
    tag_range: Option<(f64, f64)>,
}

impl Progress {
    fn report(&self, fraction: f64, message: &str) {
        let fraction = fraction.clamp(0.0, 1.0);
        if let Some((lo, hi)) = self.tag_range {
            let mut out = std::io::stdout().lock();
            let _ = writeln!(out, "<filter-progress>{:.4}</filter-progress>", lo + (hi - lo) * fraction);
            let _ = out.flush();
        }
        if self.bar {
            let width = 30;
            let done = (fraction * width as f64).round() as usize;
            let mut err = std::io::stderr().lock();
            let _ = write!(
                err,
                "\r[{}{}] {:5.1}% {:6.1}s {}\x1b[K",
                "#".repeat(done),
                " ".repeat(width - done),
                100.0 * fraction,
                self.start.elapsed().as_secs_f64(),
                message
            );
            let _ = err.flush();
        }
    }
    fn finish(&self) {
        if self.bar {
            eprintln!();
        }
    }
}

pub fn run_simulate(args: &SimulateArgs) -> Result<(), String> {
    run_simulate_tagged(args, Some((0.0, 1.0)))
}

/// `baffle simulate` with the progress tags mapped into `tag_range` (None: no tags).
pub fn run_simulate_tagged(args: &SimulateArgs, tag_range: Option<(f64, f64)>) -> Result<(), String> {
    let start = Instant::now();
    let mut case = case::read_case(&args.case)?;
    if args.steady {
        case.time.mode = "steady".into();
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
    if let Some(v) = args.vtu_every {
        case.output.vtu_every_steps = v;
    }
    let (settings, flow) = case::settings(&case)?;
    let steady = settings.mode == RunMode::Steady;
    if args.resume && steady {
        return Err("--resume continues a transient run; steady runs start over".into());
    }
    let mesh = case::load_mesh(&case)?;
    std::fs::create_dir_all(&args.out).map_err(|e| format!("{}: {e}", args.out.display()))?;
    let output = Output { dir: &args.out, mesh: &mesh };

    let (mut rows, start_state, previous_wall) = if args.resume {
        let path = args.out.join("checkpoint.json");
        let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e} (nothing to resume)", path.display()))?;
        let cp: Checkpoint = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
        if cp.n_nodes != mesh.points_cm.len() || (cp.dt_s - settings.dt_s).abs() > 1e-12 * settings.dt_s {
            return Err(format!(
                "{}: checkpoint of {} nodes, dt {} s does not match this case ({} nodes, dt {} s)",
                path.display(),
                cp.n_nodes,
                cp.dt_s,
                mesh.points_cm.len(),
                settings.dt_s
            ));
        }
        let state = SolverState {
            step: cp.step,
            time_s: cp.time_s,
            velocity_cm_s: cp.velocity_cm_s,
            pressure_dyn_cm2: cp.pressure_dyn_cm2,
            previous_velocity_cm_s: cp.previous_velocity_cm_s,
            previous_pressure_dyn_cm2: cp.previous_pressure_dyn_cm2,
            steady: None,
        };
        (cp.rows, Some(state), cp.wall_time_s)
    } else {
        (Vec::new(), None, 0.0)
    };

    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGTERM, signal_hook::consts::SIGINT] {
        signal_hook::flag::register(signal, Arc::clone(&stop)).map_err(|e| format!("cannot install signal handler: {e}"))?;
    }
    let progress = Progress { bar: std::io::stderr().is_terminal(), start, tag_range };
    let step_limit = case.time.steps.filter(|_| !steady);
    let period_steps = (flow.period_s / settings.dt_s).round();
    let peak_step_in_cycle = (flow.peak_time_in_cycle_s / settings.dt_s).round();
    let n_steps = if steady { settings.steady_max_iterations } else { step_limit.unwrap_or((settings.cycles as f64 * period_steps) as usize) };
    let cp_every = case.output.checkpoint_every_steps;
    let vtu_every = case.output.vtu_every_steps;
    let case_path = args.case.clone();
    let mut io_error: Option<String> = None;
    let mut signalled = false;
    let mut limit_reached = false;
    let first_row = rows.len();

    let result = simulate_from(&mesh, &settings, start_state.as_ref(), &mut |view| {
        let fraction = if steady { view.fraction } else { view.step as f64 / n_steps.max(1) as f64 };
        progress.report(fraction, view.message);
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
        signalled = stop.load(Ordering::SeqCst);
        limit_reached = step_limit.is_some_and(|n| view.step >= n);
        let stopping = signalled || limit_reached;
        if !steady && (stopping || (cp_every > 0 && view.step % cp_every == 0)) {
            if let Some(state) = view.state() {
                let cp = Checkpoint {
                    case: case_path.clone(),
                    dt_s: settings.dt_s,
                    n_nodes: state.pressure_dyn_cm2.len(),
                    step: state.step,
                    time_s: state.time_s,
                    velocity_cm_s: state.velocity_cm_s.clone(),
                    pressure_dyn_cm2: state.pressure_dyn_cm2.clone(),
                    previous_velocity_cm_s: state.previous_velocity_cm_s.clone(),
                    previous_pressure_dyn_cm2: state.previous_pressure_dyn_cm2.clone(),
                    rows: rows.clone(),
                    wall_time_s: previous_wall + start.elapsed().as_secs_f64(),
                };
                if let Err(e) = output.checkpoint(&cp).and_then(|_| output.csv(&rows)) {
                    io_error = Some(e);
                    return false;
                }
            }
        }
        !stopping
    });
    progress.finish();
    let wall = previous_wall + start.elapsed().as_secs_f64();
    let write_summary = |rows: &[Row], status: &str, message: Option<String>, converged: bool| -> Result<(), String> {
        let json = summary_json(&case, &settings, &flow, rows, status, message, converged, wall);
        output.csv(rows)?;
        write_atomic(&args.out.join("summary.json"), serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?.as_bytes())
    };
    if let Some(e) = io_error {
        return Err(e);
    }
    let run = match result {
        Ok(run) => run,
        Err(e) => {
            // Divergence or linear-solver failure: keep the steps done, name the failure.
            write_summary(&rows, "failed", Some(e.to_string()), false)?;
            return Err(format!("{e} (results of the {} steps before it in {})", rows.len(), args.out.display()));
        }
    };
    if steady {
        rows = run.summary.steps.iter().map(Row::of).collect();
        output.vtu("peak.vtu", &run.summary.velocity_cm_s, &run.summary.pressure_dyn_cm2)?;
    }
    output.vtu("final.vtu", &run.summary.velocity_cm_s, &run.summary.pressure_dyn_cm2)?;
    let (status, message) = match (run.cancelled_at_s, signalled) {
        (Some(t), true) => ("stopped", Some(format!("stopped by signal after t = {t:.4} s; continue with --resume"))),
        (Some(_), false) if limit_reached => ("completed", Some(format!("step limit {} reached", n_steps))),
        (Some(t), false) => ("stopped", Some(format!("stopped at t = {t:.4} s"))),
        (None, _) => ("completed", None),
    };
    write_summary(&rows, status, message.clone(), run.summary.converged)?;
    let summary = summary_json(&case, &settings, &flow, &rows, status, message.clone(), run.summary.converged, wall);
    println!(
        "{} {} steps ({} this run): dp {:.3} mmHg (faces {} - {}), v_max {:.3} m/s, Q_peak {:.2} mL/s, {:.1} s; wrote {}",
        status,
        rows.len(),
        rows.len() - first_row.min(rows.len()),
        summary["dp_peak_mmhg"].as_f64().unwrap_or(f64::NAN),
        dp_faces(&case).0,
        dp_faces(&case).1,
        summary["max_velocity_m_s"].as_f64().unwrap_or(f64::NAN),
        summary["q_peak_ml_s"].as_f64().unwrap_or(f64::NAN),
        wall,
        args.out.display()
    );
    if steady && !run.summary.converged {
        eprintln!("baffle: warning: the steady solve did not reach its residual target");
    }
    if status == "stopped" {
        return Err(message.unwrap_or_default());
    }
    Ok(())
}
