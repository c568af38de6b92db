//! The extended CFD domain (paper 2.5) on the synthetic heart and on patients p2 and
//! p3 from their segmentations (prepare, then design with the patient's suture points,
//! then extend). Re-measured with baffle-verify (edge use, winding, volume), not with
//! the checks `extend` runs itself. p2/p3 are skipped (with a note) without the data.

use baffle_core::io::{read_points, CoordinateSystem};
use baffle_test_support::reference_data::reference_data_if_present;
use baffle_core::{design, DesignOptions, TargetArea, Vec3};
use baffle_prepare::extend::{extend, ExtendOptions, StjOptions};
use baffle_prepare::shapes::{capped_tube, uv_sphere};
use baffle_prepare::{prepare, read_segmentations, BloodPools, PrepareError, PrepareOptions};

mod common;
use common::check_extended;


/// A capped ventricle (prepare's output) has no baffle: extended as it is, as said.
fn capped_ventricle_options() -> ExtendOptions {
    ExtendOptions { without_baffle: true, ..ExtendOptions::default() }
}

fn synthetic_pools() -> BloodPools {
    BloodPools {
        lv: uv_sphere(Vec3::zeros(), 10.0, 48, 96),
        rv: uv_sphere(Vec3::new(16.0, 0.0, 0.0), 9.0, 48, 96),
        aorta: capped_tube(Vec3::new(16.0, 0.0, 4.0), Vec3::new(16.0, 0.0, 25.0), 4.0, 20, 64),
    }
}

#[test]
fn the_synthetic_heart_is_extended_to_the_lv_centre_and_one_diameter_up_the_aorta() {
    let pools = synthetic_pools();
    let (capped, _) = prepare(&pools, &PrepareOptions { closing_radius_mm: 0.0, ..PrepareOptions::default() }).unwrap();
    let extended = extend(&capped, &pools, &capped_ventricle_options()).unwrap();
    check_extended("synthetic", &capped, &pools, &extended);
    let r = &extended.report;
    // The mid-LV plane is x = 0 (the LV sphere's centre), parallel to the VSD plane x = 8.6.
    assert!(r.mid_lv_plane.point_mm[0].abs() < 0.05 && r.mid_lv_plane.normal[0] < -0.999, "{:?}", r.mid_lv_plane);
    assert!((r.inflow_cap.area_mm2 / (std::f64::consts::PI * 100.0) - 1.0).abs() < 0.05, "inflow {}", r.inflow_cap.area_mm2);
    // A straight tube has no STJ: the fallback, one annulus diameter (8 mm) up.
    assert!(!r.stj.found && r.stj.note.contains("not found"), "{:?}", r.stj.note);
    assert!((r.stj.distance_from_annulus_mm - r.stj.annulus_diameter_mm).abs() < 0.3, "{:?}", r.stj);
    assert!((r.outflow_cap.area_mm2 / (std::f64::consts::PI * 16.0) - 1.0).abs() < 0.05, "outflow {}", r.outflow_cap.area_mm2);
}

#[test]
fn the_inflow_and_outflow_caps_move_where_asked() {
    let pools = synthetic_pools();
    let (capped, _) = prepare(&pools, &PrepareOptions { closing_radius_mm: 0.0, ..PrepareOptions::default() }).unwrap();
    let stj = StjOptions { fixed_diameters: Some(1.5), ..StjOptions::default() };
    let options = ExtendOptions { inflow_offset_mm: Some(3.0), stj, without_baffle: true, ..ExtendOptions::default() };
    let extended = extend(&capped, &pools, &options).unwrap();
    check_extended("synthetic, caps moved", &capped, &pools, &extended);
    let r = &extended.report;
    // 3 mm from the LV centre away from the VSD (the normal is -x): x = -3, and the
    // section of a 10 mm sphere there is pi (100 - 9).
    assert!((r.mid_lv_plane.point_mm[0] + 3.0).abs() < 0.05 && r.mid_lv_plane.moved_from_centroid_mm == 3.0, "{:?}", r.mid_lv_plane);
    assert!(r.mid_lv_plane.rule.contains("+3.00 mm"), "{}", r.mid_lv_plane.rule);
    assert!((r.inflow_cap.area_mm2 / (std::f64::consts::PI * 91.0) - 1.0).abs() < 0.05, "inflow {}", r.inflow_cap.area_mm2);
    // 1.5 annulus diameters up the tube instead of the fallback's one.
    assert!((r.stj.distance_from_annulus_mm - 1.5 * r.stj.annulus_diameter_mm).abs() < 0.3, "{:?}", r.stj);
    assert!(r.stj.note.contains("as asked"), "{}", r.stj.note);
}

