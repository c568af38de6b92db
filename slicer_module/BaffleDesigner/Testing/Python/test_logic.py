"""BaffleDesignerLogic on a real headless MRML scene (slicer-core): p2 patient data loaded
through Slicer's storage nodes, design outputs, auto-update on drag, candidates, errors."""

import math
import time

import numpy as np
import pytest
import vtk
from vtkmodules.util import numpy_support

from conftest import bdlogic, column, curve_from_points, load_model, p2_inputs, phantom_candidate, slicer, translation_node


def points_of(polydata):
    return numpy_support.vtk_to_numpy(polydata.GetPoints().GetData()).copy()


def open_and_nonmanifold_edges(polydata):
    edges = vtk.vtkFeatureEdges()
    edges.SetInputData(polydata)
    edges.BoundaryEdgesOn()
    edges.NonManifoldEdgesOn()
    edges.FeatureEdgesOff()
    edges.ManifoldEdgesOff()
    edges.Update()
    return edges.GetOutput().GetNumberOfCells()


def test_model_storage_node_puts_lps_file_into_ras_like_slicer(scene):
    surface_path, _ = p2_inputs()
    model = load_model(scene, surface_path)
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(surface_path))
    reader.Update()
    on_disk = points_of(reader.GetOutput())
    in_node = points_of(model.GetPolyData())
    np.testing.assert_allclose(in_node, on_disk * np.array([-1.0, -1.0, 1.0]), atol=1e-4)
    assert model.GetPolyData().GetCellData().GetArray("ModelFaceID") is not None


def test_design_p2_fills_the_scene(p2_scene):
    scene, logic, model, curve = p2_scene
    result = logic.design(curve)

    # Suture points (JSON storage node, RAS world) and the surface (model storage node,
    # RAS) agree: every point lies on the designed domain's wall.
    domain_node = curve.GetNodeReference(bdlogic.REF_DOMAIN)
    distance = vtk.vtkImplicitPolyDataDistance()
    distance.SetInput(domain_node.GetPolyData())
    for p in logic.suturePointsWorld(curve):
        assert abs(distance.EvaluateFunction(*p)) < 2.0

    # Domain: closed, manifold, labelled; baffle: an open patch bounded by the seam.
    domain = domain_node.GetPolyData()
    assert domain.GetNumberOfPolys() == len(result.domain.triangles) > 1000
    assert open_and_nonmanifold_edges(domain) == 0
    labels = set(numpy_support.vtk_to_numpy(domain.GetCellData().GetArray("ModelFaceID")).tolist())
    assert labels == {2, 10, 11, 16}
    baffle_model = curve.GetNodeReference(bdlogic.REF_BAFFLE)
    assert baffle_model.GetPolyData().GetNumberOfPolys() == len(result.baffle.triangles) > 100
    assert open_and_nonmanifold_edges(baffle_model.GetPolyData()) > 0
    assert baffle_model.GetDisplayNode() is not None

    # Centerline as a locked markups curve with one control point per sample.
    centerline = curve.GetNodeReference(bdlogic.REF_CENTERLINE)
    assert centerline.IsA("vtkMRMLMarkupsCurveNode") and centerline.GetLocked()
    assert centerline.GetNumberOfControlPoints() == len(result.centerline_s_mm)
    first = [0.0, 0.0, 0.0]
    centerline.GetNthControlPointPositionWorld(0, first)
    np.testing.assert_allclose(first, result.centerline_points_mm[0], atol=1e-6)

    # Section table: every constrained section at or above the target, by the library's
    # measure and by the loop this module cuts from the domain model.
    table = curve.GetNodeReference(bdlogic.REF_TABLE)
    assert table.GetNumberOfRows() == len(result.report["sections"])
    target = result.report["target_area_mm2"]
    assert target == pytest.approx(math.pi * (9.43 / 2) ** 2, rel=2e-3)  # Boston annulus at BSA 0.37
    status = column(table, bdlogic.COL_STATUS)
    final = column(table, bdlogic.COL_FINAL)
    measured = column(table, bdlogic.COL_MEASURED)
    constrained = np.array([s == "constrained" for s in status])
    assert constrained.sum() == result.report["constrained_sections"] >= 10
    checked = np.array([s == "constrained" or s.startswith("checked only") for s in status])
    assert checked.sum() == result.report["constrained_sections"] + result.report["checked_only_sections"]
    assert np.all(final[checked] >= target)
    assert np.all(measured[checked] >= target * 0.999)
    np.testing.assert_allclose(measured[checked], final[checked], rtol=0.02)
    assert np.all(np.isnan(final[~checked]))
    assert table.GetColumnUnitLabel(bdlogic.COL_FINAL) == "mm2"

    # Sections model: one closed loop per section with its area.
    sections = curve.GetNodeReference(bdlogic.REF_SECTIONS).GetPolyData()
    assert sections.GetNumberOfLines() == int(np.isfinite(measured).sum()) >= constrained.sum()

    # Plot: a chart of three series (final, raw, target) over the section table.
    chart = curve.GetNodeReference(bdlogic.REF_CHART)
    assert chart.IsA("vtkMRMLPlotChartNode") and chart.GetNumberOfPlotSeriesNodes() == 3
    for role, y in ((bdlogic.REF_SERIES_FINAL, bdlogic.COL_FINAL), (bdlogic.REF_SERIES_TARGET, bdlogic.COL_TARGET)):
        series = curve.GetNodeReference(role)
        assert series.GetTableNodeID() == table.GetID()
        assert series.GetXColumnName() == bdlogic.COL_S and series.GetYColumnName() == y

    # Per-candidate state on the curve node.
    assert curve.GetAttribute("BaffleDesigner.Status") == "designed"
    assert float(curve.GetAttribute("BaffleDesigner.MinSectionAreaMm2")) >= target
    assert float(curve.GetAttribute("BaffleDesigner.BaffleAreaMm2")) == pytest.approx(result.report["baffle_area_mm2"])
    assert logic.candidates() == [curve]


