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
//! `run_mesh`, `run_simulate`) with each command's typed options: its defaults
//! (`Default`) and the plan's values, so the plan keeps each command's defaults and checks. A stage reads its inputs from the files
//! of the stages before it, so what the report shows is what those files hold.

use crate::error::PlanError;
use crate::case::{Case, FaceRoles, Inflow, MeshSpec, OutletSpec, TimeSpec};
use crate::design_cmd::{design_reporting, DesignSettings};
use crate::plan_stages::{
    flow_bsa_m2, is_extended, plan_stages, FlowCase, PlanLayout, PlanSettings, Stage, StageRecord, Step,
};
use crate::centerline_cmd::{self, CenterlineSettings};
use crate::extend_cmd::{self, ExtendSettings};
use crate::mesh_cmd::{self, MeshSettings};
use crate::prepare_cmd::{self, PrepareSettings};
use crate::progress::Progress;
use crate::report;
use crate::simulate_cmd::{self, SimulateSettings};
use baffle_prepare::extend::{INFLOW_CAP_LABEL, OUTFLOW_CAP_LABEL};
use crate::verdict::{Verdict, DP_THRESHOLD_MMHG};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The `baffle simulate` case of one run, its mesh given relative to the case file.
fn simulate_case(args: &PlanSettings, level: &str, flow: FlowCase) -> Result<Case, String> {
    let mesh_dir = PathBuf::from("..").join(format!("mesh-{level}"));
    plan_case(args, &mesh_dir.join("mesh.vtu"), &mesh_dir.join("mesh-faces.vtp"), flow)
}

