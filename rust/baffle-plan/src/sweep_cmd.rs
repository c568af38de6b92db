//! `baffle sweep`: the design at several targets on one input (issue 17), so the team
//! sees what a larger tunnel costs the right ventricle and where the surgeon's seam
//! stops admitting one. Each target is a full `design`; an infeasible one is a row with
//! its reason and the largest target the seam admits, not the end of the sweep.
//!
//! Writes into --out: sweep.csv, sweep.md, sweep.json, sweep.svg and, per designed
//! target, a subfolder named after it (z-1, z+0.5, area-80) holding the design's files in
//! `design/`. With --cfd each designed target also gets the quick dp estimate of
//! `baffle plan --quick` (the plan's own [extend,] mesh and simulate stages, in `extend/`,
//! `mesh-nominal/` and `simulate-nominal/` beside `design/`), so the table shows what the tunnel's size does to
//! the pressure difference and to the right ventricle side by side. Every designed target
//! also carries the reduced-order dp and v_max estimate (issue 31, at --peak-flow-ml-s or
//! the CFD case's peak flow for the body size), so the curve of dp against the target is
//! drawn in seconds, before any 3D run; --cfd's quick runs then confirm chosen points.

use crate::error::PlanError;
use crate::files::{read_json, write_atomic};
use crate::plan_cmd;
use crate::plan_stages::{self, PlanLayout, PlanSettings, Stage, Step};
use crate::prepare_cmd::PrepareSource;
use crate::progress::Progress;
use crate::run_summary::RunSummary;
use crate::report::svg_plot::{line_chart, with_note, Series};
use crate::design_cmd::{design_by_rule, design_inputs, design_options, measure_rv_outflow, rv_cost_line, target_from, DesignSettings, TargetSettings};
use crate::verdict::{self, Verdict};
use baffle_core::analyses::hemodynamics_estimate::{dp_uncertainty, peak_flow_ml_s, Blood, EstimateOutcome, HemodynamicsEstimate};
use baffle_core::io::outputs::write_design_outputs;
use baffle_core::analyses::rv_outflow::NarrowedSection;
use baffle_core::{DesignError, DesignReport, TargetArea};
use serde_json::json;
use std::fmt::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

documented_settings! {
pub struct SweepSettings {
    pub design: DesignSettings,
    /// Annulus z-scores to design at (comma-separated; with --bsa or --height-cm/--weight-kg).
    pub z_scores: Vec<f64>,
    /// Target areas to design at (mm2, comma-separated), instead of --z-scores.
    pub areas_mm2: Vec<f64>,
    /// Instead of --surface: prepare the capped ventricle from these blood pools once (as
    /// `baffle plan`, into --out/prepare); --cfd then runs on each design's extended domain.
    pub prepare: PrepareSource,
    pub cfd: SweepCfd,
}
}

documented_settings! {
/// The quick dp estimate per designed target (opt-in: it is minutes, the design seconds).
pub struct SweepCfd {
    /// Also mesh each designed domain and run the quick estimate (`baffle plan --quick`:
    /// from rest to the first flow peak; inflow on the VSD cap, or with --segmentations on
    /// the mid-LV cap of the extended domain): dp, v_max and the verdict per row.
    pub cfd: bool,
    /// Blood pressure SBP/DBP (mmHg) for --cfd: the outlet resistance R = MAP / Q_mean.
    pub bp: Option<(f64, f64)>,
    /// Heart rate (beats/min) for --cfd; default: the built-in period of 0.682 s.
    pub hr: Option<f64>,
    /// Largest tetrahedron edge of --cfd's meshes (mm); the paper's coarse level, for speed.
    pub edge_length_mm: f64,
    /// Cardiac index of --cfd's runs (L/min/m2): the mean flow is BSA x cardiac index.
    pub cardiac_index: f64,
}
}

/// The plan's quick settings by default, at the paper's coarse mesh size (for speed).
impl Default for SweepCfd {
    fn default() -> Self {
        let plan = PlanSettings::default();
        SweepCfd { cfd: false, bp: None, hr: None, edge_length_mm: plan_stages::PAPER_COARSE_MM, cardiac_index: plan.cardiac_index }
    }
}

/// A designed target's quick estimate: dp at the first flow peak and its verdict.
struct Quick {
    dp_mmhg: f64,
    vmax_m_s: f64,
    verdict: Verdict,
    cfd_s: f64,
}

/// One target of the sweep and what became of it.
struct Row {
    z_score: Option<f64>,
    target_area_mm2: f64,
    outcome: Outcome,
    design_ms: f64,
    /// With --cfd, on a designed row.
    quick: Option<Quick>,
}

enum Outcome {
    Designed(Box<DesignReport>),
    Infeasible { max_feasible_area_mm2: f64, max_feasible_z_score: Option<f64>, reason: String },
    Failed(String),
}

