//! `baffle plan`: [prepare ->] design -> centerline -> mesh -> simulate in one run, each stage in
//! its own subfolder of --out, then report.json and report.html (see `report`). The
//! prepare stage runs when the ventricle is given as --segmentations or --labelmap
//! instead of --surface; it is then followed, after the design, by an `extend` stage
//! (paper 2.5: the LV back to a mid-LV plane and the aorta up to the sinotubular
//! junction), and the CFD runs on that extended domain: inflow at the mid-LV cap, outflow
//! at the STJ cap, dp between the VSD and aortic caps as interior planes. From --surface
//! (no LV or aorta known) the domain stays the designed one, inflow at the VSD cap.
//!
//! The stages run the commands' own code (`prepare_to_file`, `design_reporting`,
//! `run_mesh`, `run_simulate_tagged`) with the arguments a user would type for them, so the plan
//! keeps each command's defaults and checks. A stage reads its inputs from the files
//! of the stages before it, so what the report shows is what those files hold.

use crate::case::{Case, FaceRoles, Inflow, MeshSpec, OutletSpec, TimeSpec};
use crate::prepare_cmd::{self, PrepareSource};
use crate::progress::{Progress, Style};
use crate::{centerline_cmd, design_reporting, extend_cmd, mesh_cmd, report, simulate_cmd, DesignArgs};
use baffle_prepare::extend::{INFLOW_CAP_LABEL, OUTFLOW_CAP_LABEL};
use baffle_cfd::hemodynamics::{CARDIAC_INDEX_DEFAULT_L_MIN_M2, CARDIAC_INDEX_ELEVATED_L_MIN_M2};
use clap::{Args, FromArgMatches};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args)]
#[command(
    mut_arg("surface", |a| a.help("Capped ventricle (.vtp, .vtk or .stl, mm, ModelFaceID); or give --segmentations DIR, --labelmap FILE or --phantom instead")),
    after_help = "Examples:\n  \
    # quick estimate (from rest to the first flow peak) from Slicer's segment surfaces (LV, RV, aorta), CFD on the extended domain\n  \
    baffle plan --segmentations ../shared/data/p2/segmentations --points ../shared/data/p2/design_input/suture_points.mrk.json \\\n      \
    --bsa 0.37 --bp 107/78 --hr 133 --quick --edge-length-mm 1.25 --out out/plan-p2\n  \
    # the paper's pulsatile run with its mesh study, from a capped ventricle\n  \
    baffle plan --surface ../shared/data/p2/design_input/capped_ventricle.vtp --points ../shared/data/p2/design_input/suture_points.mrk.json \\\n      \
    --bsa 0.37 --bp 107/78 --hr 133 --pulsatile --mesh-study --out out/plan-p2-full\n  \
    # the built-in synthetic phantom\n  \
    baffle plan --phantom --bp 107/78 --quick --out out/plan-phantom\n\
Ends with report.json and report.html in --out; the last line printed is the verdict: PASSES, FAILS or INCONCLUSIVE (with its reason)."
)]
pub struct PlanArgs {
    #[command(flatten)]
    pub design: DesignArgs,
    /// Build the capped ventricle from segmentations or a label map first (a `prepare`
    /// stage), instead of --surface; the CFD then runs on the extended domain (an
    /// `extend` stage after the design: mid-LV inflow cap 20, STJ outflow cap 21, dp
    /// between the VSD and aortic caps as interior planes).
    #[command(flatten)]
    pub prepare: PrepareSource,
    /// Blood pressure SBP/DBP (mmHg), e.g. 107/78: the outlet resistance R = MAP / Q_mean.
    #[arg(long, value_parser = parse_bp)]
    pub bp: (f64, f64),
    /// Heart rate (beats/min); default: the built-in period of 0.682 s.
    #[arg(long)]
    pub hr: Option<f64>,
    /// Steady run with the inflow held at Q_peak. It may not converge where the peak flow
    /// is not steady (p2's and p3's extended domains); the verdict is then INCONCLUSIVE.
    #[arg(long, conflicts_with_all = ["pulsatile", "quick"])]
    pub steady: bool,
    /// Quick estimate: a pulsatile run from rest up to the first flow peak (a twentieth of
    /// 4 cycles' steps; on p2 and p3 within 0.6 % of the fourth cycle's peak dp).
    #[arg(long, conflicts_with = "pulsatile")]
    pub quick: bool,
    /// Pulsatile run over --cycles cardiac cycles (the default, as the paper).
    #[arg(long)]
    pub pulsatile: bool,
    /// Cardiac cycles of a pulsatile run (the last one is reported).
    #[arg(long, default_value_t = 4)]
    pub cycles: usize,
    /// Largest tetrahedron edge of the nominal mesh (mm); the paper used 0.95.
    #[arg(long, default_value_t = 0.95)]
    pub edge_length_mm: f64,
    /// Also mesh and simulate at the paper's coarse and fine sizes (1.25 / 0.75 mm,
    /// scaled by --edge-length-mm / 0.95).
    #[arg(long)]
    pub mesh_study: bool,
    /// Also simulate the nominal mesh at cardiac index 4.22 L/min/m2.
    #[arg(long)]
    pub elevated_flow: bool,
    /// Cardiac index of the nominal runs (L/min/m2): the mean flow is BSA x cardiac index.
    #[arg(long, default_value_t = CARDIAC_INDEX_DEFAULT_L_MIN_M2)]
    pub cardiac_index: f64,
    /// Target edge of the prepare stage's final isotropic remesh (mm; `baffle prepare
    /// --remesh-edge-mm`, default 0.5). The design remeshes the kept wall at --remesh-edge-mm.
    #[arg(long)]
    pub prepare_remesh_edge_mm: Option<f64>,
    /// How the report names the patient (default: the paper's patient id when the input
    /// lies in one of its patients' folders).
    #[arg(long)]
    pub patient_label: Option<String>,
}

