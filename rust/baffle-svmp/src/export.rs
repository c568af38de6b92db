//! [`export_case`]: a complete svMultiPhysics case directory from a mesh and case settings.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use baffle_cfd::{CaseSettings, InflowProfile, RunMode, Waveform};
use baffle_mesh::TetMesh;
use serde::{Deserialize, Serialize};

use crate::format::{
    flow_file_text, solver_xml_text, InflowSpec, SolverSpec, INFLOW_FILE, README_FILE, RESULTS_DIR, RUN_SCRIPT,
    SOLVER_FILE,
};
use crate::fourier::fit_within;
use crate::mesh_export::{mesh_in_cm, write_mesh_complete, MeshFiles};
use crate::SvmpError;

/// svMultiPhysics runs Newton iterations to `Tolerance` each step, as the paper did; the
/// embedded solver's one-solve (semi-implicit) steps are its own choice and are not
/// handed on: the export asks for at least this many.
pub const SVMP_MIN_NEWTON_ITERATIONS: usize = 3;

/// The manifest baffle writes next to `solver.xml` so results can be read back anywhere
/// (e.g. after the directory returns from a cluster).
pub const MANIFEST_FILE: &str = "baffle_case.json";

/// Default generalized-alpha spectral radius rho_infinity (svMultiPhysics' fluid examples).
pub const DEFAULT_SPECTRAL_RADIUS: f64 = 0.5;
/// The fitted inflow must be within this fraction of the peak flow at every sample.
pub const DEFAULT_FOURIER_TOLERANCE: f64 = 0.005;
/// Most Fourier modes tried.
pub const MAX_FOURIER_MODES: usize = 1024;
/// Fewest samples per period in the flow file for an analytic waveform.
pub const MIN_FLOW_SAMPLES: usize = 256;

#[derive(Clone, Debug, PartialEq)]
pub struct ExportOptions {
    /// A file-name-safe name for every face id of the mesh (e.g. 1 -> "wall", 2 -> "inflow").
    pub face_names: BTreeMap<i32, String>,
    /// Measurement planes whose face-averaged pressures give the summary's pressure drop
    /// (first minus second).
    pub measurement_face_ids: Vec<i32>,
    /// `mpiexec -n` in `run.sh`.
    pub mpi_processes: usize,
    /// Time of the spatial output (s); default: the inflow peak of the last cycle.
    pub peak_time_s: Option<f64>,
    pub spectral_radius: f64,
    /// Largest deviation of the fitted inflow, as a fraction of the peak flow.
    pub fourier_tolerance: f64,
    /// Steady mode: simulated time at constant peak inflow (svMultiPhysics has no steady solver).
    pub steady_duration_s: f64,
    /// Transient mode: stop after this time step (the case's `time.steps`, `--steps`, or
    /// the quick estimate's first flow peak) instead of after the last cycle.
    pub max_time_steps: Option<usize>,
}

impl ExportOptions {
    pub fn new(face_names: BTreeMap<i32, String>, measurement_face_ids: Vec<i32>) -> Self {
        ExportOptions {
            face_names,
            measurement_face_ids,
            mpi_processes: 4,
            peak_time_s: None,
            spectral_radius: DEFAULT_SPECTRAL_RADIUS,
            fourier_tolerance: DEFAULT_FOURIER_TOLERANCE,
            steady_duration_s: 1.0,
            max_time_steps: None,
        }
    }
}

/// What a face is in the case.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaceRole {
    Inlet,
    Outlet,
    Wall,
    /// An interior face: a measurement plane (no boundary condition).
    Plane,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ManifestFace {
    pub id: i32,
    pub name: String,
    pub role: FaceRole,
}

/// Written to [`MANIFEST_FILE`]; all [`crate::read_results`] needs besides the outputs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaseManifest {
    pub dt_s: f64,
    pub n_time_steps: usize,
    /// Inflow period (s); absent for a steady case.
    pub period_s: Option<f64>,
    pub peak_step: usize,
    pub mpi_processes: usize,
    pub faces: Vec<ManifestFace>,
    pub measurement_face_ids: Vec<i32>,
    pub results_dir: String,
    /// solver.xml's Newton `Tolerance`, against which the step log is read back (absent in
    /// manifests written before it was recorded: the log's convergence is then not judged).
    #[serde(default)]
    pub nonlinear_tolerance: Option<f64>,
}

