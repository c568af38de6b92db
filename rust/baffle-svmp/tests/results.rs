//! Recorded svMultiPhysics outputs (small files in its documented layouts) read back into
//! the summary.

mod common;

use std::path::{Path, PathBuf};

use baffle_svmp::{export_case, read_results};
use common::*;

const MMHG: f64 = 1333.22;
/// Column order of the recorded files: not the Add_face order, to test the mapping.
const COLUMNS: [&str; 6] = ["plane_2", "inflow", "wall_a", "outflow", "plane_1", "wall_b"];

/// One cycle at dt = 10 ms (68 steps, peak at step 16) exported to a fresh directory.
fn exported(name: &str) -> (PathBuf, baffle_cfd::CaseSettings) {
    let dir = scratch(name);
    let mut settings = settings();
    settings.cycles = 1;
    settings.dt_s = 0.01;
    let case = export_case(&dir, &box_mesh(), &settings, &options()).unwrap();
    assert_eq!((case.manifest.n_time_steps, case.manifest.peak_step), (68, 16));
    std::fs::create_dir_all(dir.join("results")).unwrap();
    (dir, settings)
}

/// Face values at time t: inflow Q(t) through the inlet (negative outward flux) and out
/// of the outlet, +Q through the planes; plane_1 is 5 mmHg above plane_2.
fn recorded_values(q_ml_s: f64, t: f64) -> ([f64; 6], [f64; 6]) {
    let pressure = [MMHG * t, 7.0, 8.0, 9.0, MMHG * (5.0 + t), 10.0];
    let flux = [q_ml_s, -q_ml_s, 0.0, q_ml_s, q_ml_s, 0.0];
    (pressure, flux)
}

/// The recorded `B_NS_*` files of `steps` steps, columns in [`COLUMNS`] order.
fn write_current_layout(results: &Path, settings: &baffle_cfd::CaseSettings, steps: usize) {
    write_boundary_files(results, &COLUMNS, settings.dt_s, steps, |t| {
        let (p, q) = recorded_values(settings.inflow.flow_ml_s(t), t);
        (p.to_vec(), q.to_vec())
    });
}

/// results/histor.dat as svMultiPhysics writes it (output.cpp): three Newton iterations a
/// step, the last below the 1e-3 tolerance, except `unconverged` steps, whose last iterate
/// stays above it after a linear solve marked unconverged.
fn write_step_log(results: &Path, steps: usize, unconverged: &[usize]) {
    let mut text = String::from(" Eq     N-i     T       dB  Ri/R1   Ri/R0    R/Ri     lsIt   dB  %t\n");
    for k in 1..=steps {
        text += &format!(" NS {k}-1  1.000e+00  [0 1.000e+00 1.000e+00 2.700e-05]  [3 -17 80]\n");
        text += &format!(" NS {k}-2  2.000e+00  [-57 1.300e-03 1.700e-01 2.000e-05]  [5 -17 90]\n");
        text += &if unconverged.contains(&k) {
            format!(" NS {k}-3  3.000e+00  [-40 1.000e-02 2.000e-01 3.000e-01]  !10 -10 95!  WARNING: The linear system solution has not converged\n")
        } else {
            format!(" NS {k}-3  3.000e+00  [-94 1.900e-05 2.500e-03 6.800e-05]  [4 -17 91]\n")
        };
    }
    std::fs::write(results.join("histor.dat"), text).unwrap();
}

#[test]
fn the_step_log_says_which_steps_missed_the_newton_tolerance_or_a_linear_one() {
    let (dir, settings) = exported("results-convergence");
    write_current_layout(&dir.join("results"), &settings, 68);
    write_step_log(&dir.join("results"), 68, &[]);
    let summary = read_results(&dir).unwrap();
    assert_eq!(summary.converged, Some(true), "{:?}", summary.warnings);
    let c = summary.steps[40].convergence.unwrap();
    assert_eq!((c.newton_iterations, c.nonlinear_converged, c.linear_converged, c.final_step_relative_residual), (3, true, true, 1.9e-5));
    write_step_log(&dir.join("results"), 67, &[30, 31]);
    let summary = read_results(&dir).unwrap();
    assert_eq!(summary.converged, Some(false));
    assert!(!summary.steps[29].convergence.unwrap().nonlinear_converged && summary.steps[32].convergence.unwrap().nonlinear_converged);
    let w = summary.warnings.join("\n");
    assert!(w.contains("2 of 68 time steps stopped at Max_iterations above the Newton tolerance 1e-3 (steps 30, 31;"), "{w}");
    assert!(w.contains("2 of 68 time steps had a linear solve that did not reach its tolerance"), "{w}");
    assert!(w.contains("1 of 68 time steps have no iteration line"), "{w}");
}

