//! The plan's report: report.json and a self-contained report.html (inline SVG charts,
//! PNG pictures as data URLs, no scripts, no external references), built only from the
//! stages' own files. The 3D pictures are VTK's (see `pictures`).

mod paper;
mod pictures;
pub(crate) mod svg_plot;

use crate::plan_stages::{flow_bsa_m2, FlowCase, PlanLayout, PlanSettings, Stage, StageRecord, Step};
use crate::sampling::{PeakFields, Profile};
use crate::files::{read_json, write_atomic};
use crate::centerline_cmd::CenterlineFigures;
use crate::run_summary::{required, RunSummary};
use baffle_cfd::Waveform;
use baffle_core::design::SectionRecord;
use baffle_core::analyses::hemodynamics_estimate::{compare_with_3d, EstimateComparison, EstimateOutcome};
use baffle_core::analyses::rv_outflow::{NarrowedSection, RvOutflow};
use baffle_core::DesignReport;
use baffle_mesh::QualityReport;
use baffle_prepare::extend::ExtendReport;
use baffle_prepare::prepare::CapReport;
use baffle_prepare::separation::CutSeparation;
use baffle_prepare::PrepareReport;
use serde::Serialize;
use serde_json::{json, Value};
use svg_plot::{escape, line_chart, Series};
use std::fmt::Write;
use std::path::{Path, PathBuf};
use crate::mesh_convergence::Level;
use crate::verdict::{self, MeshStudy, Verdict, DP_THRESHOLD_MMHG};

/// A table value for report.json: counts as integers, non-finite as null.
fn json_value(q: &Quantity) -> Value {
    match q.value {
        v if !v.is_finite() => Value::Null,
        v if q.decimals == 0 => json!(v.round() as i64),
        v => json!(v),
    }
}

fn write_json(path: &Path, doc: &Value) -> Result<(), String> {
    write_atomic(path, serde_json::to_string_pretty(doc).map_err(|e| e.to_string())?.as_bytes())
}

pub fn write_failure_json(layout: &PlanLayout, stage: &str, error: &str, records: &[StageRecord]) -> Result<(), String> {
    let doc = json!({ "status": "failed", "failed_stage": stage, "error": error, "stages": records });
    write_json(&layout.report_json(), &doc)
}

/// One simulation run with the mesh it ran on.
struct Run {
    stage: String,
    level: &'static str,
    flow: FlowCase,
    cardiac_index_l_min_m2: f64,
    edge_length_mm: f64,
    quality: QualityReport,
    summary: RunSummary,
    summary_path: PathBuf,
}

impl Run {
    fn dp_mmhg(&self) -> Result<f64, String> {
        required(self.summary.dp_peak_mmhg, "dp_peak_mmhg", &self.summary_path)
    }
    /// This run as a level of a mesh study (its dp NaN when it gave none).
    fn mesh_level(&self) -> Level {
        Level {
            edge_length_mm: self.edge_length_mm,
            tetrahedra: self.quality.tetrahedra,
            volume_mm3: self.quality.volume_mm3,
            value: self.dp_mmhg().unwrap_or(f64::NAN),
        }
    }
    fn v_max_m_s(&self) -> Result<f64, String> {
        required(self.summary.max_velocity_m_s, "max_velocity_m_s", &self.summary_path)
    }
    fn peak_time_s(&self) -> Result<f64, String> {
        required(self.summary.peak_time_s, "peak_time_s", &self.summary_path)
    }
    fn period_s(&self) -> Result<f64, String> {
        required(self.summary.inputs.period_s, "inputs.period_s", &self.summary_path)
    }
    /// This run's own verdict (its solve and cycles; the mesh study is the plan's).
    fn verdict(&self) -> Verdict {
        Verdict::of(self.dp_mmhg().unwrap_or(f64::NAN), verdict::run_doubts(&self.summary))
    }
}

fn load_runs(args: &PlanSettings, layout: &PlanLayout, stages: &[Stage], records: &[StageRecord]) -> Result<Vec<Run>, String> {
    let edge = |level: &str| {
        stages.iter().find_map(|s| match s.step {
            Step::Mesh { level: l, edge_length_mm } if l == level => Some(edge_length_mm),
            _ => None,
        })
    };
    let mut runs = Vec::new();
    for (stage, record) in stages.iter().zip(records) {
        if record.status != "completed" {
            continue;
        }
        if let Step::Simulate { level, flow } = stage.step {
            let summary_path = layout.stage_dir(&stage.name).join("summary.json");
            let quality_path = layout.mesh(level).with_file_name("mesh-quality.json");
            runs.push(Run {
                stage: stage.name.clone(),
                level,
                flow,
                cardiac_index_l_min_m2: flow.cardiac_index_l_min_m2(args),
                edge_length_mm: edge(level).unwrap_or(f64::NAN),
                quality: read_json(&quality_path)?,
                summary: read_json(&summary_path)?,
                summary_path,
            });
        }
    }
    Ok(runs)
}

/// A row of the paper's table: key in report.json, label, value, unit, decimals.
struct Quantity {
    key: &'static str,
    label: &'static str,
    value: f64,
    unit: &'static str,
    decimals: usize,
}

/// A figure of the section the baffle narrows most (NaN when it was not measured).
fn most_narrowed(outflow: &RvOutflow, figure: fn(&NarrowedSection) -> f64) -> f64 {
    outflow.rv_outflow_most_narrowed.as_ref().map_or(f64::NAN, figure)
}

fn quantities(design: &DesignReport, nominal: &Run, centerline: &CenterlineProfile) -> Result<Vec<Quantity>, String> {
    let (q, rv, outflow) = (&nominal.quality, &design.rv_cost, &design.rv_cost.rv_outflow);
    let row = |key, label, value, unit, decimals| Quantity { key, label, value, unit, decimals };
    Ok(vec![
        row("target_area_mm2", "Target area", design.target_area_mm2, "mm²", 1),
        row("centerline_length_mm", "Centerline length", design.centerline_length_mm, "mm", 2),
        row("flow_centerline_length_mm", "Flow-domain centerline length", centerline.length_mm, "mm", 2),
        row("min_flow_section_mm2", "Smallest tunnel section normal to the flow (flow-domain centerline)", centerline.min_section_mm2, "mm²", 1),
        row("baffle_area_mm2", "Baffle area", design.baffle_area_mm2, "mm²", 1),
        row("baffle_triangles", "Baffle triangles", design.baffle_triangles as f64, "", 0),
        row("rv_volume_before_ml", "RV volume before the baffle (capped ventricle)", rv.rv_volume_before_ml, "mL", 2),
        row("rv_volume_after_ml", "RV volume after the baffle (outside the pathway)", rv.rv_volume_after_ml, "mL", 2),
        // Null where the pulmonary artery is not known or does not touch the RV ("—").
        row("rv_outflow_min_section_mm2", "RV outflow smallest section after the baffle (apex region to the pulmonary interface)", outflow.rv_outflow_min_section_mm2.unwrap_or(f64::NAN), "mm²", 1),
        row("rv_outflow_most_narrowed_before_mm2", "RV outflow section the baffle narrows most: before the baffle", most_narrowed(outflow, |n| n.area_before_mm2), "mm²", 1),
        row("rv_outflow_most_narrowed_after_mm2", "RV outflow section the baffle narrows most: after the baffle", most_narrowed(outflow, |n| n.area_after_mm2), "mm²", 1),
        row("rv_outflow_most_narrowed_after_over_before", "RV outflow section the baffle narrows most: after / before", most_narrowed(outflow, |n| n.after_over_before), "", 2),
        row("rv_outflow_most_narrowed_from_pulmonary_end_mm", "RV outflow section the baffle narrows most: distance from the pulmonary end", most_narrowed(outflow, |n| n.distance_from_pulmonary_end_mm), "mm", 1),
        row("tetrahedra", "Tetrahedra", q.tetrahedra as f64, "", 0),
        row("min_scaled_jacobian", "Scaled Jacobian, min", q.min_scaled_jacobian, "", 3),
        row("p1_scaled_jacobian", "Scaled Jacobian, 1st percentile", q.p1_scaled_jacobian, "", 3),
        row("p99_aspect_ratio", "Aspect ratio, 99th percentile", q.p99_aspect_ratio, "", 2),
        row("dp_peak_mmhg", "Pressure difference at peak flow (VSD − aortic cap)", nominal.dp_mmhg()?, "mmHg", 2),
        row("max_velocity_m_s", "v_max (domain)", nominal.v_max_m_s()?, "m/s", 3),
        row("max_centerline_velocity_m_s", "v_max along the flow-domain centerline", centerline.profile.v_max_m_s(), "m/s", 3),
    ])
}

