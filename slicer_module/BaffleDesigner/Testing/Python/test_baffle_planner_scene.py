"""BaffleDesigner in the scene a SlicerHeart user has: BafflePlanner's 'BC' closed curve,
its parameter node and its logic, which rebuilds its baffle on every ModifiedEvent of the
curve (baffle_planner_standin.py, after SlicerHeart's public BafflePlanner.py). On
slicer-core's real MRML classes, without Qt."""

import time

import pytest
import vtk

from baffle_planner_standin import BafflePlannerLogic
from BaffleDesignerLib import logic as bdlogic
from BaffleDesignerLib import process
from conftest import phantom_candidate


def planner_on(scene, curve):
    """BafflePlanner's logic working on `curve`, auto-updating its 'BaffleModel'."""
    planner = BafflePlannerLogic(scene)
    planner.setInputCurveNode(curve)
    baffle_model = scene.AddNewNodeByClass("vtkMRMLModelNode", "Baffle")
    planner.setOutputBaffleModelNode(baffle_model)
    assert curve.GetAttribute("AutoUpdate") == "true" and planner.rebuilds > 0
    assert baffle_model.GetPolyData().GetNumberOfPoints() > 0  # its soap bubble
    planner.rebuilds = planner.modified_reactions = 0
    return planner


def count_modified(node):
    counter = {"n": 0}
    tag = node.AddObserver(vtk.vtkCommand.ModifiedEvent, lambda *_: counter.__setitem__("n", counter["n"] + 1))
    return counter, tag


def test_one_design_is_one_modified_event_and_one_baffle_planner_reaction(phantom_scene):
    scene, logic, _, curve = phantom_scene
    planner = planner_on(scene, curve)
    counter, tag = count_modified(curve)
    logic.design(curve)
    curve.RemoveObserver(tag)
    assert curve.GetAttribute("BaffleDesigner.Status") == "designed"
    assert counter["n"] == 1, f"{counter['n']} ModifiedEvents of the curve for one design"
    assert planner.modified_reactions == 1
    # BafflePlanner's own answer to one ModifiedEvent: setOutputBaffleModelNode ->
    # updatePointPlaceMode rebuilds, then it rebuilds again (its code, not ours).
    assert planner.rebuilds == 2
    # Storing parameters is one event too.
    counter, tag = count_modified(curve)
    logic.setParameters(curve, bdlogic.DesignParameters(target_mode="area", target_area_mm2=60.0))
    curve.RemoveObserver(tag)
    assert counter["n"] == 1


def test_a_failed_design_is_one_modified_event(phantom_scene):
    scene, logic, _, curve = phantom_scene
    logic.setParameters(curve, bdlogic.DesignParameters(target_mode="area", target_area_mm2=1e6))
    counter, tag = count_modified(curve)
    with pytest.raises(bdlogic.BaffleDesignerError):
        logic.design(curve)
    curve.RemoveObserver(tag)
    assert curve.GetAttribute("BaffleDesigner.Status") == "failed" and counter["n"] == 1


def add_preview_point(curve, position):
    """Place mode as Slicer's markups widget does it: a preview control point that follows
    the mouse (PositionPreview), moved on every mouse move with no interaction events."""
    index = curve.AddControlPointWorld(vtk.vtkVector3d(*position))
    curve.SetNthControlPointPositionWorld(index, *position, curve.PositionPreview)
    return index


def test_moving_a_preview_point_requests_no_design(phantom_scene):
    scene, logic, _, curve = phantom_scene
    logic.setAutoUpdate(curve, True)
    a = curve.GetNthControlPointPositionWorld(0)
    index = add_preview_point(curve, [a[0] + 5, a[1], a[2]])
    assert curve.GetNthControlPointPositionStatus(index) == curve.PositionPreview
    logic._pending.clear()  # whatever the add asked for; the moves are the question
    for step in range(20):
        curve.SetNthControlPointPositionWorld(index, a[0] + 5 + step, a[1] + step, a[2], curve.PositionPreview)
    assert logic.pendingUpdates() == []
    assert logic.processPendingUpdates(force=True) == {} and logic.design_count == 0
    # Placing it (the click) is a change of the defined points: that redesigns.
    curve.SetNthControlPointPositionWorld(index, a[0] + 1, a[1], a[2])
    assert logic.pendingUpdates() == [curve.GetID()]
    logic.cleanup()


