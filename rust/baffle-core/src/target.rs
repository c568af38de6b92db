//! The target cross-sectional area of the baffle's outflow (paper Table 3).
//!
//! The paper sizes the LV-to-aorta pathway to the normal aortic annulus for the
//! patient's body size: BSA (Haycock) -> Boston (Colan 2006) annulus diameter at a
//! chosen z-score -> area of the circle of that diameter.

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Body surface area (m^2) by Haycock et al.
pub fn haycock_bsa_m2(height_cm: f64, weight_kg: f64) -> f64 {
    0.024265 * weight_kg.powf(0.5378) * height_cm.powf(0.3964)
}

/// Aortic annulus diameter (cm) from the Boston z-score relation as the paper's
/// issue states it: 1.55 sqrt(BSA) + z (0.06 + 0.083 BSA).
pub fn boston_aortic_annulus_diameter_cm(bsa_m2: f64, z_score: f64) -> f64 {
    1.55 * bsa_m2.sqrt() + z_score * (0.06 + 0.083 * bsa_m2)
}

/// The Boston z-score of an annulus of `diameter_cm` (the relation above inverted).
pub fn boston_z_score(bsa_m2: f64, diameter_cm: f64) -> f64 {
    (diameter_cm - 1.55 * bsa_m2.sqrt()) / (0.06 + 0.083 * bsa_m2)
}

/// Area (mm^2) of the circle of diameter `diameter_mm`.
pub fn circle_area_mm2(diameter_mm: f64) -> f64 {
    PI * (0.5 * diameter_mm).powi(2)
}

/// How the target area is specified: directly, by annulus diameter, or from body size.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum TargetArea {
    AreaMm2(f64),
    AnnulusDiameterMm(f64),
    Bsa { bsa_m2: f64, z_score: f64 },
    HeightWeight { height_cm: f64, weight_kg: f64, z_score: f64 },
}

// Plausible ranges; values outside them are almost certainly unit mistakes.
const BSA_RANGE_M2: (f64, f64) = (0.1, 3.0);
const HEIGHT_RANGE_CM: (f64, f64) = (30.0, 250.0);
const WEIGHT_RANGE_KG: (f64, f64) = (1.0, 250.0);
const Z_SCORE_RANGE: (f64, f64) = (-5.0, 5.0);
const AREA_RANGE_MM2: (f64, f64) = (1.0, 2000.0);

/// `value` if finite and within [min, max], else an error naming it.
fn checked(name: &str, value: f64, (min, max): (f64, f64)) -> Result<f64, String> {
    if value.is_finite() && value >= min && value <= max {
        Ok(value)
    } else {
        Err(format!("{name} = {value} is outside the plausible range [{min}, {max}]"))
    }
}

/// Finite and strictly positive, else an error naming the value.
fn checked_positive(name: &str, value: f64) -> Result<f64, String> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(format!("{name} = {value} must be a positive finite number"))
    }
}

impl TargetArea {
    /// The target area in mm^2, validating every input.
    pub fn area_mm2(&self) -> Result<f64, String> {
        let area_mm2 = match *self {
            TargetArea::AreaMm2(area_mm2) => checked_positive("area (mm2)", area_mm2)?,
            TargetArea::AnnulusDiameterMm(diameter_mm) => {
                circle_area_mm2(checked_positive("annulus diameter (mm)", diameter_mm)?)
            }
            _ => circle_area_mm2(self.annulus_diameter_mm()?),
        };
        checked("area (mm2)", area_mm2, AREA_RANGE_MM2)
    }

    /// Annulus diameter (mm) for the body-size variants, the given diameter for
    /// `AnnulusDiameterMm`, and the equivalent circle's diameter for `AreaMm2`.
    pub fn annulus_diameter_mm(&self) -> Result<f64, String> {
        match *self {
            TargetArea::AreaMm2(_) => Ok(2.0 * (self.area_mm2()? / PI).sqrt()),
            TargetArea::AnnulusDiameterMm(diameter_mm) => checked_positive("annulus diameter (mm)", diameter_mm),
            TargetArea::Bsa { bsa_m2, z_score } => boston_diameter_mm(bsa_m2, z_score),
            TargetArea::HeightWeight { z_score, .. } => boston_diameter_mm(self.bsa_m2()?, z_score),
        }
    }

