"""The module's Widget, Logic and Test classes as Slicer runs them, on the headless harness
(slicer_harness.py: PySide6 offscreen in PythonQt's manner, the .ui's custom widgets,
Slicer's scripted module base, slicer-core's MRML, logics and slicer.util).

setup; design on p2 with its table and chart shown; a drag with auto-update; simulate on
the phantom with cancel; closing the scene during and after a run; the first-run check;
cleanup and reload; and the module's own BaffleDesignerTest."""

import os
import re
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

import slicer_harness as harness
from conftest import MODULE_DIR, data_dir, p2_inputs

SCRIPT = MODULE_DIR / "BaffleDesigner.py"

app = harness.install()
import qt  # noqa: E402  (the harness's PythonQt-style module)
import slicer  # noqa: E402


@pytest.fixture(scope="module")
def module():
    return harness.load_scripted_module(SCRIPT)


@pytest.fixture
def widget(module):
    """A fresh scene and module panel; unloaded (cleanup) afterwards."""
    slicer.mrmlScene.Clear(0)
    made = harness.make_module_widget(module)
    assert harness.process_events_for(30, until=lambda: made.probe.done), "the subcommand check never ended"
    harness.process_events_for(0.3)  # the probe timer reports
    yield made
    harness.unload_module(module)
    slicer.mrmlScene.Clear(0)


def bdlogic():
    return sys.modules["BaffleDesignerLib.logic"]


def bdcandidate():
    """The scene's names and the flow modes (what logic, prepare and simulation share)."""
    return sys.modules["BaffleDesignerLib.candidate"]


def p2_candidate():
    surface, points = p2_inputs()
    model = slicer.util.loadModel(str(surface))
    curve = slicer.util.loadMarkups(str(points))
    return model, curve


def phantom_candidate():
    baffle, vtk_adapters = bdlogic().library()
    mesh, points, bsa = baffle.phantom()
    model = slicer.modules.models.logic().AddModel(vtk_adapters.mesh_to_polydata(mesh))
    curve = slicer.mrmlScene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", "phantom BC")
    for p in points:
        curve.AddControlPointWorld(*[float(x) for x in p])
    return model, curve, bsa


def design_in_widget(w, model, curve, bsa):
    w.ui.surfaceSelector.setCurrentNode(model)
    w.ui.curveSelector.setCurrentNode(curve)
    w.ui.targetModeComboBox.currentIndex = 0
    w.ui.bsaSpinBox.value = bsa
    w.ui.designButton.click()
    wait_design(w)
    assert curve.GetAttribute("BaffleDesigner.Status") == "designed", w.ui.statusLabel.text


def wait_design(w, seconds=120):
    """Let the design timer run until the design (on its worker thread) has been written."""
    assert harness.process_events_for(seconds, until=lambda: w.designJob is None), "the design never ended"


def require_cfd(w):
    if w.simulateReason or w.volumeMeshReason:
        pytest.skip(f"no CFD in this build: {w.simulateReason or w.volumeMeshReason}")


def wait_run(w, seconds, until=None):
    """Let the widget's timers run until its process has ended (or until())."""
    done = harness.process_events_for(seconds, until=until or (lambda: w.run is None))
    assert done, f"{w.runKind} still running after {seconds} s: {w.ui.statusLabel.text}"


def skip_without_gmsh(w):
    text = w.ui.statusLabel.text
    if "gmsh" in text.lower() and "failed" in text.lower():
        pytest.skip(f"gmsh is not installed: {text}")


# ---- the module class and its logic ------------------------------------------------------


def test_old_base_order_fails_on_slicers_cooperative_base(module):
    """The Logic as it was (Slicer's base first) hits the library's __init__ without a
    scene through ScriptedLoadableModuleLogic's super().__init__() (Slicer >= 5.0)."""
    from slicer.ScriptedLoadableModule import ScriptedLoadableModuleLogic

    class BaffleDesignerLogic(ScriptedLoadableModuleLogic, bdlogic().BaffleDesignerLogic):
        def __init__(self, scene=None):
            ScriptedLoadableModuleLogic.__init__(self)
            bdlogic().BaffleDesignerLogic.__init__(self, scene or slicer.mrmlScene)

    with pytest.raises(TypeError, match="scene"):
        BaffleDesignerLogic()
    logic = sys.modules["BaffleDesigner"].BaffleDesignerLogic()
    assert logic.moduleName == "BaffleDesigner" and logic.scene is slicer.mrmlScene
    parameter_node = logic.getParameterNode()
    assert parameter_node.GetAttribute("ModuleName") == "BaffleDesigner"
    assert logic.getParameterNode() is parameter_node  # singleton


def test_module_declares_every_module_it_uses(module):
    used = set()
    for path in [SCRIPT, *sorted((MODULE_DIR / "BaffleDesignerLib").glob("*.py"))]:
        used |= set(re.findall(r"slicer\.modules\.([a-z]+)\b", path.read_text()))
    declared = {name.lower() for name in module.dependencies}
    assert used - {"baffledesigner"} <= declared, f"used, not in dependencies: {used - declared}"
    assert "segmentations" in declared
    assert module.title == "Baffle Designer" and module.categories == ["Cardiac"]
    assert module.icon is not None and slicer.selfTests["BaffleDesigner"]


# ---- setup and the first-run check -------------------------------------------------------


