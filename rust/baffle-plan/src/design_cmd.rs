//! `baffle`: area-constrained DORV baffle design from the command line.

use baffle_core::io::{read_points, read_surface_labeled, write_markups_closed_curve, write_trimesh_vtp, CoordinateSystem};
use baffle_core::caps::{label_planar_caps, CapSeed, CapTolerances};
use baffle_core::outputs::write_design_outputs;
use baffle_core::phantom::phantom_default;
use baffle_core::{design, DesignOptions, FaceLabels, TargetArea, TriMesh, Vec3};
use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

mod case;
mod centerline_cmd;
mod export_cmd;
mod extend_cmd;
mod mesh_cmd;
mod plan_cmd;
mod prepare_cmd;
mod progress;
mod report;
mod sampling;
mod feasibility;
mod files;
mod simulate_cmd;
mod simulate_svmp;
mod sweep_cmd;
mod template_cmd;
mod verdict;

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
    Design(DesignArgs),
    /// The capped ventricle (design input) from segmented LV, RV and aorta surfaces.
    Prepare(prepare_cmd::PrepareArgs),
    /// The extended CFD domain (paper 2.5): the designed domain plus the LV back to a
    /// mid-LV plane (inflow cap, 20) and the aorta up to the sinotubular junction
    /// (outflow cap, 21); the VSD and aortic caps stay inside as measurement planes.
    Extend(extend_cmd::ExtendArgs),
    /// Tetrahedral volume mesh of a closed labelled surface (gmsh, run as a separate process).
    Mesh(mesh_cmd::MeshArgs),
    /// CFD on a volume mesh from a JSON case (embedded solver; results in mm, m/s, mmHg; SIGTERM stops with results).
    Simulate(simulate_cmd::SimulateArgs),
    /// Flow-domain centerline of a closed lumen between two measurement planes (paper
    /// 2.5): length, inscribed radii and, with --results, v_max and pressure along it.
    Centerline(centerline_cmd::CenterlineArgs),
    /// Write the same case for svMultiPhysics (the paper's MPI solver), to run on a cluster.
    ExportSvmp(export_cmd::ExportArgs),
    /// Prepare (from --segmentations or --labelmap), design, mesh and simulate in one run,
    /// and write report.json and report.html.
    Plan(plan_cmd::PlanArgs),
    /// True-scale patch template (A4 PDF or SVG): the designed baffle flattened, suture
    /// points numbered, VSD and aortic rims, 10 mm scale bar and check square.
    Template(template_cmd::TemplateArgs),
    /// Designs at several targets on one input (--z-scores or --areas-mm2): a table
    /// (CSV, markdown, JSON) and a plot (SVG) of baffle area, RV volume and the largest
    /// feasible target, so the team sees what a larger tunnel costs the ventricle.
    Sweep(sweep_cmd::SweepArgs),
    /// Write the built-in synthetic phantom (capped ventricle + suture points).
    Phantom {
        /// Output directory (gets capped_ventricle.vtp and suture_points.mrk.json).
        #[arg(long)]
        out: PathBuf,
        /// Write the synthetic heart as segment surfaces instead (LV.vtp, RV.vtp, aorta.vtp
        /// and suture_points.mrk.json, BSA 0.2 m2): the input of `baffle plan --segmentations`.
        #[arg(long)]
        heart: bool,
    },
}

