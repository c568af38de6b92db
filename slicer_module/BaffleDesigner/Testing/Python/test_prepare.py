"""A segmentation node as the ventricle (slicer-core): p2's LV, RV and aorta surfaces
loaded as Slicer loads model files (LPS on disk -> RAS) and imported into a segmentation
as closed-surface segments; the logic exports them, runs `baffle prepare` as a separate
process, loads the capped ventricle and designs on it with p2's suture points."""

import time

import numpy as np
import pytest
import vtk
from vtkmodules.util import numpy_support

from conftest import bdlogic, column, curve_from_points, data_dir, has_subcommand, missing_data, load_closed_curve, load_model, p2_inputs, slicer, translation_node
from BaffleDesignerLib import candidate as bdcandidate
from BaffleDesignerLib import prepare, process
from test_logic import open_and_nonmanifold_edges


def p2_segmentation(scene, structures=("LV", "RV", "aorta"), names=None):
    """A segmentation node of p2's blood pools, one closed-surface segment per file."""
    folder = data_dir() / "p2" / "segmentations"
    if not folder.exists():
        missing_data(folder)
    segmentation = scene.AddNewNodeByClass("vtkMRMLSegmentationNode", "p2 blood pools")
    segmentation.SetSourceRepresentationToClosedSurface()
    for structure, name in zip(structures, names or structures):
        model = load_model(scene, folder / f"{structure}.vtp", name=name)
        assert slicer.vtkSlicerSegmentationsModuleLogic.ImportModelToSegmentationNode(model, segmentation)
        scene.RemoveNode(model)
    return segmentation


def label_centroids(polydata):
    """{label: area-weighted centroid} of a labelled triangle surface."""
    points = numpy_support.vtk_to_numpy(polydata.GetPoints().GetData()).astype(np.float64)
    polys = polydata.GetPolys()
    offsets = numpy_support.vtk_to_numpy(polys.GetOffsetsArray())
    assert np.all(np.diff(offsets) == 3), "triangles expected"
    triangles = numpy_support.vtk_to_numpy(polys.GetConnectivityArray()).reshape(-1, 3)
    labels = numpy_support.vtk_to_numpy(polydata.GetCellData().GetArray("ModelFaceID")).ravel()
    a, b, c = (points[triangles[:, k]] for k in range(3))
    areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    centers = (a + b + c) / 3.0
    return {int(l): (areas[labels == l, None] * centers[labels == l]).sum(0) / areas[labels == l].sum() for l in np.unique(labels)}


@pytest.fixture(scope="module")
def prepared(executable):
    """p2 designed from its segmentation: (scene, logic, segmentation, curve, result, seconds)."""
    if not has_subcommand(executable, "prepare"):
        pytest.skip("this baffle build has no prepare subcommand")
    _, points_path = p2_inputs()
    scene = slicer.vtkMRMLScene()
    segmentation = p2_segmentation(scene, names=("lv", "Right ventricle", "AORTA"))
    curve = load_closed_curve(scene, points_path)
    logic = bdlogic.BaffleDesignerLogic(scene)
    logic.executable = executable
    logic.setSurfaceNode(curve, segmentation)
    logic.setParameters(curve, bdlogic.DesignParameters(target_mode="bsa", bsa_m2=0.37, rv_segment="right ventricle"))
    assert logic.needsPrepare(curve)
    started = time.monotonic()
    result = logic.design(curve)
    yield scene, logic, segmentation, curve, result, time.monotonic() - started
    scene.Clear(1)


def test_prepared_ventricle_is_closed_and_labelled(prepared):
    scene, logic, segmentation, curve, result, seconds = prepared
    node = curve.GetNodeReference(bdcandidate.REF_PREPARED)
    assert node is not None and node.IsA("vtkMRMLModelNode") and node.GetDisplayNode() is not None
    polydata = node.GetPolyData()
    labels = set(numpy_support.vtk_to_numpy(polydata.GetCellData().GetArray("ModelFaceID")).tolist())
    assert labels == {2, 11, 16}
    assert open_and_nonmanifold_edges(polydata) == 0
    assert logic.surfaceNode(curve) is segmentation  # the input stays the segmentation
    assert logic.prepare_count == 1 and not logic.needsPrepare(curve)
    assert float(node.GetAttribute("BaffleDesigner.PrepareVsdCapAreaMm2")) > 0
    print(
        f"prepare + design from the segmentation: {seconds:.1f} s (of it baffle prepare's own "
        f"{float(node.GetAttribute('BaffleDesigner.PrepareTimeMs')):.0f} ms), {polydata.GetNumberOfPolys()} triangles"
    )


