//! Shared helpers of the integration tests: where the real data is.
#![allow(dead_code)]

use std::path::PathBuf;

/// The patients' data directory, or `None` (with a note) when it is absent.
pub fn data_dir() -> Option<PathBuf> {
    baffle_test_support::reference_data::reference_data_if_present()
}
