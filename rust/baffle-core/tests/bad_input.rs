//! Bad input never panics and never yields a silently wrong mesh: each case gets an
//! error that names the problem and where it is.

use baffle_core::phantom::{phantom, phantom_default, PhantomParams};
use baffle_core::{design, DesignError, DesignOptions, TargetArea, TriMesh, Vec3};

fn target() -> TargetArea {
    TargetArea::Bsa { bsa_m2: 0.37, z_score: 0.0 }
}

fn run(surface: &TriMesh, points: &[Vec3], target: &TargetArea) -> Result<(), DesignError> {
    design(surface, points, target, &DesignOptions::default(), &mut |_, _| true).map(|_| ())
}

fn expect_error(surface: &TriMesh, points: &[Vec3], target: &TargetArea, needles: &[&str]) -> DesignError {
    let err = run(surface, points, target).expect_err("bad input was accepted");
    let text = err.to_string();
    for needle in needles {
        assert!(text.contains(needle), "error '{text}' does not mention '{needle}'");
    }
    err
}

#[test]
fn open_surface_is_rejected_with_an_edge_location() {
    let p = phantom_default();
    let mut surface = p.surface.clone();
    surface.triangles.remove(100);
    surface.face_ids.remove(100);
    expect_error(&surface, &p.suture_points_mm, &target(), &["not a closed manifold", "3 boundary edges", "between points"]);
}

#[test]
fn non_manifold_surface_is_rejected() {
    let p = phantom_default();
    let mut surface = p.surface.clone();
    surface.triangles.push(surface.triangles[7]);
    surface.face_ids.push(2);
    expect_error(&surface, &p.suture_points_mm, &target(), &["non-manifold"]);
}

#[test]
fn missing_cap_label_is_named() {
    let p = phantom_default();
    let mut surface = p.surface.clone();
    surface.face_ids.iter_mut().filter(|l| **l == 16).for_each(|l| *l = 2);
    expect_error(&surface, &p.suture_points_mm, &target(), &["16", "aortic-annulus cap"]);
}

#[test]
fn non_finite_coordinates_are_named() {
    let p = phantom_default();
    let mut surface = p.surface.clone();
    surface.points[42].y = f64::NAN;
    expect_error(&surface, &p.suture_points_mm, &target(), &["point 42", "non-finite"]);
    let mut points = p.suture_points_mm.clone();
    points[3].x = f64::INFINITY;
    expect_error(&p.surface, &points, &target(), &["point 4", "non-finite"]);
}

#[test]
fn too_few_points_are_rejected() {
    let p = phantom_default();
    expect_error(&p.surface, &p.suture_points_mm[..3], &target(), &["3 point(s)", "at least 4"]);
}

#[test]
fn points_along_a_line_are_named_as_such() {
    // Twelve points on the wall along the short chord from point 1 to point 3: they
    // enclose nothing (before, "the seam crosses itself near seam point 52").
    let p = phantom_default();
    let bvh = baffle_core::geometry::spatial::TriangleBvh::new(&p.surface).unwrap();
    let (a, b) = (p.suture_points_mm[0], p.suture_points_mm[2]);
    let points: Vec<Vec3> = (0..12)
        .map(|i| bvh.closest_point(&p.surface, a + (b - a) * (i as f64 / 11.0)).unwrap().point)
        .collect();
    expect_error(&p.surface, &points, &target(), &["12 points lie almost on a line", "mm across it"]);
}

#[test]
fn a_point_far_from_the_surface_is_named_with_its_distance() {
    let p = phantom_default();
    let mut points = p.suture_points_mm.clone();
    // Push point 6 (index 5) 3 mm out of the tube, away from its centerline (the
    // bend's arc of radius 12 mm about the z axis).
    let p5 = points[5];
    let on_centerline = 12.0 * Vec3::new(p5.x, p5.y, 0.0).normalize();
    points[5] += 3.0 * (p5 - on_centerline).normalize();
    expect_error(&p.surface, &points, &target(), &["point 6", "mm from the surface"]);
}

#[test]
fn a_point_on_a_cap_is_rejected() {
    let p = phantom_default();
    let mut points = p.suture_points_mm.clone();
    // The VSD cap lies in the plane y = 0 around (12, 0, 0).
    points[0] = Vec3::new(13.0, 0.0, 0.5);
    expect_error(&p.surface, &points, &target(), &["VSD cap"]);
}

