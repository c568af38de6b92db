//! Valid input files of every reader, built in memory from a mesh or points: the fuzz
//! bench's seeds and the bad-input campaign's starting points (shared so the two stay
//! the same formats).
#![allow(dead_code)]

use baffle_core::io::{write_markups_closed_curve, write_trimesh_vtp, CoordinateSystem};
use baffle_core::{TriMesh, Vec3};
use std::io::Write;

/// The first `n` triangles of `mesh` (a small open patch: quick to parse many times).
pub fn first_triangles(mesh: &TriMesh, n: usize) -> TriMesh {
    let keep: Vec<bool> = (0..mesh.triangles.len()).map(|t| t < n).collect();
    mesh.submesh(&keep).0
}

pub fn vtp_bytes(mesh: &TriMesh) -> Vec<u8> {
    let path = std::env::temp_dir().join(format!("baffle-fuzz-seed-{}.vtp", std::process::id()));
    write_trimesh_vtp(&path, mesh).expect("write seed");
    let bytes = std::fs::read(&path).expect("read seed");
    std::fs::remove_file(&path).ok();
    bytes
}

pub fn markups_bytes(points: &[Vec3]) -> Vec<u8> {
    let path = std::env::temp_dir().join(format!("baffle-fuzz-seed-{}.mrk.json", std::process::id()));
    write_markups_closed_curve(&path, "BC", points, CoordinateSystem::Lps).expect("write seed");
    let bytes = std::fs::read(&path).expect("read seed");
    std::fs::remove_file(&path).ok();
    bytes
}

pub fn legacy_vtk(mesh: &TriMesh, binary: bool) -> Vec<u8> {
    let mut out = format!(
        "# vtk DataFile Version 3.0\nfuzz seed\n{}\nDATASET POLYDATA\nPOINTS {} double\n",
        if binary { "BINARY" } else { "ASCII" },
        mesh.points.len()
    )
    .into_bytes();
    if binary {
        mesh.points.iter().flat_map(|p| [p.x, p.y, p.z]).for_each(|v| out.extend(v.to_be_bytes()));
        out.extend(format!("\nPOLYGONS {} {}\n", mesh.triangles.len(), 4 * mesh.triangles.len()).bytes());
        for t in &mesh.triangles {
            [3, t[0], t[1], t[2]].iter().for_each(|v| out.extend((*v as i32).to_be_bytes()));
        }
        out.extend(format!("\nCELL_DATA {}\nSCALARS ModelFaceID int 1\nLOOKUP_TABLE default\n", mesh.triangles.len()).bytes());
        mesh.face_ids.iter().for_each(|v| out.extend(v.to_be_bytes()));
        out.push(b'\n');
    } else {
        mesh.points.iter().for_each(|p| out.extend(format!("{} {} {}\n", p.x, p.y, p.z).bytes()));
        out.extend(format!("POLYGONS {} {}\n", mesh.triangles.len(), 4 * mesh.triangles.len()).bytes());
        mesh.triangles.iter().for_each(|t| out.extend(format!("3 {} {} {}\n", t[0], t[1], t[2]).bytes()));
        out.extend(format!("CELL_DATA {}\nSCALARS ModelFaceID int 1\nLOOKUP_TABLE default\n", mesh.triangles.len()).bytes());
        mesh.face_ids.iter().for_each(|v| out.extend(format!("{v}\n").bytes()));
    }
    out
}

pub fn ascii_stl(mesh: &TriMesh) -> Vec<u8> {
    let mut s = String::from("solid fuzz\n");
    for t in 0..mesh.triangles.len() {
        let n = mesh.triangle_normal2(t).normalize();
        s += &format!("facet normal {} {} {}\nouter loop\n", n.x, n.y, n.z);
        for p in mesh.triangle_points(t) {
            s += &format!("vertex {} {} {}\n", p.x, p.y, p.z);
        }
        s += "endloop\nendfacet\n";
    }
    (s + "endsolid fuzz\n").into_bytes()
}

pub fn binary_stl(mesh: &TriMesh) -> Vec<u8> {
    let mut out = vec![0u8; 80];
    out.extend((mesh.triangles.len() as u32).to_le_bytes());
    for t in 0..mesh.triangles.len() {
        let n = mesh.triangle_normal2(t).normalize();
        let ps = mesh.triangle_points(t);
        for v in [n, ps[0], ps[1], ps[2]] {
            [v.x, v.y, v.z].iter().for_each(|c| out.extend((*c as f32).to_le_bytes()));
        }
        out.extend([0, 0]);
    }
    out
}

pub fn fcsv(points: &[Vec3]) -> Vec<u8> {
    let mut s = String::from("# Markups fiducial file version = 4.11\n# CoordinateSystem = LPS\n# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n");
    for (i, p) in points.iter().enumerate() {
        s += &format!("vtkMRMLMarkupsFiducialNode_{i},{},{},{},0,0,0,1,1,1,0,F-{i},,\n", p.x, p.y, p.z);
    }
    s.into_bytes()
}

pub fn csv(points: &[Vec3]) -> Vec<u8> {
    points.iter().map(|p| format!("{},{},{}\n", p.x, p.y, p.z)).collect::<String>().into_bytes()
}

/// A 6x5x4 label map with labels 0..7.
pub fn labels() -> Vec<u8> {
    (0..6 * 5 * 4).map(|v| (v % 7) as u8).collect()
}

pub fn nrrd(gzipped: bool) -> Vec<u8> {
    let mut out = format!(
        "NRRD0004\ntype: unsigned char\ndimension: 3\nspace: left-posterior-superior\nsizes: 6 5 4\n\
         space directions: (0.5,0,0) (0,0.5,0) (0,0,0.7)\nkinds: domain domain domain\nencoding: {}\nspace origin: (1,2,3)\n\n",
        if gzipped { "gzip" } else { "raw" }
    )
    .into_bytes();
    out.extend(if gzipped { gzip(&labels()) } else { labels() });
    out
}

/// NIfTI-1, u8 samples, an sform in RAS.
pub fn nifti() -> Vec<u8> {
    let mut h = vec![0u8; 352];
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    for (d, v) in [3i16, 6, 5, 4, 1, 1, 1, 1].iter().enumerate() {
        h[40 + 2 * d..42 + 2 * d].copy_from_slice(&v.to_le_bytes());
    }
    h[70..72].copy_from_slice(&2i16.to_le_bytes());
    h[72..74].copy_from_slice(&8i16.to_le_bytes());
    h[108..112].copy_from_slice(&352f32.to_le_bytes());
    h[254..256].copy_from_slice(&1i16.to_le_bytes());
    let sform = [[0.5f32, 0.0, 0.0, 1.0], [0.0, 0.5, 0.0, 2.0], [0.0, 0.0, 0.7, 3.0]];
    for (r, row) in sform.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            let o = 280 + 16 * r + 4 * c;
            h[o..o + 4].copy_from_slice(&v.to_le_bytes());
        }
    }
    h[344..348].copy_from_slice(b"n+1\0");
    h.extend(labels());
    h
}

pub fn gzip(data: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(data).expect("gzip");
    e.finish().expect("gzip")
}