impl Row {
    fn status(&self) -> &'static str {
        match self.outcome {
            Outcome::Designed(_) => "designed",
            Outcome::Infeasible { .. } => "infeasible",
            Outcome::Failed(_) => "failed",
        }
    }

    fn report(&self) -> Option<&DesignReport> {
        match &self.outcome {
            Outcome::Designed(r) => Some(r),
            _ => None,
        }
    }

    /// A designed row's figure, NaN otherwise (a gap in the plot, empty in the tables).
    fn designed(&self, f: impl Fn(&DesignReport) -> f64) -> f64 {
        self.report().map_or(f64::NAN, f)
    }

    /// The RV outflow's smallest section after the baffle, NaN where not measured.
    fn rv_outflow_mm2(&self) -> f64 {
        self.report().and_then(|d| d.rv_cost.rv_outflow.rv_outflow_min_section_mm2).unwrap_or(f64::NAN)
    }

    /// A figure of the outflow section the baffle narrows most, NaN where not measured.
    fn most_narrowed(&self, f: impl Fn(&NarrowedSection) -> f64) -> f64 {
        self.report().and_then(|d| d.rv_cost.rv_outflow.rv_outflow_most_narrowed.as_ref()).map_or(f64::NAN, f)
    }

    /// Why the RV outflow figures of a designed row are missing.
    fn outflow_unavailable(&self) -> Option<&str> {
        self.report()?.rv_cost.rv_outflow.rv_outflow_unavailable.as_deref()
    }

    fn max_feasible(&self) -> (f64, Option<f64>) {
        match self.outcome {
            Outcome::Infeasible { max_feasible_area_mm2, max_feasible_z_score, .. } => (max_feasible_area_mm2, max_feasible_z_score),
            _ => (f64::NAN, None),
        }
    }

    fn reason(&self) -> &str {
        match &self.outcome {
            Outcome::Designed(_) => "",
            Outcome::Infeasible { reason, .. } | Outcome::Failed(reason) => reason,
        }
    }

    fn folder(&self) -> String {
        folder_name(self.z_score, self.target_area_mm2)
    }

    /// A figure of the reduced-order estimate, NaN without one.
    fn estimate(&self, f: impl Fn(&HemodynamicsEstimate) -> f64) -> f64 {
        match self.report().and_then(|d| d.hemodynamics_estimate.as_ref()) {
            Some(EstimateOutcome::Estimated(e)) => f(e),
            _ => f64::NAN,
        }
    }

    /// Why a designed row has no reduced-order estimate.
    fn estimate_absent(&self) -> Option<&str> {
        match self.report()?.hemodynamics_estimate.as_ref()? {
            EstimateOutcome::Absent { absent_because } => Some(absent_because),
            EstimateOutcome::Estimated(_) => None,
        }
    }

    /// A figure of the quick estimate, NaN without one.
    fn quick(&self, f: impl Fn(&Quick) -> f64) -> f64 {
        self.quick.as_ref().map_or(f64::NAN, f)
    }

    fn verdict_key(&self) -> &'static str {
        self.quick.as_ref().map_or("", |q| q.verdict.key())
    }

    /// Why the row is not a plain design: the design's failure, or an inconclusive estimate.
    fn note(&self) -> String {
        let inconclusive = self.quick.as_ref().and_then(|q| q.verdict.reason()).map(|r| format!("quick estimate inconclusive: {r}"));
        inconclusive.unwrap_or_else(|| self.reason().to_string())
    }
}

/// Subfolder of a target's design files: z-1, z+0.5, area-80.
fn folder_name(z_score: Option<f64>, target_area_mm2: f64) -> String {
    match z_score {
        Some(z) => format!("z{z:+}"),
        None => format!("area-{target_area_mm2}"),
    }
}

pub fn run_sweep(args: &SweepSettings, progress: &Progress) -> Result<(), PlanError> {
    sweep(args, progress).map_err(PlanError::Sweep)
}

/// The designs (and with --cfd the quick estimates) of every target, and the tables and plot.
fn sweep(args: &SweepSettings, progress: &Progress) -> Result<(), String> {
    // Design options that make no sense per target are refused, not silently dropped.
    if args.design.reference_baffle.is_some() || args.design.progress_tags {
        return Err("baffle sweep takes neither --reference-baffle nor --progress-tags (run baffle design on one target)".into());
    }
    let options = design_options(&args.design)?;
    let prepared = prepare_once(args, progress)?;
    let (surface, points, default_bsa) = design_inputs(&DesignSettings { surface: prepared.or(args.design.surface.clone()), ..args.design.clone() })?;
    let targets = sweep_targets(args, default_bsa)?;
    let estimate_flow = estimate_peak_flow_ml_s(args, default_bsa);
    let pulmonary = args.design.pulmonary.clone().or_else(|| args.prepare.pulmonary_surface(&PlanLayout::new(&args.design.out, false).prepared_surface()));
    if args.cfd.cfd {
        // Every stage's arguments are checked before the first design, as the plan does.
        plan_stages::plan_stages(&plan_args(args, &args.design.out, f64::NAN))?;
    }
    std::fs::create_dir_all(&args.design.out).map_err(|e| format!("{}: {e}", args.design.out.display()))?;
    let started = Instant::now();
    let mut rows = Vec::new();
    for (z_score, target) in targets {
        // The area first: a target that cannot even be computed is a row, not a stop.
        let target_area_mm2 = target.area_mm2().unwrap_or(f64::NAN);
        let clock = Instant::now();
        let row_dir = args.design.out.join(folder_name(z_score, target_area_mm2));
        let outcome = match design_by_rule(args.design.flow_sections, &surface, &points, &target, &options, &mut |_, _| true) {
            Ok(mut result) => {
                measure_rv_outflow(&surface, &mut result, pulmonary.as_deref())?;
                result.report.hemodynamics_estimate = Some(match &estimate_flow {
                    Ok(q) => EstimateOutcome::for_domain(&result.domain, options.labels, Some(*q), Blood::default()),
                    Err(why) => EstimateOutcome::Absent { absent_because: why.clone() },
                });
                write_design_outputs(&row_dir.join("design"), &result).map_err(|e| e.to_string())?;
                Outcome::Designed(Box::new(result.report))
            }
            Err(DesignError::Infeasible { max_feasible_area_mm2, max_feasible_z_score, reason, .. }) => {
                Outcome::Infeasible { max_feasible_area_mm2, max_feasible_z_score, reason }
            }
            Err(e) => Outcome::Failed(e.to_string()),
        };
        let design_ms = clock.elapsed().as_secs_f64() * 1e3;
        let quick = match &outcome {
            Outcome::Designed(report) if args.cfd.cfd => Some(quick_estimate(&plan_args(args, &row_dir, target_area_mm2), report, progress)),
            _ => None,
        };
        let row = Row { z_score, target_area_mm2, outcome, design_ms, quick };
        progress.say(&summary_line(&row));
        rows.push(row);
    }
    let total_s = started.elapsed().as_secs_f64();
    let out = &args.design.out;
    write_atomic(&out.join("sweep.csv"), csv(&rows).as_bytes())?;
    write_atomic(&out.join("sweep.md"), markdown(&rows).as_bytes())?;
    write_atomic(&out.join("sweep.svg"), plot(&rows).as_bytes())?;
    write_atomic(&out.join("sweep.json"), json_doc(&rows, total_s).to_string().as_bytes())?;
    progress.say(&format!("{} targets in {total_s:.1} s; wrote {}", rows.len(), out.display()));
    Ok(())
}

