//! The JSON case file of `baffle simulate`: mesh, face roles, fluid, inflow, outlet,
//! time stepping and output. Relative paths are relative to the case file.

use baffle_cfd::hemodynamics::{hemodynamics, mean_arterial_pressure_mmhg, ClinicalInputs, CARDIAC_INDEX_DEFAULT_L_MIN_M2, DYN_CM2_PER_MMHG};
use baffle_cfd::{
    CaseSettings, Face, FlowMesh, InflowProfile, NonlinearIterations, Outlet, RunMode, TimeIntegration, Waveform, AUTO_NONLINEAR_CAP, DEFAULT_RHO_INF,
};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A transient run resolves each cardiac cycle by at least this many steps: fewer cannot
/// place the flow peak, where dp is reported (the paper's runs take 500-700 a cycle; the
/// tests run cycles of 20).
pub const MIN_STEPS_PER_CYCLE: f64 = 10.0;

fn check_steps_per_cycle(s: &CaseSettings) -> Result<(), String> {
    let period_s = s.inflow.period_s();
    match matches!(s.mode, RunMode::Transient) && s.dt_s * MIN_STEPS_PER_CYCLE > period_s {
        true => Err(format!(
            "time.dt_s = {} s gives {:.1} steps in the {period_s} s cardiac cycle; at least {MIN_STEPS_PER_CYCLE} are needed (the paper used 1 ms)",
            s.dt_s,
            period_s / s.dt_s
        )),
        false => Ok(()),
    }
}


pub const EXAMPLE: &str = r#"{
  "mesh": { "volume": "mesh.vtu", "faces": "mesh-faces.vtp", "format": "baffle", "units": "mm" },
  "faces": { "inlet": 11, "outlets": [16], "walls": [2, 10], "planes": [] },
  "fluid": { "density_g_cm3": 1.06, "viscosity_g_cm_s": 0.04 },
  "inflow": { "bsa_m2": 0.37, "cardiac_index_l_min_m2": 3.48, "period_s": 0.682, "profile": "plug" },
  "outlet": { "sbp_mmhg": 107, "dbp_mmhg": 78 },
  "time": { "mode": "transient", "dt_s": 0.001, "cycles": 4 },
  "output": { "vtu_every_steps": 0, "checkpoint_every_steps": 50 }
}"#;

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Case {
    pub mesh: MeshSpec,
    pub faces: FaceRoles,
    #[serde(default)]
    pub fluid: Fluid,
    pub inflow: Inflow,
    pub outlet: OutletSpec,
    #[serde(default)]
    pub time: TimeSpec,
    #[serde(default)]
    pub output: OutputSpec,
}

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// Tetrahedral volume (.vtu).
    pub volume: PathBuf,
    /// Labelled faces (.vtp, cell ModelFaceID, point GlobalNodeID); default: `baffle
    /// mesh`'s `<stem>-faces.vtp` beside the volume.
    pub faces: Option<PathBuf>,
    /// "baffle" (GlobalNodeID = 1-based volume point index, as `baffle mesh` writes) or
    /// "simvascular" (GlobalNodeID matched to the volume's GlobalNodeID array).
    #[serde(default = "default_format")]
    pub format: String,
    /// Coordinate units of the files: "mm" (default for `baffle mesh`) or "cm" (SimVascular).
    pub units: Option<String>,
}

fn default_format() -> String {
    "baffle".into()
}

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FaceRoles {
    pub inlet: i32,
    pub outlets: Vec<i32>,
    /// No-slip walls (every boundary face that is not inlet or outlet is a wall; listed ones are checked to exist).
    #[serde(default)]
    pub walls: Vec<i32>,
    /// Interior measurement planes: dp = p(first) - p(second).
    #[serde(default)]
    pub planes: Vec<i32>,
}

/// The blood of the case (`fluid` in case.json): the design's estimate uses the same.
pub use baffle_core::analyses::hemodynamics_estimate::Blood as Fluid;

#[derive(Clone, Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Inflow {
    /// Mean flow (mL/s) given directly, or from BSA x cardiac index.
    pub q_mean_ml_s: Option<f64>,
    pub bsa_m2: Option<f64>,
    pub cardiac_index_l_min_m2: Option<f64>,
    /// Tabulated waveform file ("time flow" lines or .flx); scaled to the mean flow when one is given.
    pub waveform_file: Option<PathBuf>,
    /// Period of the built-in waveform (s), or from the heart rate; default 0.682 s.
    pub period_s: Option<f64>,
    pub heart_rate_bpm: Option<f64>,
    /// "plug" (default) or "poiseuille".
    pub profile: Option<String>,
}