/// The design's reduced-order estimate of dp and v_max beside the nominal 3D run (report.json
/// `hemodynamics_estimate`). Advisory: the verdict is the 3D dp's and never reads this.
#[derive(serde::Serialize)]
struct EstimateBeside3d {
    /// As the design stage wrote it (design/report.json), or why there is none.
    design: EstimateOutcome,
    /// Against the nominal run's plane-averaged dp and the flow-centerline v_max (the 3D
    /// quantities the estimate's error was measured on).
    comparison_with_3d: Option<EstimateComparison>,
    comparison_absent_because: Option<String>,
    /// The 3D run the estimate is set beside, in words, and how far its error range (measured
    /// on first peaks) is known to hold for it.
    compared_with: String,
    verdict_uses: &'static str,
}

/// What is measured of a later peak's or a steady solve's dp against the first peak's, on
/// which the estimate's error range was measured (docs/validation.md).
const OTHER_RUNS_AGAINST_FIRST_PEAK: &str = "the estimate's error range was measured against first peaks; on p1-p3's published domains the fourth cycle's peak dp lay within 0.031 mmHg of the first, and a converged steady solve at peak flow within 0.02 mmHg of it on p2's (docs/validation.md)";

/// The 3D figure the estimate is compared with, in words (`run`'s mode and mesh).
fn compared_run_text(run: &RunSummary, edge_length_mm: f64) -> String {
    let mesh = format!("the nominal {edge_length_mm:.2} mm mesh");
    if run.is_quick() {
        return format!("the dp at the first flow peak of {mesh}, the kind of run the estimate's error range was measured on");
    }
    let figure = if run.is_steady() { "the steady solve's dp at peak flow" } else { "the dp at the last cycle's flow peak" };
    format!("{figure} of {mesh}: {OTHER_RUNS_AGAINST_FIRST_PEAK}")
}

impl EstimateBeside3d {
    /// `design`: the design report's `hemodynamics_estimate` (None: the file at
    /// `design_path` has none); `run`: the nominal run's summary, whose dp and v_max these
    /// are. A run with doubts (`run_doubts`: unconverged, stopped early) is no reference.
    fn of(design: Option<&EstimateOutcome>, design_path: &Path, dp_3d_mmhg: f64, v_max_3d_m_s: f64, run: &RunSummary, edge_length_mm: f64) -> EstimateBeside3d {
        let design = match design {
            Some(outcome) => outcome.clone(),
            None => EstimateOutcome::Absent { absent_because: format!("{} has no hemodynamics_estimate", design_path.display()) },
        };
        let doubts = crate::verdict::run_doubts(run);
        let compared = match &design {
            EstimateOutcome::Absent { .. } => Err("the design has no estimate".into()),
            EstimateOutcome::Estimated(_) if !doubts.is_empty() => Err(format!("the 3D run is no reference: {}", doubts.join("; "))),
            EstimateOutcome::Estimated(e) => compare_with_3d(e, dp_3d_mmhg, v_max_3d_m_s),
        };
        let (comparison_with_3d, comparison_absent_because) = match compared {
            Ok(c) => (Some(c), None),
            Err(why) => (None, Some(why)),
        };
        let compared_with = compared_run_text(run, edge_length_mm);
        EstimateBeside3d { design, comparison_with_3d, comparison_absent_because, compared_with, verdict_uses: "the 3D dp (dp_peak_mmhg); the estimate never changes the verdict" }
    }

    /// One paragraph for report.html, beside the 3D dp.
    fn text(&self) -> String {
        match (&self.design, &self.comparison_with_3d, &self.comparison_absent_because) {
            (_, Some(c), _) => format!("{} Compared with {}. The verdict uses the 3D dp.", c.text, self.compared_with),
            (EstimateOutcome::Estimated(e), None, why) => format!(
                "Reduced-order estimate (not a CFD result): {:.2} mmHg, v_max {:.2} m/s at peak flow {:.1} ml/s; not compared with the 3D run ({}). The verdict uses the 3D dp.",
                e.dp_estimate_mmhg,
                e.v_max_estimate_m_s,
                e.peak_flow_ml_s,
                why.as_deref().unwrap_or("no reason given")
            ),
            (EstimateOutcome::Absent { absent_because }, None, _) => format!("No reduced-order estimate of dp: {absent_because}."),
        }
    }
}

/// The RV outflow figures in words for the surgeon: what each means, or why there are none.
fn rv_outflow_text(outflow: &RvOutflow) -> String {
    if let Some(reason) = &outflow.rv_outflow_unavailable {
        return format!("RV outflow sections not measured: {reason}.");
    }
    let n = |figure| most_narrowed(outflow, figure);
    let (ratio, after, distance) = (n(|n| n.after_over_before), n(|n| n.area_after_mm2), n(|n| n.distance_from_pulmonary_end_mm));
    let smallest = outflow.rv_outflow_min_section_mm2.unwrap_or(f64::NAN);
    let verdict = if ratio >= 1.0 {
        "the baffle narrows no section of it".to_string()
    } else if after >= smallest {
        format!("where the baffle narrows it most ({distance:.1} mm from the pulmonary end) {:.0} % of the section is left, {after:.1} mm², still no less than the smallest section ({smallest:.1} mm²): the baffle does not make a new narrowest point", 100.0 * ratio)
    } else {
        format!("where the baffle narrows it most ({distance:.1} mm from the pulmonary end) {:.0} % of the section is left, {after:.1} mm²: this is the outflow's narrowest point after the baffle", 100.0 * ratio)
    };
    format!(
        "RV outflow (the widest, centred path from the RV apex region to the pulmonary artery, with no pulmonary valve plane known): its smallest section is {smallest:.1} mm² after the baffle; {verdict}."
    )
}

/// The flow-domain centerline of the centerline stage (mm) and the nominal run's
/// pressure and speed sampled along it.
struct CenterlineProfile {
    vtp: std::path::PathBuf,
    line: baffle_core::io::PolyData,
    length_mm: f64,
    /// The tunnel's smallest section normal to the flow and its arc length (mm2, mm; NaN
    /// when none was measured).
    min_section_mm2: f64,
    min_section_at_mm: f64,
    s_mm: Vec<f64>,
    profile: Profile,
}

/// Name of the centerline's pressure relative to the aortic plane (report.json, centerline.vtp).
const GAUGE_PRESSURE: &str = "pressure_rel_aortic_plane_mmhg";

fn centerline_profile(layout: &PlanLayout, peak_path: &Path) -> Result<CenterlineProfile, String> {
    let (vtp, json_path) = crate::centerline_cmd::output_paths(&layout.flow_centerline());
    let line = baffle_core::io::read_polydata(&vtp).map_err(|e| e.to_string())?;
    let s_mm = match line.point_array("s_mm").and_then(|a| a.as_f64()) {
        Some((1, values)) => values.to_vec(),
        _ => return Err(format!("{}: no point array s_mm", vtp.display())),
    };
    let figures: CenterlineFigures = read_json(&json_path)?;
    let (min_section_mm2, min_section_at_mm) = (figures.min_section_mm2.unwrap_or(f64::NAN), figures.min_section_at_mm.unwrap_or(f64::NAN));
    let profile = PeakFields::read(peak_path)?.profile(&line.points);
    Ok(CenterlineProfile { vtp, line, length_mm: figures.length_mm, min_section_mm2, min_section_at_mm, s_mm, profile })
}

impl CenterlineProfile {
    /// The sampled pressure minus `reference_mmhg` (None where the point was not sampled).
    fn gauge_mmhg(&self, reference_mmhg: f64) -> Vec<Option<f64>> {
        self.profile.pressure_mmhg.iter().map(|p| p.map(|p| p - reference_mmhg)).collect()
    }