    /// Body surface area (m^2) for the body-size variants; an error for the others.
    pub fn bsa_m2(&self) -> Result<f64, String> {
        match *self {
            TargetArea::Bsa { bsa_m2, .. } => checked("BSA (m2)", bsa_m2, BSA_RANGE_M2),
            TargetArea::HeightWeight { height_cm, weight_kg, .. } => {
                let height_cm = checked("height (cm)", height_cm, HEIGHT_RANGE_CM)?;
                let weight_kg = checked("weight (kg)", weight_kg, WEIGHT_RANGE_KG)?;
                checked("Haycock BSA (m2)", haycock_bsa_m2(height_cm, weight_kg), BSA_RANGE_M2)
            }
            _ => Err(format!("{self:?} does not specify a body size")),
        }
    }

    /// The Boston z-score of a circular annulus of `area_mm2` for this target's body
    /// size; `None` when the target was not given by body size.
    pub fn z_score_of_area(&self, area_mm2: f64) -> Option<f64> {
        let bsa_m2 = self.bsa_m2().ok()?;
        let diameter_cm = 0.2 * (area_mm2.max(0.0) / PI).sqrt();
        Some(boston_z_score(bsa_m2, diameter_cm))
    }

    /// One line for logs and reports, e.g.
    /// "BSA 0.37 m2, z 0 -> Boston annulus 9.43 mm -> 69.8 mm2".
    pub fn describe(&self) -> String {
        let area = match self.area_mm2() {
            Ok(area_mm2) => format!("{area_mm2:.1} mm2"),
            Err(e) => format!("invalid ({e})"),
        };
        let diameter = self.annulus_diameter_mm().map_or_else(|_| "?".to_string(), |d| format!("{d:.2}"));
        match *self {
            TargetArea::AreaMm2(_) => format!("target area given -> {area}"),
            TargetArea::AnnulusDiameterMm(_) => format!("annulus {diameter} mm -> {area}"),
            TargetArea::Bsa { bsa_m2, z_score } => {
                format!("BSA {bsa_m2} m2, z {z_score} -> Boston annulus {diameter} mm -> {area}")
            }
            TargetArea::HeightWeight { height_cm, weight_kg, z_score } => {
                let bsa = self.bsa_m2().map_or_else(|_| "?".to_string(), |b| format!("{b:.3}"));
                format!(
                    "height {height_cm} cm, weight {weight_kg} kg -> Haycock BSA {bsa} m2, z {z_score} -> Boston annulus {diameter} mm -> {area}"
                )
            }
        }
    }
}

