//! `baffle export-svmp`'s arguments.

use super::at_least_one;
use baffle_plan::export_cmd::ExportSettings;
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ExportArgs {
    /// Case file (JSON), as for `baffle simulate`.
    pub case: PathBuf,
    /// Output directory: mesh-complete/, solver.xml, the inflow file, run.sh, README.md.
    #[arg(long)]
    pub out: PathBuf,
    /// MPI processes in run.sh.
    #[arg(long, default_value_t = ExportSettings::default().mpi_processes, value_parser = at_least_one)]
    pub mpi_processes: usize,
    /// Export the steady estimate (constant inflow at Q_peak) instead of the pulsatile run.
    #[arg(long)]
    pub steady: bool,
}

impl From<ExportArgs> for ExportSettings {
    fn from(a: ExportArgs) -> Self {
        ExportSettings {
            case: a.case,
            out: a.out,
            mpi_processes: a.mpi_processes,
            steady: a.steady,
        }
    }
}