def test_setup_connects_the_panel(widget):
    w = widget
    assert w.logic.moduleName == "BaffleDesigner"
    assert w.updateTimer.singleShot and w.updateTimer.interval == 300
    # Nothing is missing here, but gmsh on a machine without it (its own test is below).
    assert [line for line in w.ui.requirementsLabel.text.splitlines() if "gmsh" not in line] == []
    assert not w.ui.designButton.enabled  # no candidate yet
    model, curve = p2_candidate()
    assert w.curve is curve and w.ui.surfaceSelector.currentNode() is model  # the selectors picked them
    assert w.ui.designButton.enabled
    w.ui.bsaSpinBox.value = 0.41  # valueChanged(double) -> stored on the candidate
    assert w.logic.parameters(curve).bsa_m2 == pytest.approx(0.41)
    w.ui.flowModeComboBox.currentIndex = bdcandidate().FLOW_MODES.index("pulsatile")
    assert w.logic.parameters(curve).flow_mode == "pulsatile"


def test_a_plan_folder_shows_its_verdict_and_pictures(widget, tmp_path):
    from plan_folder import plan_folder

    w = widget
    w.showPlanReport(str(plan_folder(tmp_path / "rendered")))
    assert w.ui.planVerdictLabel.text.startswith("INCONCLUSIVE: ") and "Warning: poor mesh" in w.ui.planVerdictLabel.text
    assert w.ui.openReportButton.enabled
    layout = w.ui.planPicturesWidget.layout()
    labels = [layout.itemAt(k).widget() for k in range(layout.count())]
    images = [label for label in labels if not label.pixmap.isNull()]
    assert len(images) == 2 and all(image.pixmap.width() >= 240 for image in images)
    assert [label.text for label in labels if label.pixmap.isNull()] == ["caption of context_anterior.png", "caption of speed_cut_face_on.png"]
    # Another plan replaces them; one without pictures says why.
    w.showPlanReport(str(plan_folder(tmp_path / "without", rendered=False)))
    harness.process_events_for(0.1)  # the replaced labels are deleted
    assert layout.count() == 1 and "python3 could not be started" in layout.itemAt(0).widget().text


def slow_program(tmp_path, name, delay_s):
    """A program `name` that answers anything (--help, --version) after delay_s."""
    path = tmp_path / name
    path.write_text(f"#!/bin/sh\nsleep {delay_s}\nexit 0\n")
    path.chmod(path.stat().st_mode | stat.S_IEXEC)
    return str(path)


def test_setup_does_not_wait_for_the_program(module, tmp_path, monkeypatch):
    monkeypatch.setenv("BAFFLE_EXECUTABLE", slow_program(tmp_path, "baffle", 1))
    monkeypatch.setenv("BAFFLE_GMSH", slow_program(tmp_path, "gmsh", 1))
    slicer.mrmlScene.Clear(0)
    started = time.monotonic()
    w = harness.make_module_widget(module)
    try:
        assert time.monotonic() - started < 1.0
        p2_candidate()
        assert not w.ui.simulateButton.enabled and "checking" in w.ui.simulateButton.toolTip
        assert harness.process_events_for(10, until=lambda: w.probe.done and not w.probeTimer.active)
        assert w.ui.simulateButton.enabled and w.ui.volumeMeshButton.enabled
    finally:
        harness.unload_module(module)


FRESH_START_WITHOUT_BAFFLE = """
import sys
sys.modules["baffle"] = None  # this Python has no baffle package: `import baffle` raises ImportError
import slicer_harness as harness
harness.install()
import slicer
module = harness.load_scripted_module(sys.argv[1])
w = harness.make_module_widget(module)
assert harness.process_events_for(30, until=lambda: w.probe.done and not w.probeTimer.active)
slicer.util.loadMarkups(sys.argv[2])
print("VISIBLE", w.ui.requirementsLabel.visible)
print("DESIGN", w.ui.designButton.enabled, w.ui.designButton.toolTip)
print("LABEL", w.ui.requirementsLabel.text.replace("\\n", " | "))
harness.unload_module(module)
"""


def test_first_run_check_says_what_is_missing(tmp_path):
    """A Slicer whose Python lacks the baffle package, with no program: the module loads,
    its panel says what to install, and Design is off (a fresh process, as Slicer starts)."""
    _, points = p2_inputs()
    env = dict(os.environ, BAFFLE_EXECUTABLE=str(tmp_path / "no-such-baffle"), QT_QPA_PLATFORM="offscreen")
    done = subprocess.run([sys.executable, "-c", FRESH_START_WITHOUT_BAFFLE, str(SCRIPT), str(points)],
                          cwd=Path(__file__).parent, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-3000:]
    out = dict(line.split(" ", 1) for line in done.stdout.splitlines() if line.split(" ", 1)[0] in ("VISIBLE", "DESIGN", "LABEL"))
    assert out["VISIBLE"] == "True"
    assert out["DESIGN"].startswith("False") and "pip_install" in out["DESIGN"]
    label = out["LABEL"]
    assert "The baffle Python package cannot be imported" in label and "slicer.util.pip_install(" in label
    assert "Simulate (baffle simulate) is unavailable" in label and "no-such-baffle" in label


