"""BaffleDesigner: area-constrained DORV baffle design (after Martinez et al.) in 3D Slicer,
next to SlicerHeart's BafflePlanner. The Widget is a thin Qt layer; the work is done by
BaffleDesignerLib.logic (MRML + vtk + numpy + the `baffle` package), which the pytest
suite in Testing/Python drives headless with slicer-core."""

import logging
import os
import tempfile

import qt
import slicer
import vtk
from slicer.ScriptedLoadableModule import (
    ScriptedLoadableModule,
    ScriptedLoadableModuleLogic,
    ScriptedLoadableModuleTest,
    ScriptedLoadableModuleWidget,
)
from slicer.util import VTKObservationMixin

from BaffleDesignerLib import logic as bdlogic
from BaffleDesignerLib import process as bdprocess


class BaffleDesigner(ScriptedLoadableModule):
    def __init__(self, parent):
        ScriptedLoadableModule.__init__(self, parent)
        self.parent.title = "Baffle Designer"
        self.parent.categories = ["Cardiac"]
        self.parent.dependencies = ["Markups", "Models", "Tables", "Plots"]
        self.parent.contributors = ["baffle project team"]
        self.parent.helpText = """
Designs the area-constrained intraventricular baffle for DORV repair (after Martinez et al.,
"Semi-Automated Generation and Hemodynamic Assessment of Surgical Baffle Geometry for
Biventricular Repair") from the capped right ventricle (model with ModelFaceID 2/11/16) and
BafflePlanner's closed curve of suture points. Each closed curve is one candidate: its
target, outputs (baffle, domain, centerline, sections, area table and chart) and results are
kept on the curve node, so one scene can hold several candidates to compare.
"""
        self.parent.acknowledgementText = """
Built on SlicerHeart's BafflePlanner conventions; geometry by the baffle library (Rust, C ABI).
"""


# Target modes in the order of the UI's targetModeComboBox.
TARGET_MODES = ("bsa", "height_weight", "area", "diameter")


