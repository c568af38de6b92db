//! Incompressible Newtonian Navier-Stokes on linear tetrahedra for baffle
//! hemodynamics (issue #4, after Martinez et al. who used svMultiPhysics).
//!
//! CGS units throughout: cm, g, s; pressure dyn/cm^2; flow mL/s = cm^3/s.
//! See [`assembly`] for the formulation and [`solver`] for the linear solver choice.

pub mod assembly;
pub mod boundary;
pub mod coarse;
mod error;
pub mod hemodynamics;
pub mod linear;
pub mod memory;
pub mod flow_mesh;
pub mod periodicity;
pub mod settings;
pub mod solver;
pub mod sparse;
pub mod time_integration;
/// Structured tube meshes for verification tests and benchmarks.
pub mod test_meshes;
pub mod vtu;
pub mod waveform;

#[cfg(test)]
mod test_data;

pub use error::CfdError;
pub use flow_mesh::{Face, FlowMesh, ValidationReport};
pub use settings::{CaseSettings, InflowProfile, NonlinearIterations, Outlet, RunMode, AUTO_NONLINEAR_CAP, SVMULTIPHYSICS_FORMULATION, TWO_LEVEL_AGGREGATE_NODES};
pub use solver::{simulate, simulate_from, FaceResult, Run, SolverState, SteadyProgress, StepResult, StepView, Summary, Timings};
pub use periodicity::periodicity_nrmsd;
pub use time_integration::{TimeIntegration, DEFAULT_RHO_INF};
pub use waveform::Waveform;
#[cfg(test)]
mod verification;