def test_designing_again_reuses_the_output_nodes(p2_scene):
    scene, logic, model, curve = p2_scene
    logic.design(curve)
    ids = {role: curve.GetNodeReferenceID(role) for role in (bdlogic.REF_BAFFLE, bdlogic.REF_TABLE, bdlogic.REF_CHART)}
    count = scene.GetNumberOfNodes()
    logic.design(curve)
    assert scene.GetNumberOfNodes() == count
    assert {role: curve.GetNodeReferenceID(role) for role in ids} == ids


def test_dragging_a_suture_point_updates_the_baffle_debounced(p2_scene):
    scene, logic, model, curve = p2_scene
    logic.design(curve)
    baffle_node = curve.GetNodeReference(bdlogic.REF_BAFFLE)
    before = points_of(baffle_node.GetPolyData())
    area_before = float(curve.GetAttribute("BaffleDesigner.BaffleAreaMm2"))
    requested = []
    logic.onUpdateRequested = requested.append
    logic.setAutoUpdate(curve, True)
    designs = logic.design_count

    # A drag is a stream of PointModifiedEvents: move point 3 along the suture line in steps.
    a, b = [0.0] * 3, [0.0] * 3
    curve.GetNthControlPointPositionWorld(3, a)
    curve.GetNthControlPointPositionWorld(4, b)
    for t in (0.1, 0.2, 0.3, 0.4):
        p = (1 - t) * np.array(a) + t * np.array(b)
        curve.SetNthControlPointPositionWorld(3, *p)
    assert len(requested) >= 4 and requested[-1] is curve
    assert logic.pendingUpdates() == [curve.GetID()]

    # Still within the debounce interval: nothing runs yet.
    assert logic.processPendingUpdates(now=time.monotonic()) == {}
    assert logic.design_count == designs

    started = time.perf_counter()
    done = logic.processPendingUpdates(now=time.monotonic() + logic.debounce_seconds + 0.01)
    elapsed = time.perf_counter() - started
    assert done == {curve.GetID(): None}
    assert logic.design_count == designs + 1  # four events, one design
    assert logic.pendingUpdates() == []
    assert elapsed < 2.0, f"an auto-update took {elapsed:.2f} s; too slow to feel live"

    assert curve.GetNodeReference(bdlogic.REF_BAFFLE) is baffle_node
    after = points_of(baffle_node.GetPolyData())
    assert after.shape != before.shape or not np.allclose(after, before)
    assert float(curve.GetAttribute("BaffleDesigner.BaffleAreaMm2")) != pytest.approx(area_before, rel=1e-6)
    target = float(curve.GetAttribute("BaffleDesigner.TargetAreaMm2"))
    assert float(curve.GetAttribute("BaffleDesigner.MinSectionAreaMm2")) >= target

    # Auto-update off: drags no longer schedule anything.
    logic.setAutoUpdate(curve, False)
    curve.SetNthControlPointPositionWorld(3, *a)
    assert logic.pendingUpdates() == []