#[test]
fn cap_positions_that_leave_no_valid_cut_are_named() {
    let pools = synthetic_pools();
    let (capped, _) = prepare(&pools, &PrepareOptions { closing_radius_mm: 0.0, ..PrepareOptions::default() }).unwrap();
    let run = |options: ExtendOptions| extend(&capped, &pools, &options).unwrap_err().to_string();
    // The VSD plane is x = 8.6: 8 mm toward it leaves the plane 0.6 mm beyond it; 12 mm
    // away misses the 10 mm LV. Neither falls back to another plane.
    let near = run(ExtendOptions { inflow_offset_mm: Some(-8.0), without_baffle: true, ..ExtendOptions::default() });
    assert!(near.contains("inflow cap offset leaves no valid cut") && near.contains("need 1 mm toward the LV") && !near.contains("+2 mm"), "{near}");
    let beyond = run(ExtendOptions { inflow_offset_mm: Some(12.0), without_baffle: true, ..ExtendOptions::default() });
    assert!(beyond.contains("inflow cap offset leaves no valid cut"), "{beyond}");
    // The aorta tube is 21 mm long: 4 diameters (32 mm) is past its end.
    let high = run(ExtendOptions { stj: StjOptions { fixed_diameters: Some(4.0), ..StjOptions::default() }, without_baffle: true, ..ExtendOptions::default() });
    assert!(high.contains("below the asked outflow height"), "{high}");
    for bad in [Some(0.0), Some(-1.0), Some(f64::NAN)] {
        let err = run(ExtendOptions { stj: StjOptions { fixed_diameters: bad, ..StjOptions::default() }, without_baffle: true, ..ExtendOptions::default() });
        assert!(err.contains("must be positive"), "{bad:?}: {err}");
    }
    let err = run(ExtendOptions { inflow_offset_mm: Some(f64::INFINITY), without_baffle: true, ..ExtendOptions::default() });
    assert!(err.contains("offset must be finite"), "{err}");
}

#[test]
fn an_lv_behind_the_rv_side_of_the_vsd_plane_is_named() {
    let pools = synthetic_pools();
    let (capped, _) = prepare(&pools, &PrepareOptions { closing_radius_mm: 0.0, ..PrepareOptions::default() }).unwrap();
    // An LV whose centroid lies on the RV's side of the VSD plane.
    let moved = BloodPools { lv: uv_sphere(Vec3::new(12.0, 0.0, 0.0), 4.0, 16, 32), ..pools };
    let err = extend(&capped, &moved, &capped_ventricle_options()).unwrap_err();
    assert!(matches!(err, PrepareError::Geometry { step: "mid-LV plane", .. }), "{err}");
    assert!(err.to_string().contains("VSD"), "{err}");
}

#[test]
fn a_domain_without_an_aortic_cap_is_named() {
    let pools = synthetic_pools();
    let (mut capped, _) = prepare(&pools, &PrepareOptions { closing_radius_mm: 0.0, ..PrepareOptions::default() }).unwrap();
    capped.face_ids.iter_mut().filter(|l| **l == 16).for_each(|l| *l = 2);
    let err = extend(&capped, &pools, &capped_ventricle_options()).unwrap_err().to_string();
    assert!(err.contains("no aortic-annulus cap"), "{err}");
}

#[test]
fn a_domain_without_a_baffle_is_refused_unless_said() {
    let pools = synthetic_pools();
    let (capped, _) = prepare(&pools, &PrepareOptions { closing_radius_mm: 0.0, ..PrepareOptions::default() }).unwrap();
    let err = extend(&capped, &pools, &ExtendOptions::default()).unwrap_err().to_string();
    assert!(err.contains("no baffle (no triangle labelled 10)") && err.contains("--no-baffle"), "{err}");
    // Said, it extends; its report lists the checks of the output, each passed.
    let extended = extend(&capped, &pools, &capped_ventricle_options()).unwrap();
    let names: Vec<&str> = extended.report.checks.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names.len(), 5, "{names:?}");
    assert!(names.iter().any(|n| n.contains("crossing itself")) && names.iter().any(|n| n.contains("inflow cap rim on the LV")) && names.iter().any(|n| n.contains("outflow cap centroid inside the aorta")), "{names:?}");
    assert!(extended.report.checks.iter().all(|c| c.passed), "{:?}", extended.report.checks);
}

