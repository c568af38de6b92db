//! Speed and memory of the CFD solver (issue #4), on patient p2's published mesh
//! (147k tets, faces 11 VSD cap = inlet, 16 aortic cap = resistance outlet) with the
//! paper's settings.
//!
//!   cargo bench -p baffle-cfd --bench solver -- [--runs N] [--steps S] [--t0 T] [--picard K]
//!                          [--precision mixed|f64|both] [--coarse N] [--restart N] [--reuse N]
//!                          [--steady] [--full] [--compare-schemes] [--smoke]
//!
//! - default: time per time step, median over N runs (3) of S steps (20) started from
//!   rest at t = T (0.1 s: steep systole, the hardest part) with at most K nonlinear
//!   iterations per step (the case default unless given), and the projected
//!   4-cycle wall time = median per step x steps of 4 cycles;
//! - `--steady`: the steady planning estimate (Q_peak), median of N runs;
//! - `--compare-schemes`: the same S-step window with one linear solve per step
//!   (semi-implicit) and with Picard iterations to convergence (up to 5 per step,
//!   1e-3): the difference of dp and v_max, step by step;
//! - `--full`: one complete 4-cycle run (2728 steps): wall time, dp at peak flow,
//!   periodicity (cycle 3 vs 4);
//! - `--time-accuracy be,ga,ga1 [--dt-ms 0.5,1,2] [--t-end 0.164]`: each scheme (backward
//!   Euler; generalized-alpha with its auto Picard loop; generalized-alpha semi-implicit)
//!   at each dt from rest to t_end: dp, v_max, steps, linear solves, GMRES iterations, CPU;
//! - `--smoke`: a few steps on a small tube, so CI checks the bench still runs;
//! - `--scaling`: GMRES iterations and time per step against the mesh size, on one tube
//!   (radius 4 mm, length 40 mm, Re ~2,700 at peak flow) meshed at 9.7k, 45k and 150k
//!   tets (`--big`: and 622k), S steps from rest at t = T, median over N runs.
//!
//! `--reuse N`: solves one preconditioner factorization may serve (1: new factors every step);
//! BENCH_VERBOSE=1 in the environment also prints the GMRES iterations of every step.
//!
//! Every mode prints the peak resident memory (VmHWM). Data: $BAFFLE_DATA_DIR or ../shared/data.

mod support;
use support::process_cpu_s;

use std::time::Instant;

use baffle_cfd::hemodynamics::{hemodynamics, ClinicalInputs, CARDIAC_INDEX_DEFAULT_L_MIN_M2};
use baffle_cfd::test_meshes::{tube, INLET, OUTLET};
use baffle_cfd::vtu::read_simvascular_mesh;
use baffle_cfd::{
    periodicity_nrmsd, simulate, simulate_from, CaseSettings, FlowMesh, NonlinearIterations, Outlet, RunMode, Summary, TimeIntegration, Waveform, AUTO_NONLINEAR_CAP,
    DEFAULT_RHO_INF,
};

const MMHG: f64 = 1333.22;
const VSD_CAP: i32 = 11;
const AORTIC_CAP: i32 = 16;

struct Options {
    runs: usize,
    steps: usize,
    precisions: Vec<bool>,
    steady: bool,
    full: bool,
    smoke: bool,
    scaling: bool,
    /// Two-level preconditioner's aggregate size (0: ILU(0) alone; default the case's, 256).
    coarse: usize,
    /// `--scaling` also on a 622k-tet tube.
    big: bool,
    /// `--scaling` from this size on (0: 9.7k, 1: 45k, 2: 150k, 3: 622k tets).
    from_size: usize,
    /// GMRES restart length (default: the case's, 60).
    restart: Option<usize>,
    /// Solves one preconditioner may serve (default: the case's).
    reuse: Option<usize>,
    compare_schemes: bool,
    /// `--time-accuracy`: these schemes at these time steps (ms), from rest to t_end.
    time_accuracy: Option<(Vec<String>, Vec<f64>, f64)>,
    t0_s: f64,
    picard: Option<usize>,
}

