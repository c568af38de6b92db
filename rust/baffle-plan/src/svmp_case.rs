//! The JSON case, loaded, written as an svMultiPhysics case (mesh-complete/, solver.xml,
//! the inflow file, run.sh): the one export of `baffle export-svmp` and of `baffle
//! simulate --engine svmultiphysics`.

use crate::case;
use baffle_cfd::{CaseSettings, FlowMesh};
use baffle_core::Vec3;
use baffle_mesh::{FaceSet, TetMesh};
use baffle_svmp::{export_case, CaseManifest, ExportOptions, ExportedCase};
use std::collections::BTreeMap;
use std::path::Path;

/// svMultiPhysics always integrates by generalized-alpha: a case that chose it keeps its
/// rho_inf, a backward-Euler case gets svMultiPhysics' default.
fn spectral_radius(settings: &CaseSettings) -> f64 {
    match settings.time_integration {
        baffle_cfd::TimeIntegration::GeneralizedAlpha { rho_inf } => rho_inf,
        baffle_cfd::TimeIntegration::BackwardEuler => baffle_svmp::DEFAULT_SPECTRAL_RADIUS,
    }
}

/// svMultiPhysics runs its own method: a case that switched the embedded engine's
/// ingredients (`time.tau_metric` ... `time.tau_includes_dt`) would be run as another
/// method than it names, so its export is refused, naming what differs.
fn check_svmultiphysics_method(settings: &CaseSettings) -> Result<(), String> {
    let mut differs = Vec::new();
    if settings.formulation != baffle_cfd::SVMULTIPHYSICS_FORMULATION {
        differs.push(format!("the element terms ({:?}; svMultiPhysics': {:?})", settings.formulation, baffle_cfd::SVMULTIPHYSICS_FORMULATION));
    }
    if !settings.tau_includes_dt {
        differs.push("time.tau_includes_dt false (svMultiPhysics' tau holds dt)".to_string());
    }
    match differs.is_empty() {
        true => Ok(()),
        false => Err(format!("the case chooses a method svMultiPhysics does not run: {}; remove these time.* fields to compare the engines", differs.join("; "))),
    }
}

/// Export the loaded case to `dir` (also `baffle simulate --engine svmultiphysics`'s
/// first step); [`inflow_line`] says how the inflow was fitted.
pub(crate) fn export_to(
    dir: &Path,
    case: &case::Case,
    mesh: &FlowMesh,
    settings: &CaseSettings,
    mpi_processes: usize,
) -> Result<ExportedCase, String> {
    check_svmultiphysics_method(settings)?;
    let planes = case.faces.planes.clone();
    let tet_mesh = tet_mesh_mm(mesh, &planes);
    let options = ExportOptions {
        mpi_processes,
        spectral_radius: spectral_radius(settings),
        max_time_steps: step_limit(case, settings),
        ..ExportOptions::new(face_names(&case.faces, mesh), planes)
    };
    export_case(dir, &tet_mesh, settings, &options).map_err(|e| e.to_string())
}

/// How the export fitted the inflow, in one line.
pub(crate) fn inflow_line(exported: &ExportedCase) -> String {
    match (exported.fourier_modes, exported.fourier_max_deviation_ml_s) {
        (Some(modes), Some(dev)) => format!("inflow: {modes} Fourier modes, largest deviation {dev:.3} mL/s"),
        _ => "inflow: constant (steady)".to_string(),
    }
}

/// Where a transient run stops before its last cycle, as on the embedded engine: the
/// case's `time.steps` (or `--steps`), else the quick estimate's first flow peak.
fn step_limit(case: &case::Case, settings: &CaseSettings) -> Option<usize> {
    case.time.steps.or(case::is_quick(case).then(|| case::first_peak_step(settings)))
}