#[derive(Clone, Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OutletSpec {
    /// Resistance (dyn s/cm^5) given directly, or R = MAP / Q_mean from SBP/DBP
    /// (MAP = (SBP + 2 DBP)/3 rounded, as the paper), or from a MAP.
    pub resistance_dyn_s_cm5: Option<f64>,
    pub sbp_mmhg: Option<f64>,
    pub dbp_mmhg: Option<f64>,
    pub map_mmhg: Option<f64>,
}

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct TimeSpec {
    /// "transient", "steady" (flow fixed at Q_peak) or "quick" (transient from rest up
    /// to the first flow peak: the quick estimate of the peak dp, see [`first_peak_step`]).
    pub mode: String,
    pub dt_s: f64,
    pub cycles: usize,
    /// Stop after this time step (default: cycles x period / dt).
    pub steps: Option<usize>,
    /// Picard iterations per step: a count (1: semi-implicit, one linear solve with the
    /// extrapolated convection velocity) or "auto" (until the velocity and the pressure
    /// change by less than `nonlinear_tolerance`, at most 6; a step at the cap is counted
    /// in summary.json's `unconverged_nonlinear_steps`). Default: 1 for backward Euler,
    /// "auto" for generalized-alpha.
    pub nonlinear_iterations: Option<IterationsSpec>,
    /// The auto loop's relative change of velocity and pressure (a fixed count's residual
    /// reduction) at which a step's Picard iterations stop (default 1e-3).
    pub nonlinear_tolerance: Option<f64>,
    pub linear_tolerance: Option<f64>,
    /// GMRES iterations per linear solve at most (default 600).
    pub max_linear_iterations: Option<usize>,
    /// Preconditioner of the linear solves: "ilu" (block ILU(0)) or "two-level" (ILU(0)
    /// and a coarse correction on node aggregates, `baffle_cfd::coarse`).
    pub preconditioner: Option<String>,
    /// Transient runs: solves one preconditioner factorization may serve (default 50,
    /// renewed earlier when GMRES slows down; 1: new factors every step, so that a
    /// resumed run continues bit for bit instead of to the linear tolerance).
    pub preconditioner_max_age: Option<usize>,
    /// Time integration of transient runs: "backward-euler" (default) or
    /// "generalized-alpha" (second order, as svMultiPhysics; `baffle_cfd::time_integration`).
    pub time_integration: Option<String>,
    /// Generalized-alpha's spectral radius at infinite time step, in [0, 1] (default 0.5,
    /// svMultiPhysics' `Spectral_radius_of_infinite_time_step`).
    pub rho_inf: Option<f64>,
    pub steady_tolerance: Option<f64>,
    pub steady_max_iterations: Option<usize>,
    /// The discrete method's ingredients, for comparing it with svMultiPhysics one at a
    /// time (docs/validation.md, issue 28): tau's metric "svmultiphysics" (default) or
    /// "invariant" (`baffle_cfd::assembly::TauMetric`), the Galerkin convection "exact"
    /// (default) or "centroid", VMS advection by a + u' (default true), the viscous term
    /// "laplacian" (default) or "stress", the stabilization's quadrature "gauss" (default:
    /// four points, as svMultiPhysics) or "centroid", svMultiPhysics' VMS Reynolds-stress
    /// term (default true). These switch the embedded engine only: an export to
    /// svMultiPhysics refuses a case that sets them away from its method.
    pub tau_metric: Option<String>,
    pub convection: Option<String>,
    pub vms_advection: Option<bool>,
    pub viscous_form: Option<String>,
    pub stabilization_quadrature: Option<String>,
    pub vms_reynolds_stress: Option<bool>,
    /// Whether tau holds the time step (default true, svMultiPhysics' 4 (C_t/dt)^2): the
    /// discrete problem then changes with dt at a fixed mesh; false keeps tau's flow and
    /// mesh scales only, so a dt study sees the time scheme's own error.
    pub tau_includes_dt: Option<bool>,
}

