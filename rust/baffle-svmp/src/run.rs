//! Running an exported case with svMultiPhysics out of process: find the executables,
//! spawn `mpiexec [--allow-run-as-root] -n N svmultiphysics solver.xml`, report progress
//! from its step log.

use std::ffi::{OsStr, OsString};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::export::CaseManifest;
use crate::format::{parse_step_line, SOLVER_FILE};
use crate::SvmpError;
use baffle_mesh::start_retrying_busy;

/// Executable names tried, in order.
pub const SVMP_NAMES: [&str; 2] = ["svmultiphysics", "svMultiPhysics"];
pub const MPIEXEC_NAME: &str = "mpiexec";
/// svMultiPhysics' stdout is copied to LOG_FILE in the case directory, stderr to ERR_FILE.
pub const LOG_FILE: &str = "svmultiphysics.log";
pub const ERR_FILE: &str = "svmultiphysics.err";
/// How long a cancelled run gets to end after SIGTERM before it is killed.
pub const STOP_GRACE: Duration = Duration::from_secs(10);

#[derive(Clone, Debug, PartialEq)]
pub struct Engine {
    pub svmultiphysics: PathBuf,
    pub mpiexec: PathBuf,
}

/// Find svMultiPhysics and mpiexec on `PATH`.
pub fn find_engine() -> Result<Engine, SvmpError> {
    find_engine_in(&std::env::var_os("PATH").unwrap_or_default())
}

/// Find svMultiPhysics and mpiexec in the directories of `path_var` (PATH syntax); the
/// error says which is missing and where it looked.
pub fn find_engine_in(path_var: &OsStr) -> Result<Engine, SvmpError> {
    let dirs: Vec<PathBuf> = std::env::split_paths(path_var).collect();
    let svmp = SVMP_NAMES.iter().find_map(|name| find_executable(&dirs, name));
    let mpiexec = find_executable(&dirs, MPIEXEC_NAME);
    let mut missing = Vec::new();
    if svmp.is_none() {
        missing.push(format!("neither {} is on PATH", SVMP_NAMES.join(" nor ")));
    }
    if mpiexec.is_none() {
        missing.push(format!("{MPIEXEC_NAME} is not on PATH"));
    }
    match (svmp, mpiexec) {
        (Some(svmultiphysics), Some(mpiexec)) => Ok(Engine { svmultiphysics, mpiexec }),
        _ => Err(SvmpError::NotInstalled(format!(
            "{} (searched: {})",
            missing.join(" and "),
            dirs.iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(":")
        ))),
    }
}

fn find_executable(dirs: &[PathBuf], name: &str) -> Option<PathBuf> {
    dirs.iter().map(|d| d.join(name)).find(|p| is_executable(p))
}

#[cfg(unix)]
fn is_executable(path: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    path.metadata().map(|m| m.is_file() && m.permissions().mode() & 0o111 != 0).unwrap_or(false)
}

#[cfg(not(unix))]
fn is_executable(path: &Path) -> bool {
    path.is_file()
}

/// Which MPI implementation an `mpiexec` belongs to; only Open MPI needs telling that it
/// may run as root.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MpiFlavor {
    OpenMpi,
    /// MPICH (Hydra), Intel MPI, or a launcher whose `--version` said nothing we know.
    Other,
}

impl MpiFlavor {
    /// From `mpiexec --version`: Open MPI 4 prints "mpiexec (OpenRTE) 4.1.4", Open MPI 5
    /// "mpiexec (Open MPI) 5.0.3", both with a help URL on open-mpi.org. MPICH prints
    /// "HYDRA build details:".
    pub fn from_version_output(text: &str) -> Self {
        let open_mpi = ["Open MPI", "OpenRTE", "open-mpi.org"].iter().any(|mark| text.contains(mark));
        if open_mpi {
            MpiFlavor::OpenMpi
        } else {
            MpiFlavor::Other
        }
    }

    /// Runs `mpiexec --version`; a launcher that cannot say is treated as not Open MPI.
    pub fn detect(mpiexec: &Path) -> Self {
        let output = start_retrying_busy(|| Command::new(mpiexec).arg("--version").stdin(Stdio::null()).output());
        match output {
            Ok(out) => {
                let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
                MpiFlavor::from_version_output(&text)
            }
            Err(_) => MpiFlavor::Other,
        }
    }
}

