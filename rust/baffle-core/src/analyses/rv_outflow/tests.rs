use super::*;
use crate::geometry::plane_section::section_area;

/// A closed surface of the union of axis-aligned boxes (mm, corners on a 0.5 mm lattice):
/// every face between a filled and an empty 0.5 mm cell, as two outward triangles.
fn boxes(list: &[([f64; 3], [f64; 3])]) -> TriMesh {
    const CELL: f64 = 0.5;
    let lo = list.iter().fold([0.0f64; 3], |m, (a, _)| [m[0].min(a[0]), m[1].min(a[1]), m[2].min(a[2])]);
    let hi = list.iter().fold([0.0f64; 3], |m, (_, b)| [m[0].max(b[0]), m[1].max(b[1]), m[2].max(b[2])]);
    let first = lo.map(|l| (l / CELL).floor() as i64 - 1);
    let last = hi.map(|h| (h / CELL).ceil() as i64 + 1);
    let filled = |c: [i64; 3]| list.iter().any(|(a, b)| (0..3).all(|k| (c[k] as f64 + 0.5) * CELL > a[k] && (c[k] as f64 + 0.5) * CELL < b[k]));
    let (mut points, mut triangles) = (Vec::new(), Vec::new());
    for c in (first[0]..last[0]).flat_map(|i| (first[1]..last[1]).flat_map(move |j| (first[2]..last[2]).map(move |k| [i, j, k]))) {
        if !filled(c) {
            continue;
        }
        for axis in 0..3 {
            for side in [-1i64, 1] {
                let mut next = c;
                next[axis] += side;
                if filled(next) {
                    continue;
                }
                // The face's corners, counter-clockwise seen from outside.
                let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
                let corner = |da: i64, db: i64| {
                    let mut p = Vec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
                    p[axis] += if side > 0 { 1.0 } else { 0.0 };
                    p[a] += da as f64;
                    p[b] += db as f64;
                    p * CELL
                };
                let quad = if side > 0 { [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)] } else { [corner(0, 0), corner(0, 1), corner(1, 1), corner(1, 0)] };
                let base = points.len() as u32;
                points.extend(quad);
                triangles.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
            }
        }
    }
    let count = triangles.len();
    TriMesh::new(points, triangles, vec![2; count])
}

/// Two 10 mm cubes joined by a neck 3 mm (y) by 4 mm (z) across, 6 mm long between them.
fn dumbbell() -> TriMesh {
    boxes(&[([0.0, 0.0, 0.0], [10.0, 10.0, 10.0]), ([9.0, 3.5, 3.0], [17.0, 6.5, 7.0]), ([16.0, 0.0, 0.0], [26.0, 10.0, 10.0])])
}

/// The pulmonary artery: a 6 mm box beyond the far cube's +x face, `gap_mm` away
/// (0: it overlaps the cube by 0.5 mm).
fn pulmonary(gap_mm: f64) -> TriMesh {
    boxes(&[([25.5 + gap_mm, 2.0, 2.0], [31.5 + gap_mm, 8.0, 8.0])])
}

/// A domain far from the neck: a box inside the first cube's corner.
fn small_domain() -> TriMesh {
    boxes(&[([1.0, 1.0, 1.0], [4.0, 4.0, 4.0])])
}

#[test]
fn a_box_section_is_its_area() {
    let cube = boxes(&[([0.0, 0.0, 0.0], [10.0, 10.0, 10.0])]);
    let area = section_area(&cube, None, Vec3::new(5.0, 5.0, 5.0), Vec3::x()).unwrap();
    assert!((area - 100.0).abs() < 0.5, "{area}");
    // Tilted 30 degrees about z: 10 x 10 / cos 30.
    let normal = Vec3::new(30f64.to_radians().cos(), 30f64.to_radians().sin(), 0.0);
    let area = section_area(&cube, None, Vec3::new(5.0, 5.0, 5.0), normal).unwrap();
    assert!((area - 100.0 / 30f64.to_radians().cos()).abs() < 0.5, "{area}");
    // A hole through the middle leaves the ring; outside the solid there is no section.
    let hole = boxes(&[([2.0, 3.0, 3.0], [8.0, 7.0, 7.0])]);
    let ring = section_area(&cube, Some(&hole), Vec3::new(5.0, 1.0, 1.0), Vec3::x()).unwrap();
    assert!((ring - 84.0).abs() < 0.5, "{ring}");
    assert_eq!(section_area(&cube, None, Vec3::new(5.0, 12.0, 5.0), Vec3::x()), None);
}

#[test]
fn the_smallest_section_of_a_dumbbell_is_its_neck() {
    let r = rv_outflow(&dumbbell(), &small_domain(), &pulmonary(0.0)).unwrap();
    assert_eq!(r.rv_outflow_unavailable, None, "{r:?}");
    for path in [r.rv_outflow_before.as_ref().unwrap(), r.rv_outflow_after.as_ref().unwrap()] {
        assert!((path.min_section_mm2 - 12.0).abs() <= 0.24, "{path:?}");
        let p = path.min_section_point_mm;
        assert!(p[0] > 10.0 && p[0] < 16.0, "the smallest section is in the neck: {path:?}");
        // From the first cube's widest voxel (about its centre) to the far cube's +x face.
        assert!(path.path_length_mm > 18.0 && path.path_length_mm < 25.0, "{path:?}");
        assert!((path.bottleneck_radius_mm - 1.5).abs() <= 0.5, "{path:?}");
    }
    assert_eq!(r.rv_outflow_min_section_mm2, Some(r.rv_outflow_after.unwrap().min_section_mm2));
}

