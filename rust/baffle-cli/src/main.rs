//! `baffle`: area-constrained DORV baffle design from the command line. This crate only
//! parses the arguments; the commands' work is the library `baffle-plan`'s.

mod args;

use baffle_plan::error::PlanError;
use baffle_plan::progress::{Console, Progress};
use baffle_plan::{centerline_cmd, design_cmd, export_cmd, extend_cmd, mesh_cmd, plan_cmd, prepare_cmd, simulate_cmd, sweep_cmd, template_cmd};
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

#[derive(Parser)]
#[command(name = "baffle", version, about = "Area-constrained baffle design for DORV repair (Martinez et al.)")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Design the area-constrained baffle and the watertight VSD-to-aorta domain.
    ///
    /// Writes into --out: domain.vtp (closed, outward, ModelFaceID 2 wall / 10 baffle /
    /// 11 VSD cap / 16 aortic cap), baffle.vtp, centerline.vtp (point arrays s_mm,
    /// tangent), sections.vtp (raw and regularized baffle arcs), seam.vtp and
    /// report.json (target, per-section areas and amplitudes, step timings).
    #[command(after_help = "Examples:\n  \
        baffle design --surface ../shared/data/p2/design_input/capped_ventricle.vtp \\\n      \
        --points ../shared/data/p2/design_input/suture_points.mrk.json --bsa 0.37 --out out/p2\n  \
        baffle design --surface capped.stl --vsd-cap-point 1,2,3 --aortic-cap-point 4,5,6 --points P.fcsv --annulus-diameter-mm 12 --out out/x\n  \
        baffle design --phantom --out out/phantom")]
    Design(args::design::DesignArgs),
    /// The capped ventricle (design input) from segmented LV, RV and aorta surfaces.
    Prepare(args::prepare::PrepareArgs),
    /// The extended CFD domain (paper 2.5): the designed domain plus the LV back to a
    /// mid-LV plane (inflow cap, 20) and the aorta up to the sinotubular junction
    /// (outflow cap, 21); the VSD and aortic caps stay inside as measurement planes.
    Extend(args::extend::ExtendArgs),
    /// Tetrahedral volume mesh of a closed labelled surface (gmsh, run as a separate process).
    Mesh(args::mesh::MeshArgs),
    /// CFD on a volume mesh from a JSON case (embedded solver; results in mm, m/s, mmHg; SIGTERM stops with results).
    Simulate(args::simulate::SimulateArgs),
    /// Flow-domain centerline of a closed lumen between two measurement planes (paper
    /// 2.5): length, inscribed radii and, with --results, v_max and pressure along it.
    Centerline(args::centerline::CenterlineArgs),
    /// Write the same case for svMultiPhysics (the paper's MPI solver), to run on a cluster.
    ExportSvmp(args::export::ExportArgs),
    /// Prepare (from --segmentations or --labelmap), design, mesh and simulate in one run,
    /// and write report.json and report.html.
    Plan(args::plan::PlanArgs),
    /// True-scale patch template (A4 PDF or SVG): the designed baffle flattened, suture
    /// points numbered, VSD and aortic rims, 10 mm scale bar and check square.
    Template(args::template::TemplateArgs),
    /// Designs at several targets on one input (--z-scores or --areas-mm2): a table
    /// (CSV, markdown, JSON) and a plot (SVG) of baffle area, RV volume and the largest
    /// feasible target, so the team sees what a larger tunnel costs the ventricle.
    Sweep(args::sweep::SweepArgs),
    /// Write the built-in synthetic phantom (capped ventricle + suture points).
    Phantom {
        /// Output directory (gets capped_ventricle.vtp and suture_points.mrk.json).
        #[arg(long)]
        out: PathBuf,
        /// Write the synthetic heart as segment surfaces instead (LV.vtp, RV.vtp, aorta.vtp
        /// and suture_points.mrk.json, BSA 0.2 m2): the input of `baffle plan --segmentations`.
        #[arg(long)]
        heart: bool,
        /// How far the phantom's suture loop wraps round the tunnel from its outermost
        /// line, as a section angle (degrees; default 70). Wider loops leave the sections
        /// near the caps less baffle to widen, so large targets become infeasible.
        #[arg(long, conflicts_with = "heart")]
        suture_half_angle_deg: Option<f64>,
    },
}

fn main() -> ExitCode {
    restore_default_sigpipe();
    let cli = parse_arguments();
    let result = run(cli.command);
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("baffle: error: {message}");
            ExitCode::FAILURE
        }
    }
}

/// Run the command, its progress and lines on this terminal: Slicer's progress tags with
/// `baffle simulate --progress-tags` and `baffle plan --progress-tags` (`baffle design`
/// writes its own).
fn run(command: Command) -> Result<(), PlanError> {
    let tags = match &command {
        Command::Simulate(args) => args.progress_tags,
        Command::Plan(args) => args.design.progress_tags,
        _ => false,
    };
    let progress = Progress::start(Arc::new(Terminal), tags);
    let p = &progress;
    let result = match command {
        Command::Design(args) => design_cmd::run_design(&args.into(), p),
        Command::Prepare(args) => prepare_cmd::run_prepare(&args.into(), p),
        Command::Extend(args) => extend_cmd::run_extend(&args.into(), p),
        Command::Mesh(args) => mesh_cmd::run_mesh(&args.into(), p),
        Command::Simulate(args) => simulate_cmd::run_simulate(&args.into(), p),
        Command::Centerline(args) => centerline_cmd::run_centerline(&args.into(), p),
        Command::ExportSvmp(args) => export_cmd::run_export(&args.into(), p),
        Command::Plan(args) => plan_cmd::run_plan(&args.into(), p).map(|_| ()),
        Command::Template(args) => template_cmd::run_template(&args.into(), p),
        Command::Sweep(args) => sweep_cmd::run_sweep(&args.into(), p),
        Command::Phantom { out, heart: false, suture_half_angle_deg } => design_cmd::write_phantom(&out, suture_half_angle_deg, p),
        Command::Phantom { out, heart: true, .. } => prepare_cmd::write_synthetic_heart(&out, p),
    };
    progress.finish(None);
    result
}

/// The command's lines (and Slicer's tags) on stdout, its progress on stderr.
struct Terminal;

impl Console for Terminal {
    fn line(&self, text: &str) {
        println!("{text}");
    }

    fn status(&self, text: &str) {
        let mut err = std::io::stderr().lock();
        let _ = err.write_all(text.as_bytes());
        let _ = err.flush();
    }

    fn status_is_terminal(&self) -> bool {
        std::io::stderr().is_terminal()
    }
}

/// The arguments, where a value may be a negative number after a space (`--z-score -2`,
/// `--bsa -1`): such a value then reaches the option's own range check, which names it,
/// instead of being taken for an unknown flag.
fn parse_arguments() -> Cli {
    let negative_values = |arg: clap::Arg| if arg.get_action().takes_values() { arg.allow_negative_numbers(true) } else { arg };
    let command = Cli::command().mut_subcommands(|sub| sub.mut_args(negative_values));
    Cli::from_arg_matches(&command.get_matches()).unwrap_or_else(|e| e.exit())
}

/// Rust starts with SIGPIPE ignored, so printing to a closed pipe (`baffle mesh | head`)
/// panics; the default action ends the command quietly, as other command-line tools.
fn restore_default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first in main, before any thread exists; sets a standard disposition.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

