use super::*;
use crate::geometry::spatial::{closest_point_on_triangle, winding_number};
use std::f64::consts::PI;

/// A closed tube of radius `r` around the planar curve `c(x)` (x in [0, 1], the curve
/// in the xz-plane so y is normal to it), wall 2, start cap 11, end cap 16.
fn tube(c: impl Fn(f64) -> (Vec3, Vec3), r: f64, along: usize, around: usize) -> TriMesh {
    let mut points = Vec::new();
    for i in 0..=along {
        let (p, t) = c(i as f64 / along as f64);
        let (u, v) = (Vec3::y(), t.normalize().cross(&Vec3::y()));
        for j in 0..around {
            let phi = 2.0 * PI * j as f64 / around as f64;
            points.push(p + r * (phi.cos() * u + phi.sin() * v));
        }
    }
    let id = |i: usize, j: usize| (i * around + j % around) as u32;
    let (mut triangles, mut labels) = (Vec::new(), Vec::new());
    for i in 0..along {
        for j in 0..around {
            triangles.push([id(i, j), id(i, j + 1), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i + 1, j)]);
            labels.extend([2, 2]);
        }
    }
    for (i, label) in [(0, 11), (along, 16)] {
        let centre = points.len() as u32;
        points.push(c(i as f64 / along as f64).0);
        for j in 0..around {
            triangles.push(if i == 0 { [centre, id(i, j + 1), id(i, j)] } else { [centre, id(i, j), id(i, j + 1)] });
            labels.push(label);
        }
    }
    TriMesh::new(points, triangles, labels)
}


/// Distance to the wall (labels not in `open`) over every triangle, no tree.
fn brute_force_wall_distance(mesh: &TriMesh, open: &[i32], q: Vec3) -> f64 {
    (0..mesh.triangles.len()).filter(|&t| !open.contains(&mesh.face_ids[t])).map(|t| (closest_point_on_triangle(&q, &mesh.triangle_points(t)).0 - q).norm()).fold(f64::INFINITY, f64::min)
}

/// Every point inside the lumen, every radius the brute-force wall distance, the
/// points 0.5 mm apart at most and the arc lengths consistent.
fn check_independently(mesh: &TriMesh, open: &[i32], line: &FlowCenterline) {
    assert!(line.points.len() >= 2);
    for (k, (&p, &r)) in line.points.iter().zip(&line.radius_mm).enumerate() {
        let inner = k > 0 && k + 1 < line.points.len();
        if inner {
            let w = winding_number(mesh, p).abs();
            assert!((w - 1.0).abs() < 1e-6, "point {k} {p:?}: winding number {w}");
        }
        let brute = brute_force_wall_distance(mesh, open, p);
        assert!((brute - r).abs() < 1e-9, "point {k}: radius {r} vs brute force {brute}");
    }
    for w in line.points.windows(2) {
        assert!((w[1] - w[0]).norm() <= PAPER_SPACING_MM + 1e-9);
    }
    assert!((line.s_mm.last().unwrap() - line.length_mm).abs() < 1e-12);
}

#[test]
fn straight_cylinder_length_and_radius() {
    // Oblique to the grid, so the voxel path is a staircase before smoothing.
    let (length, radius) = (12.0, 3.0);
    let d = Vec3::new(0.6, 0.0, 0.8);
    let origin = Vec3::new(0.13, -0.07, 0.21);
    let mesh = tube(|x| (origin + x * length * d, d), radius, 24, 64);
    let lumen = Lumen::between_caps(&mesh, 11, 16).unwrap();
    let line = flow_centerline(&lumen, &CenterlineOptions::default()).unwrap();
    check_independently(&mesh, &[11, 16], &line);
    assert!((line.length_mm / length - 1.0).abs() < 0.01, "length {} vs {length}", line.length_mm);
    // Inscribed radius of the 64-gon; away from the ends (within R of a cap the wall
    // is farther than R only if the point leaves the axis).
    let polygon = radius * (PI / 64.0).cos();
    for (k, &r) in line.radius_mm.iter().enumerate() {
        assert!((r / polygon - 1.0).abs() < 0.02, "point {k}: radius {r} vs {polygon}");
    }
    assert!(line.voxel_mm == 0.2 && line.inside_voxels > 1000);
}