def test_prepared_caps_match_the_published_design_input(prepared):
    scene, logic, segmentation, curve, result, _ = prepared
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(data_dir() / "p2" / "design_input" / "capped_ventricle.vtp"))
    reader.Update()
    published = label_centroids(reader.GetOutput())  # LPS, as on disk
    in_scene = prepare.flip_lps_ras(curve.GetNodeReference(bdcandidate.REF_PREPARED).GetPolyData())  # RAS -> LPS
    ours = label_centroids(in_scene)
    for label in (11, 16):
        distance = float(np.linalg.norm(ours[label] - published[label]))
        print(f"cap {label}: centroid {distance:.2f} mm from the published design input")
        assert distance < 1.5, f"cap {label} centroid {distance:.2f} mm from the published one"


def test_design_on_the_prepared_ventricle_meets_the_target(prepared):
    scene, logic, segmentation, curve, result, _ = prepared
    assert curve.GetAttribute("BaffleDesigner.Status") == "designed"
    table = curve.GetNodeReference(bdlogic.REF_TABLE)
    target = result.report["target_area_mm2"]
    constrained = np.array([s == "constrained" for s in column(table, bdlogic.COL_STATUS)])
    assert constrained.sum() >= 10
    assert np.all(column(table, bdlogic.COL_FINAL)[constrained] >= target)
    assert np.all(column(table, bdlogic.COL_MEASURED)[constrained] >= 0.999 * target)
    assert open_and_nonmanifold_edges(curve.GetNodeReference(bdlogic.REF_DOMAIN).GetPolyData()) == 0


def test_redesign_and_drag_reuse_the_prepared_ventricle(prepared):
    scene, logic, segmentation, curve, result, _ = prepared
    node = curve.GetNodeReference(bdcandidate.REF_PREPARED)
    logic.design(curve)
    logic.setAutoUpdate(curve, True)
    p = [0.0] * 3
    curve.GetNthControlPointPositionWorld(3, p)
    curve.SetNthControlPointPositionWorld(3, p[0] + 0.2, p[1], p[2])  # a move (one to the same place is none)
    assert logic.processPendingUpdates(force=True) == {curve.GetID(): None}
    logic.setAutoUpdate(curve, False)
    assert logic.prepare_count == 1 and curve.GetNodeReference(bdcandidate.REF_PREPARED) is node

    # Another segment choice is another input: live updates say so instead of preparing.
    parameters = logic.parameters(curve)
    parameters.lv_segment = "AORTA"
    logic.setParameters(curve, parameters)
    with pytest.raises(bdlogic.BaffleDesignerError, match="three different segments"):
        logic.design(curve, allow_prepare=False)
    parameters.lv_segment = "LV"
    logic.setParameters(curve, parameters)
    assert not logic.needsPrepare(curve)


def test_candidates_on_one_segmentation_share_the_prepared_ventricle(prepared):
    scene, logic, segmentation, curve, result, _ = prepared
    second = curve_from_points(scene, logic.suturePointsWorld(curve), "BC second")
    logic.setSurfaceNode(second, segmentation)
    logic.setParameters(second, logic.parameters(curve))
    assert not logic.needsPrepare(second)
    logic.design(second, allow_prepare=False)
    shared = curve.GetNodeReference(bdcandidate.REF_PREPARED)
    assert second.GetNodeReference(bdcandidate.REF_PREPARED) is shared and logic.prepare_count == 1
    polydata = shared.GetPolyData()
    # Re-preparing one candidate leaves the other's ventricle alone.
    prepare.store_prepared(logic, second, segmentation, vtk.vtkPolyData(), {}, "other inputs")
    assert second.GetNodeReference(bdcandidate.REF_PREPARED) is not shared
    assert curve.GetNodeReference(bdcandidate.REF_PREPARED) is shared and shared.GetPolyData() is polydata
    scene.RemoveNode(second)


