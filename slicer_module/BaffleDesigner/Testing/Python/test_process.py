"""The process plumbing of Simulate, against the `baffle` subcommands this build has:
progress tags of `baffle design --progress-tags`, errors, cancellation of a long
`baffle mesh`, the simulate-availability check, and a volume mesh loaded into the scene."""

import subprocess
import time

import pytest

from conftest import bdlogic, has_subcommand
from BaffleDesignerLib import process


def test_design_progress_tags_are_parsed(executable, tmp_path):
    run = process.CliProcess([executable, "design", "--phantom", "--out", tmp_path, "--progress-tags"]).start()
    assert run.wait(timeout=120) == process.COMPLETED, run.error_lines
    assert run.returncode == 0 and run.progress == 1.0
    assert run.progress_updates >= 5
    tagged = [line for line in run.output_lines if line.startswith("<filter-progress>")]
    values = [float(line[len("<filter-progress>"):-len("</filter-progress>")]) for line in tagged]
    assert values == sorted(values) and len(values) == run.progress_updates
    assert run.stage  # the last <filter-stage> seen
    assert (tmp_path / "domain.vtp").exists() and (tmp_path / "report.json").exists()


def test_a_failing_run_carries_the_programs_message(executable, tmp_path):
    run = process.CliProcess(
        [executable, "design", "--surface", tmp_path / "missing.vtp", "--points", tmp_path / "missing.mrk.json",
         "--bsa", "0.37", "--out", tmp_path / "out"]
    ).start()
    assert run.wait(timeout=60) == process.FAILED
    assert run.returncode != 0
    message = run.error_message()
    assert message.startswith("baffle: error:") and "missing.vtp" in message


def test_cancel_ends_a_long_mesh_run_without_blocking(executable, tmp_path):
    if not has_subcommand(executable, "mesh"):
        pytest.skip("this baffle build has no mesh subcommand")
    design = process.CliProcess([executable, "design", "--phantom", "--out", tmp_path / "design"]).start()
    assert design.wait(timeout=120) == process.COMPLETED
    # A fine mesh of the phantom domain (about 3e6 tetrahedra, under `baffle mesh`'s
    # 5e6 limit) takes far longer than the test waits.
    command = [executable, "mesh", "--surface", tmp_path / "design" / "domain.vtp", "--out", tmp_path / "fine.vtu",
               "--edge-length-mm", "0.2"]
    started = time.monotonic()
    run = process.CliProcess(command).start()
    assert time.monotonic() - started < 1.0  # start() does not wait for the process
    time.sleep(1.5)
    # Ending early would leave nothing to cancel: a failure, not a skip.
    assert run.state == process.RUNNING, f"baffle mesh ended before it could be cancelled: {run.state}, {run.error_message()}"
    cancel_at = time.monotonic()
    run.cancel()
    assert time.monotonic() - cancel_at < 0.5  # cancel() does not wait either
    assert run.wait(timeout=15) == process.CANCELLED
    assert run.returncode != 0
    assert not (tmp_path / "fine.vtu").exists()
    # The process group is gone too (gmsh runs as a child of baffle mesh).
    assert live_group_members(run._process.pid) == []


def live_group_members(group, patience=5.0):
    """Processes of the group that are not zombies, after up to `patience` seconds."""
    deadline = time.monotonic() + patience
    while True:
        listing = subprocess.run(["ps", "-eo", "pid=,pgid=,stat=,comm="], capture_output=True, text=True).stdout
        alive = [line.split() for line in listing.splitlines()]
        alive = [row for row in alive if len(row) >= 3 and row[1] == str(group) and not row[2].startswith("Z")]
        if not alive or time.monotonic() > deadline:
            return alive
        time.sleep(0.1)


def test_simulate_availability_matches_the_build(executable):
    available, reason = process.simulate_availability(executable)
    assert available == has_subcommand(executable, "simulate")
    if not available:
        assert reason.startswith("The CFD worker is not available in this build")
    assert process.simulate_availability(None)[0] is False


def test_volume_mesh_of_a_candidate_is_loaded_into_the_scene(executable, phantom_scene, tmp_path):
    if not has_subcommand(executable, "mesh"):
        pytest.skip("this baffle build has no mesh subcommand")
    scene, logic, model, curve = phantom_scene
    with pytest.raises(bdlogic.BaffleDesignerError, match="design the baffle first"):
        logic.volumeMeshCommand(curve, executable, str(tmp_path))
    logic.design(curve)
    run = process.CliProcess(logic.volumeMeshCommand(curve, executable, str(tmp_path), edge_length_mm=1.2)).start()
    state = run.wait(timeout=300)
    if state == process.FAILED and "gmsh" in run.error_message().lower():
        pytest.skip(f"gmsh is not installed: {run.error_message()}")
    assert state == process.COMPLETED, run.error_message()
    node, quality = logic.loadVolumeMesh(curve, str(tmp_path))
    assert node.GetMeshType() == node.UnstructuredGridMeshType
    cells = node.GetMesh().GetNumberOfCells()
    names = quality.GetTable().GetColumnByName("Measure")
    values = quality.GetTable().GetColumnByName("Value")
    figures = {names.GetValue(i): values.GetValue(i) for i in range(names.GetNumberOfValues())}
    assert figures["tetrahedra"] == cells > 1000
    assert curve.GetNodeReference(bdlogic.REF_VOLUME_MESH) is node
