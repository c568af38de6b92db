//! What is measured on a design once it exists, never used to shape it (except through
//! the optional flow-section rule, [`crate::flow_target`], which re-runs the design):
//!
//! - [`flow_centerline`]: the flow-domain centerline and the sections normal to the flow
//!   (paper 2.5);
//! - [`hemodynamics_estimate`]: a reduced-order estimate of dp and the peak velocity from
//!   those sections, in well under a second;
//! - [`rv_outflow`]: the smallest section of the RV's outflow, before and after the baffle;
//! - [`rv_cost`]: the room the baffle takes from the right ventricle;
//! - [`compare`]: a designed baffle against a reference surface (e.g. the published one);
//! - [`self_check`]: a stage's check of its own output by a second method, as listed in
//!   its report.

pub mod flow_centerline;
pub mod hemodynamics_estimate;
pub mod rv_outflow;
pub mod rv_cost;
pub mod compare;
pub mod self_check;