impl CaseManifest {
    pub fn read(case_dir: &Path) -> Result<Self, SvmpError> {
        let path = case_dir.join(MANIFEST_FILE);
        let text = std::fs::read_to_string(&path).map_err(|e| SvmpError::io(&path, e))?;
        serde_json::from_str(&text).map_err(|e| SvmpError::io(&path, format!("not a baffle case manifest: {e}")))
    }

    pub fn face(&self, id: i32) -> Option<&ManifestFace> {
        self.faces.iter().find(|f| f.id == id)
    }
}

/// The written case.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportedCase {
    pub dir: PathBuf,
    pub manifest: CaseManifest,
    pub mesh: MeshFiles,
    /// Absent in steady mode (constant inflow in `solver.xml`).
    pub inflow_file: Option<PathBuf>,
    pub fourier_modes: Option<usize>,
    /// Largest |fit - waveform| over the samples and the time steps of a period (mL/s).
    pub fourier_max_deviation_ml_s: Option<f64>,
}

/// Write a complete svMultiPhysics case to `dir` (created if needed): `mesh-complete/`
/// (coordinates converted from mm to cm), `solver.xml`, the inflow file, `run.sh`,
/// `README.md` and the manifest.
pub fn export_case(
    dir: &Path,
    mesh: &TetMesh,
    settings: &CaseSettings,
    options: &ExportOptions,
) -> Result<ExportedCase, SvmpError> {
    settings.validate().map_err(|e| SvmpError::InvalidCase(e.to_string()))?;
    check_options(options)?;
    mesh.validate()?;
    let faces = face_roles(mesh, settings, options)?;
    let timing = Timing::of(settings, options)?;
    std::fs::create_dir_all(dir).map_err(|e| SvmpError::io(dir, e))?;
    let walls: Vec<i32> = faces.iter().filter(|f| f.role == FaceRole::Wall).map(|f| f.id).collect();
    let mesh_files = write_mesh_complete(dir, &mesh_in_cm(mesh), &options.face_names, &walls)?;
    let inflow = write_inflow(dir, settings, options)?;
    let spec = solver_spec(settings, options, &timing, &faces, &mesh_files, &inflow.spec);
    write_text(&dir.join(SOLVER_FILE), &solver_xml_text(&spec))?;
    write_run_script(dir, options.mpi_processes)?;
    write_text(&dir.join(README_FILE), &readme_text(options.mpi_processes))?;
    let manifest = CaseManifest {
        dt_s: settings.dt_s,
        n_time_steps: timing.n_time_steps,
        period_s: timing.period_s,
        peak_step: timing.peak_step,
        mpi_processes: options.mpi_processes,
        faces,
        measurement_face_ids: options.measurement_face_ids.clone(),
        results_dir: RESULTS_DIR.to_string(),
        nonlinear_tolerance: Some(spec.nonlinear_tolerance),
    };
    let json = serde_json::to_string_pretty(&manifest).map_err(|e| SvmpError::io(&dir.join(MANIFEST_FILE), e))?;
    write_text(&dir.join(MANIFEST_FILE), &json)?;
    Ok(ExportedCase {
        dir: dir.to_path_buf(),
        manifest,
        mesh: mesh_files,
        inflow_file: inflow.file,
        fourier_modes: inflow.modes,
        fourier_max_deviation_ml_s: inflow.max_deviation_ml_s,
    })
}

fn check_options(options: &ExportOptions) -> Result<(), SvmpError> {
    if options.mpi_processes == 0 {
        return Err(SvmpError::InvalidCase("mpi_processes must be >= 1".into()));
    }
    if !(options.spectral_radius >= 0.0 && options.spectral_radius <= 1.0) {
        return Err(SvmpError::InvalidCase(format!(
            "spectral radius must be in [0, 1], got {}",
            options.spectral_radius
        )));
    }
    if !(options.fourier_tolerance > 0.0 && options.steady_duration_s > 0.0) {
        return Err(SvmpError::InvalidCase(format!(
            "Fourier tolerance ({}) and steady duration ({} s) must be positive",
            options.fourier_tolerance, options.steady_duration_s
        )));
    }
    let mut seen = std::collections::HashSet::new();
    for (id, name) in &options.face_names {
        let safe = !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c));
        if !safe || name.starts_with('.') {
            return Err(SvmpError::InvalidCase(format!(
                "face {id} name '{name}' must be letters, digits, '_', '-' or '.' (it names a file)"
            )));
        }
        if !seen.insert(name.as_str()) {
            return Err(SvmpError::InvalidCase(format!("face name '{name}' is used twice")));
        }
    }
    Ok(())
}

