//! `baffle simulate --engine svmultiphysics` end to end with the stand-in engine of
//! baffle-svmp's tests (the real solver is not installed in CI): the case exported, run
//! through mpiexec, and recorded svMultiPhysics outputs read back into summary.json and
//! timeseries.csv with the embedded engine's columns and keys; a missing engine, a
//! failing one, and SIGTERM.
#![cfg(unix)]

#[path = "../../baffle-svmp/tests/common/mod.rs"]
mod common;
mod support;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use baffle_cfd::hemodynamics::DYN_CM2_PER_MMHG;
use baffle_cfd::Waveform;
use baffle_core::io::DataArray;
use baffle_mesh::{write_faces_vtp, write_vtu, TetMesh};
use common::*;
use support::sigterm_after_progress_tags;

const Q_MEAN_ML_S: f64 = 21.46;
/// Recorded column order (not the mesh's face order, so the mapping is exercised).
const COLUMNS: [&str; 6] = ["plane_11", "inflow", "wall_1", "outlet_3", "plane_10", "wall_4"];
/// The embedded engine's columns for this case: faces in id order, named by role.
const CSV_HEADER: &str = "step,time_s,prescribed_inflow_ml_s,inflow_ml_s,outflow_ml_s,max_velocity_m_s,residual,\
                          p_wall_1_mmhg,p_inlet_2_mmhg,p_outlet_3_mmhg,p_wall_4_mmhg,p_plane1_10_mmhg,p_plane2_11_mmhg,\
                          q_wall_1_ml_s,q_inlet_2_ml_s,q_outlet_3_ml_s,q_wall_4_ml_s,q_plane1_10_ml_s,q_plane2_11_ml_s";
/// One 0.682 s cycle at 10 ms: 68 steps, results saved at the peak, step 16.
const STEPS: usize = 68;
const PEAK_STEP: usize = 16;

/// The recorded face values at time t in [`COLUMNS`] order: (pressure dyn/cm^2, flux mL/s).
fn recorded(t: f64) -> (Vec<f64>, Vec<f64>) {
    let q = 20.0 + 30.0 * (9.0 * t).sin();
    let pressure = [9000.0 + 100.0 * t, 10_000.0 + 2000.0 * t, 11_000.0, 9500.0 - 50.0 * t, 12_000.0 + 3000.0 * t, 11_000.0];
    (pressure.to_vec(), vec![q, -q, 0.0, 0.99 * q, q, 0.0])
}

fn column(name: &str) -> usize {
    COLUMNS.iter().position(|c| *c == name).unwrap()
}

/// Speed of node k (cm/s) in the recorded result_016.vtu.
fn speed_cm_s(k: usize) -> f64 {
    let v = node_velocity(k);
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn node_velocity(k: usize) -> [f64; 3] {
    let x = k as f64;
    [0.5 * x, -0.25 * x, 3.0 + (x * 0.7).cos()]
}

/// The box mesh as `baffle mesh` writes it, a case on it, and a directory of recorded
/// svMultiPhysics outputs of the transient run. Returns (case file, recorded dir).
fn box_case(name: &str) -> (PathBuf, PathBuf) {
    box_case_recorded(name, STEPS, PEAK_STEP)
}

/// As [`box_case`], outputs recorded for `steps` steps, results saved at `saved_step`.
fn box_case_recorded(name: &str, steps: usize, saved_step: usize) -> (PathBuf, PathBuf) {
    let dir = scratch(&format!("cli-{name}"));
    let mesh = box_mesh();
    write_vtu(&dir.join("mesh.vtu"), &mesh, &[], &[]).unwrap();
    write_faces_vtp(&dir.join("mesh-faces.vtp"), &mesh).unwrap();
    let case = dir.join("case.json");
    let text = format!(
        r#"{{
          "mesh": {{ "volume": "mesh.vtu", "units": "mm" }},
          "faces": {{ "inlet": {INLET}, "outlets": [{OUTLET}], "planes": [{PLANE_1}, {PLANE_2}] }},
          "inflow": {{ "q_mean_ml_s": {Q_MEAN_ML_S} }},
          "outlet": {{ "resistance_dyn_s_cm5": 5467 }},
          "time": {{ "dt_s": 0.01, "cycles": 1 }}
        }}"#
    );
    std::fs::write(&case, text).unwrap();
    let recorded_dir = dir.join("recorded");
    write_boundary_files(&recorded_dir, &COLUMNS, 0.01, steps, recorded);
    write_result(&recorded_dir.join(format!("result_{saved_step:03}.vtu")), &mesh);
    (case, recorded_dir)
}

