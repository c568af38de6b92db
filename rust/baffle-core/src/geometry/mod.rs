//! Geometry the steps and analyses share, none of it specific to the baffle: the one
//! triangle mesh type ([`mesh`]), spatial queries ([`spatial`]), numerical building blocks
//! ([`numerics`]: best-fit planes, splines, thin-plate splines, concave majorants, seeded
//! random numbers), isotropic remeshing ([`remesh`]), Taubin smoothing ([`smoothing`]),
//! inside/outside voxel masks ([`voxel`]), the area of a plane section of a closed surface
//! ([`plane_section`]), and the planar caps of a surface ([`caps`]: labelling them from one
//! point each, measuring and restoring their flatness).
//!
//! Nothing here uses the design steps, the design or the analyses.

pub mod mesh;
pub mod spatial;
pub mod numerics;
pub mod remesh;
pub mod smoothing;
pub mod voxel;
pub mod plane_section;
pub mod caps;
