//! Shared helpers of the integration tests: where the real data is.
#![allow(dead_code)]

use std::path::PathBuf;

/// `BAFFLE_DATA_DIR`, else `../shared/data` beside the repository.
pub fn data_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("BAFFLE_DATA_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data")));
    if dir.join("p2").is_dir() {
        Some(dir)
    } else {
        eprintln!("note: patient data not found at {}; real-data checks skipped", dir.display());
        None
    }
}
