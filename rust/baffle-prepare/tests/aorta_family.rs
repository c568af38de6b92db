//! `prepare` and `design` on the aorta-tilt family (`aorta_family`): the aorta leans
//! from the RV's top toward the VSD until it sits over the LV. Where the VSD and the
//! annulus meet, prepare must move its cuts apart and say by how much, or refuse saying
//! why; a prepared surface is re-measured here, independently of prepare's own report:
//! closed, outward, labelled, two flat caps, each rim on its own pool, the caps apart
//! and no farther from the true interfaces than the reported moves.

use baffle_core::geometry::spatial::TriangleBvh;
use baffle_core::{design, DesignOptions, TargetArea, TriMesh, Vec3};
use baffle_prepare::aorta_family::{aorta_tilt_member, AortaTiltMember};
use baffle_prepare::{prepare, PrepareOptions, PrepareReport};
use baffle_verify::{edge_usage_counts, is_consistently_oriented, signed_volume_mm3};

/// Tilts 0-25 degrees, one member in each 5 degrees: the aorta clear of the LV, then
/// touching it, then over the VSD (the `aorta_tilt` example runs the
/// whole family to 75 degrees, where the aorta arises from the LV and prepare refuses, at
/// 100 clips of a wide union each; `synthetic.rs` tests one refusal).
const SEEDS: std::ops::Range<u64> = 0..5;

fn options() -> PrepareOptions {
    PrepareOptions { voxel_mm: 0.3, closing_radius_mm: 0.0, ..PrepareOptions::default() }
}

/// The rim points of cap `label`, and the cap's largest distance from its own plane (mm).
fn cap_rim_and_flatness(mesh: &TriMesh, label: i32) -> (Vec<Vec3>, f64) {
    let cap = mesh.with_labels(|l| l == label);
    let loops = cap.boundary_loops().expect("cap boundary");
    assert_eq!(loops.len(), 1, "cap {label} is one disc");
    let (c, n, _) = cap.label_centroid_normal(label).expect("cap");
    let off = cap.points.iter().map(|p| (p - c).dot(&n).abs()).fold(0.0, f64::max);
    (loops[0].iter().map(|&v| cap.points[v as usize]).collect(), off)
}

fn farthest_from(points: &[Vec3], surface: &TriMesh) -> f64 {
    let bvh = TriangleBvh::new(surface).unwrap();
    points.iter().filter_map(|&p| bvh.closest_point(surface, p)).map(|h| h.distance_mm).fold(0.0, f64::max)
}

/// Everything a prepared member must satisfy; returns a table note.
fn check_prepared(m: &AortaTiltMember, mesh: &TriMesh, report: &PrepareReport) -> String {
    let name = format!("seed {} (tilt {:.1} deg, aorta r {:.2} mm)", m.seed, m.params.tilt_deg, m.params.aorta_radius_mm);
    assert_eq!(edge_usage_counts(mesh), (0, 0), "{name}: not closed and manifold");
    assert!(is_consistently_oriented(mesh) && signed_volume_mm3(mesh).unwrap() > 0.0, "{name}: not outward-wound");
    let mut labels = mesh.face_ids.clone();
    labels.sort_unstable();
    labels.dedup();
    assert_eq!(labels, [2, 11, 16], "{name}: labels");
    let (vsd_rim, vsd_flat) = cap_rim_and_flatness(mesh, 11);
    let (ao_rim, ao_flat) = cap_rim_and_flatness(mesh, 16);
    assert!(vsd_flat < 1e-6 && ao_flat < 1e-6, "{name}: caps {vsd_flat:.1e} / {ao_flat:.1e} mm off planar");
    let s = &report.separation;
    let gap = vsd_rim.iter().flat_map(|p| ao_rim.iter().map(move |q| (p - q).norm())).fold(f64::INFINITY, f64::min);
    assert!((gap - s.rim_gap_mm).abs() < 1e-9 && gap >= 0.9 * s.clearance_mm, "{name}: rims {gap:.3} mm apart, reported {:.3}", s.rim_gap_mm);
    let on_lv = farthest_from(&vsd_rim, &m.pools.lv);
    let on_aorta = farthest_from(&ao_rim, &m.pools.aorta);
    assert!(on_lv < 1.0 && on_aorta < 1.0, "{name}: the VSD rim is up to {on_lv:.2} mm off the LV, the aortic rim {on_aorta:.2} mm off the aorta");
    // The caps lie at the interfaces, moved by no more than the report says.
    let (vsd_c, _, _) = mesh.label_centroid_normal(11).unwrap();
    let (ao_c, ao_n, ao_area) = mesh.label_centroid_normal(16).unwrap();
    let vsd_off = (vsd_c - m.params.vsd_circle().0).norm();
    let ao_off = (ao_c - m.params.annulus_center()).norm();
    assert!(vsd_off <= s.vsd_cut_moved_into_lv_mm + 1.0, "{name}: VSD cap {vsd_off:.2} mm from the VSD, moved {:.1}", s.vsd_cut_moved_into_lv_mm);
    assert!(ao_off <= s.aortic_cut_moved_into_aorta_mm + 1.5, "{name}: aortic cap {ao_off:.2} mm from the annulus, moved {:.1}", s.aortic_cut_moved_into_aorta_mm);
    let section = std::f64::consts::PI * m.params.aorta_radius_mm.powi(2) / ao_n.dot(&m.params.aorta_axis()).abs();
    assert!((ao_area / section - 1.0).abs() < 0.2, "{name}: aortic cap {ao_area:.1} mm2, the tube's section there {section:.1}");
    format!("VSD cap {vsd_off:.2} mm from the VSD, aortic cap {ao_off:.2} mm from the annulus, rims {gap:.2} mm apart")
}