def test_a_point_dragged_off_the_wall_keeps_the_last_baffle_and_says_why(p2_scene):
    scene, logic, model, curve = p2_scene
    logic.design(curve)
    baffle_node = curve.GetNodeReference(bdlogic.REF_BAFFLE)
    before = points_of(baffle_node.GetPolyData())
    reported = []
    logic.onAutoUpdated = lambda node, error: reported.append((node, error))
    logic.setAutoUpdate(curve, True)
    p = [0.0] * 3
    curve.GetNthControlPointPositionWorld(5, p)
    curve.SetNthControlPointPositionWorld(5, p[0], p[1], p[2] + 25.0)
    done = logic.processPendingUpdates(force=True)
    message = done[curve.GetID()]
    assert message is not None and "mm from the surface" in message  # the library's own message
    assert reported == [(curve, message)]
    assert curve.GetAttribute("BaffleDesigner.Status") == "failed"
    assert curve.GetAttribute("BaffleDesigner.Error") == message
    np.testing.assert_array_equal(points_of(baffle_node.GetPolyData()), before)
    logic.cleanup()


def test_candidates_compare_table(p2_scene):
    scene, logic, model, curve = p2_scene
    logic.design(curve)
    second = curve_from_points(scene, logic.suturePointsWorld(curve), "BC wide")
    logic.setSurfaceNode(second, model)
    logic.setParameters(second, bdlogic.DesignParameters(target_mode="area", target_area_mm2=90.0))
    logic.design(second)
    third = curve_from_points(scene, logic.suturePointsWorld(curve), "BC not designed")
    logic.setSurfaceNode(third, model)

    table = logic.updateCompareTable("not simulated: test")
    assert table.GetNumberOfRows() == 3
    assert column(table, "Candidate") == ["BC", "BC wide", "BC not designed"]
    target, minimum, area = column(table, "Target area"), column(table, "Min section area"), column(table, "Baffle area")
    assert target[1] == pytest.approx(90.0)
    assert np.all(minimum[:2] >= target[:2])
    assert area[1] > area[0]  # a larger target needs a larger baffle
    rv_after = column(table, "RV after")
    assert rv_after[1] < rv_after[0] and np.isnan(rv_after[2])  # the larger tunnel leaves less
    assert np.isnan(target[2]) and column(table, "Status")[2] == "not designed"
    assert np.all(np.isnan(column(table, "dp")))
    # Each design carries the reduced-order estimate at the CFD step's flow (BSA x CI).
    estimate = column(table, "dp estimate")
    assert np.all(np.isfinite(estimate[:2])) and np.isnan(estimate[2])
    assert estimate[0] == pytest.approx(float(curve.GetAttribute("BaffleDesigner.DpEstimateMmhg")))
    assert np.all(column(table, "v_max estimate")[:2] > 0)
    assert column(table, "Simulation") == ["not simulated: test"] * 3
    # Each candidate owns its outputs.
    assert curve.GetNodeReferenceID(bdlogic.REF_BAFFLE) != second.GetNodeReferenceID(bdlogic.REF_BAFFLE)
    assert logic.updateCompareTable() is table  # one compare table per scene


