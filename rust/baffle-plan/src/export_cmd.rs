//! `baffle export-svmp`: hand the same JSON case as `baffle simulate` to
//! svMultiPhysics (the paper's solver), for a cluster run.

use crate::case;
use crate::svmp_case::export_to;
use baffle_cfd::RunMode;
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ExportArgs {
    /// Case file (JSON), as for `baffle simulate`.
    case: PathBuf,
    /// Output directory: mesh-complete/, solver.xml, the inflow file, run.sh, README.md.
    #[arg(long)]
    out: PathBuf,
    /// MPI processes in run.sh.
    #[arg(long, default_value_t = 4, value_parser = crate::case::at_least_one)]
    mpi_processes: usize,
    /// Export the steady estimate (constant inflow at Q_peak) instead of the pulsatile run.
    #[arg(long)]
    steady: bool,
}

pub fn run_export(args: &ExportArgs) -> Result<(), String> {
    let case = case::read_case(&args.case)?;
    let mesh = case::load_mesh(&case)?;
    let (mut settings, _) = case::settings(&case)?;
    if args.steady {
        settings.mode = RunMode::Steady;
    }
    export_to(&args.out, &case, &mesh, &settings, args.mpi_processes)?;
    println!("wrote the svMultiPhysics case to {} (run it with run.sh)", args.out.display());
    Ok(())
}