def test_first_run_check_finds_a_missing_gmsh(module, monkeypatch, tmp_path):
    """`baffle mesh` runs gmsh; without it Volume mesh and Simulate are off and say why."""
    monkeypatch.setenv("BAFFLE_GMSH", str(tmp_path / "no-such-gmsh"))
    slicer.mrmlScene.Clear(0)
    w = harness.make_module_widget(module)
    try:
        assert harness.process_events_for(30, until=lambda: w.probe.done and not w.probeTimer.active)
        assert "Volume mesh and Simulate need gmsh" in w.ui.requirementsLabel.text
        assert "no-such-gmsh" in w.ui.requirementsLabel.text
        p2_candidate()
        assert not w.ui.volumeMeshButton.enabled and "gmsh" in w.ui.volumeMeshButton.toolTip
        assert not w.ui.simulateButton.enabled and w.ui.designButton.enabled
    finally:
        harness.unload_module(module)


# ---- design, layout, progress ----------------------------------------------------------


def test_design_on_p2_shows_table_and_chart_and_repaints_progress(widget):
    w = widget
    model, curve = p2_candidate()
    seen = []
    w.ui.progressBar.connect("valueChanged(int)", seen.append)
    design_in_widget(w, model, curve, 0.37)
    # The design timer (50 ms) shows the worker's progress; p2 may design within one tick.
    if float(curve.GetAttribute("BaffleDesigner.DesignTimeMs")) > 150:
        assert len(set(seen)) >= 2
    assert w.ui.progressBar.value == 0 and w.ui.progressBar.format == ""
    assert "target" in w.ui.statusLabel.text and "baffle" in w.ui.statusLabel.text

    views = app.layoutManager().viewClasses()
    assert {"vtkMRMLPlotViewNode", "vtkMRMLTableViewNode"} <= views, views
    table = curve.GetNodeReference(bdcandidate().REF_TABLE)
    chart = curve.GetNodeReference(bdcandidate().REF_CHART)
    table_views = slicer.util.getNodesByClass("vtkMRMLTableViewNode")
    plot_views = slicer.util.getNodesByClass("vtkMRMLPlotViewNode")
    assert any(v.GetTableNodeID() == table.GetID() for v in table_views)
    assert any(v.GetPlotChartNodeID() == chart.GetID() for v in plot_views)


def test_flatten_and_save_template_buttons(widget, tmp_path, monkeypatch):
    w = widget
    model, curve = p2_candidate()
    w.ui.curveSelector.setCurrentNode(curve)
    assert not w.ui.flattenButton.enabled and not w.ui.saveTemplateButton.enabled  # nothing designed yet
    design_in_widget(w, model, curve, 0.37)
    assert "RV" in w.ui.statusLabel.text and "mL after the baffle" in w.ui.statusLabel.text
    assert w.ui.flattenButton.enabled and w.ui.saveTemplateButton.enabled
    w.ui.flattenButton.click()
    flat = curve.GetNodeReference(bdcandidate().REF_FLAT_TEMPLATE)
    assert flat is not None and flat.GetPolyData().GetNumberOfPolys() > 100
    assert "perimeter error" in w.ui.statusLabel.text, w.ui.statusLabel.text
    # Save: the file dialog answers with a path (PySide's (path, filter) as PythonQt's path).
    target = tmp_path / "p2 template.pdf"
    monkeypatch.setattr(qt.QFileDialog, "getSaveFileName", staticmethod(lambda *args: (str(target), "PDF (*.pdf)")))
    w.ui.saveTemplateButton.click()
    assert target.read_bytes().startswith(b"%PDF"), w.ui.statusLabel.text
    assert "saved" in w.ui.statusLabel.text and curve.GetAttribute("BaffleDesigner.TemplatePath") == str(target)
    # A cancelled dialog writes nothing and says nothing went wrong.
    monkeypatch.setattr(qt.QFileDialog, "getSaveFileName", staticmethod(lambda *args: ("", "")))
    w.ui.saveTemplateButton.click()
    assert "saved" in w.ui.statusLabel.text


def test_old_show_outputs_leaves_the_table_out_of_the_layout(widget):
    """What the module did before: ShowChartInLayout from the default layout switches to
    a plot layout without a table view (slicer-core's real plots logic)."""
    app.layoutManager().setLayout(slicer.vtkMRMLLayoutNode.SlicerLayoutFourUpView)
    chart = slicer.mrmlScene.AddNewNodeByClass("vtkMRMLPlotChartNode")
    slicer.modules.plots.logic().ShowChartInLayout(chart)
    assert "vtkMRMLTableViewNode" not in app.layoutManager().viewClasses()


# ---- auto-update ---------------------------------------------------------------------------


def drag(curve, index, positions, pause_s):
    """A mouse drag as Slicer's markups widget reports it: start, moves (with pauses
    longer than the debounce), end."""
    curve.InvokeEvent(curve.PointStartInteractionEvent)
    for position in positions:
        curve.SetNthControlPointPositionWorld(index, *position)
        harness.process_events_for(pause_s)
    curve.InvokeEvent(curve.PointEndInteractionEvent)