// Required-ness of --surface/--points is checked at run time (read_inputs), so that
// `baffle plan` can offer other sources of the surface.
#[derive(Args, Clone)]
struct DesignArgs {
    /// Closed, labelled ventricle surface (.vtp, .vtk or .stl), in mm (required unless --phantom).
    #[arg(long)]
    surface: Option<PathBuf>,
    /// Suture points: Slicer markups (.mrk.json), .fcsv, CSV (x,y,z per line) or JSON (required unless --phantom).
    #[arg(long)]
    points: Option<PathBuf>,
    /// Use the built-in synthetic phantom as surface and points (BSA 0.37 m2 unless given).
    #[arg(long, conflicts_with_all = ["surface", "points"])]
    phantom: bool,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    target: TargetArgs,
    /// Frame of the surface file; suture points are converted into it. Slicer writes
    /// models in LPS.
    #[arg(long, value_enum, default_value_t = Frame::Lps)]
    surface_frame: Frame,
    /// Target edge length of the isotropic remeshing of the kept wall (mm).
    #[arg(long, default_value_t = 0.85)]
    remesh_edge_mm: f64,
    /// Keep the input's wall triangles (no isotropic remeshing).
    #[arg(long)]
    no_remesh: bool,
    /// Target edge length of the baffle (mm).
    #[arg(long, default_value_t = 0.85)]
    baffle_edge_mm: f64,
    /// Points the seam spline is resampled at.
    #[arg(long, default_value_t = 600)]
    seam_samples: usize,
    /// Centerline section spacing (mm).
    #[arg(long, default_value_t = 0.5)]
    centerline_spacing_mm: f64,
    /// Interior TPS control points of the initial patch.
    #[arg(long, default_value_t = 9)]
    control_points: usize,
    /// Largest distance of a suture point from the surface (mm).
    #[arg(long, default_value_t = 2.0)]
    max_point_distance_mm: f64,
    /// ModelFaceID of the RV wall.
    #[arg(long, default_value_t = 2)]
    wall_label: i32,
    /// ModelFaceID given to the baffle.
    #[arg(long, default_value_t = 10)]
    baffle_label: i32,
    /// ModelFaceID of the VSD cap.
    #[arg(long, default_value_t = 11)]
    vsd_label: i32,
    /// ModelFaceID of the aortic-annulus cap.
    #[arg(long, default_value_t = 16)]
    aortic_label: i32,
    /// A point (x,y,z in the surface's frame, mm) on the VSD cap: labels the planar
    /// cap around it. Needed for surfaces without ModelFaceID (.stl, plain .vtk).
    #[arg(long, value_parser = parse_point, requires = "aortic_cap_point", allow_hyphen_values = true)]
    vsd_cap_point: Option<Vec3>,
    /// A point on the aortic-annulus cap (see --vsd-cap-point).
    #[arg(long, value_parser = parse_point, requires = "vsd_cap_point", allow_hyphen_values = true)]
    aortic_cap_point: Option<Vec3>,
    /// A reference baffle to compare with (area ratio, symmetric surface distance),
    /// written to reference_comparison.json; e.g. the paper's published_baffle.vtp.
    #[arg(long)]
    reference_baffle: Option<PathBuf>,
    /// Scale of the reference's coordinates to mm (10 for the published files, in cm).
    #[arg(long, default_value_t = 1.0)]
    reference_scale: f64,
    /// Print Slicer CLI progress tags (<filter-progress>) instead of a summary.
    #[arg(long)]
    progress_tags: bool,
}

#[derive(Args, Clone)]
struct TargetArgs {
    /// Target cross-section area (mm2).
    #[arg(long, group = "target_kind")]
    target_area_mm2: Option<f64>,
    /// Target aortic annulus diameter (mm): A = pi (D/2)^2.
    #[arg(long, group = "target_kind")]
    annulus_diameter_mm: Option<f64>,
    /// Body surface area (m2): Boston (Colan 2006) aortic annulus at --z-score.
    #[arg(long, group = "target_kind")]
    bsa: Option<f64>,
    /// Height (cm), with --weight-kg: Haycock BSA, then the Boston annulus.
    #[arg(long, requires = "weight_kg", group = "target_kind")]
    height_cm: Option<f64>,
    /// Weight (kg), with --height-cm.
    #[arg(long, requires = "height_cm")]
    weight_kg: Option<f64>,
    /// Annulus z-score for --bsa or --height-cm/--weight-kg.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    z_score: f64,
}

/// The frame a surface's coordinates are in (the points are converted into it).
#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum Frame {
    Lps,
    Ras,
}

impl From<Frame> for CoordinateSystem {
    fn from(f: Frame) -> Self {
        match f {
            Frame::Lps => CoordinateSystem::Lps,
            Frame::Ras => CoordinateSystem::Ras,
        }
    }
}