impl Default for TimeSpec {
    fn default() -> Self {
        TimeSpec {
            mode: "transient".into(),
            dt_s: 1e-3,
            cycles: 4,
            steps: None,
            nonlinear_iterations: None,
            nonlinear_tolerance: None,
            linear_tolerance: None,
            max_linear_iterations: None,
            preconditioner: None,
            preconditioner_max_age: None,
            time_integration: None,
            rho_inf: None,
            steady_tolerance: None,
            steady_max_iterations: None,
            tau_metric: None,
            convection: None,
            vms_advection: None,
            viscous_form: None,
            stabilization_quadrature: None,
            vms_reynolds_stress: None,
            tau_includes_dt: None,
        }
    }
}

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputSpec {
    /// Write fields_<step>.vtu every this many steps (0: only peak.vtu and final.vtu).
    pub vtu_every_steps: usize,
    /// Write checkpoint.json every this many steps (it is always written when stopping).
    pub checkpoint_every_steps: usize,
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec { vtu_every_steps: 0, checkpoint_every_steps: 50 }
    }
}

/// Derived flow conditions, reported in summary.json.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FlowInputs {
    pub q_mean_ml_s: f64,
    pub q_peak_ml_s: f64,
    pub peak_time_in_cycle_s: f64,
    pub period_s: f64,
    pub resistance_dyn_s_cm5: f64,
    pub map_mmhg: Option<f64>,
}

pub fn read_case(path: &Path) -> Result<Case, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut case: Case = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let resolve = |p: &mut PathBuf| {
        if p.is_relative() {
            *p = base.join(&*p);
        }
    };
    resolve(&mut case.mesh.volume);
    if let Some(f) = case.mesh.faces.as_mut() {
        resolve(f);
    }
    if let Some(f) = case.inflow.waveform_file.as_mut() {
        resolve(f);
    }
    Ok(case)
}

fn faces_path(spec: &MeshSpec) -> PathBuf {
    spec.faces.clone().unwrap_or_else(|| {
        let stem = spec.volume.with_extension("");
        PathBuf::from(format!("{}-faces.vtp", stem.display()))
    })
}

fn face_name(id: i32, roles: &FaceRoles) -> String {
    if id == roles.inlet {
        format!("inlet_{id}")
    } else if roles.outlets.contains(&id) {
        format!("outlet_{id}")
    } else if let Some(k) = roles.planes.iter().position(|&p| p == id) {
        format!("plane{}_{id}", k + 1)
    } else {
        format!("wall_{id}")
    }
}

/// The flow mesh in cm with named faces.
pub fn load_mesh(case: &Case) -> Result<FlowMesh, String> {
    let spec = &case.mesh;
    let vtp = faces_path(spec);
    for p in [&spec.volume, &vtp] {
        if !p.is_file() {
            return Err(format!("{}: mesh file not found", p.display()));
        }
    }
    let units = spec.units.clone().unwrap_or_else(|| if spec.format == "simvascular" { "cm".into() } else { "mm".into() });
    let to_cm = match units.as_str() {
        "mm" => 0.1,
        "cm" => 1.0,
        "m" => 100.0,
        other => return Err(format!("mesh units '{other}': expected mm, cm or m")),
    };
    let mut mesh = match spec.format.as_str() {
        "simvascular" => baffle_cfd::vtu::read_simvascular_mesh(&spec.volume, &vtp).map_err(|e| e.to_string())?,
        "baffle" => read_baffle_mesh(&spec.volume, &vtp)?,
        other => return Err(format!("mesh format '{other}': expected baffle or simvascular")),
    };
    if to_cm != 1.0 {
        mesh.points_cm.iter_mut().flatten().for_each(|x| *x *= to_cm);
    }
    for f in &mut mesh.faces {
        f.name = face_name(f.id, &case.faces);
    }
    let ids: Vec<i32> = mesh.faces.iter().map(|f| f.id).collect();
    let roles = &case.faces;
    let named = std::iter::once(("inlet", roles.inlet))
        .chain(roles.outlets.iter().map(|&o| ("outlet", o)))
        .chain(roles.walls.iter().map(|&w| ("wall", w)))
        .chain(roles.planes.iter().map(|&p| ("plane", p)));
    for (role, id) in named {
        if !ids.contains(&id) {
            return Err(format!("{}: {role} face {id} is not in the mesh (faces {ids:?})", vtp.display()));
        }
    }
    if !roles.planes.is_empty() && roles.planes.len() != 2 {
        return Err(format!("faces.planes: give two measurement planes (dp = first - second), got {:?}", roles.planes));
    }
    mesh.validate().map_err(|e| format!("{}: {e}", spec.volume.display()))?;
    Ok(mesh)
}

