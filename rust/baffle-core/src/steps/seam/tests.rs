//! Tests of the seam: projection, tracing and insertion on a box made of small triangles.
use super::*;
use crate::geometry::mesh::edge_key;
use crate::geometry::mesh::manifold_report;
use std::collections::HashSet;

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
    let seam = project_seam(WallProjector::new(&mesh, &bvh, &labels, 2.0), &pts, 200).unwrap();
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
    let seam = project_seam(WallProjector::new(&mesh, &bvh, &labels, 2.0), &pts, 300).unwrap();
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
    let projector = WallProjector { surface: &mesh, bvh: &bvh, labels: &labels, max_rim_shift_mm: 2.0 };
    let samples: Vec<ClosestHit> = (0..200)
        .map(|k| {
            let a = k as f64 / 200.0 * std::f64::consts::TAU;
            projector.project(Vec3::new(2.0 + 1.5 * a.sin(), 2.0 + 1.2 * a.sin() * a.cos(), 4.0), k).unwrap()
        })
        .collect();
    let tracer = PathTracer { projector, neighbors: mesh.triangle_neighbors(), wall: OnceCell::new() };
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
    let e = project_seam(WallProjector::new(&mesh, &bvh, &labels, 2.0), &three, 100).unwrap_err();
    assert!(e.to_string().contains("at least 4"), "{e}");
    let mut far = three.clone();
    far.push(Vec3::new(1., 2., 7.5));
    let e = project_seam(WallProjector::new(&mesh, &bvh, &labels, 2.0), &far, 100).unwrap_err();
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
    let err = project_seam(WallProjector::new(&mesh, &bvh, &labels, 2.0), &pts, 200)
        .and_then(|s| imprint_seam(&mesh, &s).map(|_| ()))
        .unwrap_err();
    assert!(err.to_string().contains("VSD cap"), "{err}");
}

/// Label as VSD cap (11) every triangle whose centroid satisfies `inside`.
fn with_cap(mut mesh: TriMesh, inside: impl Fn(Vec3) -> bool) -> TriMesh {
    for t in 0..mesh.triangles.len() {
        let [a, b, c] = mesh.triangle_points(t);
        if inside((a + b + c) / 3.0) {
            mesh.face_ids[t] = 11;
        }
    }
    mesh
}

/// Eight points on a circle of radius 1.5 around (cx, 2) on the top face, offset by
/// half a spacing so the leftmost point of the circle lies between two of them.
fn octagon_on_top(cx: f64) -> Vec<Vec3> {
    (0..8)
        .map(|k| {
            let a = (k as f64 + 0.5) / 8.0 * std::f64::consts::TAU;
            Vec3::new(cx + 1.5 * a.cos(), 2.0 + 1.5 * a.sin(), 4.0)
        })
        .collect()
}

#[test]
fn a_seam_bulging_over_a_cap_rim_follows_the_rim() {
    // Cap: the top face's strip x < 1. The points stay on the wall (leftmost at x =
    // 1.014), the spline between the two leftmost bulges to x = 0.9, 0.1 mm over the cap.
    let mesh = with_cap(grid_box(8), |c| (c.z - 4.0).abs() < 1e-9 && c.x < 1.0);
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let labels = FaceLabels::default();
    let points = octagon_on_top(2.4);
    let seam = project_seam(WallProjector::new(&mesh, &bvh, &labels, 2.0), &points, 200).unwrap();
    let leftmost = seam.path.iter().map(|p| p.position_mm.x).fold(f64::INFINITY, f64::min);
    assert!((leftmost - 1.0).abs() < 1e-9, "the seam runs along the rim x = 1, not {leftmost}");
    let imprinted = imprint_seam(&mesh, &seam).unwrap();
    assert!(manifold_report(&imprinted.mesh).is_closed_manifold());
    // With a tolerance below the bulge the same points are refused, and the distance named.
    let err = project_seam(WallProjector::new(&mesh, &bvh, &labels, 0.08), &points, 200).unwrap_err().to_string();
    assert!(err.contains("crosses the VSD cap") && err.contains("inside its rim"), "{err}");
}

#[test]
fn a_suture_point_on_a_cap_rim_is_on_the_wall() {
    let mesh = with_cap(grid_box(8), |c| (c.z - 4.0).abs() < 1e-9 && c.x < 1.0);
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let mut points = octagon_on_top(2.5);
    points[3] = Vec3::new(1.0, 2.3, 4.0);
    project_seam(WallProjector::new(&mesh, &bvh, &FaceLabels::default(), 2.0), &points, 200).unwrap();
}

#[test]
fn a_seam_across_a_cap_band_is_refused_by_name() {
    // A 0.5 mm band x in [1.75, 2.25] over the top and down both sides y = 0 and y = 4:
    // the seam cannot go around it, and its spline is only 0.25 mm deep in it.
    let mesh = with_cap(grid_box(16), |c| (c.x - 2.0).abs() < 0.25 && (c.z > 3.99 || c.y < 1e-9 || c.y > 4.0 - 1e-9));
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let points: Vec<Vec3> = octagon_on_top(2.0).into_iter().filter(|p| (p.x - 2.0).abs() > 0.3).collect();
    let err = project_seam(WallProjector::new(&mesh, &bvh, &FaceLabels::default(), 2.0), &points, 200).unwrap_err().to_string();
    assert!(err.contains("crosses the VSD cap") && err.contains("leaves it on another"), "{err}");
}

