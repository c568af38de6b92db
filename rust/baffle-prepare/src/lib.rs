//! The capped ventricle, the design input of `baffle design`, from segmented blood
//! pools (Martinez et al., section 2.2.2). One module per step:
//! [`voxelize`] (inside/outside masks), [`union_surface`] (one manifold surface
//! without internal walls), [`interfaces`] (labels by nearest structure, VSD and
//! aortic loops), [`clip`] (cut along both loops, keep the RV between them),
//! [`capping`] (planar caps and the final remesh), joined by [`prepare::prepare`].
//! [`extend`] grows a designed domain into the extended CFD domain (paper 2.5): the LV
//! back to a mid-LV plane and the aorta up to the sinotubular junction.
//!
//! Units: millimetres, in the frame of the input surfaces.

pub mod shapes;
pub mod voxelize;
pub mod union_surface;
pub mod error;
pub mod input;
pub mod interfaces;
pub mod clip;
pub mod capping;
pub mod cap_checks;
mod planar_cap;
mod polygon2d;
pub mod openings;
pub mod separation;
pub mod prepare;
pub mod labelmap;
pub mod extend;
pub mod lv_family;
pub mod aorta_family;

pub use error::PrepareError;
pub use input::{read_segmentations, BloodPools};
pub use prepare::{prepare, PrepareOptions, PrepareReport};
pub use labelmap::{pools_from_labelmap, pulmonary_from_labelmap, read_labelmap, LabelMap, LabelSurfaceOptions, PoolLabels};
pub use extend::{extend, ExtendOptions, ExtendReport, Extended};
