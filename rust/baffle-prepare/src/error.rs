//! What went wrong in `prepare`, naming the missing file, structure or contact.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum PrepareError {
    #[error("{structure} surface not found: expected {}", path.display())]
    MissingFile { structure: &'static str, path: PathBuf },
    #[error("{0}")]
    Read(String),
    #[error("{}: the {structure} surface is not closed: {count} open or non-manifold edges, e.g. edge {}-{} at ({:.2}, {:.2}, {:.2}) mm",
        path.display(), edge.0, edge.1, at_mm[0], at_mm[1], at_mm[2])]
    OpenSurface { structure: &'static str, path: PathBuf, count: usize, edge: (u32, u32), at_mm: [f64; 3] },
    #[error("the {a} and {b} blood pools do not touch, so there is no {what} (closest {distance_mm:.2} mm apart)")]
    NoContact { a: &'static str, b: &'static str, what: &'static str, distance_mm: f64 },
    #[error("{step}: {message}")]
    Geometry { step: &'static str, message: String },
    /// A cap failed its check against the segmentations' opening: no file is written.
    #[error("self-check failed, no capped ventricle written: {check} (cuts: {summary})")]
    SelfCheck { check: String, summary: String },
    #[error("invalid option: {0}")]
    Option(String),
}

impl PrepareError {
    pub fn geometry(step: &'static str, message: impl Into<String>) -> Self {
        PrepareError::Geometry { step, message: message.into() }
    }
}
