//! Readers for SimVascular-style meshes: the tetrahedral volume (`.vtu`) and its
//! labelled surface (`.vtp`, `ModelFaceID` per triangle, `GlobalNodeID` per point =
//! the volume's `GlobalNodeID`, 1-based).
//!
//! Both are read with baffle-core's readers (`read_vtu`, `read_polydata`).

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use crate::flow_mesh::{Face, FlowMesh};
use crate::CfdError;

fn io_err(path: &Path, message: impl Into<String>) -> CfdError {
    CfdError::Io { path: path.display().to_string(), message: message.into() }
}

/// Conventional names of the published meshes' face ids (README of the data set).
fn face_name(id: i32) -> String {
    match id {
        2 => "rv_wall".into(),
        10 => "baffle".into(),
        11 => "vsd_inlet".into(),
        16 => "aortic_outlet".into(),
        _ => format!("face_{id}"),
    }
}

/// Read a SimVascular mesh: volume `.vtu` (cm) and its surface `.vtp`, whose
/// triangles become faces grouped by `ModelFaceID`, mapped to volume nodes through
/// `GlobalNodeID`. The result is validated.
pub fn read_simvascular_mesh(vtu_path: &Path, vtp_path: &Path) -> Result<FlowMesh, CfdError> {
    let volume = baffle_core::io::read_vtu(vtu_path).map_err(|e| io_err(vtu_path, e.kind.to_string()))?;
    let volume_ids = volume.point_i32("GlobalNodeID").ok_or_else(|| io_err(vtu_path, "no Int32 point array GlobalNodeID"))?;
    let index_of_global: HashMap<i64, u32> = volume_ids.iter().enumerate().map(|(i, &g)| (g as i64, i as u32)).collect();
    let surface = baffle_core::io::read_polydata(vtp_path).map_err(|e| io_err(vtp_path, e.to_string()))?;
    let surface_ids = surface
        .point_array("GlobalNodeID")
        .and_then(|a| a.as_i32())
        .ok_or_else(|| io_err(vtp_path, "no Int32 point array GlobalNodeID"))?;
    let face_ids = surface
        .cell_array("ModelFaceID")
        .and_then(|a| a.as_i32())
        .ok_or_else(|| io_err(vtp_path, "no Int32 cell array ModelFaceID"))?;
    let mut grouped: BTreeMap<i32, Vec<[u32; 3]>> = BTreeMap::new();
    for (k, poly) in surface.polys.iter().enumerate() {
        if poly.len() != 3 {
            return Err(io_err(vtp_path, format!("polygon {k} has {} nodes; expected triangles", poly.len())));
        }
        let mut tri = [0u32; 3];
        for (j, &local) in poly.iter().enumerate() {
            let global = surface_ids[local as usize] as i64;
            tri[j] = *index_of_global
                .get(&global)
                .ok_or_else(|| io_err(vtp_path, format!("triangle {k}: GlobalNodeID {global} is not in the volume mesh")))?;
        }
        let id = face_ids[surface.poly_cell_index(k)];
        grouped.entry(id).or_default().push(tri);
    }
    let faces = grouped.into_iter().map(|(id, triangles)| Face { id, name: face_name(id), triangles }).collect();
    let points_cm = volume.points.iter().map(|p| [p.x, p.y, p.z]).collect();
    let mut mesh = FlowMesh { points_cm, tets: volume.tets, faces };
    mesh.validate()?;
    Ok(mesh)
}

/// Unit factors from the solver's CGS to the files' mm, m/s and mmHg: every surface of
/// the project is in mm, so a result loads on top of its domain without scaling.
pub const MM_PER_CM: f64 = 10.0;
pub const CM_S_PER_M_S: f64 = 100.0;

/// Point arrays of a written solution: velocity (3 components), its magnitude, pressure.
pub const VELOCITY_ARRAY: &str = "velocity_m_s";
pub const SPEED_ARRAY: &str = "speed_m_s";
pub const PRESSURE_ARRAY: &str = "pressure_mmhg";