@pytest.mark.parametrize(
    "parameters, expected_mm2",
    [
        (dict(target_mode="diameter", annulus_diameter_mm=10.0), math.pi * 25.0),
        (dict(target_mode="area", target_area_mm2=75.0), 75.0),
        # Haycock BSA of 60 cm / 6 kg, then the Boston annulus at z = +1.
        (
            dict(target_mode="height_weight", height_cm=60.0, weight_kg=6.0, z_score=1.0),
            (lambda bsa: math.pi * (5.0 * (1.55 * math.sqrt(bsa) + 1.0 * (0.06 + 0.083 * bsa))) ** 2)(
                0.024265 * 60.0**0.3964 * 6.0**0.5378
            ),
        ),
    ],
)
def test_target_modes(phantom_scene, parameters, expected_mm2):
    scene, logic, model, curve = phantom_scene
    logic.setParameters(curve, bdlogic.DesignParameters(**parameters))
    assert logic.parameters(curve) == bdlogic.DesignParameters(**parameters)  # stored on the curve
    result = logic.design(curve)
    assert result.report["target_area_mm2"] == pytest.approx(expected_mm2, rel=1e-3)
    assert min(s["final_area_mm2"] for s in result.constrained_sections) >= expected_mm2


def test_transformed_model_is_designed_in_world_coordinates(phantom_scene):
    scene, logic, model, curve = phantom_scene
    untransformed = logic.design(curve)
    shift = np.array([12.0, -5.0, 3.0])
    model.SetAndObserveTransformNodeID(translation_node(scene, shift).GetID())
    for i in range(curve.GetNumberOfControlPoints()):
        p = [0.0] * 3
        curve.GetNthControlPointPositionWorld(i, p)
        curve.SetNthControlPointPositionWorld(i, *(np.array(p) + shift))
    moved = logic.design(curve)
    np.testing.assert_allclose(moved.domain.points.mean(axis=0), untransformed.domain.points.mean(axis=0) + shift, atol=0.05)


def test_input_errors_are_clear(phantom_scene):
    scene, logic, model, curve = phantom_scene
    unlabeled = scene.AddNewNodeByClass("vtkMRMLModelNode", "no labels")
    polydata = vtk.vtkPolyData()
    polydata.DeepCopy(model.GetPolyData())
    polydata.GetCellData().RemoveArray("ModelFaceID")
    unlabeled.SetAndObservePolyData(polydata)
    logic.setSurfaceNode(curve, unlabeled)
    with pytest.raises(bdlogic.BaffleDesignerError, match="ModelFaceID"):
        logic.design(curve)

    logic.setSurfaceNode(curve, model)
    open_curve = scene.AddNewNodeByClass("vtkMRMLMarkupsCurveNode", "open")
    with pytest.raises(bdlogic.BaffleDesignerError, match="closed curve"):
        logic.design(open_curve)
    few = curve_from_points(scene, logic.suturePointsWorld(curve)[:2], "two points")
    logic.setSurfaceNode(few, model)
    with pytest.raises(bdlogic.BaffleDesignerError, match="at least 3"):
        logic.design(few)
    with pytest.raises(bdlogic.BaffleDesignerError, match="bsa_m2 must be a positive"):
        logic.setParameters(curve, bdlogic.DesignParameters(target_mode="bsa", bsa_m2=0.0))


def test_an_unreachable_target_shows_the_largest_feasible_area(scene):
    # A suture loop wrapped 100 degrees round the tunnel leaves too little baffle near the caps.
    scene, logic, model, curve = phantom_candidate(scene, suture_half_angle_deg=100.0)
    logic.setParameters(curve, bdlogic.DesignParameters(target_mode="area", target_area_mm2=300.0))
    with pytest.raises(bdlogic.BaffleDesignerError, match="admits a tunnel of at most"):
        logic.design(curve)
    assert curve.GetAttribute("BaffleDesigner.Status") == "failed"
    largest = float(curve.GetAttribute("BaffleDesigner.MaxFeasibleAreaMm2"))
    assert 100.0 < largest < 300.0
    assert f"at most {largest:.1f} mm2" in curve.GetAttribute("BaffleDesigner.Error")
    # Designing at the reported area succeeds and clears it.
    logic.setParameters(curve, bdlogic.DesignParameters(target_mode="area", target_area_mm2=largest))
    logic.design(curve)
    assert curve.GetAttribute("BaffleDesigner.MaxFeasibleAreaMm2") == ""


