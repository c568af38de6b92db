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
        /// Case file (JSON): mesh, face roles, fluid, inflow, outlet, time stepping, output.
        pub case: PathBuf,
        /// Output directory: summary.json, timeseries.csv, peak.vtu, final.vtu, checkpoint.json
        /// (with --engine svmultiphysics: summary.json, timeseries.csv, peak.vtu, svmultiphysics/).
        /// The .vtu files are in mm like every surface (they overlay the domain without
        /// scaling), with point arrays velocity_m_s (vector), speed_m_s and pressure_mmhg.
        /// summary.json and timeseries.csv give pressures in mmHg, velocities in m/s, flows
        /// in mL/s.
        #[arg(long)]
        pub out: PathBuf,
        /// Steady run with the inflow held at Q_peak (overrides time.mode), a quick estimate
        /// of the peak dp. summary.json: q_held_ml_s is the held flow, q_mean_ml_s the case's
        /// mean flow; outlet_mean_pressure_mmhg is R x Q_peak, far above MAP because R = MAP /
        /// Q_mean. dp is unaffected: with rigid walls the outlet pressure only offsets the
        /// pressure field uniformly.
        #[arg(long, conflicts_with = "quick")]
        pub steady: bool,
        /// Quick estimate of the peak dp (overrides time.mode with "quick"): time-accurate
        /// from rest up to the first flow peak of the waveform (about 110-170 steps instead of
        /// 4 cycles); unlike --steady it converges where the peak flow is not steady.
        #[arg(long)]
        pub quick: bool,
        /// Stop after this time step (overrides time.steps).
        #[arg(long)]
        pub steps: Option<usize>,
        /// Time step (s) (overrides time.dt_s).
        #[arg(long)]
        pub dt_s: Option<f64>,
        /// Preconditioner of the linear solves: ilu or two-level (overrides time.preconditioner).
        #[arg(long, value_parser = ["ilu", "two-level"])]
        pub preconditioner: Option<String>,
        /// Time integration of a transient run: backward-euler or generalized-alpha (second
        /// order, as svMultiPhysics; overrides time.time_integration).
        #[arg(long, value_parser = ["backward-euler", "generalized-alpha"])]
        pub time_integration: Option<String>,
        /// Generalized-alpha's spectral radius at infinite time step, 0-1 (default 0.5;
        /// overrides time.rho_inf).
        #[arg(long)]
        pub rho_inf: Option<f64>,
        /// Cardiac cycles (overrides time.cycles).
        #[arg(long, value_parser = at_least_one)]
        pub cycles: Option<usize>,
        /// Write fields_<step>.vtu every N steps (overrides output.vtu_every_steps).
        #[arg(long)]
        pub vtu_every: Option<usize>,
        /// Continue the run (transient, or with --steady the steady solve) from OUT/checkpoint.json.
        #[arg(long)]
        pub resume: bool,
        /// Solver: the embedded one, or svMultiPhysics (exported to OUT/svmultiphysics/ and
        /// run there with mpiexec; needs svmultiphysics or svMultiPhysics, and mpiexec, on PATH).
        #[arg(long, value_enum, default_value_t = Engine::from(SimulateSettings::default().engine))]
        pub engine: Engine,
        /// With --engine svmultiphysics: read back the case already exported to
        /// OUT/svmultiphysics/ and run elsewhere (a cluster; the directory copied back in
        /// place), without exporting or running it again. It must be this case's export.
        #[arg(long)]
        pub read_back: bool,
        /// MPI processes of an svMultiPhysics run (default: the available cores).
        #[arg(long, value_parser = at_least_one)]
        pub mpi_processes: Option<usize>,
        /// Print Slicer CLI progress tags (<filter-progress>) on stdout (also with
        /// BAFFLE_PROGRESS_TAGS=1). Otherwise: a bar on a terminal, plain lines in a log (stderr).
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