/// `baffle mesh` output: volume .vtu and faces .vtp whose GlobalNodeID is the 1-based volume index.
fn read_baffle_mesh(vtu: &Path, vtp: &Path) -> Result<FlowMesh, String> {
    let volume = baffle_mesh::read_vtu(vtu).map_err(|e| e.to_string())?.mesh;
    let n = volume.points_mm.len();
    let surface = baffle_core::io::read_polydata(vtp).map_err(|e| format!("{}: {e}", vtp.display()))?;
    let global = surface
        .point_array("GlobalNodeID")
        .and_then(|a| a.as_i32())
        .ok_or_else(|| format!("{}: no Int32 point array GlobalNodeID", vtp.display()))?;
    let labels = surface
        .cell_array("ModelFaceID")
        .and_then(|a| a.as_i32())
        .ok_or_else(|| format!("{}: no Int32 cell array ModelFaceID", vtp.display()))?;
    let mut grouped: BTreeMap<i32, Vec<[u32; 3]>> = BTreeMap::new();
    for (k, poly) in surface.polys.iter().enumerate() {
        if poly.len() != 3 {
            return Err(format!("{}: polygon {k} has {} points; triangles expected", vtp.display(), poly.len()));
        }
        let mut tri = [0u32; 3];
        for (j, &local) in poly.iter().enumerate() {
            let g = *global.get(local as usize).ok_or_else(|| format!("{}: polygon {k} uses point {local} beyond the points", vtp.display()))?;
            if g < 1 || g as usize > n {
                return Err(format!("{}: GlobalNodeID {g} outside 1..={n} of {}", vtp.display(), vtu.display()));
            }
            tri[j] = g as u32 - 1;
        }
        grouped.entry(labels[surface.poly_cell_index(k)]).or_default().push(tri);
    }
    Ok(FlowMesh {
        points_cm: volume.points_mm.iter().map(|p| [p.x, p.y, p.z]).collect(),
        tets: volume.tets,
        faces: grouped.into_iter().map(|(id, triangles)| Face { id, name: String::new(), triangles }).collect(),
    })
}

/// Heart rates a child can have (beats/min): a newborn's runs to about 190, an exercising
/// teenager's to about 220; outside this range the number is a typo.
pub const HEART_RATE_RANGE_BPM: (f64, f64) = (30.0, 250.0);

pub fn heart_rate_bpm(name: &str, v: f64) -> Result<f64, String> {
    let (lo, hi) = HEART_RATE_RANGE_BPM;
    match v.is_finite() && (lo..=hi).contains(&v) {
        true => Ok(v),
        false => Err(format!("{name} = {v} beats/min is outside the plausible heart rates [{lo}, {hi}]")),
    }
}

fn positive(name: &str, v: f64) -> Result<f64, String> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{name} must be positive and finite, got {v}"))
    }
}

/// `time.mode` of the quick estimate: a transient run from rest that stops at the
/// first flow peak. On p2 and p3's extended domains (1.25 mm) its peak dp is within
/// 0.6 % of the fourth cycle's (docs/measurements.md), at about a twentieth of the steps.
pub const QUICK_MODE: &str = "quick";

/// The time integration scheme a case asks for; rho_inf only goes with generalized-alpha.
/// `time.nonlinear_iterations`: a count or "auto".
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(untagged)]
pub enum IterationsSpec {
    Count(usize),
    Name(String),
}

impl IterationsSpec {
    fn iterations(&self) -> Result<NonlinearIterations, String> {
        match self {
            IterationsSpec::Count(0) => Err("time.nonlinear_iterations is 0; a step needs at least 1 linear solve".into()),
            IterationsSpec::Count(n) => Ok(NonlinearIterations::Fixed(*n)),
            IterationsSpec::Name(name) if name == "auto" => Ok(NonlinearIterations::Auto { cap: AUTO_NONLINEAR_CAP }),
            IterationsSpec::Name(other) => Err(format!("time.nonlinear_iterations '{other}': expected a count (1: semi-implicit) or \"auto\"")),
        }
    }
}

