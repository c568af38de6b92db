//! Writing output files so that a reader never sees half a file, and a failed or
//! cancelled run never leaves a truncated copy in place of an earlier good one; reading
//! the stages' JSON files back as the types they hold.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Deserializer};
use std::path::Path;

/// The JSON file `path` as a `T`: an error names the file and what is wrong (a missing
/// field by its name, a value of the wrong type by its line and column).
pub(crate) fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// For `#[serde(deserialize_with = "crate::files::nullable")]` on an `Option` field that
/// the writer always puts in the file, as null where it has no value: null is None, and
/// a missing field is an error (serde would take it for None).
pub(crate) fn nullable<'de, D: Deserializer<'de>, T: Deserialize<'de>>(deserializer: D) -> Result<Option<T>, D::Error> {
    Option::deserialize(deserializer)
}

/// Write `bytes` to `path` atomically (`baffle_core::io::write_atomic`), the error naming the file.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), String> {
    baffle_core::io::write_atomic(path, bytes).map_err(|e| format!("{}: {e}", path.display()))
}

/// Create the folder an output file goes into (as `--out DIR` commands create DIR), naming
/// it if that fails.
pub(crate) fn create_parent_dir(path: &Path) -> Result<(), String> {
    match path.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(dir) => std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display())),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_write_names_the_file_and_keeps_nothing() {
        let path = std::env::temp_dir().join(format!("baffle-files-missing-{}", std::process::id())).join("out.json");
        let err = write_atomic(&path, b"x").unwrap_err();
        assert!(err.contains("out.json"), "{err}");
        assert!(!path.exists());
    }
}
