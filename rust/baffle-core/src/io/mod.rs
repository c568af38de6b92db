//! File I/O: surfaces and polylines (VTK XML `.vtp`, legacy `.vtk`, `.stl`), tetrahedral
//! volumes (`.vtu`, read) and suture point lists (Slicer markups, CSV, JSON); and a
//! design's result files ([`outputs`]).
//!
//! Geometry is returned as stored (millimetres expected, frame as in the file).
//! Every error is an [`IoError`] whose message starts with the file's path.

mod atomic;
mod error;
pub mod outputs;
mod legacy;
mod points;
mod polydata;
mod stl;
mod vtp_read;
mod vtp_write;
mod vtu_read;

use std::path::Path;

pub use atomic::{write_atomic, write_atomic_with};
pub use error::{IoError, IoErrorKind};
pub use points::{read_points, write_markups_closed_curve, CoordinateSystem, SuturePoints};
pub use polydata::{ArrayValues, DataArray, LabeledSurface, PolyData, PolyDataOut, MODEL_FACE_ID};
pub use vtp_read::ScalarType;
pub use vtu_read::{read_vtu, TetGrid};

use crate::geometry::mesh::TriMesh;
use error::read_bytes;

/// File formats told apart by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SurfaceFormat {
    VtkXml,
    VtkLegacy,
    Stl,
}

fn surface_format(path: &Path) -> Result<SurfaceFormat, IoError> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("vtp") => Ok(SurfaceFormat::VtkXml),
        Some("vtk") => Ok(SurfaceFormat::VtkLegacy),
        Some("stl") => Ok(SurfaceFormat::Stl),
        _ => {
            Err(IoError::new(path, IoErrorKind::Unsupported("unknown extension (expected .vtp, .vtk or .stl)".into())))
        }
    }
}

/// Read a triangle surface from `.vtp`, `.vtk` or `.stl`. Polygons are triangulated
/// as fans, strips split into triangles, vertices and lines ignored. `face_ids` are
/// the `ModelFaceID` cell array, or all 0 when the file has none (see
/// [`read_surface_labeled`] to tell the two apart).
pub fn read_surface(path: &Path) -> Result<TriMesh, IoError> {
    Ok(read_surface_labeled(path)?.mesh)
}

/// Like [`read_surface`], also saying whether the file had a `ModelFaceID` array.
pub fn read_surface_labeled(path: &Path) -> Result<LabeledSurface, IoError> {
    let format = surface_format(path)?;
    let bytes = read_bytes(path)?;
    let surface = match format {
        SurfaceFormat::Stl => stl::parse_stl(&bytes).and_then(|mesh| {
            polydata::check_finite_points(&mesh.points)?;
            Ok(LabeledSurface { mesh, has_model_face_id: false })
        }),
        SurfaceFormat::VtkXml => vtp_read::parse_vtp(&bytes).and_then(|pd| pd.to_labeled_surface()),
        SurfaceFormat::VtkLegacy => legacy::parse_legacy(&bytes).and_then(|pd| pd.to_labeled_surface()),
    };
    surface.map_err(|kind| IoError::new(path, kind))
}

/// Read VTK PolyData (`.vtp` or legacy `.vtk`) with its lines, polygons and numeric
/// point/cell arrays (see [`PolyData`] for how vertices and strips are handled).
pub fn read_polydata(path: &Path) -> Result<PolyData, IoError> {
    let format = surface_format(path)?;
    let bytes = read_bytes(path)?;
    let parsed = match format {
        SurfaceFormat::VtkXml => vtp_read::parse_vtp(&bytes),
        SurfaceFormat::VtkLegacy => legacy::parse_legacy(&bytes),
        SurfaceFormat::Stl => Err(IoErrorKind::Unsupported("STL holds no PolyData; use read_surface".into())),
    };
    parsed.map_err(|kind| IoError::new(path, kind))
}

/// Write VTK XML PolyData (base64 binary, Float64 points), atomically ([`write_atomic`]).
/// The data is validated first (finite points, indices in range, array lengths).
pub fn write_vtp(path: &Path, data: &PolyData) -> Result<(), IoError> {
    data.validate().map_err(|kind| IoError::new(path, kind))?;
    write_atomic(path, vtp_write::vtp_text(data).as_bytes()).map_err(|e| IoError::new(path, IoErrorKind::Os(e)))
}

