//! Area-constrained baffle design for double outlet right ventricle repair,
//! after Martinez et al., "Semi-Automated Generation and Hemodynamic Assessment of
//! Surgical Baffle Geometry for Biventricular Repair".
//!
//! - [`steps`]: the paper's Methods, one module per step (section numbers in each
//!   module's header): [`steps::seam`] (2.3.3), [`steps::partition`] (2.3.3),
//!   [`steps::patch`] (2.3.3), [`steps::centerline`] (2.4.2), [`steps::sections`] (2.4.3),
//!   [`steps::amplitudes`] (2.4.4), [`steps::envelope`] (2.4.5), [`steps::surface`] (2.4.6);
//! - [`design`](mod@design): the steps joined ([`design::design`]), with the target area
//!   ([`target`], paper Table 3), the tunables' ranges ([`option_ranges`]), the optional
//!   flow-section rule ([`flow_target`]) and the errors ([`error`]);
//! - [`geometry`]: the mesh type and the helpers the steps and analyses share;
//! - [`analyses`]: what is measured on a design after it exists (flow centerline,
//!   hemodynamic estimate, RV outflow and cost, comparison, self-checks);
//! - [`io`]: reading the inputs and writing the results;
//! - [`phantom`]: the built-in synthetic heart (`baffle phantom`, `--phantom`).
//!
//! Imports run one way: [`geometry`] uses nothing else here; [`steps`] use it (and
//! [`error`]); [`analyses`] use it only; [`design`](mod@design) uses all three, and
//! [`io::outputs`] writes what it returns (`scripts/check_import_cycles.py` checks
//! this, at the root and inside each folder). Test inputs (the phantom family, perturbations,
//! the reference data's location) are in the `baffle-test-support` crate, not here.
//!
//! Units: millimetres for geometry, in the frame (LPS or RAS) the input uses.

pub mod geometry;
pub mod steps;
pub mod analyses;
pub mod io;

pub mod error;
pub mod target;
pub mod design;
pub mod option_ranges;
pub mod flow_target;
pub mod phantom;

pub use design::{design, DesignOptions, DesignReport, DesignResult};
pub use error::DesignError;
pub use geometry::mesh::{FaceLabels, TriMesh, Vec3};
pub use target::TargetArea;