def test_a_missing_aorta_segment_is_named(scene, executable):
    _, points_path = p2_inputs()
    segmentation = p2_segmentation(scene, structures=("LV", "RV"))
    curve = load_closed_curve(scene, points_path)
    logic = bdlogic.BaffleDesignerLogic(scene)
    logic.executable = executable
    logic.setSurfaceNode(curve, segmentation)
    with pytest.raises(bdlogic.BaffleDesignerError) as error:
        logic.design(curve)
    message = str(error.value)
    assert "no segment named 'aorta' for the aorta" in message and "'LV', 'RV'" in message, message
    assert curve.GetAttribute("BaffleDesigner.Error") == message
    assert curve.GetNodeReference(bdcandidate.REF_PREPARED) is None and logic.prepare_count == 0


def test_prepare_errors_carry_the_command_line_message(scene, executable, tmp_path):
    """Surfaces that do not touch: `baffle prepare` fails and says why; nothing is loaded."""
    _, points_path = p2_inputs()
    segmentation = scene.AddNewNodeByClass("vtkMRMLSegmentationNode", "spheres")
    segmentation.SetSourceRepresentationToClosedSurface()
    for name, x in (("LV", 0.0), ("RV", 40.0), ("aorta", 80.0)):
        sphere = vtk.vtkSphereSource()
        sphere.SetCenter(x, 0.0, 0.0)
        sphere.SetRadius(10.0)
        sphere.SetThetaResolution(24)
        sphere.SetPhiResolution(24)
        sphere.Update()
        segmentation.AddSegmentFromClosedSurfaceRepresentation(sphere.GetOutput(), name, [1.0, 0.0, 0.0])
    curve = load_closed_curve(scene, points_path)
    logic = bdlogic.BaffleDesignerLogic(scene)
    logic.setSurfaceNode(curve, segmentation)
    job = logic.startPrepare(curve, executable, str(tmp_path / "work"))
    assert job.wait(timeout=120) == process.FAILED
    assert job.message.startswith("prepare failed: baffle: error:"), job.message
    assert curve.GetNodeReference(bdcandidate.REF_PREPARED) is None
    assert sorted(p.name for p in (tmp_path / "work" / "segmentations").iterdir()) == ["LV.stl", "RV.stl", "aorta.stl"]


def test_prepare_can_be_cancelled(scene, executable, tmp_path):
    _, points_path = p2_inputs()
    segmentation = p2_segmentation(scene)
    curve = load_closed_curve(scene, points_path)
    logic = bdlogic.BaffleDesignerLogic(scene)
    logic.setSurfaceNode(curve, segmentation)
    job = logic.startPrepare(curve, executable, str(tmp_path / "work"))
    assert job.running
    job.cancel()
    assert job.wait(timeout=30) == process.CANCELLED
    assert "cancelled" in job.message and curve.GetNodeReference(bdcandidate.REF_PREPARED) is None
    with pytest.raises(bdlogic.BaffleDesignerError, match="not an executable"):
        logic.startPrepare(curve, str(tmp_path / "no-such-baffle"))


def test_segments_are_exported_in_world_lps_and_a_move_needs_a_new_prepare(scene, tmp_path):
    segmentation = p2_segmentation(scene)
    parameters = bdlogic.DesignParameters()
    before = prepare.fingerprint(segmentation, parameters)
    shift = np.array([5.0, -3.0, 2.0])  # RAS
    segmentation.SetAndObserveTransformNodeID(translation_node(scene, shift).GetID())
    assert prepare.fingerprint(segmentation, parameters) != before

    prepare.export_segments(segmentation, prepare.segment_ids(segmentation, parameters), str(tmp_path))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["LV.stl", "RV.stl", "aorta.stl"]
    for structure in ("LV", "aorta"):
        stl = vtk.vtkSTLReader()
        stl.SetFileName(str(tmp_path / f"{structure}.stl"))
        stl.Update()
        source = vtk.vtkXMLPolyDataReader()
        source.SetFileName(str(data_dir() / "p2" / "segmentations" / f"{structure}.vtp"))
        source.Update()
        exported = numpy_support.vtk_to_numpy(stl.GetOutput().GetPoints().GetData())
        on_disk = numpy_support.vtk_to_numpy(source.GetOutput().GetPoints().GetData())
        lps_shift = shift * np.array(prepare.LPS_RAS)
        np.testing.assert_allclose(exported.min(0), on_disk.min(0) + lps_shift, atol=1e-3)
        np.testing.assert_allclose(exported.max(0), on_disk.max(0) + lps_shift, atol=1e-3)