/// A result file as svMultiPhysics writes it (cm, point GlobalNodeID, Velocity, Pressure).
fn write_result(path: &Path, mesh: &TetMesh) {
    let n = mesh.points_mm.len();
    let cm = TetMesh { points_mm: mesh.points_mm.iter().map(|p| p * 0.1).collect(), tets: mesh.tets.clone(), faces: Vec::new() };
    let velocity: Vec<f64> = (0..n).flat_map(node_velocity).collect();
    let point_data = [
        DataArray::i32("GlobalNodeID", (1..=n as i32).collect()),
        DataArray::f64("Velocity", 3, velocity),
        DataArray::f64("Pressure", 1, (0..n).map(|k| 100.0 * k as f64).collect()),
    ];
    write_vtu(path, &cm, &point_data, &[]).unwrap();
}

fn simulate(case: &Path, out: &Path, bin: &Path, extra: &[&str]) -> Output {
    simulate_command(case, out, bin, extra).output().unwrap()
}

fn simulate_command(case: &Path, out: &Path, bin: &Path, extra: &[&str]) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_baffle"));
    command
        .args(["simulate", case.to_str().unwrap(), "--out", out.to_str().unwrap(), "--engine", "svmultiphysics"])
        .args(extra)
        // Only the stand-ins and the shell tools their scripts use.
        .env("PATH", format!("{}:/usr/bin:/bin", bin.display()));
    command
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