def test_section_loop_area_of_a_cylinder():
    # The independent re-measurement against a known shape: a closed cylinder of radius 4.
    source = vtk.vtkCylinderSource()
    source.SetRadius(4.0)
    source.SetHeight(20.0)
    source.SetResolution(400)
    source.CappingOn()
    triangles = vtk.vtkTriangleFilter()
    triangles.SetInputConnection(source.GetOutputPort())
    triangles.Update()
    loop = bdlogic.section_loop(triangles.GetOutput(), (0.0, 1.0, 0.0), (0.0, 1.0, 0.0))
    assert loop is not None
    assert bdlogic.polygon_area(loop) == pytest.approx(math.pi * 16.0, rel=1e-3)
    assert bdlogic.section_loop(triangles.GetOutput(), (0.0, 50.0, 0.0), (0.0, 1.0, 0.0)) is None


def test_rv_volumes_are_on_the_candidate(p2_scene):
    scene, logic, model, curve = p2_scene
    result = logic.design(curve)
    report = result.report
    mass = vtk.vtkMassProperties()
    mass.SetInputData(model.GetPolyData())
    mass.Update()
    # The model's own volume (VTK) is the RV volume before the baffle.
    assert float(curve.GetAttribute("BaffleDesigner.RvVolumeBeforeMl")) == pytest.approx(mass.GetVolume() / 1e3, abs=1e-3)
    after = report["rv_volume_before_ml"] - report["rv_volume_taken_ml"]
    assert float(curve.GetAttribute("BaffleDesigner.RvVolumeAfterMl")) == pytest.approx(after, abs=1e-3)
    # The library is given no pulmonary artery here: the outflow figures are empty, not 0, and the reason is shown.
    assert curve.GetAttribute("BaffleDesigner.RvOutflowMostNarrowedAfterMm2") == ""
    line = bdlogic.rv_outflow_line(lambda name: curve.GetAttribute("BaffleDesigner." + name))
    assert line.startswith("RV outflow not measured: no pulmonary artery surface given"), line


def test_a_design_carries_the_estimate_at_the_cfd_steps_peak_flow(p2_scene):
    """The flow is the one the CFD step would use (3.26 x BSA x cardiac index), and the
    line says it is an estimate, with its measured error."""
    scene, logic, model, curve = p2_scene
    parameters = logic.parameters(curve)
    parameters.cardiac_index_l_min_m2 = 4.22
    logic.setParameters(curve, parameters)
    result = logic.design(curve)
    estimate = result.report["hemodynamics_estimate"]
    import baffle

    assert estimate["peak_flow_ml_s"] == pytest.approx(baffle.peak_flow_ml_s(parameters.cfd_bsa_m2(), 4.22))
    assert curve.GetAttribute("BaffleDesigner.DpEstimateMmhg") == f"{estimate['dp_estimate_mmhg']:.2f}"
    line = bdlogic.estimate_line(lambda name: curve.GetAttribute("BaffleDesigner." + name))
    assert line.startswith(f"dp estimate {estimate['dp_estimate_mmhg']:.2f} mmHg") and "reduced-order estimate, not CFD" in line, line
    assert "mmHg below" in line  # the measured error, from the library's report


def test_the_estimate_line_says_why_there_is_none():
    attributes = dict(bdlogic.estimate_attributes({"hemodynamics_estimate": {"absent_because": "no tunnel found"}}))
    assert attributes["DpEstimateMmhg"] == "" and bdlogic.estimate_line(attributes.get) == "no dp estimate: no tunnel found"
    assert bdlogic.estimate_line(dict(bdlogic.estimate_attributes({})).get) == "no dp estimate"


def test_the_rv_outflow_line_says_where_the_baffle_narrows_it():
    report = {
        "rv_outflow_min_section_mm2": 17.04,
        "rv_outflow_most_narrowed": {"area_before_mm2": 326.77, "area_after_mm2": 228.92, "after_over_before": 0.70055, "distance_from_pulmonary_end_mm": 11.31},
        "rv_outflow_unavailable": None,
    }
    attributes = dict(bdlogic.rv_outflow_attributes(report))
    assert attributes["RvOutflowMostNarrowedAfterMm2"] == "228.9" and attributes["RvOutflowMostNarrowedAfterOverBefore"] == "0.701"
    line = bdlogic.rv_outflow_line(attributes.get)
    assert line == "RV outflow: smallest section 17.0 mm2; the baffle narrows it most 11.3 mm from the pulmonary end: 326.8 -> 228.9 mm2 (70 % left)", line


