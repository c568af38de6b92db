//! Where the patients' reference data (the paper's public dataset) is read from by
//! tests, benchmarks and examples: `$BAFFLE_DATA_DIR`, else `shared/data` beside the
//! repository. It is read in place, never copied into the repository.

use std::path::PathBuf;

/// `$BAFFLE_DATA_DIR`, else `<repository>/../shared/data` (every crate of this
/// workspace sits two folders below the repository root, like this one).
pub fn reference_data_dir() -> PathBuf {
    std::env::var_os("BAFFLE_DATA_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data")))
}

/// The reference data directory if it holds the dataset; otherwise `None`, with a
/// note on stderr so a skipped check is visible.
pub fn reference_data_if_present() -> Option<PathBuf> {
    let dir = reference_data_dir();
    if dir.join("patients.json").is_file() {
        Some(dir)
    } else {
        eprintln!("note: patient data not found at {}; real-data checks skipped", dir.display());
        None
    }
}
