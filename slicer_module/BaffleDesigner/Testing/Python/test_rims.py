"""The route from BafflePlanner's plain RV model (no ModelFaceID): the user marks the VSD and
aortic-annulus rims as closed curves, the module cuts the model there and caps it."""

import numpy as np
import pytest

from BaffleDesignerLib import logic as bdlogic
from BaffleDesignerLib import rims
from conftest import curve_from_points, data_dir, load_model, missing_data, p2_inputs
from plain_rv import cap_rim, plain_phantom


def test_the_plain_phantom_capped_at_its_rims_designs_as_the_phantom(scene):
    plain, vsd_rim, aortic_rim, points, bsa, mesh = plain_phantom()
    model = scene.AddNewNodeByClass("vtkMRMLModelNode", "RV")
    model.SetAndObservePolyData(plain)
    curve = curve_from_points(scene, points, "BC")
    vsd = curve_from_points(scene, vsd_rim, "VSD rim")
    aortic = curve_from_points(scene, aortic_rim, "aortic rim")
    logic = bdlogic.BaffleDesignerLogic(scene)
    logic.setSurfaceNode(curve, model)
    logic.setParameters(curve, bdlogic.DesignParameters(target_mode="bsa", bsa_m2=bsa))
    with pytest.raises(bdlogic.BaffleDesignerError, match="mark the VSD rim and the aortic-annulus rim"):
        logic.design(curve)
    logic.setRims(curve, vsd, aortic)
    result = logic.design(curve)
    capped = curve.GetNodeReference(bdlogic.REF_RIM_CAPPED)
    labels = capped.GetPolyData().GetCellData().GetArray("ModelFaceID")
    assert {int(labels.GetValue(i)) for i in range(labels.GetNumberOfTuples())} == {2, 11, 16}
    assert rims.boundary_loops(capped.GetPolyData()) == []
    import baffle

    reference = baffle.design(mesh.points, mesh.triangles, mesh.labels, points, bsa_m2=bsa)
    # The caps are cut in on the phantom's own flat rims and triangulated anew, and the
    # library remeshes its input: the caps' rims, planes and centroids (all the design reads
    # of a cap) are the phantom's to rounding, but their triangles are not, so the design's
    # sums run in another order (CI measured 1.5e-9 relative on the baffle). 1e-6 (0.0002
    # mm2 here) is still 5000 times below the design's own 0.5 % area margin.
    assert result.report["baffle_area_mm2"] == pytest.approx(reference.report["baffle_area_mm2"], rel=1e-6)
    assert result.report["min_constrained_final_area_mm2"] == pytest.approx(reference.report["min_constrained_final_area_mm2"], rel=1e-6)
    # Designing again reuses the capped model; moving a rim makes it again.
    logic.design(curve)
    assert curve.GetNodeReference(bdlogic.REF_RIM_CAPPED) is capped
    key = capped.GetAttribute("BaffleDesigner.MadeFrom")
    p = vsd.GetNthControlPointPositionWorld(0)
    vsd.SetNthControlPointPositionWorld(0, p[0] + 0.01, p[1], p[2])
    logic.design(curve)
    assert capped.GetAttribute("BaffleDesigner.MadeFrom") != key


def test_a_rim_not_on_the_model_is_refused_with_how_far_it_is(scene):
    """p2's RV segmentation does not reach the published caps' rims (the prepare step joins
    LV, RV and aorta there): the cut at the VSD rim's plane is far from the rim."""
    folder = data_dir() / "p2" / "segmentations"
    if not (folder / "RV.vtp").exists():
        missing_data(folder)
    surface_path, points_path = p2_inputs()
    rv = load_model(scene, folder / "RV.vtp", "RV")
    capped = load_model(scene, surface_path, "capped")
    vsd = curve_from_points(scene, cap_rim(capped.GetPolyData(), 11), "VSD rim")
    aortic = curve_from_points(scene, cap_rim(capped.GetPolyData(), 16), "aortic rim")
    from conftest import load_closed_curve

    curve = load_closed_curve(scene, points_path)
    logic = bdlogic.BaffleDesignerLogic(scene)
    logic.setSurfaceNode(curve, rv)
    logic.setRims(curve, vsd, aortic)
    with pytest.raises(bdlogic.BaffleDesignerError, match=r"the VSD rim is not on the RV model: .* up to \d+\.\d mm from the rim"):
        logic.design(curve)
    assert curve.GetAttribute("BaffleDesigner.Status") == "failed"


def test_an_open_model_is_refused():
    import vtk

    sphere = vtk.vtkSphereSource()
    sphere.Update()
    clip = vtk.vtkClipPolyData()
    plane = vtk.vtkPlane()
    clip.SetInputConnection(sphere.GetOutputPort())
    clip.SetClipFunction(plane)
    clip.Update()
    with pytest.raises(bdlogic.BaffleDesignerError, match="closed triangulated surface"):
        rims.capped_ventricle(clip.GetOutput(), [("VSD", 11, np.eye(3))])
