//! A target the seam cannot hold is answered with the largest one it can, and that
//! answer is true: designing at the reported area succeeds and every checked section
//! of the result re-measures (by `baffle-verify`) at or above it.

use baffle_core::phantom::phantom_with_suture_half_angle;
use baffle_core::{design, DesignError, DesignOptions, TargetArea, Vec3};

#[test]
fn an_infeasible_target_reports_a_largest_area_that_designs() {
    // The suture loop wrapped 100 degrees round the tunnel (the default phantom's is 70):
    // near the caps the sections have too little baffle to widen.
    let phantom = phantom_with_suture_half_angle(100.0).unwrap();
    let options = DesignOptions::default();
    let designs = |target: &TargetArea| design(&phantom.surface, &phantom.suture_points_mm, target, &options, &mut |_, _| true);
    // That tunnel holds 150 mm2 but not 300.
    let too_large = TargetArea::AreaMm2(300.0);
    let Err(DesignError::Infeasible { target_area_mm2, max_feasible_area_mm2, max_feasible_z_score, reason }) = designs(&too_large) else {
        panic!("the wrapped phantom at 300 mm2 should be infeasible")
    };
    println!("target {target_area_mm2:.1} mm2: at most {max_feasible_area_mm2:.1} mm2 (z {max_feasible_z_score:?}); {reason}");
    assert!(max_feasible_area_mm2 >= 150.0 && max_feasible_area_mm2 < target_area_mm2);
    // A target given as an area has no body size, so no z-score.
    assert_eq!(max_feasible_z_score, None);
    let result = designs(&TargetArea::AreaMm2(max_feasible_area_mm2)).expect("the reported largest area designs");
    for section in result.report.sections.iter().filter(|s| s.final_area_mm2.is_some()) {
        let area = baffle_verify::section_area_nearest(&result.domain, Vec3::from(section.origin_mm), Vec3::from(section.normal))
            .unwrap()
            .unwrap_or(0.0);
        assert!(area >= max_feasible_area_mm2, "s = {:.1} mm: {area:.2} < {max_feasible_area_mm2:.2}", section.s_mm);
    }
}
