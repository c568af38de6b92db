use super::*;
use std::collections::HashMap;

/// xorshift64*: deterministic test randomness without a dependency.
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn in_box(&mut self, half_width: f64) -> Vec3 {
        Vec3::new(self.unit(), self.unit(), self.unit()).map(|c| (2.0 * c - 1.0) * half_width)
    }
}

/// Outward-wound icosphere of `radius` around `center`, label 2.
fn icosphere(subdivisions: usize, radius: f64, center: Vec3) -> TriMesh {
    let g = (1.0 + 5f64.sqrt()) / 2.0;
    let mut points: Vec<Vec3> = [
        (-1.0, g, 0.0),
        (1.0, g, 0.0),
        (-1.0, -g, 0.0),
        (1.0, -g, 0.0),
        (0.0, -1.0, g),
        (0.0, 1.0, g),
        (0.0, -1.0, -g),
        (0.0, 1.0, -g),
        (g, 0.0, -1.0),
        (g, 0.0, 1.0),
        (-g, 0.0, -1.0),
        (-g, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoint: HashMap<(u32, u32), u32> = HashMap::new();
        let mut mid = |a: u32, b: u32, points: &mut Vec<Vec3>| {
            *midpoint
                .entry(crate::geometry::mesh::edge_key(a, b))
                .or_insert_with(|| {
                    points.push((points[a as usize] + points[b as usize]).normalize());
                    points.len() as u32 - 1
                })
        };
        let mut finer = Vec::with_capacity(triangles.len() * 4);
        for [a, b, c] in triangles {
            let (ab, bc, ca) = (
                mid(a, b, &mut points),
                mid(b, c, &mut points),
                mid(c, a, &mut points),
            );
            finer.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = finer;
    }
    let points = points.into_iter().map(|p| center + radius * p).collect();
    let n = triangles.len();
    TriMesh::new(points, triangles, vec![2; n])
}

fn merged(a: &TriMesh, b: &TriMesh) -> TriMesh {
    let offset = a.points.len() as u32;
    let mut out = a.clone();
    out.points.extend(&b.points);
    out.triangles
        .extend(b.triangles.iter().map(|t| t.map(|i| i + offset)));
    out.face_ids.extend(&b.face_ids);
    out
}

fn brute_force_closest(mesh: &TriMesh, q: &Vec3, accept: impl Fn(u32) -> bool) -> Option<f64> {
    (0..mesh.triangles.len())
        .filter(|&t| accept(t as u32))
        .map(|t| (closest_point_on_triangle(q, &mesh.triangle_points(t)).0 - q).norm())
        .min_by(f64::total_cmp)
}

#[test]
fn closest_point_matches_brute_force_on_a_sphere() {
    let mut mesh = icosphere(3, 10.0, Vec3::new(1.0, -2.0, 3.0));
    for t in 0..mesh.triangles.len() {
        mesh.face_ids[t] = if mesh.triangle_points(t)[0].z > 3.0 {
            10
        } else {
            2
        };
    }
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    for _ in 0..300 {
        let q = Vec3::new(1.0, -2.0, 3.0) + rng.in_box(15.0);
        let hit = bvh.closest_point(&mesh, q).unwrap();
        let expected = brute_force_closest(&mesh, &q, |_| true).unwrap();
        assert!(
            (hit.distance_mm - expected).abs() < 1e-12,
            "q {q:?}: bvh {} brute {expected}",
            hit.distance_mm
        );
        let [a, b, c] = mesh.triangle_points(hit.triangle as usize);
        let rebuilt = hit.barycentric[0] * a + hit.barycentric[1] * b + hit.barycentric[2] * c;
        assert!((rebuilt - hit.point).norm() < 1e-9);
        assert!(((hit.point - q).norm() - hit.distance_mm).abs() < 1e-12);

        let is_baffle = |t: u32| mesh.face_ids[t as usize] == 10;
        let filtered = bvh.closest_point_filtered(&mesh, q, is_baffle).unwrap();
        assert!(is_baffle(filtered.triangle));
        let expected_filtered = brute_force_closest(&mesh, &q, is_baffle).unwrap();
        assert!((filtered.distance_mm - expected_filtered).abs() < 1e-12);

        let limit_mm = 2.0;
        let within = bvh.closest_point_within(&mesh, q, limit_mm);
        assert_eq!(
            within.is_some(),
            expected <= limit_mm,
            "q {q:?} at {expected} mm"
        );
        if let Some(w) = within {
            assert!((w.distance_mm - expected).abs() < 1e-12);
        }
    }
}

#[test]
fn ray_cast_and_box_query_match_brute_force() {
    let mesh = merged(
        &icosphere(2, 5.0, Vec3::zeros()),
        &icosphere(2, 3.0, Vec3::new(9.0, 0.5, 0.0)),
    );
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let mut rng = Rng(42);
    for _ in 0..200 {
        let origin = rng.in_box(12.0);
        let dir = rng.in_box(1.0);
        let expected = (0..mesh.triangles.len())
            .filter_map(|t| ray_triangle(&origin, &dir, &mesh.triangle_points(t)))
            .min_by(f64::total_cmp);
        let got = bvh.ray_cast(&mesh, origin, dir).map(|(t, _)| t);
        assert_eq!(got, expected, "ray from {origin:?} along {dir:?}");

        let centre = rng.in_box(10.0);
        let query = Aabb {
            min: centre,
            max: centre + Vec3::repeat(2.0),
        };
        let mut found = Vec::new();
        bvh.triangles_overlapping_box(&mesh, &query, |t| found.push(t));
        found.sort_unstable();
        let brute: Vec<u32> = (0..mesh.triangles.len() as u32)
            .filter(|&t| Aabb::of_triangle(&mesh.triangle_points(t as usize)).overlaps(&query))
            .collect();
        assert_eq!(found, brute);
    }
    assert_eq!(bvh.ray_cast(&mesh, Vec3::zeros(), Vec3::zeros()), None);
}

#[test]
fn clean_sphere_has_no_self_intersections() {
    let mesh = icosphere(4, 30.0, Vec3::new(5.0, 5.0, 5.0));
    let bvh = TriangleBvh::new(&mesh).unwrap();
    assert_eq!(bvh.self_intersections(&mesh, |_, _| true), vec![]);
    assert_eq!(bvh.self_intersections_par(&mesh, |_, _| true), vec![]);
}

#[test]
fn interpenetrating_spheres_intersect_only_across_spheres() {
    let first = icosphere(3, 10.0, Vec3::zeros());
    let second = icosphere(3, 10.0, Vec3::new(12.0, 1.0, -0.5));
    let mesh = merged(&first, &second);
    let split = first.triangles.len() as u32;
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let pairs = bvh.self_intersections(&mesh, |_, _| true);
    assert!(
        pairs.len() > 10,
        "expected a ring of crossings, got {}",
        pairs.len()
    );
    assert!(
        pairs.iter().all(|&(i, j)| i < split && j >= split),
        "{pairs:?}"
    );
    assert_eq!(bvh.self_intersections_par(&mesh, |_, _| true), pairs);
    // The filter can skip every pair.
    assert!(bvh
        .self_intersections(&mesh, |i, j| (i < split) == (j < split))
        .is_empty());
}

#[test]
fn folded_edge_pair_intersects_and_open_hinge_does_not() {
    let points = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.5, 1.0, 0.0),
        Vec3::new(0.3, 0.7, 0.0), // folded back onto the first triangle
        Vec3::new(0.5, -1.0, 0.2),
    ];
    let folded = TriMesh::new(points.clone(), vec![[0, 1, 2], [1, 0, 3]], vec![2; 2]);
    let bvh = TriangleBvh::new(&folded).unwrap();
    assert_eq!(bvh.self_intersections(&folded, |_, _| true), vec![(0, 1)]);
    let hinge = TriMesh::new(points, vec![[0, 1, 2], [1, 0, 4]], vec![2; 2]);
    let bvh = TriangleBvh::new(&hinge).unwrap();
    assert!(bvh.self_intersections(&hinge, |_, _| true).is_empty());
}

