//! `baffle plan`'s settings and its stages: which run, in what order, and where each
//! writes ([`PlanLayout`]: the paths `plan_cmd` writes to and `report` reads from). Checked before any
//! stage runs.

use crate::design_cmd::{target_from, DesignSettings};
use crate::error::PlanError;
use crate::prepare_cmd::PrepareSource;
use baffle_cfd::hemodynamics::{hemodynamics, ClinicalInputs, CARDIAC_INDEX_DEFAULT_L_MIN_M2, CARDIAC_INDEX_ELEVATED_L_MIN_M2};
use std::path::{Path, PathBuf};

documented_settings! {
pub struct PlanSettings {
    pub design: DesignSettings,
    /// Build the capped ventricle from segmentations or a label map first (a `prepare`
    /// stage), instead of --surface; the CFD then runs on the extended domain (an
    /// `extend` stage after the design: mid-LV inflow cap 20, STJ outflow cap 21, dp
    /// between the VSD and aortic caps as interior planes).
    pub prepare: PrepareSource,
    /// Blood pressure SBP/DBP (mmHg), e.g. 107/78: the outlet resistance R = MAP / Q_mean.
    pub bp: (f64, f64),
    /// Heart rate (beats/min); default: the built-in period of 0.682 s.
    pub hr: Option<f64>,
    /// Steady run with the inflow held at Q_peak. It may not converge where the peak flow
    /// is not steady (p2's and p3's extended domains); the verdict is then INCONCLUSIVE.
    pub steady: bool,
    /// Quick estimate: a pulsatile run from rest up to the first flow peak (a twentieth of
    /// 4 cycles' steps; on p2 and p3 within 0.6 % of the fourth cycle's peak dp).
    pub quick: bool,
    /// Pulsatile run over --cycles cardiac cycles (the default, as the paper).
    pub pulsatile: bool,
    /// Cardiac cycles of a pulsatile run (the last one is reported).
    pub cycles: usize,
    /// Largest tetrahedron edge of the nominal mesh (mm); the paper used 0.95.
    pub edge_length_mm: f64,
    /// On an extended domain, coarsen the LV and aortic parts away from the VSD and
    /// aortic caps up to this many times each level's edge (within one cap diameter of
    /// the caps the edge stays); 1: the whole domain at the edge.
    pub extension_coarsening: f64,
    /// The default: also mesh and simulate at the paper's coarse and fine sizes (1.25 /
    /// 0.75 mm, scaled by --edge-length-mm / 0.95), the boundary refined with the volume
    /// (on an extended domain every level is extended again from the designed domain
    /// remeshed at its size); the report gives dp's grid convergence index and judges the
    /// verdict with its band. No single edge length converges dp on every patient (the
    /// dataset's p3 needs about 0.45 mm for 5 %: docs/validation.md).
    pub mesh_study: bool,
    /// The nominal mesh only (about a third of the study's time): the report then cannot
    /// say whether dp is mesh-converged, and warns so.
    pub single_mesh: bool,
    /// Also simulate the nominal mesh at cardiac index 4.22 L/min/m2.
    pub elevated_flow: bool,
    /// Cardiac index of the nominal runs (L/min/m2): the mean flow is BSA x cardiac index.
    pub cardiac_index: f64,
    /// Target edge of the prepare stage's final isotropic remesh (mm; `baffle prepare
    /// --remesh-edge-mm`, default 0.5). The design remeshes the kept wall at --remesh-edge-mm.
    pub prepare_remesh_edge_mm: Option<f64>,
    /// How the report names the patient (default: the paper's patient id when the input
    /// lies in one of its patients' folders).
    pub patient_label: Option<String>,
}
}

/// Cardiac cycles of a pulsatile run by default.
pub const CYCLES: usize = 4;

/// The paper's settings; no blood pressure (NaN: a plan needs the patient's) and no
/// output folder.
impl Default for PlanSettings {
    fn default() -> Self {
        PlanSettings {
            design: DesignSettings::default(),
            prepare: PrepareSource::default(),
            bp: (f64::NAN, f64::NAN),
            hr: None,
            steady: false,
            quick: false,
            pulsatile: false,
            cycles: CYCLES,
            edge_length_mm: PAPER_NOMINAL_MM,
            extension_coarsening: 1.0,
            mesh_study: false,
            single_mesh: false,
            elevated_flow: false,
            cardiac_index: CARDIAC_INDEX_DEFAULT_L_MIN_M2,
            prepare_remesh_edge_mm: None,
            patient_label: None,
        }
    }
}

impl PlanSettings {
    /// Whether the plan runs the three-level mesh study (unless --single-mesh).
    pub fn runs_mesh_study(&self) -> bool {
        !self.single_mesh
    }
}


