//! `baffle export-svmp`'s arguments.

use super::at_least_one;
use baffle_plan::export_cmd::ExportSettings;
use clap::Args;
use std::path::PathBuf;

super::settings_args! {
    #[derive(Args)]
    pub struct ExportArgs into ExportSettings {
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
}
