//! Helpers shared by the `baffle simulate` tests of both engines.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read};
use std::process::{Command, ExitStatus, Stdio};

/// Start `command` with piped output, wait for `tags` Slicer progress tags on its stdout,
/// send SIGTERM (not SIGKILL: the run must stop cleanly), and return its exit status once
/// it has written everything.
pub fn sigterm_after_progress_tags(command: &mut Command, tags: usize) -> ExitStatus {
    let mut child = command.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("start baffle");
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let (mut seen, mut line) = (0, String::new());
    while seen < tags {
        line.clear();
        assert!(stdout.read_line(&mut line).unwrap() > 0, "baffle simulate ended early");
        seen += usize::from(line.contains("<filter-progress>"));
    }
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) }, 0);
    let mut rest = String::new();
    stdout.read_to_string(&mut rest).unwrap();
    child.wait().unwrap()
}
