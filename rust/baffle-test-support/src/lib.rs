//! Test inputs, for the workspace's tests, benches and examples only (a dev-dependency,
//! never a dependency of the product):
//!
//! - [`phantom_family`]: a seeded family of synthetic anatomies of every plausible size
//!   and shape, built from the product's one built-in phantom
//!   (`baffle_core::phantom`, which `baffle phantom` and `--phantom` ship);
//! - [`perturb`]: what real acquisitions and bad segmentations do to a valid surface
//!   (bumps, noise, flipped triangles, bent caps, another pose, smoothing, subdivision);
//! - [`reference_data`]: where the paper's public dataset is read from
//!   (`$BAFFLE_DATA_DIR`, else `shared/data` beside the repository), and the design cases
//!   built from it.

pub mod perturb;
pub mod phantom_family;
pub mod reference_data;
