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
/// note on stderr so a skipped check is visible. Under `CI=true` a missing dataset
/// panics instead: a broken path must not turn every real-data check into a pass.
pub fn reference_data_if_present() -> Option<PathBuf> {
    let dir = reference_data_dir();
    if dir.join("patients.json").is_file() {
        return Some(dir);
    }
    if running_in_ci() {
        panic!("patient data not found at {} (CI=true: the real-data checks must run; set BAFFLE_DATA_DIR)", dir.display());
    }
    eprintln!("note: patient data not found at {}; real-data checks skipped", dir.display());
    None
}

/// `CI` set to `true` or `1` (as `.ci/run` and most CI services do).
pub fn running_in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v.eq_ignore_ascii_case("true") || v == "1")
}
