//! When the target area cannot be reached on the surgeon's seam, the design's error
//! says the largest target it admits; `infeasible.json` in the output folder keeps
//! that for the report and the Slicer module (earlier outputs are left as they are).

use crate::files::write_atomic;
use baffle_core::DesignError;
use std::path::Path;

pub(crate) const INFEASIBLE_FILE: &str = "infeasible.json";

/// The design's error as a message, with `infeasible.json` written into `out` when
/// the error is an infeasible target.
pub(crate) fn design_failure(out: &Path, error: DesignError) -> String {
    let message = error.to_string();
    if let DesignError::Infeasible { target_area_mm2, max_feasible_area_mm2, max_feasible_z_score, reason } = &error {
        let doc = serde_json::json!({
            "status": "infeasible",
            "target_area_mm2": target_area_mm2,
            "max_feasible_area_mm2": max_feasible_area_mm2,
            "max_feasible_z_score": max_feasible_z_score,
            "reason": reason,
            "message": message,
        });
        let written = std::fs::create_dir_all(out)
            .map_err(|e| format!("{}: {e}", out.display()))
            .and_then(|_| write_atomic(&out.join(INFEASIBLE_FILE), doc.to_string().as_bytes()));
        if let Err(e) = written {
            return format!("{message} (and {INFEASIBLE_FILE} could not be written: {e})");
        }
    }
    message
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_infeasible_target_is_written_with_its_largest_feasible_area() {
        let dir = std::env::temp_dir().join(format!("baffle-infeasible-{}", std::process::id()));
        let error = DesignError::Infeasible {
            target_area_mm2: 100.0,
            max_feasible_area_mm2: 80.5,
            max_feasible_z_score: Some(-1.2),
            reason: "could not reach the target".into(),
        };
        let message = design_failure(&dir, error);
        assert!(message.contains("at most 80.5 mm2 (z = -1.2"), "{message}");
        let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join(INFEASIBLE_FILE)).unwrap()).unwrap();
        assert_eq!(doc["max_feasible_area_mm2"], 80.5);
        assert_eq!(doc["max_feasible_z_score"], -1.2);
        std::fs::remove_dir_all(&dir).unwrap();
        // Other errors write nothing.
        design_failure(&dir, DesignError::Seam("x".into()));
        assert!(!dir.exists());
    }
}
