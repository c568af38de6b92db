//! The one error type of the svMultiPhysics export, run and read-back.

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum SvmpError {
    /// The case, its options or its mesh cannot be exported as given.
    #[error("cannot export the case: {0}")]
    InvalidCase(String),
    /// The volume mesh failed its checks or could not be written.
    #[error(transparent)]
    Mesh(#[from] baffle_mesh::MeshError),
    /// A face file could not be written.
    #[error(transparent)]
    SurfaceIo(#[from] baffle_core::io::IoError),
    /// A file could not be read or written.
    #[error("{path}: {message}")]
    Io { path: PathBuf, message: String },
    /// An svMultiPhysics file does not have the documented layout.
    #[error("{path}: line {line}: {message}")]
    Format { path: PathBuf, line: usize, message: String },
    /// The svMultiPhysics executable or mpiexec is not on PATH.
    #[error("svMultiPhysics cannot be run here: {0}")]
    NotInstalled(String),
    /// svMultiPhysics ran but failed; `log_tail` is the end of its output.
    #[error("svMultiPhysics failed: {reason}\n--- last lines of its log ---\n{log_tail}")]
    RunFailed { reason: String, log_tail: String },
    /// The progress callback asked to stop; the process was killed.
    #[error("svMultiPhysics run cancelled at step {step}")]
    Cancelled { step: usize },
}

impl SvmpError {
    pub(crate) fn io(path: &Path, message: impl ToString) -> Self {
        SvmpError::Io { path: path.to_path_buf(), message: message.to_string() }
    }

    pub(crate) fn format(path: &Path, line: usize, message: impl Into<String>) -> Self {
        SvmpError::Format { path: path.to_path_buf(), line, message: message.into() }
    }
}