def test_drag_redesigns_once_after_the_drag_ends(widget):
    w = widget
    model, curve = p2_candidate()
    design_in_widget(w, model, curve, 0.37)
    area = float(curve.GetAttribute("BaffleDesigner.BaffleAreaMm2"))
    w.ui.autoUpdateCheckBox.checked = True
    assert w.logic.isAutoUpdating(curve)
    count = w.logic.design_count
    a = curve.GetNthControlPointPositionWorld(3)
    b = curve.GetNthControlPointPositionWorld(4)
    path = [[a[i] + t * (b[i] - a[i]) for i in range(3)] for t in (0.1, 0.2, 0.3)]
    drag(curve, 3, path, pause_s=0.5)  # pauses past the 300 ms debounce: no design mid-drag
    assert w.logic.design_count == count
    assert harness.process_events_for(5, until=lambda: w.logic.design_count == count + 1)
    harness.process_events_for(0.5)
    assert w.logic.design_count == count + 1
    assert float(curve.GetAttribute("BaffleDesigner.BaffleAreaMm2")) != pytest.approx(area, abs=1e-3)
    # The redesign's dp estimate is in the status line, marked as an estimate.
    dp = curve.GetAttribute("BaffleDesigner.DpEstimateMmhg")
    assert dp and f"dp estimate {dp} mmHg" in w.ui.statusLabel.text, w.ui.statusLabel.text
    assert "reduced-order estimate, not CFD" in w.ui.statusLabel.text
    # A move from a script (no interaction events) redesigns after the debounce.
    curve.SetNthControlPointPositionWorld(3, *a)
    assert harness.process_events_for(5, until=lambda: w.logic.design_count == count + 2)


def test_the_debounce_timer_designs_when_it_fires(widget):
    """Qt's coarse timers may fire up to 5 % early; the timeout must still design, not
    wait another interval."""
    w = widget
    model, curve = p2_candidate()
    design_in_widget(w, model, curve, 0.37)
    w.ui.autoUpdateCheckBox.checked = True
    count = w.logic.design_count
    a, b = curve.GetNthControlPointPositionWorld(3), curve.GetNthControlPointPositionWorld(4)
    curve.SetNthControlPointPositionWorld(3, *[0.8 * a[i] + 0.2 * b[i] for i in range(3)])
    w.updateTimer.stop()
    w.onUpdateTimer()  # fires at once, well before debounce_seconds of quiet
    assert w.designJob is not None and not w.logic.pendingUpdates()
    wait_design(w)
    assert w.logic.design_count == count + 1


# ---- separate processes: simulate, cancel, scene close ------------------------------------


def test_simulate_on_the_phantom_then_cancel_a_pulsatile_run(widget):
    w = widget
    require_cfd(w)
    model, curve, bsa = phantom_candidate()
    design_in_widget(w, model, curve, bsa)
    w.ui.flowModeComboBox.currentIndex = bdcandidate().FLOW_MODES.index("steady")
    w.ui.meshEdgeLengthSpinBox.value = 1.25
    w.ui.simulateButton.click()
    assert w.run is not None and w.ui.cancelButton.enabled and not w.ui.simulateButton.enabled
    wait_run(w, 180)
    skip_without_gmsh(w)
    assert "dp " in w.ui.statusLabel.text and "mmHg" in w.ui.statusLabel.text, w.ui.statusLabel.text
    summary = curve.GetNodeReference(bdcandidate().REF_SIM_SUMMARY)
    assert summary is not None and summary.GetNumberOfRows() > 0
    assert any(v.GetTableNodeID() == summary.GetID() for v in slicer.util.getNodesByClass("vtkMRMLTableViewNode"))
    dp = curve.GetAttribute("BaffleDesigner.SimulationDpMmhg")
    work = Path(curve.GetAttribute("BaffleDesigner.SimulationDir")).parent
    assert not (work / "volume.vtu").exists() and (work / "results" / "summary.json").exists()  # cleaned, results kept

    w.ui.flowModeComboBox.currentIndex = bdcandidate().FLOW_MODES.index("pulsatile")  # long enough to cancel
    w.ui.simulateButton.click()
    wait_run(w, 120, until=lambda: w.run is not None and w.run.stage == "simulation" and (w.run.progress or 0) > 0)
    w.ui.cancelButton.click()
    wait_run(w, 90)
    assert "cancelled" in w.ui.statusLabel.text, w.ui.statusLabel.text
    assert not os.path.exists(w.runDir)  # a cancelled run's work folder is removed
    assert curve.GetAttribute("BaffleDesigner.SimulationDpMmhg") == dp  # the steady results stay
    assert not w.processTimer.active and w.ui.simulateButton.enabled


def plan_in_widget(w, systolic=107.0, diastolic=78.0):
    """The phantom candidate in the panel with quick plan settings; Run whole plan clicked."""
    model, curve, bsa = phantom_candidate()
    w.ui.surfaceSelector.setCurrentNode(model)
    w.ui.curveSelector.setCurrentNode(curve)
    w.ui.targetModeComboBox.currentIndex = 0
    w.ui.bsaSpinBox.value = bsa
    w.ui.systolicSpinBox.value, w.ui.diastolicSpinBox.value = systolic, diastolic
    w.ui.flowModeComboBox.currentIndex = bdcandidate().FLOW_MODES.index("quick")
    w.ui.meshEdgeLengthSpinBox.value = 1.5
    w.ui.planSingleMeshCheckBox.checked = True
    assert w.ui.runPlanButton.enabled
    w.ui.runPlanButton.click()
    return curve