fn options() -> Result<Options, String> {
    let mut o = Options { runs: 3, steps: 20, precisions: vec![true], steady: false, full: false, smoke: false, scaling: false, coarse: baffle_cfd::TWO_LEVEL_AGGREGATE_NODES, big: false, from_size: 0, restart: None, reuse: None, compare_schemes: false, time_accuracy: None, t0_s: 0.1, picard: None };
    let (mut schemes, mut dts_ms, mut t_end_s) = (None, None, 0.164);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = |name: &str| args.next().ok_or(format!("{name} needs a value"));
        match a.as_str() {
            "--runs" => o.runs = value("--runs")?.parse().map_err(|e| format!("--runs: {e}"))?,
            "--steps" => o.steps = value("--steps")?.parse().map_err(|e| format!("--steps: {e}"))?,
            "--precision" => {
                o.precisions = match value("--precision")?.as_str() {
                    "mixed" => vec![true],
                    "f64" => vec![false],
                    "both" => vec![true, false],
                    other => return Err(format!("--precision takes mixed, f64 or both, not {other}")),
                }
            }
            "--steady" => o.steady = true,
            "--full" => o.full = true,
            "--smoke" => o.smoke = true,
            "--scaling" => o.scaling = true,
            "--big" => o.big = true,
            "--restart" => o.restart = Some(value("--restart")?.parse().map_err(|e| format!("--restart: {e}"))?),
            "--reuse" => o.reuse = Some(value("--reuse")?.parse().map_err(|e| format!("--reuse: {e}"))?),
            "--from-size" => o.from_size = value("--from-size")?.parse().map_err(|e| format!("--from-size: {e}"))?,
            "--coarse" => o.coarse = value("--coarse")?.parse().map_err(|e| format!("--coarse: {e}"))?,
            "--compare-schemes" => o.compare_schemes = true,
            "--time-accuracy" => schemes = Some(value("--time-accuracy")?.split(',').map(str::to_string).collect::<Vec<_>>()),
            "--dt-ms" => dts_ms = Some(value("--dt-ms")?.split(',').map(|v| v.parse::<f64>().map_err(|e| format!("--dt-ms: {e}"))).collect::<Result<Vec<_>, _>>()?),
            "--t-end" => t_end_s = value("--t-end")?.parse().map_err(|e| format!("--t-end: {e}"))?,
            "--t0" => o.t0_s = value("--t0")?.parse().map_err(|e| format!("--t0: {e}"))?,
            "--picard" => o.picard = Some(value("--picard")?.parse().map_err(|e| format!("--picard: {e}"))?),
            "--bench" => {} // passed by `cargo bench`
            other => return Err(format!("unknown argument {other}")),
        }
    }
    if let Some(schemes) = schemes {
        o.time_accuracy = Some((schemes, dts_ms.unwrap_or_else(|| vec![0.5, 1.0, 2.0]), t_end_s));
    }
    if o.runs == 0 || o.steps == 0 {
        return Err("--runs and --steps must be >= 1".into());
    }
    Ok(o)
}

fn peak_memory_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|kb| kb.parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg").map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" ")).unwrap_or_default()
}

/// p2's case: Table 4 hemodynamics (BSA 0.37, 107/78 mmHg, CI 3.48), the built-in waveform.
fn p2_case() -> Result<(FlowMesh, CaseSettings), Box<dyn std::error::Error>> {
    let dir = baffle_test_support::reference_data::reference_data_dir();
    let mesh = read_simvascular_mesh(&dir.join("p2/published_M_final.vtu"), &dir.join("p2/published_M_final.vtp"))?;
    let h = hemodynamics(&ClinicalInputs { bsa_m2: 0.37, sbp_mmhg: 107.0, dbp_mmhg: 78.0, cardiac_index_l_min_m2: CARDIAC_INDEX_DEFAULT_L_MIN_M2 })?;
    let outlets = vec![Outlet { face_id: AORTIC_CAP, resistance_dyn_s_cm5: h.resistance_dyn_s_cm5 }];
    let settings = CaseSettings::new(VSD_CAP, Waveform::default_for_mean(h.q_mean_ml_s)?, outlets);
    Ok((mesh, settings))
}