def test_auto_update_is_rearmed_in_a_reopened_scene(phantom_scene):
    scene, logic, _, curve = phantom_scene
    logic.setAutoUpdate(curve, True)
    logic.cleanup()  # the scene is closed and read back: the attribute stays, observers do not
    again = bdlogic.BaffleDesignerLogic(scene)
    assert not again.isAutoUpdating(curve)
    assert again.rearmAutoUpdates() == [curve.GetID()]
    a = curve.GetNthControlPointPositionWorld(2)
    curve.SetNthControlPointPositionWorld(2, a[0] + 0.5, a[1], a[2])
    assert again.pendingUpdates() == [curve.GetID()]
    again.cleanup()


def test_the_design_runs_off_the_calling_thread_and_can_be_cancelled(phantom_scene):
    scene, logic, _, curve = phantom_scene
    first = logic.design(curve)
    area = curve.GetAttribute("BaffleDesigner.BaffleAreaMm2")
    baffle_id = curve.GetNodeReferenceID(bdlogic.REF_BAFFLE)
    started = time.perf_counter()
    job = logic.startDesign(curve)
    returned_s = time.perf_counter() - started
    assert job.state == process.RUNNING and job._thread.is_alive()
    job.cancel()
    assert job.wait(timeout=60) == process.CANCELLED, job.message
    assert curve.GetAttribute("BaffleDesigner.BaffleAreaMm2") == area  # the last good baffle stays
    assert curve.GetNodeReferenceID(bdlogic.REF_BAFFLE) == baffle_id
    assert curve.GetAttribute("BaffleDesigner.Status") == "designed"
    assert returned_s < 0.5 * float(curve.GetAttribute("BaffleDesigner.DesignTimeMs")) / 1000.0 + 0.05
    assert first.report["baffle_area_mm2"] > 0


def test_a_design_whose_curve_was_removed_writes_nothing(phantom_scene):
    scene, logic, _, curve = phantom_scene
    models_before = scene.GetNumberOfNodesByClass("vtkMRMLModelNode")
    job = logic.startDesign(curve)
    scene.RemoveNode(curve)
    assert job.wait(timeout=60) == process.CANCELLED
    assert "removed" in job.message
    assert scene.GetNumberOfNodesByClass("vtkMRMLModelNode") == models_before


def test_the_parameter_node_defaults_to_baffle_planners_input_curve(scene):
    _, logic, _, curve = phantom_candidate(scene)
    other = scene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", "another curve")
    assert logic.defaultInputCurve() is None
    planner = BafflePlannerLogic(scene)
    planner.setInputCurveNode(curve)
    assert planner.getParameterNode().GetNodeReference("InputCurve") is curve
    assert logic.bafflePlannerCurve() is curve and logic.defaultInputCurve() is curve
    logic.setInputCurve(other)  # the user's choice wins, and is the parameter node's
    assert logic.defaultInputCurve() is other
    node = logic.parameterNode()
    assert node.GetAttribute("ModuleName") == "BaffleDesigner" and node.GetSingletonTag() == "BaffleDesigner"
    assert node.GetNodeReference("InputCurve") is other


def test_a_candidates_outputs_are_in_its_folder_and_leave_with_its_curve(phantom_scene):
    import slicer

    scene, logic, model, curve = phantom_scene
    logic.design(curve)
    sh = slicer.vtkMRMLSubjectHierarchyNode.GetSubjectHierarchyNode(scene)
    folder = logic.candidateFolder(curve, create=False)
    assert folder and sh.GetItemName(folder) == "phantom BC BaffleDesigner"
    outputs = [curve.GetNodeReference(role) for role in bdlogic.OUTPUT_ROLES if curve.GetNodeReference(role)]
    assert len(outputs) >= 8
    assert all(sh.GetItemParent(sh.GetItemByDataNode(node)) == folder for node in outputs)
    ids = [node.GetID() for node in outputs]
    scene.RemoveNode(curve)
    assert [node_id for node_id in ids if scene.GetNodeByID(node_id) is not None] == []
    assert scene.GetNodeByID(model.GetID()) is model  # the ventricle is an input: it stays
    assert logic.candidateFolder(curve, create=False) == 0