def test_run_whole_plan_shows_the_librarys_verdict_and_loads_the_plan(widget):
    """The button runs the candidate's plan through the library off the GUI thread (the
    panel polls it: progress by stage, Cancel on), the status line shows the library's
    verdict marked as the library's, and the plan is loaded as Load plan folder loads it."""
    import json

    w = widget
    require_cfd(w)
    curve = plan_in_widget(w)
    assert w.run is not None and w.runKind == "whole plan", w.ui.statusLabel.text
    assert w.ui.cancelButton.enabled and not w.ui.runPlanButton.enabled and not w.ui.simulateButton.enabled
    shown = set()
    wait_run(w, 900, until=lambda: shown.add(w.ui.progressBar.format) or w.run is None)
    skip_without_gmsh(w)
    status = w.ui.statusLabel.text
    folder = Path(w.logic.parameterNode().GetAttribute("BaffleDesigner.PlanFolder"))
    verdict = json.loads((folder / "report.json").read_text())["verdict"]
    assert f"{curve.GetName()}: the library's verdict: {verdict['text']}" in status, status
    assert f"dp {verdict['dp_peak_mmhg']:.2f} mmHg against its threshold {verdict['threshold_mmhg']:g} mmHg" in status
    assert w.logic.parameterNode().GetAttribute("BaffleDesigner.PlanVerdict") == verdict["verdict"]
    assert {"design %p%", "mesh (gmsh) %p%", "time steps %p%", "report %p%"} <= shown, shown  # the stages in the progress bar
    # Loaded as Load plan folder loads it: its verdict line, report button and geometry.
    assert w.ui.planVerdictLabel.text.startswith(verdict["text"]) and w.ui.openReportButton.enabled
    assert f"plan {folder.name} domain" in model_names() and "surfaces loaded" in status
    assert folder.is_dir() and w.ui.runPlanButton.enabled and not w.processTimer.active


def test_run_whole_plan_shows_the_librarys_error(widget, tmp_path):
    """DBP above SBP: the module does not check it, the library does; its message, verbatim."""
    import baffle

    w = widget
    plan_in_widget(w, systolic=78.0, diastolic=107.0)
    wait_run(w, 60)
    with pytest.raises(baffle.BaffleError) as library:
        baffle.plan(tmp_path / "plan", phantom=True, sbp_mmhg=78.0, dbp_mmhg=107.0)
    status = w.ui.statusLabel.text
    assert "DBP 107 mmHg exceeds SBP 78 mmHg" in str(library.value)
    assert status == f"Run whole plan: the plan failed: {library.value}", status
    assert w.logic.parameterNode().GetAttribute("BaffleDesigner.PlanStatus") == "failed"


def test_run_whole_plan_designs_for_the_panels_explicit_area(widget):
    """An explicit area in the panel is the plan's target (its design report holds it);
    cancelled once the design is written, so no mesh or CFD runs."""
    import json

    w = widget
    require_cfd(w)
    model, curve, bsa = phantom_candidate()
    w.ui.surfaceSelector.setCurrentNode(model)
    w.ui.curveSelector.setCurrentNode(curve)
    w.ui.targetModeComboBox.currentIndex = bdcandidate().TARGET_MODES.index("area")
    w.ui.areaSpinBox.value = 65.0
    w.ui.bsaSpinBox.value = bsa  # the flow's BSA
    w.ui.systolicSpinBox.value, w.ui.diastolicSpinBox.value = 107.0, 78.0
    w.ui.flowModeComboBox.currentIndex = bdcandidate().FLOW_MODES.index("quick")
    w.ui.planSingleMeshCheckBox.checked = True
    w.ui.runPlanButton.click()
    assert w.run is not None and w.runKind == "whole plan", w.ui.statusLabel.text
    folder = Path(w.run.out_dir)
    wait_run(w, 300, until=lambda: (folder / "design" / "report.json").exists())
    if w.run is not None:
        w.ui.cancelButton.click()
        wait_run(w, 300)
    assert json.loads((folder / "design" / "report.json").read_text())["target_area_mm2"] == 65.0


def test_cancel_a_whole_plan_in_the_panel(widget):
    w = widget
    require_cfd(w)
    plan_in_widget(w)
    folder = Path(w.run.out_dir)
    wait_run(w, 300, until=lambda: (folder / "design" / "report.json").exists())  # the design stage has finished
    assert w.run is not None, w.ui.statusLabel.text
    w.ui.cancelButton.click()
    wait_run(w, 300)
    status = w.ui.statusLabel.text
    assert "plan cancelled at stage" in status and "failed" not in status, status
    assert (folder / "design" / "domain.vtp").is_file() and not (folder / "report.json").exists()


def model_names():
    return {n.GetName() for n in slicer.util.getNodesByClass("vtkMRMLModelNode")}


def start_volume_mesh(w):
    """Design the phantom in the widget and start its volume mesh; the running process."""
    require_cfd(w)
    model, curve, bsa = phantom_candidate()
    design_in_widget(w, model, curve, bsa)
    w.ui.volumeMeshButton.click()
    return w.run


def test_closing_the_scene_during_a_run_stops_it(widget):
    w = widget
    process = start_volume_mesh(w)
    slicer.mrmlScene.Clear(0)
    assert w.run is None and not w.processTimer.active
    assert process.wait(timeout=10) == "cancelled"
    harness.process_events_for(0.5)
    assert not any("volume mesh" in name for name in model_names())


