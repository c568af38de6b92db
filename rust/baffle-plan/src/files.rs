//! Writing output files so that a reader never sees half a file, and a failed or
//! cancelled run never leaves a truncated copy in place of an earlier good one.

use std::path::Path;

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
