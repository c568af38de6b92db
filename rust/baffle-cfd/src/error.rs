//! Errors of the CFD crate: every message names the problem (file, element, step).

use thiserror::Error;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum CfdError {
    #[error("{path}: {message}")]
    Io { path: String, message: String },
    #[error("invalid mesh: {0}")]
    Mesh(String),
    #[error("invalid case settings: {0}")]
    Settings(String),
    #[error("invalid inflow waveform: {0}")]
    Waveform(String),
    #[error("solution diverged at step {step} (t = {time_s:.4} s): {reason}; residual {residual:.3e}")]
    Diverged { step: usize, time_s: f64, residual: f64, reason: String },
    #[error(
        "linear solver failed at step {step} (t = {time_s:.4} s): relative residual {residual:.3e} after {iterations} GMRES iterations"
    )]
    LinearSolver { step: usize, time_s: f64, iterations: usize, residual: f64 },
    /// A time step that failed on every rung of the solver's retry ladder.
    #[error(
        "time step {step} (t = {time_s:.4} s) failed on every retry ({tried}). Try a smaller time step (dt), a larger GMRES budget (max_linear_iterations), or a coarser or better-shaped mesh (check its smallest scaled Jacobian); on meshes of several hundred thousand tetrahedra the external svMultiPhysics engine may be needed"
    )]
    StepFailed { step: usize, time_s: f64, tried: String },
    /// The run would need more memory than the machine has free (see `memory`).
    #[error(
        "the run needs about {:.1} GB for {tets} tetrahedra, but only {:.1} GB of memory is free; use a coarser mesh (a larger edge length) or the external svMultiPhysics engine",
        needed_bytes / 1e9,
        available_bytes / 1e9
    )]
    Memory { tets: usize, needed_bytes: f64, available_bytes: f64 },
    #[error("cancelled at t = {time_s:.4} s")]
    Cancelled { time_s: f64 },
}