fn time_integration(t: &TimeSpec) -> Result<TimeIntegration, String> {
    match (t.time_integration.as_deref(), t.rho_inf) {
        (None | Some("backward-euler"), None) => Ok(TimeIntegration::BackwardEuler),
        (None | Some("backward-euler"), Some(rho)) => {
            Err(format!("time.rho_inf {rho} is generalized-alpha's spectral radius; backward Euler has none (set time.time_integration to generalized-alpha)"))
        }
        (Some("generalized-alpha"), rho) => Ok(TimeIntegration::GeneralizedAlpha { rho_inf: rho.unwrap_or(DEFAULT_RHO_INF) }),
        (Some(other), _) => Err(format!("time.time_integration '{other}': expected backward-euler or generalized-alpha")),
    }
}

/// The method's ingredients a case names (see [`TimeSpec::tau_metric`]); unnamed ones keep
/// `CaseSettings`' defaults.
fn formulation(t: &TimeSpec, s: &mut CaseSettings) -> Result<(), String> {
    let pick = |field: &str, given: &Option<String>, choices: &[&str]| -> Result<Option<usize>, String> {
        match given.as_deref() {
            None => Ok(None),
            Some(v) => choices.iter().position(|c| *c == v).map(Some).ok_or_else(|| format!("time.{field} '{v}': expected {}", choices.join(" or "))),
        }
    };
    if let Some(k) = pick("tau_metric", &t.tau_metric, &["invariant", "svmultiphysics"])? {
        s.formulation.tau_metric = [baffle_cfd::assembly::TauMetric::Invariant, baffle_cfd::assembly::TauMetric::SvMultiPhysics][k];
    }
    if let Some(k) = pick("convection", &t.convection, &["exact", "centroid"])? {
        s.formulation.exact_convection = k == 0;
    }
    if let Some(v) = t.vms_advection {
        s.formulation.vms_advection = v;
    }
    if let Some(v) = t.vms_reynolds_stress {
        s.formulation.vms_reynolds_stress = v;
    }
    if let Some(v) = t.tau_includes_dt {
        s.tau_includes_dt = v;
    }
    if let Some(k) = pick("viscous_form", &t.viscous_form, &["laplacian", "stress"])? {
        s.formulation.stress_viscosity = k == 1;
    }
    if let Some(k) = pick("stabilization_quadrature", &t.stabilization_quadrature, &["centroid", "gauss"])? {
        s.formulation.gauss_stabilization = k == 1;
    }
    Ok(())
}

pub fn is_quick(case: &Case) -> bool {
    case.time.mode == QUICK_MODE
}

/// The time step at the first flow peak (at least 1): where a quick run stops.
pub fn first_peak_step(settings: &CaseSettings) -> usize {
    ((settings.inflow.peak().1 / settings.dt_s).round() as usize).max(1)
}