/// The arguments of `mpiexec` for a run. Open MPI refuses to start as root unless told
/// `--allow-run-as-root` (containers often run as root); MPICH does not know the option
/// and would fail on it, so it is only added for Open MPI with effective uid 0.
pub fn mpiexec_args(flavor: MpiFlavor, effective_uid: u32, processes: usize, svmultiphysics: &Path) -> Vec<OsString> {
    let mut args: Vec<OsString> = Vec::new();
    if flavor == MpiFlavor::OpenMpi && effective_uid == 0 {
        args.push("--allow-run-as-root".into());
    }
    args.extend(["-n".into(), processes.to_string().into(), svmultiphysics.as_os_str().to_owned(), SOLVER_FILE.into()]);
    args
}

#[cfg(unix)]
fn effective_uid() -> u32 {
    // SAFETY: geteuid has no preconditions and cannot fail.
    unsafe { libc::geteuid() }
}

#[cfg(not(unix))]
fn effective_uid() -> u32 {
    u32::MAX
}

/// How a finished run went.
#[derive(Clone, Debug, PartialEq)]
pub struct RunReport {
    pub last_step: usize,
    pub elapsed_s: f64,
    pub log_file: PathBuf,
}

/// Run the case in `case_dir` with `manifest.mpi_processes` processes. `progress(fraction,
/// message)` is called at every new time step of the log; returning false kills the run.
pub fn run_case(
    engine: &Engine,
    case_dir: &Path,
    progress: &mut dyn FnMut(f64, &str) -> bool,
) -> Result<RunReport, SvmpError> {
    let manifest = CaseManifest::read(case_dir)?;
    clear_results(&case_dir.join(&manifest.results_dir))?;
    let log_path = case_dir.join(LOG_FILE);
    let err_path = case_dir.join(ERR_FILE);
    let mut log = std::fs::File::create(&log_path).map_err(|e| SvmpError::io(&log_path, e))?;
    let err = std::fs::File::create(&err_path).map_err(|e| SvmpError::io(&err_path, e))?;
    let flavor = MpiFlavor::detect(&engine.mpiexec);
    let args = mpiexec_args(flavor, effective_uid(), manifest.mpi_processes, &engine.svmultiphysics);
    let mut child = start_retrying_busy(|| {
        Command::new(&engine.mpiexec)
            .args(&args)
            .current_dir(case_dir)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::from(err.try_clone()?))
            .spawn()
    })
        .map_err(|e| SvmpError::io(&engine.mpiexec, format!("could not start: {e}")))?;
    let stdout = child.stdout.take().ok_or_else(|| SvmpError::io(&engine.mpiexec, "no stdout pipe"))?;
    let mut tracker = StepTracker::new(manifest.n_time_steps);
    let mut lines = BufReader::new(stdout).lines();
    while let Some(line) = lines.next() {
        let line = line.map_err(|e| SvmpError::io(&log_path, e))?;
        writeln!(log, "{line}").map_err(|e| SvmpError::io(&log_path, e))?;
        if let Some((fraction, message)) = tracker.update(&line) {
            if !progress(fraction, &message) {
                drain_into(lines, log);
                stop(&mut child);
                return Err(SvmpError::Cancelled { step: tracker.last_step });
            }
        }
    }
    let status = child.wait().map_err(|e| SvmpError::io(&engine.mpiexec, e))?;
    if !status.success() || tracker.last_step < manifest.n_time_steps {
        return Err(SvmpError::RunFailed {
            reason: format!("{status}, last time step {} of {}", tracker.last_step, manifest.n_time_steps),
            log_tail: log_tail(&[&log_path, &err_path], 20),
        });
    }
    Ok(RunReport { last_step: tracker.last_step, elapsed_s: tracker.elapsed_s, log_file: log_path })
}

/// A run starts with no results folder, so a run that fails early cannot leave an earlier
/// run's outputs to be read back as its own.
fn clear_results(results: &Path) -> Result<(), SvmpError> {
    match std::fs::remove_dir_all(results) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(SvmpError::io(results, format!("cannot clear: {e}"))),
        _ => Ok(()),
    }
}

/// Keep copying the engine's remaining output to its log in the background while it
/// stops: an engine blocked writing to a full pipe cannot act on SIGTERM (the CLI test's
/// stand-in then missed its 10 s grace). The thread ends when the last writer closes the
/// pipe; it is not joined, as ranks killed with their launcher may hold it a while.
fn drain_into<R: BufRead + Send + 'static>(lines: std::io::Lines<R>, mut log: std::fs::File) {
    std::thread::spawn(move || {
        for line in lines.map_while(Result::ok) {
            let _ = writeln!(log, "{line}");
        }
    });
}