fn check_patient(patient: &str) {
    let Some(data) = reference_data_if_present() else { return };
    let dir = data.join(patient);
    let pools = read_segmentations(&dir.join("segmentations")).expect("segmentations");
    let (capped, _) = prepare(&pools, &PrepareOptions::default()).unwrap_or_else(|e| panic!("{patient}: prepare: {e}"));
    let table: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(data.join("patients.json")).unwrap()).unwrap();
    let bsa_m2 = table["patients"][patient]["bsa_m2"].as_f64().expect("bsa");
    let points = read_points(&dir.join("design_input/suture_points.mrk.json")).expect("points").to_frame(CoordinateSystem::Lps);
    let target = TargetArea::Bsa { bsa_m2, z_score: 0.0 };
    let designed = design(&capped, &points, &target, &DesignOptions::default(), &mut |_, _| true).unwrap_or_else(|e| panic!("{patient}: design: {e}"));
    let extended = extend(&designed.domain, &pools, &ExtendOptions::default()).unwrap_or_else(|e| panic!("{patient}: extend: {e}"));
    check_extended(patient, &designed.domain, &pools, &extended);
    let r = &extended.report;
    eprintln!("{patient}: STJ profile (mm, mm2): {:?}", r.stj.profile.iter().step_by(4).map(|[h, a]| format!("{h:.1}:{a:.0}")).collect::<Vec<_>>());
    eprintln!("{patient}: caps VSD {:.1}, aortic {:.1}, inflow {:.1}, outflow {:.1} mm2; sinus max {:.1} mm2 at {:.1} mm", r.vsd_cap.area_mm2, r.aortic_cap.area_mm2, r.inflow_cap.area_mm2, r.outflow_cap.area_mm2, r.stj.sinus_max_area_mm2, r.stj.sinus_max_distance_mm);
}

#[test]
fn p2_extended_from_segmentations() {
    check_patient("p2");
}

#[test]
fn p3_extended_from_segmentations() {
    check_patient("p3");
}

/// The paper's own designed domain (`published_M_final.vtp`, cm -> mm, wound
/// outward) extended with the patient's segmentations: its caps are planar to
/// micrometres, not to rounding, and must be accepted as they are.
fn check_published(patient: &str) {
    let Some(data) = reference_data_if_present() else { return };
    let dir = data.join(patient);
    let pools = read_segmentations(&dir.join("segmentations")).expect("segmentations");
    let mut domain = baffle_core::io::read_surface(&dir.join("published_M_final.vtp")).expect("published domain");
    domain.points.iter_mut().for_each(|p| *p *= 10.0);
    if domain.signed_volume_mm3() < 0.0 {
        domain.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    }
    // As it is: the extension at the published rims' own 0.3-0.5 mm edge.
    let extended = extend(&domain, &pools, &ExtendOptions::default()).unwrap_or_else(|e| panic!("{patient} published: extend: {e}"));
    check_extended(&format!("{patient} published"), &domain, &pools, &extended);
    let r = &extended.report;
    eprintln!("{patient} published: caps off their planes by {:.4} (VSD) and {:.4} mm (aortic)", r.vsd_cap_off_plane_mm, r.aortic_cap_off_plane_mm);
    assert!(r.vsd_cap_off_plane_mm > 0.0 && r.aortic_cap_off_plane_mm > 0.0);
}

#[test]
fn p1_published_domain_extends() {
    check_published("p1");
}

#[test]
fn p2_published_domain_extends() {
    check_published("p2");
}

#[test]
fn p3_published_domain_extends() {
    check_published("p3");
}

