//! Writing a file so that a reader never sees half of it, and a failed or cancelled run
//! never leaves a truncated copy in place of an earlier good one: the bytes go to a
//! temporary file in the same folder (so the rename stays on one file system), which is
//! then renamed over the target. The temporary's name is unique per process and call
//! (`.<name>.tmp-<pid>-<n>`), so concurrent writers of the same file do not share it. The
//! temporary is synced before the rename (as baffle-cfd's and baffle-plan's copies did),
//! so a power loss leaves the old file or the new one.
//! Every crate's output files go through here (baffle-mesh, baffle-cfd, baffle-plan map
//! the `std::io::Error` to their own error types).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Write `bytes` to `path` atomically (see the module doc).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Write `path` atomically from a writer, for files too large to build in memory first;
/// an error from `write` leaves the target as it was.
pub fn write_atomic_with(path: &Path, write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>) -> std::io::Result<()> {
    let tmp = temporary_name(path);
    let result = (|| {
        let mut w = BufWriter::new(File::create(&tmp)?);
        write(&mut w)?;
        // On disk before the rename: a crash then leaves the old file or the new one,
        // never an empty one under the final name (a run's earlier results are kept).
        w.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn temporary_name(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    path.with_file_name(format!(".{name}.tmp-{}-{n}", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_is_replaced_whole_and_no_temporary_is_left() {
        let dir = std::env::temp_dir().join(format!("baffle-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("summary.json");
        write_atomic(&path, b"first").unwrap();
        write_atomic(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        let failed = write_atomic_with(&path, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("cancelled"))
        });
        assert!(failed.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, vec![std::ffi::OsString::from("summary.json")]);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn temporaries_are_unique_in_the_same_folder() {
        let path = Path::new("out/report.json");
        let (a, b) = (temporary_name(path), temporary_name(path));
        assert_ne!(a, b);
        assert_eq!(a.parent(), path.parent());
        assert!(a.file_name().unwrap().to_string_lossy().starts_with(".report.json.tmp-"));
    }
}
