//! `prepare` on a synthetic heart: two overlapping spheres as LV and RV, a tube
//! as the aorta leaving the RV. The VSD is their circle of intersection, the
//! aortic annulus the tube's circle on the RV sphere, both known exactly.

use baffle_core::geometry::mesh::manifold_report;
use baffle_core::{TriMesh, Vec3};
use baffle_prepare::shapes::{capped_tube, uv_sphere};
use baffle_prepare::{prepare, BloodPools, PrepareError, PrepareOptions};

const LV_RADIUS: f64 = 10.0;
const RV_RADIUS: f64 = 9.0;
const RV_CENTER_X: f64 = 16.0;
const AORTA_RADIUS: f64 = 4.0;

fn pools() -> BloodPools {
    BloodPools {
        lv: uv_sphere(Vec3::zeros(), LV_RADIUS, 48, 96),
        rv: uv_sphere(Vec3::new(RV_CENTER_X, 0.0, 0.0), RV_RADIUS, 48, 96),
        aorta: capped_tube(Vec3::new(RV_CENTER_X, 0.0, 4.0), Vec3::new(RV_CENTER_X, 0.0, 25.0), AORTA_RADIUS, 20, 64),
    }
}

/// The VSD: the spheres' radical plane x = x0, circle radius a.
fn vsd_circle() -> (Vec3, f64) {
    let d = RV_CENTER_X;
    let x0 = (d * d + LV_RADIUS * LV_RADIUS - RV_RADIUS * RV_RADIUS) / (2.0 * d);
    (Vec3::new(x0, 0.0, 0.0), (LV_RADIUS * LV_RADIUS - x0 * x0).sqrt())
}

/// The aortic annulus: the tube meets the RV sphere at height sqrt(R^2 - r^2).
fn aortic_circle() -> (Vec3, f64) {
    let z = (RV_RADIUS * RV_RADIUS - AORTA_RADIUS * AORTA_RADIUS).sqrt();
    (Vec3::new(RV_CENTER_X, 0.0, z), AORTA_RADIUS)
}

fn options() -> PrepareOptions {
    PrepareOptions { voxel_mm: 0.3, closing_radius_mm: 0.0, ..PrepareOptions::default() }
}

fn check_cap(mesh: &TriMesh, label: i32, (center, radius): (Vec3, f64), normal_axis: Vec3) {
    let (c, n, area) = mesh.label_centroid_normal(label).expect("cap present");
    let exact = std::f64::consts::PI * radius * radius;
    assert!((c - center).norm() < 0.5, "cap {label}: centroid {c:?} vs {center:?}");
    assert!(n.dot(&normal_axis).abs() > 0.995, "cap {label}: normal {n:?}");
    assert!((area / exact - 1.0).abs() < 0.15, "cap {label}: area {area:.1} vs {exact:.1} mm2");
}

#[test]
fn synthetic_heart_gives_a_closed_capped_rv_with_the_exact_caps() {
    let (mesh, report) = prepare(&pools(), &options()).unwrap();
    let r = manifold_report(&mesh);
    assert!(r.is_closed_manifold() && r.inconsistently_wound_edges == 0, "{r:?}");
    assert!(mesh.signed_volume_mm3() > 0.0, "outward");
    let mut labels = mesh.face_ids.clone();
    labels.sort_unstable();
    labels.dedup();
    assert_eq!(labels, vec![2, 11, 16]);
    check_cap(&mesh, 11, vsd_circle(), Vec3::x());
    check_cap(&mesh, 16, aortic_circle(), Vec3::z());
    // The RV sphere less the two spherical caps cut off by the openings.
    let cap_volume = |h: f64| std::f64::consts::PI * h * h * (3.0 * RV_RADIUS - h) / 3.0;
    let h_vsd = RV_RADIUS - (RV_CENTER_X - vsd_circle().0.x);
    let h_ao = RV_RADIUS - aortic_circle().0.z;
    let expected = 4.0 / 3.0 * std::f64::consts::PI * RV_RADIUS.powi(3) - cap_volume(h_vsd) - cap_volume(h_ao);
    assert!((report.volume_mm3 / expected - 1.0).abs() < 0.03, "volume {} vs {expected}", report.volume_mm3);
    eprintln!("{}", serde_json::to_string(&report).unwrap());
}

