//! The one error type of the stages' public functions: which command or plan stage
//! failed, with its message (the text the command line prints after `baffle: error:`).

/// A failed stage: the variant names it, the message says what went wrong (and is the
/// whole of the error's text, so the command line prints it as it was).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    #[error("{0}")]
    Prepare(String),
    #[error("{0}")]
    Design(String),
    #[error("{0}")]
    Extend(String),
    #[error("{0}")]
    Centerline(String),
    #[error("{0}")]
    Mesh(String),
    #[error("{0}")]
    Simulate(String),
    #[error("{0}")]
    Export(String),
    #[error("{0}")]
    Template(String),
    #[error("{0}")]
    Sweep(String),
    /// `baffle phantom` (the phantom or the synthetic heart written out).
    #[error("{0}")]
    Phantom(String),
    /// `baffle plan` itself: its settings, its report, or a stage that failed (the
    /// message then names the stage and the folders kept).
    #[error("{0}")]
    Plan(String),
    /// `baffle plan` stopped because its caller asked (a front end's cancel): the message
    /// names the stage it stopped at and the folders of the stages finished before it.
    #[error("{0}")]
    Cancelled(String),
}

impl PlanError {
    /// The command or stage that failed, as the command line names it.
    pub fn stage(&self) -> &'static str {
        match self {
            PlanError::Prepare(_) => "prepare",
            PlanError::Design(_) => "design",
            PlanError::Extend(_) => "extend",
            PlanError::Centerline(_) => "centerline",
            PlanError::Mesh(_) => "mesh",
            PlanError::Simulate(_) => "simulate",
            PlanError::Export(_) => "export-svmp",
            PlanError::Template(_) => "template",
            PlanError::Sweep(_) => "sweep",
            PlanError::Phantom(_) => "phantom",
            PlanError::Plan(_) | PlanError::Cancelled(_) => "plan",
        }
    }
}

/// Inside the stages, errors are still messages; a stage's error joins them as its text.
impl From<PlanError> for String {
    fn from(e: PlanError) -> String {
        e.to_string()
    }
}
