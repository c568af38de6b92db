//! The one error type of file I/O: which file, and what is wrong with it.

use std::fmt;
use std::path::{Path, PathBuf};

/// What went wrong, without the file (the file is in [`IoError`]).
#[derive(Debug, thiserror::Error)]
pub enum IoErrorKind {
    #[error("file not found")]
    NotFound,
    #[error("{0}")]
    Os(#[from] std::io::Error),
    /// The file type, or a feature of it (compressor, cell kind), is not supported.
    #[error("unsupported format: {0}")]
    Unsupported(String),
    /// The content does not parse; the message says where (line, element, point).
    #[error("{0}")]
    Malformed(String),
    #[error("array '{array}' has {found} values, expected {expected}")]
    ArrayLength { array: String, expected: usize, found: usize },
    #[error("{cell} refers to point {index}, but there are only {num_points} points")]
    IndexOutOfRange { cell: String, index: u64, num_points: usize },
    #[error("non-finite coordinate ({value}) at point {point}")]
    NonFiniteCoordinate { point: usize, value: f64 },
}

/// A file I/O error; `Display` gives "<path>: <problem>".
#[derive(Debug)]
pub struct IoError {
    pub path: PathBuf,
    pub kind: IoErrorKind,
}

impl IoError {
    pub fn new(path: &Path, kind: IoErrorKind) -> Self {
        IoError { path: path.to_path_buf(), kind }
    }
}

impl fmt::Display for IoError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.kind)
    }
}

impl std::error::Error for IoError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.kind {
            IoErrorKind::Os(e) => Some(e),
            _ => None,
        }
    }
}

/// Shorthand for a parse problem.
pub(crate) fn malformed(msg: impl Into<String>) -> IoErrorKind {
    IoErrorKind::Malformed(msg.into())
}

/// Read a whole file, telling "not found" apart from other OS errors.
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>, IoError> {
    std::fs::read(path).map_err(|e| {
        let kind = if e.kind() == std::io::ErrorKind::NotFound { IoErrorKind::NotFound } else { IoErrorKind::Os(e) };
        IoError::new(path, kind)
    })
}
