//! `.vtu` / face `.vtp` round trips and the paper's published SimVascular meshes.

use baffle_core::io::{read_polydata, DataArray};
use baffle_core::Vec3;
use baffle_mesh::tetmesh::tet_faces;
use baffle_mesh::{
    quality_report, read_simvascular, read_vtu, write_faces_vtp, write_vtu, FaceSet, TetMesh,
};
use std::path::PathBuf;

fn data_dir() -> Option<PathBuf> {
    baffle_test_support::reference_data::reference_data_if_present()
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("baffle-mesh-vtu-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Two tets sharing face (1, 2, 3); boundary face 2, interior face 20 on the shared face.
fn two_tets() -> TetMesh {
    let points_mm = vec![
        Vec3::zeros(),
        Vec3::x(),
        Vec3::y(),
        Vec3::z(),
        Vec3::new(1.0, 1.0, 1.0),
    ];
    let tets = vec![[0, 1, 2, 3], [4, 1, 3, 2]];
    let mut boundary: Vec<[u32; 3]> = tet_faces(&tets[0])
        .into_iter()
        .filter(|f| f.contains(&0))
        .collect();
    boundary.extend(tet_faces(&tets[1]).into_iter().filter(|f| f.contains(&4)));
    let faces = vec![
        FaceSet {
            id: 2,
            triangles: boundary,
            interior: false,
        },
        FaceSet {
            id: 20,
            triangles: vec![[1, 2, 3]],
            interior: true,
        },
    ];
    TetMesh {
        points_mm,
        tets,
        faces,
    }
}

#[test]
fn vtu_round_trips_points_tets_and_arrays() {
    let mesh = two_tets();
    mesh.validate().unwrap();
    let path = scratch("two.vtu");
    let region = DataArray::i32("ModelRegionID", vec![1, 1]);
    let speed = DataArray::f64("speed_m_s", 1, vec![0.5, 0.25, 0.0, 1.0, 2.0]);
    write_vtu(
        &path,
        &mesh,
        std::slice::from_ref(&speed),
        std::slice::from_ref(&region),
    )
    .unwrap();
    let back = read_vtu(&path).unwrap();
    assert_eq!(back.mesh.points_mm, mesh.points_mm);
    assert_eq!(back.mesh.tets, mesh.tets);
    assert_eq!(back.point_data, vec![speed]);
    assert_eq!(back.cell_data, vec![region]);
}

#[test]
fn vtu_writer_rejects_arrays_of_the_wrong_length() {
    let mesh = two_tets();
    let err = write_vtu(
        &scratch("bad.vtu"),
        &mesh,
        &[],
        &[DataArray::i32("x", vec![1])],
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("cell array 'x' has 1 tuples, expected 2"),
        "{err}"
    );
}

#[test]
fn face_vtp_carries_labels_and_global_node_ids() {
    let mesh = two_tets();
    let path = scratch("faces.vtp");
    write_faces_vtp(&path, &mesh).unwrap();
    let pd = read_polydata(&path).unwrap();
    let ids = pd
        .cell_data
        .iter()
        .find(|a| a.name == "ModelFaceID")
        .unwrap()
        .as_i32()
        .unwrap()
        .to_vec();
    assert_eq!(ids, vec![2, 2, 2, 2, 2, 2, 20]);
    let interior = pd
        .cell_data
        .iter()
        .find(|a| a.name == "InteriorFace")
        .unwrap()
        .as_i32()
        .unwrap()
        .to_vec();
    assert_eq!(interior.iter().sum::<i32>(), 1);
    let global = pd
        .point_data
        .iter()
        .find(|a| a.name == "GlobalNodeID")
        .unwrap()
        .as_i32()
        .unwrap();
    for (local, &g) in global.iter().enumerate() {
        assert_eq!(pd.points[local], mesh.points_mm[g as usize - 1]);
    }
}

#[test]
fn missing_and_non_tet_files_are_errors_not_panics() {
    let err = read_vtu(&scratch("nope.vtu")).unwrap_err().to_string();
    assert!(
        err.contains("nope.vtu") && err.contains("not found"),
        "{err}"
    );
    let garbage = scratch("garbage.vtu");
    std::fs::write(
        &garbage,
        "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece",
    )
    .unwrap();
    assert!(read_vtu(&garbage)
        .unwrap_err()
        .to_string()
        .contains("garbage.vtu"));
}

#[test]
fn published_p2_mesh_reads_with_its_four_faces() {
    let Some(dir) = data_dir() else { return };
    let p2 = dir.join("p2");
    let mesh = read_simvascular(
        &p2.join("published_M_final.vtu"),
        &p2.join("published_M_final.vtp"),
        10.0,
    )
    .unwrap();
    assert_eq!(mesh.tets.len(), 147_013);
    let ids: Vec<i32> = mesh.faces.iter().map(|f| f.id).collect();
    assert_eq!(ids, vec![2, 10, 11, 16]);
    // validate() ran inside: every boundary triangle is one tet's face, tets positive.
    let surface = mesh.boundary_surface();
    let enclosed = surface.signed_volume_mm3();
    assert!(enclosed > 0.0, "boundary not wound outward");
    assert!(
        (mesh.volume_mm3() - enclosed).abs() / enclosed < 1e-5,
        "{} vs {enclosed}",
        mesh.volume_mm3()
    );
    let report = quality_report(&mesh).unwrap();
    assert!(
        report.min_scaled_jacobian > 0.0 && report.p99_aspect_ratio.is_finite(),
        "{report:?}"
    );
    eprintln!("p2 published mesh: {}", serde_json_like(&report));
}

fn serde_json_like(r: &baffle_mesh::QualityReport) -> String {
    format!(
        "tets {} min SJ {:.3} p1 SJ {:.3} p99 AR {:.2} p99 RR {:.2} min dihedral {:.1} deg volume {:.1} mm3",
        r.tetrahedra, r.min_scaled_jacobian, r.p1_scaled_jacobian, r.p99_aspect_ratio, r.p99_radius_ratio, r.min_dihedral_deg, r.volume_mm3
    )
}