/// Whether a case directory returned from elsewhere (a cluster) was exported from this
/// case: the same faces under the same names, the same measurement planes and time step.
/// A mismatch names the first difference, so results of another case are never read as
/// this one's (the node count is checked when the peak fields are read).
pub(crate) fn check_returned_case(dir: &Path, case: &case::Case, mesh: &FlowMesh, settings: &CaseSettings) -> Result<CaseManifest, String> {
    let manifest = CaseManifest::read(dir).map_err(|e| format!("{e}; --read-back reads a case exported to this --out (svmultiphysics/) and run elsewhere"))?;
    let names = face_names(&case.faces, mesh);
    let returned: BTreeMap<i32, String> = manifest.faces.iter().map(|f| (f.id, f.name.clone())).collect();
    let differs = |what: &str, ours: String, theirs: String| {
        Err(format!("{}: the returned case has {what} {theirs}, this case {ours}: it was exported from another case", dir.display()))
    };
    if returned != names {
        return differs("faces", format!("{names:?}"), format!("{returned:?}"));
    }
    if manifest.measurement_face_ids != case.faces.planes {
        return differs("measurement planes", format!("{:?}", case.faces.planes), format!("{:?}", manifest.measurement_face_ids));
    }
    if manifest.dt_s != settings.dt_s {
        return differs("time step (s)", settings.dt_s.to_string(), manifest.dt_s.to_string());
    }
    Ok(manifest)
}

/// File-name-safe names by role: inflow, outlet_<id>, plane_<id>, wall_<id>.
fn face_names(roles: &case::FaceRoles, mesh: &FlowMesh) -> BTreeMap<i32, String> {
    mesh.faces
        .iter()
        .map(|f| {
            let name = if f.id == roles.inlet {
                "inflow".to_string()
            } else if roles.outlets.contains(&f.id) {
                format!("outlet_{}", f.id)
            } else if roles.planes.contains(&f.id) {
                format!("plane_{}", f.id)
            } else {
                format!("wall_{}", f.id)
            };
            (f.id, name)
        })
        .collect()
}

/// The solver's mesh (cm) as the exporter's tetrahedral mesh (mm; it writes cm).
fn tet_mesh_mm(mesh: &FlowMesh, planes: &[i32]) -> TetMesh {
    TetMesh {
        points_mm: mesh.points_cm.iter().map(|p| Vec3::new(p[0], p[1], p[2]) * 10.0).collect(),
        tets: mesh.tets.clone(),
        faces: mesh
            .faces
            .iter()
            .map(|f| FaceSet { id: f.id, triangles: f.triangles.clone(), interior: planes.contains(&f.id) })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_export_keeps_a_generalized_alpha_case_rho_inf() {
        let mut s = CaseSettings::new(1, baffle_cfd::Waveform::Constant { q_ml_s: 1.0 }, vec![baffle_cfd::Outlet { face_id: 2, resistance_dyn_s_cm5: 0.0 }]);
        assert_eq!(spectral_radius(&s), baffle_svmp::DEFAULT_SPECTRAL_RADIUS);
        s.time_integration = baffle_cfd::TimeIntegration::GeneralizedAlpha { rho_inf: 0.3 };
        assert_eq!(spectral_radius(&s), 0.3);
    }

    #[test]
    fn a_case_with_the_embedded_engines_own_method_is_not_exported_as_svmultiphysics() {
        let svmp = CaseSettings::new(1, baffle_cfd::Waveform::Constant { q_ml_s: 1.0 }, Vec::new());
        assert_eq!(check_svmultiphysics_method(&svmp), Ok(()));
        let mut without_dt = svmp.clone();
        without_dt.tau_includes_dt = false;
        assert!(check_svmultiphysics_method(&without_dt).unwrap_err().contains("time.tau_includes_dt false"));
        let mut invariant = svmp.clone();
        invariant.formulation.tau_metric = baffle_cfd::assembly::TauMetric::Invariant;
        let e = check_svmultiphysics_method(&invariant).unwrap_err();
        assert!(e.contains("Invariant") && e.contains("does not run"), "{e}");
    }
}