/// Write the solution (given in the solver's CGS: points cm, velocity cm/s, pressure
/// dyn/cm^2) as a VTK XML UnstructuredGrid (ASCII) in mm, m/s and mmHg: points (mm),
/// linear tetrahedra, point arrays `velocity_m_s` (3 components), `speed_m_s` and
/// `pressure_mmhg` (the solver's pressure, whose zero is the resistance outlet's
/// downstream pressure). Atomic (`baffle_core::io::write_atomic_with`): a reader never
/// sees a partial file.
pub fn write_solution_vtu(path: &Path, points_cm: &[[f64; 3]], tets: &[[u32; 4]], velocity_cm_s: &[[f64; 3]], pressure_dyn_cm2: &[f64]) -> Result<(), CfdError> {
    use crate::hemodynamics::DYN_CM2_PER_MMHG;
    use std::io::Write;
    if velocity_cm_s.len() != points_cm.len() || pressure_dyn_cm2.len() != points_cm.len() {
        let msg = format!("{} velocities and {} pressures for {} points", velocity_cm_s.len(), pressure_dyn_cm2.len(), points_cm.len());
        return Err(io_err(path, msg));
    }
    if path.file_name().is_none() {
        return Err(io_err(path, "no file name"));
    }
    let write = |w: &mut std::io::BufWriter<std::fs::File>| -> std::io::Result<()> {
        writeln!(w, r#"<?xml version="1.0"?>"#)?;
        writeln!(w, r#"<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">"#)?;
        writeln!(w, "<UnstructuredGrid>")?;
        writeln!(w, r#"<Piece NumberOfPoints="{}" NumberOfCells="{}">"#, points_cm.len(), tets.len())?;
        writeln!(w, r#"<PointData Vectors="{VELOCITY_ARRAY}" Scalars="{SPEED_ARRAY}">"#)?;
        writeln!(w, r#"<DataArray type="Float64" Name="{VELOCITY_ARRAY}" NumberOfComponents="3" format="ascii">"#)?;
        for v in velocity_cm_s {
            writeln!(w, "{:e} {:e} {:e}", v[0] / CM_S_PER_M_S, v[1] / CM_S_PER_M_S, v[2] / CM_S_PER_M_S)?;
        }
        writeln!(w, "</DataArray>")?;
        writeln!(w, r#"<DataArray type="Float64" Name="{SPEED_ARRAY}" format="ascii">"#)?;
        for v in velocity_cm_s {
            writeln!(w, "{:e}", (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() / CM_S_PER_M_S)?;
        }
        writeln!(w, "</DataArray>")?;
        writeln!(w, r#"<DataArray type="Float64" Name="{PRESSURE_ARRAY}" format="ascii">"#)?;
        for p in pressure_dyn_cm2 {
            writeln!(w, "{:e}", p / DYN_CM2_PER_MMHG)?;
        }
        writeln!(w, "</DataArray>\n</PointData>")?;
        writeln!(w, r#"<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">"#)?;
        for p in points_cm {
            writeln!(w, "{:e} {:e} {:e}", p[0] * MM_PER_CM, p[1] * MM_PER_CM, p[2] * MM_PER_CM)?;
        }
        writeln!(w, "</DataArray></Points>\n<Cells>")?;
        writeln!(w, r#"<DataArray type="Int64" Name="connectivity" format="ascii">"#)?;
        for t in tets {
            writeln!(w, "{} {} {} {}", t[0], t[1], t[2], t[3])?;
        }
        writeln!(w, "</DataArray>")?;
        writeln!(w, r#"<DataArray type="Int64" Name="offsets" format="ascii">"#)?;
        for k in 1..=tets.len() {
            writeln!(w, "{}", 4 * k)?;
        }
        writeln!(w, "</DataArray>")?;
        writeln!(w, r#"<DataArray type="UInt8" Name="types" format="ascii">"#)?;
        for _ in tets {
            writeln!(w, "10")?;
        }
        writeln!(w, "</DataArray>\n</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>")
    };
    baffle_core::io::write_atomic_with(path, write).map_err(|e| io_err(path, format!("cannot write: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_data::data_dir;
    use vtkio::model::{Attribute, DataSet};

    #[test]
    fn solution_vtu_round_trips_through_vtkio() {
        let mesh = crate::test_meshes::tube(0.25, 1.0, 2, 3, &[]);
        let n = mesh.points_cm.len();
        let velocity: Vec<[f64; 3]> = (0..n).map(|i| [i as f64, -0.5 * i as f64, 1e-3 * i as f64]).collect();
        let pressure: Vec<f64> = (0..n).map(|i| 1000.0 + 0.25 * i as f64).collect();
        let dir = std::env::temp_dir().join(format!("baffle-cfd-solution-vtu-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("solution.vtu");
        write_solution_vtu(&path, &mesh.points_cm, &mesh.tets, &velocity, &pressure).unwrap();
        // Only the final file is left behind.
        let names: Vec<String> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        assert_eq!(names, vec!["solution.vtu".to_string()]);
        let back = baffle_core::io::read_vtu(&path).unwrap();
        assert_eq!(back.tets, mesh.tets);
        // Written in mm, as every surface of the project.
        for (mm, cm) in back.points.iter().zip(&mesh.points_cm) {
            assert!((0..3).all(|k| (mm[k] - 10.0 * cm[k]).abs() <= 1e-12 * (1.0 + mm[k].abs())), "{mm:?} vs {cm:?} cm");
        }
        let vtk = vtkio::Vtk::import(&path).unwrap();
        let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else { panic!("not a grid") };
        let piece = pieces.into_iter().next().unwrap().into_loaded_piece_data(None).unwrap();
        let array = |name: &str| -> Vec<f64> {
            piece.data.point.iter().find_map(|a| match a {
                Attribute::DataArray(d) if d.name == name => d.data.clone().cast_into::<f64>(),
                _ => None,
            }).unwrap()
        };
        let close = |a: &[f64], b: &[f64]| a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-12 * (1.0 + y.abs()));
        let mmhg: Vec<f64> = pressure.iter().map(|p| p / crate::hemodynamics::DYN_CM2_PER_MMHG).collect();
        assert!(close(&array(PRESSURE_ARRAY), &mmhg));
        let m_s: Vec<f64> = velocity.iter().flatten().map(|v| v / 100.0).collect();
        assert!(close(&array(VELOCITY_ARRAY), &m_s));
        let speed: Vec<f64> = velocity.iter().map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() / 100.0).collect();
        assert!(close(&array(SPEED_ARRAY), &speed));
        assert!(write_solution_vtu(&path, &mesh.points_cm, &mesh.tets, &velocity[1..], &pressure).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn p2_published_mesh_reads_with_inlet_and_outlet() {
        let Some(dir) = data_dir() else { return };
        let start = std::time::Instant::now();
        let mesh = read_simvascular_mesh(&dir.join("p2/published_M_final.vtu"), &dir.join("p2/published_M_final.vtp")).unwrap();
        println!("p2 mesh read + validated in {:?}", start.elapsed());
        assert_eq!(mesh.points_cm.len(), 25680);
        assert_eq!(mesh.tets.len(), 147_013);
        let ids: Vec<i32> = mesh.faces.iter().map(|f| f.id).collect();
        assert_eq!(ids, vec![2, 10, 11, 16]);
        let total: usize = mesh.faces.iter().map(|f| f.triangles.len()).sum();
        assert_eq!(total, 10620);
        let mut copy = mesh.clone();
        let report = copy.validate().unwrap();
        assert_eq!(report.reoriented_tets, 0, "validated mesh is already positive");
        assert_eq!(report.boundary_triangles, 10620, "the surface covers the whole boundary");
        // The caps are about the annulus size: VSD and aortic caps of ~0.1-2 cm2.
        for id in [11, 16] {
            let area = crate::boundary::face_area_cm2(&mesh, mesh.face(id).unwrap());
            assert!(area > 0.1 && area < 2.0, "face {id}: {area} cm2");
        }
    }

    #[test]
    fn missing_files_are_named() {
        let msg = read_simvascular_mesh(Path::new("/nonexistent/mesh.vtu"), Path::new("/nonexistent/mesh.vtp")).unwrap_err().to_string();
        assert!(msg.contains("/nonexistent/mesh.vtu") && msg.contains("not found"), "{msg}");
        let dir = std::env::temp_dir().join(format!("baffle-cfd-vtu-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let garbage = dir.join("garbage.vtu");
        std::fs::write(&garbage, "<VTKFile type=\"PolyData\"></VTKFile>").unwrap();
        let msg = read_simvascular_mesh(&garbage, &dir.join("garbage.vtp")).unwrap_err().to_string();
        assert!(msg.contains("garbage.vtu"), "{msg}");
    }
}
