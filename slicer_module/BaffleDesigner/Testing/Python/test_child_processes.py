"""How the module starts child processes on every platform (Windows' flags checked with
Popen recorded, since they cannot be used here): UTF-8 output that a stray byte cannot
stop, no console windows, process-tree cancel, and the Python the gmsh check and
`baffle mesh` use, found the way Slicer runs Python."""

import os
import stat
import sys

import pytest

from BaffleDesignerLib import environment, process

# 300 KB after a byte that is not UTF-8: a reader thread that dies on it leaves the child
# blocked on a full pipe (64 KB), so the run never ends.
NOISY_CHILD = (
    "import sys; out = sys.stdout.buffer; out.write('Temp: C:/Users/Jos\\u00e9/AppData\\n'.encode('utf-8'));"
    "out.write(b'cp1252 byte: \\xff\\n'); [out.write(b'x' * 99 + b'\\n') for _ in range(3000)];"
    "out.write(b'<filter-progress>0.5</filter-progress>\\n'); out.flush()"
)


def test_output_is_utf8_and_a_stray_byte_cannot_hang_the_run():
    run = process.CliProcess([sys.executable, "-c", NOISY_CHILD]).start()
    try:
        assert run.wait(timeout=30) == process.COMPLETED, run.error_lines
    finally:
        run.cancel()
    assert run.output_lines[0] == "Temp: C:/Users/Jos\u00e9/AppData"
    assert run.output_lines[1] == "cp1252 byte: \ufffd"
    assert len(run.output_lines) == 3003 and run.progress == 1.0 and run.progress_updates == 1


def test_every_child_gets_utf8_and_its_own_group():
    posix = process.child_options("posix")
    assert posix["encoding"] == "utf-8" and posix["errors"] == "replace" and posix["start_new_session"]
    windows = process.child_options("nt")
    assert windows["encoding"] == "utf-8" and "start_new_session" not in windows
    assert windows["creationflags"] & process.CREATE_NO_WINDOW
    assert windows["creationflags"] & process.CREATE_NEW_PROCESS_GROUP


class RecordedPopen:
    """subprocess.Popen as Windows would be asked: the arguments are kept, nothing runs."""

    calls = []

    def __init__(self, command, **kwargs):
        RecordedPopen.calls.append((command, kwargs))
        self.pid = 4242
        self.stdout = iter(())
        self.stderr = iter(())
        self._code = None

    def wait(self, timeout=None):
        import time

        while self._code is None:
            if timeout is not None:
                raise process.subprocess.TimeoutExpired("baffle", timeout)
            time.sleep(0.01)
        return self._code


def test_on_windows_no_console_window_and_cancel_ends_the_process_tree(monkeypatch):
    RecordedPopen.calls = []
    killed = []
    monkeypatch.setattr(process, "OS_NAME", "nt")
    monkeypatch.setattr(process.subprocess, "Popen", RecordedPopen)

    def fake_run(command, **kwargs):
        killed.append((command, kwargs))
        run._process._code = 1  # taskkill ended it
        return process.subprocess.CompletedProcess(command, 0, "", "")

    monkeypatch.setattr(process.subprocess, "run", fake_run)
    run = process.CliProcess(["baffle.exe", "mesh"]).start()
    command, kwargs = RecordedPopen.calls[0]
    assert kwargs["creationflags"] & process.CREATE_NO_WINDOW and kwargs["encoding"] == "utf-8"
    assert "text" not in kwargs and "start_new_session" not in kwargs
    run.cancel(kill_after=0.1)
    assert run.wait(timeout=5) == process.CANCELLED
    assert killed[0][0] == ["taskkill", "/PID", "4242", "/T", "/F"]  # gmsh under baffle mesh too
    assert killed[0][1]["creationflags"] & process.CREATE_NO_WINDOW  # taskkill shows no window either


def test_the_python_for_gmsh_is_found_as_slicer_runs_python(tmp_path):
    bin_dir = tmp_path / "Slicer-5.8.1" / "bin"
    bin_dir.mkdir(parents=True)
    python_slicer = bin_dir / "PythonSlicer"
    python_slicer.write_text("#!/bin/sh\n")
    python_slicer.chmod(python_slicer.stat().st_mode | stat.S_IEXEC)
    application = str(bin_dir / "SlicerApp-real")
    assert environment.python_interpreter({}, executable=application) == str(python_slicer)
    assert environment.python_interpreter({"BAFFLE_PYTHON": "/opt/py"}, executable=application) == "/opt/py"
    assert environment.python_interpreter({"PATH": ""}, executable=str(tmp_path / "Slicer.exe"), os_name="nt") == "python"
    assert environment.python_interpreter({"PATH": ""}, executable="/usr/bin/python3.11") == "/usr/bin/python3.11"
    assert environment.child_environment({"PATH": str(bin_dir)})["BAFFLE_PYTHON"] == str(python_slicer)


def test_the_gmsh_check_runs_the_python_baffle_mesh_will_run(tmp_path):
    env = {"PATH": str(tmp_path), "BAFFLE_PYTHON": str(tmp_path / "no-such-python")}
    available, reason = environment.gmsh_availability(env)
    assert not available and "no-such-python" in reason and "python3:" not in reason
