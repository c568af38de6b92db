//! Suture points of a patient's published seam, each moved by a random offset and put
//! back on the wall (as a surgeon's clicks scatter), designed one by one: counts the
//! outcomes by the error they end with. The CI check is `tests/seam_variants.rs`.
//!
//!     cargo run --release -p baffle-core --example seam_jitter -- p1 [radius_mm] [variants]

use baffle_core::geometry::numerics::random::SplitMix64;
use baffle_test_support::reference_data::{evenly_spaced_on_loop, published_seam_mm, reference_data_dir, scattered_clicks};
use baffle_core::geometry::spatial::TriangleBvh;
use baffle_core::{design, DesignOptions, TargetArea};
use std::collections::BTreeMap;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().collect();
    let patient = args.get(1).ok_or("usage: seam_jitter <patient> [radius_mm] [variants]")?;
    let radius_mm: f64 = args.get(2).map_or(Ok(2.0), |s| s.parse().map_err(|e| format!("{e}")))?;
    let variants: usize = args.get(3).map_or(Ok(40), |s| s.parse().map_err(|e| format!("{e}")))?;
    let dir = reference_data_dir().join(patient);
    let table: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("../patients.json")).map_err(|e| e.to_string())?)
            .map_err(|e| e.to_string())?;
    let bsa_m2 = table["patients"][patient.as_str()]["bsa_m2"].as_f64().ok_or("no bsa")?;
    let surface =
        baffle_core::io::read_surface(&dir.join("design_input/capped_ventricle.vtp")).map_err(|e| e.to_string())?;
    let bvh = TriangleBvh::new(&surface)?;
    let seam = published_seam_mm(&dir)?;
    let target = TargetArea::Bsa { bsa_m2, z_score: 0.0 };
    let mut outcomes: BTreeMap<String, usize> = BTreeMap::new();
    let mut rng = SplitMix64::new(7);
    for v in 0..variants {
        let n = 12 + rng.below(4);
        let on_loop = evenly_spaced_on_loop(&seam, n, rng.unit());
        let points = scattered_clicks(&surface, &bvh, 2, &on_loop, radius_mm, &mut rng);
        let key = match design(&surface, &points, &target, &DesignOptions::default(), &mut |_, _| true) {
            Ok(_) => "designed".to_string(),
            Err(e) => {
                let s = e.to_string();
                println!("{patient} variant {v} (N={n}): {s}");
                s.split(" near").next().unwrap_or(&s).chars().take(70).collect()
            }
        };
        *outcomes.entry(key).or_default() += 1;
    }
    for (k, c) in &outcomes {
        println!("{patient} r={radius_mm}: {c:4} {k}");
    }
    Ok(())
}