fn main() -> ExitCode {
    restore_default_sigpipe();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Design(args) => run_design(&args),
        Command::Prepare(args) => prepare_cmd::run_prepare(&args),
        Command::Extend(args) => extend_cmd::run_extend(&args),
        Command::Mesh(args) => mesh_cmd::run_mesh(&args),
        Command::Simulate(args) => simulate_cmd::run_simulate(&args),
        Command::Centerline(args) => centerline_cmd::run_centerline(&args),
        Command::ExportSvmp(args) => export_cmd::run_export(&args),
        Command::Plan(args) => plan_cmd::run_plan(&args),
        Command::Template(args) => template_cmd::run_template(&args),
        Command::Sweep(args) => sweep_cmd::run_sweep(&args),
        Command::Phantom { out, heart: false } => write_phantom(&out),
        Command::Phantom { out, heart: true } => prepare_cmd::write_synthetic_heart(&out),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("baffle: error: {message}");
            ExitCode::FAILURE
        }
    }
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

fn target_from(args: &TargetArgs, default_bsa_m2: Option<f64>) -> Result<TargetArea, String> {
    let z_score = args.z_score;
    if let Some(a) = args.target_area_mm2 {
        return Ok(TargetArea::AreaMm2(a));
    }
    if let Some(d) = args.annulus_diameter_mm {
        return Ok(TargetArea::AnnulusDiameterMm(d));
    }
    if let (Some(height_cm), Some(weight_kg)) = (args.height_cm, args.weight_kg) {
        return Ok(TargetArea::HeightWeight { height_cm, weight_kg, z_score });
    }
    match args.bsa.or(default_bsa_m2) {
        Some(bsa_m2) => Ok(TargetArea::Bsa { bsa_m2, z_score }),
        None => Err("give the target: --bsa, --height-cm and --weight-kg, --target-area-mm2 or --annulus-diameter-mm".into()),
    }
}

fn run_design(args: &DesignArgs) -> Result<(), String> {
    let tags = args.progress_tags;
    design_reporting(args, &mut |fraction, stage| {
        if tags {
            print_progress_tag(fraction, stage);
        }
        true
    })
}

/// A Slicer CLI progress tag and the stage it is in, on stdout.
fn print_progress_tag(fraction: f64, stage: &str) {
    println!("<filter-progress>{fraction:.3}</filter-progress>\n<filter-stage>{stage}</filter-stage>");
}

/// `baffle design` with the progress sent to `progress`.
fn design_reporting(args: &DesignArgs, progress: &mut dyn FnMut(f64, &str) -> bool) -> Result<(), String> {
    // Options first: a bad number is refused before any file is read.
    let options = design_options(args)?;
    let (surface, points, default_bsa) = design_inputs(args)?;
    let target = target_from(&args.target, default_bsa)?;
    let result = design(&surface, &points, &target, &options, progress).map_err(|e| feasibility::design_failure(&args.out, e))?;
    write_design_outputs(&args.out, &result).map_err(|e| e.to_string())?;
    let r = &result.report;
    println!(
        "target {:.1} mm2 ({}); centerline {:.2} mm; baffle {:.1} mm2, {} triangles; {} constrained sections, smallest {:.1} mm2; {:.0} ms",
        r.target_area_mm2,
        r.target,
        r.centerline_length_mm,
        r.baffle_area_mm2,
        r.baffle_triangles,
        r.constrained_sections,
        r.min_constrained_final_area_mm2,
        r.timings.total_ms
    );
    println!("{}", rv_cost_line(&r.rv_cost));
    if let Some(path) = &args.reference_baffle {
        compare_with_reference(&result.baffle, path, args.reference_scale, &args.out)?;
    }
    println!("wrote {}", args.out.display());
    Ok(())
}

/// Surface, suture points (in the surface's frame) and the BSA that comes with the
/// phantom (None for files).
fn design_inputs(args: &DesignArgs) -> Result<(TriMesh, Vec<Vec3>, Option<f64>), String> {
    if args.phantom {
        let p = phantom_default();
        return Ok((p.surface, p.suture_points_mm, Some(p.bsa_m2)));
    }
    let (surface, points) = read_inputs(args)?;
    Ok((surface, points, None))
}

/// The RV cost in one line, saying when the baffle leaves the capped ventricle (then the
/// volumes are net figures, e.g. on an input that encloses only the pathway).
fn rv_cost_line(c: &baffle_core::rv_cost::RvCost) -> String {
    let line = format!(
        "RV (capped ventricle) {:.2} mL before, {:.2} mL after the baffle (the pathway takes {:.2} mL)",
        c.rv_volume_before_ml, c.rv_volume_after_ml, c.rv_volume_taken_ml
    );
    match c.baffle_area_outside_ventricle_mm2 {
        a if a > 0.0 => format!("{line}; {a:.1} mm2 of the baffle lies outside the capped ventricle, so these are net volumes, not the RV cavity"),
        _ => line,
    }
}