/// The role of every mesh face; errs on unnamed faces, names of absent faces, and inlet,
/// outlet or measurement ids that are not faces of the mesh.
fn face_roles(mesh: &TetMesh, settings: &CaseSettings, options: &ExportOptions) -> Result<Vec<ManifestFace>, SvmpError> {
    let mesh_ids: Vec<i32> = mesh.faces.iter().map(|f| f.id).collect();
    if let Some(id) = options.face_names.keys().find(|id| !mesh_ids.contains(id)) {
        return Err(SvmpError::InvalidCase(format!("face {id} is named but the mesh has no such face (faces: {mesh_ids:?})")));
    }
    let outlet_ids: Vec<i32> = settings.outlets.iter().map(|o| o.face_id).collect();
    let wanted = std::iter::once(("inlet", settings.inlet_face_id))
        .chain(outlet_ids.iter().map(|&id| ("outlet", id)))
        .chain(options.measurement_face_ids.iter().map(|&id| ("measurement", id)));
    for (what, id) in wanted {
        if !mesh_ids.contains(&id) {
            return Err(SvmpError::InvalidCase(format!("{what} face {id} is not a face of the mesh (faces: {mesh_ids:?})")));
        }
    }
    mesh.faces
        .iter()
        .map(|set| {
            let name = options.face_names.get(&set.id).ok_or_else(|| {
                SvmpError::InvalidCase(format!("face {} has no name in face_names", set.id))
            })?;
            let role = match (set.interior, set.id) {
                (true, id) if id == settings.inlet_face_id || outlet_ids.contains(&id) => {
                    return Err(SvmpError::InvalidCase(format!("inlet/outlet face {id} is interior")))
                }
                (true, _) => FaceRole::Plane,
                (false, id) if id == settings.inlet_face_id => FaceRole::Inlet,
                (false, id) if outlet_ids.contains(&id) => FaceRole::Outlet,
                (false, _) => FaceRole::Wall,
            };
            Ok(ManifestFace { id: set.id, name: name.clone(), role })
        })
        .collect()
}

/// Number of steps, period and the step of the spatial output.
struct Timing {
    n_time_steps: usize,
    period_s: Option<f64>,
    peak_step: usize,
}

impl Timing {
    fn of(settings: &CaseSettings, options: &ExportOptions) -> Result<Self, SvmpError> {
        let dt = settings.dt_s;
        let (duration_s, period_s, default_peak_s) = match settings.mode {
            RunMode::Transient => {
                let period = settings.inflow.period_s();
                let duration = settings.cycles as f64 * period;
                (duration, Some(period), duration - period + settings.inflow.peak().1)
            }
            RunMode::Steady => (options.steady_duration_s, None, options.steady_duration_s),
        };
        let all_steps = (duration_s / dt).round() as usize;
        let n_time_steps = match (settings.mode, options.max_time_steps) {
            (_, Some(0)) => return Err(SvmpError::InvalidCase("the step limit is 0; a run needs at least 1 step".into())),
            (RunMode::Transient, Some(limit)) => all_steps.min(limit),
            _ => all_steps,
        };
        let peak_time_s = options.peak_time_s.unwrap_or(default_peak_s);
        let mut peak_step = (peak_time_s / dt).round();
        if n_time_steps < all_steps && options.peak_time_s.is_none() && peak_step > n_time_steps as f64 {
            // The run stops before the last cycle's peak: its fields at its own largest inflow.
            peak_step = largest_inflow_step(&settings.inflow, dt, n_time_steps) as f64;
        }
        if n_time_steps == 0 || !(peak_step >= 1.0 && peak_step <= n_time_steps as f64) {
            return Err(SvmpError::InvalidCase(format!(
                "peak time {peak_time_s} s is not within the run's {n_time_steps} steps of {dt} s"
            )));
        }
        Ok(Timing { n_time_steps, period_s, peak_step: peak_step as usize })
    }
}

