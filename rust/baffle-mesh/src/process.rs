//! Starting the out-of-process tools (gmsh, mpiexec).
//!
//! Linux refuses to execute a file that any process still holds open for writing
//! (`ETXTBSY`, "Text file busy"). A program that has just been written, such as a launcher
//! script, can briefly be in that state after its writer closed it: a child forked at that
//! moment by another thread keeps a copy of the writer's descriptor until its own `exec`.
//! The condition clears within milliseconds, so a start that fails with it is retried
//! rather than reported as a missing program.

use std::io;
use std::time::Duration;

/// How many times a busy executable is retried, and the pause before the first retry
/// (doubled each time, so the last wait is about 0.6 s and the total about 1.3 s).
const BUSY_RETRIES: u32 = 8;
const FIRST_BUSY_PAUSE: Duration = Duration::from_millis(5);

/// Runs `start` (a `Command::spawn` or `Command::output`) and retries it while it fails
/// with "Text file busy"; any other result is returned as it is.
pub fn start_retrying_busy<T>(mut start: impl FnMut() -> io::Result<T>) -> io::Result<T> {
    let mut pause = FIRST_BUSY_PAUSE;
    for _ in 0..BUSY_RETRIES {
        match start() {
            Err(e) if e.kind() == io::ErrorKind::ExecutableFileBusy => std::thread::sleep(pause),
            result => return result,
        }
        pause *= 2;
    }
    start()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    #[test]
    fn a_busy_start_is_retried_until_it_succeeds() {
        let calls = Cell::new(0);
        let result = start_retrying_busy(|| {
            calls.set(calls.get() + 1);
            if calls.get() < 3 {
                Err(io::Error::from(io::ErrorKind::ExecutableFileBusy))
            } else {
                Ok(calls.get())
            }
        });
        assert_eq!(result.unwrap(), 3);
    }

    /// A start that always fails with `kind`: the error returned and the attempts made.
    fn always_failing(kind: io::ErrorKind) -> (io::ErrorKind, u32) {
        let calls = Cell::new(0);
        let result: io::Result<()> = start_retrying_busy(|| {
            calls.set(calls.get() + 1);
            Err(io::Error::from(kind))
        });
        (result.unwrap_err().kind(), calls.get())
    }

    #[test]
    fn other_errors_are_returned_at_once() {
        assert_eq!(always_failing(io::ErrorKind::NotFound), (io::ErrorKind::NotFound, 1));
    }

    #[test]
    fn a_start_that_stays_busy_is_reported_after_the_retries() {
        let busy = io::ErrorKind::ExecutableFileBusy;
        assert_eq!(always_failing(busy), (busy, BUSY_RETRIES + 1));
    }

    /// The real condition: a script held open for writing cannot be executed, and the
    /// retry starts it once the writer lets go.
    #[cfg(target_os = "linux")]
    #[test]
    fn a_script_still_open_for_writing_starts_once_it_is_closed() {
        use std::io::Write;
        use std::os::unix::fs::OpenOptionsExt;
        let dir = std::env::temp_dir().join(format!("baffle-busy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("tool");
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .mode(0o755)
            .open(&path)
            .unwrap();
        file.write_all(b"#!/bin/sh\nexit 0\n").unwrap();
        let busy = std::process::Command::new(&path).status().unwrap_err();
        assert_eq!(busy.kind(), io::ErrorKind::ExecutableFileBusy);
        let closer = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(20));
            drop(file);
        });
        let status = start_retrying_busy(|| std::process::Command::new(&path).status()).unwrap();
        closer.join().unwrap();
        assert!(status.success());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
