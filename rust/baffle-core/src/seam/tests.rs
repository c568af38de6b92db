//! Tests of the seam: projection, tracing and insertion on a box made of small triangles.
use super::*;
use crate::mesh::edge_key;
use std::collections::HashSet;
use crate::mesh::manifold_report;

/// A closed box [0,4]^3 made of small right triangles, all labelled wall.
fn grid_box(n: usize) -> TriMesh {
    let mut m = TriMesh::default();
    let s = 4.0 / n as f64;
    // Six faces, each an (n+1)^2 grid; duplicates merged by a coordinate map.
    let mut index = std::collections::HashMap::new();
    let mut vid = |m: &mut TriMesh, p: Vec3| -> u32 {
        let key = ((p.x * 1e6).round() as i64, (p.y * 1e6).round() as i64, (p.z * 1e6).round() as i64);
        *index.entry(key).or_insert_with(|| {
            m.points.push(p);
            (m.points.len() - 1) as u32
        })
    };
    let faces: [(Vec3, Vec3, Vec3); 6] = [
        (Vec3::new(0., 0., 0.), Vec3::new(0., 1., 0.), Vec3::new(1., 0., 0.)),
        (Vec3::new(0., 0., 4.), Vec3::new(1., 0., 0.), Vec3::new(0., 1., 0.)),
        (Vec3::new(0., 0., 0.), Vec3::new(1., 0., 0.), Vec3::new(0., 0., 1.)),
        (Vec3::new(0., 4., 0.), Vec3::new(0., 0., 1.), Vec3::new(1., 0., 0.)),
        (Vec3::new(0., 0., 0.), Vec3::new(0., 0., 1.), Vec3::new(0., 1., 0.)),
        (Vec3::new(4., 0., 0.), Vec3::new(0., 1., 0.), Vec3::new(0., 0., 1.)),
    ];
    for (o, u, v) in faces {
        for i in 0..n {
            for j in 0..n {
                let p = |a: usize, b: usize| o + u * (a as f64 * s) + v * (b as f64 * s);
                let q = [p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)].map(|x| vid(&mut m, x));
                m.triangles.push([q[0], q[1], q[2]]);
                m.triangles.push([q[0], q[2], q[3]]);
            }
        }
    }
    m.face_ids = vec![2; m.triangles.len()];
    m
}

#[test]
fn seam_on_a_box_face_is_an_exact_edge_loop() {
    let mesh = grid_box(8);
    assert!(manifold_report(&mesh).is_closed_manifold());
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let labels = FaceLabels::default();
    // A loop on the top face z = 4 around (2, 2).
    let pts: Vec<Vec3> = (0..12)
        .map(|k| {
            let a = k as f64 / 12.0 * std::f64::consts::TAU;
            Vec3::new(2.0 + 1.3 * a.cos(), 2.0 + 1.1 * a.sin(), 4.0)
        })
        .collect();
    let seam = project_seam(&mesh, &bvh, &labels, &pts, 200, 2.0).unwrap();
    let imprinted = imprint_seam(&mesh, &seam).unwrap();
    let rep = manifold_report(&imprinted.mesh);
    assert!(rep.is_closed_manifold(), "{rep:?}");
    assert_eq!(rep.inconsistently_wound_edges, 0);
    assert!((imprinted.mesh.signed_volume_mm3() - mesh.signed_volume_mm3()).abs() < 1e-9);
    // Consecutive loop vertices are joined by mesh edges, and the loop is simple.
    let edges = imprinted.mesh.edge_triangles();
    let lp = &imprinted.loop_vertices;
    for i in 0..lp.len() {
        let e = edge_key(lp[i], lp[(i + 1) % lp.len()]);
        assert_eq!(edges.get(&e).map(|v| v.len()), Some(2), "seam edge {e:?} missing");
    }
    let distinct: HashSet<u32> = lp.iter().copied().collect();
    assert_eq!(distinct.len(), lp.len());
    // Every seam vertex is on the top face.
    for &v in lp {
        assert!((imprinted.mesh.points[v as usize].z - 4.0).abs() < 1e-12);
    }
}