def test_flatten_and_save_template(p2_scene, tmp_path):
    scene, logic, model, curve = p2_scene
    with pytest.raises(bdlogic.BaffleDesignerError, match="design the baffle first"):
        logic.flattenTemplate(curve)
    result = logic.design(curve)
    template = logic.flattenTemplate(curve)

    # The flat model: the baffle's triangles in the plane, with the per-triangle area change.
    flat = curve.GetNodeReference(bdlogic.REF_FLAT_TEMPLATE)
    polydata = flat.GetPolyData()
    assert polydata.GetNumberOfPolys() == len(result.baffle.triangles)
    assert np.all(points_of(polydata)[:, 2] == 0.0)
    ratio = numpy_support.vtk_to_numpy(polydata.GetCellData().GetArray("area_ratio"))
    np.testing.assert_allclose(ratio, template.area_ratio)
    # The flat outline is as long as the 3D seam (the surgeon sews the seam).
    seam = result.seam_points_mm
    seam_mm = np.linalg.norm(np.roll(seam, -1, axis=0) - seam, axis=1).sum()
    assert float(curve.GetAttribute("BaffleDesigner.TemplateSeamLengthMm")) == pytest.approx(seam_mm, abs=0.01)
    assert float(curve.GetAttribute("BaffleDesigner.TemplatePerimeterErrorPct")) <= 1.0
    assert 0.0 < float(curve.GetAttribute("BaffleDesigner.TemplateAreaChangeMaxPct")) < 100.0

    # Save reuses the template of the current design; the page names the suture points as
    # the curve does.
    path = logic.saveTemplate(curve, tmp_path / "p2 template.svg")
    assert curve.GetNodeReference(bdlogic.REF_FLAT_TEMPLATE) is flat and logic._templates[curve.GetID()] is template
    svg = (tmp_path / "p2 template.svg").read_text()
    assert path == str(tmp_path / "p2 template.svg") and 'width="210mm"' in svg
    assert all(f">{curve.GetNthControlPointLabel(i)}<" in svg for i in range(curve.GetNumberOfControlPoints()))
    assert (tmp_path / "t.pdf").exists() is False and logic.saveTemplate(curve, tmp_path / "t.pdf")
    assert (tmp_path / "t.pdf").read_bytes().startswith(b"%PDF")
    # A new design makes the kept template stale: saving flattens again.
    logic.design(curve)
    logic.saveTemplate(curve, tmp_path / "again.pdf")
    assert logic._templates[curve.GetID()] is not template
    assert logic.saveTemplate(curve, tmp_path / "t.png") and (tmp_path / "t.png").read_bytes().startswith(b"\x89PNG")
    with pytest.raises(bdlogic.BaffleDesignerError, match=r"\.pdf, \.svg or \.png"):
        logic.saveTemplate(curve, tmp_path / "template.jpg")


def test_flow_sections_reach_the_librarys_design(phantom_scene):
    """The flow-section rule is a parameter of the candidate (stored on the curve) that the
    module hands to baffle.design: the library raises the target until the sections normal
    to the flow reach it, and its report says how."""
    scene, logic, model, curve = phantom_scene
    bsa_m2 = logic.parameters(curve).bsa_m2
    logic.setParameters(curve, bdlogic.DesignParameters(target_mode="bsa", bsa_m2=bsa_m2, flow_sections=True))
    assert logic.parameters(curve).flow_sections is True
    flow = logic.design(curve).report["flow_sections"]
    assert flow["goal_area_mm2"] > 0 and len(flow["rounds"]) >= 1
    logic.setParameters(curve, bdlogic.DesignParameters(target_mode="bsa", bsa_m2=bsa_m2))
    assert logic.parameters(curve).flow_sections is False
    assert "flow_sections" not in logic.design(curve).report
