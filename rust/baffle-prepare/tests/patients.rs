//! `prepare` on patients p1, p2 and p3 of the paper's dataset, from their segmented
//! blood pools: the caps against the published ones (paper's surfaces, cm x 10),
//! the surface's topology, and `design` run on the result with the patient's
//! suture points. Skipped (with a note) when the data directory is absent.

use baffle_core::io::{read_points, read_surface, CoordinateSystem};
use baffle_core::geometry::mesh::manifold_report;
use baffle_test_support::reference_data::reference_data_if_present;
use baffle_core::{design, DesignOptions, TargetArea, TriMesh};
use baffle_prepare::voxelize::{voxelize, Grid};
use baffle_prepare::{pools_from_labelmap, prepare, read_segmentations, BloodPools, LabelMap, LabelSurfaceOptions, PoolLabels, PrepareOptions};
use std::path::Path;

/// Published VSD (11) and aortic-annulus (16) caps: centroid (mm) and area (mm2).
fn published_caps(dir: &Path) -> [(baffle_core::Vec3, f64); 2] {
    let mut published = read_surface(&dir.join("published_M_final.vtp")).expect("published surface");
    published.points.iter_mut().for_each(|p| *p *= 10.0);
    [11, 16].map(|label| {
        let (c, _, area) = published.label_centroid_normal(label).expect("published cap");
        (c, area)
    })
}

fn check_topology(name: &str, mesh: &TriMesh) {
    let r = manifold_report(mesh);
    assert!(r.is_closed_manifold() && r.inconsistently_wound_edges == 0, "{name}: {r:?}");
    assert!(mesh.signed_volume_mm3() > 0.0, "{name}: wound inward");
    let mut labels = mesh.face_ids.clone();
    labels.sort_unstable();
    labels.dedup();
    assert_eq!(labels, vec![2, 11, 16], "{name}: labels");
}

/// Prepare from `pools`; check the topology and the caps against the published ones.
fn check_caps(patient: &str, dir: &Path, pools: &BloodPools) -> TriMesh {
    let (mesh, report) = prepare(pools, &PrepareOptions::default()).unwrap_or_else(|e| panic!("{patient}: prepare failed: {e}"));
    check_topology(patient, &mesh);
    for ((label, name), (center, area)) in [(11, "VSD"), (16, "aortic")].into_iter().zip(published_caps(&dir)) {
        let (c, _, a) = mesh.label_centroid_normal(label).expect("cap");
        let distance = (c - center).norm();
        eprintln!("{patient} {name} cap: centroid {distance:.2} mm from the published one, area {a:.1} vs {area:.1} mm2 (ratio {:.3})", a / area);
        assert!(distance < 1.5, "{patient} {name} cap centroid {distance:.2} mm from the published one");
        assert!((a / area - 1.0).abs() < 0.25, "{patient} {name} cap area {a:.1} vs {area:.1} mm2");
    }
    for check in &report.checks {
        eprintln!("{patient}: {}: {:.3} {} (limit {:.3})", check.name, check.value, check.unit, check.limit);
    }
    assert_eq!(report.checks.len(), 6, "{patient}: centroid, area and rim of both caps");
    assert!(report.checks.iter().all(|c| c.passed), "{patient}: a failed check is an error, not a report entry");
    eprintln!("{patient}: {} triangles, {:.0} ms; {}", report.triangles, report.timings.total_ms, report.separation.summary());
    assert!(!report.separation.moved(), "{patient}: the openings are apart, the cuts stay in the loops' planes");
    mesh
}

fn check_patient(patient: &str) {
    let Some(data) = reference_data_if_present() else { return };
    let dir = data.join(patient);
    let pools = read_segmentations(&dir.join("segmentations")).expect("segmentations");
    let mesh = check_caps(patient, &dir, &pools);

    let table: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(data.join("patients.json")).unwrap()).unwrap();
    let bsa_m2 = table["patients"][patient]["bsa_m2"].as_f64().expect("bsa");
    let points = read_points(&dir.join("design_input/suture_points.mrk.json")).expect("points").to_frame(CoordinateSystem::Lps);
    let target = TargetArea::Bsa { bsa_m2, z_score: 0.0 };
    let result = design(&mesh, &points, &target, &DesignOptions::default(), &mut |_, _| true)
        .unwrap_or_else(|e| panic!("{patient}: design on the prepared surface failed: {e}"));
    let published_baffle = read_surface(&dir.join("published_baffle.vtp")).expect("published baffle").area_mm2() * 100.0;
    let ratio = result.report.baffle_area_mm2 / published_baffle;
    eprintln!("{patient}: designed baffle {:.1} mm2 vs published {published_baffle:.1} mm2 (ratio {ratio:.3})", result.report.baffle_area_mm2);
    assert!((0.8..1.25).contains(&ratio), "{patient}: baffle area ratio {ratio:.3}");
}

#[test]
fn p1_prepared_from_segmentations() {
    check_patient("p1");
}

#[test]
fn p2_prepared_from_segmentations() {
    check_patient("p2");
}

#[test]
fn p3_prepared_from_segmentations() {
    check_patient("p3");
}

/// p2's segmentations rasterized into a label map (0.4 mm, labels 1 LV, 2 RV, 6
/// aorta, RV first where the surfaces overlap), then prepared from it.
#[test]
fn p2_prepared_from_a_labelmap() {
    let Some(data) = reference_data_if_present() else { return };
    let dir = data.join("p2");
    let pools = read_segmentations(&dir.join("segmentations")).expect("segmentations");
    let lo = pools.rv.points.iter().fold(baffle_core::Vec3::repeat(f64::INFINITY), |a, p| a.inf(p)) - baffle_core::Vec3::repeat(8.0);
    let hi = pools.rv.points.iter().fold(baffle_core::Vec3::repeat(f64::NEG_INFINITY), |a, p| a.sup(p)) + baffle_core::Vec3::repeat(8.0);
    let grid = Grid::covering(lo, hi, 0.4, 0);
    let [lv, rv, aorta] = [&pools.lv, &pools.rv, &pools.aorta].map(|m| voxelize(m, &grid));
    let labels = (0..grid.voxel_count()).map(|v| if rv[v] { 2 } else if lv[v] { 1 } else if aorta[v] { 6 } else { 0 }).collect();
    let map = LabelMap { dims: grid.dims, labels, origin_mm: grid.origin, axes_mm: nalgebra::Matrix3::from_diagonal(&baffle_core::Vec3::repeat(0.4)) };
    let from_map = pools_from_labelmap(&map, &PoolLabels::default(), &LabelSurfaceOptions::default()).expect("label surfaces");
    check_caps("p2 (label map)", &dir, &from_map);
}
