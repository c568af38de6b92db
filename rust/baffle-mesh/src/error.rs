//! The one error type of volume meshing and volume-mesh I/O.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The caller's surface or options cannot be meshed as given.
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// No gmsh executable was found (the message lists where it looked).
    #[error("gmsh not found: {0}")]
    GmshNotFound(String),
    /// gmsh ran but failed or timed out; `log_tail` is the end of its output.
    #[error("gmsh failed: {reason}\n--- last lines of the gmsh log ---\n{log_tail}")]
    GmshFailed { reason: String, log_tail: String },
    /// A `.msh` file gmsh wrote does not parse as expected.
    #[error("{path}: malformed gmsh output: {message}")]
    MalformedMsh { path: PathBuf, message: String },
    /// The volume mesh violates an invariant (inverted tet, lost face, non-conforming surface...).
    #[error("invalid volume mesh: {0}")]
    InvalidMesh(String),
    /// gmsh returned a tet too flat for the CFD solver (see `tetmesh::DEGENERATE_VOLUME_RATIO`).
    #[error("invalid volume mesh: {0}")]
    DegenerateTet(String),
    /// A file could not be read or written, or its content is not what is expected.
    #[error("{path}: {message}")]
    File { path: PathBuf, message: String },
    #[error(transparent)]
    SurfaceIo(#[from] baffle_core::io::IoError),
}

impl MeshError {
    pub(crate) fn file(path: &std::path::Path, message: impl Into<String>) -> Self {
        MeshError::File {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}
