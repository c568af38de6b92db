//! The extended domain's caps on the patients' published and designed domains (as
//! tests/extend.rs builds them): inflow / outflow cap centroid, normal and area, the
//! mid-LV plane's depth and move, and the triangle counts, one line each, to compare
//! extend before and after a change.
//!
//!     cargo run --release -p baffle-prepare --example extend_caps [p1 p2 p3]

use baffle_core::io::{read_points, read_surface, CoordinateSystem};
use baffle_test_support::reference_data::reference_data_if_present;
use baffle_core::{design, DesignOptions, TargetArea, TriMesh};
use baffle_prepare::extend::{extend, ExtendOptions, Extended};
use baffle_prepare::{prepare, read_segmentations, PrepareOptions};

fn main() {
    let Some(data) = reference_data_if_present() else { return eprintln!("no patient data") };
    let args: Vec<String> = std::env::args().skip(1).collect();
    let patients = if args.is_empty() { vec!["p1".to_string(), "p2".into(), "p3".into()] } else { args };
    for patient in &patients {
        let dir = data.join(patient);
        let pools = read_segmentations(&dir.join("segmentations")).expect("segmentations");
        let published = published_domain(&dir.join("published_M_final.vtp"));
        let options = ExtendOptions { remesh_edge_mm: Some(0.8), ..ExtendOptions::default() };
        print_caps(&format!("{patient} published"), extend(&published, &pools, &options));
        let (capped, _) = prepare(&pools, &PrepareOptions::default()).expect("prepare");
        let table: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(data.join("patients.json")).unwrap()).unwrap();
        let bsa_m2 = table["patients"][patient.as_str()]["bsa_m2"].as_f64().expect("bsa");
        let points = read_points(&dir.join("design_input/suture_points.mrk.json")).expect("points").to_frame(CoordinateSystem::Lps);
        let target = TargetArea::Bsa { bsa_m2, z_score: 0.0 };
        match design(&capped, &points, &target, &DesignOptions::default(), &mut |_, _| true) {
            Ok(designed) => print_caps(&format!("{patient} designed"), extend(&designed.domain, &pools, &ExtendOptions::default())),
            Err(e) => println!("{patient} designed: design failed: {e}"),
        }
    }
}

fn published_domain(path: &std::path::Path) -> TriMesh {
    let mut domain = read_surface(path).expect("published domain");
    domain.points.iter_mut().for_each(|p| *p *= 10.0);
    if domain.signed_volume_mm3() < 0.0 {
        domain.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    }
    domain
}

fn print_caps(name: &str, result: Result<Extended, baffle_prepare::PrepareError>) {
    let r = match result {
        Ok(e) => e.report,
        Err(e) => return println!("{name}: extend failed: {e}"),
    };
    let f = |v: [f64; 3]| format!("({:.3}, {:.3}, {:.3})", v[0], v[1], v[2]);
    println!("{name}: inflow {} n {} {:.2} mm2; outflow {} {:.2} mm2; mid-LV {:.2} mm beyond the VSD, moved {:+.0} mm; LV part {} tris, aortic {} tris, volume {:.1} mm3",
        f(r.inflow_cap.centroid_mm), f(r.inflow_cap.normal), r.inflow_cap.area_mm2, f(r.outflow_cap.centroid_mm), r.outflow_cap.area_mm2,
        r.mid_lv_plane.distance_from_vsd_mm, r.mid_lv_plane.moved_from_centroid_mm, r.lv_extension_triangles, r.aortic_extension_triangles, r.volume_mm3);
}