/// The step in 1..=n_steps with the largest |inflow| (the first of equals).
fn largest_inflow_step(inflow: &Waveform, dt_s: f64, n_steps: usize) -> usize {
    (1..=n_steps).fold((1, f64::NEG_INFINITY), |best, k| {
        let q = inflow.flow_ml_s(k as f64 * dt_s).abs();
        if q > best.1 { (k, q) } else { best }
    }).0
}

struct Inflow {
    spec: InflowSpec,
    file: Option<PathBuf>,
    modes: Option<usize>,
    max_deviation_ml_s: Option<f64>,
}

/// Transient: the flow file with enough modes. Steady: the peak flow as a constant.
fn write_inflow(dir: &Path, settings: &CaseSettings, options: &ExportOptions) -> Result<Inflow, SvmpError> {
    if settings.mode == RunMode::Steady {
        let spec = InflowSpec::Steady { flux_out_ml_s: -settings.inflow.peak().0 };
        return Ok(Inflow { spec, file: None, modes: None, max_deviation_ml_s: None });
    }
    let waveform = &settings.inflow;
    let (times, flows) = inflow_samples(waveform, settings.dt_s);
    let check_times = check_times(&times, waveform.period_s(), settings.dt_s);
    let peak = check_times.iter().map(|&t| waveform.flow_ml_s(t).abs()).fold(0.0, f64::max);
    // svMultiPhysics prescribes flux along the outward normal: inflow is negative.
    // (0.0 - q keeps zero flow a plain "0" instead of "-0".)
    let flux_out: Vec<f64> = flows.iter().map(|q| 0.0 - q).collect();
    let tolerance = options.fourier_tolerance * peak.max(f64::MIN_POSITIVE);
    let (series, deviation) =
        fit_within(&times, &flux_out, &check_times, |t| -waveform.flow_ml_s(t), tolerance, MAX_FOURIER_MODES)?;
    let path = dir.join(INFLOW_FILE);
    write_text(&path, &flow_file_text(&times, &flux_out, series.modes()))?;
    Ok(Inflow {
        spec: InflowSpec::Unsteady { file: INFLOW_FILE.to_string() },
        file: Some(path),
        modes: Some(series.modes()),
        max_deviation_ml_s: Some(deviation),
    })
}

/// One period of (time, inflow) samples, the first repeated one period later: a table's
/// own samples, or an analytic waveform at >= one sample per time step.
pub fn inflow_samples(waveform: &Waveform, dt_s: f64) -> (Vec<f64>, Vec<f64>) {
    let period = waveform.period_s();
    let (mut times, mut flows) = match waveform {
        Waveform::Table { times_s, flows_ml_s, .. } => (times_s.clone(), flows_ml_s.clone()),
        _ => {
            let n = ((period / dt_s).ceil() as usize).max(MIN_FLOW_SAMPLES);
            let times: Vec<f64> = (0..n).map(|i| i as f64 * period / n as f64).collect();
            let flows = times.iter().map(|&t| waveform.flow_ml_s(t)).collect();
            (times, flows)
        }
    };
    times.push(times[0] + period);
    flows.push(flows[0]);
    (times, flows)
}

/// The samples and every time step of one period: where the fit must match.
fn check_times(samples: &[f64], period_s: f64, dt_s: f64) -> Vec<f64> {
    let steps = (period_s / dt_s).ceil() as usize;
    samples.iter().copied().chain((0..=steps).map(|k| k as f64 * dt_s)).collect()
}