def test_closing_the_scene_after_a_run_ended_loads_nothing(widget):
    """The process has exited but the poll timer has not seen it yet: cancel() has
    nothing to stop, and the results must not land in the next scene."""
    w = widget
    process = start_volume_mesh(w)
    state = process.wait(timeout=120)  # no events processed: the timer does not poll
    if state == "failed" and "gmsh" in process.error_message().lower():
        pytest.skip(f"gmsh is not installed: {process.error_message()}")
    assert state == "completed", process.error_message()
    slicer.mrmlScene.Clear(0)
    harness.process_events_for(1.0)
    assert w.run is None and not w.processTimer.active
    assert not any("volume mesh" in name for name in model_names()), model_names()
    assert slicer.mrmlScene.GetNumberOfNodesByClass("vtkMRMLMarkupsClosedCurveNode") == 0


# ---- cleanup and reload ------------------------------------------------------------------


def test_cleanup_on_unload_and_reload_of_the_library(module):
    slicer.mrmlScene.Clear(0)
    w = harness.make_module_widget(module)
    harness.process_events_for(10, until=lambda: w.probe.done)
    model, curve = p2_candidate()
    w.ui.autoUpdateCheckBox.checked = True
    old_logic_class = sys.modules["BaffleDesignerLib.logic"].BaffleDesignerLogic
    w.onReload()  # the panel's Reload button
    new = slicer.modules.BaffleDesignerWidget
    assert new is not w and not w.updateTimer.active and not w.logic.isAutoUpdating(curve)  # old one cleaned up
    new_logic_class = sys.modules["BaffleDesignerLib.logic"].BaffleDesignerLogic
    assert new_logic_class is not old_logic_class  # BaffleDesignerLib re-read, not only the script
    assert isinstance(new.logic, new_logic_class)
    assert sys.modules["BaffleDesigner"].bdlogic is sys.modules["BaffleDesignerLib.logic"]
    assert new.curve is curve  # the new panel picks up the scene
    harness.unload_module(module)
    assert not new.updateTimer.active and not new.processTimer.active and not new.probeTimer.active
    slicer.mrmlScene.Clear(0)


# ---- the module's own in-application test --------------------------------------------------


def test_the_modules_own_self_test(module):
    """BaffleDesignerTest.runTest as Slicer's Reload and Test runs it (p2 design, p2
    segmentation -> prepare, phantom simulate and cancel, the phantom's whole plan)."""
    slicer.mrmlScene.Clear(0)
    module.instance.runTest(msec=0)
    # Its last part, the whole plan, ran (not skipped) where gmsh is found.
    environment = sys.modules["BaffleDesignerLib.environment"]
    if environment.gmsh_availability(sys.modules["BaffleDesigner"].childEnvironment())[0]:
        parameter_node = slicer.mrmlScene.GetSingletonNode("BaffleDesigner", "vtkMRMLScriptedModuleNode")
        assert parameter_node.GetAttribute("BaffleDesigner.PlanStatus") == "completed"
    slicer.mrmlScene.Clear(0)


def test_self_test_finds_the_data_from_a_build_tree_only_by_BAFFLE_DATA_DIR(module, tmp_path, monkeypatch):
    """A build tree's copy of the module (lib/Slicer-5.8/qt-scripted-modules) has no
    shared/data beside it: BAFFLE_DATA_DIR finds it, and a wrong one is an error."""
    environment = sys.modules["BaffleDesignerLib.environment"]
    data = data_dir()
    if not (data / "p2").is_dir():
        pytest.skip(f"patient data not found at {data} (set BAFFLE_DATA_DIR)")
    built = tmp_path / "lib" / "Slicer-5.8" / "qt-scripted-modules" / "BaffleDesigner.py"
    built.parent.mkdir(parents=True)
    built.write_text(SCRIPT.read_text())
    monkeypatch.delenv("BAFFLE_DATA_DIR", raising=False)
    found, tried = environment.patient_data_dir(str(built))
    assert found is None and tmp_path / "lib" / "shared" / "data" in tried
    monkeypatch.setenv("BAFFLE_DATA_DIR", str(data))
    assert environment.patient_data_dir(str(built))[0] == data
    monkeypatch.setenv("BAFFLE_DATA_DIR", str(tmp_path))
    test = sys.modules["BaffleDesigner"].BaffleDesignerTest()
    with pytest.raises(AssertionError, match="BAFFLE_DATA_DIR"):
        test._patientFolder("design_input")


# ---- the view keeps drawing; placing points; BafflePlanner's scene ------------------------


def test_the_view_keeps_drawing_during_a_design(widget):
    """A 20 ms timer stands for the views' rendering: during a p2 design (its library part
    on the worker thread) the event loop keeps serving it; the longest gap is the writing
    of the outputs on the GUI thread at the end."""
    w = widget
    model, curve = p2_candidate()
    w.ui.surfaceSelector.setCurrentNode(model)
    w.ui.curveSelector.setCurrentNode(curve)
    ticks = []
    render = qt.QTimer()
    render.setInterval(20)
    render.connect("timeout()", lambda: ticks.append(time.perf_counter()))
    render.start()
    harness.process_events_for(0.2)
    started = time.perf_counter()
    w.ui.designButton.click()
    clicked = time.perf_counter() - started
    wait_design(w)
    harness.process_events_for(0.1)
    render.stop()
    during = [t for t in ticks if t >= started]
    gaps_ms = [1000 * (b - a) for a, b in zip(during, during[1:])]
    design_ms = float(curve.GetAttribute("BaffleDesigner.DesignTimeMs"))
    print(f"design {design_ms:.0f} ms; GUI thread {w.lastDesignGuiMs:.0f} ms; click returned after {1000 * clicked:.0f} ms; "
          f"{len(gaps_ms)} ticks, longest gap {max(gaps_ms):.0f} ms")
    assert curve.GetAttribute("BaffleDesigner.Status") == "designed"
    assert len(during) >= 2
    # The GUI thread's share (inputs, then the outputs and the layout) is what can stall
    # a view; 250 ms leaves room for a loaded machine and is far below a design that
    # blocks (0.7-2.6 s of CPU on the patients in the issue).
    assert w.lastDesignGuiMs < 250 and max(gaps_ms) < 250, (w.lastDesignGuiMs, gaps_ms)