pub(crate) fn parse_bp(text: &str) -> Result<(f64, f64), String> {
    let parts: Vec<&str> = text.split('/').collect();
    let numbers: Vec<f64> = parts.iter().filter_map(|p| p.trim().parse::<f64>().ok()).filter(|v| v.is_finite()).collect();
    match numbers[..] {
        [sbp, dbp] if parts.len() == 2 && dbp > 0.0 && sbp > dbp => Ok((sbp, dbp)),
        _ => Err(format!("expected SBP/DBP in mmHg with SBP > DBP > 0 (e.g. 107/78), got '{text}'")),
    }
}

/// The nominal mesh size and the paper's mesh-study sizes (mm) at 0.95 mm nominal.
const PAPER_NOMINAL_MM: f64 = 0.95;
const PAPER_COARSE_MM: f64 = 1.25;
const PAPER_FINE_MM: f64 = 0.75;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FlowCase {
    Nominal,
    Elevated,
}

impl FlowCase {
    /// The run's cardiac index: the plan's --cardiac-index, or the paper's elevated one.
    pub fn cardiac_index_l_min_m2(self, args: &PlanArgs) -> f64 {
        match self {
            FlowCase::Nominal => args.cardiac_index,
            FlowCase::Elevated => CARDIAC_INDEX_ELEVATED_L_MIN_M2,
        }
    }
}