#[test]
fn seam_over_a_box_edge_is_traced() {
    let mesh = grid_box(8);
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let labels = FaceLabels::default();
    // A loop that wraps over the edge between the top (z=4) and the side x=4.
    let pts: Vec<Vec3> = (0..14)
        .map(|k| {
            let a = k as f64 / 14.0 * std::f64::consts::TAU;
            let (s, t) = (1.5 * a.cos(), 1.2 * a.sin());
            // Unfold: s>0 goes down the side x=4, s<0 stays on top.
            if s >= 0.0 {
                Vec3::new(4.0, 2.0 + t, 4.0 - s)
            } else {
                Vec3::new(4.0 + s, 2.0 + t, 4.0)
            }
        })
        .collect();
    let seam = project_seam(&mesh, &bvh, &labels, &pts, 300, 2.0).unwrap();
    let imprinted = imprint_seam(&mesh, &seam).unwrap();
    assert!(manifold_report(&imprinted.mesh).is_closed_manifold());
    assert!(imprinted.loop_vertices.len() >= 300);
}

#[test]
fn a_seam_that_crosses_itself_is_rejected() {
    // A figure eight on the top face, traced without the angle ordering.
    let mesh = grid_box(8);
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let labels = FaceLabels::default();
    let projector = WallProjector { surface: &mesh, bvh: &bvh, labels: &labels };
    let samples: Vec<ClosestHit> = (0..200)
        .map(|k| {
            let a = k as f64 / 200.0 * std::f64::consts::TAU;
            projector.project(Vec3::new(2.0 + 1.5 * a.sin(), 2.0 + 1.2 * a.sin() * a.cos(), 4.0), k).unwrap()
        })
        .collect();
    let tracer = PathTracer { projector, neighbors: mesh.triangle_neighbors() };
    let (path, samples_mm) = tracer.trace_closed(&samples).unwrap();
    let seam = ProjectedSeam { ordered_points_mm: Vec::new(), samples_mm, path };
    let err = imprint_seam(&mesh, &seam).unwrap_err();
    assert!(err.to_string().contains("crosses itself"), "{err}");
}

#[test]
fn too_few_or_far_points_are_named() {
    let mesh = grid_box(4);
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let labels = FaceLabels::default();
    let three = vec![Vec3::new(1., 1., 4.), Vec3::new(2., 1., 4.), Vec3::new(2., 2., 4.)];
    let e = project_seam(&mesh, &bvh, &labels, &three, 100, 2.0).unwrap_err();
    assert!(e.to_string().contains("at least 4"), "{e}");
    let mut far = three.clone();
    far.push(Vec3::new(1., 2., 7.5));
    let e = project_seam(&mesh, &bvh, &labels, &far, 100, 2.0).unwrap_err();
    assert!(e.to_string().contains("point 4") && e.to_string().contains("3.50 mm"), "{e}");
}

#[test]
fn seam_across_a_cap_is_rejected() {
    let mut mesh = grid_box(8);
    // Label the triangles of the top face with x in [1.5, 2.5] as a cap.
    for t in 0..mesh.triangles.len() {
        let [a, b, c] = mesh.triangle_points(t);
        let cen = (a + b + c) / 3.0;
        if (cen.z - 4.0).abs() < 1e-9 && (cen.x - 2.0).abs() < 0.5 {
            mesh.face_ids[t] = 11;
        }
    }
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let pts: Vec<Vec3> = (0..12)
        .map(|k| {
            let a = k as f64 / 12.0 * std::f64::consts::TAU;
            Vec3::new(2.0 + 1.5 * a.cos(), 2.0 + 1.5 * a.sin(), 4.0)
        })
        .collect();
    let labels = FaceLabels::default();
    let err = project_seam(&mesh, &bvh, &labels, &pts, 200, 2.0)
        .and_then(|s| imprint_seam(&mesh, &s).map(|_| ()))
        .unwrap_err();
    assert!(err.to_string().contains("VSD cap"), "{err}");
}