/// The case the plan simulates (face roles, inflow from BSA x cardiac index, outlet from
/// the blood pressure, the run's mode) for the volume mesh `volume` with its labelled
/// faces `faces` (as `baffle mesh` writes them; relative paths are relative to the case
/// file): the plan's own stages and a front end that meshes by itself (the Slicer
/// module) simulate the same case.
pub fn plan_case(args: &PlanSettings, volume: &Path, faces: &Path, flow: FlowCase) -> Result<Case, String> {
    Ok(Case {
        mesh: MeshSpec { volume: volume.to_path_buf(), faces: Some(faces.to_path_buf()), format: "baffle".into(), units: Some("mm".into()) },
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
fn run_mode(args: &PlanSettings) -> &'static str {
    match (args.steady, args.quick) {
        (true, _) => "steady",
        (_, true) => crate::case::QUICK_MODE,
        _ => "transient",
    }
}

/// Extended: inflow cap in, STJ cap out, dp between the VSD and aortic caps (interior);
/// otherwise in at the VSD cap, out at the aortic cap.
fn face_roles(args: &PlanSettings) -> FaceRoles {
    let d = &args.design;
    let walls = vec![d.labels.wall, d.labels.baffle];
    if is_extended(args) {
        FaceRoles { inlet: INFLOW_CAP_LABEL, outlets: vec![OUTFLOW_CAP_LABEL], walls, planes: vec![d.labels.vsd_cap, d.labels.aortic_cap] }
    } else {
        FaceRoles { inlet: d.labels.vsd_cap, outlets: vec![d.labels.aortic_cap], walls, planes: vec![] }
    }
}

/// Write `case` as `dir`/case.json (atomically; `dir` made if missing), after checking it
/// as `baffle simulate` will (physiological inputs, time stepping), so a bad case is
/// refused here and nothing is written.
pub fn write_case(dir: &Path, case: &Case) -> Result<PathBuf, String> {
    crate::case::settings(case)?;
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let path = dir.join("case.json");
    let text = serde_json::to_string_pretty(case).map_err(|e| e.to_string())?;
    crate::files::write_atomic(&path, text.as_bytes())?;
    Ok(path)
}

/// The peak flow the design's reduced-order estimate is made at (ml/s): --peak-flow-ml-s
/// when given, else the nominal CFD case's own (BSA x cardiac index through its inflow
/// waveform), so the plan's design/report.json always holds the estimate (issue 31).
fn design_peak_flow_ml_s(args: &PlanSettings) -> Result<f64, String> {
    if let Some(q) = args.design.peak_flow_ml_s {
        return Ok(q);
    }
    let case = simulate_case(args, "nominal", FlowCase::Nominal)?;
    let (_, flow) = crate::case::settings(&case).map_err(|e| format!("the nominal CFD case's peak flow (for the design's estimate): {e}"))?;
    Ok(flow.q_peak_ml_s)
}

/// Run one stage into `dir`, its progress shown on `progress` (the stage's part of the plan's).
pub(crate) fn run_stage(args: &PlanSettings, stage: &Stage, dir: &Path, progress: &Progress) -> Result<(), PlanError> {
    run_stage_cancellable(args, stage, dir, progress, None)
}

/// [`run_stage`], the design and the embedded simulation asking `cancel` as they run when
/// it is given (without it the simulation stops on SIGTERM / SIGINT, as `baffle simulate`).
fn run_stage_cancellable(args: &PlanSettings, stage: &Stage, dir: &Path, progress: &Progress, cancel: Option<&Cancel>) -> Result<(), PlanError> {
    match &stage.step {
        Step::Prepare => progress.while_running("prepare", || prepare_cmd::prepare_to_file(&prepare_stage(args), progress)).map(|_| ()),
        Step::Design => {
            let design = design_stage(args, dir).map_err(PlanError::Design)?;
            design_reporting(&design, progress, &mut |f, s| {
                progress.report(f, "design", s);
                !cancel.is_some_and(|c| c())
            })
        }
        Step::Centerline => centerline_cmd::run_centerline(&centerline_stage(args), progress),
        Step::Extend { level, remesh_domain_edge_mm } => {
            let extend = extend_stage(args, *level, *remesh_domain_edge_mm);
            progress.while_running("extend", || extend_cmd::extend_to_file(&extend)).map(|_| ())
        }
        Step::Mesh { level, edge_length_mm } => mesh_cmd::run_mesh(&mesh_stage(args, level, *edge_length_mm), progress),
        Step::Simulate { level, flow } => {
            let case = simulate_case(args, level, *flow).and_then(|case| write_case(dir, &case)).map_err(PlanError::Simulate)?;
            let settings = SimulateSettings { case, out: dir.to_path_buf(), cancel: cancel.cloned(), ..SimulateSettings::default() };
            simulate_cmd::run_simulate(&settings, progress)
        }
    }
}

/// The prepare stage: `baffle prepare`'s defaults, the plan's source and remesh edge.
fn prepare_stage(args: &PlanSettings) -> PrepareSettings {
    let defaults = PrepareSettings::default();
    PrepareSettings {
        source: args.prepare.clone(),
        out: PlanLayout::of(args).prepared_surface(),
        remesh_edge_mm: args.prepare_remesh_edge_mm.unwrap_or(defaults.remesh_edge_mm),
        ..defaults
    }
}

/// The design stage: the plan's design options, from the prepared surface when there is
/// one, with the pulmonary artery and the peak flow the plan knows.
fn design_stage(args: &PlanSettings, dir: &Path) -> Result<DesignSettings, String> {
    let prepared_surface = PlanLayout::of(args).prepared_surface();
    let pulmonary = args.design.pulmonary.clone().or_else(|| args.prepare.pulmonary_surface(&prepared_surface));
    let prepared = args.prepare.is_given().then_some(prepared_surface);
    let peak_flow_ml_s = Some(design_peak_flow_ml_s(args)?);
    Ok(DesignSettings { out: dir.to_path_buf(), surface: prepared.or(args.design.surface.clone()), pulmonary, peak_flow_ml_s, ..args.design.clone() })
}

/// The centerline stage between the VSD and aortic caps.
fn centerline_stage(args: &PlanSettings) -> CenterlineSettings {
    let (d, layout) = (&args.design, PlanLayout::of(args));
    let (surface, ends) = match is_extended(args) {
        // Paper 2.5: the medial path of the extended lumen, from the mid-LV cap to the
        // STJ cap, trimmed at the VSD and aortic caps (interior planes).
        true => (layout.extended_surface(), Some(vec![INFLOW_CAP_LABEL, OUTFLOW_CAP_LABEL])),
        false => (layout.designed_domain(), None),
    };
    CenterlineSettings { surface, planes: vec![d.labels.vsd_cap, d.labels.aortic_cap], ends, out: layout.flow_centerline(), ..CenterlineSettings::default() }
}

/// An extend stage: the designed domain, with a mesh-study level's own remesh.
fn extend_stage(args: &PlanSettings, level: Option<&str>, remesh_domain_edge_mm: Option<f64>) -> ExtendSettings {
    let (d, layout) = (&args.design, PlanLayout::of(args));
    ExtendSettings {
        domain: layout.designed_domain(),
        source: args.prepare.clone(),
        out: level.map_or_else(|| layout.extended_surface(), |l| layout.level_extended_surface(l)),
        remesh_domain_edge_mm,
        extension_coarsening: args.extension_coarsening,
        labels: d.labels,
        ..ExtendSettings::default()
    }
}

/// A mesh stage: the extended domain as built (its interior caps share the boundary's
/// rim points), or the designed domain with its boundary remeshed.
fn mesh_stage(args: &PlanSettings, level: &str, edge_length_mm: f64) -> MeshSettings {
    let (d, layout) = (&args.design, PlanLayout::of(args));
    let mesh = MeshSettings { edge_length_mm, out: layout.mesh(level), ..MeshSettings::default() };
    match is_extended(args) {
        true => MeshSettings {
            surface: layout.level_extended_surface(level),
            interior_labels: vec![d.labels.vsd_cap, d.labels.aortic_cap],
            // gmsh then sizes the graded extension from its boundary.
            largest_edge_mm: (args.extension_coarsening > 1.0).then_some(args.extension_coarsening * edge_length_mm),
            ..mesh
        },
        false => MeshSettings { surface: layout.designed_domain(), remesh_surface: true, ..mesh },
    }
}

/// Asked between the stages, and by the design and the embedded simulation while they
/// run; the mesh stage (gmsh) and the prepare and extend stages only stop at their end.
pub use crate::progress::Cancel;

/// A finished plan's verdict with the numbers it judged, and where its report is.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanOutcome {
    /// Passes or fails against `dp_threshold_mmhg`, or inconclusive with its reasons.
    pub verdict: Verdict,
    /// The nominal run's plane-averaged peak pressure difference (mmHg).
    pub dp_mmhg: f64,
    /// The nominal run's largest speed at peak flow (m/s).
    pub v_max_m_s: f64,
    /// The planning threshold the verdict judged dp against (mmHg).
    pub dp_threshold_mmhg: f64,
    /// The verdict in one sentence (the command line's last line).
    pub verdict_line: String,
    /// The report's warnings (a single mesh, a poor mesh, a short flow section).
    pub warnings: Vec<String>,
    pub report_json: PathBuf,
    pub report_html: PathBuf,
}

/// `baffle plan`: each stage's progress shown on `progress` (the caller applies
/// --progress-tags), the stages' lines, the report's warnings and the verdict said on it.
pub fn run_plan(args: &PlanSettings, progress: &Progress) -> Result<PlanOutcome, PlanError> {
    plan(args, progress, None)
}

/// [`run_plan`] that stops when `cancel` says so: PlanError::Cancelled, the stages
/// finished before it kept in their folders (and the stopped simulation's results so far
/// in its own).
pub fn run_plan_cancellable(args: &PlanSettings, progress: &Progress, cancel: &Cancel) -> Result<PlanOutcome, PlanError> {
    plan(args, progress, Some(cancel))
}

/// The plan, stopped by `cancel` when given (else, in the simulation, by SIGTERM / SIGINT).
fn plan(args: &PlanSettings, progress: &Progress, cancel: Option<&Cancel>) -> Result<PlanOutcome, PlanError> {
    let stages = plan_stages(args)?;
    let layout = PlanLayout::of(args);
    let out = layout.root();
    std::fs::create_dir_all(out).map_err(|e| PlanError::Plan(format!("{}: {e}", out.display())))?;
    let records = run_stages(args, &stages, progress, cancel)?;
    progress.report(1.0, "report", "writing the report and rendering its pictures (VTK)");
    let outcome = report::write_reports(args, &stages, &records).map_err(PlanError::Plan)?;
    progress.report(1.0, "report", "written");
    progress.finish(None);
    progress.say(&format!("wrote {} and {}", layout.report_json().display(), layout.report_html().display()));
    say_outcome(&outcome, progress);
    Ok(PlanOutcome {
        verdict: outcome.verdict,
        dp_mmhg: outcome.dp_mmhg,
        v_max_m_s: outcome.v_max_m_s,
        dp_threshold_mmhg: DP_THRESHOLD_MMHG,
        verdict_line: outcome.verdict_line,
        warnings: outcome.warnings,
        report_json: layout.report_json(),
        report_html: layout.report_html(),
    })
}

/// The folders of the stages before the `k`th, for the message of a plan that ended there.
fn kept_folders(layout: &PlanLayout, stages: &[Stage], k: usize) -> String {
    let kept: Vec<String> = stages[..k].iter().map(|s| layout.stage_dir(&s.name).display().to_string()).collect();
    if kept.is_empty() { "none".to_string() } else { kept.join(", ") }
}

fn cancelled(layout: &PlanLayout, stages: &[Stage], k: usize) -> PlanError {
    PlanError::Cancelled(format!("plan cancelled at stage {} (finished stages' files kept: {})", stages[k].name, kept_folders(layout, stages, k)))
}

/// The stages of `args` in order, each into its folder; their records for the report.
fn run_stages(args: &PlanSettings, stages: &[Stage], progress: &Progress, cancel: Option<&Cancel>) -> Result<Vec<StageRecord>, PlanError> {
    let cancelled_now = || cancel.is_some_and(|c| c());
    let layout = PlanLayout::of(args);
    let total: f64 = stages.iter().map(|s| s.weight).sum();
    let mut records: Vec<StageRecord> =
        stages.iter().map(|s| StageRecord { name: s.name.clone(), status: "not run", wall_time_s: None, error: None }).collect();
    let mut done = 0.0;
    // Mesh-study levels that failed, with the stage and its reason.
    let mut failed_levels: Vec<(&str, String)> = Vec::new();
    for (k, stage) in stages.iter().enumerate() {
        let range = (done / total, (done + stage.weight) / total);
        if let Some((_, why)) = failed_levels.iter().find(|(level, _)| Some(*level) == stage.study_level()) {
            records[k].status = "skipped";
            records[k].error = Some(why.clone());
            done += stage.weight;
            continue;
        }
        if cancelled_now() {
            return Err(cancelled(&layout, stages, k));
        }
        progress.say(&format!("plan: stage {}/{} {} ...", k + 1, stages.len(), stage.name));
        let part = progress.part(range);
        part.report(0.0, &stage.name, "starting");
        let dir = layout.stage_dir(&stage.name);
        let start = Instant::now();
        let result = std::fs::create_dir_all(&dir)
            .map_err(|e| format!("{}: {e}", dir.display()))
            .and_then(|_| Ok(run_stage_cancellable(args, stage, &dir, &part, cancel)?));
        part.finish(None);
        let record = &mut records[k];
        record.wall_time_s = Some(start.elapsed().as_secs_f64());
        if let Err(e) = result {
            if cancelled_now() {
                // A stopped simulation keeps its results so far in its folder.
                return Err(cancelled(&layout, stages, k));
            }
            // A failed stage's folder goes if it holds nothing (remove_dir only removes empty ones).
            let _ = std::fs::remove_dir(&dir);
            record.status = "failed";
            record.error = Some(e.clone());
            if let Some(level) = stage.study_level() {
                // The nominal result stands; the report's mesh study says why it has no band.
                progress.say(&format!("plan: stage {} failed: {e}\nplan: the mesh study goes on without its {level} level", stage.name));
                failed_levels.push((level, format!("the {level} level's stage {} failed: {e}", stage.name)));
                done += stage.weight;
                continue;
            }
            report::write_failure_json(&layout, &stage.name, &e, &records).map_err(PlanError::Plan)?;
            let kept = kept_folders(&layout, stages, k);
            return Err(PlanError::Plan(format!("stage {} failed: {e}\n(finished stages' files kept: {kept})", stage.name)));
        }
        record.status = "completed";
        progress.say(&format!("plan: stage {} done in {:.1} s", stage.name, record.wall_time_s.unwrap_or(0.0)));
        done += stage.weight;
    }
    Ok(records)
}

/// The report's warnings and note, then the verdict as the last line: PASSES, FAILS or
/// INCONCLUSIVE with its reason.
fn say_outcome(outcome: &report::Outcome, progress: &Progress) {
    for warning in &outcome.warnings {
        progress.say(&format!("warning: {warning}"));
    }
    if let Some(reason) = &outcome.pictures_missing {
        progress.say(&format!("note: the report has no 3D pictures: {reason}"));
    }
    progress.say(&outcome.verdict_line);
}

