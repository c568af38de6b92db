//! Where the patients' reference data (the paper's public dataset) is read from by
//! tests, benchmarks and examples: `$BAFFLE_DATA_DIR`, else `shared/data` beside the
//! repository. It is read in place, never copied into the repository.

use std::path::PathBuf;

/// `$BAFFLE_DATA_DIR`, else `<repository>/../shared/data` (every crate of this
/// workspace sits two folders below the repository root, like this one).
pub fn reference_data_dir() -> PathBuf {
    std::env::var_os("BAFFLE_DATA_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data")))
}

/// The reference data directory if it holds the dataset; otherwise `None`, with a
/// note on stderr so a skipped check is visible. Under `CI=true` a missing dataset
/// panics instead: a broken path must not turn every real-data check into a pass.
pub fn reference_data_if_present() -> Option<PathBuf> {
    let dir = reference_data_dir();
    if dir.join("patients.json").is_file() {
        return Some(dir);
    }
    if running_in_ci() {
        panic!(
            "patient data not found at {} (CI=true: the real-data checks must run; set BAFFLE_DATA_DIR)",
            dir.display()
        );
    }
    eprintln!("note: patient data not found at {}; real-data checks skipped", dir.display());
    None
}

/// `CI` set to `true` or `1` (as `.ci/run` and most CI services do).
pub fn running_in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v.eq_ignore_ascii_case("true") || v == "1")
}

/// The published seam of a patient (`<patient>/design_input/published_seam.vtp`, a
/// closed polyline in mm), without the repeated closing point.
pub fn published_seam_mm(patient_dir: &std::path::Path) -> Result<Vec<baffle_core::Vec3>, String> {
    let path = patient_dir.join("design_input/published_seam.vtp");
    let polydata = baffle_core::io::read_polydata(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let line = polydata.lines.first().ok_or_else(|| format!("{}: no polyline", path.display()))?;
    let mut points: Vec<baffle_core::Vec3> = line.iter().map(|&i| polydata.points[i as usize]).collect();
    if points.len() > 1 && (points[0] - points[points.len() - 1]).norm() < 1e-9 {
        points.pop();
    }
    Ok(points)
}

/// `n` points spaced evenly by arc length along a closed polyline, the first at
/// `phase` (a fraction of the spacing) from its first vertex: how the suture-point
/// variants of a published seam are made (N = 12-15, phases 0, 1/3, 2/3).
pub fn evenly_spaced_on_loop(closed: &[baffle_core::Vec3], n: usize, phase: f64) -> Vec<baffle_core::Vec3> {
    let m = closed.len();
    let mut cumulative = vec![0.0];
    for k in 0..m {
        cumulative.push(cumulative[k] + (closed[(k + 1) % m] - closed[k]).norm());
    }
    let total = cumulative[m];
    (0..n)
        .map(|j| {
            let s = (j as f64 + phase) * total / n as f64;
            let k = cumulative.partition_point(|&c| c <= s).saturating_sub(1).min(m - 1);
            let t = (s - cumulative[k]) / (cumulative[k + 1] - cumulative[k]).max(1e-300);
            closed[k] + t * (closed[(k + 1) % m] - closed[k])
        })
        .collect()
}

/// Suture points as a surgeon's clicks scatter: `evenly_spaced_on_loop`'s points, each
/// moved by a random offset of up to `radius_mm` along each axis and put back onto the
/// nearest wall triangle (label `wall_label`) of `surface`.
pub fn scattered_clicks(
    surface: &baffle_core::TriMesh,
    bvh: &baffle_core::geometry::spatial::TriangleBvh,
    wall_label: i32,
    on_loop: &[baffle_core::Vec3],
    radius_mm: f64,
    rng: &mut baffle_core::geometry::numerics::random::SplitMix64,
) -> Vec<baffle_core::Vec3> {
    on_loop
        .iter()
        .filter_map(|p| {
            let offset = baffle_core::Vec3::new(rng.symmetric_unit(), rng.symmetric_unit(), rng.symmetric_unit()) * radius_mm;
            bvh.closest_point_filtered(surface, p + offset, |t| surface.face_ids[t as usize] == wall_label)
                .map(|hit| hit.point)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use baffle_core::Vec3;

    #[test]
    fn evenly_spaced_points_on_a_square() {
        let square =
            [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
        let points = evenly_spaced_on_loop(&square, 8, 0.0);
        assert_eq!(points.len(), 8);
        assert!((points[1] - Vec3::new(0.5, 0.0, 0.0)).norm() < 1e-12);
        assert!((points[5] - Vec3::new(0.5, 1.0, 0.0)).norm() < 1e-12);
        let shifted = evenly_spaced_on_loop(&square, 4, 0.5);
        assert!((shifted[0] - Vec3::new(0.5, 0.0, 0.0)).norm() < 1e-12);
        assert!((shifted[3] - Vec3::new(0.0, 0.5, 0.0)).norm() < 1e-12);
    }
}

/// A design input with its target: the phantom's, or a patient's `design_input/` at the
/// paper's BSA (Table 3) and z = 0.
pub struct DesignCase {
    pub name: String,
    pub surface: baffle_core::TriMesh,
    pub points: Vec<baffle_core::Vec3>,
    pub target: baffle_core::TargetArea,
}

/// The phantom, then p1-p3's design inputs where the data is present (tests and benches).
pub fn design_cases() -> Vec<DesignCase> {
    let p = baffle_core::phantom::phantom_default();
    let target = baffle_core::TargetArea::Bsa { bsa_m2: p.bsa_m2, z_score: 0.0 };
    let mut cases = vec![DesignCase { name: "phantom".into(), surface: p.surface, points: p.suture_points_mm, target }];
    let Some(dir) = reference_data_if_present() else { return cases };
    let table = std::fs::read_to_string(dir.join("patients.json")).expect("patients.json");
    let table: serde_json::Value = serde_json::from_str(&table).expect("patients.json");
    for patient in ["p1", "p2", "p3"] {
        let input = dir.join(patient).join("design_input");
        let surface = baffle_core::io::read_surface(&input.join("capped_ventricle.vtp")).expect("surface");
        let points = baffle_core::io::read_points(&input.join("suture_points.mrk.json")).expect("points").to_frame(baffle_core::io::CoordinateSystem::Lps);
        let bsa_m2 = table["patients"][patient]["bsa_m2"].as_f64().expect("bsa_m2");
        cases.push(DesignCase { name: patient.into(), surface, points, target: baffle_core::TargetArea::Bsa { bsa_m2, z_score: 0.0 } });
    }
    cases
}