/// The box squashed to a 4 x 4 x 0.2 mm slab: its top and bottom are 0.2 mm apart
/// in space and at least 4 mm apart along the surface.
fn slab() -> TriMesh {
    let mut mesh = grid_box(8);
    mesh.points.iter_mut().for_each(|p| p.z *= 0.05);
    mesh
}

#[test]
fn a_short_jump_is_walked_along_wall_edges() {
    let mesh = slab();
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let graph = WallGraph::new(&mesh, 2);
    let (a, b) = (
        bvh.closest_point(&mesh, Vec3::new(1.1, 1.2, 0.3)).unwrap(),
        bvh.closest_point(&mesh, Vec3::new(2.1, 1.3, 0.3)).unwrap(),
    );
    let chain = graph.detour(&mesh, &a, &b).unwrap();
    assert!(mesh.triangles[a.triangle as usize].contains(&chain[0]));
    assert!(mesh.triangles[b.triangle as usize].contains(chain.last().unwrap()));
    let edges: HashSet<(u32, u32)> =
        mesh.triangles.iter().flat_map(|t| (0..3).map(move |k| edge_key(t[k], t[(k + 1) % 3]))).collect();
    assert!(
        chain.windows(2).all(|w| edges.contains(&edge_key(w[0], w[1]))),
        "consecutive chain vertices share an edge"
    );
    let walk: f64 = chain.windows(2).map(|w| (mesh.points[w[0] as usize] - mesh.points[w[1] as usize]).norm()).sum();
    assert!(walk < 2.0, "walk {walk}");
}

#[test]
fn a_jump_through_a_thin_fold_is_refused_with_its_way_round() {
    let mesh = slab();
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let (top, bottom) = (
        bvh.closest_point(&mesh, Vec3::new(2.1, 2.2, 0.3)).unwrap(),
        bvh.closest_point(&mesh, Vec3::new(2.1, 2.2, -0.1)).unwrap(),
    );
    let walk_mm = WallGraph::new(&mesh, 2).detour(&mesh, &top, &bottom).unwrap_err();
    assert!(walk_mm > 3.0, "the way round the slab's rim is at least 4 mm, not {walk_mm}");
}

/// Jittered points on a thin loop bent round a 115-degree, 20 mm radius tunnel with 4 mm
/// caps: in their best-fit plane the loop is not star-shaped.
fn thin_bent_loop() -> crate::phantom::PhantomParams {
    crate::phantom::PhantomParams {
        bend_radius_mm: 19.85,
        sweep_angle_deg: 115.24,
        vsd_semi_axes_mm: (4.01, 3.37),
        aortic_semi_axes_mm: (4.02, 3.20),
        suture_point_count: 12,
        suture_rim_margin_mm: 2.22,
        suture_half_angle_deg: 65.48,
        suture_jitter_fraction: 0.1304,
        suture_jitter_seed: 5179611965503769330,
        ..Default::default()
    }
}

#[test]
fn the_given_order_is_tried_where_the_angle_order_zigzags_into_a_crossing_seam() {
    let phantom = crate::phantom::phantom(&thin_bent_loop());
    let (surface, points) = (&phantom.surface, &phantom.suture_points_mm);
    let bvh = TriangleBvh::new(surface).unwrap();
    let labels = FaceLabels::default();
    assert!(!is_rotation_or_reversal(points, &order_by_pca_angle(points)), "the angle order should zigzag on this loop");
    let by_angle = project_seam(WallProjector::new(surface, &bvh, &labels, 2.0), points, 600).and_then(|p| imprint_seam(surface, &p));
    assert!(matches!(by_angle, Err(DesignError::Seam(ref why)) if why.contains("crosses itself")), "{:?}", by_angle.err());
    let (projected, _) = seam_on_wall(WallProjector::new(surface, &bvh, &labels, 2.0), points, 600).unwrap();
    assert_eq!(projected.ordered_points_mm, *points);
    let target = crate::TargetArea::AreaMm2(30.0);
    let designed = crate::design(surface, points, &target, &Default::default(), &mut |_, _| true).unwrap();
    assert!(designed.report.min_constrained_final_area_mm2 >= 30.0);
    // Points clicked in any order: the angle order, the paper's, whenever its seam holds.
    let round: Vec<Vec3> = (0..12).map(|k| (k as f64 * std::f64::consts::TAU / 12.0).sin_cos()).map(|(s, c)| Vec3::new(10.0 * c, 6.0 * s, 0.1 * s * c)).collect();
    let rotated: Vec<Vec3> = round.iter().cycle().skip(5).take(12).copied().collect();
    assert!(is_rotation_or_reversal(&round, &rotated) && is_rotation_or_reversal(&round, &rotated.iter().rev().copied().collect::<Vec<_>>()));
    assert!(!is_rotation_or_reversal(&round, &[&round[1..], &round[..1]].concat().iter().rev().skip(1).copied().collect::<Vec<_>>()));
}