/// The plan of one target's quick estimate: its design in `row_dir/design`, the
/// target as the area the design was made for (the flow needs the BSA, kept).
fn plan_args(args: &SweepSettings, row_dir: &Path, target_area_mm2: f64) -> PlanSettings {
    let mut design = args.design.clone();
    design.out = row_dir.to_path_buf();
    if target_area_mm2.is_finite() {
        // The row's area is the whole target: its z-score (if any) already made it.
        design.target = TargetSettings { target_area_mm2: Some(target_area_mm2), annulus_diameter_mm: None, z_score: 0.0, ..design.target };
    }
    let c = &args.cfd;
    PlanSettings {
        design,
        prepare: args.prepare.clone(),
        bp: c.bp.unwrap_or((f64::NAN, f64::NAN)),
        hr: c.hr,
        steady: false,
        quick: true,
        pulsatile: false,
        cycles: plan_stages::CYCLES,
        edge_length_mm: c.edge_length_mm,
        extension_coarsening: PlanSettings::default().extension_coarsening,
        mesh_study: false,
        single_mesh: true,
        elevated_flow: false,
        cardiac_index: c.cardiac_index,
        prepare_remesh_edge_mm: None,
        patient_label: None,
    }
}

/// The peak flow (ml/s) every target's reduced-order estimate is made at: --peak-flow-ml-s,
/// else the CFD case's (BSA x cardiac index through the built-in waveform, as the plan's
/// design stage); or why there is none (no body size).
fn estimate_peak_flow_ml_s(args: &SweepSettings, default_bsa: Option<f64>) -> Result<f64, String> {
    if let Some(q) = args.design.peak_flow_ml_s {
        return Ok(q);
    }
    let t = &args.design.target;
    let from_size = t.height_cm.zip(t.weight_kg).map(|(h, w)| baffle_core::target::haycock_bsa_m2(h, w));
    let bsa = t.bsa.or(from_size).or(default_bsa).ok_or("no peak flow for the estimate: give --bsa (or --height-cm/--weight-kg) or --peak-flow-ml-s")?;
    peak_flow_ml_s(bsa, args.cfd.cardiac_index)
}

/// With --segmentations or --labelmap: the plan's prepare stage into --out/prepare, once
/// for every target; the capped ventricle it wrote.
fn prepare_once(args: &SweepSettings, progress: &Progress) -> Result<Option<PathBuf>, String> {
    if !args.prepare.is_given() {
        return Ok(None);
    }
    if args.design.surface.is_some() || args.design.phantom {
        return Err("baffle sweep takes one source of the ventricle: --surface, --phantom, --segmentations or --labelmap".into());
    }
    let (out, layout) = (&args.design.out, PlanLayout::new(&args.design.out, false));
    let stage = Stage { name: "prepare".into(), step: Step::Prepare, weight: 1.0 };
    let dir = layout.stage_dir(&stage.name);
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let progress = progress.restart();
    plan_cmd::run_stage(&plan_args(args, out, f64::NAN), &stage, &dir, &progress).map_err(|e| format!("stage prepare failed: {e}"))?;
    progress.finish(None);
    Ok(Some(layout.prepared_surface()))
}

/// Mesh the designed domain and run the quick estimate with the plan's own stages
/// (everything after its design), then judge dp as the plan does. A stage that fails
/// makes the row inconclusive with the stage and its reason, not the sweep's end.
fn quick_estimate(plan: &PlanSettings, report: &DesignReport, progress: &Progress) -> Quick {
    let clock = Instant::now();
    let result = run_after_design(plan, &progress.restart());
    let cfd_s = clock.elapsed().as_secs_f64();
    let design_doubt = verdict::design_doubt(report.min_constrained_final_area_mm2, report.target_area_mm2);
    match result {
        Ok(summary) => {
            let dp_mmhg = summary.dp_peak_mmhg.unwrap_or(f64::NAN);
            let vmax_m_s = summary.max_velocity_m_s.unwrap_or(f64::NAN);
            let mut doubts = verdict::run_doubts(&summary);
            doubts.extend(design_doubt);
            Quick { dp_mmhg, vmax_m_s, verdict: Verdict::of(dp_mmhg, doubts), cfd_s }
        }
        Err(e) => Quick { dp_mmhg: f64::NAN, vmax_m_s: f64::NAN, verdict: Verdict::Inconclusive { reasons: vec![e] }, cfd_s },
    }
}

