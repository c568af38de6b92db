//! Access to the read-only patient data for tests (BAFFLE_DATA_DIR or ../shared/data).

use std::path::PathBuf;

pub fn data_dir() -> Option<PathBuf> {
    baffle_test_support::reference_data::reference_data_if_present()
}

pub fn patients_json() -> Option<serde_json::Value> {
    let text = std::fs::read_to_string(data_dir()?.join("patients.json")).ok()?;
    Some(serde_json::from_str(&text).expect("patients.json is valid JSON"))
}

/// A number from patients.json: `patient` "common" or a patient id.
pub fn table_value(json: &serde_json::Value, patient: &str, key: &str) -> f64 {
    let v = if patient == "common" { &json["common"][key] } else { &json["patients"][patient][key] };
    v.as_f64().unwrap_or_else(|| panic!("patients.json has no number {patient}.{key}"))
}

/// The paper's hemodynamic inputs for `patient` (BSA, SBP, DBP, default cardiac index).
pub fn table4_hemodynamics(json: &serde_json::Value, patient: &str) -> crate::hemodynamics::Hemodynamics {
    use crate::hemodynamics::{hemodynamics, ClinicalInputs, CARDIAC_INDEX_DEFAULT_L_MIN_M2};
    let v = |key: &str| table_value(json, patient, key);
    let inputs = ClinicalInputs {
        bsa_m2: v("bsa_m2"),
        sbp_mmhg: v("sbp_mmhg"),
        dbp_mmhg: v("dbp_mmhg"),
        cardiac_index_l_min_m2: CARDIAC_INDEX_DEFAULT_L_MIN_M2,
    };
    hemodynamics(&inputs).expect("Table 4 inputs are valid")
}
