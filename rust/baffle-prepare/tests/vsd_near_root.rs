//! Issue 27's failure, synthetically: a VSD in a septum the RV wraps around, on a wide LV
//! (semi-axes 16 x 16 x 22 mm) that widens behind the VSD, the aorta 15 mm from the VSD
//! loop. The plane through the VSD loop also cuts the RV where it wraps round the LV
//! (its rim runs 2.9-8.5 mm off the LV), so the cut has to move into the LV, where each
//! millimetre adds LV wall to the cap. The earlier code moved it 1 mm and wrote a
//! 287 mm2 VSD cap for a 225 mm2 VSD loop (the wrap of 0.06 / mm) without a word; now a
//! move stays where the cap still closes the VSD, or prepare refuses, naming the widening.

use baffle_core::geometry::spatial::TriangleBvh;
use baffle_prepare::lv_family::{lv_family_pools, LvFamilyParams};
use baffle_prepare::openings::largest_opening;
use baffle_prepare::{prepare, BloodPools, PrepareOptions};

/// The RV (semi-axes 9 and 20 mm) bent round the LV by `wrap_per_mm`, 1 mm into it at the
/// VSD; the aorta (r 6 mm) tilted 35 degrees away from the LV.
fn wrapped_rv(wrap_per_mm: f64) -> BloodPools {
    lv_family_pools(&LvFamilyParams {
        lv_semi_axes_mm: [16.0, 16.0, 22.0],
        lv_bend_per_mm: 0.0,
        vsd_height: 0.3,
        vsd_overlap_mm: 1.0,
        rv_semi_axes_mm: [9.0, 20.0],
        rv_bend_per_mm: wrap_per_mm,
        aorta_radius_mm: 6.0,
        aorta_tilt: 35f64.to_radians(),
        second_vsd: None,
    })
}

#[test]
fn a_slight_wrap_moves_the_vsd_cut_half_a_millimetre_and_keeps_the_vsd_cap() {
    let pools = wrapped_rv(0.04);
    let (_, report) = prepare(&pools, &PrepareOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let s = &report.separation;
    assert!(s.interface_loops_gap_mm > 14.0 && s.interface_loops_gap_mm < 18.0, "{s:?}");
    assert!(s.vsd_cut_moved_into_lv_mm <= 0.5, "{}", s.summary());
    assert!(report.checks.iter().all(|c| c.passed) && report.checks.len() == 6, "{:?}", report.checks);
    // Independently of prepare's checks: the LV's opening into the RV where they are at
    // most the closing's diameter plus a voxel apart (1.5 mm).
    let opening = largest_opening(&pools.lv, &pools.rv, &TriangleBvh::new(&pools.rv).unwrap(), 1.5).expect("an opening");
    let ratio = report.vsd_cap.area_mm2 / opening.area_mm2;
    let off = (baffle_core::Vec3::from(report.vsd_cap.centroid_mm) - opening.centroid_mm).norm();
    eprintln!("VSD cap {:.1} mm2, {ratio:.3} of the opening, centroid {off:.2} mm off; {}", report.vsd_cap.area_mm2, s.summary());
    assert!((ratio - 1.0).abs() < 0.25 && off < 1.5, "VSD cap {:.1} mm2 vs opening {:.1} mm2, {off:.2} mm off", report.vsd_cap.area_mm2, opening.area_mm2);
}

#[test]
fn a_tighter_wrap_is_refused_naming_the_widening_lv() {
    let err = prepare(&wrapped_rv(0.06), &PrepareOptions::default()).unwrap_err().to_string();
    assert!(err.contains("off the LV") && err.contains("into the LV closes") && err.contains("LV wall as if it were the opening"), "{err}");
}
