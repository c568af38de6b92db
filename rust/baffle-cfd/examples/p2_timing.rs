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
    let dir = baffle_core::reference_data::reference_data_dir();
    let start = Instant::now();
    let mesh = read_simvascular_mesh(&dir.join("p2/published_M_final.vtu"), &dir.join("p2/published_M_final.vtp"))?;
    println!("read p2: {} nodes, {} tets in {:.2} s; threads {}", mesh.points_cm.len(), mesh.tets.len(), start.elapsed().as_secs_f64(), rayon::current_num_threads());
    // Caps: area, equivalent diameter, mean velocity at Q_peak and its dynamic pressure.
    let q_peak = Waveform::default_for_mean(21.5)?.peak().0;
    for id in [11, 16] {
        let face = mesh.face(id).ok_or("missing cap")?;
        let area = baffle_cfd::boundary::face_area_cm2(&mesh, face);
        let v = q_peak / area;
        println!(
            "cap {id}: area {area:.4} cm2 (equivalent diameter {:.3} cm), mean velocity at {q_peak:.1} mL/s {v:.1} cm/s, 0.5 rho v^2 = {:.3} mmHg",
            (4.0 * area / std::f64::consts::PI).sqrt(),
            0.5 * 1.06 * v * v / 1333.22
        );
    }
    let h = hemodynamics(&ClinicalInputs { bsa_m2: 0.37, sbp_mmhg: 107.0, dbp_mmhg: 78.0, cardiac_index_l_min_m2: CARDIAC_INDEX_DEFAULT_L_MIN_M2 })?;
    let outlets = vec![Outlet { face_id: 16, resistance_dyn_s_cm5: h.resistance_dyn_s_cm5 }];
    let mut settings = CaseSettings::new(11, Waveform::default_for_mean(h.q_mean_ml_s)?, outlets);
    if steps > 0 {
        // Start the run at the steepest part of systole by shifting the waveform: t0 = 0.1 s.
        // The run is one "cycle" of `steps` steps of the shifted waveform, so that it
        // ends normally and reports its timing breakdown.
        let shifted = Waveform::Table {
            times_s: (0..=steps).map(|i| i as f64 * 1e-3).collect(),
            flows_ml_s: (0..=steps).map(|i| settings.inflow.flow_ml_s(0.1 + i as f64 * 1e-3)).collect(),
            period_s: steps as f64 * 1e-3 + 1e-3,
        };
        let mut s = settings.clone();
        s.inflow = shifted;
        s.cycles = 1;
        if let Some(k) = std::env::var("BAFFLE_CFD_PICARD").ok().and_then(|v| v.parse().ok()) {
            s.max_nonlinear_iterations = k;
        }
        println!("transient: at most {} nonlinear iterations per step", s.max_nonlinear_iterations);
        let mut last = Instant::now();
        let summary = simulate(&mesh, &s, &mut |_, msg| {
            println!("  {msg} ({:.2} s)", last.elapsed().as_secs_f64());
            last = Instant::now();
            true
        });
        match summary {
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
        if std::env::var("BAFFLE_CFD_PROFILE").is_ok_and(|v| v == "poiseuille") {
            settings.inflow_profile = baffle_cfd::InflowProfile::Poiseuille;
        }
        println!("steady: inflow profile {:?}", settings.inflow_profile);
        if let Some(v) = env("BAFFLE_CFD_PSEUDO_DT") {
            settings.steady_pseudo_dt_s = v;
        }
        let summary = simulate(&mesh, &settings, &mut |_, msg| {
            println!("  {msg}");
            true
        })?;
        report("steady", &summary);
        // Where the fastest node is, relative to the caps' centroids.
        let speed = |v: &[f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let (imax, vmax) = summary.velocity_cm_s.iter().map(speed).enumerate().fold((0, 0.0), |m, (i, v)| if v > m.1 { (i, v) } else { m });
        let at = mesh.points_cm[imax];
        for id in [11, 16] {
            let face = mesh.face(id).ok_or("missing cap")?;
            let nodes: Vec<[f64; 3]> = face.triangles.iter().flatten().map(|&i| mesh.points_cm[i as usize]).collect();
            let c = [0, 1, 2].map(|k| nodes.iter().map(|p| p[k]).sum::<f64>() / nodes.len() as f64);
            let d = ((at[0] - c[0]).powi(2) + (at[1] - c[1]).powi(2) + (at[2] - c[2]).powi(2)).sqrt();
            println!("  vmax {vmax:.1} cm/s at node {imax} {at:?}: {d:.3} cm from the centroid of cap {id}");
        }
        let fast = summary.velocity_cm_s.iter().filter(|v| speed(v) > 150.0).count();
        println!("  nodes faster than 150 cm/s: {fast} of {}", summary.velocity_cm_s.len());
        println!("  converged: {}", summary.converged);
        if let Some(path) = std::env::var_os("BAFFLE_CFD_VTU") {
            let path = PathBuf::from(path);
            baffle_cfd::vtu::write_solution_vtu(&path, &mesh.points_cm, &mesh.tets, &summary.velocity_cm_s, &summary.pressure_dyn_cm2)?;
            println!("  wrote {}", path.display());
        }
    }
    println!("peak memory {:.0} MB", peak_memory_mb());
    Ok(())
}