class BaffleDesignerWidget(ScriptedLoadableModuleWidget, VTKObservationMixin):
    def __init__(self, parent=None):
        ScriptedLoadableModuleWidget.__init__(self, parent)
        VTKObservationMixin.__init__(self)
        self.logic = None
        self.curve = None
        self.run = None  # the running bdprocess.CliProcess
        self.runKind = ""
        self.runDir = ""
        self._updatingGUI = False

    def setup(self):
        ScriptedLoadableModuleWidget.setup(self)
        uiWidget = slicer.util.loadUI(self.resourcePath("UI/BaffleDesigner.ui"))
        self.layout.addWidget(uiWidget)
        self.ui = slicer.util.childWidgetVariables(uiWidget)
        uiWidget.setMRMLScene(slicer.mrmlScene)

        self.logic = BaffleDesignerLogic(slicer.mrmlScene)
        self.logic.onUpdateRequested = lambda curve: self.updateTimer.start()
        self.logic.onAutoUpdated = self.onAutoUpdated

        # Debounce: restarted by every point event, fires once the drag has paused.
        self.updateTimer = qt.QTimer()
        self.updateTimer.setSingleShot(True)
        self.updateTimer.setInterval(int(1000 * self.logic.debounce_seconds))
        self.updateTimer.connect("timeout()", self.onUpdateTimer)
        # Polls a running command line process (progress, end) without blocking the GUI.
        self.processTimer = qt.QTimer()
        self.processTimer.setInterval(200)
        self.processTimer.connect("timeout()", self.onProcessTimer)

        self.ui.curveSelector.connect("currentNodeChanged(vtkMRMLNode*)", self.onCurveSelected)
        self.ui.surfaceSelector.connect("currentNodeChanged(vtkMRMLNode*)", self.onSurfaceSelected)
        self.ui.targetModeComboBox.connect("currentIndexChanged(int)", self.onParametersChanged)
        for spinBox in self.parameterSpinBoxes():
            spinBox.connect("valueChanged(double)", self.onParametersChanged)
        self.ui.autoUpdateCheckBox.connect("toggled(bool)", self.onAutoUpdateToggled)
        self.ui.designButton.connect("clicked(bool)", self.onDesign)
        self.ui.volumeMeshButton.connect("clicked(bool)", self.onVolumeMesh)
        self.ui.cancelButton.connect("clicked(bool)", self.onCancel)
        self.ui.compareButton.connect("clicked(bool)", self.onCompare)

        self.executable = bdprocess.find_baffle_executable()
        available, reason = bdprocess.simulate_availability(self.executable)
        # This module version does not drive the CFD worker yet, whether or not the build has it.
        self.ui.simulateButton.enabled = False
        self.ui.simulateButton.toolTip = reason if not available else (
            "`baffle simulate` was found, but this BaffleDesigner version cannot drive it yet; update the module."
        )
        meshAvailable, meshReason = bdprocess.subcommand_availability(self.executable, "mesh")
        self.volumeMeshReason = meshReason
        self.ui.cancelButton.enabled = False
        self.ui.progressBar.setRange(0, 1000)

        self.addObserver(slicer.mrmlScene, slicer.mrmlScene.StartCloseEvent, self.onSceneStartClose)
        self.onCurveSelected(self.ui.curveSelector.currentNode())

    def parameterSpinBoxes(self):
        return (
            self.ui.bsaSpinBox, self.ui.heightSpinBox, self.ui.weightSpinBox, self.ui.zScoreSpinBox,
            self.ui.areaSpinBox, self.ui.diameterSpinBox, self.ui.systolicSpinBox, self.ui.diastolicSpinBox,
            self.ui.heartRateSpinBox,
        )

    def cleanup(self):
        self.removeObservers()
        self.updateTimer.stop()
        self.processTimer.stop()
        if self.run is not None:
            self.run.cancel()
        if self.logic is not None:
            self.logic.cleanup()

    def onSceneStartClose(self, caller, event):
        self.logic.cleanup()
        self.curve = None

    # ---- GUI <-> curve node ----------------------------------------------------------

    def parametersFromGUI(self):
        return bdlogic.DesignParameters(
            target_mode=TARGET_MODES[max(0, self.ui.targetModeComboBox.currentIndex)],
            bsa_m2=self.ui.bsaSpinBox.value,
            height_cm=self.ui.heightSpinBox.value,
            weight_kg=self.ui.weightSpinBox.value,
            z_score=self.ui.zScoreSpinBox.value,
            target_area_mm2=self.ui.areaSpinBox.value,
            annulus_diameter_mm=self.ui.diameterSpinBox.value,
            systolic_mmhg=self.ui.systolicSpinBox.value,
            diastolic_mmhg=self.ui.diastolicSpinBox.value,
            heart_rate_bpm=self.ui.heartRateSpinBox.value,
        )

    def onCurveSelected(self, curve):
        self.curve = curve
        self.updateGUIFromCurve()

    def updateGUIFromCurve(self):
        self._updatingGUI = True
        try:
            curve = self.curve
            enabled = curve is not None
            for widget in (self.ui.designButton, self.ui.autoUpdateCheckBox, self.ui.compareButton):
                widget.enabled = enabled
            self.ui.volumeMeshButton.enabled = enabled and not self.volumeMeshReason
            self.ui.volumeMeshButton.toolTip = self.volumeMeshReason or "Tetrahedral mesh of the domain by `baffle mesh`."
            if curve is None:
                self.setStatus("Select the suture points (BafflePlanner's closed curve).")
                return
            parameters = self.logic.parameters(curve)
            self.ui.targetModeComboBox.currentIndex = TARGET_MODES.index(parameters.target_mode)
            for spinBox, value in zip(self.parameterSpinBoxes(), (
                parameters.bsa_m2, parameters.height_cm, parameters.weight_kg, parameters.z_score,
                parameters.target_area_mm2, parameters.annulus_diameter_mm, parameters.systolic_mmhg,
                parameters.diastolic_mmhg, parameters.heart_rate_bpm,
            )):
                spinBox.value = value
            surface = self.logic.surfaceNode(curve)
            if surface is not None:
                self.ui.surfaceSelector.setCurrentNode(surface)
            self.ui.autoUpdateCheckBox.checked = self.logic.isAutoUpdating(curve)
            self.setStatus(self.curveSummary(curve))
        except bdlogic.BaffleDesignerError as error:
            self.setStatus(str(error), error=True)
        finally:
            self._updatingGUI = False

    def onSurfaceSelected(self, node):
        if self._updatingGUI or self.curve is None:
            return
        self.logic.setSurfaceNode(self.curve, node)
        self.requestAutoUpdate()

    def onParametersChanged(self, *_):
        if self._updatingGUI or self.curve is None:
            return
        try:
            self.logic.setParameters(self.curve, self.parametersFromGUI())
        except bdlogic.BaffleDesignerError as error:
            self.setStatus(str(error), error=True)
            return
        self.requestAutoUpdate()

    def requestAutoUpdate(self):
        if self.curve is not None and self.logic.isAutoUpdating(self.curve):
            self.logic.requestUpdate(self.curve)
            self.updateTimer.start()

    def onAutoUpdateToggled(self, enabled):
        if self._updatingGUI or self.curve is None:
            return
        self.logic.setSurfaceNode(self.curve, self.ui.surfaceSelector.currentNode())
        self.logic.setAutoUpdate(self.curve, enabled)
        if enabled:
            self.requestAutoUpdate()

    # ---- design ----------------------------------------------------------------------

    def curveSummary(self, curve):
        status = curve.GetAttribute("BaffleDesigner.Status")
        if status == "designed":
            a = lambda name: float(curve.GetAttribute("BaffleDesigner." + name))
            return (
                f"{curve.GetName()}: target {a('TargetAreaMm2'):.1f} mm2, baffle {a('BaffleAreaMm2'):.1f} mm2, "
                f"smallest section {a('MinSectionAreaMm2'):.1f} mm2 ({curve.GetAttribute('BaffleDesigner.DesignTimeMs')} ms)"
            )
        if status == "failed":
            return f"{curve.GetName()}: {curve.GetAttribute('BaffleDesigner.Error')}"
        return f"{curve.GetName()}: not designed yet"

    def onDesign(self):
        if self.curve is None:
            return
        try:
            self.logic.setSurfaceNode(self.curve, self.ui.surfaceSelector.currentNode())
            self.logic.setParameters(self.curve, self.parametersFromGUI())
            with slicer.util.WaitCursor():
                self.logic.design(self.curve, progress=self.onDesignProgress)
        except bdlogic.BaffleDesignerError as error:
            self.showError("Baffle design failed", str(error))
            return
        self.setStatus(self.curveSummary(self.curve))
        self.showOutputs(self.curve)

    def onDesignProgress(self, fraction, stage):
        self.ui.progressBar.value = int(1000 * fraction)
        self.ui.progressBar.format = stage
        return True

    def onUpdateTimer(self):
        self.logic.processPendingUpdates()
        if self.logic.pendingUpdates():  # a change came in during the design: go again
            self.updateTimer.start()

    def onAutoUpdated(self, curve, error):
        # No message box while the surgeon drags: the status line says why, the last
        # good baffle stays in place.
        if curve is self.curve:
            self.setStatus(self.curveSummary(curve), error=error is not None)

    def showOutputs(self, curve):
        chart = curve.GetNodeReference(bdlogic.REF_CHART)
        table = curve.GetNodeReference(bdlogic.REF_TABLE)
        if chart is not None:
            slicer.modules.plots.logic().ShowChartInLayout(chart)
        if table is not None:
            slicer.app.applicationLogic().GetSelectionNode().SetActiveTableID(table.GetID())
            slicer.app.applicationLogic().PropagateTableSelection()

    def onCompare(self):
        _, reason = bdprocess.simulate_availability(self.executable)
        table = self.logic.updateCompareTable(f"not simulated: {reason}" if reason else "not simulated")
        slicer.app.layoutManager().setLayout(slicer.vtkMRMLLayoutNode.SlicerLayoutFourUpTableView)
        slicer.app.applicationLogic().GetSelectionNode().SetActiveTableID(table.GetID())
        slicer.app.applicationLogic().PropagateTableSelection()

    # ---- separate processes (volume mesh now; the CFD worker when it exists) ----------

    def onVolumeMesh(self):
        if self.curve is None or self.run is not None:
            return
        try:
            self.runDir = tempfile.mkdtemp(prefix="BaffleDesigner-mesh-")
            command = self.logic.volumeMeshCommand(self.curve, self.executable, self.runDir)
            self.run = bdprocess.CliProcess(command).start()
        except (bdlogic.BaffleDesignerError, OSError) as error:
            self.showError("Volume mesh failed", str(error))
            self.run = None
            return
        self.runKind = "volume mesh"
        self.ui.cancelButton.enabled = True
        self.ui.volumeMeshButton.enabled = False
        self.ui.progressBar.setRange(0, 0)  # `baffle mesh` reports no fractions: busy indicator
        self.setStatus(f"{self.curve.GetName()}: {self.runKind} running ...")
        self.processTimer.start()

    def onCancel(self):
        if self.run is not None:
            self.run.cancel()
            self.setStatus(f"Cancelling the {self.runKind} ...")

    def onProcessTimer(self):
        run = self.run
        if run is None:
            self.processTimer.stop()
            return
        if run.progress_updates:
            self.ui.progressBar.setRange(0, 1000)
            self.ui.progressBar.value = int(1000 * run.progress)
            self.ui.progressBar.format = run.stage or "%p%"
        if run.running:
            return
        self.processTimer.stop()
        self.run = None
        self.ui.cancelButton.enabled = False
        self.ui.progressBar.setRange(0, 1000)
        self.ui.progressBar.value = 0
        self.updateGUIFromCurve()
        if run.state == bdprocess.CANCELLED:
            self.setStatus(f"The {self.runKind} was cancelled.")
        elif run.state == bdprocess.FAILED:
            self.showError(f"The {self.runKind} failed", run.error_message())
        elif self.runKind == "volume mesh":
            try:
                node, quality = self.logic.loadVolumeMesh(self.curve, self.runDir)
            except (bdlogic.BaffleDesignerError, OSError, ValueError) as error:
                self.showError("Loading the volume mesh failed", str(error))
                return
            self.setStatus(f"{self.curve.GetName()}: volume mesh of {node.GetMesh().GetNumberOfCells()} tetrahedra loaded.")

    # ---- messages --------------------------------------------------------------------

    def setStatus(self, text, error=False):
        self.ui.statusLabel.text = text
        self.ui.statusLabel.setStyleSheet("color: #c0392b" if error else "")
        (logging.error if error else logging.info)(text)

    def showError(self, title, message):
        self.setStatus(f"{title}: {message}", error=True)
        slicer.util.errorDisplay(message, windowTitle=title)