/// `steps` steps of the case's waveform from t0: the waveform shifted by t0, one step
/// longer than the window so that no step wraps around to the start ([`run_window`]
/// stops after `steps`).
fn window(settings: &CaseSettings, t0_s: f64, steps: usize) -> CaseSettings {
    let dt = settings.dt_s;
    let mut s = settings.clone();
    s.inflow = Waveform::Table {
        times_s: (0..=steps + 1).map(|i| i as f64 * dt).collect(),
        flows_ml_s: (0..=steps + 1).map(|i| settings.inflow.flow_ml_s(t0_s + i as f64 * dt)).collect(),
        period_s: (steps + 1) as f64 * dt,
    };
    s.cycles = 1;
    s.mode = RunMode::Transient;
    s
}

fn dp_mmhg(summary: &Summary, step: usize) -> f64 {
    let r = &summary.steps[step];
    let p = |id| r.face(id).map_or(f64::NAN, |f| f.mean_pressure_dyn_cm2);
    (p(VSD_CAP) - p(AORTIC_CAP)) / MMHG
}

fn run(mesh: &FlowMesh, settings: &CaseSettings) -> Result<(Summary, f64), Box<dyn std::error::Error>> {
    let start = Instant::now();
    let summary = simulate(mesh, settings, &mut |_, _| true)?;
    Ok((summary, start.elapsed().as_secs_f64()))
}

/// The first `steps` steps of a [`window`] case.
fn run_window(mesh: &FlowMesh, settings: &CaseSettings, steps: usize) -> Result<(Summary, f64), Box<dyn std::error::Error>> {
    let start = Instant::now();
    let run = simulate_from(mesh, settings, None, &mut |view| view.step < steps)?;
    Ok((run.summary, start.elapsed().as_secs_f64()))
}

