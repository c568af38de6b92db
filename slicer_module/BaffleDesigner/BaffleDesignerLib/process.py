"""Runs the `baffle` command line as a separate process without blocking the caller:
Slicer CLI progress tags (<filter-progress>, <filter-stage>, <filter-comment>) are parsed
from its standard output on a reader thread; the GUI polls `progress`/`stage`/`state`
from a QTimer and calls cancel(). Pure Python (subprocess + threading), no Qt."""

import os
import re
import signal
import subprocess
import threading
import time
from typing import List, Optional, Tuple


_TAG = re.compile(r"<(filter-[a-z]+)>(.*?)</\1>")

RUNNING, COMPLETED, FAILED, CANCELLED = "running", "completed", "failed", "cancelled"

# Windows process creation flags (subprocess has them only on Windows).
CREATE_NEW_PROCESS_GROUP = 0x00000200
CREATE_NO_WINDOW = 0x08000000
# The platform the children run on; a module constant so that tests can ask for Windows'.
OS_NAME = os.name


def child_options(os_name: Optional[str] = None) -> dict:
    """Popen arguments for every child process: output decoded as UTF-8 (what the Rust
    program writes; the locale codec of a Windows Slicer is not, and a non-ASCII temp
    path would then end the reader thread and leave the child blocked on a full pipe),
    undecodable bytes replaced, never raised; no console window on Windows (as
    slicer.util.launchConsoleProcess does); and a process group of its own, so that
    cancel ends its children too (gmsh under `baffle mesh`)."""
    options = {"encoding": "utf-8", "errors": "replace", "stdin": subprocess.DEVNULL}
    if (os_name or OS_NAME) == "nt":
        options["creationflags"] = CREATE_NO_WINDOW | CREATE_NEW_PROCESS_GROUP
    else:
        options["start_new_session"] = True
    return options


def tree_kill_command(pid: int) -> List[str]:
    """Windows: end the process and every process it started (taskkill /T), forcibly (/F:
    console programs ignore the polite close)."""
    return ["taskkill", "/PID", str(pid), "/T", "/F"]


def run_captured(command: List[str], env: Optional[dict] = None, timeout: float = 20.0) -> subprocess.CompletedProcess:
    """A short child run with its output captured, under child_options()."""
    return subprocess.run([str(c) for c in command], env=env, capture_output=True, timeout=timeout, check=False,
                          **child_options())


def subcommand_availability(executable: Optional[str], subcommand: str, timeout: float = 20.0) -> Tuple[bool, str]:
    """(True, "") when `executable SUBCOMMAND --help` succeeds, else (False, why)."""
    if not executable:
        return False, "the baffle command line program was not found (set BAFFLE_EXECUTABLE or put baffle on PATH)"
    try:
        done = run_captured([executable, subcommand, "--help"], timeout=timeout)
    except (OSError, subprocess.TimeoutExpired) as error:
        return False, f"{executable} {subcommand} --help: {error}"
    if done.returncode == 0:
        return True, ""
    detail = (done.stderr or done.stdout).strip().splitlines()
    return False, f"`baffle {subcommand}` is not available in this build" + (f" ({detail[0]})" if detail else "")


def simulate_availability(executable: Optional[str]) -> Tuple[bool, str]:
    """Whether this build has the CFD worker (`baffle simulate`), and if not, why."""
    available, reason = subcommand_availability(executable, "simulate")
    if available:
        return True, ""
    return False, "The CFD worker is not available in this build: " + reason


class SubcommandProbe:
    """subcommand_availability() for several subcommands on a background thread, so that
    a GUI asking at start-up never waits for the program (`--help` of a cold binary on a
    network drive can take seconds). `results` (subcommand -> (available, why not)) is
    complete once `done`; until then the GUI treats the subcommands as not yet known."""

    def __init__(self, executable: Optional[str], subcommands, timeout: float = 20.0, checks: Optional[dict] = None):
        """`checks`: more named checks to run there, name -> callable returning (available, why not)."""
        self.executable = executable
        self.subcommands = list(subcommands)
        self.timeout = timeout
        self.checks = dict(checks or {})
        self.results = {}
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> "SubcommandProbe":
        self._thread.start()
        return self

    def _run(self) -> None:
        results = {name: subcommand_availability(self.executable, name, self.timeout) for name in self.subcommands}
        results.update({name: check() for name, check in self.checks.items()})
        self.results = results  # one assignment: readers see all of them or none

    @property
    def done(self) -> bool:
        return not self._thread.is_alive() and len(self.results) == len(self.subcommands) + len(self.checks)

    def wait(self, timeout: Optional[float] = None) -> dict:
        self._thread.join(timeout)
        return self.results