class BaffleDesignerLogic(ScriptedLoadableModuleLogic, bdlogic.BaffleDesignerLogic):
    """The module logic: Slicer's scripted logic base plus the Qt-free BaffleDesignerLib logic."""

    def __init__(self, scene=None):
        ScriptedLoadableModuleLogic.__init__(self)
        bdlogic.BaffleDesignerLogic.__init__(self, scene if scene is not None else slicer.mrmlScene)


class BaffleDesignerTest(ScriptedLoadableModuleTest):
    """The headless pytest suite's checks, inside the Slicer application with its own
    readers (slicer.util.loadModel / loadMarkups). Patient data from $BAFFLE_DATA_DIR."""

    def setUp(self):
        slicer.mrmlScene.Clear(0)

    def runTest(self):
        self.setUp()
        self.test_phantom_design_and_drag()
        self.setUp()
        self.test_patient_design_and_compare()

    def _check_outputs(self, curve, result):
        table = curve.GetNodeReference(bdlogic.REF_TABLE)
        self.assertEqual(table.GetNumberOfRows(), len(result.report["sections"]))
        target = result.report["target_area_mm2"]
        status = table.GetTable().GetColumnByName(bdlogic.COL_STATUS)
        final = table.GetTable().GetColumnByName(bdlogic.COL_FINAL)
        measured = table.GetTable().GetColumnByName(bdlogic.COL_MEASURED)
        constrained = 0
        for row in range(table.GetNumberOfRows()):
            if status.GetValue(row) == "constrained":
                constrained += 1
                self.assertGreaterEqual(final.GetValue(row), target)
                self.assertGreaterEqual(measured.GetValue(row), 0.999 * target)
        self.assertGreater(constrained, 5)
        edges = vtk.vtkFeatureEdges()
        edges.SetInputData(curve.GetNodeReference(bdlogic.REF_DOMAIN).GetPolyData())
        edges.BoundaryEdgesOn()
        edges.NonManifoldEdgesOn()
        edges.FeatureEdgesOff()
        edges.ManifoldEdgesOff()
        edges.Update()
        self.assertEqual(edges.GetOutput().GetNumberOfCells(), 0)
        self.assertEqual(curve.GetNodeReference(bdlogic.REF_CHART).GetNumberOfPlotSeriesNodes(), 3)

    def test_phantom_design_and_drag(self):
        import baffle
        from baffle import vtk_adapters

        self.delayDisplay("Phantom: design, then drag a suture point")
        mesh, points, bsa = baffle.phantom()
        model = slicer.modules.models.logic().AddModel(vtk_adapters.mesh_to_polydata(mesh))
        curve = slicer.mrmlScene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", "BC")
        for p in points:
            curve.AddControlPointWorld(vtk.vtkVector3d(*p))
        logic = BaffleDesignerLogic()
        logic.setSurfaceNode(curve, model)
        logic.setParameters(curve, bdlogic.DesignParameters(target_mode="bsa", bsa_m2=bsa))
        result = logic.design(curve)
        self._check_outputs(curve, result)
        area = float(curve.GetAttribute("BaffleDesigner.BaffleAreaMm2"))
        logic.setAutoUpdate(curve, True)
        a, b = curve.GetNthControlPointPositionWorld(3), curve.GetNthControlPointPositionWorld(4)
        curve.SetNthControlPointPositionWorld(3, [0.7 * a[i] + 0.3 * b[i] for i in range(3)])
        self.assertEqual(logic.pendingUpdates(), [curve.GetID()])
        self.assertEqual(logic.processPendingUpdates(force=True), {curve.GetID(): None})
        self.assertNotAlmostEqual(float(curve.GetAttribute("BaffleDesigner.BaffleAreaMm2")), area, places=3)
        logic.cleanup()
        self.delayDisplay("Phantom test passed")

    def test_patient_design_and_compare(self):
        folder = os.path.join(
            os.environ.get("BAFFLE_DATA_DIR", os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data")),
            "p2", "design_input",
        )
        if not os.path.exists(os.path.join(folder, "capped_ventricle.vtp")):
            self.delayDisplay(f"Patient data not found at {folder} (set BAFFLE_DATA_DIR): skipped")
            return
        self.delayDisplay("p2: design from the files as Slicer loads them")
        model = slicer.util.loadModel(os.path.join(folder, "capped_ventricle.vtp"))  # LPS file -> RAS node
        curve = slicer.util.loadMarkups(os.path.join(folder, "suture_points.mrk.json"))
        logic = BaffleDesignerLogic()
        logic.setSurfaceNode(curve, model)
        logic.setParameters(curve, bdlogic.DesignParameters(target_mode="bsa", bsa_m2=0.37))
        self._check_outputs(curve, logic.design(curve))
        table = logic.updateCompareTable()
        self.assertEqual(table.GetNumberOfRows(), 1)
        self.delayDisplay("Patient test passed")