/// Runs of the two precisions alternate, so a change of the machine's load hits both.
fn per_step(mesh: &FlowMesh, settings: &CaseSettings, o: &Options) -> Result<(), Box<dyn std::error::Error>> {
    let total_steps = (settings.cycles as f64 * settings.inflow.period_s() / settings.dt_s).round();
    let mut per_step_s = vec![Vec::new(); o.precisions.len()];
    let mut cases = Vec::new();
    for &mixed in &o.precisions {
        let mut s = window(settings, o.t0_s, o.steps);
        s.mixed_precision = mixed;
        s.coarse_aggregate_nodes = o.coarse;
        s.gmres_restart = o.restart.unwrap_or(s.gmres_restart);
        s.preconditioner_max_age = o.reuse.unwrap_or(s.preconditioner_max_age);
        if let Some(k) = o.picard {
            s.nonlinear_iterations = Some(NonlinearIterations::Fixed(k));
        }
        cases.push(s);
    }
    for k in 0..o.runs {
        for (case, times) in cases.iter().zip(&mut per_step_s) {
            let cpu_before = process_cpu_s();
            let (summary, _) = run_window(mesh, case, o.steps)?;
            let cpu_step_s = (process_cpu_s() - cpu_before) / summary.steps.len() as f64;
            let t = &summary.timings;
            let n = summary.steps.len() as f64;
            let gmres: usize = summary.steps.iter().map(|r| r.linear_iterations).sum();
            if std::env::var_os("BENCH_VERBOSE").is_some() {
                println!("    GMRES it per step: {:?}", summary.steps.iter().map(|r| r.linear_iterations).collect::<Vec<_>>());
            }
            let step_s = (t.total_s - t.setup_s) / n;
            println!(
                "  run {k} ({}, coarse aggregates of {} nodes, GMRES({}), preconditioner kept <= {} solves): {step_s:.3} s/step, CPU {cpu_step_s:.3} s/step incl. setup (assembly {:.3}, ILU {:.3}, GMRES {:.3} s/step; {:.1} GMRES it/step, {:.1} ms per GMRES iteration, {} factorizations), last dp(11-16) {:.4} mmHg, vmax {:.2} cm/s, load {}",
                if case.mixed_precision { "mixed" } else { "f64" },
                case.coarse_aggregate_nodes,
                case.gmres_restart,
                case.preconditioner_max_age,
                t.assembly_s / n,
                t.preconditioner_s / n,
                t.gmres_s / n,
                gmres as f64 / n,
                1e3 * t.gmres_s / gmres.max(1) as f64,
                t.factorizations,
                dp_mmhg(&summary, summary.steps.len() - 1),
                summary.steps.last().map_or(f64::NAN, |r| r.max_velocity_cm_s),
                load_average()
            );
            times.push(step_s);
        }
    }
    for (case, times) in cases.iter().zip(per_step_s) {
        let m = median(times.clone());
        println!(
            "transient ({} precision, at most {} nonlinear iterations): median {m:.3} s per step over {} runs of {} steps (min {:.3}, max {:.3}); 4 cycles = {total_steps} steps ~ {:.1} min",
            if case.mixed_precision { "mixed f32/f64" } else { "f64" },
            case.nonlinear().max_iterations(),
            o.runs,
            o.steps,
            times.iter().cloned().fold(f64::INFINITY, f64::min),
            times.iter().cloned().fold(0.0, f64::max),
            m * total_steps / 60.0
        );
    }
    Ok(())
}

fn steady(mesh: &FlowMesh, settings: &CaseSettings, o: &Options) -> Result<(), Box<dyn std::error::Error>> {
    let mut s = settings.clone();
    s.mode = RunMode::Steady;
    s.gmres_restart = o.restart.unwrap_or(s.gmres_restart);
    let mut walls = Vec::new();
    for k in 0..o.runs {
        let cpu_before = process_cpu_s();
        let (summary, wall) = run(mesh, &s)?;
        let cpu = process_cpu_s() - cpu_before;
        let r = &summary.steps[0];
        println!(
            "  run {k} (GMRES({})): {wall:.1} s (CPU {cpu:.1} s), converged {}, {} iterations, {} GMRES, dp(11-16) {:.3} mmHg, vmax {:.1} cm/s, load {}",
            s.gmres_restart,
            summary.converged,
            r.nonlinear_iterations,
            r.linear_iterations,
            dp_mmhg(&summary, 0),
            r.max_velocity_cm_s,
            load_average()
        );
        walls.push(wall);
    }
    println!("steady estimate: median {:.1} s over {} runs", median(walls), o.runs);
    Ok(())
}