/// A quarter circle of radius `bend` in the xz-plane: point and tangent at x in [0, 1].
fn quarter_circle(bend: f64) -> impl Fn(f64) -> (Vec3, Vec3) {
    move |x| {
        let a = 0.5 * PI * x;
        (Vec3::new(bend * a.cos(), 0.0, bend * a.sin()), Vec3::new(-a.sin(), 0.0, a.cos()))
    }
}

#[test]
fn quarter_torus_length_is_the_arc_length() {
    let (bend, radius) = (10.0, 2.5);
    let arc = quarter_circle(bend);
    let mesh = tube(arc, radius, 60, 48);
    let lumen = Lumen::between_caps(&mesh, 11, 16).unwrap();
    let line = flow_centerline(&lumen, &CenterlineOptions::default()).unwrap();
    check_independently(&mesh, &[11, 16], &line);
    let exact = 0.5 * PI * bend;
    assert!((line.length_mm / exact - 1.0).abs() < 0.02, "length {} vs {exact}", line.length_mm);
    // On the core circle (the medial line), not cut towards the inner side.
    for p in &line.points {
        let off = ((p.x * p.x + p.z * p.z).sqrt() - bend).hypot(p.y);
        assert!(off < 0.1, "{p:?} is {off} mm off the core circle");
    }
}

#[test]
fn interior_planes_trim_the_centerline() {
    // The extended-domain case: the path runs cap to cap, measured between two
    // interior discs 3 mm and 9 mm along a 12 mm cylinder.
    let mesh = tube(|x| (Vec3::new(0.0, 0.0, 12.0 * x), Vec3::z()), 2.0, 24, 48);
    let disc = |z: f64, label| {
        let ring: Vec<Vec3> = (0..40).map(|j| 2.0 * j as f64 * PI / 40.0).map(|a| Vec3::new(2.0 * a.cos(), 2.0 * a.sin(), z)).collect();
        MeasurementPlane { label, triangles: (0..40).map(|j| [Vec3::new(0.0, 0.0, z), ring[j], ring[(j + 1) % 40]]).collect() }
    };
    let lumen = Lumen::with_end_caps(&mesh, 11, 16, [disc(3.0, 21), disc(9.0, 22)]).unwrap();
    let line = flow_centerline(&lumen, &CenterlineOptions::default()).unwrap();
    assert!((line.length_mm - 6.0).abs() < 0.02, "length {}", line.length_mm);
    assert!((line.points[0].z - 3.0).abs() < 1e-9 && (line.points.last().unwrap().z - 9.0).abs() < 1e-9);
    // Planes given in the wrong order: the outflow plane is never crossed after the inflow one.
    let swapped = Lumen::with_end_caps(&mesh, 11, 16, [disc(9.0, 22), disc(3.0, 21)]).unwrap();
    assert!(flow_centerline(&swapped, &CenterlineOptions::default()).unwrap_err().contains("before plane"));
}

#[test]
fn resampling_keeps_the_ends_and_spacing() {
    let points = vec![Vec3::zeros(), Vec3::new(1.2, 0.0, 0.0), Vec3::new(1.2, 0.9, 0.0)];
    let r = resample(&points, 0.5);
    assert_eq!(r.first(), points.first());
    assert!((r.last().unwrap() - points[2]).norm() < 1e-12);
    assert_eq!(r.len(), 6); // 2.1 mm in 5 steps of 0.42 mm
}

/// The patients' published surfaces (cm, inward) and design inputs, when present.
fn published_surface(patient: &str) -> Option<TriMesh> {
    let dir = baffle_test_support::reference_data::reference_data_if_present()?;
    let mut mesh = crate::io::read_surface(&dir.join(patient).join("published_M_final.vtp")).unwrap();
    mesh.points.iter_mut().for_each(|p| *p *= 10.0);
    Some(mesh)
}