/// A fan of `n` triangles around a centre at height `apex_height_mm` above its rim.
fn fan(n: u32, apex_height_mm: f64) -> TriMesh {
    let mut points = vec![Vec3::new(0.0, 0.0, apex_height_mm)];
    for k in 0..n {
        let a = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
        points.push(Vec3::new(a.cos(), a.sin(), 0.0));
    }
    let triangles = (0..n).map(|k| [0, 1 + k, 1 + (k + 1) % n]).collect();
    TriMesh::new(points, triangles, vec![2; n as usize])
}

#[test]
fn fans_around_a_vertex_do_not_self_intersect() {
    for (n, height) in [(6, 0.0), (17, 0.0), (12, 0.4), (40, -2.0), (5, 1e-7)] {
        let mesh = fan(n, height);
        let bvh = TriangleBvh::new(&mesh).unwrap();
        assert!(
            bvh.self_intersections(&mesh, |_, _| true).is_empty(),
            "fan of {n} at height {height}"
        );
    }
}

#[test]
fn overlapping_coplanar_fan_is_reported() {
    // Two wedges at the same centre covering the same angle, sharing only the centre.
    let points = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(1.0, 0.3, 0.0),
        Vec3::new(-0.2, 1.0, 0.0),
    ];
    let mesh = TriMesh::new(points, vec![[0, 1, 2], [0, 3, 4]], vec![2; 2]);
    let bvh = TriangleBvh::new(&mesh).unwrap();
    assert_eq!(bvh.self_intersections(&mesh, |_, _| true), vec![(0, 1)]);
}