/// The design options of the command line, range-checked in the one place the C ABI also uses.
fn design_options(args: &DesignArgs) -> Result<DesignOptions, String> {
    let options = DesignOptions {
        labels: FaceLabels {
            wall: args.wall_label,
            baffle: args.baffle_label,
            vsd_cap: args.vsd_label,
            aortic_cap: args.aortic_label,
        },
        seam_samples: args.seam_samples,
        max_point_distance_mm: args.max_point_distance_mm,
        remesh_edge_mm: (!args.no_remesh).then_some(args.remesh_edge_mm),
        baffle_edge_mm: args.baffle_edge_mm,
        interior_control_points: args.control_points,
        centerline_spacing_mm: args.centerline_spacing_mm,
        ..DesignOptions::default()
    };
    options.validate().map_err(|e| e.to_string())?;
    Ok(options)
}

fn compare_with_reference(baffle: &TriMesh, path: &Path, scale: f64, out: &Path) -> Result<(), String> {
    let mut reference = baffle_core::io::read_surface(path).map_err(|e| e.to_string())?;
    reference.points.iter_mut().for_each(|p| *p *= scale);
    let c = baffle_core::compare::compare_surfaces(baffle, &reference).map_err(|e| format!("{}: {e}", path.display()))?;
    println!(
        "reference {}: area {:.1} vs {:.1} mm2 (ratio {:.3}); symmetric surface distance mean {:.2} mm, max {:.2} mm",
        path.display(),
        c.area_mm2,
        c.reference_area_mm2,
        c.area_ratio,
        c.mean_distance_mm,
        c.max_distance_mm
    );
    let file = out.join("reference_comparison.json");
    let text = serde_json::to_string_pretty(&c).map_err(|e| e.to_string())?;
    files::write_atomic(&file, text.as_bytes())
}

fn read_inputs(args: &DesignArgs) -> Result<(TriMesh, Vec<Vec3>), String> {
    let (Some(surface_path), Some(points_path)) = (&args.surface, &args.points) else {
        return Err("--surface and --points are required (or --phantom)".into());
    };
    let labeled = read_surface_labeled(surface_path).map_err(|e| e.to_string())?;
    let mut mesh = labeled.mesh;
    if let (Some(vsd), Some(aortic)) = (args.vsd_cap_point, args.aortic_cap_point) {
        let seeds = [CapSeed { point_mm: vsd, label: args.vsd_label }, CapSeed { point_mm: aortic, label: args.aortic_label }];
        mesh.face_ids = label_planar_caps(&mesh, &seeds, args.wall_label, &CapTolerances::default())
            .map_err(|e| format!("{}: {e}", surface_path.display()))?;
    } else if !labeled.has_model_face_id {
        return Err(format!(
            "{}: no ModelFaceID cell array; give --vsd-cap-point and --aortic-cap-point to label the caps",
            surface_path.display()
        ));
    }
    let points = read_points(points_path).map_err(|e| e.to_string())?;
    Ok((mesh, points.to_frame(args.surface_frame.into())))
}

fn parse_point(text: &str) -> Result<Vec3, String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|_| format!("'{v}' is not a number")))
        .collect::<Result<_, _>>()?;
    match values[..] {
        [x, y, z] if values.iter().all(|v| v.is_finite()) => Ok(Vec3::new(x, y, z)),
        _ => Err(format!("expected x,y,z (three finite numbers), got '{text}'")),
    }
}

fn write_phantom(out: &Path) -> Result<(), String> {
    let p = phantom_default();
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    write_trimesh_vtp(&out.join("capped_ventricle.vtp"), &p.surface).map_err(|e| e.to_string())?;
    write_markups_closed_curve(&out.join("suture_points.mrk.json"), "BC", &p.suture_points_mm, CoordinateSystem::Lps)
        .map_err(|e| e.to_string())?;
    println!("wrote {} (BSA {} m2)", out.display(), p.bsa_m2);
    Ok(())
}