/// What a stage does.
#[derive(Clone, Debug, PartialEq)]
pub enum Step {
    /// Segmentations or a label map -> the capped ventricle (`baffle prepare`).
    Prepare,
    Design,
    /// The designed domain -> the extended CFD domain (`baffle extend`).
    Extend,
    /// The flow-domain centerline of the designed domain (`baffle centerline`).
    Centerline,
    Mesh { level: &'static str, edge_length_mm: f64 },
    Simulate { level: &'static str, flow: FlowCase },
}

#[derive(Clone, Debug)]
pub struct Stage {
    /// Also the name of its subfolder of --out.
    pub name: String,
    pub step: Step,
    /// Share of the progress range (rough relative run time).
    pub weight: f64,
}

/// Outcome of one stage, for report.json.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StageRecord {
    pub name: String,
    pub status: &'static str,
    pub wall_time_s: Option<f64>,
    pub error: Option<String>,
}

/// (level, edge length mm) of each mesh: the nominal one first.
fn mesh_levels(args: &PlanArgs) -> Vec<(&'static str, f64)> {
    let nominal = args.edge_length_mm;
    let mut levels = vec![("nominal", nominal)];
    if args.mesh_study {
        let scale = nominal / PAPER_NOMINAL_MM;
        levels.push(("coarse", PAPER_COARSE_MM * scale));
        levels.push(("fine", PAPER_FINE_MM * scale));
    }
    levels
}

/// The source of the capped ventricle: exactly one of --surface, --segmentations,
/// --labelmap and --phantom.
fn check_one_surface_source(args: &PlanArgs) -> Result<(), String> {
    let given: Vec<&str> = [
        ("--surface", args.design.surface.is_some()),
        ("--segmentations", args.prepare.segmentations.is_some()),
        ("--labelmap", args.prepare.labelmap.is_some()),
        ("--phantom", args.design.phantom),
    ]
    .into_iter()
    .filter_map(|(flag, present)| present.then_some(flag))
    .collect();
    match given.len() {
        1 => Ok(()),
        0 => Err("baffle plan needs the ventricle: give one of --surface FILE, --segmentations DIR, --labelmap FILE or --phantom".into()),
        _ => Err(format!("baffle plan takes one source of the ventricle, got {}", given.join(" and "))),
    }
}

/// The extended domain an extend stage writes.
pub fn extended_surface_path(out: &Path) -> PathBuf {
    out.join("extend").join("extended.vtp")
}

/// Whether the CFD runs on the extended domain: the LV and aorta are known (a prepare stage).
pub fn is_extended(args: &PlanArgs) -> bool {
    args.prepare.is_given()
}

/// The capped ventricle a prepare stage writes.
pub fn prepared_surface_path(out: &Path) -> PathBuf {
    out.join("prepare").join("capped_ventricle.vtp")
}

/// Everything the stages need that can be checked before any of them runs, so a
/// missing argument is named at once rather than after minutes of work.
fn check_arguments(args: &PlanArgs) -> Result<(), String> {
    check_one_surface_source(args)?;
    if args.design.points.is_none() && !args.design.phantom {
        return Err("baffle plan needs the suture points: give --points FILE (.mrk.json, .fcsv, .csv or .json), or use --phantom".into());
    }
    // The flow is BSA x cardiac index, and the design needs its target.
    flow_bsa_m2(args)?;
    let default_bsa = args.design.phantom.then(|| baffle_core::phantom::phantom_default().bsa_m2);
    crate::target_from(&args.design.target, default_bsa)?;
    if !(args.cardiac_index.is_finite() && args.cardiac_index > 0.0) {
        return Err(format!("--cardiac-index must be a positive number of L/min/m2, got {}", args.cardiac_index));
    }
    if !(args.edge_length_mm.is_finite() && args.edge_length_mm > 0.0) {
        return Err(format!("--edge-length-mm must be a positive length, got {}", args.edge_length_mm));
    }
    if args.prepare_remesh_edge_mm.is_some() && !args.prepare.is_given() {
        return Err("--prepare-remesh-edge-mm applies to a prepare stage: give --segmentations or --labelmap".into());
    }
    Ok(())
}

pub fn plan_stages(args: &PlanArgs) -> Result<Vec<Stage>, String> {
    check_arguments(args)?;
    let simulate_weight = if args.steady || args.quick { 4.0 } else { 4.0 * args.cycles as f64 };
    let mut stages = Vec::new();
    if args.prepare.is_given() {
        stages.push(Stage { name: "prepare".into(), step: Step::Prepare, weight: 1.0 });
    }
    stages.push(Stage { name: "design".into(), step: Step::Design, weight: 1.0 });
    if is_extended(args) {
        stages.push(Stage { name: "extend".into(), step: Step::Extend, weight: 1.0 });
    }
    stages.push(Stage { name: "centerline".into(), step: Step::Centerline, weight: 0.5 });
    for (level, edge_length_mm) in mesh_levels(args) {
        stages.push(Stage { name: format!("mesh-{level}"), step: Step::Mesh { level, edge_length_mm }, weight: 1.0 });
        stages.push(Stage { name: format!("simulate-{level}"), step: Step::Simulate { level, flow: FlowCase::Nominal }, weight: simulate_weight });
    }
    if args.elevated_flow {
        let step = Step::Simulate { level: "nominal", flow: FlowCase::Elevated };
        stages.push(Stage { name: "simulate-elevated".into(), step, weight: simulate_weight });
    }
    Ok(stages)
}

/// BSA (m2) for the flow: --bsa, or the phantom's.
pub fn flow_bsa_m2(args: &PlanArgs) -> Result<f64, String> {
    match (args.design.target.bsa, args.design.phantom) {
        (Some(bsa), _) => Ok(bsa),
        (None, true) => Ok(baffle_core::phantom::phantom_default().bsa_m2),
        (None, false) => Err("baffle plan needs --bsa: the flow is BSA x cardiac index".into()),
    }
}

/// Parse `argv` as the arguments of the command whose `Args` are `A`.
fn command_args<A: Args + FromArgMatches>(name: &'static str, argv: &[OsString]) -> Result<A, String> {
    let command = A::augment_args(clap::Command::new(name).no_binary_name(true));
    let matches = command.try_get_matches_from(argv).map_err(|e| format!("{name} arguments: {e}"))?;
    A::from_arg_matches(&matches).map_err(|e| format!("{name} arguments: {e}"))
}

/// The flow-domain centerline a centerline stage writes (its figures in the .json beside it).
pub fn flow_centerline_path(out: &Path) -> PathBuf {
    out.join("centerline").join("centerline.vtp")
}

pub fn mesh_path(out: &Path, level: &str) -> PathBuf {
    out.join(format!("mesh-{level}")).join("mesh.vtu")
}

/// The `baffle simulate` case of one run, its mesh given relative to the case file.
fn simulate_case(args: &PlanArgs, level: &str, flow: FlowCase) -> Result<Case, String> {
    let mesh_dir = PathBuf::from("..").join(format!("mesh-{level}"));
    Ok(Case {
        mesh: MeshSpec {
            volume: mesh_dir.join("mesh.vtu"),
            faces: Some(mesh_dir.join("mesh-faces.vtp")),
            format: "baffle".into(),
            units: Some("mm".into()),
        },
        faces: face_roles(args),
        fluid: Default::default(),
        inflow: Inflow {
            bsa_m2: Some(flow_bsa_m2(args)?),
            cardiac_index_l_min_m2: Some(flow.cardiac_index_l_min_m2(args)),
            heart_rate_bpm: args.hr,
            profile: Some("plug".into()),
            ..Inflow::default()
        },
        outlet: OutletSpec { sbp_mmhg: Some(args.bp.0), dbp_mmhg: Some(args.bp.1), ..OutletSpec::default() },
        time: TimeSpec { mode: run_mode(args).into(), cycles: args.cycles, ..TimeSpec::default() },
        output: Default::default(),
    })
}

/// The case's time.mode: steady, quick (rest to the first flow peak) or transient.
fn run_mode(args: &PlanArgs) -> &'static str {
    match (args.steady, args.quick) {
        (true, _) => "steady",
        (_, true) => crate::case::QUICK_MODE,
        _ => "transient",
    }
}

