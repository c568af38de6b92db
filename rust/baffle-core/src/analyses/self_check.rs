//! A stage's check of its own output by a second method: prepare re-measures its caps
//! against the segmentations' interfaces, design re-cuts its sections, extend checks its
//! caps against the pools and the surface for crossings. Each check is listed in the
//! stage's `*-report.json` with its figure and limit, and a failed one is an error that
//! names the place, never a silently wrong file.

use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SelfCheck {
    /// What was checked, e.g. "VSD cap rim on the LV-RV interface".
    pub name: String,
    /// The measured figure, in `unit`.
    pub value: f64,
    /// The limit it is held to, in `unit`.
    pub limit: f64,
    /// "mm", "mm2", "%", "deg", "count", ...
    pub unit: String,
    /// Whether `value` is within `limit` (at most, or at least: see `kind`).
    pub passed: bool,
    /// "at_most" or "at_least".
    pub kind: String,
    /// How it was measured (the second method), and where it failed if it did.
    pub detail: String,
}

impl SelfCheck {
    /// Passes when `value <= limit` (a NaN value fails).
    pub fn at_most(name: &str, value: f64, limit: f64, unit: &str, detail: impl Into<String>) -> Self {
        Self::new(name, value, limit, unit, value <= limit, "at_most", detail.into())
    }

    /// Passes when `value >= limit` (a NaN value fails).
    pub fn at_least(name: &str, value: f64, limit: f64, unit: &str, detail: impl Into<String>) -> Self {
        Self::new(name, value, limit, unit, value >= limit, "at_least", detail.into())
    }

    fn new(name: &str, value: f64, limit: f64, unit: &str, passed: bool, kind: &str, detail: String) -> Self {
        SelfCheck { name: name.into(), value, limit, unit: unit.into(), passed, kind: kind.into(), detail }
    }

    /// "VSD cap area against the LV-RV opening: 812.3 % (limit 25 %): <detail>".
    pub fn describe(&self) -> String {
        let relation = if self.kind == "at_least" { "at least" } else { "at most" };
        format!("{}: {:.3} {} (must be {relation} {:.3} {}); {}", self.name, self.value, self.unit, self.limit, self.unit, self.detail)
    }
}

/// The first failed check as an error message, or Ok.
pub fn first_failure(checks: &[SelfCheck]) -> Result<(), String> {
    match checks.iter().find(|c| !c.passed) {
        Some(c) => Err(format!("self-check failed: {}", c.describe())),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_pass_and_fail_either_way_and_nan_fails() {
        assert!(SelfCheck::at_most("a", 1.0, 1.0, "mm", "").passed);
        assert!(!SelfCheck::at_most("a", 1.1, 1.0, "mm", "").passed);
        assert!(SelfCheck::at_least("a", 2.0, 1.0, "mm2", "").passed);
        assert!(!SelfCheck::at_least("a", 0.5, 1.0, "mm2", "").passed);
        assert!(!SelfCheck::at_most("a", f64::NAN, 1.0, "mm", "").passed && !SelfCheck::at_least("a", f64::NAN, 1.0, "mm", "").passed);
        let checks = [SelfCheck::at_most("ok", 0.0, 1.0, "mm", ""), SelfCheck::at_most("cap centroid", 15.5, 1.5, "mm", "near (1, 2, 3)")];
        let err = first_failure(&checks).unwrap_err();
        assert!(err.contains("cap centroid") && err.contains("15.500 mm") && err.contains("near (1, 2, 3)"), "{err}");
        assert!(first_failure(&checks[..1]).is_ok());
    }
}
