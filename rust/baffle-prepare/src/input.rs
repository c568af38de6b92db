//! The three blood pools `prepare` joins, read from per-structure closed surfaces
//! (`LV.vtp`, `RV.vtp`, `aorta.vtp` as Slicer exports segments; `.vtk` and `.stl`
//! too), each checked to be closed.

use crate::error::PrepareError;
use baffle_core::io::read_surface;
use baffle_core::geometry::mesh::manifold_report;
use baffle_core::TriMesh;
use std::path::{Path, PathBuf};

/// The LV, RV and aorta blood pools as closed surfaces (mm).
#[derive(Clone, Debug)]
pub struct BloodPools {
    pub lv: TriMesh,
    pub rv: TriMesh,
    pub aorta: TriMesh,
}

/// File stems tried for each structure, in order.
const STEMS: [(&str, &[&str]); 3] = [("LV", &["LV", "lv"]), ("RV", &["RV", "rv"]), ("aorta", &["aorta", "Aorta", "AO", "Ao"])];
const EXTENSIONS: [&str; 3] = ["vtp", "vtk", "stl"];

/// Read `DIR/{LV,RV,aorta}.{vtp,vtk,stl}`; a missing file is named, and so is an
/// open or non-manifold surface (with one offending edge).
pub fn read_segmentations(dir: &Path) -> Result<BloodPools, PrepareError> {
    let [lv, rv, aorta] = STEMS.map(|(structure, stems)| read_structure(dir, structure, stems));
    Ok(BloodPools { lv: lv?, rv: rv?, aorta: aorta? })
}

/// `DIR/pulmonary.{vtp,vtk,stl}` (or PA), where the folder has one: the RV outflow's end.
pub fn pulmonary_file(dir: &Path) -> Option<PathBuf> {
    find_file(dir, &["pulmonary", "Pulmonary", "PA", "pa"])
}

fn find_file(dir: &Path, stems: &[&str]) -> Option<PathBuf> {
    stems.iter().flat_map(|s| EXTENSIONS.iter().map(move |e| dir.join(format!("{s}.{e}")))).find(|p| p.is_file())
}

fn read_structure(dir: &Path, structure: &'static str, stems: &[&str]) -> Result<TriMesh, PrepareError> {
    let path = find_file(dir, stems).ok_or_else(|| PrepareError::MissingFile { structure, path: dir.join(format!("{}.vtp", stems[0])) })?;
    let mesh = read_surface(&path).map_err(|e| PrepareError::Read(e.to_string()))?;
    check_closed(&mesh, structure, &path)?;
    Ok(mesh)
}

/// Errors unless `mesh` is a closed, manifold surface with at least one triangle.
pub fn check_closed(mesh: &TriMesh, structure: &'static str, path: &Path) -> Result<(), PrepareError> {
    if mesh.triangles.is_empty() {
        return Err(PrepareError::Read(format!("{}: the {structure} surface has no triangles", path.display())));
    }
    let report = manifold_report(mesh);
    if report.boundary_edges + report.non_manifold_edges == 0 {
        return Ok(());
    }
    let edge = report.example_edge.unwrap_or((0, 0));
    let at = mesh.points[edge.0 as usize];
    Err(PrepareError::OpenSurface {
        structure,
        path: path.to_path_buf(),
        count: report.boundary_edges + report.non_manifold_edges,
        edge,
        at_mm: [at.x, at.y, at.z],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::uv_sphere;
    use baffle_core::io::write_trimesh_vtp;
    use baffle_core::Vec3;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("baffle-prepare-input-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_missing_structure_names_its_file() {
        let dir = scratch("missing");
        let sphere = uv_sphere(Vec3::zeros(), 1.0, 6, 12);
        write_trimesh_vtp(&dir.join("LV.vtp"), &sphere).unwrap();
        write_trimesh_vtp(&dir.join("RV.vtp"), &sphere).unwrap();
        let err = read_segmentations(&dir).unwrap_err().to_string();
        assert!(err.contains("aorta") && err.contains("aorta.vtp"), "{err}");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn an_open_surface_names_its_file_and_an_edge() {
        let dir = scratch("open");
        let mut open = uv_sphere(Vec3::zeros(), 1.0, 6, 12);
        open.triangles.pop();
        open.face_ids.pop();
        let path = dir.join("RV.vtp");
        write_trimesh_vtp(&path, &open).unwrap();
        let err = check_closed(&read_surface(&path).unwrap(), "RV", &path).unwrap_err().to_string();
        assert!(err.contains("RV.vtp") && err.contains("not closed") && err.contains("edge"), "{err}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