fn csv(dir: &Path) -> (String, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(dir.join("timeseries.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse::<f64>().unwrap()).collect()).collect();
    (header, rows)
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn recorded_outputs_become_the_embedded_engines_summary_and_time_series() {
    let (case, recorded_dir) = box_case("run");
    let bin = standin_bin("cli-run-bin", &StandIn { recorded: Some(&recorded_dir), ..StandIn::default() });
    let out_dir = case.parent().unwrap().join("out");
    let out = simulate(&case, &out_dir, &bin, &["--mpi-processes", "2", "--progress-tags"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", stderr(&out));
    // Slicer's progress tags (asked for), from svMultiPhysics' step log.
    assert_eq!(stdout.matches("<filter-progress>").count(), STEPS + 4, "{stdout}");
    assert!(stdout.contains("<filter-progress>1.0000</filter-progress>"));
    let case_dir = out_dir.join("svmultiphysics");
    assert!(case_dir.join("solver.xml").is_file());
    let args = std::fs::read_to_string(case_dir.join("mpiexec.args")).unwrap();
    assert!(args.contains("-n 2 ") && args.ends_with("svMultiPhysics solver.xml\n"), "{args}");

    let (header, rows) = csv(&out_dir);
    assert_eq!(header, CSV_HEADER.split_whitespace().collect::<String>());
    assert_eq!(rows.len(), STEPS);
    let waveform = Waveform::Ejection { period_s: 0.682, q_mean_ml_s: Q_MEAN_ML_S };
    let faces_in_csv = ["wall_1", "inflow", "outlet_3", "wall_4", "plane_10", "plane_11"];
    let max_speed_m_s = (0..box_mesh().points_mm.len()).map(speed_cm_s).fold(0.0, f64::max) / 100.0;
    for (k, row) in rows.iter().enumerate() {
        let step = k + 1;
        let t = as_recorded(step as f64 * 0.01);
        let (p, q) = recorded(step as f64 * 0.01);
        let (p, q): (Vec<f64>, Vec<f64>) = (p.into_iter().map(as_recorded).collect(), q.into_iter().map(as_recorded).collect());
        assert_eq!(row[..5], [step as f64, t, waveform.flow_ml_s(t), -q[column("inflow")], q[column("outlet_3")]]);
        if step == PEAK_STEP {
            assert_eq!(row[5], max_speed_m_s);
        } else {
            assert!(row[5].is_nan(), "velocity is only known at the saved peak step");
        }
        assert!(row[6].is_nan(), "svMultiPhysics' residual is not read back");
        for (j, face) in faces_in_csv.iter().enumerate() {
            assert_eq!(row[7 + j], p[column(face)] / DYN_CM2_PER_MMHG, "step {step}, {face}");
            assert_eq!(row[13 + j], q[column(face)], "step {step}, {face}'s flux as svMultiPhysics recorded it");
        }
    }

    let s = summary(&out_dir);
    assert_eq!((s["engine"].as_str(), s["status"].as_str(), s["converged"].as_bool()), (Some("svmultiphysics"), Some("completed"), Some(true)));
    assert_eq!((s["steps_done"].as_u64(), s["last_step"].as_u64()), (Some(STEPS as u64), Some(STEPS as u64)));
    let peak = &rows[PEAK_STEP - 1];
    let number = |key: &str| s[key].as_f64().unwrap_or_else(|| panic!("{key}: {s}"));
    assert_eq!(number("peak_time_s"), peak[1]);
    assert_eq!(s["dp_faces"], serde_json::json!([PLANE_1, PLANE_2]));
    assert_eq!(number("dp_peak_mmhg"), peak[11] - peak[12]);
    // Each plane's flux at the peak and its share of the inflow, as the engine gave them.
    for (k, plane) in s["plane_flows_at_peak"].as_array().unwrap().iter().enumerate() {
        assert_eq!((plane["face"].as_i64(), plane["flow_ml_s"].as_f64()), (Some([PLANE_1, PLANE_2][k] as i64), Some(peak[17 + k])), "{plane}");
        assert_eq!(plane["fraction_of_inflow"].as_f64(), Some(peak[17 + k].abs() / peak[3]), "{plane}");
    }
    assert_eq!(number("q_peak_ml_s"), peak[3]);
    assert_eq!(number("max_velocity_m_s"), max_speed_m_s);
    assert_eq!(number("max_velocity_run_m_s"), max_speed_m_s);
    let mean = |c: usize| rows.iter().map(|r| r[c]).sum::<f64>() / STEPS as f64;
    assert!((number("q_mean_ml_s") - mean(3)).abs() < 1e-12);
    assert!((number("outlet_mean_pressure_mmhg") - mean(9)).abs() < 1e-12);
    assert!((number("mass_imbalance") - 0.01).abs() < 1e-9, "outflow is 0.99 of the inflow");
    // Every key the embedded engine writes (steady_phantom_gives_a_positive_pressure_drop).
    for key in ["mode", "message", "periodicity_nrmsd", "wall_time_s", "inputs"] {
        assert!(s.get(key).is_some(), "{key} missing: {s}");
    }
    assert_eq!(s["inputs"]["dt_s"], 0.01);
    let peak_vtu = baffle_core::io::read_vtu(&out_dir.join("peak.vtu")).unwrap();
    assert_eq!(peak_vtu.tets.len(), box_mesh().tets.len());
}

#[test]
fn a_missing_engine_is_named_and_the_exported_case_is_left_ready() {
    let (case, _) = box_case("missing");
    // svMultiPhysics present, mpiexec not: only mpiexec is reported missing.
    let bin = standin_bin("cli-missing-bin", &StandIn::default());
    std::fs::remove_file(bin.join("mpiexec")).unwrap();
    let out_dir = case.parent().unwrap().join("out");
    // PATH is the bin directory alone: this machine may have a real mpiexec in /usr/bin.
    let only_bin = |command: &mut Command| command.env("PATH", &bin).output().unwrap();
    let out = only_bin(&mut simulate_command(&case, &out_dir, &bin, &[]));
    assert!(!out.status.success());
    let e = stderr(&out);
    let case_dir = out_dir.join("svmultiphysics");
    assert!(e.contains("mpiexec is not on PATH") && !e.contains("neither svmultiphysics"), "{e}");
    assert!(e.contains(&format!("the exported case is ready in {}", case_dir.display())), "{e}");
    for file in ["solver.xml", "run.sh", "inflow.flw", "mesh-complete/mesh-complete.mesh.vtu", "baffle_case.json"] {
        assert!(case_dir.join(file).is_file(), "{file} missing");
    }
    assert!(!out_dir.join("summary.json").exists(), "nothing ran, nothing to summarize");

    std::fs::remove_file(bin.join("svMultiPhysics")).unwrap();
    let e = stderr(&only_bin(&mut simulate_command(&case, &out_dir, &bin, &[])));
    assert!(e.contains("neither svmultiphysics nor svMultiPhysics is on PATH"), "{e}");
}

#[test]
fn a_failing_engine_gives_a_failed_summary_and_embedded_only_options_are_refused() {
    let (case, _) = box_case("fail");
    let bin = standin_bin("cli-fail-bin", &StandIn { steps: Some(3), exit_code: 1, ..StandIn::default() });
    let out_dir = case.parent().unwrap().join("out");
    let out = simulate(&case, &out_dir, &bin, &[]);
    assert!(!out.status.success());
    let s = summary(&out_dir);
    assert_eq!(s["status"], "failed", "{s}");
    let message = s["message"].as_str().unwrap();
    assert!(message.contains("last time step 3 of 68") && message.contains("B_NS_Pressure_average.txt"), "{message}");
    assert!(stderr(&out).contains("last time step 3 of 68"));

    for option in [&["--resume"][..], &["--vtu-every", "2"]] {
        let e = stderr(&simulate(&case, &out_dir, &bin, option));
        assert!(e.contains(&format!("{} applies to the embedded engine only", option[0])), "{e}");
    }
}

#[test]
fn sigterm_stops_the_engine_and_says_so() {
    let (case, _) = box_case("sigterm");
    let bin = standin_bin("cli-sigterm-bin", &StandIn { steps: Some(100_000_000), ..StandIn::default() });
    let out_dir = case.parent().unwrap().join("out");
    assert!(!sigterm_after_progress_tags(&mut simulate_command(&case, &out_dir, &bin, &[]), 3).success());
    let s = summary(&out_dir);
    assert_eq!(s["status"], "stopped", "{s}");
    assert!(s["message"].as_str().unwrap().contains("stopped by signal at svMultiPhysics step"), "{s}");
    // The engine was asked to stop too, not left running.
    assert!(out_dir.join("svmultiphysics/standin.terminated").is_file());
}

/// The engine's convergence warnings reach summary.json: steps its log shows stopped at
/// the Newton cap count as unconverged, and the run is not reported converged.
#[test]
fn the_engines_convergence_warnings_are_not_read_back_as_converged() {
    let (case, recorded_dir) = box_case("unconverged");
    let bin = standin_bin("cli-unconverged-bin", &StandIn { recorded: Some(&recorded_dir), unconverged_from_step: Some(60), ..StandIn::default() });
    let out_dir = case.parent().unwrap().join("out");
    let out = simulate(&case, &out_dir, &bin, &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    let s = summary(&out_dir);
    assert_eq!((s["status"].as_str(), s["converged"].as_bool()), (Some("completed"), Some(false)), "{s}");
    assert_eq!(s["unconverged_nonlinear_steps"].as_u64(), Some((STEPS - 59) as u64), "{s}");
    let message = s["message"].as_str().unwrap();
    assert!(message.contains("9 of 68 time steps stopped at Max_iterations") && message.contains("steps 60, 61, 62, 63, 64, ..."), "{message}");
    assert!(message.contains("9 of 68 time steps had a linear solve that did not reach its tolerance"), "{message}");
}

/// --steps stops svMultiPhysics as it stops the embedded engine: solver.xml runs that many
/// steps, and the summary's peak is the run's own flow peak (step 16 of 20 at 10 ms).
#[test]
fn a_step_limit_stops_the_engine_there() {
    let (case, recorded_dir) = box_case_recorded("steps", 20, PEAK_STEP);
    let bin = standin_bin("cli-steps-bin", &StandIn { recorded: Some(&recorded_dir), ..StandIn::default() });
    let out_dir = case.parent().unwrap().join("out");
    let out = simulate(&case, &out_dir, &bin, &["--steps", "20"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let xml = std::fs::read_to_string(out_dir.join("svmultiphysics/solver.xml")).unwrap();
    assert!(xml.contains("<Number_of_time_steps> 20 </Number_of_time_steps>"), "{xml}");
    let s = summary(&out_dir);
    assert_eq!((s["status"].as_str(), s["steps_done"].as_u64(), s["last_step"].as_u64()), (Some("completed"), Some(20), Some(20)), "{s}");
    let (_, rows) = csv(&out_dir);
    assert_eq!(s["peak_time_s"].as_f64(), Some(rows[PEAK_STEP - 1][1]), "{s}");
}

/// --steady: svMultiPhysics has no steady solver, so the export runs 1 s at constant peak
/// inflow (100 steps of 10 ms) and saves the last step; the summary's peak is that step.
#[test]
fn steady_runs_read_back_at_the_last_step() {
    let (case, recorded_dir) = box_case_recorded("steady", 100, 100);
    let bin = standin_bin("cli-steady-bin", &StandIn { recorded: Some(&recorded_dir), ..StandIn::default() });
    let out_dir = case.parent().unwrap().join("out");
    let out = simulate(&case, &out_dir, &bin, &["--steady"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let s = summary(&out_dir);
    assert_eq!((s["mode"].as_str(), s["steps_done"].as_u64()), (Some("steady"), Some(100)));
    let (_, rows) = csv(&out_dir);
    let q_peak = s["inputs"]["q_peak_ml_s"].as_f64().unwrap();
    assert!(rows.iter().all(|r| r[2] == q_peak), "the prescribed inflow is the constant peak");
    let last = &rows[99];
    assert_eq!((s["peak_time_s"].as_f64(), s["dp_peak_mmhg"].as_f64()), (Some(last[1]), Some(last[11] - last[12])));
    assert!(last[5] > 0.0 && s["max_velocity_m_s"].as_f64() == Some(last[5]));
    let xml = std::fs::read_to_string(out_dir.join("svmultiphysics/solver.xml")).unwrap();
    assert!(xml.contains("<Number_of_time_steps> 100 </Number_of_time_steps>"), "{xml}");
}

/// Export the case without running it (no svMultiPhysics on PATH), then put `recorded`'s
/// outputs where a run elsewhere leaves them, as if the directory came back from a cluster.
fn exported_and_returned(case: &Path, out_dir: &Path, recorded: &Path, bin_name: &str) {
    let bin = standin_bin(bin_name, &StandIn::default());
    std::fs::remove_file(bin.join("svMultiPhysics")).unwrap();
    assert!(!simulate_command(case, out_dir, &bin, &[]).env("PATH", &bin).output().unwrap().status.success());
    let case_dir = out_dir.join("svmultiphysics");
    let results = case_dir.join(baffle_svmp::CaseManifest::read(&case_dir).unwrap().results_dir);
    std::fs::create_dir_all(&results).unwrap();
    for entry in std::fs::read_dir(recorded).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, results.join(path.file_name().unwrap())).unwrap();
    }
}

fn read_back(case: &Path, out_dir: &Path, extra: &[&str]) -> Output {
    // No engine and no mpiexec anywhere on PATH: a read-back neither exports nor runs.
    let empty = scratch("cli-readback-empty-bin");
    simulate_command(case, out_dir, &empty, &["--read-back"]).args(extra).env("PATH", &empty).output().unwrap()
}

#[test]
fn a_case_run_elsewhere_is_read_back_in_place() {
    let (case, recorded_dir) = box_case("readback");
    let out_dir = case.parent().unwrap().join("out");
    exported_and_returned(&case, &out_dir, &recorded_dir, "cli-readback-bin");
    // Not exported again: the solver file it would rewrite stays gone.
    std::fs::remove_file(out_dir.join("svmultiphysics/solver.xml")).unwrap();
    let out = read_back(&case, &out_dir, &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(!out_dir.join("svmultiphysics/solver.xml").exists());
    let s = summary(&out_dir);
    assert_eq!((s["engine"].as_str(), s["status"].as_str(), s["steps_done"].as_u64()), (Some("svmultiphysics"), Some("completed"), Some(STEPS as u64)));
    let (_, rows) = csv(&out_dir);
    let peak = &rows[PEAK_STEP - 1];
    assert_eq!(s["dp_peak_mmhg"].as_f64(), Some(peak[11] - peak[12]));
    let (p, _) = recorded(PEAK_STEP as f64 * 0.01);
    assert_eq!(peak[11], as_recorded(p[column("plane_10")]) / DYN_CM2_PER_MMHG);
    assert!(out_dir.join("peak.vtu").is_file());

    let embedded = Command::new(env!("CARGO_BIN_EXE_baffle"))
        .args(["simulate", case.to_str().unwrap(), "--out", out_dir.to_str().unwrap(), "--read-back"])
        .output()
        .unwrap();
    let e = stderr(&embedded);
    assert!(!embedded.status.success() && e.contains("--read-back reads an svMultiPhysics run"), "{e}");
}

#[test]
fn a_returned_run_that_stopped_early_is_a_failure_not_a_result() {
    let (case, recorded_dir) = box_case_recorded("readback-short", 20, PEAK_STEP);
    let out_dir = case.parent().unwrap().join("out");
    exported_and_returned(&case, &out_dir, &recorded_dir, "cli-readback-short-bin");
    let out = read_back(&case, &out_dir, &[]);
    assert!(!out.status.success());
    let s = summary(&out_dir);
    assert_eq!((s["status"].as_str(), s["converged"].as_bool()), (Some("failed"), Some(false)), "{s}");
    assert!(s["message"].as_str().unwrap().contains(&format!("end at time step 20 of {STEPS}")), "{s}");
}

#[test]
fn results_of_another_case_or_of_no_export_are_refused_by_name() {
    let (case, recorded_dir) = box_case("readback-other");
    let out_dir = case.parent().unwrap().join("out");
    let e = stderr(&read_back(&case, &out_dir, &[]));
    assert!(e.contains("baffle_case.json") && e.contains("--read-back reads a case exported to this --out"), "{e}");
    assert!(!out_dir.join("summary.json").exists());

    exported_and_returned(&case, &out_dir, &recorded_dir, "cli-readback-other-bin");
    let text = std::fs::read_to_string(&case).unwrap();
    for (from, to, what) in [
        (format!("[{PLANE_1}, {PLANE_2}]"), format!("[{PLANE_2}, {PLANE_1}]"), "measurement planes"),
        ("\"dt_s\": 0.01".to_string(), "\"dt_s\": 0.005".to_string(), "time step (s) 0.01"),
        (format!("\"inlet\": {INLET},"), "\"inlet\": 4,".to_string(), "faces"),
    ] {
        let other = case.with_file_name(format!("other-{}.json", what.len()));
        std::fs::write(&other, text.replace(&from, &to)).unwrap();
        let e = stderr(&read_back(&other, &out_dir, &[]));
        assert!(e.contains(&format!("the returned case has {what}")) && e.contains("exported from another case"), "{what}: {e}");
    }
}
