//! The paper's published values beside ours, when the plan's input is one of its
//! patients: a `patients.json` (the data set's table of the paper's values) in a folder
//! above the input, and the input inside that patient's folder (e.g.
//! `data/p2/segmentations` with `data/patients.json` holding `p2`).

use serde_json::Value;
use std::path::{Path, PathBuf};

/// Our quantity key -> the table's key and the factor from the table's unit to ours.
const KEYS: &[(&str, &str, f64)] = &[
    ("target_area_mm2", "target_area_mm2_table4", 1.0),
    ("flow_centerline_length_mm", "flow_centerline_length_mm", 1.0),
    ("baffle_area_mm2", "baffle_area_mm2", 1.0),
    ("baffle_triangles", "baffle_triangles", 1.0),
    ("tetrahedra", "nominal_tets_thousands", 1000.0),
    ("min_scaled_jacobian", "min_scaled_jacobian", 1.0),
    ("p1_scaled_jacobian", "p1_scaled_jacobian", 1.0),
    ("p99_aspect_ratio", "p99_aspect_ratio", 1.0),
    ("dp_peak_mmhg", "cfd_dp_peak_mmhg", 1.0),
    ("max_centerline_velocity_m_s", "cfd_centerline_vmax_m_s", 1.0),
];

/// A patient of the paper and its published values, by our quantity keys.
pub struct PaperPatient {
    pub id: String,
    pub table: PathBuf,
    pub values: Vec<(&'static str, f64)>,
}

impl PaperPatient {
    /// The paper's patient `input` belongs to, if any.
    pub fn of_input(input: &Path) -> Option<PaperPatient> {
        let input = std::path::absolute(input).ok()?;
        for dir in input.ancestors().skip(1) {
            let table = dir.join("patients.json");
            if !table.is_file() {
                continue;
            }
            let id = input.strip_prefix(dir).ok()?.components().next()?.as_os_str().to_str()?.to_string();
            let doc: Value = serde_json::from_str(&std::fs::read_to_string(&table).ok()?).ok()?;
            let patient = doc["patients"].get(&id)?;
            let values = KEYS.iter().filter_map(|&(ours, theirs, factor)| Some((ours, patient[theirs].as_f64()? * factor))).collect();
            return Some(PaperPatient { id, table, values });
        }
        None
    }

    pub fn value(&self, key: &str) -> Option<f64> {
        self.values.iter().find(|(k, _)| *k == key).map(|(_, v)| *v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_patients_folder_under_a_table_finds_its_published_values() {
        let root = std::env::temp_dir().join(format!("baffle-paper-{}", std::process::id()));
        let input = root.join("p2").join("segmentations");
        std::fs::create_dir_all(&input).unwrap();
        let table = r#"{ "patients": { "p2": { "cfd_dp_peak_mmhg": 1.58, "nominal_tets_thousands": 147, "baffle_area_mm2": 246.0 } } }"#;
        std::fs::write(root.join("patients.json"), table).unwrap();
        let p = PaperPatient::of_input(&input).unwrap();
        assert_eq!(p.id, "p2");
        assert_eq!((p.value("dp_peak_mmhg"), p.value("tetrahedra"), p.value("baffle_triangles")), (Some(1.58), Some(147_000.0), None));
        assert!(PaperPatient::of_input(&root.join("p9").join("x.vtp")).is_none(), "not a patient of the table");
        assert!(PaperPatient::of_input(&std::env::temp_dir().join("elsewhere.vtp")).is_none());
        std::fs::remove_dir_all(root).ok();
    }
}