    /// centerline.vtp again, with the nominal run's peak fields sampled on it: pressure_mmhg
    /// (as in peak.vtu), the pressure relative to the aortic plane, and speed_m_s (NaN
    /// where a point was not sampled), so it can be coloured beside the results.
    fn write_with_fields(&self, reference_mmhg: f64) -> Result<(), String> {
        let mut line = self.line.clone();
        let values = |v: &[Option<f64>]| v.iter().map(|x| x.unwrap_or(f64::NAN)).collect::<Vec<f64>>();
        let arrays = [
            ("pressure_mmhg", values(&self.profile.pressure_mmhg)),
            (GAUGE_PRESSURE, values(&self.gauge_mmhg(reference_mmhg))),
            ("speed_m_s", values(&self.profile.speed_m_s)),
        ];
        line.point_data.retain(|a| !arrays.iter().any(|(name, _)| a.name == *name));
        line.point_data.extend(arrays.into_iter().map(|(name, v)| baffle_core::io::DataArray::f64(name, 1, v)));
        baffle_core::io::write_vtp(&self.vtp, &line).map_err(|e| e.to_string())
    }
}

/// The tunnel narrower than the target where the flow crosses it: the design constrains
/// sections normal to the paper's centerline (2.4.2), which runs oblique to the flow near
/// the caps, so the flow's own sections can be smaller (issue 13: 11-25% on p1 and p3).
fn flow_section_warning(line: &CenterlineProfile, target_mm2: f64) -> Option<String> {
    // Within the design rule's own tolerance (`--flow-sections` stops there) is no shortfall.
    (line.min_section_mm2 < target_mm2 * (1.0 - baffle_core::flow_target::FLOW_TARGET_TOLERANCE)).then(|| {
        format!(
            "the tunnel's smallest section normal to the flow is {:.1} mm² at {:.1} mm from the VSD plane along the flow-domain centerline, {:.0} % below the target {:.1} mm²: \
             the design makes the sections normal to the paper's centerline (between the cap centroids) at least the target, and that centerline runs oblique to the flow",
            line.min_section_mm2,
            line.min_section_at_mm,
            100.0 * (1.0 - line.min_section_mm2 / target_mm2),
            target_mm2
        )
    })
}

/// How the centerline's pressure drop compares with the plane-averaged dp, in report.json
/// and in the report's words.
struct PressureComparison {
    centerline_drop_mmhg: f64,
    min_gauge_mmhg: f64,
    min_at_s_mm: f64,
}

impl PressureComparison {
    fn of(s_mm: &[f64], gauge: &[Option<f64>]) -> PressureComparison {
        let sampled: Vec<(f64, f64)> = s_mm.iter().zip(gauge).filter_map(|(&s, p)| Some((s, (*p)?))).collect();
        let drop = match (sampled.first(), sampled.last()) {
            (Some(first), Some(last)) => first.1 - last.1,
            _ => f64::NAN,
        };
        let min = sampled.iter().copied().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap_or((f64::NAN, f64::NAN));
        PressureComparison { centerline_drop_mmhg: drop, min_gauge_mmhg: min.1, min_at_s_mm: min.0 }
    }

    /// The paragraph under the centerline plot.
    fn text(&self, dp_mmhg: f64, reference_mmhg: f64) -> String {
        format!(
            "Pressures are gauge: relative to the mean pressure over the aortic-annulus plane at peak flow ({reference_mmhg:.2} mmHg on the solver's scale, \
whose zero is downstream of the outlet resistance). The verdict uses the plane-averaged pressure difference, {dp_mmhg:.2} mmHg: the mean over the whole \
VSD plane minus the mean over the whole aortic plane, as in the paper. Along the flow-domain centerline the pressure falls by {:.2} mmHg from its VSD end \
to its aortic end ({:+.2} mmHg against the plane-averaged dp). The two differ because the centerline samples single points in the middle of the flow, where it \
is fastest: there the pressure is lower than the section's mean by the extra dynamic pressure (Bernoulli), and in a bend the pressure also varies across \
the section. The lowest centerline pressure is {:.2} mmHg at s = {:.1} mm; a value below zero is a point below the aortic plane's mean, not a negative pressure.",
            self.centerline_drop_mmhg,
            self.centerline_drop_mmhg - dp_mmhg,
            self.min_gauge_mmhg,
            self.min_at_s_mm
        )
    }
}

/// A run's timeseries.csv: its header and numeric rows.
struct Timeseries {
    path: std::path::PathBuf,
    header: Vec<String>,
    rows: Vec<Vec<f64>>,
}

impl Timeseries {
    fn read(run_dir: &Path) -> Result<Timeseries, String> {
        let path = run_dir.join("timeseries.csv");
        let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut lines = text.lines();
        let header = lines.next().unwrap_or("").split(',').map(str::to_string).collect();
        let rows = lines.map(|l| l.split(',').map(|v| v.parse().unwrap_or(f64::NAN)).collect()).collect();
        Ok(Timeseries { path, header, rows })
    }

    fn column(&self, name: &str) -> Result<usize, String> {
        self.header.iter().position(|h| h == name).ok_or_else(|| format!("{}: no column {name}", self.path.display()))
    }

    /// The mean pressure over `face` (its timeseries name) at the run's peak flow (its
    /// time `peak` in s; mmHg).
    fn pressure_at_peak_mmhg(&self, peak: f64, face: &str) -> Result<f64, String> {
        let (t, p) = (self.column("time_s")?, self.column(&format!("p_{face}_mmhg"))?);
        self.rows
            .iter()
            .min_by(|a, b| (a[t] - peak).abs().total_cmp(&(b[t] - peak).abs()))
            .map(|row| row[p])
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{}: no pressure of {face} at the peak time {peak} s", self.path.display()))
    }

    /// (time in cycle, dp) over the last cycle of the run of `period_s`; empty for a
    /// steady run (None). `faces`: the timeseries' names of the two faces dp is taken
    /// between (first minus second).
    fn dp_over_cycle(&self, period_s: Option<f64>, faces: (&str, &str)) -> Result<Vec<(f64, f64)>, String> {
        let Some(period) = period_s else {
            return Ok(Vec::new());
        };
        let (t, a, b) = (self.column("time_s")?, self.column(&format!("p_{}_mmhg", faces.0))?, self.column(&format!("p_{}_mmhg", faces.1))?);
        let last = self.rows.last().map_or(0.0, |r| r[t]);
        let start = (last - period).max(0.0);
        Ok(self.rows.iter().filter(|r| r[t] > start + 1e-12).map(|r| (r[t] - start, r[a] - r[b])).collect())
    }
}

fn waveform_series(run: &Run, color: &'static str) -> Result<Series, String> {
    let q_mean = required(run.summary.inputs.q_mean_ml_s, "inputs.q_mean_ml_s", &run.summary_path)?;
    let period = run.period_s()?;
    let w = Waveform::Ejection { period_s: period, q_mean_ml_s: q_mean };
    let points = (0..=200).map(|k| period * k as f64 / 200.0).map(|t| (t, w.flow_ml_s(t))).collect();
    let label = format!("CI {:.2} L/min/m²", run.cardiac_index_l_min_m2);
    Ok(Series::line(&label, points, color))
}

/// The plan's verdict: the nominal run's own doubts, the mesh study's and the design's.
fn plan_verdict(nominal: &Run, study: Option<&Result<MeshStudy, String>>, design: &DesignReport) -> Verdict {
    let dp = nominal.dp_mmhg().unwrap_or(f64::NAN);
    let mut doubts = verdict::run_doubts(&nominal.summary);
    doubts.extend(study.and_then(|s| verdict::mesh_study_doubt(dp, s)));
    doubts.extend(verdict::design_doubt(design.min_constrained_final_area_mm2, design.target_area_mm2));
    Verdict::of(dp, doubts)
}

/// The mesh study of the nominal-flow runs (None with --single-mesh); a level whose stage
/// failed makes it an error that says which and why.
fn mesh_study(args: &PlanSettings, runs: &[Run], records: &[StageRecord]) -> Option<Result<MeshStudy, String>> {
    if !args.runs_mesh_study() {
        return None;
    }
    if let Some(failed) = records.iter().find(|r| r.status == "failed") {
        // One line: the verdict is the command's last line.
        let why: Vec<&str> = failed.error.as_deref().unwrap_or("no reason given").lines().map(str::trim).filter(|l| !l.is_empty()).collect();
        return Some(Err(format!("its stage {} failed: {}", failed.name, why.join("; "))));
    }
    let levels: Vec<Level> = runs.iter().filter(|r| r.flow == FlowCase::Nominal).map(Run::mesh_level).collect();
    Some(MeshStudy::of(&levels))
}