class CliProcess:
    """One command line run. start() returns at once; `progress` (0..1), `stage`,
    `state` and `output_lines` update from reader threads; cancel() terminates it
    (then kills it after `kill_after` seconds)."""

    def __init__(self, command: List[str], cwd: Optional[str] = None, env: Optional[dict] = None):
        self.command = [str(c) for c in command]
        self.cwd = cwd
        self.env = env
        self.progress = 0.0
        self.stage = ""
        self.comment = ""
        self.state = ""
        self.returncode: Optional[int] = None
        self.output_lines: List[str] = []
        self.error_lines: List[str] = []
        self.progress_updates = 0
        self._process: Optional[subprocess.Popen] = None
        self._threads: List[threading.Thread] = []
        self._cancel_requested = False
        self._lock = threading.Lock()
        self.started_at = 0.0
        self.finished_at = 0.0

    def start(self) -> "CliProcess":
        if self._process is not None:
            raise RuntimeError("already started")
        self.started_at = time.monotonic()
        self._process = subprocess.Popen(
            self.command, cwd=self.cwd, env=self.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=1,
            **child_options(),
        )
        self.state = RUNNING
        self._threads = [
            threading.Thread(target=self._read_stdout, daemon=True),
            threading.Thread(target=self._read_stderr, daemon=True),
        ]
        for thread in self._threads:
            thread.start()
        threading.Thread(target=self._wait, daemon=True).start()
        return self

    def _read_stdout(self) -> None:
        for line in self._process.stdout:
            line = line.rstrip("\n")
            with self._lock:
                self.output_lines.append(line)
                for tag, value in _TAG.findall(line):
                    if tag == "filter-progress":
                        try:
                            self.progress = min(1.0, max(0.0, float(value)))
                            self.progress_updates += 1
                        except ValueError:
                            pass
                    elif tag in ("filter-stage", "filter-name"):
                        self.stage = value
                    elif tag == "filter-comment":
                        self.comment = value

    def _read_stderr(self) -> None:
        for line in self._process.stderr:
            with self._lock:
                self.error_lines.append(line.rstrip("\n"))

    def _wait(self) -> None:
        code = self._process.wait()
        if self._cancel_requested:
            # Children the program started (gmsh under `baffle mesh`) go with it.
            self._signal(signal.SIGKILL if OS_NAME != "nt" else None)
        for thread in self._threads:
            thread.join()
        with self._lock:
            self.returncode = code
            self.finished_at = time.monotonic()
            if self._cancel_requested:
                self.state = CANCELLED
            elif code == 0:
                self.progress = 1.0
                self.state = COMPLETED
            else:
                self.state = FAILED

    @property
    def running(self) -> bool:
        return self.state == RUNNING

    def cancel(self, kill_after: float = 3.0) -> None:
        """Ask the process (group) to stop; returns at once. A background timer kills it
        if it has not exited after `kill_after` seconds."""
        if self._process is None or self.state != RUNNING:
            return
        self._cancel_requested = True
        self._signal(signal.SIGTERM if OS_NAME != "nt" else None)

        def kill_later():
            try:
                self._process.wait(timeout=kill_after)
            except subprocess.TimeoutExpired:
                self._signal(signal.SIGKILL if OS_NAME != "nt" else None)

        threading.Thread(target=kill_later, daemon=True).start()

    def _signal(self, sig) -> None:
        """sig to the child's process group; None (Windows): end its process tree."""
        try:
            if sig is None:
                run_captured(tree_kill_command(self._process.pid), timeout=10.0)
            else:
                os.killpg(self._process.pid, sig)
        except (ProcessLookupError, PermissionError, OSError, subprocess.TimeoutExpired):
            pass

    def wait(self, timeout: Optional[float] = None) -> str:
        """Block until the run has ended (tests and scripts; the GUI polls instead)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.state == RUNNING:
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"{' '.join(self.command)} still running after {timeout} s")
            time.sleep(0.02)
        return self.state

    def error_message(self) -> str:
        """The program's own error line (`baffle: error: ...`), else its last stderr line."""
        with self._lock:
            for line in reversed(self.error_lines):
                if "error" in line.lower():
                    return line.strip()
            return self.error_lines[-1].strip() if self.error_lines else f"exit code {self.returncode}"


