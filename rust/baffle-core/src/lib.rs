//! Area-constrained baffle design for double outlet right ventricle repair,
//! after Martinez et al., "Semi-Automated Generation and Hemodynamic Assessment of
//! Surgical Baffle Geometry for Biventricular Repair". One module per step of the
//! paper's Methods (section numbers in each module's header):
//! [`seam`] (2.3.3), [`partition`] (2.3.3), [`patch`] (2.3.3), [`centerline`] (2.4.2),
//! [`sections`] (2.4.3), [`amplitudes`] (2.4.4), [`envelope`] (2.4.5), [`surface`] (2.4.6),
//! joined by [`design::design`].
//!
//! Units: millimetres for geometry, in the frame (LPS or RAS) the input uses.

pub mod mesh;
pub mod error;
pub mod io;
pub mod spatial;
pub mod numerics;
pub mod target;
pub mod phantom;
pub mod plane_section;
pub mod caps;
pub mod self_check;
pub mod remesh;
pub mod smoothing;
pub mod seam;
pub mod partition;
pub mod patch;
pub mod centerline;
pub mod sections;
pub mod amplitudes;
pub mod envelope;
pub mod surface;
pub mod design;
pub mod option_ranges;
pub mod outputs;
pub mod compare;
pub mod voxel;
pub mod flow_centerline;
pub mod flow_target;
pub mod hemodynamics_estimate;
pub mod rv_cost;
pub mod rv_outflow;

pub use design::{design, DesignOptions, DesignReport, DesignResult};
pub use error::DesignError;
pub use mesh::{FaceLabels, TriMesh, Vec3};
pub use target::TargetArea;
