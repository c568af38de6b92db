//! Hemodynamic inputs as in Martinez et al. (Table 4): cardiac output from the
//! cardiac index, mean flow, mean arterial pressure and the outlet resistance.

use serde::{Deserialize, Serialize};

/// 1 mmHg in dyn/cm^2 (one constant for the CFD and the design's estimate).
pub use baffle_core::analyses::hemodynamics_estimate::DYN_CM2_PER_MMHG;
/// 1 Wood unit (mmHg min/L) in dyn s/cm^5, the clinical rounding the paper uses.
pub const DYN_S_CM5_PER_WOOD: f64 = 80.0;
/// Paper's default cardiac index (L/min/m^2) and the elevated-flow scenario.
pub const CARDIAC_INDEX_DEFAULT_L_MIN_M2: f64 = 3.48;
pub const CARDIAC_INDEX_ELEVATED_L_MIN_M2: f64 = 4.22;
/// Peak-to-mean flow ratio of the paper's inflow waveform (Table 4: Q_peak = 3.26 Q_mean),
/// one constant for the CFD and the design's estimate.
pub use baffle_core::analyses::hemodynamics_estimate::PEAK_TO_MEAN_FLOW;

/// Clinical inputs of one patient.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClinicalInputs {
    pub bsa_m2: f64,
    pub sbp_mmhg: f64,
    pub dbp_mmhg: f64,
    pub cardiac_index_l_min_m2: f64,
}

/// Derived flow conditions (Table 4 columns).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Hemodynamics {
    pub cardiac_output_l_min: f64,
    pub q_mean_ml_s: f64,
    pub q_peak_ml_s: f64,
    pub map_mmhg: f64,
    pub resistance_dyn_s_cm5: f64,
    pub resistance_wood: f64,
}

/// MAP = (SBP + 2 DBP) / 3.
pub fn mean_arterial_pressure_mmhg(sbp_mmhg: f64, dbp_mmhg: f64) -> f64 {
    (sbp_mmhg + 2.0 * dbp_mmhg) / 3.0
}

/// Table 4 quantities. The paper rounds MAP to whole mmHg before R = MAP / Q_mean
/// (its R values are reproduced only that way, e.g. p2: 88 mmHg / 21.46 mL/s = 5467).
pub fn hemodynamics(inputs: &ClinicalInputs) -> Result<Hemodynamics, crate::CfdError> {
    let ClinicalInputs { bsa_m2, sbp_mmhg, dbp_mmhg, cardiac_index_l_min_m2 } = *inputs;
    let positive = [("BSA", bsa_m2), ("SBP", sbp_mmhg), ("DBP", dbp_mmhg), ("cardiac index", cardiac_index_l_min_m2)];
    for (name, value) in positive {
        if !(value.is_finite() && value > 0.0) {
            return Err(crate::CfdError::Settings(format!("{name} must be positive and finite, got {value}")));
        }
    }
    if dbp_mmhg > sbp_mmhg {
        return Err(crate::CfdError::Settings(format!("DBP {dbp_mmhg} mmHg exceeds SBP {sbp_mmhg} mmHg")));
    }
    let cardiac_output_l_min = cardiac_index_l_min_m2 * bsa_m2;
    let q_mean_ml_s = 1000.0 * cardiac_output_l_min / 60.0;
    let map_mmhg = mean_arterial_pressure_mmhg(sbp_mmhg, dbp_mmhg).round();
    let resistance_dyn_s_cm5 = map_mmhg * DYN_CM2_PER_MMHG / q_mean_ml_s;
    Ok(Hemodynamics {
        cardiac_output_l_min,
        q_mean_ml_s,
        q_peak_ml_s: PEAK_TO_MEAN_FLOW * q_mean_ml_s,
        map_mmhg,
        resistance_dyn_s_cm5,
        resistance_wood: resistance_dyn_s_cm5 / DYN_S_CM5_PER_WOOD,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_data::{patients_json, table4_hemodynamics, table_value};

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs()
    }

    #[test]
    fn table4_is_reproduced_for_published_patients() {
        let Some(json) = patients_json() else { return };
        for patient in ["p2", "p3"] {
            let v = |key: &str| table_value(&json, patient, key);
            let h = table4_hemodynamics(&json, patient);
            // Table values are printed rounded (CO to 0.01, Q to 0.1, R to 1, Wood to 0.1).
            assert!((h.cardiac_output_l_min - v("cardiac_output_l_min")).abs() <= 0.005, "{patient} CO {h:?}");
            assert!((h.q_mean_ml_s - v("q_mean_ml_s")).abs() <= 0.05, "{patient} Q {h:?}");
            assert!(rel(h.q_peak_ml_s, v("q_peak_ml_s")) < 0.01, "{patient} Qpeak {h:?}");
            assert_eq!(h.map_mmhg, v("map_mmhg"), "{patient}");
            assert!((h.resistance_dyn_s_cm5 - v("resistance_dyn_s_cm5")).abs() <= 1.0, "{patient} R {h:?}");
            // Wood units are printed from the rounded R (p3: 4876 / 80 = 60.95 -> 61.0).
            let wood_printed = (h.resistance_dyn_s_cm5.round() / DYN_S_CM5_PER_WOOD * 10.0).round() / 10.0;
            assert_eq!(wood_printed, v("resistance_wood"), "{patient} Wood {h:?}");
            assert!((h.resistance_wood - v("resistance_wood")).abs() <= 0.06, "{patient} Wood {h:?}");
        }
    }

    #[test]
    fn map_formula_and_bad_inputs() {
        assert_eq!(mean_arterial_pressure_mmhg(120.0, 60.0), 80.0);
        let bad = ClinicalInputs { bsa_m2: -1.0, sbp_mmhg: 100.0, dbp_mmhg: 60.0, cardiac_index_l_min_m2: 3.48 };
        assert!(hemodynamics(&bad).unwrap_err().to_string().contains("BSA"));
        let swapped = ClinicalInputs { bsa_m2: 0.3, sbp_mmhg: 60.0, dbp_mmhg: 100.0, cardiac_index_l_min_m2: 3.48 };
        assert!(hemodynamics(&swapped).unwrap_err().to_string().contains("exceeds"));
    }
}
