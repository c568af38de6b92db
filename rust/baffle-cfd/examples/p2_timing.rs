//! Timing of the solver on patient p2's published mesh (147k tets):
//! `cargo run --release -p baffle-cfd --example p2_timing -- [steps] [steady_iterations]`.
//! Reads BAFFLE_DATA_DIR (default ../shared/data). Prints time per time step, per
//! Picard iteration, GMRES iterations and the peak resident memory.

use std::path::PathBuf;
use std::time::Instant;

use baffle_cfd::hemodynamics::{hemodynamics, ClinicalInputs, CARDIAC_INDEX_DEFAULT_L_MIN_M2};
use baffle_cfd::vtu::read_simvascular_mesh;
use baffle_cfd::{simulate, CaseSettings, Outlet, RunMode, Summary, Waveform};

fn peak_memory_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|kb| kb.parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn report(label: &str, s: &Summary) {
    let picard: usize = s.steps.iter().map(|r| r.nonlinear_iterations).sum();
    let gmres: usize = s.steps.iter().map(|r| r.linear_iterations).sum();
    let t = &s.timings;
    println!(
        "{label}: {} steps, {picard} Picard iterations, {gmres} GMRES iterations; total {:.1} s (setup {:.2}, assembly {:.2}, ILU {:.2}, GMRES {:.2}); {:.3} s per Picard iteration",
        s.steps.len(),
        t.total_s,
        t.setup_s,
        t.assembly_s,
        t.preconditioner_s,
        t.gmres_s,
        (t.total_s - t.setup_s) / picard.max(1) as f64
    );
    let last = s.steps.last().expect("at least one step");
    let dp = last.face(11).map_or(f64::NAN, |f| f.mean_pressure_dyn_cm2) - last.face(16).map_or(f64::NAN, |f| f.mean_pressure_dyn_cm2);
    println!(
        "  last step t={:.3} s: Q_in {:.2} Q_out {:.2} mL/s, dp(11-16) {:.3} mmHg, vmax {:.1} cm/s, residual {:.1e}",
        last.time_s,
        last.inflow_ml_s,
        last.outflow_ml_s,
        dp / 1333.22,
        last.max_velocity_cm_s,
        last.residual
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<usize> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let steps = args.first().copied().unwrap_or(10);
    let steady_iterations = args.get(1).copied().unwrap_or(0);
    let dir = std::env::var_os("BAFFLE_DATA_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data")));
    let start = Instant::now();
    let mesh = read_simvascular_mesh(&dir.join("p2/published_M_final.vtu"), &dir.join("p2/published_M_final.vtp"))?;
    println!("read p2: {} nodes, {} tets in {:.2} s; threads {}", mesh.points_cm.len(), mesh.tets.len(), start.elapsed().as_secs_f64(), rayon::current_num_threads());
    let h = hemodynamics(&ClinicalInputs { bsa_m2: 0.37, sbp_mmhg: 107.0, dbp_mmhg: 78.0, cardiac_index_l_min_m2: CARDIAC_INDEX_DEFAULT_L_MIN_M2 })?;
    let outlets = vec![Outlet { face_id: 16, resistance_dyn_s_cm5: h.resistance_dyn_s_cm5 }];
    let mut settings = CaseSettings::new(11, Waveform::default_for_mean(h.q_mean_ml_s)?, outlets);
    if steps > 0 {
        // Start the run at the steepest part of systole by shifting the waveform: t0 = 0.1 s.
        let shifted = Waveform::Table {
            times_s: (0..682).map(|i| i as f64 * 1e-3).collect(),
            flows_ml_s: (0..682).map(|i| settings.inflow.flow_ml_s(0.1 + i as f64 * 1e-3)).collect(),
            period_s: 0.682,
        };
        let mut s = settings.clone();
        s.inflow = shifted;
        s.cycles = 1;
        let mut n = 0;
        let mut last = Instant::now();
        let summary = simulate(&mesh, &s, &mut |_, msg| {
            n += 1;
            println!("  {msg} ({:.2} s)", last.elapsed().as_secs_f64());
            last = Instant::now();
            n < steps
        });
        match summary {
            Err(baffle_cfd::CfdError::Cancelled { .. }) => println!("transient: stopped after {steps} steps (see per-step lines)"),
            Err(e) => println!("transient failed: {e}"),
            Ok(s) => report("transient", &s),
        }
        println!("peak memory so far {:.0} MB", peak_memory_mb());
    }
    if steady_iterations > 0 {
        settings.mode = RunMode::Steady;
        settings.steady_max_iterations = steady_iterations;
        // Optional overrides for experiments: BAFFLE_CFD_NEWTON_BELOW, BAFFLE_CFD_PSEUDO_DT.
        let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<f64>().ok());
        if let Some(v) = env("BAFFLE_CFD_NEWTON_BELOW") {
            settings.steady_newton_below = v;
        }
        if let Some(v) = env("BAFFLE_CFD_PSEUDO_DT") {
            settings.steady_pseudo_dt_s = v;
        }
        let summary = simulate(&mesh, &settings, &mut |_, msg| {
            println!("  {msg}");
            true
        })?;
        report("steady", &summary);
        println!("  converged: {}", summary.converged);
    }
    println!("peak memory {:.0} MB", peak_memory_mb());
    Ok(())
}