#[test]
fn a_seam_between_the_caps_is_rejected() {
    // A ring around the tube halfway along separates the two caps.
    let params = PhantomParams::default();
    let p = phantom(&params);
    let mid = 0.5 * params.sweep_angle_deg.to_radians();
    let ring: Vec<Vec3> = (0..12).map(|k| params.wall_point_mm(mid, std::f64::consts::TAU * k as f64 / 12.0)).collect();
    expect_error(&p.surface, &ring, &target(), &["separates the VSD cap from the aortic-annulus cap"]);
}

#[test]
fn an_unreachable_target_is_an_error_not_a_broken_mesh() {
    // A suture loop wrapped 100 degrees round the tunnel leaves too little baffle near the caps.
    let p = phantom(&PhantomParams { suture_half_angle_deg: 100.0, ..PhantomParams::default() });
    let err = expect_error(&p.surface, &p.suture_points_mm, &TargetArea::AreaMm2(300.0), &["admits a tunnel of at most"]);
    assert!(matches!(err, DesignError::Infeasible { max_feasible_area_mm2, .. } if max_feasible_area_mm2 > 100.0 && max_feasible_area_mm2 < 300.0), "{err}");
}

#[test]
fn invalid_targets_are_named() {
    let p = phantom_default();
    expect_error(&p.surface, &p.suture_points_mm, &TargetArea::Bsa { bsa_m2: -1.0, z_score: 0.0 }, &["-1"]);
    expect_error(&p.surface, &p.suture_points_mm, &TargetArea::AreaMm2(f64::NAN), &["target"]);
}

#[test]
fn an_inward_wound_surface_is_reoriented_not_rejected() {
    let p = phantom_default();
    let mut surface = p.surface.clone();
    surface.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    let result = design(&surface, &p.suture_points_mm, &target(), &DesignOptions::default(), &mut |_, _| true).unwrap();
    assert!(result.report.input_was_inward_wound);
    assert!(result.domain.signed_volume_mm3() > 0.0);
}

#[test]
fn cancelling_from_the_progress_callback_stops_the_design() {
    let p = phantom_default();
    let mut stages = Vec::new();
    let err = design(&p.surface, &p.suture_points_mm, &target(), &DesignOptions::default(), &mut |_, stage| {
        stages.push(stage.to_string());
        stage != "centerline"
    })
    .unwrap_err();
    assert!(matches!(err, DesignError::Cancelled(ref s) if s == "centerline"), "{err}");
    assert_eq!(stages.last().map(String::as_str), Some("centerline"));
}

#[test]
fn a_stray_label_is_named_not_taken_as_wall() {
    let p = phantom_default();
    let mut surface = p.surface.clone();
    surface.face_ids[40] = 77;
    expect_error(&surface, &p.suture_points_mm, &target(), &["1 triangle(s) are labelled 77", "--vsd-label"]);
}

#[test]
fn a_coordinate_beyond_any_scanner_is_named() {
    let p = phantom_default();
    let mut surface = p.surface.clone();
    surface.points[5].x = 1e30;
    expect_error(&surface, &p.suture_points_mm, &target(), &["point 5", "broken coordinate"]);
}

#[test]
fn a_crumpled_cap_is_named_before_the_remesher_sees_it() {
    let p = phantom_default();
    let mut surface = p.surface.clone();
    let (_, normal, _) = surface.label_centroid_normal(11).unwrap();
    // One interior vertex of the VSD cap pushed 1 mm off its plane.
    let on_other: std::collections::HashSet<u32> =
        surface.triangles.iter().zip(&surface.face_ids).filter(|(_, &f)| f != 11).flat_map(|(t, _)| *t).collect();
    let v = surface.triangles.iter().zip(&surface.face_ids).filter(|(_, &f)| f == 11).flat_map(|(t, _)| *t).find(|v| !on_other.contains(v)).unwrap();
    surface.points[v as usize] += normal * 1.0;
    expect_error(&surface, &p.suture_points_mm, &target(), &["VSD cap is not planar", "mm off its plane"]);
}

#[test]
fn a_point_given_twice_is_named_in_the_surgeons_numbering() {
    let p = phantom_default();
    let mut points = p.suture_points_mm.clone();
    points[6] = points[2];
    expect_error(&p.surface, &points, &target(), &["points 3 and 7", "given twice"]);
}
