//! [`read_results`]: svMultiPhysics' outputs of an exported case read back into the same
//! per-step face series and peak figures as the embedded engine reports.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use baffle_cfd::hemodynamics::DYN_CM2_PER_MMHG;
use baffle_core::io::DataArray;
use serde::Serialize;

use crate::export::{CaseManifest, FaceRole};
use crate::format::{
    parse_boundary_integral, parse_step_line, result_file_step, BoundaryTable, GLOBAL_NODE_ID, PRESSURE_AVERAGE_FILE,
    RESULT_PRESSURE, RESULT_VELOCITY, VELOCITY_FLUX_FILE,
};
use crate::SvmpError;

/// Pressure and flow on one face at one step (field names as the embedded engine's).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FaceSample {
    pub id: i32,
    pub name: String,
    pub mean_pressure_dyn_cm2: f64,
    /// Flux along the outward normal (boundary faces) or the triangles' winding normal
    /// (measurement planes; see `GlobalElementID` in [`crate::format`]).
    pub flow_ml_s: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StepSample {
    pub step: usize,
    pub time_s: f64,
    /// Flux into the domain through the inlet.
    pub inflow_ml_s: f64,
    /// Total flux out through the outlets.
    pub outflow_ml_s: f64,
    pub faces: Vec<FaceSample>,
    /// How the engine's step log says the step converged (None: no log line for it).
    pub convergence: Option<StepConvergence>,
}

/// One time step's convergence as svMultiPhysics logged it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct StepConvergence {
    pub newton_iterations: usize,
    /// The last iterate met the Newton tolerance (false: the step stopped at Max_iterations).
    pub nonlinear_converged: bool,
    /// Every linear solve of the step reached its tolerance.
    pub linear_converged: bool,
    /// The last iterate's residual relative to the step's first.
    pub final_step_relative_residual: f64,
}

