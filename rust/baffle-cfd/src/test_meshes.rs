//! Structured tetrahedral meshes of a straight tube for verification tests.
//!
//! Cross-section: a centre node and rings k = 1..N of 6k nodes, triangulated ring to
//! ring by angle. Along z: layers of prisms, each split into 3 tets by the
//! global-index rule (every quad face is cut by the diagonal from its lowest-index
//! node), which makes neighbouring prisms conform.

use std::f64::consts::PI;

use crate::flow_mesh::{Face, FlowMesh};

pub const INLET: i32 = 1;
pub const OUTLET: i32 = 2;
/// Interior measurement plane at layer l has id PLANE + l.
pub const PLANE: i32 = 100;

/// Disk of radius r: points (x, y) and triangles.
fn disk(radius_cm: f64, rings: usize) -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
    let mut pts = vec![[0.0, 0.0]];
    let mut ring_start = vec![0usize];
    for k in 1..=rings {
        ring_start.push(pts.len());
        let n = 6 * k;
        let r = radius_cm * k as f64 / rings as f64;
        for j in 0..n {
            let a = 2.0 * PI * j as f64 / n as f64;
            pts.push([r * a.cos(), r * a.sin()]);
        }
    }
    let mut tris = Vec::new();
    for k in 1..=rings {
        let (m, n) = (if k == 1 { 1 } else { 6 * (k - 1) }, 6 * k);
        let inner = |i: usize| (ring_start[k - 1] + i % m) as u32;
        let outer = |j: usize| (ring_start[k] + j % n) as u32;
        let (mut i, mut j) = (0, 0);
        while i < m || j < n {
            let next_in = if k == 1 { f64::INFINITY } else { (i + 1) as f64 / m as f64 };
            let next_out = (j + 1) as f64 / n as f64;
            if i < m && (j == n || next_in <= next_out) && k > 1 {
                tris.push([inner(i), outer(j), inner(i + 1)]);
                i += 1;
            } else {
                tris.push([inner(i), outer(j), outer(j + 1)]);
                j += 1;
            }
            if k == 1 && j == n {
                break;
            }
        }
    }
    (pts, tris)
}

/// Tube of radius r along z in [0, L] with `rings` radial and `layers` axial
/// divisions; faces: inlet (z = 0), outlet (z = L), interior planes at `planes` (layer indices).
pub fn tube(radius_cm: f64, length_cm: f64, rings: usize, layers: usize, planes: &[usize]) -> FlowMesh {
    let (disk_pts, disk_tris) = disk(radius_cm, rings);
    let nd = disk_pts.len() as u32;
    let mut points_cm = Vec::new();
    for l in 0..=layers {
        let z = length_cm * l as f64 / layers as f64;
        points_cm.extend(disk_pts.iter().map(|p| [p[0], p[1], z]));
    }
    let mut tets = Vec::new();
    for l in 0..layers as u32 {
        for t in &disk_tris {
            let mut v = *t;
            v.sort_unstable();
            let b = v.map(|d| l * nd + d);
            let u = v.map(|d| (l + 1) * nd + d);
            tets.push([b[0], b[1], b[2], u[2]]);
            tets.push([b[0], b[1], u[1], u[2]]);
            tets.push([b[0], u[0], u[1], u[2]]);
        }
    }
    let layer_face = |l: u32| disk_tris.iter().map(|t| t.map(|d| l * nd + d)).collect::<Vec<_>>();
    let mut faces = vec![
        Face { id: INLET, name: "inlet".into(), triangles: layer_face(0) },
        Face { id: OUTLET, name: "outlet".into(), triangles: layer_face(layers as u32) },
    ];
    for &l in planes {
        faces.push(Face { id: PLANE + l as i32, name: format!("plane_{l}"), triangles: layer_face(l as u32) });
    }
    let mut mesh = FlowMesh { points_cm, tets, faces };
    mesh.validate().expect("structured tube mesh is valid");
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tube_is_a_closed_conforming_mesh_of_the_right_volume() {
        let (rings, layers) = (4, 6);
        let mut mesh = tube(0.5, 2.0, rings, layers, &[3]);
        let report = mesh.validate().unwrap();
        // Inscribed 24-gon area times length.
        let sides = 6.0 * rings as f64;
        let polygon = 0.5 * sides * 0.25 * (2.0 * PI / sides).sin();
        assert!((report.volume_cm3 - polygon * 2.0).abs() < 1e-12, "{report:?}");
        // Boundary = 2 caps of 6 N^2 triangles + side of 2 x 6N x layers triangles;
        // a non-conforming split would leave unmatched interior triangles on the boundary.
        assert_eq!(report.boundary_triangles, 2 * 6 * rings * rings + 2 * 6 * rings * layers);
        let faces = crate::boundary::face_geometries(&mesh, &crate::flow_mesh::element_faces(&mesh.tets)).unwrap();
        assert_eq!(faces[0].kind, crate::boundary::FaceKind::Boundary);
        assert_eq!(faces[2].kind, crate::boundary::FaceKind::Interior);
        assert!(faces[0].mean_unit_normal()[2] < -0.999 && faces[1].mean_unit_normal()[2] > 0.999);
        assert!((faces[2].area_cm2 - polygon).abs() < 1e-12);
    }
}