fn full(mesh: &FlowMesh, settings: &CaseSettings) -> Result<(), Box<dyn std::error::Error>> {
    let start = Instant::now();
    let mut last_report = Instant::now();
    let summary = simulate(mesh, settings, &mut |f, msg| {
        if last_report.elapsed().as_secs() >= 60 {
            println!("  {:.0}% after {:.0} s: {msg} (load {})", 100.0 * f, start.elapsed().as_secs_f64(), load_average());
            last_report = Instant::now();
        }
        true
    })?;
    let wall = start.elapsed().as_secs_f64();
    let period_steps = (settings.inflow.period_s() / settings.dt_s).round() as usize;
    let last_cycle = summary.steps.len() - period_steps..summary.steps.len();
    let peak = last_cycle.clone().max_by(|&a, &b| summary.steps[a].inflow_ml_s.total_cmp(&summary.steps[b].inflow_ml_s)).unwrap_or(0);
    let dp: Vec<f64> = (0..summary.steps.len()).map(|k| dp_mmhg(&summary, k)).collect();
    let nrmsd = periodicity_nrmsd(&dp, period_steps).unwrap_or(f64::NAN);
    let gmres: usize = summary.steps.iter().map(|r| r.linear_iterations).sum();
    println!(
        "full 4-cycle run: {} steps in {:.1} min ({:.3} s/step, {:.1} GMRES it/step); peak flow {:.1} mL/s at t = {:.3} s: dp(11-16) {:.3} mmHg, vmax {:.1} cm/s; periodicity NRMSD cycle 3 vs 4 {:.2e}",
        summary.steps.len(),
        wall / 60.0,
        wall / summary.steps.len() as f64,
        gmres as f64 / summary.steps.len() as f64,
        summary.steps[peak].inflow_ml_s,
        summary.steps[peak].time_s,
        dp[peak],
        summary.steps[peak].max_velocity_cm_s,
        nrmsd
    );
    Ok(())
}

fn compare_schemes(mesh: &FlowMesh, settings: &CaseSettings, o: &Options) -> Result<(), Box<dyn std::error::Error>> {
    let mut semi = window(settings, o.t0_s, o.steps);
    semi.nonlinear_iterations = Some(NonlinearIterations::Fixed(1));
    let mut picard = semi.clone();
    picard.nonlinear_iterations = Some(NonlinearIterations::Fixed(5));
    picard.nonlinear_tolerance = 1e-3;
    let (a, wall_a) = run_window(mesh, &semi, o.steps)?;
    let (b, wall_b) = run_window(mesh, &picard, o.steps)?;
    let mut worst_dp = 0.0f64;
    let mut worst_v = 0.0f64;
    for k in 0..a.steps.len() {
        let (dpa, dpb) = (dp_mmhg(&a, k), dp_mmhg(&b, k));
        let (va, vb) = (a.steps[k].max_velocity_cm_s, b.steps[k].max_velocity_cm_s);
        // The first steps after the impulsive start are dominated by the start itself.
        if k >= o.steps / 2 {
            worst_dp = worst_dp.max((dpa - dpb).abs() / dpb.abs());
            worst_v = worst_v.max((va - vb).abs() / vb);
        }
        if k % 5 == 4 || k + 1 == a.steps.len() {
            println!(
                "  step {:3} t={:.3} Q={:.1}: dp semi-implicit {dpa:.4} / Picard {dpb:.4} mmHg ({} iterations), vmax {va:.1} / {vb:.1} cm/s",
                a.steps[k].step, a.steps[k].time_s, a.steps[k].inflow_ml_s, b.steps[k].nonlinear_iterations
            );
        }
    }
    println!(
        "schemes over {} steps from rest at t = {} s: semi-implicit {wall_a:.0} s, Picard {wall_b:.0} s; second half: max |d dp| / dp {:.2}%, max |d vmax| / vmax {:.2}%",
        o.steps,
        o.t0_s,
        100.0 * worst_dp,
        100.0 * worst_v
    );
    Ok(())
}

/// The case with a scheme by name: `be` (backward Euler, one solve a step), `ga`
/// (generalized-alpha, rho_inf 0.5, the auto Picard loop), `ga1` (generalized-alpha,
/// one solve a step), `be-auto` (backward Euler with the auto loop).
fn with_scheme(settings: &CaseSettings, scheme: &str) -> Result<CaseSettings, String> {
    let mut s = settings.clone();
    let ga = TimeIntegration::GeneralizedAlpha { rho_inf: DEFAULT_RHO_INF };
    (s.time_integration, s.nonlinear_iterations) = match scheme {
        "be" => (TimeIntegration::BackwardEuler, None),
        "be-auto" => (TimeIntegration::BackwardEuler, Some(NonlinearIterations::Auto { cap: AUTO_NONLINEAR_CAP })),
        "ga" => (ga, None),
        "ga1" => (ga, Some(NonlinearIterations::Fixed(1))),
        other => return Err(format!("--time-accuracy takes be, be-auto, ga or ga1, not {other}")),
    };
    Ok(s)
}

