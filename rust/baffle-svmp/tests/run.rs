//! Finding and running the engine, with stand-in executables that print svMultiPhysics'
//! step log (the real one is not installed in CI).
#![cfg(unix)]

mod common;

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use baffle_svmp::{export_case, find_engine_in, run_case, Engine, SvmpError};
use common::*;

/// The stand-in printing `steps` steps and exiting with `code`.
fn fake_bin(name: &str, steps: usize, code: i32) -> PathBuf {
    standin_bin(name, &StandIn { steps: Some(steps), exit_code: code, ..StandIn::default() })
}

fn exported_case(name: &str) -> PathBuf {
    exported_case_for(name, 3)
}

fn exported_case_for(name: &str, processes: usize) -> PathBuf {
    let dir = scratch(name);
    let mut settings = settings();
    settings.cycles = 1;
    settings.dt_s = 0.01;
    let mut options = options();
    options.mpi_processes = processes;
    export_case(&dir, &box_mesh(), &settings, &options).unwrap();
    dir
}

fn engine(bin: &Path) -> Engine {
    find_engine_in(&OsString::from(format!("/nonexistent:{}", bin.display()))).unwrap()
}

#[test]
fn missing_executables_are_reported_with_where_we_looked() {
    let empty = scratch("empty-path");
    let e = find_engine_in(empty.as_os_str()).unwrap_err();
    assert!(matches!(e, SvmpError::NotInstalled(_)));
    let e = e.to_string();
    assert!(e.contains("neither svmultiphysics nor svMultiPhysics") && e.contains("mpiexec is not on PATH"), "{e}");
    assert!(e.contains(&empty.display().to_string()), "{e}");
}

#[test]
fn run_reports_progress_per_time_step_and_keeps_the_log() {
    let bin = fake_bin("bin-ok", 68, 0);
    let engine = engine(&bin);
    assert_eq!(engine.svmultiphysics, bin.join("svMultiPhysics"));
    let dir = exported_case("run-ok");
    let mut reports = Vec::new();
    let report = run_case(&engine, &dir, &mut |f, m| {
        reports.push((f, m.to_string()));
        true
    })
    .unwrap();
    assert_eq!(report.last_step, 68);
    // One report per step, and one more at each save (every 16 steps from the peak, 16).
    assert_eq!(reports.len(), 72);
    assert!(reports.windows(2).all(|w| w[1].0 >= w[0].0));
    assert_eq!(reports[71].0, 1.0);
    assert!(reports[15].1.contains("step 16/68 ("), "{}", reports[15].1);
    assert!(reports[16].1.contains("step 16/68, results saved"), "{}", reports[16].1);
    let log = std::fs::read_to_string(report.log_file).unwrap();
    assert_eq!(log.lines().filter(|l| l.contains(" NS ")).count(), 136);
    // Open MPI (the stand-in's --version) is told it may run as root only when we are root.
    let args = std::fs::read_to_string(dir.join("mpiexec.args")).unwrap();
    let tail = format!("-n 3 {} solver.xml\n", bin.join("svMultiPhysics").display());
    let root = unsafe { libc::geteuid() } == 0;
    let expected = if root { format!("--allow-run-as-root {tail}") } else { tail };
    assert_eq!(args, expected);
}

#[test]
fn mpich_never_gets_the_open_mpi_root_option() {
    let bin = standin_bin("bin-mpich", &StandIn { steps: Some(68), mpi_version: MPICH_VERSION, ..StandIn::default() });
    let dir = exported_case("run-mpich");
    run_case(&engine(&bin), &dir, &mut |_, _| true).unwrap();
    let args = std::fs::read_to_string(dir.join("mpiexec.args")).unwrap();
    assert!(args.starts_with("-n 3 "), "{args}");
}

#[test]
fn cancel_stops_the_run_and_failures_show_the_log_tail() {
    let dir = exported_case("run-fail");
    // A long run: cancelling must end it (SIGTERM) instead of waiting for it to finish.
    let engine_long = engine(&fake_bin("bin-cancel", 1_000_000, 0));
    let started = std::time::Instant::now();
    let e = run_case(&engine_long, &dir, &mut |f, _| f < 0.07).unwrap_err();
    assert!(matches!(e, SvmpError::Cancelled { step: 5 }), "{e}");
    assert!(started.elapsed() < std::time::Duration::from_secs(5), "{:?}", started.elapsed());
    // It was asked to stop (SIGTERM, which mpiexec forwards to the ranks), not just killed.
    assert!(dir.join("standin.terminated").is_file());

    // A failed run leaves no earlier run's outputs behind to be read back as its own.
    std::fs::create_dir_all(dir.join("results")).unwrap();
    std::fs::write(dir.join("results/B_NS_Pressure_average.txt"), "from an earlier run").unwrap();
    let engine_bad = engine(&fake_bin("bin-bad", 3, 1));
    let e = run_case(&engine_bad, &dir, &mut |_, _| true).unwrap_err().to_string();
    assert!(e.contains("last time step 3 of 68") && e.contains("solver finished"), "{e}");
    assert!(!dir.join("results").exists());
}

/// The stand-in svMultiPhysics started by this machine's own mpiexec, when it has one:
/// the launch arguments against a real launcher (Debian's Open MPI refuses to run as root
/// without --allow-run-as-root, so this fails if the option is missing or misplaced).
#[test]
fn the_machines_own_mpiexec_starts_the_engine() {
    let bin = fake_bin("bin-real-mpi", 68, 0);
    std::fs::remove_file(bin.join("mpiexec")).unwrap();
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
    let engine = match find_engine_in(&OsString::from(path)) {
        Ok(engine) => engine,
        Err(_) => return eprintln!("note: no mpiexec on PATH; the real launcher is not tested"),
    };
    assert_eq!(engine.svmultiphysics, bin.join("svMultiPhysics"));
    // One process: Open MPI refuses more processes than cores unless told to oversubscribe.
    let dir = exported_case_for("run-real-mpi", 1);
    let report = run_case(&engine, &dir, &mut |_, _| true)
        .unwrap_or_else(|e| panic!("{} could not start the engine: {e}", engine.mpiexec.display()));
    assert_eq!(report.last_step, 68);
}