#[test]
fn a_domain_in_the_neck_narrows_the_section_after_the_baffle() {
    // The domain fills the neck's lower 1.5 mm (y 3.5..5): 1.5 x 4 mm are left.
    let domain = boxes(&[([11.0, 3.0, 2.5], [15.0, 5.0, 7.5])]);
    let r = rv_outflow(&dumbbell(), &domain, &pulmonary(0.0)).unwrap();
    let (before, after) = (r.rv_outflow_min_section_before_mm2.unwrap(), r.rv_outflow_min_section_mm2.unwrap());
    assert!((before - 12.0).abs() <= 0.24, "{r:?}");
    assert!((after - 6.0).abs() <= 0.24, "{r:?}");
    // The neck is also where the baffle narrows the path most: half of it is left.
    let n = r.rv_outflow_most_narrowed.unwrap();
    assert!((n.area_before_mm2 - 12.0).abs() <= 0.24 && (n.area_after_mm2 - 6.0).abs() <= 0.24, "{n:?}");
    assert!((n.after_over_before - 0.5).abs() <= 0.03, "{n:?}");
    // The domain spans x 11..15 of the neck; the path ends at the far cube's face x = 26.
    assert!(n.point_mm[0] > 11.0 && n.point_mm[0] < 15.0, "{n:?}");
    assert!((n.distance_from_pulmonary_end_mm - (26.0 - n.point_mm[0])).abs() < 1.0, "{n:?}");
}

#[test]
fn a_domain_off_the_path_narrows_nothing() {
    // The corner box is cut by the tilted planes near the path's start (9 % there);
    // a domain beside the ventricle is in no section's piece.
    let r = rv_outflow(&dumbbell(), &small_domain(), &pulmonary(0.0)).unwrap();
    assert!(r.rv_outflow_most_narrowed.as_ref().unwrap().after_over_before > 0.8, "{r:?}");
    let beside = boxes(&[([2.0, 11.0, 2.0], [8.0, 14.0, 8.0])]);
    let n = rv_outflow(&dumbbell(), &beside, &pulmonary(0.0)).unwrap().rv_outflow_most_narrowed.unwrap();
    assert_eq!(n.after_over_before, 1.0, "{n:?}");
    assert_eq!(n.area_before_mm2, n.area_after_mm2);
}

#[test]
fn the_section_before_is_the_solid_through_the_same_pixel() {
    // A cube with a hole box through the middle that splits the plane x = 5 into a ring:
    // the hole does not split the ring, so after = 100 - 24, before = 100.
    let cube = boxes(&[([0.0, 0.0, 0.0], [10.0, 10.0, 10.0])]);
    let hole = boxes(&[([2.0, 3.0, 3.0], [8.0, 7.0, 7.0])]);
    let a = section_areas(&cube, Some(&hole), Vec3::new(5.0, 1.0, 1.0), Vec3::x()).unwrap();
    assert!((a.region_mm2 - 84.0).abs() < 0.5 && (a.solid_mm2 - 100.0).abs() < 0.5, "{a:?}");
    // A wall across the cube (y 4..6) cuts the plane in two: after is the half holding
    // the point (40 mm2 of y 0..4), before the whole square.
    let wall = boxes(&[([-1.0, 4.0, -1.0], [11.0, 6.0, 11.0])]);
    let a = section_areas(&cube, Some(&wall), Vec3::new(5.0, 1.0, 5.0), Vec3::x()).unwrap();
    assert!((a.region_mm2 - 40.0).abs() < 0.5 && (a.solid_mm2 - 100.0).abs() < 0.5, "{a:?}");
    assert_eq!(section_areas(&cube, None, Vec3::new(5.0, 5.0, 5.0), Vec3::x()).map(|a| a.region_mm2 == a.solid_mm2), Some(true));
}

#[test]
fn without_contact_the_figure_is_unavailable_with_the_gap() {
    let r = rv_outflow(&dumbbell(), &small_domain(), &pulmonary(5.0)).unwrap();
    assert_eq!(r.rv_outflow_min_section_mm2, None);
    let reason = r.rv_outflow_unavailable.unwrap();
    assert!(reason.contains("4.5 mm") && reason.contains("does not touch the RV"), "{reason}");
}

#[test]
fn a_domain_covering_the_interface_is_named() {
    let domain = boxes(&[([20.0, -1.0, -1.0], [27.0, 11.0, 11.0])]);
    let r = rv_outflow(&dumbbell(), &domain, &pulmonary(0.0)).unwrap();
    assert!(r.rv_outflow_min_section_before_mm2.is_some() && r.rv_outflow_min_section_mm2.is_none(), "{r:?}");
    assert_eq!(r.rv_outflow_most_narrowed, None);
    assert!(r.rv_outflow_unavailable.unwrap().contains("covers the RV's interface"));
}

#[test]
fn the_interface_is_the_ventricle_surface_at_the_pulmonary_artery() {
    // The far cube's +x face inside the 6 x 6 mm pulmonary box (36 mm2), and the
    // triangles of the 0.5 mm band around it whose centroids are within 0.5 mm of it.
    let r = rv_outflow(&dumbbell(), &small_domain(), &pulmonary(0.0)).unwrap();
    let a = r.rv_pulmonary_interface_mm2.unwrap();
    assert!((36.0..=49.0).contains(&a), "{a}");
    let r = rv_outflow(&dumbbell(), &small_domain(), &pulmonary(5.0)).unwrap();
    assert_eq!(r.rv_pulmonary_interface_mm2, Some(0.0));
}
