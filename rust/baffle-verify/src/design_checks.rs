//! The design's checks of its own output, by this crate's code rather than the
//! construction's: the domain's edges re-counted, its volume re-integrated, and every
//! section the design checked re-cut by this crate's plane slicer. A front end runs them
//! after a design and refuses to write a domain that fails one (report.json `checks`).

use crate::{edge_usage_counts, section_area_nearest, signed_volume_mm3};
use baffle_core::analyses::self_check::SelfCheck;
use baffle_core::{DesignResult, Vec3};

/// A section re-cut by other code may differ from the construction's by rounding only
/// (both cut the same triangles with the same plane).
const RECUT_RELATIVE_ROUNDING: f64 = 1e-9;

/// The design checks of `result`, each with its figure.
pub fn design_checks(result: &DesignResult) -> Vec<SelfCheck> {
    let (open, non_manifold) = edge_usage_counts(&result.domain);
    let mut checks = vec![SelfCheck::at_most(
        "domain edges used other than twice",
        (open + non_manifold) as f64,
        0.0,
        "count",
        format!("baffle-verify's edge count on the written domain: {open} open, {non_manifold} non-manifold"),
    )];
    let volume_mm3 = signed_volume_mm3(&result.domain).unwrap_or(f64::NAN);
    checks.push(SelfCheck::at_least("domain volume, outward", volume_mm3, 0.0, "mm3", "baffle-verify's divergence-theorem volume (positive: wound outward)"));
    checks.push(smallest_recut_section(result));
    checks
}

/// The smallest of the design's checked sections, each re-cut by `section_area_nearest`.
fn smallest_recut_section(result: &DesignResult) -> SelfCheck {
    let target_mm2 = result.report.target_area_mm2;
    let (mut smallest, mut at, mut count) = (f64::INFINITY, None, 0);
    for s in result.report.sections.iter().filter(|s| s.final_area_mm2.is_some()) {
        let area = match section_area_nearest(&result.domain, Vec3::from(s.origin_mm), Vec3::from(s.normal)) {
            Ok(Some(a)) => a,
            Ok(None) | Err(_) => 0.0,
        };
        count += 1;
        if area < smallest {
            (smallest, at) = (area, Some(s.s_mm));
        }
    }
    if count == 0 {
        smallest = 0.0;
    }
    let detail = match at {
        Some(s) => format!("{count} checked sections re-cut by baffle-verify's plane slicer; the smallest at s = {s:.2} mm along the centerline"),
        None => "the design checked no section".to_string(),
    };
    SelfCheck::at_least("smallest checked section, re-cut", smallest, target_mm2 * (1.0 - RECUT_RELATIVE_ROUNDING), "mm2", detail)
}

/// `result` with its checks in `report.checks`, or the first failed check as an error
/// (the domain is then not to be written).
pub fn checked_design(mut result: DesignResult) -> Result<DesignResult, baffle_core::DesignError> {
    let checks = design_checks(&result);
    baffle_core::analyses::self_check::first_failure(&checks).map_err(|why| baffle_core::DesignError::numerical("design self-check", why))?;
    result.report.checks = checks;
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;
    use baffle_core::phantom::phantom_default;
    use baffle_core::{design, DesignOptions, TargetArea};

    #[test]
    fn a_phantom_design_passes_its_checks_and_a_broken_domain_fails_them_by_name() {
        let p = phantom_default();
        let result = design(&p.surface, &p.suture_points_mm, &TargetArea::Bsa { bsa_m2: p.bsa_m2, z_score: 0.0 }, &DesignOptions::default(), &mut |_, _| true).unwrap();
        let checked = checked_design(result.clone()).unwrap();
        assert_eq!(checked.report.checks.len(), 3);
        assert!(checked.report.checks.iter().all(|c| c.passed), "{:?}", checked.report.checks);
        let mut open = result.clone();
        open.domain.triangles.pop();
        open.domain.face_ids.pop();
        let err = checked_design(open).unwrap_err().to_string();
        assert!(err.contains("domain edges used other than twice"), "{err}");
        // A domain shrunk toward the centerline's start has sections below the target.
        let mut narrow = result;
        let c = narrow.domain.points.iter().sum::<Vec3>() / narrow.domain.points.len() as f64;
        narrow.domain.points.iter_mut().for_each(|q| *q = c + 0.8 * (*q - c));
        let err = checked_design(narrow).unwrap_err().to_string();
        assert!(err.contains("smallest checked section, re-cut") && err.contains("mm2"), "{err}");
    }
}