#[test]
fn current_layout_gives_series_peak_pressure_drop_and_flows() {
    let (dir, settings) = exported("results-current");
    write_current_layout(&dir.join("results"), &settings, 68);
    write_step_log(&dir.join("results"), 68, &[]);
    std::fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/result_016.vtu"), dir.join("results/result_016.vtu")).unwrap();
    let summary = read_results(&dir).unwrap();

    assert_eq!(summary.steps.len(), 68);
    let s = &summary.steps[15];
    assert_eq!((s.step, s.time_s), (16, 0.16));
    let q16 = settings.inflow.flow_ml_s(0.16);
    assert!((s.inflow_ml_s - q16).abs() < 1e-8 && (s.outflow_ml_s - q16).abs() < 1e-8, "{s:?}");
    let plane_1 = s.faces.iter().find(|f| f.id == PLANE_1).unwrap();
    assert_eq!(plane_1.name, "plane_1");
    assert!((plane_1.mean_pressure_dyn_cm2 - MMHG * 5.16).abs() < 1e-6);
    assert!((plane_1.flow_ml_s - q16).abs() < 1e-8);
    let wall_b = s.faces.iter().find(|f| f.id == WALL_B).unwrap();
    assert_eq!(wall_b.mean_pressure_dyn_cm2, 10.0);

    assert_eq!((summary.peak_step, summary.peak_time_s), (16, 0.16));
    assert!((summary.dp_peak_mmhg.unwrap() - 5.0).abs() < 1e-9, "{:?}", summary.dp_peak_mmhg);
    let flows: Vec<f64> = (1..=68).map(|k| settings.inflow.flow_ml_s(k as f64 * 0.01)).collect();
    let mean = flows.iter().sum::<f64>() / 68.0;
    let peak = flows.iter().copied().fold(0.0, f64::max);
    assert!((summary.q_mean_ml_s - mean).abs() < 1e-8, "{} vs {mean}", summary.q_mean_ml_s);
    assert!((summary.q_peak_ml_s - peak).abs() < 1e-8, "{} vs {peak}", summary.q_peak_ml_s);
    // One cycle of ~21 mL/s mean, sampled every 10 ms.
    assert!((summary.q_mean_ml_s - 21.46).abs() < 0.3, "{}", summary.q_mean_ml_s);

    // The peak fields, written by VTK's default XML writer (appended, zlib), put back in
    // volume-node order through GlobalNodeID (see tests/data/make_result_vtu.py).
    let fields = summary.peak_fields.as_ref().expect("peak fields");
    assert_eq!(fields.step, 16);
    for k in 0..5 {
        let kf = k as f64;
        assert_eq!(fields.velocity_cm_s[k], [kf, 10.0 * kf, 100.0 * kf], "node {k}");
        assert_eq!(fields.pressure_dyn_cm2[k], 1000.0 * kf, "node {k}");
    }
    assert!(summary.warnings.is_empty(), "{:?}", summary.warnings);

    let json = serde_json::to_value(&summary).unwrap();
    assert_eq!(json["engine"], "svMultiPhysics");
    assert_eq!(json["steps"][15]["faces"][4]["name"], "plane_1");
    assert!(json.get("peak_fields").is_none() && json["peak_fields_file"].is_string());
}

#[test]
fn legacy_layout_takes_steps_from_rows_and_a_missing_result_is_a_warning() {
    let (dir, settings) = exported("results-legacy");
    for (file, which) in [("B_NS_Pressure_average.txt", 0), ("B_NS_Velocity_flux.txt", 1)] {
        let mut text = COLUMNS.iter().map(|c| format!(" {c} ")).collect::<String>() + "\n";
        for step in 1..=20 {
            let t = step as f64 * settings.dt_s;
            let (p, q) = recorded_values(settings.inflow.flow_ml_s(t), t);
            let values = if which == 0 { p } else { q };
            text += &values.iter().map(|v| format!(" {v:.10e} ")).collect::<String>();
            text.push('\n');
        }
        std::fs::write(dir.join("results").join(file), text).unwrap();
    }
    let summary = read_results(&dir).unwrap();
    assert_eq!(summary.steps.len(), 20);
    assert_eq!(summary.steps[19].step, 20);
    assert!((summary.steps[19].time_s - 0.2).abs() < 1e-15);
    assert_eq!(summary.peak_step, 16);
    assert!((summary.dp_peak_mmhg.unwrap() - 5.0).abs() < 1e-9);
    assert!(summary.peak_fields.is_none());
    assert!(summary.warnings.iter().any(|w| w.contains("no result_*.vtu for step 16")), "{:?}", summary.warnings);
    // No step log to read the engine's convergence from: unknown, and said so.
    assert_eq!(summary.converged, None);
    assert!(summary.warnings.iter().any(|w| w.contains("no step log (histor.dat")), "{:?}", summary.warnings);
}

#[test]
fn missing_face_column_and_missing_files_are_named() {
    let (dir, settings) = exported("results-bad");
    let e = read_results(&dir).unwrap_err().to_string();
    assert!(e.contains("B_NS_Pressure_average.txt"), "{e}");

    write_current_layout(&dir.join("results"), &settings, 3);
    let path = dir.join("results/B_NS_Velocity_flux.txt");
    let text = std::fs::read_to_string(&path).unwrap().replace(" plane_1 ", " other ");
    std::fs::write(&path, text).unwrap();
    let e = read_results(&dir).unwrap_err().to_string();
    assert!(e.contains("B_NS_Velocity_flux.txt") && e.contains("no column for face 'plane_1'"), "{e}");
}