/// Flat 4x4 grid of unit cells at z = 0 with its centre point raised to `bump_mm`,
/// and a tent whose base copies the grid's rim points bit-for-bit.
fn grid_and_tent(bump_mm: f64, tent_height_mm: f64) -> (TriMesh, TriMesh) {
    let index = |i: u32, j: u32| i * 5 + j;
    let mut points = Vec::new();
    for i in 0..5 {
        for j in 0..5 {
            let z = if (i, j) == (2, 2) { bump_mm } else { 0.0 };
            points.push(Vec3::new(i as f64, j as f64, z));
        }
    }
    let mut triangles = Vec::new();
    for i in 0..4 {
        for j in 0..4 {
            triangles.push([index(i, j), index(i + 1, j), index(i + 1, j + 1)]);
            triangles.push([index(i, j), index(i + 1, j + 1), index(i, j + 1)]);
        }
    }
    let n = triangles.len();
    let grid = TriMesh::new(points.clone(), triangles, vec![2; n]);
    let rim: Vec<u32> = (0..4)
        .map(|j| index(0, j))
        .chain((0..4).map(|i| index(i, 4)))
        .chain((0..4).map(|j| index(4, 4 - j)))
        .chain((0..4).map(|i| index(4 - i, 0)))
        .collect();
    let mut tent_points: Vec<Vec3> = rim.iter().map(|&p| points[p as usize]).collect();
    tent_points.push(Vec3::new(2.0, 2.0, tent_height_mm));
    let apex = rim.len() as u32;
    let tent_triangles: Vec<[u32; 3]> = (0..apex).map(|k| [k, (k + 1) % apex, apex]).collect();
    let m = tent_triangles.len();
    (grid, TriMesh::new(tent_points, tent_triangles, vec![10; m]))
}

#[test]
fn tent_sharing_rim_points_touches_but_does_not_intersect() {
    let (grid, tent) = grid_and_tent(0.0, 1.0);
    let bvh = TriangleBvh::new(&grid).unwrap();
    assert!(bvh.intersects_mesh(&grid, &tent).is_empty());
}

#[test]
fn bump_through_tent_is_found() {
    let (grid, tent) = grid_and_tent(2.0, 1.0);
    let bvh = TriangleBvh::new(&grid).unwrap();
    let pairs = bvh.intersects_mesh(&grid, &tent);
    assert!(!pairs.is_empty());
    let centre = 12; // grid point (2, 2)
    for (g, _) in &pairs {
        assert!(
            grid.triangles[*g as usize].contains(&centre),
            "grid triangle {g} is away from the bump"
        );
    }
}

#[test]
fn flat_tent_lying_on_the_grid_is_found() {
    let (grid, tent) = grid_and_tent(0.0, 0.0);
    let bvh = TriangleBvh::new(&grid).unwrap();
    assert!(!bvh.intersects_mesh(&grid, &tent).is_empty());
}

#[test]
fn bad_meshes_are_rejected_and_empty_ones_answer_none() {
    let mut mesh = icosphere(0, 1.0, Vec3::zeros());
    mesh.triangles[7][1] = 99;
    let err = TriangleBvh::new(&mesh).unwrap_err();
    assert!(
        err.contains("triangle 7") && err.contains("point 99"),
        "{err}"
    );
    let mut mesh = icosphere(0, 1.0, Vec3::zeros());
    mesh.points[3].x = f64::NAN;
    assert!(TriangleBvh::new(&mesh).unwrap_err().contains("point 3"));

    let empty = TriMesh::default();
    let bvh = TriangleBvh::new(&empty).unwrap();
    assert_eq!(bvh.closest_point(&empty, Vec3::zeros()), None);
    assert_eq!(bvh.ray_cast(&empty, Vec3::zeros(), Vec3::x()), None);
    assert!(bvh.self_intersections(&empty, |_, _| true).is_empty());
}