/// The nominal mesh size and the paper's mesh-study sizes (mm) at 0.95 mm nominal.
const PAPER_NOMINAL_MM: f64 = 0.95;
pub const PAPER_COARSE_MM: f64 = 1.25;
const PAPER_FINE_MM: f64 = 0.75;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FlowCase {
    Nominal,
    Elevated,
}

impl FlowCase {
    /// The run's cardiac index: the plan's --cardiac-index, or the paper's elevated one.
    pub fn cardiac_index_l_min_m2(self, args: &PlanSettings) -> f64 {
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
    /// The designed domain -> the extended CFD domain (`baffle extend`); a mesh study's
    /// level remeshes the designed domain at its size first (`--remesh-domain-edge-mm`).
    Extend { level: Option<&'static str>, remesh_domain_edge_mm: Option<f64> },
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

impl Stage {
    /// The mesh-study level (coarse or fine) this stage belongs to: a level that fails
    /// leaves the plan's nominal result standing (the study then says why it has no band).
    pub fn study_level(&self) -> Option<&'static str> {
        let level = match self.step {
            Step::Extend { level, .. } => level?,
            Step::Mesh { level, .. } | Step::Simulate { level, .. } => level,
            _ => return None,
        };
        (level != "nominal").then_some(level)
    }
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
fn mesh_levels(args: &PlanSettings) -> Vec<(&'static str, f64)> {
    let nominal = args.edge_length_mm;
    let mut levels = vec![("nominal", nominal)];
    if args.runs_mesh_study() {
        let scale = nominal / PAPER_NOMINAL_MM;
        levels.push(("coarse", PAPER_COARSE_MM * scale));
        levels.push(("fine", PAPER_FINE_MM * scale));
    }
    levels
}

/// The source of the capped ventricle: exactly one of --surface, --segmentations,
/// --labelmap and --phantom.
fn check_one_surface_source(args: &PlanSettings) -> Result<(), String> {
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

/// Every path of a plan folder: each stage's subfolder and the files the stages write
/// there and the report reads back, so the folder's layout is said in one place.
#[derive(Clone, Debug)]
pub struct PlanLayout {
    root: PathBuf,
    /// Whether each mesh-study level extends the designed domain at its own size.
    level_extensions: bool,
}

impl PlanLayout {
    /// The folder `root`; `level_extensions` when each mesh-study level has its own
    /// extend stage (an extended domain's mesh study).
    pub fn new(root: &Path, level_extensions: bool) -> PlanLayout {
        PlanLayout { root: root.to_path_buf(), level_extensions }
    }

    /// The layout of the plan `args` (its --out).
    pub fn of(args: &PlanSettings) -> PlanLayout {
        PlanLayout::new(&args.design.out, args.runs_mesh_study())
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    /// A stage's subfolder, named after the stage.
    pub fn stage_dir(&self, stage: &str) -> PathBuf {
        self.root.join(stage)
    }

    /// The capped ventricle a prepare stage writes.
    pub fn prepared_surface(&self) -> PathBuf {
        self.stage_dir("prepare").join("capped_ventricle.vtp")
    }

    /// The design stage's folder (domain.vtp, report.json and the rest of `baffle design`'s files).
    pub fn design_dir(&self) -> PathBuf {
        self.stage_dir("design")
    }

    /// The designed domain.
    pub fn designed_domain(&self) -> PathBuf {
        self.design_dir().join("domain.vtp")
    }

    /// The extended domain the extend stage writes.
    pub fn extended_surface(&self) -> PathBuf {
        self.stage_dir("extend").join("extended.vtp")
    }

    /// The extended domain a mesh level is meshed from: a mesh study's own extension of
    /// the level, else the one extend stage's.
    pub fn level_extended_surface(&self, level: &str) -> PathBuf {
        match self.level_extensions {
            true => self.stage_dir(&format!("extend-{level}")).join("extended.vtp"),
            false => self.extended_surface(),
        }
    }

    /// The flow-domain centerline a centerline stage writes (its figures in the .json beside it).
    pub fn flow_centerline(&self) -> PathBuf {
        self.stage_dir("centerline").join("centerline.vtp")
    }

    /// A mesh level's volume mesh (its faces and quality files beside it).
    pub fn mesh(&self, level: &str) -> PathBuf {
        self.stage_dir(&format!("mesh-{level}")).join("mesh.vtu")
    }

    pub fn report_json(&self) -> PathBuf {
        self.root.join("report.json")
    }

    pub fn report_html(&self) -> PathBuf {
        self.root.join("report.html")
    }
}

/// Whether the CFD runs on the extended domain: the LV and aorta are known (a prepare stage).
pub fn is_extended(args: &PlanSettings) -> bool {
    args.prepare.is_given()
}

/// Everything the stages need that can be checked before any of them runs, so a
/// missing argument is named at once rather than after minutes of work.
fn check_arguments(args: &PlanSettings) -> Result<(), String> {
    check_one_surface_source(args)?;
    if args.design.points.is_none() && !args.design.phantom {
        return Err("baffle plan needs the suture points: give --points FILE (.mrk.json, .fcsv, .csv or .json), or use --phantom".into());
    }
    // The flow is BSA x cardiac index, and the design needs its target.
    flow_bsa_m2(args)?;
    let default_bsa = args.design.phantom.then(|| baffle_core::phantom::phantom_default().bsa_m2);
    // A target area that cannot be computed (a negative diameter) is named now too, in the
    // design's own words.
    target_from(&args.design.target, default_bsa)?.area_mm2().map_err(|e| baffle_core::DesignError::Target(e).to_string())?;
    if let Some(hr) = args.hr {
        crate::case::heart_rate_bpm("--hr (heart rate)", hr)?;
    }
    if !(args.cardiac_index.is_finite() && args.cardiac_index > 0.0) {
        return Err(format!("--cardiac-index must be a positive number of L/min/m2, got {}", args.cardiac_index));
    }
    // The outlet's resistance comes from the blood pressure: a bad one is named now, not
    // after the design and the mesh.
    let (sbp_mmhg, dbp_mmhg) = args.bp;
    let clinical = ClinicalInputs { bsa_m2: flow_bsa_m2(args)?, sbp_mmhg, dbp_mmhg, cardiac_index_l_min_m2: args.cardiac_index };
    hemodynamics(&clinical).map_err(|e| format!("--bp {sbp_mmhg}/{dbp_mmhg} (SBP/DBP, mmHg): {e}"))?;
    if !(args.edge_length_mm.is_finite() && args.edge_length_mm > 0.0) {
        return Err(format!("--edge-length-mm must be a positive length, got {}", args.edge_length_mm));
    }
    if !(args.extension_coarsening.is_finite() && args.extension_coarsening >= 1.0) {
        return Err(format!("--extension-coarsening must be at least 1 (times the edge), got {}", args.extension_coarsening));
    }
    if args.prepare_remesh_edge_mm.is_some() && !args.prepare.is_given() {
        return Err("--prepare-remesh-edge-mm applies to a prepare stage: give --segmentations or --labelmap".into());
    }
    Ok(())
}

pub fn plan_stages(args: &PlanSettings) -> Result<Vec<Stage>, PlanError> {
    check_arguments(args).map_err(PlanError::Plan)?;
    let simulate_weight = if args.steady || args.quick { 4.0 } else { 4.0 * args.cycles as f64 };
    let mut stages = Vec::new();
    if args.prepare.is_given() {
        stages.push(Stage { name: "prepare".into(), step: Step::Prepare, weight: 1.0 });
    }
    stages.push(Stage { name: "design".into(), step: Step::Design, weight: 1.0 });
    if is_extended(args) {
        stages.push(Stage { name: "extend".into(), step: Step::Extend { level: None, remesh_domain_edge_mm: None }, weight: 1.0 });
    }
    stages.push(Stage { name: "centerline".into(), step: Step::Centerline, weight: 0.5 });
    for (level, edge_length_mm) in mesh_levels(args) {
        if is_extended(args) && args.runs_mesh_study() {
            let step = Step::Extend { level: Some(level), remesh_domain_edge_mm: Some(edge_length_mm) };
            stages.push(Stage { name: format!("extend-{level}"), step, weight: 1.0 });
        }
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
pub fn flow_bsa_m2(args: &PlanSettings) -> Result<f64, String> {
    match (args.design.target.bsa, args.design.phantom) {
        (Some(bsa), _) => Ok(bsa),
        (None, true) => Ok(baffle_core::phantom::phantom_default().bsa_m2),
        (None, false) => Err("baffle plan needs --bsa: the flow is BSA x cardiac index".into()),
    }
}


#[cfg(test)]
mod tests {
    use super::*;

    /// A plan of the suture points p.mrk.json, BSA 0.37 and 107/78 into `o`, with `edit` applied.
    fn plan(edit: impl FnOnce(&mut PlanSettings)) -> PlanSettings {
        let mut args = PlanSettings { bp: (107.0, 78.0), ..PlanSettings::default() };
        args.design.points = Some("p.mrk.json".into());
        args.design.target.bsa = Some(0.37);
        args.design.out = "o".into();
        edit(&mut args);
        args
    }

    fn stage_names(edit: impl FnOnce(&mut PlanSettings)) -> Vec<String> {
        plan_stages(&plan(edit)).unwrap().into_iter().map(|s| s.name).collect()
    }

    fn segmentations(a: &mut PlanSettings) {
        a.prepare.segmentations = Some("seg".into());
    }

    #[test]
    fn a_blood_pressure_the_outlet_cannot_use_is_named_before_any_stage() {
        let error = |bp| plan_stages(&plan(|a| (a.design.surface = Some("capped.vtp".into()), a.bp = bp).1)).unwrap_err().to_string();
        assert!(error((78.0, 107.0)).contains("DBP 107 mmHg exceeds SBP 78 mmHg"), "{}", error((78.0, 107.0)));
        assert!(error((f64::NAN, 78.0)).starts_with("--bp NaN/78"), "{}", error((f64::NAN, 78.0)));
    }

    #[test]
    fn a_given_area_or_diameter_is_the_target_beside_the_flows_bsa_and_two_targets_are_refused() {
        let surface = |a: &mut PlanSettings| a.design.surface = Some("capped.vtp".into());
        // --bsa stays the flow's: the area or the diameter alone is the target.
        assert!(plan_stages(&plan(|a| (surface(a), a.design.target.target_area_mm2 = Some(200.0)).1)).is_ok());
        assert!(plan_stages(&plan(|a| (surface(a), a.design.target.annulus_diameter_mm = Some(16.0)).1)).is_ok());
        assert!(plan_stages(&plan(|a| (surface(a), a.design.target.z_score = 1.5).1)).is_ok());
        let error = |edit: fn(&mut PlanSettings)| plan_stages(&plan(|a| (surface(a), edit(a)).1)).unwrap_err().to_string();
        let both = error(|a| (a.design.target.target_area_mm2, a.design.target.annulus_diameter_mm) = (Some(200.0), Some(16.0)));
        assert!(both.contains("give one target: --target-area-mm2 or --annulus-diameter-mm, not both"), "{both}");
        let z_and_area = error(|a| (a.design.target.target_area_mm2, a.design.target.z_score) = (Some(200.0), 1.0));
        assert!(z_and_area.contains("--z-score 1 applies to the BSA's annulus"), "{z_and_area}");
        let z_and_diameter = error(|a| (a.design.target.annulus_diameter_mm, a.design.target.z_score) = (Some(16.0), -1.0));
        assert!(z_and_diameter.contains("--z-score -1 applies"), "{z_and_diameter}");
    }

    #[test]
    fn segmentations_or_a_label_map_put_a_prepare_stage_first() {
        let rest = ["design", "centerline", "mesh-nominal", "simulate-nominal"];
        let extended = ["design", "extend", "centerline", "mesh-nominal", "simulate-nominal"];
        let single = |a: &mut PlanSettings| a.single_mesh = true;
        assert_eq!(stage_names(|a| (segmentations(a), single(a)).1), [&["prepare"][..], &extended].concat());
        let labelmap = |a: &mut PlanSettings| {
            (a.prepare.labelmap, a.prepare.aorta_label) = (Some("heart.nrrd".into()), 8);
            single(a)
        };
        assert_eq!(stage_names(labelmap), [&["prepare"][..], &extended].concat());
        assert_eq!(stage_names(|a| (a.design.surface = Some("capped.vtp".into()), single(a)).1), rest);
    }

    #[test]
    fn an_extended_mesh_study_extends_every_level_at_its_own_size() {
        // The study is the default; --mesh-study says so explicitly.
        assert_eq!(stage_names(segmentations), stage_names(|a| (segmentations(a), a.mesh_study = true).1));
        let names = stage_names(|a| (segmentations(a), a.edge_length_mm = 0.95).1);
        let levels = ["nominal", "coarse", "fine"].map(|l| [format!("extend-{l}"), format!("mesh-{l}"), format!("simulate-{l}")]).concat();
        assert_eq!(names, [&["prepare", "design", "extend", "centerline"].map(String::from)[..], &levels].concat());
        let args = plan(|a| (segmentations(a), a.mesh_study = true).1);
        let extends: Vec<Option<f64>> = plan_stages(&args)
            .unwrap()
            .into_iter()
            .filter_map(|s| match s.step {
                Step::Extend { remesh_domain_edge_mm, .. } => Some(remesh_domain_edge_mm),
                _ => None,
            })
            .collect();
        assert_eq!(extends, [None, Some(0.95), Some(1.25), Some(0.75)]);
        assert_eq!(PlanLayout::of(&args).level_extended_surface("fine"), PathBuf::from("o/extend-fine/extended.vtp"));
        let study: Vec<(String, Option<&str>)> = plan_stages(&args).unwrap().into_iter().map(|s| (s.name.clone(), s.study_level())).collect();
        assert!(study.iter().all(|(name, level)| level.is_some() == (name.ends_with("-coarse") || name.ends_with("-fine"))), "{study:?}");
        // From a surface the mesh stage remeshes the boundary itself: no extend stages.
        let names = stage_names(|a| a.design.surface = Some("capped.vtp".into()));
        assert!(!names.iter().any(|n| n.starts_with("extend")) && names.contains(&"mesh-fine".to_string()), "{names:?}");
    }

}