/// Velocity and pressure at the nodes (volume-mesh numbering) from a `result_*.vtu`.
#[derive(Clone, Debug, PartialEq)]
pub struct PeakFields {
    pub step: usize,
    pub file: PathBuf,
    pub velocity_cm_s: Vec<[f64; 3]>,
    pub pressure_dyn_cm2: Vec<f64>,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SvmpSummary {
    pub engine: String,
    pub steps: Vec<StepSample>,
    /// The written step at (or nearest to) the exported peak step.
    pub peak_step: usize,
    pub peak_time_s: f64,
    /// Face-averaged pressure of the first measurement plane minus the second, at the peak.
    pub dp_peak_mmhg: Option<f64>,
    /// Inflow over the last cycle (the last step in steady mode).
    pub q_mean_ml_s: f64,
    pub q_peak_ml_s: f64,
    pub peak_fields_file: Option<PathBuf>,
    #[serde(skip)]
    pub peak_fields: Option<PeakFields>,
    /// Whether every step met the Newton tolerance with every linear solve converged, as
    /// the step log says (None: no log, or no tolerance, to judge by).
    pub converged: Option<bool>,
    /// What was expected but not found (e.g. no result file at the peak step), and the
    /// engine's convergence warnings.
    pub warnings: Vec<String>,
}

/// Read `B_NS_Pressure_average.txt`, `B_NS_Velocity_flux.txt` and the peak `result_*.vtu`
/// of the case exported to `case_dir`.
pub fn read_results(case_dir: &Path) -> Result<SvmpSummary, SvmpError> {
    let manifest = CaseManifest::read(case_dir)?;
    let results = case_dir.join(&manifest.results_dir);
    let pressure = read_table(&results.join(PRESSURE_AVERAGE_FILE), manifest.dt_s)?;
    let flux = read_table(&results.join(VELOCITY_FLUX_FILE), manifest.dt_s)?;
    let mut steps = step_samples(&manifest, &results, &pressure, &flux)?;
    let peak = peak_index(&steps, manifest.peak_step);
    let (q_mean_ml_s, q_peak_ml_s) = inflow_figures(&steps, manifest.period_s);
    let mut warnings = Vec::new();
    let converged = match (step_log(case_dir, &manifest), manifest.nonlinear_tolerance) {
        (Some((path, text)), Some(tolerance)) => {
            let logged = step_convergence(&text, tolerance);
            for step in &mut steps {
                step.convergence = logged.get(&step.step).copied();
            }
            let found = convergence_warnings(&steps, tolerance, &path);
            let ok = found.is_empty();
            warnings.extend(found);
            Some(ok)
        }
        (None, _) => {
            warnings.push(format!("no step log ({HISTORY_FILE} in {}, or {}): the engine's convergence is unknown", results.display(), crate::run::LOG_FILE));
            None
        }
        (Some(_), None) => {
            warnings.push("the case manifest has no Newton tolerance (exported by an older baffle): the engine's convergence is not judged".into());
            None
        }
    };
    let peak_fields = match find_result_file(&results, steps[peak].step)? {
        Some(file) => Some(read_peak_fields(&file, steps[peak].step)?),
        None => {
            warnings.push(format!("no result_*.vtu for step {} in {}", steps[peak].step, results.display()));
            None
        }
    };
    Ok(SvmpSummary {
        engine: "svMultiPhysics".into(),
        peak_step: steps[peak].step,
        peak_time_s: steps[peak].time_s,
        dp_peak_mmhg: pressure_drop_mmhg(&manifest, &steps[peak]),
        q_mean_ml_s,
        q_peak_ml_s,
        peak_fields_file: peak_fields.as_ref().map(|f| f.file.clone()),
        peak_fields,
        steps,
        converged,
        warnings,
    })
}

/// svMultiPhysics' copy of its step log in the results folder.
pub const HISTORY_FILE: &str = "histor.dat";

/// The step log: results/histor.dat, else the stdout copy `baffle` keeps beside solver.xml.
fn step_log(case_dir: &Path, manifest: &CaseManifest) -> Option<(PathBuf, String)> {
    [case_dir.join(&manifest.results_dir).join(HISTORY_FILE), case_dir.join(crate::run::LOG_FILE)]
        .into_iter()
        .find_map(|path| std::fs::read_to_string(&path).ok().filter(|t| !t.trim().is_empty()).map(|t| (path, t)))
}

/// Each logged time step's convergence from its iteration lines (the last one decides
/// the Newton test, every one the linear solves).
pub fn step_convergence(log: &str, tolerance: f64) -> BTreeMap<usize, StepConvergence> {
    let mut out: BTreeMap<usize, StepConvergence> = BTreeMap::new();
    for line in log.lines().filter_map(parse_step_line) {
        let Some(r) = line.residual else { continue };
        let entry = out.entry(line.step).or_insert(StepConvergence {
            newton_iterations: 0,
            nonlinear_converged: true,
            linear_converged: true,
            final_step_relative_residual: 1.0,
        });
        if line.iteration >= entry.newton_iterations {
            entry.newton_iterations = line.iteration;
            entry.nonlinear_converged = r.meets(tolerance);
            entry.final_step_relative_residual = r.step_relative;
        }
        entry.linear_converged &= r.linear_converged;
    }
    out
}

/// What the summary says of the engine's convergence: steps stopped at the Newton cap,
/// steps with a linear solve short of its tolerance, steps the log does not show.
fn convergence_warnings(steps: &[StepSample], tolerance: f64, log: &Path) -> Vec<String> {
    let list = |pick: &dyn Fn(&StepConvergence) -> bool| -> Vec<usize> {
        steps.iter().filter(|s| s.convergence.as_ref().is_some_and(|c| pick(c))).map(|s| s.step).collect()
    };
    let first = |v: &[usize]| v.iter().take(5).map(|s| s.to_string()).collect::<Vec<_>>().join(", ");
    let mut out = Vec::new();
    let newton = list(&|c| !c.nonlinear_converged);
    if !newton.is_empty() {
        out.push(format!(
            "svMultiPhysics: {} of {} time steps stopped at Max_iterations above the Newton tolerance {tolerance:e} (steps {}{}; {})",
            newton.len(), steps.len(), first(&newton), if newton.len() > 5 { ", ..." } else { "" }, log.display()
        ));
    }
    let linear = list(&|c| !c.linear_converged);
    if !linear.is_empty() {
        out.push(format!(
            "svMultiPhysics: {} of {} time steps had a linear solve that did not reach its tolerance (steps {}{}; {})",
            linear.len(), steps.len(), first(&linear), if linear.len() > 5 { ", ..." } else { "" }, log.display()
        ));
    }
    let missing = steps.iter().filter(|s| s.convergence.is_none()).count();
    if missing > 0 {
        out.push(format!("svMultiPhysics: {missing} of {} time steps have no iteration line in {}", steps.len(), log.display()));
    }
    out
}

fn read_table(path: &Path, dt_s: f64) -> Result<BoundaryTable, SvmpError> {
    let text = std::fs::read_to_string(path).map_err(|e| SvmpError::io(path, e))?;
    let table = parse_boundary_integral(path, &text, dt_s)?;
    if table.rows.is_empty() {
        return Err(SvmpError::format(path, 1, "has no time-step rows (did the run start?)"));
    }
    Ok(table)
}

/// Column of every manifest face in `table`, in manifest order.
fn columns(manifest: &CaseManifest, table: &BoundaryTable, path: &Path) -> Result<Vec<usize>, SvmpError> {
    manifest
        .faces
        .iter()
        .map(|f| {
            table.face_names.iter().position(|n| *n == f.name).ok_or_else(|| {
                SvmpError::format(path, 1, format!("has no column for face '{}' (columns: {:?})", f.name, table.face_names))
            })
        })
        .collect()
}

fn step_samples(
    manifest: &CaseManifest,
    results: &Path,
    pressure: &BoundaryTable,
    flux: &BoundaryTable,
) -> Result<Vec<StepSample>, SvmpError> {
    let pressure_path = results.join(PRESSURE_AVERAGE_FILE);
    let flux_path = results.join(VELOCITY_FLUX_FILE);
    let p_cols = columns(manifest, pressure, &pressure_path)?;
    let q_cols = columns(manifest, flux, &flux_path)?;
    let n = pressure.rows.len().min(flux.rows.len());
    let mut steps = Vec::with_capacity(n);
    for (p_row, q_row) in pressure.rows.iter().zip(&flux.rows) {
        if p_row.step != q_row.step {
            return Err(SvmpError::format(
                &flux_path,
                0,
                format!("step {} where {} has step {}", q_row.step, PRESSURE_AVERAGE_FILE, p_row.step),
            ));
        }
        let faces: Vec<FaceSample> = manifest
            .faces
            .iter()
            .zip(p_cols.iter().zip(&q_cols))
            .map(|(f, (&pc, &qc))| FaceSample {
                id: f.id,
                name: f.name.clone(),
                mean_pressure_dyn_cm2: p_row.values[pc],
                flow_ml_s: q_row.values[qc],
            })
            .collect();
        let sum_of = |role: FaceRole| {
            manifest.faces.iter().zip(&faces).filter(|(m, _)| m.role == role).map(|(_, s)| s.flow_ml_s).sum::<f64>()
        };
        steps.push(StepSample {
            step: p_row.step,
            time_s: p_row.time_s,
            inflow_ml_s: -sum_of(FaceRole::Inlet),
            outflow_ml_s: sum_of(FaceRole::Outlet),
            faces,
            convergence: None,
        });
    }
    Ok(steps)
}

/// Index of the row at `peak_step`, or of the nearest written step.
fn peak_index(steps: &[StepSample], peak_step: usize) -> usize {
    (0..steps.len()).min_by_key(|&i| steps[i].step.abs_diff(peak_step)).unwrap_or(0)
}

/// (mean, max) of the inflow over the last period of written steps, or the last value.
fn inflow_figures(steps: &[StepSample], period_s: Option<f64>) -> (f64, f64) {
    let last = &steps[steps.len() - 1];
    let Some(period) = period_s else {
        return (last.inflow_ml_s, last.inflow_ml_s);
    };
    let cycle: Vec<f64> =
        steps.iter().filter(|s| s.time_s > last.time_s - period * (1.0 - 1e-9)).map(|s| s.inflow_ml_s).collect();
    let mean = cycle.iter().sum::<f64>() / cycle.len() as f64;
    (mean, cycle.iter().copied().fold(f64::NEG_INFINITY, f64::max))
}

fn pressure_drop_mmhg(manifest: &CaseManifest, step: &StepSample) -> Option<f64> {
    let [first, second, ..] = manifest.measurement_face_ids[..] else {
        return None;
    };
    let p = |id: i32| step.faces.iter().find(|f| f.id == id).map(|f| f.mean_pressure_dyn_cm2);
    Some((p(first)? - p(second)?) / DYN_CM2_PER_MMHG)
}

fn find_result_file(results: &Path, step: usize) -> Result<Option<PathBuf>, SvmpError> {
    let entries = std::fs::read_dir(results).map_err(|e| SvmpError::io(results, e))?;
    for entry in entries {
        let entry = entry.map_err(|e| SvmpError::io(results, e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if result_file_step(&name) == Some(step) {
            return Ok(Some(entry.path()));
        }
    }
    Ok(None)
}

/// The `Velocity` and `Pressure` point arrays, put in volume-mesh order through
/// `GlobalNodeID` when the file has it.
pub fn read_peak_fields(file: &Path, step: usize) -> Result<PeakFields, SvmpError> {
    let data = baffle_mesh::read_vtu(file)?;
    let n = data.mesh.points_mm.len();
    let velocity = f64_array(file, &data.point_data, RESULT_VELOCITY, 3, n)?;
    let pressure = f64_array(file, &data.point_data, RESULT_PRESSURE, 1, n)?;
    let order = node_order(file, &data.point_data, n)?;
    let mut velocity_cm_s = vec![[0.0; 3]; n];
    let mut pressure_dyn_cm2 = vec![0.0; n];
    for (k, &node) in order.iter().enumerate() {
        velocity_cm_s[node] = [velocity[3 * k], velocity[3 * k + 1], velocity[3 * k + 2]];
        pressure_dyn_cm2[node] = pressure[k];
    }
    Ok(PeakFields { step, file: file.to_path_buf(), velocity_cm_s, pressure_dyn_cm2 })
}

fn f64_array(file: &Path, arrays: &[DataArray], name: &str, components: usize, n: usize) -> Result<Vec<f64>, SvmpError> {
    let array = arrays.iter().find(|a| a.name == name).ok_or_else(|| {
        let names: Vec<&str> = arrays.iter().map(|a| a.name.as_str()).collect();
        SvmpError::io(file, format!("has no point array '{name}' (arrays: {names:?})"))
    })?;
    match array.as_f64() {
        Some((c, values)) if c == components && values.len() == components * n => Ok(values.to_vec()),
        _ => Err(SvmpError::io(
            file,
            format!("point array '{name}' is not {n} Float tuples of {components} components"),
        )),
    }
}

/// 0-based volume node of each file point: `GlobalNodeID - 1`, or the file order.
fn node_order(file: &Path, arrays: &[DataArray], n: usize) -> Result<Vec<usize>, SvmpError> {
    let Some(ids) = arrays.iter().find(|a| a.name == GLOBAL_NODE_ID).and_then(|a| a.as_i32()) else {
        return Ok((0..n).collect());
    };
    let mut seen = vec![false; n];
    ids.iter()
        .map(|&id| {
            let node = usize::try_from(id - 1).ok().filter(|&k| k < n && !seen[k]);
            let node = node.ok_or_else(|| {
                SvmpError::io(file, format!("{GLOBAL_NODE_ID} {id} is outside 1..={n} or repeated"))
            })?;
            seen[node] = true;
            Ok(node)
        })
        .collect()
}
