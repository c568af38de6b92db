//! Scale out to svMultiPhysics (issue #7): export a baffle CFD case as a complete
//! svMultiPhysics case ([`export_case`]), run it out of process ([`find_engine`],
//! [`run_case`]), and read its outputs back into per-step face series and the peak figures
//! ([`read_results`]).
//!
//! Units: the [`baffle_mesh::TetMesh`] is in mm and is written in cm; everything
//! svMultiPhysics reads or writes is CGS (g, cm, s; dyn/cm^2; mL/s).
//! All knowledge of svMultiPhysics' file formats lives in [`format`] (and the Fourier fit
//! of its flow files in [`fourier`]).

mod error;
pub mod export;
pub mod format;
pub mod fourier;
pub mod mesh_export;
pub mod results;
pub mod run;

pub use error::SvmpError;
pub use export::{export_case, CaseManifest, ExportOptions, ExportedCase, FaceRole, ManifestFace, DEFAULT_SPECTRAL_RADIUS, MANIFEST_FILE};
pub use fourier::FourierSeries;
pub use mesh_export::MeshFiles;
pub use results::{read_results, FaceSample, PeakFields, StepSample, SvmpSummary};
pub use run::{find_engine, find_engine_in, mpiexec_args, run_case, Engine, MpiFlavor, RunReport, StepTracker};
