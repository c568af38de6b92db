//! The patch template on the designed baffles of p1, p2 and p3 (and the phantom): the
//! flattened perimeter against the 3D seam, the distortion, the suture points and rims.

use baffle_core::io::{read_points, read_surface, CoordinateSystem};
use baffle_core::phantom::phantom_default;
use baffle_core::{design, DesignOptions, FaceLabels, TargetArea, TriMesh, Vec3};
use baffle_template::drawing::TemplateText;
use baffle_template::{template_from_domain, FlattenMethod};

fn patient(patient: &str) -> Option<(TriMesh, Vec<Vec3>, Vec<String>, TargetArea)> {
    let dir = baffle_test_support::reference_data::reference_data_if_present()?.join(patient);
    let table: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("../patients.json")).ok()?).ok()?;
    let bsa_m2 = table["patients"][patient]["bsa_m2"].as_f64()?;
    let surface = read_surface(&dir.join("design_input/capped_ventricle.vtp")).expect("surface");
    let points = read_points(&dir.join("design_input/suture_points.mrk.json")).expect("points");
    Some((surface, points.to_frame(CoordinateSystem::Lps), points.labels.clone(), TargetArea::Bsa { bsa_m2, z_score: 0.0 }))
}

fn check(name: &str, surface: &TriMesh, points: &[Vec3], labels: &[String], target: &TargetArea) {
    let result = design(surface, points, target, &DesignOptions::default(), &mut |_, _| true).unwrap_or_else(|e| panic!("{name}: design failed: {e}"));
    let text = TemplateText { patient_label: name.into(), date: "2026-01-01".into() };
    for method in [FlattenMethod::Lscm, FlattenMethod::LscmArap] {
        let template = template_from_domain(&result.domain, &FaceLabels::default(), points, labels, &text, method)
            .unwrap_or_else(|e| panic!("{name}: template failed: {e}"));
        println!("{name}, {method:?}:");
        let r = &template.flat.report;
        let seam_len: f64 = (0..result.seam_mm.len()).map(|k| (result.seam_mm[(k + 1) % result.seam_mm.len()] - result.seam_mm[k]).norm()).sum();
        println!(
            "{name}: {} triangles, seam {:.2} mm (design's seam {:.2} mm), perimeter {:.2} mm, error {:.1e}, scale {:.4}; \
         seam edge error median {:.2} % max {:.2} %; area change median {:.2} % max {:.2} %; angle change median {:.2} max {:.2} deg; \
         flat area {:.1} vs {:.1} mm2; suture point to seam max {:.2} mm; rims VSD {} Ao {} seam vertices (seam to caps {:.2}, {:.2} mm); CG {} it, ARAP {} it",
            r.triangles,
            r.seam_length_3d_mm,
            seam_len,
            r.perimeter_mm,
            r.perimeter_error,
            r.scale,
            100.0 * r.seam_edge_error_median,
            100.0 * r.seam_edge_error_max,
            100.0 * r.area_distortion_median,
            100.0 * r.area_distortion_max,
            r.angle_distortion_median_deg,
            r.angle_distortion_max_deg,
            r.area_flat_mm2,
            r.area_3d_mm2,
            template.suture_offsets_mm.iter().copied().fold(0.0, f64::max),
            template.vsd_rim_vertices,
            template.aortic_rim_vertices,
            template.seam_to_vsd_cap_mm,
            template.seam_to_aortic_cap_mm,
            r.cg_iterations,
            r.arap_iterations
        );
        // The baffle's boundary is the design's seam.
        assert!((r.seam_length_3d_mm - seam_len).abs() <= 1e-6 * seam_len, "{name}: boundary {:.3} vs seam {seam_len:.3}", r.seam_length_3d_mm);
        assert!(r.perimeter_error <= 0.01, "{name}: {r:?}");
        assert!(r.area_distortion_median.is_finite() && r.angle_distortion_max_deg.is_finite(), "{name}: {r:?}");
        assert!(template.flat.area_ratio.iter().all(|a| *a > 0.0), "{name}: a folded triangle");
        assert_eq!(template.suture_offsets_mm.len(), points.len());
        assert!(template.vsd_rim_vertices > 0 && template.aortic_rim_vertices > 0, "{name}: a rim is not marked");
    }
}

#[test]
fn templates_of_the_phantom_and_patients_keep_the_seam_length() {
    let p = phantom_default();
    check("phantom", &p.surface, &p.suture_points_mm, &[], &TargetArea::Bsa { bsa_m2: p.bsa_m2, z_score: 0.0 });
    for name in ["p1", "p2", "p3"] {
        if let Some((surface, points, labels, target)) = patient(name) {
            check(name, &surface, &points, &labels, &target);
        }
    }
}