#[test]
fn the_aorta_tilt_family_is_separated_or_refused_with_reasons_and_designs() {
    let (mut separated, mut refused, mut widened, mut designed) = (0, 0, 0, 0);
    for seed in SEEDS {
        let m = aorta_tilt_member(seed);
        match prepare(&m.pools, &options()) {
            Ok((mesh, report)) => {
                let note = check_prepared(&m, &mesh, &report);
                let s = &report.separation;
                separated += usize::from(s.moved());
                let target = TargetArea::AreaMm2(m.target_area_mm2);
                let outcome = match design(&mesh, &m.suture_points_mm, &target, &DesignOptions::default(), &mut |_, _| true) {
                    Ok(r) => {
                        designed += 1;
                        assert_eq!(edge_usage_counts(&r.domain), (0, 0), "seed {seed}: designed domain not closed");
                        format!("design ok ({:.1} mm2 baffle)", r.report.baffle_area_mm2)
                    }
                    Err(e) => format!("design failed: {e}"),
                };
                eprintln!("seed {seed} tilt {:.1}: moves {:.1} / {:.1} mm; {note}; {outcome}", m.params.tilt_deg, s.vsd_cut_moved_into_lv_mm, s.aortic_cut_moved_into_aorta_mm);
            }
            Err(e) => {
                let text = e.to_string();
                eprintln!("seed {seed} tilt {:.1}: refused: {text}", m.params.tilt_deg);
                // Refused either because no cut pair separates the openings, or because the
                // only pairs that do move the VSD cut into the LV where it widens, so that
                // its cap would close LV wall as if it were the VSD (issue 27).
                assert!(text.contains("did not separate them") && text.contains("% over the LV"), "seed {seed}: an unexplained refusal: {text}");
                widened += usize::from(text.contains("closes more than its opening"));
                refused += 1;
            }
        }
    }
    eprintln!("{separated} separated by moved cuts, {refused} refused, {designed} designed of {}", SEEDS.end - SEEDS.start);
    // Measured: seeds 0 and 1 clean, 2 separated by a 0.5 mm aortic move, each then
    // designed. Seeds 3 and 4 (and 5, 6: `aorta_tilt` example) were separated by moving
    // the VSD cut 2-4.5 mm into the LV sphere, whose section there is 1.7-2.8 times the
    // VSD (175 vs 105 mm2 for seed 3): they are now refused, naming the widening.
    assert!(separated >= 1, "members separated by moved cuts: {separated}");
    assert_eq!((refused, widened), (2, 2), "refusals, and those for a VSD cut that would close LV wall");
    assert_eq!(designed, SEEDS.end - SEEDS.start - refused, "every prepared member designs");
}