/// From rest to `t_end_s` (p2's first flow peak: 0.164 s) with each scheme at each
/// dt: dp(11-16) and v_max at t_end, and the cost (steps, linear solves, GMRES
/// iterations, factorizations, CPU s), one line a run as it ends.
fn time_accuracy(mesh: &FlowMesh, settings: &CaseSettings, schemes: &[String], dts_ms: &[f64], t_end_s: f64) -> Result<(), Box<dyn std::error::Error>> {
    for name in schemes {
        for &dt_ms in dts_ms {
            let mut s = with_scheme(settings, name)?;
            s.dt_s = dt_ms * 1e-3;
            let steps = (t_end_s / s.dt_s).round() as usize;
            let cpu_before = process_cpu_s();
            let (summary, wall) = run_window(mesh, &s, steps)?;
            let cpu = process_cpu_s() - cpu_before;
            let last = summary.steps.last().ok_or("no step")?;
            let solves: usize = summary.steps.iter().map(|r| r.nonlinear_iterations).sum();
            let gmres: usize = summary.steps.iter().map(|r| r.linear_iterations).sum();
            let unconverged = summary.steps.iter().filter(|r| !r.nonlinear_converged).count();
            println!(
                "time-accuracy {name} dt {dt_ms} ms: t = {:.4} s dp(11-16) {:.4} mmHg vmax {:.2} cm/s; {} steps, {solves} linear solves ({:.2} a step), {gmres} GMRES it ({:.1} a step), {} factorizations, {unconverged} unconverged steps, CPU {cpu:.1} s, wall {wall:.1} s, load {}",
                last.time_s,
                dp_mmhg(&summary, summary.steps.len() - 1),
                last.max_velocity_cm_s,
                summary.steps.len(),
                solves as f64 / summary.steps.len() as f64,
                gmres as f64 / summary.steps.len() as f64,
                summary.timings.factorizations,
                load_average()
            );
            if std::env::var_os("BENCH_VERBOSE").is_some() {
                let series: Vec<String> = summary.steps.iter().map(|r| format!("{:.4}:{:.4}:{}", r.time_s, dp_mmhg(&summary, r.step - 1), r.nonlinear_iterations)).collect();
                println!("    t:dp:solves {}", series.join(" "));
            }
        }
    }
    Ok(())
}

/// A few steps and a steady solve on a small tube: the bench's code paths, in seconds.
fn smoke() -> Result<(), Box<dyn std::error::Error>> {
    let mesh = tube(0.25, 2.0, 3, 10, &[]);
    let outlets = vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 4000.0 }];
    let settings = CaseSettings::new(INLET, Waveform::Ejection { period_s: 0.02, q_mean_ml_s: 1.0 }, outlets);
    let (summary, wall) = run_window(&mesh, &window(&settings, 0.004, 5), 5)?;
    let mut steady = settings.clone();
    steady.mode = RunMode::Steady;
    let (steady_summary, steady_wall) = run(&mesh, &steady)?;
    let finite = summary.steps.iter().chain(&steady_summary.steps).all(|r| r.faces.iter().all(|f| f.mean_pressure_dyn_cm2.is_finite()));
    if !finite || !steady_summary.converged {
        return Err("smoke run gave a non-finite pressure or an unconverged steady solve".into());
    }
    println!("smoke: {} steps in {wall:.3} s, steady in {steady_wall:.3} s; peak memory {:.0} MB", summary.steps.len(), peak_memory_mb());
    Ok(())
}