/// Solver settings and the derived flow conditions.
pub fn settings(case: &Case) -> Result<(CaseSettings, FlowInputs), String> {
    let inflow = &case.inflow;
    let q_mean = match (inflow.q_mean_ml_s, inflow.bsa_m2) {
        (Some(q), _) => Some(positive("inflow.q_mean_ml_s", q)?),
        (None, Some(bsa)) => {
            let ci = inflow.cardiac_index_l_min_m2.unwrap_or(CARDIAC_INDEX_DEFAULT_L_MIN_M2);
            Some(positive("inflow.bsa_m2", bsa)? * positive("inflow.cardiac_index_l_min_m2", ci)? * 1000.0 / 60.0)
        }
        (None, None) => None,
    };
    let period = match (inflow.period_s, inflow.heart_rate_bpm) {
        (Some(p), _) => positive("inflow.period_s", p)?,
        (None, Some(hr)) => 60.0 / heart_rate_bpm("inflow.heart_rate_bpm", hr)?,
        (None, None) => baffle_cfd::waveform::DEFAULT_PERIOD_S,
    };
    let waveform = match (&inflow.waveform_file, q_mean) {
        (Some(file), q) => {
            let w = Waveform::read(file).map_err(|e| e.to_string())?;
            match q {
                Some(q) => w.scaled_to_mean(q).map_err(|e| e.to_string())?,
                None => w,
            }
        }
        (None, Some(q)) => Waveform::Ejection { period_s: period, q_mean_ml_s: q },
        (None, None) => return Err("inflow: give q_mean_ml_s, bsa_m2 (with cardiac_index_l_min_m2) or waveform_file".into()),
    };
    let q_mean = waveform.mean_ml_s();
    let out = &case.outlet;
    let (resistance, map_mmhg) = match (out.resistance_dyn_s_cm5, out.map_mmhg, out.sbp_mmhg, out.dbp_mmhg) {
        (Some(r), _, _, _) => (r, None),
        (None, Some(map), _, _) => (positive("outlet.map_mmhg", map)? * DYN_CM2_PER_MMHG / q_mean, Some(map)),
        (None, None, Some(sbp), Some(dbp)) => match (inflow.bsa_m2, inflow.q_mean_ml_s, &inflow.waveform_file) {
            (Some(bsa), None, None) => {
                let ci = inflow.cardiac_index_l_min_m2.unwrap_or(CARDIAC_INDEX_DEFAULT_L_MIN_M2);
                let h = hemodynamics(&ClinicalInputs { bsa_m2: bsa, sbp_mmhg: sbp, dbp_mmhg: dbp, cardiac_index_l_min_m2: ci })
                    .map_err(|e| e.to_string())?;
                (h.resistance_dyn_s_cm5, Some(h.map_mmhg))
            }
            _ => {
                let map = mean_arterial_pressure_mmhg(positive("outlet.sbp_mmhg", sbp)?, positive("outlet.dbp_mmhg", dbp)?).round();
                (map * DYN_CM2_PER_MMHG / q_mean, Some(map))
            }
        },
        _ => return Err("outlet: give resistance_dyn_s_cm5, map_mmhg, or sbp_mmhg and dbp_mmhg".into()),
    };
    let outlets = case.faces.outlets.iter().map(|&face_id| Outlet { face_id, resistance_dyn_s_cm5: resistance }).collect();
    let (q_peak, t_peak) = waveform.peak();
    let mut s = CaseSettings::new(case.faces.inlet, waveform, outlets);
    s.density_g_cm3 = case.fluid.density_g_cm3;
    s.viscosity_g_cm_s = case.fluid.viscosity_g_cm_s;
    s.inflow_profile = match inflow.profile.as_deref().unwrap_or("plug") {
        "plug" => InflowProfile::Plug,
        "poiseuille" => InflowProfile::Poiseuille,
        other => return Err(format!("inflow.profile '{other}': expected plug or poiseuille")),
    };
    let t = &case.time;
    s.mode = match t.mode.as_str() {
        "transient" | QUICK_MODE => RunMode::Transient,
        "steady" => RunMode::Steady,
        other => return Err(format!("time.mode '{other}': expected transient, steady or {QUICK_MODE}")),
    };
    if t.steps == Some(0) {
        // Zero would still run the first step and report it as a finished run.
        return Err("time.steps (or --steps) is 0; a run needs at least 1 step".into());
    }
    s.dt_s = t.dt_s;
    s.cycles = t.cycles;
    s.nonlinear_iterations = t.nonlinear_iterations.as_ref().map(IterationsSpec::iterations).transpose()?;
    if let Some(v) = t.nonlinear_tolerance {
        s.nonlinear_tolerance = v;
    }
    if let Some(v) = t.linear_tolerance {
        s.linear_tolerance = v;
    }
    if let Some(v) = t.max_linear_iterations {
        s.max_linear_iterations = v;
    }
    match t.preconditioner.as_deref() {
        None => {}
        Some("ilu") => s.coarse_aggregate_nodes = 0,
        Some("two-level") => s.coarse_aggregate_nodes = baffle_cfd::TWO_LEVEL_AGGREGATE_NODES,
        Some(other) => return Err(format!("time.preconditioner '{other}': expected ilu or two-level")),
    }
    if let Some(v) = t.preconditioner_max_age {
        s.preconditioner_max_age = v;
    }
    s.time_integration = time_integration(t)?;
    formulation(t, &mut s)?;
    if let Some(v) = t.steady_tolerance {
        s.steady_tolerance = v;
    }
    if let Some(v) = t.steady_max_iterations {
        s.steady_max_iterations = v;
    }
    s.validate().map_err(|e| e.to_string())?;
    check_steps_per_cycle(&s)?;
    let flow = FlowInputs {
        q_mean_ml_s: q_mean,
        q_peak_ml_s: q_peak,
        peak_time_in_cycle_s: t_peak,
        period_s: s.inflow.period_s(),
        resistance_dyn_s_cm5: resistance,
        map_mmhg,
    };
    Ok((s, flow))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example_with(from: &str, to: &str) -> Result<(CaseSettings, FlowInputs), String> {
        assert!(EXAMPLE.contains(from), "{from}");
        let case: Case = serde_json::from_str(&EXAMPLE.replacen(from, to, 1)).unwrap();
        settings(&case)
    }

    #[test]
    fn the_example_case_is_valid() {
        example_with("\"dt_s\": 0.001", "\"dt_s\": 0.001").unwrap();
    }

    #[test]
    fn nonlinear_iterations_take_a_count_or_auto_and_default_by_scheme() {
        let dt = "\"dt_s\": 0.001";
        let with = |extra: &str| example_with(dt, &format!("{dt}, {extra}"));
        assert_eq!(with("\"nonlinear_iterations\": 3").unwrap().0.nonlinear(), NonlinearIterations::Fixed(3));
        let (auto, _) = with("\"nonlinear_iterations\": \"auto\", \"nonlinear_tolerance\": 1e-4").unwrap();
        assert_eq!((auto.nonlinear(), auto.nonlinear_tolerance), (NonlinearIterations::Auto { cap: AUTO_NONLINEAR_CAP }, 1e-4));
        assert_eq!(with("\"time_integration\": \"generalized-alpha\"").unwrap().0.nonlinear(), NonlinearIterations::Auto { cap: AUTO_NONLINEAR_CAP });
        assert_eq!(with("\"time_integration\": \"generalized-alpha\", \"nonlinear_iterations\": 1").unwrap().0.nonlinear(), NonlinearIterations::Fixed(1));
        assert_eq!(example_with(dt, dt).unwrap().0.nonlinear(), NonlinearIterations::Fixed(1));
        assert!(with("\"nonlinear_iterations\": \"many\"").unwrap_err().contains("expected a count"));
        assert!(with("\"nonlinear_iterations\": 0").unwrap_err().contains("at least 1"));
    }

    #[test]
    fn the_methods_ingredients_are_named_in_the_time_section_and_default_as_the_solver() {
        let dt = "\"dt_s\": 0.001";
        let with = |extra: &str| example_with(dt, &format!("{dt}, {extra}"));
        let (d, _) = example_with(dt, dt).unwrap();
        let ingredients = |s: &CaseSettings| {
            let f = s.formulation;
            (f.tau_metric, f.exact_convection, f.vms_advection, f.stress_viscosity, f.gauss_stabilization, f.vms_reynolds_stress)
        };
        assert_eq!(ingredients(&d), (baffle_cfd::assembly::TauMetric::SvMultiPhysics, true, true, false, true, true));
        let (s, _) = with("\"tau_metric\": \"invariant\", \"convection\": \"centroid\", \"vms_advection\": false, \"viscous_form\": \"stress\", \"stabilization_quadrature\": \"centroid\", \"vms_reynolds_stress\": false").unwrap();
        assert_eq!(ingredients(&s), (baffle_cfd::assembly::TauMetric::Invariant, false, false, true, false, false));
        assert!(d.tau_includes_dt, "tau holds dt by default, as svMultiPhysics");
        assert!(!with("\"tau_includes_dt\": false").unwrap().0.tau_includes_dt);
        let e = with("\"tau_metric\": \"shakib\"").unwrap_err();
        assert!(e.contains("time.tau_metric 'shakib': expected invariant or svmultiphysics"), "{e}");
        assert!(with("\"viscous_form\": \"full\"").unwrap_err().contains("expected laplacian or stress"));
        assert!(with("\"stabilization_quadrature\": \"exact\"").unwrap_err().contains("expected centroid or gauss"));
    }

    #[test]
    fn a_step_too_long_for_the_cycle_is_named_with_the_steps_it_gives() {
        let e = example_with("\"dt_s\": 0.001", "\"dt_s\": 0.1").unwrap_err();
        assert!(e.contains("time.dt_s = 0.1") && e.contains("6.8 steps"), "{e}");
        // A steady run has no cycle to resolve.
        example_with("\"mode\": \"transient\", \"dt_s\": 0.001", "\"mode\": \"steady\", \"dt_s\": 0.1").unwrap();
    }

    #[test]
    fn heart_rates_outside_a_childs_are_named() {
        assert_eq!(heart_rate_bpm("--hr", 133.0), Ok(133.0));
        for bad in [0.0, f64::NAN, 900.0, -60.0] {
            let e = heart_rate_bpm("--hr", bad).unwrap_err();
            assert!(e.contains("--hr") && e.contains("beats/min"), "{e}");
        }
    }

}