/// report.json's `mesh_study`: the grid convergence of dp, or why there is none.
fn mesh_study_json(study: &Result<MeshStudy, String>) -> Value {
    match study {
        Ok(s) => json!({
            "quantity": "dp_peak_mmhg", "method": "grid convergence index, Celik et al. 2008 (three levels, observed order)",
            "fine_edge_length_mm": s.fine_edge_length_mm, "fine_dp_mmhg": s.fine_dp_mmhg,
            "observed_order": s.dp.observed_order, "asymptotic": s.dp.asymptotic, "oscillatory": s.dp.oscillatory,
            "extrapolated_dp_mmhg": s.dp.extrapolated, "gci_fine": s.dp.gci_fine, "band_mmhg": s.dp.band,
            "converged": s.dp.gci_fine <= verdict::MESH_GCI_LIMIT, "gci_limit": verdict::MESH_GCI_LIMIT,
        }),
        Err(e) => json!({ "quantity": "dp_peak_mmhg", "error": e }),
    }
}

fn profile_series(s_mm: &[f64], values: &[Option<f64>]) -> Vec<(f64, f64)> {
    s_mm.iter().zip(values).map(|(&s, v)| (s, v.unwrap_or(f64::NAN))).collect()
}

fn section_area_chart(design: &DesignReport) -> String {
    let sections = &design.sections;
    let series_of = |area: fn(&SectionRecord) -> Option<f64>| -> Vec<(f64, f64)> { sections.iter().filter_map(|s| Some((s.s_mm, area(s)?))).collect() };
    let finals = series_of(|s| s.final_area_mm2);
    let target = design.target_area_mm2;
    let (s0, s1) = (sections.first().map_or(0.0, |s| s.s_mm), sections.last().map_or(1.0, |s| s.s_mm));
    let series = [
        Series { markers: finals.len() < 40, ..Series::line("designed", finals, "#1f77b4") },
        Series { dashed: true, ..Series::line("initial patch", series_of(|s| s.raw_area_mm2), "#999999") },
        Series { dashed: true, ..Series::line("target", vec![(s0, target), (s1, target)], "#d62728") },
    ];
    line_chart("Section area along the centerline", "arc length from the VSD s (mm)", "area (mm²)", &series, true)
}

struct Html(String);