def test_a_simulation_whose_curve_was_removed_loads_nothing(phantom_scene, tmp_path):
    import stat

    scene, logic, _, curve = phantom_scene
    logic.design(curve)
    slow = tmp_path / "baffle"
    slow.write_text("#!/bin/sh\nsleep 30\n")
    slow.chmod(slow.stat().st_mode | stat.S_IEXEC)
    job = logic.startSimulation(curve, str(slow), str(tmp_path / "work"))
    assert job.poll() == process.RUNNING
    scene.RemoveNode(curve)
    assert job.poll() == process.CANCELLED and "removed" in job.message
    assert job.run.wait(timeout=10) == process.CANCELLED
    assert scene.GetNodesByClass("vtkMRMLTableNode").GetNumberOfItems() == 0


def test_the_comparison_with_baffle_planners_own_baffle(phantom_scene):
    from conftest import column

    scene, logic, _, curve = phantom_scene
    planner = planner_on(scene, curve)
    with pytest.raises(bdlogic.BaffleDesignerError, match="design the baffle first"):
        logic.compareWithBafflePlanner(curve)
    logic.design(curve)
    figures = logic.compareWithBafflePlanner(curve)
    ours = float(curve.GetAttribute("BaffleDesigner.BaffleAreaMm2"))
    # The same surface measured twice (library, VTK): the areas agree to rounding.
    assert figures["BaffleDesignerAreaMm2"] == pytest.approx(ours, rel=1e-3)
    assert figures["BafflePlannerAreaMm2"] > 0
    assert 0 < figures["BafflePlannerMeanDistanceMm"] <= figures["BafflePlannerMaxDistanceMm"] < float("inf")
    table = logic.updateCompareTable()
    assert column(table, "BafflePlanner area")[0] == pytest.approx(figures["BafflePlannerAreaMm2"], abs=1e-3)
    assert column(table, "Distance to BafflePlanner")[0] == pytest.approx(figures["BafflePlannerMeanDistanceMm"], abs=1e-3)
    # Both rim on the same suture curve: BafflePlanner's soap bubble meets ours there.
    baffle_planner_model = curve.GetNodeReference("BaffleModel").GetPolyData()
    rim = bdlogic._distances_to(baffle_planner_model, curve.GetNodeReference(bdlogic.REF_BAFFLE).GetPolyData())
    assert planner.rebuilds >= 2 and rim.min() < 1.0


def test_renaming_the_curve_renames_its_outputs_and_folder(phantom_scene):
    import slicer

    scene, logic, _, curve = phantom_scene
    logic.design(curve)
    baffle = curve.GetNodeReference(bdlogic.REF_BAFFLE)
    assert baffle.GetName() == "phantom BC baffle"
    curve.SetName("candidate A")
    assert baffle.GetName() == "candidate A baffle"
    assert curve.GetNodeReference(bdlogic.REF_TABLE).GetName() == "candidate A sections"
    sh = slicer.vtkMRMLSubjectHierarchyNode.GetSubjectHierarchyNode(scene)
    assert sh.GetItemName(logic.candidateFolder(curve, create=False)) == "candidate A BaffleDesigner"
    baffle.SetName("my own name")  # a name the user gave stays
    curve.SetName("candidate B")
    assert baffle.GetName() == "my own name"


def test_a_plan_runs_geometry_loads_as_slicer_reads_model_files(phantom_scene, tmp_path):
    import numpy as np
    import slicer

    scene, logic, model, curve = phantom_scene
    logic.design(curve)
    (tmp_path / "run" / "design").mkdir(parents=True)
    writer = vtk.vtkXMLPolyDataWriter()
    writer.SetInputData(curve.GetNodeReference(bdlogic.REF_DOMAIN).GetPolyData())
    writer.SetFileName(str(tmp_path / "run" / "design" / "domain.vtp"))  # no frame in the file: LPS
    assert writer.Write()
    with pytest.raises(bdlogic.BaffleDesignerError, match="no plan geometry"):
        logic.loadPlanGeometry(str(tmp_path))
    (node,) = logic.loadPlanGeometry(str(tmp_path / "run"))
    assert node.GetName() == "plan run domain"
    ours = curve.GetNodeReference(bdlogic.REF_DOMAIN).GetPolyData().GetBounds()
    theirs = node.GetPolyData().GetBounds()
    # LPS -> RAS: x and y flip, z stays.
    np.testing.assert_allclose(theirs, (-ours[1], -ours[0], -ours[3], -ours[2], ours[4], ours[5]), atol=1e-9)
    sh = slicer.vtkMRMLSubjectHierarchyNode.GetSubjectHierarchyNode(scene)
    assert sh.GetItemName(sh.GetItemParent(sh.GetItemByDataNode(node))) == "plan run"