/// Boston annulus diameter in mm (the formula gives cm) with validated inputs.
fn boston_diameter_mm(bsa_m2: f64, z_score: f64) -> Result<f64, String> {
    let bsa_m2 = checked("BSA (m2)", bsa_m2, BSA_RANGE_M2)?;
    let z_score = checked("z-score", z_score, Z_SCORE_RANGE)?;
    checked_positive("Boston annulus diameter (mm)", 10.0 * boston_aortic_annulus_diameter_cm(bsa_m2, z_score))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round2(v: f64) -> f64 {
        (v * 100.0).round() / 100.0
    }

    #[test]
    fn table3_diameters_at_z0() {
        for (bsa_m2, diameter_cm) in [(0.45, 1.04), (0.37, 0.94), (0.33, 0.89), (0.39, 0.97)] {
            let computed = boston_aortic_annulus_diameter_cm(bsa_m2, 0.0);
            assert_eq!(round2(computed), diameter_cm, "BSA {bsa_m2}: {computed}");
        }
    }

    #[test]
    fn area_from_each_specification() {
        assert_eq!(TargetArea::AreaMm2(69.4).area_mm2().unwrap(), 69.4);
        let from_diameter = TargetArea::AnnulusDiameterMm(9.4).area_mm2().unwrap();
        assert!((from_diameter - PI * 4.7 * 4.7).abs() < 1e-12);
        let from_bsa = TargetArea::Bsa { bsa_m2: 0.37, z_score: 0.0 }.area_mm2().unwrap();
        let d_mm = 15.5 * 0.37f64.sqrt();
        assert!((from_bsa - PI * d_mm * d_mm / 4.0).abs() < 1e-12);
        // z = +2 widens by 2 (0.06 + 0.083 BSA) cm.
        let wider = TargetArea::Bsa { bsa_m2: 0.37, z_score: 2.0 }.annulus_diameter_mm().unwrap();
        assert!((wider - d_mm - 20.0 * (0.06 + 0.083 * 0.37)).abs() < 1e-12);
        // Haycock BSA for 66 cm, 7.35 kg is about 0.37 m2 (an infant like p2).
        let infant = TargetArea::HeightWeight { height_cm: 66.0, weight_kg: 7.35, z_score: 0.0 };
        let bsa = infant.bsa_m2().unwrap();
        assert!((bsa - 0.024265 * 7.35f64.powf(0.5378) * 66f64.powf(0.3964)).abs() < 1e-15);
        assert!((bsa - 0.37).abs() < 0.01, "{bsa}");
        let same = TargetArea::Bsa { bsa_m2: bsa, z_score: 0.0 }.area_mm2().unwrap();
        assert_eq!(infant.area_mm2().unwrap(), same);
    }

    #[test]
    fn implausible_inputs_are_rejected_by_name() {
        let cases = [
            (TargetArea::AreaMm2(0.0), "area"),
            (TargetArea::AreaMm2(f64::NAN), "NaN"),
            (TargetArea::AreaMm2(5000.0), "5000"),
            (TargetArea::AnnulusDiameterMm(-3.0), "-3"),
            (TargetArea::AnnulusDiameterMm(80.0), "area"),
            (TargetArea::Bsa { bsa_m2: 3.7, z_score: 0.0 }, "BSA (m2) = 3.7"),
            (TargetArea::Bsa { bsa_m2: 0.4, z_score: 7.0 }, "z-score = 7"),
            (TargetArea::Bsa { bsa_m2: 0.4, z_score: f64::INFINITY }, "z-score = inf"),
            (TargetArea::HeightWeight { height_cm: 1.7, weight_kg: 70.0, z_score: 0.0 }, "height (cm) = 1.7"),
            (TargetArea::HeightWeight { height_cm: 170.0, weight_kg: 0.0, z_score: 0.0 }, "weight (kg) = 0"),
        ];
        for (target, expected) in cases {
            let err = target.area_mm2().unwrap_err();
            assert!(err.contains(expected), "{target:?}: {err}");
        }
    }

    #[test]
    fn z_score_of_an_area_inverts_the_boston_relation() {
        for z in [-2.0, 0.0, 1.5] {
            let t = TargetArea::Bsa { bsa_m2: 0.37, z_score: z };
            let back = t.z_score_of_area(t.area_mm2().unwrap()).unwrap();
            assert!((back - z).abs() < 1e-9, "{z} -> {back}");
        }
        assert_eq!(TargetArea::AreaMm2(70.0).z_score_of_area(70.0), None);
    }

    #[test]
    fn describe_reads_like_the_paper() {
        let text = TargetArea::Bsa { bsa_m2: 0.37, z_score: 0.0 }.describe();
        assert_eq!(text, "BSA 0.37 m2, z 0 -> Boston annulus 9.43 mm -> 69.8 mm2");
        assert!(TargetArea::AreaMm2(-1.0).describe().contains("invalid"));
    }

    #[test]
    fn serde_round_trip() {
        let target = TargetArea::HeightWeight { height_cm: 68.0, weight_kg: 7.35, z_score: -1.0 };
        let json = serde_json::to_string(&target).unwrap();
        assert_eq!(serde_json::from_str::<TargetArea>(&json).unwrap(), target);
        let parsed: TargetArea = serde_json::from_str(r#"{"Bsa":{"bsa_m2":0.33,"z_score":0.0}}"#).unwrap();
        assert_eq!(parsed, TargetArea::Bsa { bsa_m2: 0.33, z_score: 0.0 });
    }

    #[test]
    fn patients_p2_p3_match_published_targets() {
        let Some(dir) = baffle_test_support::reference_data::reference_data_if_present() else { return };
        let text = std::fs::read_to_string(dir.join("patients.json")).expect("patients.json is readable");
        let table: serde_json::Value = serde_json::from_str(&text).expect("patients.json is valid JSON");
        for id in ["p2", "p3"] {
            let patient = &table["patients"][id];
            let field = |name: &str| patient[name].as_f64().unwrap_or_else(|| panic!("{id}: no number {name}"));
            let bsa_m2 = field("bsa_m2");
            let published_diameter_cm = field("annulus_diameter_z0_cm");
            let diameter_cm = boston_aortic_annulus_diameter_cm(bsa_m2, 0.0);
            assert_eq!(round2(diameter_cm), published_diameter_cm, "{id}: {diameter_cm} cm");
            // The paper's area uses the rounded diameter.
            let area_cm2 = PI * (0.5 * round2(diameter_cm)).powi(2);
            let published_area_cm2 = field("target_area_cm2");
            assert!((area_cm2 - published_area_cm2).abs() < 0.01 * published_area_cm2, "{id}: {area_cm2} cm2");
            let target = TargetArea::Bsa { bsa_m2, z_score: 0.0 };
            let area_mm2 = target.area_mm2().unwrap();
            assert!(
                (area_mm2 - 100.0 * published_area_cm2).abs() < 0.01 * 100.0 * published_area_cm2,
                "{id}: {area_mm2}"
            );
        }
    }
}
