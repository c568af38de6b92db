//! Remeshing tests on meshes built here: a sliver-ridden open hemisphere with a
//! seam-like boundary of ~0.1 mm edges, and a cylinder with a labelled end cap.

use super::*;
use crate::geometry::mesh::{manifold_report, TriMesh, Vec3};
use std::collections::HashSet;
use std::f64::consts::PI;

/// Deterministic pseudo-random numbers in [0, 1) (xorshift), so tests are repeatable.
struct Jitter(u64);

impl Jitter {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A ring of points: point indices and their (unwrapped, increasing) angles.
struct Ring {
    ids: Vec<u32>,
    angles: Vec<f64>,
}

fn push_ring(points: &mut Vec<Vec3>, n: usize, jitter: Option<&mut Jitter>, at: impl Fn(f64) -> Vec3) -> Ring {
    let mut offsets = vec![0.0; n];
    if let Some(j) = jitter {
        offsets.iter_mut().for_each(|o| *o = 0.6 * (j.next() - 0.5));
    }
    let angles: Vec<f64> = (0..n).map(|i| 2.0 * PI * (i as f64 + offsets[i]) / n as f64).collect();
    let ids = angles
        .iter()
        .map(|&phi| {
            points.push(at(phi));
            (points.len() - 1) as u32
        })
        .collect();
    Ring { ids, angles }
}

/// Triangulate the band between an upper/inner ring and a lower/outer ring by
/// merging them in angle order; winding is outward for rings that run
/// counter-clockwise seen from outside. Unequal counts make slivers on purpose.
fn zip_rings(upper: &Ring, lower: &Ring, label: i32, tris: &mut Vec<[u32; 3]>, ids: &mut Vec<i32>) {
    let (nu, nl) = (upper.ids.len(), lower.ids.len());
    let angle = |r: &Ring, i: usize| r.angles[i % r.ids.len()] + if i >= r.ids.len() { 2.0 * PI } else { 0.0 };
    let (mut i, mut j) = (0, 0);
    while i < nu || j < nl {
        let advance_lower = j < nl && (i == nu || angle(lower, j + 1) <= angle(upper, i + 1));
        let (u, l) = (upper.ids[i % nu], lower.ids[j % nl]);
        if advance_lower {
            tris.push([u, l, lower.ids[(j + 1) % nl]]);
            j += 1;
        } else {
            tris.push([u, l, upper.ids[(i + 1) % nu]]);
            i += 1;
        }
        ids.push(label);
    }
}

fn fan(centre: u32, ring: &Ring, label: i32, tris: &mut Vec<[u32; 3]>, ids: &mut Vec<i32>) {
    let n = ring.ids.len();
    for k in 0..n {
        tris.push([centre, ring.ids[k], ring.ids[(k + 1) % n]]);
        ids.push(label);
    }
}

/// Open hemisphere (z >= 0) of radius `r`: lat-long rows with irregular point
/// counts and jittered angles (thin triangles at the pole and between rows),
/// and an equator boundary ring of ~`seam_mm` edges like the cut seam.
fn sliver_hemisphere(r: f64, rows: usize, seam_mm: f64, seed: u64) -> TriMesh {
    let mut jitter = Jitter(seed);
    let mut points = vec![Vec3::new(0.0, 0.0, r)];
    let (mut tris, mut ids) = (Vec::new(), Vec::new());
    let mut previous: Option<Ring> = None;
    for row in 1..rows {
        let theta = 0.5 * PI * row as f64 / rows as f64;
        let n = 40 + ((row * 37) % 29) * 3 + (2.0 * PI * r * theta.sin() / (0.7 * r / rows as f64)) as usize / 3;
        let ring = push_ring(&mut points, n, Some(&mut jitter), |phi| {
            r * Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
        });
        match &previous {
            None => fan(0, &ring, 2, &mut tris, &mut ids),
            Some(up) => zip_rings(up, &ring, 2, &mut tris, &mut ids),
        }
        previous = Some(ring);
    }
    let n_seam = (2.0 * PI * r / seam_mm).round() as usize;
    let seam = push_ring(&mut points, n_seam, None, |phi| Vec3::new(r * phi.cos(), r * phi.sin(), 0.0));
    zip_rings(previous.as_ref().unwrap(), &seam, 2, &mut tris, &mut ids);
    TriMesh::new(points, tris, ids)
}

const CYL_R: f64 = 8.0;
const CYL_H: f64 = 10.0;
const RIM_N: usize = 200;

/// Cylinder side (label 2, open at z = 0) with a planar end cap at z = CYL_H
/// (label 11); both finely and irregularly triangulated, sharing a 200-gon rim.
fn capped_cylinder(seed: u64) -> TriMesh {
    let mut jitter = Jitter(seed);
    let mut points = vec![Vec3::new(0.0, 0.0, CYL_H)];
    let (mut tris, mut ids) = (Vec::new(), Vec::new());
    let cap_rings = 20;
    let mut previous: Option<Ring> = None;
    for k in 1..=cap_rings {
        let radius = CYL_R * k as f64 / cap_rings as f64;
        let n = if k == cap_rings { RIM_N } else { 12 + 9 * k + (k * 13) % 7 };
        let jit = (k < cap_rings).then_some(&mut jitter);
        let ring = push_ring(&mut points, n, jit, |phi| Vec3::new(radius * phi.cos(), radius * phi.sin(), CYL_H));
        match &previous {
            None => fan(0, &ring, 11, &mut tris, &mut ids),
            Some(inner) => zip_rings(inner, &ring, 11, &mut tris, &mut ids),
        }
        previous = Some(ring);
    }
    let side_rows = 30;
    for k in 1..=side_rows {
        let z = CYL_H * (1.0 - k as f64 / side_rows as f64);
        let n = 150 + (k * 17) % 60;
        let ring = push_ring(&mut points, n, Some(&mut jitter), |phi| {
            Vec3::new(CYL_R * phi.cos(), CYL_R * phi.sin(), z)
        });
        zip_rings(previous.as_ref().unwrap(), &ring, 2, &mut tris, &mut ids);
        previous = Some(ring);
    }
    TriMesh::new(points, tris, ids)
}

fn opts(target: f64) -> RemeshOptions {
    RemeshOptions { target_edge_mm: target, ..RemeshOptions::default() }
}

fn unique_edge_lengths(m: &TriMesh) -> Vec<f64> {
    let mut lengths: Vec<f64> = m
        .edge_triangles()
        .keys()
        .map(|&(a, b)| (m.points[a as usize] - m.points[b as usize]).norm())
        .collect();
    lengths.sort_by(|a, b| a.total_cmp(b));
    lengths
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

fn min_angles_deg(m: &TriMesh) -> Vec<f64> {
    let mut angles: Vec<f64> = (0..m.triangles.len())
        .map(|t| {
            let p = m.triangle_points(t);
            (0..3)
                .map(|k| {
                    let (u, v) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
                    u.angle(&v).to_degrees()
                })
                .fold(180.0, f64::min)
        })
        .collect();
    angles.sort_by(|a, b| a.total_cmp(b));
    angles
}

fn bits(p: &Vec3) -> [u64; 3] {
    [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]
}

fn boundary_vertices(m: &TriMesh) -> Vec<u32> {
    m.boundary_loops().unwrap().concat()
}

fn assert_clean_open_manifold(m: &TriMesh) {
    let report = manifold_report(m);
    assert_eq!(report.non_manifold_edges, 0, "{report:?}");
    assert_eq!(report.degenerate_triangles, 0, "{report:?}");
    assert_eq!(report.inconsistently_wound_edges, 0, "{report:?}");
    assert_eq!(m.boundary_loops().unwrap().len(), 1);
}

fn label_area(m: &TriMesh, label: i32) -> f64 {
    (0..m.triangles.len()).filter(|&t| m.face_ids[t] == label).map(|t| m.triangle_area_mm2(t)).sum()
}

/// Points that lie on an edge between two different labels.
fn rim_vertices(m: &TriMesh) -> HashSet<u32> {
    m.edge_triangles()
        .iter()
        .filter(|(_, ts)| ts.len() == 2 && m.face_ids[ts[0] as usize] != m.face_ids[ts[1] as usize])
        .flat_map(|(&(a, b), _)| [a, b])
        .collect()
}

fn distance_to_rim_polygon(p: &Vec3) -> f64 {
    (0..RIM_N)
        .map(|k| {
            let at = |i: usize| {
                let phi = 2.0 * PI * (i % RIM_N) as f64 / RIM_N as f64;
                Vec3::new(CYL_R * phi.cos(), CYL_R * phi.sin(), CYL_H)
            };
            (crate::geometry::spatial::closest_point_on_segment(p, &at(k), &at(k + 1)).0 - p).norm()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Does every triangle's normal point away from the solid? Cap (label 11)
/// normals must point up, others away from the z axis (cylinder) or the origin.
fn winding_is_outward(m: &TriMesh, cylinder: bool) -> bool {
    (0..m.triangles.len()).all(|t| {
        let c = m.triangle_points(t).iter().sum::<Vec3>() / 3.0;
        let away = match (m.face_ids[t], cylinder) {
            (11, _) => Vec3::z(),
            (_, true) => Vec3::new(c.x, c.y, 0.0),
            (_, false) => c,
        };
        m.triangle_normal2(t).dot(&away) > 0.0
    })
}

#[test]
fn test_meshes_are_valid_and_outward() {
    let hemisphere = sliver_hemisphere(10.0, 25, 0.1, 7);
    assert_clean_open_manifold(&hemisphere);
    assert!(winding_is_outward(&hemisphere, false));
    let cylinder = capped_cylinder(3);
    assert_clean_open_manifold(&cylinder);
    assert!(winding_is_outward(&cylinder, true));
}

#[test]
fn hemisphere_reaches_target_length_and_keeps_the_seam() {
    let input = sliver_hemisphere(10.0, 25, 0.1, 7);
    let target = 0.85;
    let out = remesh_isotropic(&input, &opts(target)).unwrap();
    assert_clean_open_manifold(&out);

    let lengths = unique_edge_lengths(&out);
    let mean = lengths.iter().sum::<f64>() / lengths.len() as f64;
    let (p5, p95) = (percentile(&lengths, 0.05), percentile(&lengths, 0.95));
    println!("hemisphere: {} -> {} points, mean edge {mean:.3}, p5 {p5:.3}, p95 {p95:.3}", input.points.len(), out.points.len());
    assert!((mean - target).abs() < 0.15 * target, "mean edge {mean}");
    assert!(p5 >= 0.5 * target && p95 <= 1.6 * target, "p5 {p5} p95 {p95}");

    let input_seam: HashSet<[u64; 3]> = boundary_vertices(&input).iter().map(|&v| bits(&input.points[v as usize])).collect();
    assert!(boundary_vertices(&out).iter().all(|&v| input_seam.contains(&bits(&out.points[v as usize]))));

    let worst = out.points.iter().map(|p| (p.norm() - 10.0).abs()).fold(0.0, f64::max);
    assert!(worst < 0.05 * target, "worst distance to sphere {worst}");
    assert!(winding_is_outward(&out, false), "winding flipped");
}

#[test]
fn hemisphere_minimum_angle_improves() {
    let input = sliver_hemisphere(10.0, 25, 0.1, 11);
    let out = remesh_isotropic(&input, &opts(0.85)).unwrap();
    let (before, after) = (min_angles_deg(&input), min_angles_deg(&out));
    let (b1, a1) = (percentile(&before, 0.01), percentile(&after, 0.01));
    println!("1st-percentile minimum angle: before {b1:.2} deg, after {a1:.2} deg (min {:.2} -> {:.2})", before[0], after[0]);
    assert!(a1 > 20.0 && a1 > 5.0 * b1, "before {b1} after {a1}");
}

#[test]
fn cap_rim_and_labels_survive() {
    let input = capped_cylinder(3);
    let out = remesh_isotropic(&input, &opts(0.85)).unwrap();
    assert_clean_open_manifold(&out);

    let rim = rim_vertices(&out);
    assert!(rim.len() > 30, "rim has {} vertices", rim.len());
    for &v in &rim {
        let d = distance_to_rim_polygon(&out.points[v as usize]);
        assert!(d < 1e-9, "rim point {v} is {d} mm off the original rim");
    }
    for label in [2, 11] {
        let (a0, a1) = (label_area(&input, label), label_area(&out, label));
        println!("label {label}: area {a0:.2} -> {a1:.2} mm^2");
        assert!((a1 - a0).abs() < 0.02 * a0, "label {label} area {a0} -> {a1}");
    }
    // No triangle spans the rim: cap triangles stay in the cap plane, wall
    // triangles touch the plane only at rim points.
    for (t, tri) in out.triangles.iter().enumerate() {
        for &v in tri {
            let p = out.points[v as usize];
            let in_plane = (p.z - CYL_H).abs() < 1e-9;
            if out.face_ids[t] == 11 {
                assert!(in_plane, "cap triangle {t} leaves the plane");
            } else if in_plane {
                assert!(distance_to_rim_polygon(&p) < 1e-9, "wall triangle {t} reaches into the cap");
            }
        }
    }
    assert!(winding_is_outward(&out, true), "winding flipped");
}

#[test]
fn boundary_is_split_only_when_allowed() {
    // A coarse seam: 40 edges of ~1.6 mm on a 10 mm hemisphere.
    let input = sliver_hemisphere(10.0, 12, 2.0 * PI * 10.0 / 40.0, 5);
    let target = 0.85;
    let kept = remesh_isotropic(&input, &opts(target)).unwrap();
    assert_eq!(boundary_vertices(&kept).len(), 40);
    let split = RemeshOptions { split_boundary: true, ..opts(target) };
    let out = remesh_isotropic(&input, &split).unwrap();
    assert_clean_open_manifold(&out);
    let seam = out.boundary_loops().unwrap().remove(0);
    assert!(seam.len() > 60, "seam has {} points", seam.len());
    for k in 0..seam.len() {
        let (a, b) = (out.points[seam[k] as usize], out.points[seam[(k + 1) % seam.len()] as usize]);
        assert!((a - b).norm() <= 4.0 / 3.0 * target + 1e-9);
        assert!(a.z.abs() < 1e-12, "split seam point left the seam plane");
    }
}

#[test]
fn bad_input_is_rejected_with_a_named_culprit() {
    let mut mesh = sliver_hemisphere(10.0, 8, 0.5, 1);
    mesh.points[5].y = f64::NAN;
    let err = remesh_isotropic(&mesh, &opts(0.85)).unwrap_err();
    assert!(err.contains("point 5"), "{err}");

    let good = sliver_hemisphere(10.0, 8, 0.5, 1);
    assert!(remesh_isotropic(&good, &opts(0.0)).unwrap_err().contains("target edge"));
    let mut bad_index = good.clone();
    bad_index.triangles[3][1] = 1_000_000;
    assert!(remesh_isotropic(&bad_index, &opts(0.85)).unwrap_err().contains("triangle 3"));
    let mut short_ids = good.clone();
    short_ids.face_ids.pop();
    assert!(remesh_isotropic(&short_ids, &opts(0.85)).unwrap_err().contains("face ids"));
    let mut flipped = good;
    flipped.triangles[0].swap(1, 2);
    assert!(remesh_isotropic(&flipped, &opts(0.85)).unwrap_err().contains("same direction"));
}

#[test]
fn local_operators_keep_a_valid_mesh() {
    // Hexagonal fan in the plane z = 0.
    let mut points = vec![Vec3::zeros()];
    points.extend((0..6).map(|k| {
        let phi = PI / 3.0 * k as f64;
        Vec3::new(phi.cos(), phi.sin(), 0.0)
    }));
    let tris: Vec<[u32; 3]> = (0..6).map(|k| [0, 1 + k, 1 + (k + 1) % 6]).collect();
    let fan_mesh = TriMesh::new(points, tris, vec![2; 6]);
    let area = fan_mesh.area_mm2();
    let check = |he: &HalfEdgeMesh, faces: usize| {
        let m = he.to_trimesh();
        assert_eq!(m.triangles.len(), faces);
        assert_clean_open_manifold(&m);
        assert!((m.area_mm2() - area).abs() < 1e-12);
        assert!((0..m.triangles.len()).all(|t| m.triangle_normal2(t).z > 0.0));
    };
    let mut he = HalfEdgeMesh::from_trimesh(&fan_mesh).unwrap();
    let spoke = (0..18u32).find(|&h| he.origin(h) == 0 && he.target(h) == 2).unwrap();
    let m = he.push_vertex(0.5 * (he.pos[0] + he.pos[2]));
    he.split_edge(spoke, m);
    check(&he, 8);
    let rim_edge = (0..he.corners.len() as u32 * 3).find(|&h| he.origin(h) == 3 && he.target(h) == 4).unwrap();
    let rim_mid = he.push_vertex(0.5 * (he.pos[3] + he.pos[4]));
    he.split_edge(rim_edge, rim_mid);
    check(&he, 9);
    let spoke4 = (0..he.corners.len() as u32 * 3).find(|&h| he.face_alive[face_of(h)] && he.origin(h) == 0 && he.target(h) == 5).unwrap();
    he.flip_edge(spoke4);
    check(&he, 9);
    // Collapse the new midpoint back into the centre.
    let to_centre = (0..he.corners.len() as u32 * 3).find(|&h| he.face_alive[face_of(h)] && he.origin(h) == m && he.target(h) == 0).unwrap();
    let mut ring = Vec::new();
    he.collapse_edge(to_centre, m, &mut ring);
    check(&he, 7);
}

/// CPU time of the calling thread (ns, Linux schedstat); unlike wall time it
/// does not count waiting while other builds share the cores.
fn thread_cpu_ns() -> Option<u64> {
    let stat = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    stat.split_whitespace().next()?.parse().ok()
}

/// Timing at the paper's scale (~5000 output points at 0.85 mm, 5 iterations).
/// Run in release: `cargo test --release -p baffle-core remesh_timing -- --ignored --nocapture`.
#[test]
#[ignore]
fn remesh_timing_5000_points() {
    let input = sliver_hemisphere(22.0, 60, 0.1, 9);
    let runs = 10;
    let (mut best_wall_ms, mut best_cpu_ms) = (f64::INFINITY, f64::INFINITY);
    let mut out = TriMesh::default();
    for _ in 0..runs {
        let (wall, cpu) = (std::time::Instant::now(), thread_cpu_ns());
        out = remesh_isotropic(&input, &opts(0.85)).unwrap();
        best_wall_ms = best_wall_ms.min(wall.elapsed().as_secs_f64() * 1e3);
        if let (Some(c0), Some(c1)) = (cpu, thread_cpu_ns()) {
            best_cpu_ms = best_cpu_ms.min((c1 - c0) as f64 * 1e-6);
        }
    }
    println!(
        "remesh {} -> {} points: best of {runs}: wall {best_wall_ms:.1} ms, thread CPU {best_cpu_ms:.1} ms",
        input.points.len(),
        out.points.len()
    );
    assert_clean_open_manifold(&out);
    let measured = if best_cpu_ms.is_finite() { best_cpu_ms } else { best_wall_ms };
    assert!(measured < 60.0, "remeshing took {measured:.1} ms");
}

#[test]
fn a_tiny_target_edge_is_refused_up_front_by_the_triangle_budget() {
    let mesh = flat_triangle_between_two_fans();
    let err = remesh_isotropic(&mesh, &RemeshOptions { target_edge_mm: 1e-6, ..RemeshOptions::default() }).unwrap_err();
    assert!(err.contains("the remesher would need more than 2000000 triangles"), "{err}");
}

/// An open square whose diagonal a-b carries a flat triangle (c, a, b), c the
/// midpoint of a-b: the shape of an ear-clipped sliver along the imprinted seam.
fn flat_triangle_between_two_fans() -> TriMesh {
    let points = vec![
        Vec3::new(0.0, 0.0, 0.0),  // a
        Vec3::new(4.0, 0.0, 0.0),  // b
        Vec3::new(2.0, 0.0, 0.0),  // c, on a-b
        Vec3::new(2.0, 3.0, 0.0),  // d
        Vec3::new(2.0, -3.0, 0.0), // e
    ];
    let triangles = vec![[0, 2, 3], [2, 1, 3], [2, 0, 1], [0, 4, 1]];
    TriMesh::new(points, triangles, vec![2; 4])
}

#[test]
fn a_long_edge_held_by_a_flat_triangle_ends_in_the_budget_not_an_abort() {
    // The flat triangle is not split, so a-b (4 mm) stays; the triangle below it then
    // cannot be resolved at 0.3 mm, and the split stops at the budget with the place.
    let mesh = flat_triangle_between_two_fans();
    let opts = RemeshOptions { target_edge_mm: 0.3, split_boundary: true, ..RemeshOptions::default() };
    let err = remesh_isotropic(&mesh, &opts).unwrap_err();
    assert!(err.contains("the remesher would need more than") && err.contains("does not converge near"), "{err}");
}

#[test]
fn a_seam_edge_longer_than_the_remesher_can_resolve_is_named() {
    // One triangle whose boundary edges are all 10 mm: kept as the seam, they cannot be resolved at 1 mm.
    let mesh = TriMesh::new(
        vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(10.0, 0.0, 0.0), Vec3::new(5.0, 8.0, 0.0)],
        vec![[0, 1, 2]],
        vec![2],
    );
    let err = remesh_isotropic(&mesh, &RemeshOptions { target_edge_mm: 1.0, ..RemeshOptions::default() }).unwrap_err();
    assert!(err.contains("the boundary (seam) edge from (0.00, 0.00, 0.00) to (10.00, 0.00, 0.00) mm is 10.00 mm long"), "{err}");
}

/// Graded from the cap: the cylinder's edges near the cap (label 11, at z = CYL_H) stay at
/// the target, those far down its side grow as the grading says, and the surface stays
/// a clean open manifold on the same cylinder.
#[test]
fn a_graded_remesh_keeps_the_target_near_the_disc_and_coarsens_away_from_it() {
    let mesh = capped_cylinder(7);
    let target = 0.5;
    let grading = SizeGrading {
        center: Vec3::new(0.0, 0.0, CYL_H),
        normal: Vec3::z(),
        radius_mm: CYL_R,
        margin_mm: 2.0,
        growth: 0.25,
        largest_edge_mm: 1.5,
    };
    let graded = remesh_isotropic(&mesh, &RemeshOptions { grading: Some(grading), ..opts(target) }).unwrap();
    assert_clean_open_manifold(&graded);
    let uniform = remesh_isotropic(&mesh, &opts(target)).unwrap();
    let side = |m: &TriMesh| m.face_ids.iter().filter(|&&l| l == 2).count();
    assert!(side(&graded) * 2 < side(&uniform), "side: {} graded against {} uniform triangles", side(&graded), side(&uniform));
    // Each edge's length against the grading's target at its midpoint.
    let mut ratios_near = Vec::new();
    let mut ratios_far = Vec::new();
    for &(a, b) in graded.edge_triangles().keys() {
        let (pa, pb) = (graded.points[a as usize], graded.points[b as usize]);
        let mid = 0.5 * (pa + pb);
        let wanted = grading.edge_mm(target, &mid);
        let ratio = (pa - pb).norm() / wanted;
        if grading.distance_mm(&mid) < grading.margin_mm { ratios_near.push(ratio) } else if wanted >= 1.4 { ratios_far.push(ratio) }
    }
    for (what, ratios) in [("near the cap", &mut ratios_near), ("far from it", &mut ratios_far)] {
        ratios.sort_by(|a, b| a.total_cmp(b));
        assert!(ratios.len() > 50, "{what}: {} edges", ratios.len());
        let median = percentile(ratios, 0.5);
        assert!((0.75..=1.3).contains(&median), "{what}: median edge / target {median}");
        assert!(percentile(ratios, 0.99) < 4.0 / 3.0 + 0.05, "{what}: an edge longer than 4/3 of its target");
    }
    // The cap's area stays (the graded side is projected back onto the cylinder).
    assert!((label_area(&graded, 11) - PI * CYL_R * CYL_R).abs() < 0.02 * PI * CYL_R * CYL_R);
}

#[test]
fn far_below_the_inputs_edge_the_remesh_is_approached_in_halvings() {
    // One midpoint halving of the input's mean edge reaches 4/3 of the next target.
    assert!(approach_targets_mm(0.79, 0.3).is_empty());
    assert_eq!(approach_targets_mm(0.8, 0.26), vec![0.52]);
    assert_eq!(approach_targets_mm(0.8, 0.1), vec![0.4, 0.2]);
}

#[test]
fn a_coarse_surface_remeshes_at_a_tenth_of_its_edge() {
    // p3's 0.85 mm domain failed below 0.27 mm: its one split pass overshot the budget.
    // Here a 2 mm remesh of the capped cylinder is refined to 0.2 mm (its open end split too).
    let coarse = remesh_isotropic(&capped_cylinder(5), &opts(2.0)).unwrap();
    let fine = remesh_isotropic(&coarse, &RemeshOptions { split_boundary: true, ..opts(0.2) }).unwrap();
    assert_clean_open_manifold(&fine);
    let lengths = unique_edge_lengths(&fine);
    let median = percentile(&lengths, 0.5);
    assert!((0.16..=0.27).contains(&median), "median edge {median} mm at a 0.2 mm target");
    for label in [2, 11] {
        let (a0, a1) = (label_area(&coarse, label), label_area(&fine, label));
        assert!((a1 - a0).abs() < 0.01 * a0, "label {label} area {a0} -> {a1}");
    }
}
