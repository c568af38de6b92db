//! `baffle export-svmp`: hand the same JSON case as `baffle simulate` to
//! svMultiPhysics (the paper's solver), for a cluster run.

use crate::error::PlanError;
use crate::case;
use crate::progress::Progress;
use crate::svmp_case::{export_to, inflow_line};
use baffle_cfd::RunMode;
use std::path::PathBuf;

documented_settings! {
pub struct ExportSettings {
    /// Case file (JSON), as for `baffle simulate`.
    pub case: PathBuf,
    /// Output directory: mesh-complete/, solver.xml, the inflow file, run.sh, README.md.
    pub out: PathBuf,
    /// MPI processes in run.sh.
    pub mpi_processes: usize,
    /// Export the steady estimate (constant inflow at Q_peak) instead of the pulsatile run.
    pub steady: bool,
}
}

/// MPI processes of run.sh by default.
pub const MPI_PROCESSES: usize = 4;

impl Default for ExportSettings {
    fn default() -> Self {
        ExportSettings { case: PathBuf::new(), out: PathBuf::new(), mpi_processes: MPI_PROCESSES, steady: false }
    }
}

/// `baffle export-svmp`, what it wrote said on `progress`.
pub fn run_export(args: &ExportSettings, progress: &Progress) -> Result<(), PlanError> {
    export(args, progress).map_err(PlanError::Export)
}

/// The case of `args` exported for svMultiPhysics.
fn export(args: &ExportSettings, progress: &Progress) -> Result<(), String> {
    let case = case::read_case(&args.case)?;
    let mesh = case::load_mesh(&case)?;
    let (mut settings, _) = case::settings(&case)?;
    if args.steady {
        settings.mode = RunMode::Steady;
    }
    let exported = export_to(&args.out, &case, &mesh, &settings, args.mpi_processes)?;
    progress.say(&inflow_line(&exported));
    progress.say(&format!("wrote the svMultiPhysics case to {} (run it with run.sh)", args.out.display()));
    Ok(())
}
