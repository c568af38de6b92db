//! Area-constrained baffle design for double outlet right ventricle repair,
//! after Martinez et al., "Semi-Automated Generation and Hemodynamic Assessment of
//! Surgical Baffle Geometry for Biventricular Repair". One module per step of the
//! paper's Methods (section numbers in each module's header).
//!
//! Units: millimetres for geometry, in the frame (LPS or RAS) the input uses.

pub mod mesh;
pub mod io;
pub mod spatial;
pub mod numerics;
pub mod target;
pub mod phantom;
pub mod remesh;

pub use mesh::{FaceLabels, TriMesh, Vec3};
