//! A patient the design was not built on is every patient: the suture-point variants
//! of each published seam (N = 12..15 points evenly spaced along it, at phases 0,
//! 1/3 and 2/3 of the spacing; 12 per patient) must all design at the paper's BSA,
//! with every checked section re-measured by `baffle-verify`'s own slicer on the
//! domain (not the construction's numbers) at or above the target.

mod common;
#[path = "common/family.rs"]
mod family;

use baffle_core::reference_data::{evenly_spaced_on_loop, published_seam_mm};
use baffle_core::{design, DesignOptions, TargetArea};

fn variants_design(patient: &str) {
    let Some(data) = common::data_dir() else { return };
    let dir = data.join(patient);
    let table: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(data.join("patients.json")).unwrap()).unwrap();
    let bsa_m2 = table["patients"][patient]["bsa_m2"].as_f64().unwrap();
    let surface = baffle_core::io::read_surface(&dir.join("design_input/capped_ventricle.vtp")).unwrap();
    let seam = published_seam_mm(&dir).unwrap();
    let target = TargetArea::Bsa { bsa_m2, z_score: 0.0 };
    let mut failures = Vec::new();
    for n in 12..=15 {
        for phase in [0.0, 1.0 / 3.0, 2.0 / 3.0] {
            let name = format!("{patient} N={n} phase={phase:.2}");
            let points = evenly_spaced_on_loop(&seam, n, phase);
            match design(&surface, &points, &target, &DesignOptions::default(), &mut |_, _| true) {
                Ok(result) => {
                    let smallest = family::verified_smallest_section_mm2(&result).unwrap_or_else(|why| panic!("{name}: {why}"));
                    let checked = result.report.sections.iter().filter(|s| s.final_area_mm2.is_some()).count();
                    assert!(checked >= 10, "{name}: only {checked} checked sections");
                    println!("{name}: {checked} sections, smallest re-measured {smallest:.2} mm2 (target {:.2})", result.report.target_area_mm2);
                }
                Err(e) => failures.push(format!("{name}: {e}")),
            }
        }
    }
    assert!(failures.is_empty(), "{} of 12 variants failed:\n{}", failures.len(), failures.join("\n"));
}

#[test]
fn p1_suture_variants_design() {
    variants_design("p1");
}

#[test]
fn p2_suture_variants_design() {
    variants_design("p2");
}

#[test]
fn p3_suture_variants_design() {
    variants_design("p3");
}