/// Per-step cost against mesh size on one geometry: a tube refined in all directions
/// by about 1.6x per level (rings 6/10/15, layers 2.5x rings).
fn scaling(o: &Options) -> Result<(), Box<dyn std::error::Error>> {
    let outlets = vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 4000.0 }];
    // Q_mean 20 mL/s: Q_peak 65 mL/s, mean speed 1.3 m/s in the 8 mm tube, Re ~2,700.
    let settings = CaseSettings::new(INLET, Waveform::default_for_mean(20.0)?, outlets);
    let sizes = [(6, 15), (10, 25), (15, 37), (24, 60)];
    for &(rings, layers) in sizes[..if o.big { 4 } else { 3 }].iter().skip(o.from_size) {
        let mesh = tube(0.4, 4.0, rings, layers, &[]);
        let mut case = window(&settings, o.t0_s, o.steps);
        case.coarse_aggregate_nodes = o.coarse;
        case.gmres_restart = o.restart.unwrap_or(case.gmres_restart);
        case.preconditioner_max_age = o.reuse.unwrap_or(case.preconditioner_max_age);
        let (mut step_s, mut cpu_step_s, mut iterations) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..o.runs {
            let cpu_before = process_cpu_s();
            let (summary, _) = run_window(&mesh, &case, o.steps)?;
            let cpu_s = process_cpu_s() - cpu_before;
            let t = &summary.timings;
            let n = summary.steps.len() as f64;
            step_s.push((t.total_s - t.setup_s) / n);
            // CPU time of the whole run (setup included) per step: what a loaded machine
            // still measures (wall time then depends on the other jobs).
            cpu_step_s.push(cpu_s / n);
            iterations.push(summary.steps.iter().map(|r| r.linear_iterations).sum::<usize>() as f64 / n);
            println!(
                "  {} tets: {:.3} s/step (CPU {:.3} s/step incl. setup): assembly {:.3}, preconditioner setup {:.3} (coarse {:.3}), GMRES {:.3}; setup {:.2} s; load {}",
                mesh.tets.len(),
                step_s.last().unwrap(),
                cpu_step_s.last().unwrap(),
                t.assembly_s / n,
                t.preconditioner_s / n,
                t.coarse_setup_s / n,
                t.gmres_s / n,
                t.setup_s,
                load_average()
            );
        }
        println!(
            "tube {} tets ({} nodes), coarse aggregates of {} nodes, GMRES({}): median {:.3} s/step (min {:.3}; CPU {:.3} s/step), {:.1} GMRES it/step, over {} runs of {} steps from t = {} s; load {}",
            mesh.tets.len(),
            mesh.points_cm.len(),
            o.coarse,
            case.gmres_restart,
            median(step_s.clone()),
            step_s.iter().cloned().fold(f64::INFINITY, f64::min),
            median(cpu_step_s),
            median(iterations),
            o.runs,
            o.steps,
            o.t0_s,
            load_average()
        );
    }
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let o = options()?;
    if o.smoke {
        return smoke();
    }
    if o.scaling {
        scaling(&o)?;
        println!("peak memory {:.0} MB", peak_memory_mb());
        return Ok(());
    }
    let start = Instant::now();
    let (mesh, settings) = p2_case()?;
    println!(
        "p2: {} nodes, {} tets read in {:.2} s; {} threads; load {}",
        mesh.points_cm.len(),
        mesh.tets.len(),
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
        load_average()
    );
    if o.full {
        full(&mesh, &settings)?;
    } else if let Some((schemes, dts_ms, t_end_s)) = &o.time_accuracy {
        time_accuracy(&mesh, &settings, schemes, dts_ms, *t_end_s)?;
    } else if o.compare_schemes {
        compare_schemes(&mesh, &settings, &o)?;
    } else if o.steady {
        steady(&mesh, &settings, &o)?;
    } else {
        per_step(&mesh, &settings, &o)?;
    }
    println!("peak memory {:.0} MB", peak_memory_mb());
    Ok(())
}
