//! Finding and running the engine, with stand-in executables that print svMultiPhysics'
//! step log (the real one is not installed in CI).
#![cfg(unix)]

mod common;

use std::ffi::OsString;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};

use baffle_svmp::{export_case, find_engine_in, run_case, Engine, SvmpError};
use common::*;

fn write_script(path: &Path, body: &str) {
    std::fs::write(path, format!("#!/bin/sh\n{body}")).unwrap();
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755)).unwrap();
}

/// A bin directory with `mpiexec` (drops "-n N", runs the rest) and an `svMultiPhysics`
/// that checks its argument, prints the step log of `steps` steps (2 iterations each,
/// "s" at step 16) and exits with `code`.
fn fake_bin(name: &str, steps: usize, code: i32) -> PathBuf {
    let bin = scratch(name).join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    write_script(&bin.join("mpiexec"), "[ \"$1\" = -n ] || exit 9\nshift 2\nexec \"$@\"\n");
    write_script(
        &bin.join("svMultiPhysics"),
        &format!(
            "[ \"$1\" = solver.xml ] && [ -f solver.xml ] || {{ echo 'no solver.xml' >&2; exit 8; }}\n\
             echo ' Eq     N-i     T       dB  Ri/R1   Ri/R0    R/Ri     lsIt   dB  %t'\n\
             i=1\nwhile [ $i -le {steps} ]; do\n\
               s=' '; [ $i -eq 16 ] && s=s\n\
               echo \" NS $i-1  1.000e-01  [0 1.000e+00 1.000e+00 1.000e-05]  [10 -40 50]\"\n\
               echo \" NS $i-2$s 2.000e-01  [-60 1.000e-03 1.000e-03 1.000e-05]  [12 -41 55]\"\n\
               i=$((i+1))\ndone\n\
             echo 'solver finished' >&2\nexit {code}\n"
        ),
    );
    bin
}

fn exported_case(name: &str) -> PathBuf {
    let dir = scratch(name);
    let mut settings = settings();
    settings.cycles = 1;
    settings.dt_s = 0.01;
    let mut options = options();
    options.mpi_processes = 3;
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
    assert!(e.contains(&empty.display().to_string()) && e.contains("run.sh"), "{e}");
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
    // One report per step, and one more when step 16's results are saved.
    assert_eq!(reports.len(), 69);
    assert!(reports.windows(2).all(|w| w[1].0 >= w[0].0));
    assert_eq!(reports[68].0, 1.0);
    assert!(reports[15].1.contains("step 16/68 ("), "{}", reports[15].1);
    assert!(reports[16].1.contains("step 16/68, results saved"), "{}", reports[16].1);
    let log = std::fs::read_to_string(report.log_file).unwrap();
    assert_eq!(log.lines().filter(|l| l.contains(" NS ")).count(), 136);
}

#[test]
fn cancel_kills_the_run_and_failures_show_the_log_tail() {
    let dir = exported_case("run-fail");
    let engine_ok = engine(&fake_bin("bin-cancel", 68, 0));
    let e = run_case(&engine_ok, &dir, &mut |f, _| f < 0.07).unwrap_err();
    assert!(matches!(e, SvmpError::Cancelled { step: 5 }), "{e}");

    let engine_bad = engine(&fake_bin("bin-bad", 3, 1));
    let e = run_case(&engine_bad, &dir, &mut |_, _| true).unwrap_err().to_string();
    assert!(e.contains("last time step 3 of 68") && e.contains("solver finished"), "{e}");
}