fn solver_spec(
    settings: &CaseSettings,
    options: &ExportOptions,
    timing: &Timing,
    faces: &[ManifestFace],
    mesh_files: &MeshFiles,
    inflow: &InflowSpec,
) -> SolverSpec {
    let name_of = |id: i32| options.face_names[&id].clone();
    let with_role = |role: FaceRole| faces.iter().filter(move |f| f.role == role).map(|f| f.name.clone());
    SolverSpec {
        n_time_steps: timing.n_time_steps,
        dt_s: settings.dt_s,
        spectral_radius: options.spectral_radius,
        save_start_step: timing.peak_step,
        save_increment: timing.peak_step,
        density_g_cm3: settings.density_g_cm3,
        viscosity_g_cm_s: settings.viscosity_g_cm_s,
        backflow_stabilization: settings.backflow_stabilization,
        max_nonlinear_iterations: settings.nonlinear().max_iterations().max(SVMP_MIN_NEWTON_ITERATIONS),
        nonlinear_tolerance: settings.nonlinear_tolerance,
        linear_tolerance: settings.linear_tolerance,
        faces: mesh_files
            .faces
            .iter()
            .map(|(_, name, path)| (name.clone(), path.to_string_lossy().into_owned()))
            .collect(),
        inlet_name: name_of(settings.inlet_face_id),
        inlet_profile: match settings.inflow_profile {
            InflowProfile::Plug => "Flat",
            InflowProfile::Poiseuille => "Parabolic",
        },
        inflow: inflow.clone(),
        outlets: settings.outlets.iter().map(|o| (name_of(o.face_id), o.resistance_dyn_s_cm5)).collect(),
        walls: with_role(FaceRole::Wall).collect(),
    }
}

fn write_text(path: &Path, text: &str) -> Result<(), SvmpError> {
    std::fs::write(path, text).map_err(|e| SvmpError::io(path, e))
}

fn write_run_script(dir: &Path, processes: usize) -> Result<(), SvmpError> {
    let path = dir.join(RUN_SCRIPT);
    let script = format!(
        r#"#!/bin/sh
# Run this svMultiPhysics case from its directory: ./run.sh
# NP=<processes> overrides the {processes} MPI processes; SVMP=/path/to/svmultiphysics the executable.
set -e
cd "$(dirname "$0")"
SVMP="${{SVMP:-$(command -v svmultiphysics || command -v svMultiPhysics || true)}}"
if [ -z "$SVMP" ]; then
  echo "run.sh: neither svmultiphysics nor svMultiPhysics is on PATH; set SVMP=/path/to/it" >&2
  exit 127
fi
# Open MPI refuses to run as root (e.g. in a container) without --allow-run-as-root,
# which MPICH does not know.
ROOT_OPTION=
if [ "$(id -u)" = 0 ] && mpiexec --version 2>/dev/null | grep -q -e 'Open MPI' -e OpenRTE; then
  ROOT_OPTION=--allow-run-as-root
fi
exec mpiexec $ROOT_OPTION -n "${{NP:-{processes}}}" "$SVMP" {SOLVER_FILE}
"#
    );
    write_text(&path, &script)?;
    set_executable(&path)
}

#[cfg(unix)]
fn set_executable(path: &Path) -> Result<(), SvmpError> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755)).map_err(|e| SvmpError::io(path, e))
}

#[cfg(not(unix))]
fn set_executable(_path: &Path) -> Result<(), SvmpError> {
    Ok(())
}

fn readme_text(processes: usize) -> String {
    format!(
        "# svMultiPhysics case exported by baffle\n\n\
         `{SOLVER_FILE}` with the mesh in `mesh-complete/` (cm), the inflow in `{INFLOW_FILE}`.\n\
         Run here: `./{RUN_SCRIPT}` (mpiexec -n {processes}; `NP=64 ./{RUN_SCRIPT}` for more processes).\n\n\
         On a Slurm cluster: `sbatch --ntasks={processes} --time=24:00:00 --wrap 'NP=$SLURM_NTASKS ./{RUN_SCRIPT}'`\n\
         (other schedulers: run `./{RUN_SCRIPT}` with NP set to the allocated process count).\n\n\
         Results land in `{RESULTS_DIR}/` (B_NS_*.txt boundary integrals, result_*.vtu at peak flow);\n\
         copy the whole directory back in place (`OUT/svmultiphysics/` when `baffle simulate --engine svmultiphysics\n\
         --out OUT` exported it) and read it with `baffle simulate CASE --engine svmultiphysics --out OUT --read-back`\n\
         (it checks `{MANIFEST_FILE}` against the case).\n"
    )
}