/// The plan's stages a designed domain needs for its dp (no centerline, no report).
const AFTER_DESIGN: [&str; 3] = ["extend", "mesh-", "simulate-"];

/// The plan's extend (when prepared), mesh and simulate stages into the row's folder; the run's summary.json.
fn run_after_design(plan: &PlanSettings, progress: &Progress) -> Result<RunSummary, String> {
    let layout = PlanLayout::of(plan);
    let mut summary = None;
    for stage in plan_stages::plan_stages(plan)?.iter().filter(|s| AFTER_DESIGN.iter().any(|p| s.name.starts_with(p))) {
        let dir = layout.stage_dir(&stage.name);
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        plan_cmd::run_stage(plan, stage, &dir, progress).map_err(|e| format!("stage {} failed: {e}", stage.name))?;
        summary = Some(dir.join("summary.json"));
    }
    progress.finish(None);
    read_json(&summary.ok_or("the plan has no simulate stage")?)
}

/// The sweep's targets, each with its z-score when the list was of z-scores.
/// The targets, each checked before the first design: a NaN or negative one is a typo,
/// not a row of the table.
fn sweep_targets(args: &SweepSettings, default_bsa: Option<f64>) -> Result<Vec<(Option<f64>, TargetArea)>, String> {
    let targets = sweep_target_list(args, default_bsa)?;
    for (z, target) in &targets {
        let which = z.map_or_else(|| "--areas-mm2".to_string(), |z| format!("--z-scores (z = {z})"));
        target.area_mm2().map_err(|e| format!("{which}: {e}"))?;
    }
    Ok(targets)
}

fn sweep_target_list(args: &SweepSettings, default_bsa: Option<f64>) -> Result<Vec<(Option<f64>, TargetArea)>, String> {
    if !args.areas_mm2.is_empty() {
        return Ok(args.areas_mm2.iter().map(|&a| (None, TargetArea::AreaMm2(a))).collect());
    }
    let base = &args.design.target;
    if base.target_area_mm2.is_some() || base.annulus_diameter_mm.is_some() {
        return Err("--z-scores needs the body size (--bsa or --height-cm/--weight-kg), not a fixed --target-area-mm2 or --annulus-diameter-mm".into());
    }
    args.z_scores
        .iter()
        .map(|&z| {
            let target = target_from(&TargetSettings { z_score: z, ..base.clone() }, default_bsa)?;
            Ok((Some(z), target))
        })
        .collect()
}

/// "; dp estimate 3.21 mmHg (reduced-order, not CFD)", or nothing without one.
fn estimate_words(row: &Row) -> String {
    let dp = row.estimate(|e| e.dp_estimate_mmhg);
    if dp.is_finite() {
        format!("; dp estimate {dp:.2} mmHg, v_max {:.2} m/s (reduced-order, not CFD)", row.estimate(|e| e.v_max_estimate_m_s))
    } else {
        String::new()
    }
}

fn summary_line(row: &Row) -> String {
    let what = match &row.outcome {
        Outcome::Designed(r) => format!("baffle {:.1} mm2; {}{}", r.baffle_area_mm2, rv_cost_line(&r.rv_cost), estimate_words(row)),
        Outcome::Infeasible { max_feasible_area_mm2, .. } => format!("infeasible: the seam admits at most {max_feasible_area_mm2:.1} mm2"),
        Outcome::Failed(reason) => format!("failed: {reason}"),
    };
    format!("{}: target {:.1} mm2: {what} ({:.0} ms)", row.folder(), row.target_area_mm2, row.design_ms)
}

/// A number for the tables: empty when not measured.
fn cell(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        String::new()
    }
}

fn optional(v: Option<f64>, decimals: usize) -> String {
    cell(v.unwrap_or(f64::NAN), decimals)
}

const CSV_HEADER: &str = "z_score,target_area_mm2,status,baffle_area_mm2,min_section_area_mm2,rv_volume_before_ml,rv_volume_after_ml,rv_volume_taken_ml,baffle_area_outside_ventricle_mm2,rv_outflow_min_section_mm2,rv_outflow_most_narrowed_before_mm2,rv_outflow_most_narrowed_after_mm2,rv_outflow_most_narrowed_after_over_before,rv_outflow_most_narrowed_from_pulmonary_end_mm,max_feasible_area_mm2,max_feasible_z_score,dp_estimate_mmhg,v_max_estimate_m_s,dp_mmhg,vmax_m_s,verdict,design_ms,cfd_s,reason";