#[test]
fn tree_is_balanced_enough_for_a_large_sphere() {
    let mesh = icosphere(5, 40.0, Vec3::zeros()); // 20480 triangles
    let started = std::time::Instant::now();
    let bvh = TriangleBvh::new(&mesh).unwrap();
    let build = started.elapsed();
    // Every triangle sits in exactly one leaf.
    let mut seen = vec![0u32; mesh.triangles.len()];
    for node in bvh.nodes.iter().filter(|n| n.is_leaf()) {
        for &t in bvh.leaf_triangles(node) {
            seen[t as usize] += 1;
        }
    }
    assert!(seen.iter().all(|&c| c == 1));
    let (serial, parallel) = timed_self_intersections("sphere", &mesh, &bvh, build);
    assert!(serial.is_empty() && parallel.is_empty());
}

/// Serial and parallel self-intersection pairs, with their times printed.
fn timed_self_intersections(
    name: &str,
    mesh: &TriMesh,
    bvh: &TriangleBvh,
    build: std::time::Duration,
) -> (Vec<(u32, u32)>, Vec<(u32, u32)>) {
    let started = std::time::Instant::now();
    let serial = bvh.self_intersections(mesh, |_, _| true);
    let serial_time = started.elapsed();
    let started = std::time::Instant::now();
    let parallel = bvh.self_intersections_par(mesh, |_, _| true);
    println!(
        "{name}: {} triangles, {} nodes: build {build:?}, self-intersections serial {serial_time:?}, parallel {:?}",
        mesh.triangles.len(),
        bvh.node_count(),
        started.elapsed()
    );
    (serial, parallel)
}

fn data_dir() -> Option<std::path::PathBuf> {
    baffle_test_support::reference_data::reference_data_if_present()
}

#[test]
fn patient_capped_ventricles_do_not_self_intersect() {
    let Some(dir) = data_dir() else { return };
    for patient in ["p2", "p3"] {
        let path = dir.join(patient).join("design_input/capped_ventricle.vtp");
        let mesh = crate::io::read_surface(&path).unwrap();
        let started = std::time::Instant::now();
        let bvh = TriangleBvh::new(&mesh).unwrap();
        let build = started.elapsed();
        let (serial, parallel) = timed_self_intersections(patient, &mesh, &bvh, build);
        assert!(
            serial.is_empty(),
            "{patient}: intersecting triangle pairs {:?}",
            &serial[..serial.len().min(10)]
        );
        assert_eq!(serial, parallel);

        // The caps and the wall meet along rims whose points both copies keep
        // bit-for-bit: touching there is not an intersection.
        let is_wall: Vec<bool> = mesh.face_ids.iter().map(|&f| f == 2).collect();
        let is_cap: Vec<bool> = is_wall.iter().map(|w| !w).collect();
        let (wall, _) = mesh.submesh(&is_wall);
        let (caps, _) = mesh.submesh(&is_cap);
        assert!(!caps.triangles.is_empty(), "{patient}: no cap triangles");
        let wall_bvh = TriangleBvh::new(&wall).unwrap();
        let crossings = wall_bvh.intersects_mesh(&wall, &caps);
        assert!(
            crossings.is_empty(),
            "{patient}: wall/cap crossings {:?}",
            &crossings[..crossings.len().min(10)]
        );
    }
}

#[test]
fn winding_number_is_one_inside_an_outward_tetrahedron_and_zero_outside() {
    let points = vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 0.0, 1.0)];
    let outward = TriMesh::new(points, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], vec![1; 4]);
    assert!((winding_number(&outward, Vec3::new(0.2, 0.2, 0.2)) - 1.0).abs() < 1e-12);
    assert!(winding_number(&outward, Vec3::new(1.0, 1.0, 1.0)).abs() < 1e-12);
    let inward = TriMesh::new(outward.points.clone(), outward.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect(), vec![1; 4]);
    assert!((winding_number(&inward, Vec3::new(0.2, 0.2, 0.2)) + 1.0).abs() < 1e-12);
}
