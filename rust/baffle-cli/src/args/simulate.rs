//! `baffle simulate`'s arguments and its engine.

use super::at_least_one;
use baffle_plan::simulate_cmd::SimulateSettings;
use baffle_plan::simulate_report::Engine as PlanEngine;
use baffle_plan::case;
use clap::Args;
use std::path::PathBuf;

super::settings_args! {
    #[derive(Args)]
    #[command(after_help = format!("Example case (relative paths are relative to the case file):\n{}", case::EXAMPLE))]
    pub struct SimulateArgs into SimulateSettings {
        pub case: PathBuf,
        #[arg(long)]
        pub out: PathBuf,
        #[arg(long, conflicts_with = "quick")]
        pub steady: bool,
        #[arg(long)]
        pub quick: bool,
        #[arg(long)]
        pub steps: Option<usize>,
        #[arg(long)]
        pub dt_s: Option<f64>,
        #[arg(long, value_parser = ["ilu", "two-level"])]
        pub preconditioner: Option<String>,
        #[arg(long, value_parser = ["backward-euler", "generalized-alpha"])]
        pub time_integration: Option<String>,
        #[arg(long)]
        pub rho_inf: Option<f64>,
        #[arg(long, value_parser = at_least_one)]
        pub cycles: Option<usize>,
        #[arg(long)]
        pub vtu_every: Option<usize>,
        #[arg(long)]
        pub resume: bool,
        #[arg(long, value_enum, default_value_t = Engine::from(SimulateSettings::default().engine))]
        pub engine: Engine,
        #[arg(long)]
        pub read_back: bool,
        #[arg(long, value_parser = at_least_one)]
        pub mpi_processes: Option<usize>,
        #[arg(long)]
        pub progress_tags: bool,
    }
    // The command line stops on SIGTERM / SIGINT.
    rest { cancel: None }
}

super::value_enum! {
    /// The solver of `baffle simulate --engine`.
    Engine mirrors PlanEngine { Embedded, Svmultiphysics }
}