fn csv(rows: &[Row]) -> String {
    let mut s = format!("{CSV_HEADER}\n");
    for r in rows {
        let (max_area, max_z) = r.max_feasible();
        let fields = [
            optional(r.z_score, 2),
            cell(r.target_area_mm2, 3),
            r.status().to_string(),
            cell(r.designed(|d| d.baffle_area_mm2), 3),
            cell(r.designed(|d| d.min_constrained_final_area_mm2), 3),
            cell(r.designed(|d| d.rv_cost.rv_volume_before_ml), 4),
            cell(r.designed(|d| d.rv_cost.rv_volume_after_ml), 4),
            cell(r.designed(|d| d.rv_cost.rv_volume_taken_ml), 4),
            cell(r.designed(|d| d.rv_cost.baffle_area_outside_ventricle_mm2), 2),
            cell(r.rv_outflow_mm2(), 2),
            cell(r.most_narrowed(|n| n.area_before_mm2), 2),
            cell(r.most_narrowed(|n| n.area_after_mm2), 2),
            cell(r.most_narrowed(|n| n.after_over_before), 4),
            cell(r.most_narrowed(|n| n.distance_from_pulmonary_end_mm), 1),
            cell(max_area, 3),
            optional(max_z, 3),
            cell(r.estimate(|e| e.dp_estimate_mmhg), 3),
            cell(r.estimate(|e| e.v_max_estimate_m_s), 3),
            cell(r.quick(|q| q.dp_mmhg), 3),
            cell(r.quick(|q| q.vmax_m_s), 3),
            r.verdict_key().to_string(),
            cell(r.design_ms, 0),
            cell(r.quick(|q| q.cfd_s), 1),
            // Quoted, inner quotes doubled (RFC 4180): reasons hold commas.
            format!("\"{}\"", r.note().replace('"', "\"\"")),
        ];
        let _ = writeln!(s, "{}", fields.join(","));
    }
    s
}

fn markdown(rows: &[Row]) -> String {
    let mut s = String::from(
        "| z | target (mm2) | status | baffle (mm2) | smallest section (mm2) | RV before (mL) | RV after (mL) | taken (mL) | RV outflow smallest section (mm2) | RV outflow most narrowed: before / after (mm2) | left (%) | from the pulmonary end (mm) | largest feasible target (mm2) | dp estimate (mmHg) | dp (mmHg) | v_max (m/s) | 10 mmHg verdict | time (s) |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let (max_area, max_z) = r.max_feasible();
        let largest = match max_z {
            Some(z) if max_area.is_finite() => format!("{max_area:.1} (z = {z:.2})"),
            _ => cell(max_area, 1),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            optional(r.z_score, 2),
            cell(r.target_area_mm2, 1),
            r.status(),
            cell(r.designed(|d| d.baffle_area_mm2), 1),
            cell(r.designed(|d| d.min_constrained_final_area_mm2), 1),
            cell(r.designed(|d| d.rv_cost.rv_volume_before_ml), 2),
            cell(r.designed(|d| d.rv_cost.rv_volume_after_ml), 2),
            cell(r.designed(|d| d.rv_cost.rv_volume_taken_ml), 2),
            cell(r.rv_outflow_mm2(), 1),
            before_after(r.most_narrowed(|n| n.area_before_mm2), r.most_narrowed(|n| n.area_after_mm2)),
            cell(r.most_narrowed(|n| 100.0 * n.after_over_before), 0),
            cell(r.most_narrowed(|n| n.distance_from_pulmonary_end_mm), 1),
            largest,
            cell(r.estimate(|e| e.dp_estimate_mmhg), 2),
            cell(r.quick(|q| q.dp_mmhg), 2),
            cell(r.quick(|q| q.vmax_m_s), 2),
            r.verdict_key(),
            cell((r.design_ms / 1e3) + r.quick(|q| q.cfd_s).max(0.0), 1),
        );
    }
    let mut notes: Vec<String> = rows.iter().filter(|r| !r.note().is_empty()).map(|r| format!("- {}: {}", r.folder(), r.note())).collect();
    // Why the RV outflow is not measured, once per distinct reason.
    notes.extend(outflow_reasons(rows).iter().map(|reason| format!("- RV outflow sections not measured: {reason}")));
    if rows.iter().any(|r| r.estimate(|e| e.dp_estimate_mmhg).is_finite()) {
        notes.push(format!("- dp estimate: reduced-order, not CFD; its measured error {}", dp_uncertainty()));
    }
    if let Some(why) = rows.iter().find_map(Row::estimate_absent) {
        notes.push(format!("- dp estimate absent: {why}"));
    }
    if !notes.is_empty() {
        let _ = write!(s, "\n{}\n", notes.join("\n"));
    }
    s
}

/// "before / after", empty when not measured.
fn before_after(before: f64, after: f64) -> String {
    if before.is_finite() && after.is_finite() {
        format!("{before:.1} / {after:.1}")
    } else {
        String::new()
    }
}

/// Why the RV outflow is not measured, once per distinct reason.
fn outflow_reasons(rows: &[Row]) -> Vec<&str> {
    let mut reasons: Vec<&str> = Vec::new();
    for reason in rows.iter().filter_map(Row::outflow_unavailable) {
        if !reasons.contains(&reason) {
            reasons.push(reason);
        }
    }
    reasons
}