/// Graded away from the designed caps (`ExtendOptions::grading`), the extension keeps the
/// rims' edge within a cap diameter of each cap, where it is zipped to the rim, and
/// coarsens beyond; the domain passes the same independent checks with fewer triangles.
#[test]
fn a_graded_extension_keeps_the_edge_at_the_caps_and_coarsens_beyond() {
    use baffle_prepare::extend::ExtensionGrading;
    let pools = synthetic_pools();
    let (capped, _) = prepare(&pools, &PrepareOptions { closing_radius_mm: 0.0, ..PrepareOptions::default() }).unwrap();
    let uniform = extend(&capped, &pools, &capped_ventricle_options()).unwrap();
    // This heart's LV part lies within one VSD diameter of the VSD: a quarter here.
    let grading = ExtensionGrading { margin_diameters: 0.25, growth: 0.2, largest_ratio: 2.5 };
    let graded = extend(&capped, &pools, &ExtendOptions { grading: Some(grading), ..capped_ventricle_options() }).unwrap();
    check_extended("synthetic graded", &capped, &pools, &graded);
    assert_eq!(graded.report.grading, Some(grading));
    let added = |e: &baffle_prepare::extend::Extended| e.surface.triangles.len() - capped.triangles.len();
    assert!(3 * added(&graded) < 2 * added(&uniform), "extension triangles: {} graded, {} uniform", added(&graded), added(&uniform));
    // Edge lengths of the extension's walls on the LV side: within 2.5 mm of the VSD cap
    // (x = 8.6, radius 5.1 mm) and beyond 8 mm (x < 0.5: 5.5 mm past the margin, 2.1 x
    // the edge of 0.5 mm and more).
    let edge = graded.report.remesh_edge_mm;
    let s = &graded.surface;
    let (mut near, mut far) = (Vec::new(), Vec::new());
    for t in capped.triangles.len()..s.triangles.len() {
        let p = s.triangle_points(t);
        let length = (0..3).map(|k| (p[k] - p[(k + 1) % 3]).norm()).sum::<f64>() / 3.0;
        let x = (p[0].x + p[1].x + p[2].x) / 3.0;
        if x > 6.0 && x < 8.5 { near.push(length) } else if x < 0.5 { far.push(length) }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!(!near.is_empty() && !far.is_empty());
    assert!((mean(&near) / edge - 1.0).abs() < 0.25, "near the VSD: mean edge {:.3} against {edge:.3} mm", mean(&near));
    assert!(mean(&far) > 1.5 * edge, "at the mid-LV plane: mean edge {:.3} against {edge:.3} mm", mean(&far));
    // A grading no remesh can follow is refused by name, not dropped.
    for bad in [ExtensionGrading { growth: 0.9, ..grading }, ExtensionGrading { largest_ratio: 0.5, ..grading }, ExtensionGrading { margin_diameters: f64::NAN, ..grading }] {
        let e = extend(&capped, &pools, &ExtendOptions { grading: Some(bad), ..capped_ventricle_options() }).unwrap_err().to_string();
        assert!(e.contains("the extension's grading needs"), "{e}");
    }
}

/// p1's published domain remeshed at 0.95 mm, its extension graded to 2.5x: the coarse LV
/// triangles cut across the designed domain where the LV wall comes close, and the
/// extension is made again at one edge, saying why (skipped without the data).
#[test]
fn p1s_graded_extension_that_crosses_the_domain_is_made_at_one_edge_and_says_why() {
    use baffle_core::geometry::remesh::{remesh_isotropic, RemeshOptions};
    use baffle_prepare::extend::ExtensionGrading;
    let Some(data) = reference_data_if_present() else { return };
    let dir = data.join("p1");
    let pools = read_segmentations(&dir.join("segmentations")).expect("segmentations");
    let mut published = baffle_core::io::read_surface(&dir.join("published_M_final.vtp")).expect("published domain");
    published.points.iter_mut().for_each(|p| *p *= 10.0);
    if published.signed_volume_mm3() < 0.0 {
        published.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    }
    let remesh = |mesh, edge_mm| remesh_isotropic(mesh, &RemeshOptions { target_edge_mm: edge_mm, guard_slivers: true, ..RemeshOptions::default() }).unwrap();
    let domain = remesh(&remesh(&published, 0.85), 0.95);
    let grading = ExtensionGrading { margin_diameters: 1.0, growth: 0.2, largest_ratio: 2.5 };
    let options = ExtendOptions { remesh_edge_mm: Some(0.95), grading: Some(grading), ..ExtendOptions::default() };
    let extended = extend(&domain, &pools, &options).unwrap_or_else(|e| panic!("p1 graded: extend: {e}"));
    check_extended("p1 published, grading dropped", &domain, &pools, &extended);
    let r = &extended.report;
    assert_eq!(r.grading, None);
    let why = r.grading_dropped.as_deref().expect("the grading was dropped");
    assert!(why.starts_with("the graded extension failed (") && why.contains("crosses"), "{why}");
}
