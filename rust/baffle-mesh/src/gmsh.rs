//! Finding gmsh and running it as a child process with a time limit.
//!
//! Lookup order: the caller's path, then `$BAFFLE_GMSH`, then `gmsh` on `PATH`, then the
//! Python module of the PyPI wheel (`$BAFFLE_PYTHON` or `python3 -c "import gmsh ..."`), which covers a wheel
//! whose launcher script is not on `PATH` or whose `#!/usr/bin/env python` finds no `python`.

use crate::error::MeshError;
use crate::process::start_retrying_busy;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Environment variable naming the gmsh executable.
pub const GMSH_ENV: &str = "BAFFLE_GMSH";

/// Runs the PyPI wheel's gmsh (the same thing its launcher script does).
const PYTHON_GMSH: &str = "import sys, gmsh; gmsh.initialize(sys.argv, run=True); gmsh.finalize()";

/// How to start gmsh: a program and the arguments that go before gmsh's own.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GmshCommand {
    pub program: PathBuf,
    pub prefix_args: Vec<OsString>,
}

impl GmshCommand {
    pub fn command(&self) -> Command {
        let mut c = Command::new(&self.program);
        c.args(&self.prefix_args);
        // gmsh is a console program: started from a `baffle` that has no console (the
        // Slicer module starts it with CREATE_NO_WINDOW) it would open a console window.
        #[cfg(windows)]
        {
            use std::os::windows::process::CommandExt;
            const CREATE_NO_WINDOW: u32 = 0x0800_0000;
            c.creation_flags(CREATE_NO_WINDOW);
        }
        c
    }

    /// Runs `start` (this command's spawn or output), retrying a busy executable; a
    /// start that fails is [`MeshError::GmshNotFound`], naming the program.
    fn start<T>(&self, start: impl FnMut() -> std::io::Result<T>) -> Result<T, MeshError> {
        start_retrying_busy(start).map_err(|e| {
            MeshError::GmshNotFound(format!(
                "{} could not be started: {e}",
                self.program.display()
            ))
        })
    }

    /// `gmsh --version`, trimmed; errors when it does not run.
    pub fn version(&self) -> Result<String, MeshError> {
        let out = self.start(|| {
            self.command()
                .arg("--version")
                .stdin(Stdio::null())
                .output()
        })?;
        let text = String::from_utf8_lossy(&out.stdout).to_string()
            + &String::from_utf8_lossy(&out.stderr);
        let version = text.trim().lines().last().unwrap_or("").trim().to_string();
        if out.status.success() && version.chars().next().is_some_and(|c| c.is_ascii_digit()) {
            Ok(version)
        } else {
            Err(MeshError::GmshNotFound(format!(
                "{} --version failed ({}): {}",
                self.program.display(),
                out.status,
                text.trim()
            )))
        }
    }
}

/// Find a gmsh that answers `--version` (see the module doc for the order).
pub fn find_gmsh(explicit: Option<&Path>) -> Result<GmshCommand, MeshError> {
    if let Some(path) = explicit {
        return checked(plain(path.to_path_buf()));
    }
    if let Some(path) = std::env::var_os(GMSH_ENV).filter(|v| !v.is_empty()) {
        return checked(plain(PathBuf::from(path)))
            .map_err(|e| MeshError::GmshNotFound(format!("${GMSH_ENV}: {e}")));
    }
    let mut tried = Vec::new();
    for candidate in [path_gmsh(), python_gmsh()].into_iter().flatten() {
        match checked(candidate) {
            Ok(found) => return Ok(found),
            Err(e) => tried.push(e.to_string()),
        }
    }
    Err(MeshError::GmshNotFound(format!(
        "no working gmsh: set MeshOptions::gmsh_executable or ${GMSH_ENV}, or install it \
         ('python3 -m pip install gmsh' or 'apt-get install gmsh'); tried: {}",
        if tried.is_empty() {
            "nothing on PATH".to_string()
        } else {
            tried.join("; ")
        }
    )))
}

fn plain(program: PathBuf) -> GmshCommand {
    GmshCommand {
        program,
        prefix_args: Vec::new(),
    }
}

fn checked(cmd: GmshCommand) -> Result<GmshCommand, MeshError> {
    cmd.version().map(|_| cmd)
}

fn path_gmsh() -> Option<GmshCommand> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join("gmsh"))
        .find(|p| p.is_file())
        .map(plain)
}

/// The interpreter of the wheel: `$BAFFLE_PYTHON` (the report's pictures take the same; a
/// caller such as the Slicer module names the Python it runs, which on Windows is not
/// `python3`), else `python3`.
fn python_gmsh() -> Option<GmshCommand> {
    let python = std::env::var_os("BAFFLE_PYTHON").filter(|v| !v.is_empty());
    Some(GmshCommand {
        program: python.map(PathBuf::from).unwrap_or_else(|| PathBuf::from("python3")),
        prefix_args: vec!["-c".into(), PYTHON_GMSH.into()],
    })
}

/// Run `cmd args` in `dir` with output to `log_path`, killing it after `timeout`.
pub fn run_gmsh(
    cmd: &GmshCommand,
    args: &[OsString],
    dir: &Path,
    log_path: &Path,
    timeout: Duration,
) -> Result<(), MeshError> {
    let log =
        std::fs::File::create(log_path).map_err(|e| MeshError::file(log_path, e.to_string()))?;
    let mut child = cmd.start(|| {
        cmd.command()
            .args(args)
            .current_dir(dir)
            .stdin(Stdio::null())
            .stdout(log.try_clone()?)
            .stderr(log.try_clone()?)
            .spawn()
    })?;
    let start = Instant::now();
    loop {
        match child.try_wait() {
            Ok(Some(status)) if status.success() => return Ok(()),
            Ok(Some(status)) => return Err(failed(format!("gmsh exited with {status}"), log_path)),
            Ok(None) if start.elapsed() > timeout => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(failed(
                    format!(
                        "gmsh did not finish within {:.0} s and was stopped",
                        timeout.as_secs_f64()
                    ),
                    log_path,
                ));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(20)),
            Err(e) => return Err(failed(format!("waiting for gmsh failed: {e}"), log_path)),
        }
    }
}

/// A [`MeshError::GmshFailed`] with the end of the log (errors and warnings first).
pub fn failed(reason: String, log_path: &Path) -> MeshError {
    MeshError::GmshFailed {
        reason,
        log_tail: log_tail(log_path),
    }
}

fn log_tail(log_path: &Path) -> String {
    let text = std::fs::read_to_string(log_path).unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    let errors: Vec<&str> = lines
        .iter()
        .copied()
        .filter(|l| l.starts_with("Error"))
        .take(10)
        .collect();
    let tail = &lines[lines.len().saturating_sub(15)..];
    let mut out = errors.join("\n");
    if !out.is_empty() {
        out.push_str("\n...\n");
    }
    out + &tail.join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn explicit_missing_gmsh_is_reported() {
        let err = find_gmsh(Some(Path::new("/nonexistent/gmsh")))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("/nonexistent/gmsh") && err.contains("could not be started"),
            "{err}"
        );
    }

    #[test]
    fn a_program_that_is_not_gmsh_is_rejected() {
        // `false` runs but fails, so it is not taken for gmsh.
        let err = find_gmsh(Some(Path::new("false"))).unwrap_err().to_string();
        assert!(err.contains("--version failed"), "{err}");
    }
}