/// Four charts over the sweep's x (z-score, else target area): the areas, the baffle,
/// the RV volumes and the RV outflow sections (and, with --cfd, the quick dp against 10
/// mmHg); infeasible targets and unmeasured figures are gaps, the largest feasible target
/// a line.
fn plot(rows: &[Row]) -> String {
    let by_z = rows.iter().all(|r| r.z_score.is_some());
    let x = |r: &Row| if by_z { r.z_score.unwrap_or(f64::NAN) } else { r.target_area_mm2 };
    let x_label = if by_z { "annulus z-score" } else { "target area (mm2)" };
    let series = |label: &str, color: &'static str, f: &dyn Fn(&Row) -> f64| Series {
        label: label.into(),
        points: rows.iter().map(|r| (x(r), f(r))).collect(),
        color,
        dashed: false,
        markers: true,
    };
    let mut areas = vec![
        Series { dashed: true, ..series("target", "#d62728", &|r| r.target_area_mm2) },
        series("smallest section", "#1f77b4", &|r| r.designed(|d| d.min_constrained_final_area_mm2)),
    ];
    let largest = rows.iter().map(|r| r.max_feasible().0).filter(|a| a.is_finite()).fold(f64::NAN, f64::min);
    if largest.is_finite() {
        let xs: Vec<f64> = rows.iter().map(x).collect();
        let (lo, hi) = xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        areas.push(Series { label: "largest feasible".into(), points: vec![(lo, largest), (hi, largest)], color: "#2ca02c", dashed: true, markers: false });
    }
    let mut charts = vec![
        line_chart("Target and section areas", x_label, "area (mm2)", &areas, true),
        line_chart("Baffle area", x_label, "area (mm2)", &[series("baffle", "#9467bd", &|r| r.designed(|d| d.baffle_area_mm2))], true),
        line_chart(
            "Right ventricle",
            x_label,
            "volume (mL)",
            &[
                series("RV after the baffle", "#1f77b4", &|r| r.designed(|d| d.rv_cost.rv_volume_after_ml)),
                series("taken by the pathway", "#ff7f0e", &|r| r.designed(|d| d.rv_cost.rv_volume_taken_ml)),
            ],
            true,
        ),
        outflow_chart(rows, x_label, &series),
    ];
    charts.extend(dp_chart(rows, x_label, &series));
    stack(&charts)
}