/// Extended: inflow cap in, STJ cap out, dp between the VSD and aortic caps (interior);
/// otherwise in at the VSD cap, out at the aortic cap.
fn face_roles(args: &PlanArgs) -> FaceRoles {
    let d = &args.design;
    let walls = vec![d.wall_label, d.baffle_label];
    if is_extended(args) {
        FaceRoles { inlet: INFLOW_CAP_LABEL, outlets: vec![OUTFLOW_CAP_LABEL], walls, planes: vec![d.vsd_label, d.aortic_label] }
    } else {
        FaceRoles { inlet: d.vsd_label, outlets: vec![d.aortic_label], walls, planes: vec![] }
    }
}

fn write_case(dir: &Path, case: &Case) -> Result<PathBuf, String> {
    let path = dir.join("case.json");
    let text = serde_json::to_string_pretty(case).map_err(|e| e.to_string())?;
    crate::files::write_atomic(&path, text.as_bytes())?;
    Ok(path)
}

/// Run one stage into `dir`, its progress shown on `progress` (the stage's part of the plan's).
pub(crate) fn run_stage(args: &PlanArgs, stage: &Stage, dir: &Path, progress: &Progress) -> Result<(), String> {
    let out = &args.design.out;
    match &stage.step {
        Step::Prepare => {
            let mut argv: Vec<OsString> = vec!["--out".into(), prepared_surface_path(out).into()];
            if let Some(edge) = args.prepare_remesh_edge_mm {
                argv.extend(["--remesh-edge-mm".into(), edge.to_string().into()]);
            }
            let mut prepare = command_args::<prepare_cmd::PrepareArgs>("prepare", &argv)?;
            prepare.source = args.prepare.clone();
            progress.while_running("prepare", || prepare_cmd::prepare_to_file(&prepare)).map(|_| ())
        }
        Step::Design => {
            let prepared = args.prepare.is_given().then(|| prepared_surface_path(out));
            let design = DesignArgs { out: dir.to_path_buf(), surface: prepared.or(args.design.surface.clone()), ..args.design.clone() };
            design_reporting(&design, &mut |f, s| {
                progress.report(f, "design", s);
                true
            })
        }
        Step::Centerline => {
            let d = &args.design;
            let planes = format!("{},{}", d.vsd_label, d.aortic_label);
            let mut argv: Vec<OsString> = vec!["--planes".into(), planes.into(), "--out".into(), flow_centerline_path(out).into()];
            if is_extended(args) {
                // Paper 2.5: the medial path of the extended lumen, from the mid-LV cap to
                // the STJ cap, trimmed at the VSD and aortic caps (interior planes).
                let ends = format!("{INFLOW_CAP_LABEL},{OUTFLOW_CAP_LABEL}");
                argv.extend(["--surface".into(), extended_surface_path(out).into(), "--ends".into(), ends.into()]);
            } else {
                argv.extend(["--surface".into(), out.join("design").join("domain.vtp").into()]);
            }
            let centerline = command_args::<centerline_cmd::CenterlineArgs>("centerline", &argv)?;
            centerline_cmd::run_centerline_with(&centerline, progress)
        }
        Step::Extend => {
            let domain = out.join("design").join("domain.vtp");
            let d = &args.design;
            let mut argv: Vec<OsString> = vec!["--domain".into(), domain.into(), "--out".into(), extended_surface_path(out).into()];
            for (flag, label) in [("--wall-label", d.wall_label), ("--baffle-label", d.baffle_label), ("--vsd-label", d.vsd_label), ("--aortic-label", d.aortic_label)] {
                argv.extend([flag.into(), label.to_string().into()]);
            }
            let mut extend = command_args::<extend_cmd::ExtendArgs>("extend", &argv)?;
            extend.source = args.prepare.clone();
            progress.while_running("extend", || extend_cmd::extend_to_file(&extend)).map(|_| ())
        }
        Step::Mesh { level, edge_length_mm } => {
            let mut argv: Vec<OsString> = vec!["--edge-length-mm".into(), edge_length_mm.to_string().into(), "--out".into(), mesh_path(out, level).into()];
            if is_extended(args) {
                // The interior caps share the boundary's rim points: the boundary is meshed as built.
                let interior = format!("{},{}", args.design.vsd_label, args.design.aortic_label);
                argv.extend(["--surface".into(), extended_surface_path(out).into(), "--interior-labels".into(), interior.into()]);
            } else {
                argv.extend(["--surface".into(), out.join("design").join("domain.vtp").into(), "--remesh-surface".into()]);
            }
            mesh_cmd::run_mesh_with(&command_args::<mesh_cmd::MeshArgs>("mesh", &argv)?, progress)
        }
        Step::Simulate { level, flow } => {
            let case_path = write_case(dir, &simulate_case(args, level, *flow)?)?;
            let argv: Vec<OsString> = vec![case_path.into(), "--out".into(), dir.into()];
            let simulate = command_args::<simulate_cmd::SimulateArgs>("simulate", &argv)?;
            simulate_cmd::run_simulate_with(&simulate, progress)
        }
    }
}