#[test]
fn separate_lv_and_rv_mean_no_vsd() {
    let mut p = pools();
    p.lv = uv_sphere(Vec3::new(-5.0, 0.0, 0.0), LV_RADIUS, 24, 48);
    let err = prepare(&p, &options()).unwrap_err();
    assert!(matches!(err, PrepareError::NoContact { what: "VSD", .. }), "{err}");
    let text = err.to_string();
    assert!(text.contains("LV") && text.contains("RV") && text.contains("VSD") && text.contains("mm apart"), "{text}");
}

#[test]
fn an_aorta_away_from_the_rv_means_no_annulus() {
    let mut p = pools();
    p.aorta = capped_tube(Vec3::new(RV_CENTER_X, 0.0, 12.0), Vec3::new(RV_CENTER_X, 0.0, 25.0), AORTA_RADIUS, 10, 32);
    let err = prepare(&p, &options()).unwrap_err().to_string();
    assert!(err.contains("RV and aorta") && err.contains("aortic annulus"), "{err}");
}

#[test]
fn bad_options_are_errors_not_panics() {
    for voxel_mm in [0.0, -1.0, f64::NAN] {
        let err = prepare(&pools(), &PrepareOptions { voxel_mm, ..options() }).unwrap_err();
        assert!(matches!(err, PrepareError::Option(_)), "{err}");
    }
}

/// The aorta tilted from the RV's top towards the VSD by `tilt_deg` (the
/// `aorta_tilt` example prints the seeded family): from 30 degrees it meets the LV.
fn tilted_aorta(tilt_deg: f64) -> BloodPools {
    let t = tilt_deg.to_radians();
    let (center, axis) = (Vec3::new(RV_CENTER_X, 0.0, 0.0), Vec3::new(-t.sin(), 0.0, t.cos()));
    BloodPools { aorta: capped_tube(center + axis * 4.0, center + axis * 25.0, AORTA_RADIUS, 20, 64), ..pools() }
}

#[test]
fn an_aorta_leaning_towards_the_vsd_is_capped_or_refused_never_capped_on_lv_wall() {
    // 0.5 mm clear of the LV at 25 degrees.
    let (mesh, report) = prepare(&tilted_aorta(25.0), &options()).unwrap();
    assert!(manifold_report(&mesh).is_closed_manifold());
    assert!((report.aortic_cap.area_mm2 / (std::f64::consts::PI * AORTA_RADIUS * AORTA_RADIUS) - 1.0).abs() < 0.15);
    // Touching it at 30 degrees the openings share a rim. The only cut pairs that part them
    // move the VSD cut 2 mm or more into the LV sphere, which widens behind the VSD: its
    // section there is 176 mm2 against the VSD's 91 mm2, and that cap was written as the
    // VSD cap (issue 27). Now refused, naming the widening.
    let err = prepare(&tilted_aorta(30.0), &options()).unwrap_err().to_string();
    assert!(err.contains("closes more than its opening") && err.contains("into the LV closes") && err.contains("LV wall as if it were the opening"), "{err}");
    // Over the LV at 45 degrees: refused, with where, why and how far the cuts were moved.
    let err = prepare(&tilted_aorta(45.0), &options()).unwrap_err().to_string();
    assert!(err.contains("the aorta comes within") && err.contains("of the LV near ("), "{err}");
    assert!(err.contains("did not separate them") && err.contains("9.0 mm up the aorta") && err.contains("% over the LV"), "{err}");
}