/// dp at peak flow against the 10 mmHg threshold: the reduced-order estimate of every
/// designed target (drawn before any 3D run) and, with --cfd, the quick 3D runs' first
/// peak; None when the sweep has neither.
fn dp_chart(rows: &[Row], x_label: &str, series: &dyn Fn(&str, &'static str, &dyn Fn(&Row) -> f64) -> Series) -> Option<String> {
    let has_estimate = rows.iter().any(|r| r.estimate(|e| e.dp_estimate_mmhg).is_finite());
    let has_quick = rows.iter().any(|r| r.quick.is_some());
    if !(has_estimate || has_quick) {
        return None;
    }
    let mut lines = vec![Series { label: "10 mmHg".into(), dashed: true, markers: false, ..series("", "#d62728", &|_| verdict::DP_THRESHOLD_MMHG) }];
    if has_estimate {
        lines.push(Series { dashed: true, ..series("reduced-order estimate (not CFD)", "#7f7f7f", &|r| r.estimate(|e| e.dp_estimate_mmhg)) });
    }
    if has_quick {
        lines.push(series("Quick dp estimate: 3D, first peak", "#1f77b4", &|r| r.quick(|q| q.dp_mmhg)));
    }
    let chart = line_chart("dp at peak flow", x_label, "dp (mmHg)", &lines, true);
    Some(if has_estimate { with_note(&chart, "the reduced-order estimate's measured error against 3D runs is in its uncertainty (docs/hemodynamics_estimate.md)") } else { chart })
}

/// The RV outflow's smallest section after the baffle and the section the baffle narrows
/// most, before and after; rows without them are gaps, and the chart says why.
fn outflow_chart(rows: &[Row], x_label: &str, series: &dyn Fn(&str, &'static str, &dyn Fn(&Row) -> f64) -> Series) -> String {
    let lines = [
        series("smallest section", "#1f77b4", &|r| r.rv_outflow_mm2()),
        Series { dashed: true, ..series("most narrowed, before", "#7f7f7f", &|r| r.most_narrowed(|n| n.area_before_mm2)) },
        series("most narrowed, after", "#ff7f0e", &|r| r.most_narrowed(|n| n.area_after_mm2)),
    ];
    let chart = line_chart("RV outflow (apex region to the pulmonary artery)", x_label, "section area (mm2)", &lines, true);
    let missing = rows.iter().filter(|r| r.report().is_some() && r.rv_outflow_mm2().is_nan()).count();
    match missing {
        0 => chart,
        _ => {
            let why = outflow_reasons(rows).first().map_or(String::new(), |r| format!(": {r}"));
            with_note(&chart, &format!("not measured at {missing} of {} designed targets{why}", rows.iter().filter(|r| r.report().is_some()).count()))
        }
    }
}

/// The charts one below the other in one SVG document.
fn stack(charts: &[String]) -> String {
    let size = |svg: &str, attr: &str| -> f64 {
        let key = format!("{attr}=\"");
        svg.find(&key).and_then(|i| svg[i + key.len()..].split('"').next()?.parse().ok()).unwrap_or(0.0)
    };
    let width = charts.iter().map(|c| size(c, "width")).fold(0.0, f64::max);
    let mut y = 0.0;
    let mut body = String::new();
    for c in charts {
        let _ = write!(body, r#"<g transform="translate(0 {y})">{c}</g>"#);
        y += size(c, "height");
    }
    format!(r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{y}" viewBox="0 0 {width} {y}">{body}</svg>"#)
}

fn json_doc(rows: &[Row], total_s: f64) -> serde_json::Value {
    let number = |v: f64| if v.is_finite() { json!(v) } else { serde_json::Value::Null };
    json!({
        "total_s": total_s,
        "rows": rows.iter().map(|r| {
            let (max_area, max_z) = r.max_feasible();
            json!({
                "folder": r.folder(),
                "z_score": r.z_score,
                "target_area_mm2": number(r.target_area_mm2),
                "status": r.status(),
                "baffle_area_mm2": number(r.designed(|d| d.baffle_area_mm2)),
                "min_section_area_mm2": number(r.designed(|d| d.min_constrained_final_area_mm2)),
                "rv_volume_before_ml": number(r.designed(|d| d.rv_cost.rv_volume_before_ml)),
                "rv_volume_after_ml": number(r.designed(|d| d.rv_cost.rv_volume_after_ml)),
                "rv_volume_taken_ml": number(r.designed(|d| d.rv_cost.rv_volume_taken_ml)),
                "baffle_area_outside_ventricle_mm2": number(r.designed(|d| d.rv_cost.baffle_area_outside_ventricle_mm2)),
                "rv_outflow_min_section_mm2": number(r.rv_outflow_mm2()),
                "rv_outflow_most_narrowed_before_mm2": number(r.most_narrowed(|n| n.area_before_mm2)),
                "rv_outflow_most_narrowed_after_mm2": number(r.most_narrowed(|n| n.area_after_mm2)),
                "rv_outflow_most_narrowed_after_over_before": number(r.most_narrowed(|n| n.after_over_before)),
                "rv_outflow_most_narrowed_from_pulmonary_end_mm": number(r.most_narrowed(|n| n.distance_from_pulmonary_end_mm)),
                "rv_outflow_unavailable": r.report().and_then(|d| d.rv_cost.rv_outflow.rv_outflow_unavailable.clone()),
                "max_feasible_area_mm2": number(max_area),
                "max_feasible_z_score": max_z,
                "dp_estimate_mmhg": number(r.estimate(|e| e.dp_estimate_mmhg)),
                "v_max_estimate_m_s": number(r.estimate(|e| e.v_max_estimate_m_s)),
                "estimate_absent_because": r.estimate_absent(),
                "dp_mmhg": number(r.quick(|q| q.dp_mmhg)),
                "vmax_m_s": number(r.quick(|q| q.vmax_m_s)),
                "verdict": r.quick.as_ref().map(|q| json!({"verdict": q.verdict.key(), "reason": q.verdict.reason(), "passes": q.verdict == Verdict::Passes})),
                "design_ms": r.design_ms,
                "cfd_s": number(r.quick(|q| q.cfd_s)),
                "reason": r.reason(),
            })
        }).collect::<Vec<_>>(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use baffle_core::design;
    use baffle_core::analyses::rv_outflow::RvOutflow;

    fn rows() -> Vec<Row> {
        vec![
            Row { z_score: Some(-1.0), target_area_mm2: 50.0, outcome: Outcome::Failed("seam, \"crossing\" the cap".into()), design_ms: 12.0, quick: None },
            Row {
                z_score: Some(2.0),
                target_area_mm2: 120.0,
                outcome: Outcome::Infeasible { max_feasible_area_mm2: 95.5, max_feasible_z_score: Some(1.1), reason: "no amplitude".into() },
                design_ms: 80.0,
                quick: None,
            },
        ]
    }

    #[test]
    fn every_row_is_in_the_tables_with_its_reason() {
        let rows = rows();
        let csv = csv(&rows);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 3);
        assert!(lines[1].starts_with("-1.00,50.000,failed,"), "{}", lines[1]);
        assert!(lines[1].ends_with(",\"seam, \"\"crossing\"\" the cap\""), "{}", lines[1]);
        assert!(lines[2].contains(",infeasible,") && lines[2].contains(",95.500,1.100,"), "{}", lines[2]);
        let md = markdown(&rows);
        assert!(md.contains("| 2.00 | 120.0 | infeasible |") && md.contains("95.5 (z = 1.10)"), "{md}");
        assert!(md.contains("- z+2: no amplitude"), "{md}");
    }

    #[test]
    fn the_plot_is_one_svg_of_four_charts_without_nan() {
        let svg = plot(&rows());
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>"));
        assert_eq!(svg.matches("<svg").count(), 5);
        assert!(svg.contains(r#"height="1200""#), "{}", &svg[..200]);
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
        assert!(svg.contains("largest feasible"));
    }

    /// Designed rows on the phantom (no pulmonary artery there), their RV outflow figures
    /// set: measured at z = -1 and +1, unavailable at z = 0.
    fn outflow_rows() -> Vec<Row> {
        let p = baffle_core::phantom::phantom_default();
        let options = baffle_core::DesignOptions::default();
        let report = design(&p.surface, &p.suture_points_mm, &TargetArea::AreaMm2(60.0), &options, &mut |_, _| true).unwrap().report;
        let measured = |smallest: f64, before: f64, after: f64| RvOutflow {
            rv_outflow_min_section_mm2: Some(smallest),
            rv_outflow_min_section_before_mm2: Some(smallest),
            rv_outflow_most_narrowed: Some(NarrowedSection {
                area_before_mm2: before,
                area_after_mm2: after,
                after_over_before: after / before,
                distance_from_pulmonary_end_mm: 11.3,
                point_mm: [0.0; 3],
                normal: [0.0, 0.0, 1.0],
            }),
            rv_outflow_unavailable: None,
            ..RvOutflow::unavailable("")
        };
        let outflows = [(-1.0, measured(17.0, 320.0, 230.0)), (0.0, RvOutflow::unavailable("the pulmonary artery does not touch the RV")), (1.0, measured(17.0, 330.0, 180.0))];
        outflows
            .into_iter()
            .map(|(z, outflow)| {
                let mut report = report.clone();
                report.rv_cost.rv_outflow = outflow;
                Row { z_score: Some(z), target_area_mm2: 60.0, outcome: Outcome::Designed(Box::new(report)), design_ms: 1.0, quick: None }
            })
            .collect()
    }

    /// A chart's data coordinates from its tick labels: (value, pixel) pairs of an axis.
    fn axis_map(ticks: &[(f64, f64)]) -> impl Fn(f64) -> f64 {
        let ((v0, p0), (v1, p1)) = (ticks[0], ticks[ticks.len() - 1]);
        move |pixel| v0 + (pixel - p0) * (v1 - v0) / (p1 - p0)
    }

    #[test]
    fn the_plot_shows_the_rv_outflow_sections_with_unmeasured_rows_as_gaps() {
        let svg = plot(&outflow_rows());
        let doc = roxmltree::Document::parse(&svg).expect("the sweep plot is XML");
        let chart = doc
            .descendants()
            .filter(|n| n.has_tag_name("svg"))
            .find(|c| c.children().find(|n| n.has_tag_name("text")).and_then(|t| t.text()) == Some("RV outflow (apex region to the pulmonary artery)"))
            .expect("an RV outflow chart");
        let number = |n: roxmltree::Node, a: &str| n.attribute(a).unwrap().parse::<f64>().unwrap();
        let texts: Vec<roxmltree::Node> = chart.children().filter(|n| n.has_tag_name("text")).collect();
        let value = |t: &roxmltree::Node| t.text().and_then(|v| v.parse::<f64>().ok());
        // Tick labels: the y axis's are right-aligned (4 px below their line), the x axis's on one row under the plot.
        let y_ticks: Vec<(f64, f64)> = texts.iter().filter(|t| t.attribute("text-anchor") == Some("end")).filter_map(|t| Some((value(t)?, number(*t, "y") - 4.0))).collect();
        let x_ticks: Vec<(f64, f64)> = texts.iter().filter(|t| t.attribute("y") == Some("270")).filter_map(|t| Some((value(t)?, number(*t, "x")))).collect();
        let (to_y, to_x) = (axis_map(&y_ticks), axis_map(&x_ticks));
        let markers = |color: &str| -> Vec<(f64, f64)> {
            chart.children().filter(|n| n.has_tag_name("circle") && n.attribute("fill") == Some(color)).map(|c| (to_x(number(c, "cx")), to_y(number(c, "cy")))).collect()
        };
        let near = |a: &[(f64, f64)], b: &[(f64, f64)]| a.len() == b.len() && a.iter().zip(b).all(|(p, q)| (p.0 - q.0).abs() < 0.02 && (p.1 - q.1).abs() < 2.0);
        // Each series has a point at z = -1 and +1 and none at z = 0 (not a zero).
        for (color, expected) in [("#1f77b4", [(-1.0, 17.0), (1.0, 17.0)]), ("#7f7f7f", [(-1.0, 320.0), (1.0, 330.0)]), ("#ff7f0e", [(-1.0, 230.0), (1.0, 180.0)])] {
            assert!(near(&markers(color), &expected), "{color}: {:?}, expected {expected:?}", markers(color));
        }
        let legend: Vec<&str> = texts.iter().filter_map(|t| t.text()).collect();
        for label in ["smallest section", "most narrowed, before", "most narrowed, after", "section area (mm2)"] {
            assert!(legend.contains(&label), "{label}: {legend:?}");
        }
        let note = texts.iter().find(|t| t.attribute("class") == Some("note")).and_then(|t| t.text()).expect("a note on the missing row");
        assert!(note.starts_with("not measured at 1 of 3 designed targets: the pulmonary artery"), "{note}");
    }

    #[test]
    fn the_tables_carry_the_rv_outflow_sections_with_their_units() {
        let rows = outflow_rows();
        let csv = csv(&rows);
        let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        let column = |name: &str, line: usize| csv.lines().nth(line).unwrap().split(',').nth(header.iter().position(|h| *h == name).unwrap()).unwrap().to_string();
        assert_eq!(column("rv_outflow_min_section_mm2", 1), "17.00");
        assert_eq!(column("rv_outflow_most_narrowed_after_mm2", 3), "180.00");
        assert_eq!(column("rv_outflow_most_narrowed_after_over_before", 3), "0.5455");
        assert_eq!(column("rv_outflow_most_narrowed_from_pulmonary_end_mm", 1), "11.3");
        assert_eq!(column("rv_outflow_most_narrowed_after_mm2", 2), "", "not measured: empty, not 0");
        let md = markdown(&rows);
        assert!(md.contains("| RV outflow most narrowed: before / after (mm2) | left (%) | from the pulmonary end (mm) |"), "{md}");
        assert!(md.contains("| 17.0 | 330.0 / 180.0 | 55 | 11.3 |"), "{md}");
        assert!(md.contains("- RV outflow sections not measured: the pulmonary artery does not touch the RV"), "{md}");
        let json = json_doc(&rows, 1.0);
        assert_eq!(json["rows"][2]["rv_outflow_most_narrowed_before_mm2"], 330.0);
        assert!(json["rows"][1]["rv_outflow_most_narrowed_after_mm2"].is_null());
    }
}
