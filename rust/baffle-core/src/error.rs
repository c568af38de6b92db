//! Errors of the design. Each names the problem and where it is, so a surgeon or
//! engineer can fix the input (which point, which label, how far off).

use thiserror::Error;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum DesignError {
    /// The ventricle surface is not a closed manifold (or has bad coordinates).
    #[error("surface: {0}")]
    Surface(String),
    /// A required face label is absent from the surface.
    #[error("surface has no triangles labelled {label} ({what}); labels present: {present:?}")]
    MissingLabel { label: i32, what: &'static str, present: Vec<i32> },
    /// A design option is outside its range (see `option_ranges`).
    #[error("option {0}")]
    Options(String),
    /// The suture points are unusable (too few, too far from the surface, ...).
    #[error("suture points: {0}")]
    SuturePoints(String),
    /// The seam built from the points crosses itself or a cap, or does not split the surface as expected.
    #[error("seam: {0}")]
    Seam(String),
    /// The target area is invalid.
    #[error("target area: {0}")]
    Target(String),
    /// The geometry cannot satisfy the area constraint (e.g. the baffle would pass through the wall).
    #[error("baffle: {0}")]
    Baffle(String),
    /// The target area cannot be reached on this seam; the largest one that can.
    #[error("baffle: {reason}. {}", feasibility_text(*.target_area_mm2, *.max_feasible_area_mm2, .max_feasible_z_score))]
    Infeasible { target_area_mm2: f64, max_feasible_area_mm2: f64, max_feasible_z_score: Option<f64>, reason: String },
    /// A numerical step failed (singular system, degenerate curve).
    #[error("{step}: {message}")]
    Numerical { step: &'static str, message: String },
    /// The caller's progress callback asked to stop.
    #[error("cancelled during {0}")]
    Cancelled(String),
}

impl DesignError {
    pub fn numerical(step: &'static str, message: impl Into<String>) -> Self {
        DesignError::Numerical { step, message: message.into() }
    }
}

/// What the seam admits, and what to do about it.
fn feasibility_text(target_area_mm2: f64, max_feasible_area_mm2: f64, z: &Option<f64>) -> String {
    if max_feasible_area_mm2 <= 0.0 {
        return format!(
            "This suture line admits no tunnel at all (every target down to {:.1} mm2 fails the same way): \
             move the suture points so the patch they span stays inside the ventricle",
            target_area_mm2 / 256.0
        );
    }
    let z = z.map(|z| format!(" (z = {z:+.1} for the patient's BSA)")).unwrap_or_default();
    format!(
        "This suture line admits a tunnel of at most {max_feasible_area_mm2:.1} mm2{z} against the target {target_area_mm2:.1} mm2: \
         move the suture points away from where the baffle meets the wall or itself"
    )
}