impl Html {
    fn heading(&mut self, text: &str) {
        let _ = writeln!(self.0, "<h2>{}</h2>", escape(text));
    }
    fn para(&mut self, text: &str) {
        let _ = writeln!(self.0, "<p>{}</p>", escape(text));
    }
    fn figure(&mut self, svg: &str, caption: &str) {
        let _ = writeln!(self.0, "<figure>{svg}<figcaption>{}</figcaption></figure>", escape(caption));
    }
    /// A rendered picture, embedded (the PNG file stays in pictures/ beside the report).
    fn picture(&mut self, picture: &pictures::Picture) {
        let _ = writeln!(
            self.0,
            "<figure class=\"picture\"><img src=\"data:image/png;base64,{}\" alt=\"{}\"/><figcaption>{}</figcaption></figure>",
            pictures::base64(&picture.png),
            escape(&picture.title),
            escape(&picture.caption)
        );
    }
    /// The rendered pictures of one section of the report.
    fn pictures(&mut self, pictures: &[pictures::Picture], section: &str) {
        for picture in pictures.iter().filter(|p| p.section == section) {
            self.picture(picture);
        }
    }
    fn table(&mut self, header: &[&str], rows: &[Vec<String>]) {
        self.0.push_str("<table><tr>");
        for h in header {
            let _ = write!(self.0, "<th>{}</th>", escape(h));
        }
        self.0.push_str("</tr>\n");
        for row in rows {
            self.0.push_str("<tr>");
            for cell in row {
                let _ = write!(self.0, "<td>{}</td>", escape(cell));
            }
            self.0.push_str("</tr>\n");
        }
        self.0.push_str("</table>\n");
    }
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}\
table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:3px 8px;text-align:left}\
figure{display:inline-block;margin:0.5em;vertical-align:top}figcaption{font-size:0.85em;color:#555}\
figure.picture{width:480px}figure.picture img{width:480px;height:auto;border:1px solid #ddd}\
.passes{background:#dff0d8;padding:0.6em;border:1px solid #3c763d}.fails{background:#f2dede;padding:0.6em;border:1px solid #a94442}\
.inconclusive{background:#fcf8e3;padding:0.6em;border:1px solid #8a6d3b}.warning{color:#8a6d3b}";

/// The date and time now, UTC ("2026-12-02 12:34 UTC"), for the report's header.
fn utc_now() -> String {
    let seconds = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs() as i64);
    utc_date_time(seconds)
}

/// Unix seconds as a UTC date and time (days to civil date: H. Hinnant's algorithm).
fn utc_date_time(seconds: i64) -> String {
    let (days, rest) = (seconds.div_euclid(86_400), seconds.rem_euclid(86_400));
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02} {:02}:{:02} UTC", rest / 3600, rest % 3600 / 60)
}

fn format_value(v: f64, decimals: usize) -> String {
    if v.is_finite() { format!("{v:.decimals$}") } else { "—".into() }
}

/// A cap of the prepare or extend stage as report.json gives it.
#[derive(Serialize)]
struct Cap {
    label: i32,
    area_mm2: f64,
    centroid_mm: [f64; 3],
}

impl From<&CapReport> for Cap {
    fn from(c: &CapReport) -> Cap {
        Cap { label: c.label, area_mm2: c.area_mm2, centroid_mm: c.centroid_mm }
    }
}

/// The prepare stage's figures in report.json: its report's caps, separation and size,
/// and the stage's wall time.
#[derive(Serialize)]
struct PrepareSummary {
    report: PathBuf,
    wall_time_s: Option<f64>,
    triangles: usize,
    vsd_cap: Cap,
    aortic_cap: Cap,
    separation: CutSeparation,
}

/// The prepare stage's report (cap areas and centroids) and wall time, if it ran.
fn prepare_summary(layout: &PlanLayout, records: &[StageRecord]) -> Result<Option<PrepareSummary>, String> {
    let Some(record) = records.iter().find(|r| r.name == "prepare") else { return Ok(None) };
    let path = crate::prepare_cmd::report_path(&layout.prepared_surface());
    let doc: PrepareReport = read_json(&path)?;
    Ok(Some(PrepareSummary {
        report: path,
        wall_time_s: record.wall_time_s,
        triangles: doc.triangles,
        vsd_cap: Cap::from(&doc.vsd_cap),
        aortic_cap: Cap::from(&doc.aortic_cap),
        separation: doc.separation,
    }))
}

/// How far apart prepare kept the two openings, and how far it moved their cuts to do so.
fn separation_text(separation: &CutSeparation) -> String {
    let mm = |v: f64| format_value(v, 2);
    let gap = format!("The VSD and aortic openings are {} mm apart (at least {} mm).", mm(separation.rim_gap_mm), mm(separation.clearance_mm));
    if !separation.moved() {
        return gap;
    }
    format!(
        "{gap} Their interfaces meet (within {} mm), so the VSD cut was moved {} mm into the LV and the aortic cut {} mm up the aortic root: \
         the caps lie that far from the anatomical openings.",
        mm(separation.interface_loops_gap_mm),
        mm(separation.vsd_cut_moved_into_lv_mm),
        mm(separation.aortic_cut_moved_into_aorta_mm)
    )
}

/// The HTML rows of the prepare stage's caps: name, label, area, centroid.
fn prepare_rows(prepare: &PrepareSummary) -> Vec<Vec<String>> {
    let cap_row = |name: &str, cap: &Cap| {
        let centroid: Vec<String> = cap.centroid_mm.iter().map(|&c| format_value(c, 2)).collect();
        vec![name.to_string(), cap.label.to_string(), format_value(cap.area_mm2, 1), format!("({})", centroid.join(", "))]
    };
    vec![cap_row("VSD cap", &prepare.vsd_cap), cap_row("Aortic cap", &prepare.aortic_cap)]
}

/// The CFD domain in report.json: the extend stage's figures, or why the designed domain
/// was kept.
#[derive(Serialize)]
struct CfdDomain {
    extended: bool,
    note: &'static str,
    #[serde(flatten)]
    extension: Option<Extension>,
}

/// The extend stage's figures (report.json `domain`).
#[derive(Serialize)]
struct Extension {
    report: PathBuf,
    wall_time_s: Option<f64>,
    triangles: usize,
    volume_mm3: f64,
    designed_volume_mm3: f64,
    baffle_area_relative_change: f64,
    inflow_cap: Cap,
    outflow_cap: Cap,
    mid_lv_distance_from_vsd_mm: f64,
    stj_found: bool,
    stj_distance_from_annulus_mm: f64,
    stj_note: String,
}

/// The CFD domain: the extend stage's figures, or why the designed domain was kept.
fn domain_summary(args: &PlanSettings, layout: &PlanLayout, records: &[StageRecord]) -> Result<CfdDomain, String> {
    let Some(record) = records.iter().find(|r| r.name == "extend").filter(|_| crate::plan_stages::is_extended(args)) else {
        return Ok(CfdDomain {
            extended: false,
            note: "the designed domain (VSD cap to aortic-annulus cap) as CFD domain, plug inflow at the VSD cap: with --surface no LV or aorta is known to extend it (give --segmentations or --labelmap)",
            extension: None,
        });
    };
    let path = crate::prepare_cmd::report_path(&layout.extended_surface());
    let doc: ExtendReport = read_json(&path)?;
    let extension = Extension {
        report: path,
        wall_time_s: record.wall_time_s,
        triangles: doc.triangles,
        volume_mm3: doc.volume_mm3,
        designed_volume_mm3: doc.designed_volume_mm3,
        baffle_area_relative_change: doc.baffle_area_relative_change,
        inflow_cap: Cap::from(&doc.inflow_cap),
        outflow_cap: Cap::from(&doc.outflow_cap),
        mid_lv_distance_from_vsd_mm: doc.mid_lv_plane.distance_from_vsd_mm,
        stj_found: doc.stj.found,
        stj_distance_from_annulus_mm: doc.stj.distance_from_annulus_mm,
        stj_note: doc.stj.note,
    };
    Ok(CfdDomain {
        extended: true,
        note: "extended domain (paper 2.5): plug inflow at the mid-LV cap, outflow at the STJ cap; dp between the VSD and aortic-annulus caps as interior planes",
        extension: Some(extension),
    })
}

/// The report's paragraph on the CFD domain.
fn domain_text(domain: &CfdDomain) -> String {
    let Some(e) = &domain.extension else {
        return format!("CFD domain: {}.", domain.note);
    };
    format!(
        "CFD domain: {}. Inflow cap {} mm² at {} mm beyond the VSD (parallel to it, through the LV's centroid); outflow cap {} mm² at {} mm above the annulus ({}). Volume {} mm³ (designed {} mm³); baffle area change {:.1e}.",
        domain.note,
        format_value(e.inflow_cap.area_mm2, 1),
        format_value(e.mid_lv_distance_from_vsd_mm, 1),
        format_value(e.outflow_cap.area_mm2, 1),
        format_value(e.stj_distance_from_annulus_mm, 1),
        e.stj_note,
        format_value(e.volume_mm3, 0),
        format_value(e.designed_volume_mm3, 0),
        e.baffle_area_relative_change
    )
}

/// The last two components of `path` ("p2/segmentations"): enough to recognise the
/// input without printing where it lives (report.json keeps the full paths).
fn short_path(path: &Path) -> String {
    let parts: Vec<_> = path.components().rev().take(2).map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
    parts.into_iter().rev().collect::<Vec<_>>().join("/")
}

/// The nominal run's residual history: a steady solve's relative residual per iteration
/// against its target, or a transient run's per-step residual; log10 scale.
fn convergence_chart(nominal: &Run, timeseries: &Timeseries) -> Option<(String, String)> {
    let log = |(x, r): (f64, f64)| (x, if r > 0.0 { r.log10() } else { f64::NAN });
    let summary = &nominal.summary;
    if summary.is_steady() {
        let history: Vec<(f64, f64)> = summary.steady_relative_residuals.iter().enumerate().filter_map(|(k, r)| Some(log(((k + 1) as f64, (*r)?)))).collect();
        let tolerance = summary.inputs.steady_tolerance?;
        let end = history.last()?.0;
        let series = [
            Series { markers: history.len() < 80, ..Series::line("relative residual", history, "#1f77b4") },
            Series { dashed: true, ..Series::line("target", vec![(1.0, tolerance.log10()), (end, tolerance.log10())], "#d62728") },
        ];
        let converged = if summary.converged { "reached" } else { "did not reach" };
        let caption = format!("Steady solve: residual relative to the first iteration's (log10) per iteration; it {converged} its target {tolerance:.0e}.");
        return Some((line_chart("Solver convergence (steady)", "iteration", "log10 relative residual", &series, false), caption));
    }
    let (t, r) = (timeseries.column("time_s").ok()?, timeseries.column("residual").ok()?);
    let points: Vec<(f64, f64)> = timeseries.rows.iter().map(|row| log((row[t], row[r]))).collect();
    let series = [Series::line("residual", points, "#1f77b4")];
    Some((line_chart("Solver convergence (per time step)", "time (s)", "log10 residual", &series, false), "The final residual of each time step's solve (log10).".into()))
}

/// What the ventricle came from, for the report's first line.
fn surface_source(args: &PlanSettings) -> String {
    let p = &args.prepare;
    match (&p.segmentations, &p.labelmap, &args.design.surface) {
        (Some(dir), _, _) => format!("Segmentations {} (prepare stage)", short_path(dir)),
        (None, Some(file), _) => format!("Label map {} (prepare stage)", short_path(file)),
        (None, None, Some(surface)) => format!("Surface {}", short_path(surface)),
        (None, None, None) => "Surface: built-in phantom".into(),
    }
}

/// The patient's name in the report: --patient-label, else the paper's patient id.
fn patient_label(args: &PlanSettings, paper: Option<&paper::PaperPatient>) -> String {
    match (&args.patient_label, paper, args.design.phantom) {
        (Some(label), _, _) => label.clone(),
        (None, Some(p), _) => p.id.clone(),
        (None, None, true) => "built-in phantom".into(),
        (None, None, false) => "not named (give --patient-label)".into(),
    }
}

/// The plan's input file or folder (for the paper's patient it belongs to).
fn input_path(args: &PlanSettings) -> Option<&Path> {
    let p = &args.prepare;
    p.segmentations.as_deref().or(p.labelmap.as_deref()).or(args.design.surface.as_deref())
}

/// What the command line says at the end (the warnings, then the verdict line), and the
/// verdict with the nominal run's numbers it judged, for a library caller.
pub struct Outcome {
    pub warnings: Vec<String>,
    /// Why the report has no 3D pictures, when it has none.
    pub pictures_missing: Option<String>,
    pub verdict_line: String,
    pub verdict: Verdict,
    /// The nominal run's plane-averaged peak pressure difference (mmHg), as judged.
    pub dp_mmhg: f64,
    /// The nominal run's largest speed in the domain at peak flow (m/s).
    pub v_max_m_s: f64,
}

/// Write report.json and report.html from the stages' files.
pub fn write_reports(args: &PlanSettings, stages: &[Stage], records: &[StageRecord]) -> Result<Outcome, String> {
    let layout = PlanLayout::of(args);
    let out = layout.root();
    let labels = (args.design.labels.vsd_cap, args.design.labels.aortic_cap);
    let design_dir = layout.design_dir();
    let design_path = design_dir.join("report.json");
    let design: DesignReport = read_json(&design_path)?;
    let runs = load_runs(args, &layout, stages, records)?;
    let nominal = runs.iter().find(|r| r.level == "nominal" && r.flow == FlowCase::Nominal).ok_or("no nominal simulation stage")?;
    let nominal_dir = layout.stage_dir(&nominal.stage);
    let flow_line = centerline_profile(&layout, &nominal_dir.join("peak.vtu"))?;
    let profile = &flow_line.profile;
    let table = quantities(&design, nominal, &flow_line)?;
    let dp = nominal.dp_mmhg()?;
    let converged = nominal.summary.converged;
    let study = mesh_study(args, &runs, records);
    let verdict = plan_verdict(nominal, study.as_ref(), &design);
    let verdict_line = verdict.text(dp);
    let mut warnings: Vec<String> = verdict::mesh_warning(&nominal.quality).into_iter().collect();
    warnings.extend(study.as_ref().and_then(|s| s.as_ref().ok()?.warning()));
    if !args.runs_mesh_study() {
        warnings.push("dp comes from one mesh (--single-mesh): its discretization error is not known; without --single-mesh the plan runs the three-level mesh study".into());
    }
    // The requested target: with --flow-sections the design ran at a raised one.
    let goal_mm2 = design.flow_sections.as_ref().map_or(design.target_area_mm2, |f| f.goal_area_mm2);
    warnings.extend(flow_section_warning(&flow_line, goal_mm2));
    let cfd_domain = domain_summary(args, &layout, records)?;
    let dp_faces = if cfd_domain.extended {
        (format!("plane1_{}", labels.0), format!("plane2_{}", labels.1))
    } else {
        (format!("inlet_{}", labels.0), format!("outlet_{}", labels.1))
    };
    let timeseries = Timeseries::read(&nominal_dir)?;
    let period_s = if nominal.summary.is_steady() { None } else { Some(nominal.period_s()?) };
    let dp_cycle = timeseries.dp_over_cycle(period_s, (&dp_faces.0, &dp_faces.1))?;
    // Gauge pressures: relative to the aortic plane's mean at peak flow.
    let reference_mmhg = timeseries.pressure_at_peak_mmhg(nominal.peak_time_s()?, &dp_faces.1)?;
    let gauge = flow_line.gauge_mmhg(reference_mmhg);
    let comparison = PressureComparison::of(&flow_line.s_mm, &gauge);
    flow_line.write_with_fields(reference_mmhg)?;
    let prepare = prepare_summary(&layout, records)?;
    let paper = input_path(args).and_then(paper::PaperPatient::of_input);
    let estimate = EstimateBeside3d::of(design.hemodynamics_estimate.as_ref(), &design_path, dp, profile.v_max_m_s(), &nominal.summary, nominal.edge_length_mm);

    let run_rows: Vec<Value> = runs
        .iter()
        .map(|r| {
            json!({
                "stage": r.stage, "mesh": r.level, "edge_length_mm": r.edge_length_mm,
                "cardiac_index_l_min_m2": r.cardiac_index_l_min_m2,
                "tetrahedra": r.quality.tetrahedra, "mode": r.summary.mode, "converged": r.summary.converged,
                "dp_peak_mmhg": r.summary.dp_peak_mmhg, "max_velocity_m_s": r.summary.max_velocity_m_s,
                "verdict": r.verdict().key(), "reason": r.verdict().reason(),
            })
        })
        .collect();
    let created_utc = utc_now();
    let mut report = json!({
        "status": "completed",
        "created_utc": created_utc,
        "patient": patient_label(args, paper.as_ref()),
        "software": { "name": "baffle", "version": env!("CARGO_PKG_VERSION") },
        "inputs": {
            "surface": args.design.surface, "points": args.design.points, "phantom": args.design.phantom,
            "segmentations": args.prepare.segmentations, "labelmap": args.prepare.labelmap,
            "bsa_m2": flow_bsa_m2(args).ok(), "sbp_mmhg": args.bp.0, "dbp_mmhg": args.bp.1,
            "heart_rate_bpm": args.hr, "cardiac_index_l_min_m2": args.cardiac_index, "mode": nominal.summary.mode,
            "edge_length_mm": args.edge_length_mm,
        },
        "stages": records,
        "prepare": prepare,
        "domain": cfd_domain,
        "quantities": table.iter().map(|q| (q.key.to_string(), json_value(q))).collect::<serde_json::Map<_, _>>(),
        // Why the RV outflow quantities are null, and what they mean.
        "rv_outflow": { "unavailable": design.rv_cost.rv_outflow.rv_outflow_unavailable, "text": rv_outflow_text(&design.rv_cost.rv_outflow) },
        // passes is true only for a trusted run below the threshold, never for an inconclusive one.
        "verdict": {
            "verdict": verdict.key(), "reason": verdict.reason(), "passes": verdict == Verdict::Passes,
            "threshold_mmhg": DP_THRESHOLD_MMHG, "dp_peak_mmhg": dp, "converged": converged, "text": verdict_line,
            "warnings": warnings,
        },
        "hemodynamics_estimate": &estimate,
        "runs": run_rows,
        "mesh_study": study.as_ref().map(mesh_study_json),
        "paper": paper.as_ref().map(|p| json!({
            "patient": p.id, "table": p.table,
            "note": "the paper's published values of this patient (pulsatile run, nominal 0.95 mm mesh)",
            "quantities": p.values.iter().map(|(k, v)| (k.to_string(), json!(v))).collect::<serde_json::Map<_, _>>(),
        })),
        "centerline": {
            "kind": "flow-domain", "file": layout.flow_centerline(), "length_mm": flow_line.length_mm,
            "pressure_reference": "mean pressure over the aortic-annulus plane at peak flow",
            "reference_pressure_solver_mmhg": reference_mmhg,
            "s_mm": flow_line.s_mm, GAUGE_PRESSURE: gauge, "speed_m_s": profile.speed_m_s,
            "sampled_points": profile.pressure_mmhg.iter().flatten().count(),
            "centerline_drop_mmhg": comparison.centerline_drop_mmhg, "plane_averaged_dp_mmhg": dp,
            "min_rel_aortic_plane_mmhg": comparison.min_gauge_mmhg, "min_at_s_mm": comparison.min_at_s_mm,
        },
        "dp_over_cycle": { "time_in_cycle_s": dp_cycle.iter().map(|p| p.0).collect::<Vec<_>>(), "dp_mmhg": dp_cycle.iter().map(|p| p.1).collect::<Vec<_>>() },
    });
    write_json(&layout.report_json(), &report)?;
    // The renderer reads report.json and the stages' files (centerline.vtp with its fields).
    let d = &args.design;
    let ras = matches!(d.surface_frame, crate::design_cmd::Frame::Ras);
    let labels = [
        ("wall", d.labels.wall),
        ("baffle", d.labels.baffle),
        ("vsd", d.labels.vsd_cap),
        ("aortic", d.labels.aortic_cap),
        ("inflow", baffle_prepare::extend::INFLOW_CAP_LABEL),
        ("outflow", baffle_prepare::extend::OUTFLOW_CAP_LABEL),
    ];
    let rendered = pictures::render(out, ras, &labels);
    report["pictures"] = match &rendered {
        pictures::Pictures::Rendered { pictures, notes } => json!({
            "rendered": true, "renderer": "VTK (python/baffle/render.py)",
            "files": pictures.iter().map(|p| &p.file).collect::<Vec<_>>(), "notes": notes,
        }),
        pictures::Pictures::NotRendered(reason) => json!({ "rendered": false, "reason": reason }),
    };
    write_json(&layout.report_json(), &report)?;

    let mut html = Html(String::new());
    let _ = write!(html.0, "<!DOCTYPE html>\n<html xmlns=\"http://www.w3.org/1999/xhtml\"><head><meta charset=\"utf-8\"/><title>Baffle plan</title><style>{STYLE}</style></head><body>\n<h1>Baffle plan</h1>\n");
    let _ = writeln!(html.0, "<p><b>Patient: {}</b></p>", escape(&patient_label(args, paper.as_ref())));
    html.para(&format!("Made {created_utc} by baffle {} (baffle plan).", env!("CARGO_PKG_VERSION")));
    html.para(&format!(
        "{}; BSA {} m²; BP {}/{} mmHg; {}; cardiac index {} L/min/m²; {} run, nominal mesh {} mm.",
        surface_source(args),
        flow_bsa_m2(args)?,
        args.bp.0,
        args.bp.1,
        args.hr.map_or("default period 0.682 s".into(), |hr| format!("HR {hr} /min")),
        args.cardiac_index,
        nominal.summary.mode,
        args.edge_length_mm
    ));
    let _ = writeln!(html.0, "<p class=\"{}\"><b>{}</b></p>", verdict.key(), escape(&verdict_line));
    for warning in &warnings {
        let _ = writeln!(html.0, "<p class=\"warning\">Warning: {}</p>", escape(warning));
    }
    html.para(&domain_text(&cfd_domain));
    match &rendered {
        pictures::Pictures::Rendered { pictures, notes } => {
            html.heading("Baffle and pathway");
            html.pictures(pictures, "anatomy");
            for note in notes {
                html.para(&format!("Note: {note}."));
            }
            html.para(&format!(
                "Views named from the input's frame ({}); the letters at the edges give the patient's directions (R/L, A/P, S/I), the bar at the bottom left the scale. The pictures are also in pictures/ beside this report, at full size.",
                if ras { "RAS, --surface-frame ras" } else { "LPS, as Slicer writes models" }
            ));
            html.heading("Flow at peak");
            html.pictures(pictures, "flow");
        }
        pictures::Pictures::NotRendered(reason) => {
            html.heading("Pictures");
            let _ = writeln!(html.0, "<p class=\"warning\">The 3D pictures could not be rendered: {}.</p>", escape(reason));
        }
    }

    html.heading("The paper's quantities");
    let mut rows: Vec<Vec<String>> = table.iter().map(|q| vec![q.label.to_string(), format_value(q.value, q.decimals), q.unit.to_string()]).collect();
    match &paper {
        Some(p) => {
            for (row, q) in rows.iter_mut().zip(&table) {
                row.push(format_value(p.value(q.key).unwrap_or(f64::NAN), q.decimals));
            }
            let header = format!("Paper ({})", p.id);
            html.table(&["Quantity", "Value", "Unit", &header], &rows);
            html.para(&format!(
                "Paper: patient {} as printed in Martinez et al. (from {}), from its pulsatile run on the nominal 0.95 mm mesh; this plan ran {} on a {} mm mesh.",
                p.id,
                p.table.display(),
                nominal.summary.mode,
                args.edge_length_mm
            ));
        }
        None => html.table(&["Quantity", "Value", "Unit"], &rows),
    }

    html.para(&estimate.text());
    html.para(&rv_outflow_text(&design.rv_cost.rv_outflow));

    if let Some(prepare) = &prepare {
        html.heading("Capped ventricle (prepare stage)");
        html.table(&["Cap", "ModelFaceID", "Area (mm²)", "Centroid (mm)"], &prepare_rows(prepare));
        html.para(&format!("Built from the segmentations in {} s.", format_value(prepare.wall_time_s.unwrap_or(f64::NAN), 1)));
        html.para(&separation_text(&prepare.separation));
    }
    html.heading("Section area");
    html.figure(&section_area_chart(&design), "Designed section areas against the target (the design's report.json).");

    html.heading("Inflow");
    let colors = ["#1f77b4", "#ff7f0e"];
    let mut inflow: Vec<Series> = Vec::new();
    for (k, run) in runs.iter().filter(|r| r.level == "nominal").enumerate() {
        inflow.push(waveform_series(run, colors[k % 2])?);
    }
    if let (true, Some(q_peak)) = (dp_cycle.is_empty(), nominal.summary.q_peak_ml_s) {
        let period = inflow[0].points.last().map_or(1.0, |p| p.0);
        inflow.push(Series { dashed: true, ..Series::line("held in the steady run", vec![(0.0, q_peak), (period, q_peak)], "#555555") });
    }
    let inflow_title = if cfd_domain.extended { "Inflow waveform (mid-LV cap)" } else { "Inflow waveform (VSD cap)" };
    html.figure(&line_chart(inflow_title, "time in cycle (s)", "flow (mL/s)", &inflow, true), "Built-in ejection waveform scaled to BSA × cardiac index; a steady run holds Q_peak.");

    html.heading("Pressure difference");
    if dp_cycle.is_empty() {
        html.para(&format!("Steady run at Q_peak: dp = {dp:.3} mmHg (VSD cap − aortic cap)."));
    } else {
        let series = [Series::line("dp", dp_cycle.clone(), "#1f77b4"), Series { dashed: true, ..Series::line("10 mmHg", vec![(0.0, DP_THRESHOLD_MMHG), (dp_cycle.last().map_or(1.0, |p| p.0), DP_THRESHOLD_MMHG)], "#d62728") }];
        // A quick run is judged at its first flow peak: there is no last cycle.
        let (title, caption) = if nominal.summary.is_quick() {
            ("Pressure difference from rest to the first flow peak", "VSD cap − aortic cap mean pressure; the quick estimate starts from rest and stops at the first flow peak.")
        } else {
            ("Pressure difference over the last cycle", "VSD cap − aortic cap mean pressure.")
        };
        html.figure(&line_chart(title, "time in cycle (s)", "dp (mmHg)", &series, true), caption);
    }
    let end = flow_line.s_mm.last().copied().unwrap_or(1.0);
    let series = [
        Series::line("centerline pressure", profile_series(&flow_line.s_mm, &gauge), "#1f77b4"),
        Series { dashed: true, ..Series::line("plane-averaged dp", vec![(0.0, dp), (end, dp)], "#2ca02c") },
    ];
    html.figure(
        &line_chart("Pressure along the flow-domain centerline (peak flow)", "arc length from the VSD plane s (mm)", "p − aortic-plane mean (mmHg)", &series, false),
        &format!(
            "Sampled from peak.vtu at {} of {} points of the flow-domain centerline (medial line between the VSD and aortic planes, 0.5 mm spacing); dashed: the level of the plane-averaged dp the verdict uses (the VSD-plane mean; the aortic-plane mean is 0).",
            profile.pressure_mmhg.iter().flatten().count(),
            flow_line.s_mm.len()
        ),
    );
    html.para(&comparison.text(dp, reference_mmhg));

    html.heading("Solver convergence");
    match convergence_chart(nominal, &timeseries) {
        Some((svg, caption)) => html.figure(&svg, &caption),
        None => html.para("No residual history in the run's files."),
    }

    html.heading("Runs");
    let rows: Vec<Vec<String>> = runs
        .iter()
        .map(|r| {
            vec![
                r.stage.clone(),
                format!("{} ({:.2} mm)", r.level, r.edge_length_mm),
                format!("{:.2}", r.cardiac_index_l_min_m2),
                r.quality.tetrahedra.to_string(),
                format_value(r.dp_mmhg().unwrap_or(f64::NAN), 3),
                format_value(r.v_max_m_s().unwrap_or(f64::NAN), 3),
                r.verdict().text(r.dp_mmhg().unwrap_or(f64::NAN)),
            ]
        })
        .collect();
    html.table(&["Run", "Mesh", "Cardiac index (L/min/m²)", "Tetrahedra", "dp (mmHg)", "v_max (m/s)", "10 mmHg verdict"], &rows);
    match &study {
        Some(Ok(s)) => html.para(&format!("Mesh study (boundary and volume refined together; Celik et al. 2008): {}.", s.text())),
        Some(Err(e)) => html.para(&format!("Mesh study: no uncertainty estimate ({e}).")),
        None => {}
    }
    html.heading("Stages");
    let rows: Vec<Vec<String>> = records.iter().map(|r| vec![r.name.clone(), r.status.to_string(), format_value(r.wall_time_s.unwrap_or(f64::NAN), 1)]).collect();
    html.table(&["Stage (subfolder)", "Status", "Wall time (s)"], &rows);
    html.0.push_str("</body></html>\n");
    write_atomic(&layout.report_html(), html.0.as_bytes())?;
    let pictures_missing = match rendered {
        pictures::Pictures::NotRendered(reason) => Some(reason),
        pictures::Pictures::Rendered { .. } => None,
    };
    let v_max_m_s = nominal.v_max_m_s()?;
    Ok(Outcome { warnings, pictures_missing, verdict_line, verdict, dp_mmhg: dp, v_max_m_s })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_prepare_separation_names_any_move() {
        let kept = CutSeparation { rim_gap_mm: 5.49, clearance_mm: 0.5, interface_loops_gap_mm: 5.2, vsd_cut_moved_into_lv_mm: 0.0, aortic_cut_moved_into_aorta_mm: 0.0, cuts_tried: 1 };
        assert_eq!(separation_text(&kept), "The VSD and aortic openings are 5.49 mm apart (at least 0.50 mm).");
        let moved = CutSeparation { rim_gap_mm: 0.66, interface_loops_gap_mm: 0.01, vsd_cut_moved_into_lv_mm: 2.0, aortic_cut_moved_into_aorta_mm: 4.0, ..kept };
        let text = separation_text(&moved);
        assert!(text.contains("0.66 mm apart") && text.contains("moved 2.00 mm into the LV") && text.contains("4.00 mm up the aortic root"), "{text}");
    }

    /// The estimate of a straight 60 mm2 tunnel between 90 and 120 mm2 planes at 70 ml/s.
    fn straight_tunnel_estimate() -> baffle_core::analyses::hemodynamics_estimate::HemodynamicsEstimate {
        let tunnel = baffle_core::analyses::hemodynamics_estimate::TunnelSections { s_mm: vec![0.0, 10.0], area_mm2: vec![Some(60.0), Some(60.0)], aspect_ratio: vec![Some(1.0), Some(1.0)], vsd_area_mm2: 90.0, aortic_area_mm2: 120.0 };
        baffle_core::analyses::hemodynamics_estimate::estimate(&tunnel, 70.0, Default::default()).unwrap()
    }

    #[test]
    fn the_designs_estimate_is_read_typed_and_set_beside_the_3d_run() {
        let path = Path::new("design/report.json");
        let e = straight_tunnel_estimate();
        let estimated = EstimateOutcome::Estimated(e.clone());
        let design = Some(&estimated);
        let quick = crate::run_summary::completed_run(crate::case::QUICK_MODE);
        // The 3D dp equal to the estimate: within its measured error.
        let near = EstimateBeside3d::of(design, path, e.dp_estimate_mmhg, e.v_max_estimate_m_s, &quick, 0.6);
        assert_eq!(near.design, EstimateOutcome::Estimated(e.clone()));
        let c = near.comparison_with_3d.as_ref().unwrap();
        assert!(c.dp_within_measured_error && c.v_max_within_measured_error && c.dp_3d_mmhg == e.dp_estimate_mmhg);
        assert!(near.text().starts_with("Reduced-order estimate (not a CFD result):") && !near.text().contains("disagree"), "{}", near.text());
        // 3D dp 20 mmHg above the estimate: beyond the range, and the text says so.
        let far = EstimateBeside3d::of(design, path, e.dp_estimate_mmhg + 20.0, e.v_max_estimate_m_s, &quick, 0.6);
        assert!(far.text().contains("disagree on dp beyond") && far.text().contains("verdict uses"), "{}", far.text());
        let report = serde_json::to_value(&far).unwrap();
        assert_eq!(report["comparison_with_3d"]["dp_within_measured_error"], false);
        assert_eq!(report["design"]["dp_estimate_mmhg"].as_f64(), Some(e.dp_estimate_mmhg));
        // No 3D v_max sampled: the estimate stands, the comparison says why not.
        let unsampled = EstimateBeside3d::of(design, path, 1.0, f64::NAN, &quick, 0.6);
        assert!(unsampled.comparison_with_3d.is_none() && unsampled.text().contains("not compared with the 3D run (hemodynamics estimate comparison: the 3D v_max"), "{}", unsampled.text());
        // Without an estimate: why, in one line.
        let absent = EstimateOutcome::Absent { absent_because: "no peak flow given".into() };
        assert_eq!(EstimateBeside3d::of(Some(&absent), path, 1.0, 1.0, &quick, 0.6).text(), "No reduced-order estimate of dp: no peak flow given.");
        assert!(EstimateBeside3d::of(None, path, 1.0, 1.0, &quick, 0.6).text().contains("design/report.json has no hemodynamics_estimate"));
    }

    #[test]
    fn the_estimate_says_which_3d_run_it_is_set_beside_and_skips_a_doubtful_one() {
        let path = Path::new("design/report.json");
        let e = straight_tunnel_estimate();
        let estimated = EstimateOutcome::Estimated(e.clone());
        let beside = |run: &RunSummary| EstimateBeside3d::of(Some(&estimated), path, e.dp_estimate_mmhg, e.v_max_estimate_m_s, run, 0.85);
        let quick = beside(&crate::run_summary::completed_run(crate::case::QUICK_MODE));
        assert!(quick.text().contains("first flow peak of the nominal 0.85 mm mesh") && !quick.text().contains("fourth cycle"), "{}", quick.text());
        // Four settled cycles: compared, with what is known of the last peak against the first.
        let cycles = RunSummary { periodicity_nrmsd: Some(1e-5), ..crate::run_summary::completed_run("transient") };
        let four = beside(&cycles);
        assert!(four.comparison_with_3d.is_some() && four.text().contains("last cycle's flow peak") && four.text().contains("within 0.031 mmHg"), "{}", four.text());
        // A steady solve stopped at its cap is no reference: no comparison, and why.
        let stalled = beside(&RunSummary { converged: false, ..crate::run_summary::completed_run("steady") });
        assert!(stalled.comparison_with_3d.is_none(), "an unconverged 3D run must not be compared");
        assert!(stalled.text().contains("not compared with the 3D run (the 3D run is no reference: the steady solve did not reach its residual target"), "{}", stalled.text());
    }

    /// A design's report.json as the design stage writes it (the phantom's), as JSON.
    fn design_report_json() -> Value {
        let p = baffle_core::phantom::phantom_default();
        let target = baffle_core::TargetArea::AreaMm2(60.0);
        let result = baffle_core::design(&p.surface, &p.suture_points_mm, &target, &Default::default(), &mut |_, _| true).unwrap();
        serde_json::to_value(&result.report).unwrap()
    }

    #[test]
    fn a_stage_file_is_read_as_the_type_that_wrote_it_and_refused_without_a_field() {
        let dir = std::env::temp_dir().join(format!("baffle-report-typed-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("report.json");
        let write = |doc: &Value| std::fs::write(&path, serde_json::to_string_pretty(doc).unwrap()).unwrap();
        let mut doc = design_report_json();
        write(&doc);
        let design: DesignReport = read_json(&path).unwrap();
        assert_eq!(serde_json::to_value(&design).unwrap(), doc, "the design report reads back as written");
        // A field the report prints, gone (as after a rename): refused, naming the file and the field.
        doc.as_object_mut().unwrap().remove("baffle_area_mm2");
        write(&doc);
        let e = read_json::<DesignReport>(&path).unwrap_err();
        assert!(e.contains(&path.display().to_string()) && e.contains("missing field `baffle_area_mm2`"), "{e}");
        // A figure of the wrong kind: refused too, not a blank figure.
        let mut doc = design_report_json();
        doc["hemodynamics_estimate"] = json!(3);
        write(&doc);
        let e = read_json::<DesignReport>(&path).unwrap_err();
        assert!(e.starts_with(&path.display().to_string()), "{e}");
        // A run's summary.json: a null figure is none, a missing one is refused the same way.
        let mut summary = json!({
            "status": "completed", "message": null, "mode": "quick", "converged": true, "unconverged_nonlinear_steps": 0,
            "last_step": 109, "steps_planned": 109, "peak_time_s": 0.109, "dp_peak_mmhg": null, "max_velocity_m_s": 1.5,
            "q_peak_ml_s": 36.0, "mass_imbalance": 1e-5, "periodicity_nrmsd": null,
            "inputs": { "q_mean_ml_s": 12.0, "period_s": 0.682, "steady_tolerance": null },
        });
        write(&summary);
        assert_eq!(read_json::<RunSummary>(&path).unwrap().dp_peak_mmhg, None);
        summary.as_object_mut().unwrap().remove("dp_peak_mmhg");
        write(&summary);
        let e = read_json::<RunSummary>(&path).unwrap_err();
        assert!(e.contains(&path.display().to_string()) && e.contains("missing field `dp_peak_mmhg`"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_designed_domain_is_its_two_fields_in_report_json() {
        let designed = CfdDomain { extended: false, note: "n", extension: None };
        assert_eq!(serde_json::to_value(&designed).unwrap(), json!({ "extended": false, "note": "n" }));
        assert_eq!(domain_text(&designed), "CFD domain: n.");
    }

    #[test]
    fn dates_are_utc_calendar_dates() {
        assert_eq!(utc_date_time(0), "1970-01-01 00:00 UTC");
        assert_eq!(utc_date_time(1_700_000_000), "2023-11-14 22:13 UTC");
        assert_eq!(utc_date_time(951_782_400), "2000-02-29 00:00 UTC");
    }

    #[test]
    fn the_centerline_drop_and_its_lowest_point_are_taken_from_sampled_points() {
        let s = [0.0, 0.5, 1.0, 1.5, 2.0];
        let gauge = [None, Some(3.0), Some(-0.4), Some(0.1), Some(0.0)];
        let c = PressureComparison::of(&s, &gauge);
        assert_eq!((c.centerline_drop_mmhg, c.min_gauge_mmhg, c.min_at_s_mm), (3.0, -0.4, 1.0));
        let text = c.text(1.72, 288.0);
        assert!(text.contains("falls by 3.00 mmHg") && text.contains("+1.28 mmHg") && text.contains("plane-averaged"), "{text}");
    }
}