class PolledJob:
    """Base of the jobs a GUI timer advances with poll(): one CliProcess at a time (`run`),
    `state` (RUNNING / COMPLETED / FAILED / CANCELLED) and `message`; wait() polls until
    the end (tests and scripts). Subclasses define poll() and call finish()."""

    def __init__(self):
        self.run: Optional[CliProcess] = None
        self.stage = ""
        self.state = ""
        self.message = ""
        self.started_at = 0.0
        self.finished_at = 0.0

    def start_process(self, command: List[str], cwd: Optional[str] = None, env: Optional[dict] = None) -> None:
        """Start the current stage's process (OSError when it cannot be started)."""
        if not self.started_at:
            self.started_at = time.monotonic()
        self.run = CliProcess(command, cwd=cwd, env=env).start()
        self.state = RUNNING
        self.message = f"{self.stage} running"

    @property
    def running(self) -> bool:
        return self.state == RUNNING

    def cancel_process(self, kill_after: float) -> None:
        if self.running:
            self.run.cancel(kill_after=kill_after)

    def poll(self) -> str:
        raise NotImplementedError

    def finish(self, state: str, message: str) -> str:
        self.state = state
        self.message = message
        self.finished_at = time.monotonic()
        return state

    def wait(self, timeout: Optional[float] = None, poll_interval: float = 0.05) -> str:
        """Poll until the job has ended."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() == RUNNING:
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"{self.stage} still running after {timeout} s")
            time.sleep(poll_interval)
        return self.state


class LibraryJob:
    """Base of the jobs that run one library call on a worker thread without blocking the
    GUI (the ctypes call releases the GIL, so the event loop keeps running): start() reads
    the inputs on the caller's thread and hands them to start_worker(); the worker keeps
    what the call returns or raises in `_outcome`; poll(), called from the caller's timer,
    hands it once to ended() when the thread is done, on the caller's thread (MRML is
    written there only). `progress` / `stage` follow the library's progress callback;
    cancel() sets `_cancel`, which _report() passes back to the library. `state` is
    RUNNING / COMPLETED / FAILED / CANCELLED. Subclasses define _work() and ended()."""

    what = "job"  # what wait()'s TimeoutError names
    poll_interval = 0.05

    def __init__(self, logic, curve, stage: str):
        self.logic = logic
        self.curve = curve
        self.curve_id = curve.GetID() if curve is not None else None
        self.progress = 0.0
        self.stage = stage
        self.state = ""
        self.message = ""
        self.result = None
        self.user_progress = None  # called from wait() on the caller's thread; False cancels
        self._cancel = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._outcome = None

    def start_worker(self, *args) -> None:
        self._thread = threading.Thread(target=self._work, args=args, daemon=True)
        self._thread.start()

    def _work(self, *args) -> None:
        raise NotImplementedError

    def ended(self, outcome) -> str:
        raise NotImplementedError

    def _report(self, fraction, stage) -> bool:
        self.progress, self.stage = float(fraction), stage
        return not self._cancel.is_set()

    @property
    def running(self) -> bool:
        return self.state == RUNNING

    def cancel(self) -> None:
        self._cancel.set()

    def poll(self) -> str:
        """RUNNING while the library works; then its outcome goes to ended() (once)."""
        if self.state != RUNNING or self._thread is None or self._thread.is_alive():
            return self.state
        outcome, self._outcome = self._outcome, None
        return self.ended(outcome)

    def wait(self, timeout: Optional[float] = None, poll_interval: Optional[float] = None, until=None) -> str:
        """Poll until the job has ended (or until() is true), reporting progress to
        `user_progress`."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() == RUNNING and not (until and until()):
            if self.user_progress is not None and self.user_progress(self.progress, self.stage) is False:
                self.cancel()
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"{self.what} still running at stage {self.stage} after {timeout} s")
            self._thread.join(self.poll_interval if poll_interval is None else poll_interval)
        return self.state