#[test]
fn published_surfaces_of_p2_and_p3() {
    for (patient, paper_mm) in [("p2", 10.14), ("p3", 13.31)] {
        let Some(mesh) = published_surface(patient) else { return };
        let lumen = Lumen::between_caps(&mesh, 11, 16).unwrap();
        let start = std::time::Instant::now();
        let line = flow_centerline(&lumen, &CenterlineOptions::default()).unwrap();
        let elapsed = start.elapsed().as_secs_f64();
        check_independently(&mesh, &[11, 16], &line);
        let gap = (lumen.planes[1].centroid() - lumen.planes[0].centroid()).norm();
        let (r_min, r_max) = line.radius_mm.iter().fold((f64::INFINITY, 0f64), |(a, b), &r| (a.min(r), b.max(r)));
        eprintln!(
            "{patient} published: flow centerline {:.2} mm (paper {paper_mm}), cap centroids {gap:.2} mm apart, {} points, radius {r_min:.2}-{r_max:.2} mm, {elapsed:.2} s {:?}, {} inside voxels",
            line.length_mm,
            line.points.len(),
            line.timings_ms,
            line.inside_voxels
        );
        // Between the planes: each end on its cap disc. Not tuned to the paper's figure:
        // a sanity range only (the caps are oblique, so the ends need not be their centroids).
        for (end, plane) in [(line.points[0], &lumen.planes[0]), (*line.points.last().unwrap(), &lumen.planes[1])] {
            let d = plane.triangles.iter().map(|t| (closest_point_on_triangle(&end, t).0 - end).norm()).fold(f64::INFINITY, f64::min);
            assert!(d < 1e-6, "{patient}: end {end:?} is {d} mm from cap {}", plane.label);
        }
        assert!(line.length_mm.is_finite() && line.length_mm > 0.8 * gap && line.length_mm < 2.0 * gap, "{patient}: {}", line.length_mm);
    }
}

#[test]
fn options_out_of_range_are_named_by_their_flag() {
    assert!(CenterlineOptions::default().validate().is_ok());
    let bad = [
        (CenterlineOptions { spacing_mm: 0.0, ..Default::default() }, "--spacing-mm = 0"),
        (CenterlineOptions { voxel_mm: f64::NAN, ..Default::default() }, "--voxel-mm = NaN"),
        (CenterlineOptions { smoothing_mm: -1.0, ..Default::default() }, "--smoothing-mm = -1"),
        (CenterlineOptions { recenter_fraction: 7.0, ..Default::default() }, "--recenter-fraction = 7"),
    ];
    for (options, needle) in bad {
        let e = options.validate().unwrap_err();
        assert!(e.contains(needle), "{e}");
    }
}

/// The cap of `mesh` labelled `label` as a measurement plane.
fn cap(mesh: &TriMesh, label: i32) -> MeasurementPlane {
    MeasurementPlane::from_label(mesh, label).unwrap()
}

#[test]
fn flow_normal_sections_of_a_tube_are_its_discs() {
    // A quarter torus: sections normal to the bent centerline are the tube's discs (the
    // 48-gon's area); a plane normal to the chord between the ends would cut ellipses.
    let (bend, radius) = (10.0, 2.5);
    let arc = quarter_circle(bend);
    let mesh = tube(arc, radius, 90, 48);
    let line = flow_centerline(&Lumen::between_caps(&mesh, 11, 16).unwrap(), &CenterlineOptions::default()).unwrap();
    let areas = flow_normal_sections(&mesh, &line.points, &[cap(&mesh, 11), cap(&mesh, 16)]);
    let polygon = 0.5 * 48.0 * radius * radius * (2.0 * PI / 48.0).sin();
    let measured = areas.iter().flatten().count();
    assert!(measured + 2 >= areas.len(), "only {measured} of {} sections measured", areas.len());
    for (k, a) in areas.iter().enumerate() {
        if let Some(a) = a {
            assert!((a / polygon - 1.0).abs() < 0.02, "point {k}: {a:.3} mm2 vs {polygon:.3}");
        }
    }
    let (smallest, _) = smallest_section(&line.s_mm, &areas).unwrap();
    assert!((smallest / polygon - 1.0).abs() < 0.02);
    // A section missing in the middle is skipped, not zero.
    let s = [0.0, 0.5, 1.0, 1.5];
    assert_eq!(smallest_section(&s, &[Some(9.0), None, Some(4.0), Some(7.0)]), Some((4.0, 1.0)));
    assert_eq!(smallest_section(&s, &[None; 4]), None);
}

