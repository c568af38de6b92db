//! The paper's published values beside ours, when the plan's input is one of its
//! patients: a `patients.json` (the data set's table of the paper's values) in a folder
//! above the input, and the input inside that patient's folder (e.g.
//! `data/p2/segmentations` with `data/patients.json` holding `p2`).

use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// patients.json: the paper's values per patient id (the table holds more).
#[derive(Deserialize)]
struct Table {
    patients: BTreeMap<String, Published>,
}

/// A patient's published values that the report sets beside ours (absent: not published).
#[derive(Deserialize)]
struct Published {
    target_area_mm2_table4: Option<f64>,
    flow_centerline_length_mm: Option<f64>,
    baffle_area_mm2: Option<f64>,
    baffle_triangles: Option<f64>,
    nominal_tets_thousands: Option<f64>,
    min_scaled_jacobian: Option<f64>,
    p1_scaled_jacobian: Option<f64>,
    p99_aspect_ratio: Option<f64>,
    cfd_dp_peak_mmhg: Option<f64>,
    cfd_centerline_vmax_m_s: Option<f64>,
}

impl Published {
    /// The published values by our quantity keys, in our units.
    fn by_our_keys(&self) -> Vec<(&'static str, f64)> {
        let values = [
            ("target_area_mm2", self.target_area_mm2_table4),
            ("flow_centerline_length_mm", self.flow_centerline_length_mm),
            ("baffle_area_mm2", self.baffle_area_mm2),
            ("baffle_triangles", self.baffle_triangles),
            ("tetrahedra", self.nominal_tets_thousands.map(|k| k * 1000.0)),
            ("min_scaled_jacobian", self.min_scaled_jacobian),
            ("p1_scaled_jacobian", self.p1_scaled_jacobian),
            ("p99_aspect_ratio", self.p99_aspect_ratio),
            ("dp_peak_mmhg", self.cfd_dp_peak_mmhg),
            ("max_centerline_velocity_m_s", self.cfd_centerline_vmax_m_s),
        ];
        values.into_iter().filter_map(|(key, value)| Some((key, value?))).collect()
    }
}

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
            let doc: Table = serde_json::from_str(&std::fs::read_to_string(&table).ok()?).ok()?;
            let values = doc.patients.get(&id)?.by_our_keys();
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
        // The table's other fields (of any kind) are not read.
        let table = r#"{ "source": "x", "patients": { "p2": { "cfd_dp_peak_mmhg": 1.58, "nominal_tets_thousands": 147, "baffle_area_mm2": 246.0, "note": "n", "bsa_m2": [0.37] } } }"#;
        std::fs::write(root.join("patients.json"), table).unwrap();
        let p = PaperPatient::of_input(&input).unwrap();
        assert_eq!(p.id, "p2");
        assert_eq!((p.value("dp_peak_mmhg"), p.value("tetrahedra"), p.value("baffle_triangles")), (Some(1.58), Some(147_000.0), None));
        assert!(PaperPatient::of_input(&root.join("p9").join("x.vtp")).is_none(), "not a patient of the table");
        assert!(PaperPatient::of_input(&std::env::temp_dir().join("elsewhere.vtp")).is_none());
        std::fs::remove_dir_all(root).ok();
    }
}