pub fn run_plan(args: &PlanArgs) -> Result<(), String> {
    let stages = plan_stages(args)?;
    let out = &args.design.out;
    let progress = Progress::new(Style::detect(args.design.progress_tags), Instant::now(), (0.0, 1.0));
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let total: f64 = stages.iter().map(|s| s.weight).sum();
    let mut records: Vec<StageRecord> =
        stages.iter().map(|s| StageRecord { name: s.name.clone(), status: "not run", wall_time_s: None, error: None }).collect();
    let mut done = 0.0;
    for (k, stage) in stages.iter().enumerate() {
        let range = (done / total, (done + stage.weight) / total);
        println!("plan: stage {}/{} {} ...", k + 1, stages.len(), stage.name);
        let part = progress.part(range);
        part.report(0.0, &stage.name, "starting");
        let dir = out.join(&stage.name);
        let start = Instant::now();
        let result = std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display())).and_then(|_| run_stage(args, stage, &dir, &part));
        part.finish(None);
        let record = &mut records[k];
        record.wall_time_s = Some(start.elapsed().as_secs_f64());
        if let Err(e) = result {
            // A failed stage's folder goes if it holds nothing (remove_dir only removes empty ones).
            let _ = std::fs::remove_dir(&dir);
            record.status = "failed";
            record.error = Some(e.clone());
            report::write_failure_json(out, &stage.name, &e, &records)?;
            let kept: Vec<String> = stages[..k].iter().map(|s| out.join(&s.name).display().to_string()).collect();
            let kept = if kept.is_empty() { "none".to_string() } else { kept.join(", ") };
            return Err(format!("stage {} failed: {e}\n(finished stages' files kept: {kept})", stage.name));
        }
        record.status = "completed";
        println!("plan: stage {} done in {:.1} s", stage.name, record.wall_time_s.unwrap_or(0.0));
        done += stage.weight;
    }
    progress.report(1.0, "report", "writing the report and rendering its pictures (VTK)");
    let outcome = report::write_reports(args, &stages, &records)?;
    progress.report(1.0, "report", "written");
    progress.finish(None);
    println!("wrote {} and {}", out.join("report.json").display(), out.join("report.html").display());
    for warning in &outcome.warnings {
        println!("warning: {warning}");
    }
    if let Some(reason) = &outcome.pictures_missing {
        println!("note: the report has no 3D pictures: {reason}");
    }
    // The verdict is the last line: PASSES, FAILS or INCONCLUSIVE with its reason.
    println!("{}", outcome.verdict_line);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stage_names(source: &[&str]) -> Vec<String> {
        let mut argv: Vec<OsString> = source.iter().map(OsString::from).collect();
        argv.extend(["--points", "p.mrk.json", "--bsa", "0.37", "--bp", "107/78", "--out", "o"].map(OsString::from));
        let args = command_args::<PlanArgs>("plan", &argv).unwrap();
        plan_stages(&args).unwrap().into_iter().map(|s| s.name).collect()
    }

    #[test]
    fn segmentations_or_a_label_map_put_a_prepare_stage_first() {
        let rest = ["design", "centerline", "mesh-nominal", "simulate-nominal"];
        let extended = ["design", "extend", "centerline", "mesh-nominal", "simulate-nominal"];
        assert_eq!(stage_names(&["--segmentations", "seg"]), [&["prepare"][..], &extended].concat());
        assert_eq!(stage_names(&["--labelmap", "heart.nrrd", "--aorta-label", "8"]), [&["prepare"][..], &extended].concat());
        assert_eq!(stage_names(&["--surface", "capped.vtp"]), rest);
    }

    #[test]
    fn blood_pressure_is_sbp_over_dbp() {
        assert_eq!(parse_bp("107/78").unwrap(), (107.0, 78.0));
        for bad in ["78/107", "107", "107/78/1", "a/b", "107/0"] {
            assert!(parse_bp(bad).unwrap_err().contains(bad), "{bad}");
        }
    }
}