#[test]
fn sections_whose_plane_crosses_an_oblique_measurement_plane_are_left_out() {
    // A straight tube whose end caps are cut 40 degrees off its axis: planes normal to the
    // axis within a radius of the ends cross the caps and would measure beyond them.
    let mut mesh = tube(|x| (Vec3::new(0.0, 0.0, 12.0 * x), Vec3::z()), 2.0, 48, 48);
    let tilt = 40f64.to_radians().tan();
    for p in mesh.points.iter_mut() {
        if p.z < 1e-9 {
            p.z = tilt * p.x;
        } else if p.z > 12.0 - 1e-9 {
            p.z = 12.0 + tilt * p.x;
        }
    }
    let line = flow_centerline(&Lumen::between_caps(&mesh, 11, 16).unwrap(), &CenterlineOptions::default()).unwrap();
    let planes = [cap(&mesh, 11), cap(&mesh, 16)];
    let areas = flow_normal_sections(&mesh, &line.points, &planes);
    let disc = 0.5 * 48.0 * 4.0 * (2.0 * PI / 48.0).sin();
    for (p, a) in line.points.iter().zip(&areas) {
        // The caps reach 2 tan(40) = 1.68 mm either side of z = 0 and z = 12.
        let clear = p.z > 2.0 * tilt + 0.3 && p.z < 12.0 - 2.0 * tilt - 0.3;
        match a {
            Some(a) => assert!((a / disc - 1.0).abs() < 0.02 && p.z > 2.0 * tilt - 0.3 && p.z < 12.0 - 2.0 * tilt + 0.3, "{p:?}: {a}"),
            None => assert!(!clear, "{p:?} is clear of the caps but was not measured"),
        }
    }
    // Without the rule, the planes near the ends measure the cut-off discs.
    let unguarded = flow_normal_sections(&mesh, &line.points, &[]);
    assert!(unguarded.iter().flatten().any(|a| a / disc < 0.9));
}

#[test]
fn a_narrowing_shows_in_the_flow_normal_sections_where_it_is() {
    // A straight tube whose radius dips from 3 to 2 mm around its middle.
    let length = 16.0;
    let mut mesh = tube(|x| (Vec3::new(0.0, 0.0, length * x), Vec3::z()), 3.0, 64, 48);
    let profile = |z: f64| 3.0 - (-((z - 8.0) / 2.0).powi(2)).exp();
    for p in mesh.points.iter_mut() {
        let r = p.x.hypot(p.y);
        if r > 1e-9 {
            let scale = profile(p.z) / 3.0;
            p.x *= scale;
            p.y *= scale;
        }
    }
    let line = flow_centerline(&Lumen::between_caps(&mesh, 11, 16).unwrap(), &CenterlineOptions::default()).unwrap();
    let areas = flow_normal_sections(&mesh, &line.points, &[cap(&mesh, 11), cap(&mesh, 16)]);
    let (smallest, at) = smallest_section(&line.s_mm, &areas).unwrap();
    let throat = 0.5 * 48.0 * 4.0 * (2.0 * PI / 48.0).sin();
    assert!((smallest / throat - 1.0).abs() < 0.03, "{smallest} vs {throat}");
    assert!((line.points[0].z + at - 8.0).abs() < 0.6, "throat at s = {at}, z0 = {}", line.points[0].z);
}

#[test]
fn a_rotated_and_moved_lumen_gives_the_same_centerline_and_sections_moved_with_it() {
    // The voxel grid follows the lumen's own frame, so a scene turned in Slicer gives the
    // same line (to rounding), not one whose staircase fell differently on the scene's axes.
    let mesh = tube(quarter_circle(10.0), 2.5, 90, 48);
    let rotation = nalgebra::Rotation3::from_euler_angles(37f64.to_radians(), -23f64.to_radians(), 61f64.to_radians());
    let shift = Vec3::new(12.0, -40.0, 25.0);
    let moved = TriMesh { points: mesh.points.iter().map(|p| rotation * p + shift).collect(), ..mesh.clone() };
    let line_of = |m: &TriMesh| flow_centerline(&Lumen::between_caps(m, 11, 16).unwrap(), &CenterlineOptions::default()).unwrap();
    let (line, moved_line) = (line_of(&mesh), line_of(&moved));
    assert_eq!(line.points.len(), moved_line.points.len());
    assert!((line.length_mm - moved_line.length_mm).abs() < 1e-9, "{} vs {}", line.length_mm, moved_line.length_mm);
    for (p, q) in line.points.iter().zip(&moved_line.points) {
        assert!((rotation * p + shift - q).norm() < 1e-9, "{p:?} moved is not {q:?}");
    }
    let sections = |m: &TriMesh, l: &FlowCenterline| flow_normal_sections(m, &l.points, &[cap(m, 11), cap(m, 16)]);
    for (a, b) in sections(&mesh, &line).iter().zip(&sections(&moved, &moved_line)) {
        assert!(a.zip(*b).map_or(a.is_none() && b.is_none(), |(a, b)| (a - b).abs() < 1e-9), "{a:?} vs {b:?}");
    }
}