def test_cancel_stops_a_running_design(widget):
    w = widget
    model, curve = p2_candidate()
    design_in_widget(w, model, curve, 0.37)
    area = curve.GetAttribute("BaffleDesigner.BaffleAreaMm2")
    w.ui.bsaSpinBox.value = 0.45
    w.ui.designButton.click()
    assert w.designJob is not None and w.ui.cancelButton.enabled and not w.ui.designButton.enabled
    w.ui.cancelButton.click()
    wait_design(w)
    assert "cancelled" in w.ui.statusLabel.text, w.ui.statusLabel.text
    assert curve.GetAttribute("BaffleDesigner.BaffleAreaMm2") == area and w.ui.designButton.enabled


def test_placing_points_causes_no_design(widget):
    """Place mode: Slicer moves a preview point on every mouse move, no drag events."""
    w = widget
    model, curve = p2_candidate()
    design_in_widget(w, model, curve, 0.37)
    w.ui.autoUpdateCheckBox.checked = True
    harness.process_events_for(1.0, until=lambda: w.designJob is None and not w.logic.pendingUpdates())
    wait_design(w)
    count = w.logic.design_count
    a = curve.GetNthControlPointPositionWorld(0)
    index = curve.AddControlPointWorld(vtk_vector(a[0] + 3, a[1], a[2]))
    curve.SetNthControlPointPositionWorld(index, a[0] + 3, a[1], a[2], curve.PositionPreview)
    harness.process_events_for(1.0)
    wait_design(w)
    count = w.logic.design_count  # whatever adding the preview point did
    for step in range(10):  # mouse moves with pauses past the debounce
        curve.SetNthControlPointPositionWorld(index, a[0] + 3 + step, a[1], a[2], curve.PositionPreview)
        harness.process_events_for(0.4)
    assert w.designJob is None and w.logic.design_count == count and not w.logic.pendingUpdates()


def vtk_vector(x, y, z):
    import vtk

    return vtk.vtkVector3d(x, y, z)


def test_baffle_planners_curve_is_the_default_and_one_design_is_one_rebuild(module):
    """A scene as a SlicerHeart user has it: BafflePlanner's 'BC' curve (its parameter
    node's InputCurve, auto-updating its 'Baffle' model) and another closed curve first
    in the scene; the module opens on BafflePlanner's curve, and one design makes
    BafflePlanner answer one ModifiedEvent."""
    from baffle_planner_standin import BafflePlannerLogic

    slicer.mrmlScene.Clear(0)
    model, _ = p2_candidate()
    slicer.mrmlScene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", "an older curve")
    _, points = p2_inputs()
    curve = slicer.util.loadMarkups(str(points))
    curve.SetName("BC")
    planner = BafflePlannerLogic()
    planner.setInputCurveNode(curve)
    planner.setOutputBaffleModelNode(slicer.mrmlScene.AddNewNodeByClass("vtkMRMLModelNode", "Baffle"))
    w = harness.make_module_widget(module)
    try:
        harness.process_events_for(10, until=lambda: w.probe.done)
        assert w.curve is curve and w.ui.curveSelector.currentNode() is curve
        w.ui.surfaceSelector.setCurrentNode(model)
        planner.rebuilds = planner.modified_reactions = 0
        w.ui.designButton.click()
        wait_design(w)
        assert curve.GetAttribute("BaffleDesigner.Status") == "designed", w.ui.statusLabel.text
        assert planner.modified_reactions == 1, planner.modified_reactions
        assert w.logic.parameterNode().GetNodeReference("InputCurve") is curve
    finally:
        harness.unload_module(module)
        slicer.mrmlScene.Clear(0)


def test_a_reopened_scene_auto_updates_again(widget):
    w = widget
    model, curve = p2_candidate()
    design_in_widget(w, model, curve, 0.37)
    w.ui.autoUpdateCheckBox.checked = True
    wait_design(w)
    w.logic.cleanup()  # as after reading the scene back: the attribute is saved, observers are not
    slicer.mrmlScene.InvokeEvent(slicer.mrmlScene.EndImportEvent)
    assert w.logic.isAutoUpdating(curve)


SELF_TEST_WITHOUT_BAFFLE = """
import sys, unittest
sys.modules["baffle"] = None  # a developer build whose Python has no baffle package
import slicer_harness as harness
harness.install()
import slicer
harness.load_scripted_module(sys.argv[1])
result = unittest.TextTestRunner(verbosity=2).run(unittest.TestSuite([sys.modules["BaffleDesigner"].BaffleDesignerTest("runTest")]))
print("SKIPPED", len(result.skipped), "FAILED", len(result.failures) + len(result.errors))
for _, reason in result.skipped:
    print("REASON", reason)
"""