/// End a cancelled run: SIGTERM first, which mpiexec forwards to the ranks (killing the
/// launcher alone could leave them running), then SIGKILL after [`STOP_GRACE`].
fn stop(child: &mut Child) {
    #[cfg(unix)]
    if let Ok(pid) = libc::pid_t::try_from(child.id()) {
        // SAFETY: kill only sends a signal to our own child, which has not been reaped.
        unsafe { libc::kill(pid, libc::SIGTERM) };
        let deadline = Instant::now() + STOP_GRACE;
        while Instant::now() < deadline {
            if let Ok(Some(_)) = child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
    let _ = child.kill();
    let _ = child.wait();
}

/// Turns step-log lines into progress: one report per new time step.
pub struct StepTracker {
    n_time_steps: usize,
    pub last_step: usize,
    pub elapsed_s: f64,
}

impl StepTracker {
    pub fn new(n_time_steps: usize) -> Self {
        StepTracker { n_time_steps, last_step: 0, elapsed_s: 0.0 }
    }

    /// (fraction done, message) when `line` starts a new time step, or says that results
    /// were saved (svMultiPhysics prints a last line with "s" after saving a step).
    pub fn update(&mut self, line: &str) -> Option<(f64, String)> {
        let step = parse_step_line(line)?;
        self.elapsed_s = step.elapsed_s;
        if step.step < self.last_step || (step.step == self.last_step && !step.saved) {
            return None;
        }
        self.last_step = step.step;
        let fraction = (step.step as f64 / self.n_time_steps.max(1) as f64).min(1.0);
        let saved = if step.saved { ", results saved" } else { "" };
        Some((fraction, format!("svMultiPhysics step {}/{}{saved} ({:.1} s)", step.step, self.n_time_steps, step.elapsed_s)))
    }
}

fn log_tail(paths: &[&Path], lines: usize) -> String {
    let mut out = Vec::new();
    for path in paths {
        let text = std::fs::read_to_string(path).unwrap_or_default();
        let all: Vec<&str> = text.lines().collect();
        out.extend(all[all.len().saturating_sub(lines)..].iter().map(|l| l.to_string()));
    }
    out.join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    const OPEN_MPI_4: &str = "mpiexec (OpenRTE) 4.1.4\n\nReport bugs to http://www.open-mpi.org/community/help/\n";
    const OPEN_MPI_5: &str = "mpiexec (Open MPI) 5.0.3\n\nReport bugs to https://www.open-mpi.org/community/help/\n";
    const MPICH: &str = "HYDRA build details:\n    Version:                                 4.0.2\n    Release Date:                            Thu Apr  7 12:34:45 CDT 2022\n";

    fn strings(args: &[OsString]) -> Vec<String> {
        args.iter().map(|a| a.to_string_lossy().into_owned()).collect()
    }

    #[test]
    fn open_mpi_is_told_it_may_run_as_root_and_only_it() {
        let svmp = Path::new("/opt/svmp/bin/svmultiphysics");
        let plain = ["-n", "4", "/opt/svmp/bin/svmultiphysics", "solver.xml"];
        for text in [OPEN_MPI_4, OPEN_MPI_5] {
            let flavor = MpiFlavor::from_version_output(text);
            assert_eq!(flavor, MpiFlavor::OpenMpi, "{text}");
            let root = strings(&mpiexec_args(flavor, 0, 4, svmp));
            assert_eq!(root[0], "--allow-run-as-root");
            assert_eq!(root[1..], plain);
            assert_eq!(strings(&mpiexec_args(flavor, 1000, 4, svmp)), plain);
        }
        for text in [MPICH, "", "mpiexec: unknown option --version"] {
            let flavor = MpiFlavor::from_version_output(text);
            assert_eq!(flavor, MpiFlavor::Other, "{text}");
            assert_eq!(strings(&mpiexec_args(flavor, 0, 4, svmp)), plain, "MPICH has no --allow-run-as-root");
        }
    }

    #[test]
    fn a_launcher_that_cannot_be_asked_is_not_open_mpi() {
        assert_eq!(MpiFlavor::detect(Path::new("/nonexistent/mpiexec")), MpiFlavor::Other);
    }
}
