//! The suture-point variants of a patient's published seam, designed one by one:
//! N = 12..15 points evenly spaced along `design_input/published_seam.vtp`, each at
//! phases 0, 1/3 and 2/3 of the spacing, at the paper's BSA (z = 0, or the z-score
//! given). Prints each variant's outcome and time; the CI check of the same
//! variants is `tests/seam_variants.rs`.
//!
//!     cargo run --release -p baffle-core --example seam_variants -- p1 [z_score]

use baffle_test_support::reference_data::{evenly_spaced_on_loop, published_seam_mm, reference_data_dir};
use baffle_core::{design, DesignOptions, TargetArea};
use std::time::Instant;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().collect();
    let patient = args.get(1).ok_or("usage: seam_variants <patient> [z_score]")?;
    let z_score: f64 = args.get(2).map_or(Ok(0.0), |z| z.parse().map_err(|e| format!("z-score {z}: {e}")))?;
    let dir = reference_data_dir().join(patient);
    let table: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("../patients.json")).map_err(|e| format!("patients.json: {e}"))?,
    )
    .map_err(|e| format!("patients.json: {e}"))?;
    let bsa_m2 = table["patients"][patient.as_str()]["bsa_m2"].as_f64().ok_or("patients.json: no bsa_m2")?;
    let surface = baffle_core::io::read_surface(&dir.join("design_input/capped_ventricle.vtp")).map_err(|e| e.to_string())?;
    let seam = published_seam_mm(&dir)?;
    let target = TargetArea::Bsa { bsa_m2, z_score };
    let mut designed = 0;
    for n in 12..=15 {
        for phase in [0.0, 1.0 / 3.0, 2.0 / 3.0] {
            let points = evenly_spaced_on_loop(&seam, n, phase);
            let start = Instant::now();
            let outcome = design(&surface, &points, &target, &DesignOptions::default(), &mut |_, _| true);
            let ms = start.elapsed().as_secs_f64() * 1e3;
            match outcome {
                Ok(r) => {
                    designed += 1;
                    println!(
                        "{patient} N={n} phase={phase:.2}: baffle {:.1} mm2, smallest section {:.1} mm2 (target {:.1}), {} constrained + {} checked-only sections, {ms:.0} ms",
                        r.report.baffle_area_mm2,
                        r.report.min_constrained_final_area_mm2,
                        r.report.target_area_mm2,
                        r.report.constrained_sections,
                        r.report.checked_only_sections
                    );
                }
                Err(e) => println!("{patient} N={n} phase={phase:.2}: {e} ({ms:.0} ms)"),
            }
        }
    }
    println!("{patient}: {designed}/12 variants designed");
    Ok(())
}