def test_the_self_test_is_a_clear_skip_without_the_package():
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
    done = subprocess.run([sys.executable, "-c", SELF_TEST_WITHOUT_BAFFLE, str(SCRIPT)], cwd=Path(__file__).parent,
                          env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "SKIPPED 1 FAILED 0" in done.stdout, done.stdout + done.stderr[-3000:]
    assert "baffle package" in done.stdout


def test_the_settings_panel_sets_the_program_and_gmsh_and_install_asks_first(module, tmp_path, monkeypatch):
    """Paths from the panel, not only from environment variables read once (a Finder-started
    Slicer on macOS has no Homebrew PATH); Install gmsh asks before running pip."""
    slicer.mrmlScene.Clear(0)
    w = harness.make_module_widget(module)
    settings = app.userSettings()
    try:
        assert harness.process_events_for(30, until=lambda: w.probe.done and not w.probeTimer.active)
        w.ui.programPathLineEdit.text = str(tmp_path / "no-such-baffle")
        w.ui.gmshPathLineEdit.text = str(tmp_path / "no-such-gmsh")
        w.ui.applySettingsButton.click()
        assert settings.value("BaffleDesigner/GmshPath") == str(tmp_path / "no-such-gmsh")
        assert w.executable == str(tmp_path / "no-such-baffle") and w.logic.child_env["BAFFLE_GMSH"].endswith("no-such-gmsh")
        assert harness.process_events_for(30, until=lambda: w.probe.done and not w.probeTimer.active)
        assert "no-such-baffle" in w.ui.requirementsLabel.text and "no-such-gmsh" in w.ui.requirementsLabel.text
        asked, installed = [], []
        monkeypatch.setattr(slicer.util, "confirmOkCancelDisplay", lambda text, **kw: asked.append(text) or False)
        monkeypatch.setattr(slicer.util, "pip_install", lambda requirement, **kw: installed.append(requirement))
        w.ui.installGmshButton.click()
        assert len(asked) == 1 and "gmsh" in asked[0] and installed == []  # declined: nothing installed
        monkeypatch.setattr(slicer.util, "confirmOkCancelDisplay", lambda text, **kw: True)
        w.ui.installGmshButton.click()
        assert installed == ["gmsh"]
        w.ui.programPathLineEdit.text = w.ui.gmshPathLineEdit.text = ""
        w.ui.applySettingsButton.click()
        assert w.executable and "no-such" not in w.executable
        assert w.logic.child_env.get("BAFFLE_GMSH") == os.environ.get("BAFFLE_GMSH")
    finally:
        settings.remove("BaffleDesigner/ProgramPath")
        settings.remove("BaffleDesigner/GmshPath")
        harness.process_events_for(30, until=lambda: w.probe.done)
        harness.unload_module(module)


def test_an_output_model_is_never_taken_for_the_ventricle(widget):
    w = widget
    model, curve = p2_candidate()
    design_in_widget(w, model, curve, 0.37)
    baffle = curve.GetNodeReference(bdcandidate().REF_BAFFLE)
    w.ui.surfaceSelector.setCurrentNode(baffle)
    assert w.logic.surfaceNode(curve) is model and "not a ventricle" in w.ui.statusLabel.text
    assert w.logic.inputVentricle() is model


def test_baffle_planners_bc_curve_and_plain_rv_model_design_through_the_module(module):
    """BafflePlanner's 'BC' curve (its InputCurve) and a plain RV model without ModelFaceID:
    the user marks the two rims as closed curves and picks them; Design caps the model there."""
    from baffle_planner_standin import BafflePlannerLogic
    from plain_rv import plain_phantom

    slicer.mrmlScene.Clear(0)
    plain, vsd_rim, aortic_rim, points, bsa, _ = plain_phantom()
    model = slicer.modules.models.logic().AddModel(plain)
    model.SetName("RV")
    curve = slicer.mrmlScene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", "BC")
    for p in points:
        curve.AddControlPointWorld(*[float(x) for x in p])
    planner = BafflePlannerLogic()
    planner.setInputCurveNode(curve)
    rims_curves = []
    for name, rim in (("VSD rim", vsd_rim), ("aortic rim", aortic_rim)):
        rim_curve = slicer.mrmlScene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", name)
        for p in rim:
            rim_curve.AddControlPointWorld(*[float(x) for x in p])
        rims_curves.append(rim_curve)
    w = harness.make_module_widget(module)
    try:
        harness.process_events_for(10, until=lambda: w.probe.done)
        assert w.curve is curve
        w.ui.surfaceSelector.setCurrentNode(model)
        assert w.ui.vsdRimSelector.visible and w.ui.aorticRimSelector.visible
        w.ui.bsaSpinBox.value = bsa
        w.ui.designButton.click()
        wait_design(w)
        assert curve.GetAttribute("BaffleDesigner.Status") == "failed" and "mark the VSD rim" in w.ui.statusLabel.text
        w.ui.vsdRimSelector.setCurrentNode(rims_curves[0])
        w.ui.aorticRimSelector.setCurrentNode(rims_curves[1])
        w.ui.designButton.click()
        wait_design(w)
        assert curve.GetAttribute("BaffleDesigner.Status") == "designed", w.ui.statusLabel.text
        assert curve.GetNodeReference(bdcandidate().REF_RIM_CAPPED) is not None
        assert w.logic.surfaceNode(curve) is model and not w.logic.candidates()[1:]  # the rims are no candidates
    finally:
        harness.unload_module(module)
        slicer.mrmlScene.Clear(0)
