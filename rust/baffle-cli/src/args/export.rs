//! `baffle export-svmp`'s arguments.

use super::at_least_one;
use baffle_plan::export_cmd::ExportSettings;
use clap::Args;
use std::path::PathBuf;

super::settings_args! {
    #[derive(Args)]
    pub struct ExportArgs into ExportSettings {
        pub case: PathBuf,
        #[arg(long)]
        pub out: PathBuf,
        #[arg(long, default_value_t = ExportSettings::default().mpi_processes, value_parser = at_least_one)]
        pub mpi_processes: usize,
        #[arg(long)]
        pub steady: bool,
    }
}