/// Write a triangle mesh as `.vtp` with `face_ids` as the Int32 cell array `ModelFaceID`.
pub fn write_trimesh_vtp(path: &Path, mesh: &TriMesh) -> Result<(), IoError> {
    if mesh.face_ids.len() != mesh.triangles.len() {
        let kind = IoErrorKind::ArrayLength {
            array: MODEL_FACE_ID.into(),
            expected: mesh.triangles.len(),
            found: mesh.face_ids.len(),
        };
        return Err(IoError::new(path, kind));
    }
    let data = PolyData {
        points: mesh.points.clone(),
        polys: mesh.triangles.iter().map(|t| t.to_vec()).collect(),
        lines: Vec::new(),
        point_data: Vec::new(),
        cell_data: vec![DataArray::i32(MODEL_FACE_ID, mesh.face_ids.clone())],
    };
    write_vtp(path, &data)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::Vec3;
    use std::collections::BTreeSet;
    use std::path::PathBuf;

    fn data_dir() -> Option<PathBuf> {
        baffle_test_support::reference_data::reference_data_if_present()
    }

    fn scratch_dir() -> PathBuf {
        let dir = std::env::temp_dir().join(format!("baffle-io-tests-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// (patient, its file `relative`) of each published patient, p2 first; none without
    /// the patient data.
    fn published_files(relative: &str) -> Vec<(&'static str, PathBuf)> {
        let Some(dir) = data_dir() else { return Vec::new() };
        ["p2", "p3"].into_iter().map(|patient| (patient, dir.join(patient).join(relative))).collect()
    }

    /// `NumberOfPoints`/`NumberOfPolys` as written in the file's Piece element.
    fn piece_count(path: &Path, attribute: &str) -> usize {
        let text = std::fs::read(path).unwrap();
        let text = String::from_utf8_lossy(&text[..4096.min(text.len())]).into_owned();
        let key = format!("{attribute}=\"");
        let start = text.find(&key).unwrap() + key.len();
        text[start..].split('"').next().unwrap().trim().parse().unwrap()
    }

    fn labels(mesh: &TriMesh) -> BTreeSet<i32> {
        mesh.face_ids.iter().copied().collect()
    }

    #[test]
    fn capped_ventricles_read_with_their_labels() {
        for (patient, path) in published_files("design_input/capped_ventricle.vtp") {
            let s = read_surface_labeled(&path).unwrap();
            assert!(s.has_model_face_id);
            assert_eq!(s.mesh.points.len(), piece_count(&path, "NumberOfPoints"), "{patient}");
            assert_eq!(s.mesh.triangles.len(), piece_count(&path, "NumberOfPolys"), "{patient}");
            assert_eq!(labels(&s.mesh), BTreeSet::from([2, 11, 16]), "{patient}");
            let report = crate::geometry::mesh::manifold_report(&s.mesh);
            assert!(report.is_closed_manifold(), "{patient}: {report:?}");
            assert!(s.mesh.signed_volume_mm3() > 0.0, "{patient}: README says outward-wound");
            if patient == "p2" {
                let plain = read_surface(&path).unwrap();
                assert_eq!((plain.points.len(), plain.triangles.len()), (5312, 10620));
            }
        }
    }

    #[test]
    fn published_surfaces_with_appended_base64_and_float32_points() {
        for (patient, path) in published_files("published_M_final.vtp") {
            let pd = read_polydata(&path).unwrap();
            assert_eq!(pd.points.len(), piece_count(&path, "NumberOfPoints"));
            assert_eq!(pd.polys.len(), piece_count(&path, "NumberOfPolys"));
            let node_ids = pd.point_array("GlobalNodeID").unwrap().as_i32().unwrap();
            assert_eq!(node_ids.len(), pd.points.len());
            assert!(pd.cell_array("GlobalElementID").is_some());
            let mesh = pd.to_labeled_surface().unwrap().mesh;
            assert_eq!(labels(&mesh), BTreeSet::from([2, 10, 11, 16]), "{patient}");
        }
    }

    #[test]
    fn published_seams_are_closed_polylines() {
        for (patient, path) in published_files("design_input/published_seam.vtp") {
            let pd = read_polydata(&path).unwrap();
            assert!(pd.polys.is_empty());
            assert_eq!(pd.lines.len(), 1, "{patient}");
            let line = &pd.lines[0];
            assert_eq!(line.len(), pd.points.len() + 1, "{patient}: every point once, first repeated to close");
            assert_eq!(line.first(), line.last());
        }
    }

    #[test]
    fn suture_points_of_both_patients() {
        for (patient, path) in published_files("design_input/suture_points.mrk.json") {
            let sp = read_points(&path).unwrap();
            assert_eq!(sp.points_mm.len(), 14, "{patient}");
            assert_eq!(sp.coordinate_system, CoordinateSystem::Lps);
            assert!(sp.closed);
            assert_eq!(sp.labels.len(), 14);
        }
    }

    #[test]
    fn segmentations_with_appended_data_read() {
        let Some(dir) = data_dir() else { return };
        let path = dir.join("p2/segmentations/LV.vtp");
        let s = read_surface_labeled(&path).unwrap();
        assert_eq!(s.mesh.points.len(), piece_count(&path, "NumberOfPoints"));
        assert_eq!(labels(&s.mesh), BTreeSet::from([1]));
    }

    #[test]
    fn read_time_of_p2_capped_ventricle() {
        let Some(dir) = data_dir() else { return };
        let path = dir.join("p2/design_input/capped_ventricle.vtp");
        let runs = 20;
        let start = std::time::Instant::now();
        for _ in 0..runs {
            read_surface(&path).unwrap();
        }
        let per_read = start.elapsed() / runs;
        println!("read_surface(p2 capped_ventricle.vtp): {per_read:?} per read");
        assert!(per_read.as_secs_f64() < 1.0, "{per_read:?}");
    }

    #[test]
    fn vtk_written_appended_raw_files_read() {
        // Synthetic fixtures written by VTK (see testdata/README.md).
        for (name, bytes) in [
            ("raw", &include_bytes!("testdata/tetra_appended_raw.vtp")[..]),
            ("raw zlib UInt64", &include_bytes!("testdata/tetra_appended_raw_zlib_uint64.vtp")[..]),
        ] {
            let pd = vtp_read::parse_vtp(bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(pd.lines, vec![vec![0, 1, 2]], "{name}");
            let s = pd.to_labeled_surface().unwrap();
            assert_eq!(s.mesh.triangles, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], "{name}");
            assert_eq!(s.mesh.face_ids, vec![2, 2, 11, 16], "{name}");
            assert_eq!(s.mesh.points[3], Vec3::new(0.0, 0.0, 1.0), "{name}");
        }
    }

    fn small_polydata() -> PolyData {
        let points = vec![
            Vec3::new(0.1, 0.2, 0.3),
            Vec3::new(1.0 / 3.0, 0.0, -1e-300),
            Vec3::new(0.0, std::f64::consts::PI, 1e12),
            Vec3::new(-2.5, 7.0, 0.0),
        ];
        PolyData {
            points,
            polys: vec![vec![0, 1, 2], vec![0, 2, 3, 1]],
            lines: vec![vec![3, 0, 1]],
            point_data: vec![
                DataArray::f64("distance_mm", 1, vec![0.5, -1.0, f64::MAX, 0.0]),
                DataArray::vectors("normal", &[Vec3::x(), Vec3::y(), Vec3::z(), -Vec3::x()]),
            ],
            cell_data: vec![
                DataArray::i32(MODEL_FACE_ID, vec![-1, 10, 11]),
                DataArray::i32("big", vec![i32::MIN, 0, i32::MAX]),
            ],
        }
    }

    #[test]
    fn vtp_round_trip_is_exact() {
        let path = scratch_dir().join("round trip & <name>.vtp");
        let original = small_polydata();
        write_vtp(&path, &original).unwrap();
        assert!(!path.with_extension("vtp.tmp").exists());
        let back = read_polydata(&path).unwrap();
        for (a, b) in original.points.iter().zip(&back.points) {
            for k in 0..3 {
                assert_eq!(a[k].to_bits(), b[k].to_bits());
            }
        }
        assert_eq!(back, original);
        let surface = read_surface_labeled(&path).unwrap();
        assert_eq!(surface.mesh.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 3, 1]]);
        assert_eq!(surface.mesh.face_ids, vec![10, 11, 11]);
    }

    #[test]
    fn trimesh_round_trip_keeps_labels() {
        let path = scratch_dir().join("mesh.vtp");
        let mesh =
            TriMesh::new(vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()], vec![[0, 2, 1], [0, 1, 3]], vec![2, 16]);
        write_trimesh_vtp(&path, &mesh).unwrap();
        assert_eq!(read_surface(&path).unwrap(), mesh);
        let mut bad = mesh.clone();
        bad.face_ids.pop();
        let msg = write_trimesh_vtp(&path, &bad).unwrap_err().to_string();
        assert!(msg.contains("mesh.vtp") && msg.contains(MODEL_FACE_ID), "{msg}");
    }

    #[test]
    fn writer_rejects_invalid_data_naming_the_problem() {
        let path = scratch_dir().join("invalid.vtp");
        let mut pd = small_polydata();
        pd.polys[1][2] = 9;
        let msg = write_vtp(&path, &pd).unwrap_err().to_string();
        assert!(msg.contains("invalid.vtp") && msg.contains("polygon 1") && msg.contains("point 9"), "{msg}");
        let mut pd = small_polydata();
        pd.points[2].z = f64::NAN;
        let msg = write_vtp(&path, &pd).unwrap_err().to_string();
        assert!(msg.contains("point 2"), "{msg}");
        assert!(!path.exists());
    }

    const LEGACY_ASCII: &str = "# vtk DataFile Version 3.0\nsmall\nASCII\nDATASET POLYDATA\n\
        POINTS 4 float\n0 0 0 1 0 0 0 1 0 0.5 0.5 1\n\
        LINES 1 3\n2 0 3\n\
        POLYGONS 2 9\n3 0 2 1\n4 0 1 3 2\n\
        CELL_DATA 3\nSCALARS ModelFaceID int 1\nLOOKUP_TABLE default\n5 2 16\n\
        POINT_DATA 4\nFIELD FieldData 1\nheight 1 4 double\n0 0 0 1\n";

    #[test]
    fn legacy_ascii_reads_fans_and_labels() {
        let path = scratch_dir().join("ascii.vtk");
        std::fs::write(&path, LEGACY_ASCII).unwrap();
        let s = read_surface_labeled(&path).unwrap();
        assert!(s.has_model_face_id);
        assert_eq!(s.mesh.triangles, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2]]);
        assert_eq!(s.mesh.face_ids, vec![2, 16, 16]);
        let pd = read_polydata(&path).unwrap();
        assert_eq!(pd.lines, vec![vec![0, 3]]);
        assert_eq!(pd.point_array("height").unwrap().as_f64().unwrap().1, &[0.0, 0.0, 0.0, 1.0]);
    }

    #[test]
    fn legacy_5_1_ascii_with_offsets_reads() {
        let text = "# vtk DataFile Version 5.1\nsmall\nASCII\nDATASET POLYDATA\n\
            POINTS 3 double\n0 0 0 1 0 0 0 1 0\n\
            POLYGONS 2 3\nOFFSETS vtktypeint64\n0 3\nCONNECTIVITY vtktypeint64\n0 1 2\n\
            CELL_DATA 1\nFIELD FieldData 1\nModelFaceID 1 1 int\n11\n";
        let path = scratch_dir().join("v51.vtk");
        std::fs::write(&path, text).unwrap();
        let s = read_surface_labeled(&path).unwrap();
        assert_eq!(s.mesh.triangles, vec![[0, 1, 2]]);
        assert_eq!(s.mesh.face_ids, vec![11]);
    }

    #[test]
    fn legacy_binary_reads_big_endian_data() {
        let pts = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let mut bytes = b"# vtk DataFile Version 3.0\nbinary\nBINARY\nDATASET POLYDATA\nPOINTS 4 float\n".to_vec();
        bytes.extend(pts.iter().flatten().flat_map(|x| x.to_be_bytes()));
        bytes.extend_from_slice(b"\nPOLYGONS 2 8\n");
        bytes.extend([3i32, 0, 2, 1, 3, 0, 1, 3].iter().flat_map(|x| x.to_be_bytes()));
        bytes.extend_from_slice(b"\nCELL_DATA 2\nSCALARS ModelFaceID int 1\nLOOKUP_TABLE default\n");
        bytes.extend([10i32, 11].iter().flat_map(|x| x.to_be_bytes()));
        bytes.push(b'\n');
        let path = scratch_dir().join("binary.vtk");
        std::fs::write(&path, &bytes).unwrap();
        let s = read_surface_labeled(&path).unwrap();
        assert_eq!(s.mesh.points[3], Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(s.mesh.triangles, vec![[0, 2, 1], [0, 1, 3]]);
        assert_eq!(s.mesh.face_ids, vec![10, 11]);
    }

    #[test]
    fn legacy_index_out_of_range_is_an_error() {
        let text = LEGACY_ASCII.replace("3 0 2 1\n", "3 0 2 7\n");
        let path = scratch_dir().join("bad_index.vtk");
        std::fs::write(&path, text).unwrap();
        let msg = read_surface(&path).unwrap_err().to_string();
        assert!(msg.contains("bad_index.vtk") && msg.contains("point 7"), "{msg}");
    }

    fn tetra_corners() -> Vec<[[f32; 3]; 3]> {
        let p = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]].iter().map(|t| t.map(|i| p[i])).collect()
    }

    fn assert_is_closed_tetra(mesh: &TriMesh) {
        assert_eq!(mesh.points.len(), 4, "shared corners are merged");
        assert_eq!(mesh.triangles.len(), 4);
        assert!(crate::geometry::mesh::manifold_report(mesh).is_closed_manifold());
        assert!((mesh.signed_volume_mm3() - 1.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn stl_ascii_reads_and_merges_corners() {
        let mut text = String::from("solid tetra\n");
        for tri in tetra_corners() {
            text.push_str("  facet normal 0 0 0\n    outer loop\n");
            for c in tri {
                text.push_str(&format!("      vertex {} {} {}\n", c[0], c[1], c[2]));
            }
            text.push_str("    endloop\n  endfacet\n");
        }
        text.push_str("endsolid tetra\n");
        let path = scratch_dir().join("tetra_ascii.stl");
        std::fs::write(&path, text).unwrap();
        let s = read_surface_labeled(&path).unwrap();
        assert!(!s.has_model_face_id);
        assert_is_closed_tetra(&s.mesh);
    }

    #[test]
    fn stl_binary_reads_and_merges_corners() {
        let mut bytes = b"solid binary file with an ascii-looking header".to_vec();
        bytes.resize(80, 0);
        let corners = tetra_corners();
        bytes.extend((corners.len() as u32).to_le_bytes());
        for tri in corners {
            bytes.extend([0f32; 3].iter().flat_map(|x| x.to_le_bytes()));
            bytes.extend(tri.iter().flatten().flat_map(|x| x.to_le_bytes()));
            bytes.extend([0u8, 0]);
        }
        let path = scratch_dir().join("tetra_binary.STL");
        std::fs::write(&path, &bytes).unwrap();
        assert_is_closed_tetra(&read_surface(&path).unwrap());
        bytes.truncate(bytes.len() - 10);
        std::fs::write(&path, &bytes).unwrap();
        let msg = read_surface(&path).unwrap_err().to_string();
        assert!(msg.contains("tetra_binary.STL") && msg.contains("4 triangles"), "{msg}");
    }

    #[test]
    fn missing_and_unknown_files_are_named() {
        let missing = scratch_dir().join("no_such_surface.vtp");
        let msg = read_surface(&missing).unwrap_err().to_string();
        assert!(msg.contains("no_such_surface.vtp") && msg.contains("not found"), "{msg}");
        let unknown = scratch_dir().join("surface.obj");
        std::fs::write(&unknown, "v 0 0 0\n").unwrap();
        let msg = read_surface(&unknown).unwrap_err().to_string();
        assert!(msg.contains("surface.obj") && msg.contains("unknown extension"), "{msg}");
        let garbage = scratch_dir().join("garbage.vtp");
        std::fs::write(&garbage, "<VTKFile type=\"UnstructuredGrid\"><Piece/></VTKFile>").unwrap();
        let msg = read_surface(&garbage).unwrap_err().to_string();
        assert!(msg.contains("garbage.vtp") && msg.contains("UnstructuredGrid"), "{msg}");
    }
}
