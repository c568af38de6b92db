//! The realism family of `prepare` (issue 27): the same anatomy as a scanner and a
//! segmentation tool would hand it over. Each member's segmentations are re-voxelized
//! (rasterized into a label map at 0.3-1.0 mm and surfaced again, walls smoothed as a
//! label map's are) or the whole scene is moved rigidly (rotated about an oblique axis
//! and shifted). Every member must prepare with all its self-checks passed, or be
//! refused by a named check; a rigidly moved scene must give the same caps, moved with it.

use baffle_test_support::reference_data::reference_data_if_present;
use baffle_core::{TriMesh, Vec3};
use baffle_prepare::shapes::synthetic_heart;
use baffle_prepare::voxelize::{voxelize, Grid};
use baffle_prepare::{pools_from_labelmap, prepare, read_segmentations, BloodPools, LabelMap, LabelSurfaceOptions, PoolLabels, PrepareOptions, PrepareReport};
use nalgebra::{Rotation3, Unit};

/// A rotation of 37 degrees about an oblique axis and a shift of (12, -7, 5) mm: no
/// voxel grid axis stays on one.
fn motion() -> (Rotation3<f64>, Vec3) {
    (Rotation3::from_axis_angle(&Unit::new_normalize(Vec3::new(1.0, 2.0, 0.5)), 37f64.to_radians()), Vec3::new(12.0, -7.0, 5.0))
}

fn moved(mesh: &TriMesh) -> TriMesh {
    let (r, t) = motion();
    TriMesh { points: mesh.points.iter().map(|p| r * p + t).collect(), ..mesh.clone() }
}

fn moved_pools(p: &BloodPools) -> BloodPools {
    BloodPools { lv: moved(&p.lv), rv: moved(&p.rv), aorta: moved(&p.aorta) }
}

/// The pools rasterized at `voxel_mm` (labels 1 LV, 2 RV, 6 aorta; the RV first where
/// they overlap, as a segmentation assigns each voxel one label) and surfaced again.
fn revoxelized(p: &BloodPools, voxel_mm: f64) -> BloodPools {
    let lo = p.rv.points.iter().fold(Vec3::repeat(f64::INFINITY), |a, q| a.inf(q)) - Vec3::repeat(10.0);
    let hi = p.rv.points.iter().fold(Vec3::repeat(f64::NEG_INFINITY), |a, q| a.sup(q)) + Vec3::repeat(10.0);
    let grid = Grid::covering(lo, hi, voxel_mm, 0);
    let [lv, rv, aorta] = [&p.lv, &p.rv, &p.aorta].map(|m| voxelize(m, &grid));
    let labels = (0..grid.voxel_count()).map(|v| if rv[v] { 2 } else if lv[v] { 1 } else if aorta[v] { 6 } else { 0 }).collect();
    let map = LabelMap { dims: grid.dims, labels, origin_mm: grid.origin, axes_mm: nalgebra::Matrix3::from_diagonal(&Vec3::repeat(voxel_mm)) };
    pools_from_labelmap(&map, &PoolLabels::default(), &LabelSurfaceOptions::default()).expect("label surfaces")
}

/// Prepared (every check passed) or refused by a named self-check or step; the note says which.
fn outcome(name: &str, pools: &BloodPools, options: &PrepareOptions) -> Option<PrepareReport> {
    match prepare(pools, options) {
        Ok((_, report)) => {
            assert!(!report.checks.is_empty() && report.checks.iter().all(|c| c.passed), "{name}: {:?}", report.checks);
            eprintln!("{name}: prepared, VSD cap {:.1} mm2, aortic cap {:.1} mm2; {}", report.vsd_cap.area_mm2, report.aortic_cap.area_mm2, report.separation.summary());
            Some(report)
        }
        Err(e) => {
            let text = e.to_string();
            eprintln!("{name}: refused: {text}");
            let named = text.contains("self-check failed") || text.contains("did not separate them") || text.contains(" mm apart");
            assert!(named, "{name}: refused without a named check: {text}");
            None
        }
    }
}

/// The moved scene's caps against the original's: areas within 0.5 %, centroids moved
/// with the scene within 0.01 mm. `prepare` voxelizes in a frame fixed to the anatomy,
/// so the grid moves with the scene (on an axis-aligned grid p1's caps changed by 3.3 %).
fn check_rigid(name: &str, original: &PrepareReport, moved_report: &PrepareReport) {
    let (r, t) = motion();
    for (a, b, cap) in [(&original.vsd_cap, &moved_report.vsd_cap, "VSD"), (&original.aortic_cap, &moved_report.aortic_cap, "aortic")] {
        let area_pct = 100.0 * (b.area_mm2 / a.area_mm2 - 1.0);
        let off = (r * Vec3::from(a.centroid_mm) + t - Vec3::from(b.centroid_mm)).norm();
        eprintln!("{name} {cap} cap after the motion: area {area_pct:+.2e} %, centroid {off:.2e} mm off the moved one");
        assert!(area_pct.abs() <= 0.5, "{name}: the {cap} cap's area changed by {area_pct:.3} % under a rigid motion");
        assert!(off <= 0.01, "{name}: the {cap} cap's centroid is {off:.3} mm off the moved one");
    }
}

/// The sample run's synthetic heart: LV and RV spheres, an aorta tube of radius 4 mm.
fn synthetic_pools() -> BloodPools {
    let heart = synthetic_heart();
    BloodPools { lv: heart.lv, rv: heart.rv, aorta: heart.aorta }
}

/// The synthetic heart re-voxelized at 0.3, 0.5, 0.75 and 1.0 mm, and moved rigidly.
#[test]
fn the_synthetic_heart_prepares_revoxelized_and_moved() {
    let options = PrepareOptions::default();
    let pools = synthetic_pools();
    let (mut prepared, mut refused) = (0, 0);
    for voxel_mm in [0.3, 0.5, 0.75, 1.0] {
        match outcome(&format!("synthetic re-voxelized at {voxel_mm} mm"), &revoxelized(&pools, voxel_mm), &options) {
            Some(_) => prepared += 1,
            None => refused += 1,
        }
    }
    let original = outcome("synthetic", &pools, &options).expect("the synthetic heart prepares");
    let after = outcome("synthetic moved", &moved_pools(&pools), &options).expect("the moved synthetic heart prepares");
    check_rigid("synthetic", &original, &after);
    eprintln!("synthetic realism family: {} prepared, {refused} refused of 6", prepared + 2);
}

/// p1-p3 re-voxelized at 0.6 mm and moved rigidly; required in CI.
#[test]
fn the_patients_prepare_revoxelized_and_moved() {
    let Some(data) = reference_data_if_present() else { return };
    let options = PrepareOptions::default();
    let (mut prepared, mut refused) = (0, 0);
    for patient in ["p1", "p2", "p3"] {
        let pools = read_segmentations(&data.join(patient).join("segmentations")).expect("segmentations");
        let original = outcome(patient, &pools, &options).expect("the patient prepares");
        let after = outcome(&format!("{patient} moved"), &moved_pools(&pools), &options);
        match after {
            Some(after) => {
                check_rigid(patient, &original, &after);
                prepared += 1;
            }
            None => refused += 1,
        }
        match outcome(&format!("{patient} re-voxelized at 0.6 mm"), &revoxelized(&pools, 0.6), &options) {
            Some(_) => prepared += 1,
            None => refused += 1,
        }
    }
    eprintln!("patient realism family: {prepared} prepared, {refused} refused of 6 (besides the 3 originals)");
    assert_eq!(refused, 0, "the patients' re-voxelized and moved segmentations all prepare");
}
