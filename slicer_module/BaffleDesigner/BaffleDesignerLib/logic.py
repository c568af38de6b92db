"""BaffleDesigner logic: MRML nodes in, the area-constrained baffle and its outputs back
into the scene. Depends only on `slicer` MRML classes, `vtk`, numpy and the project's
`baffle` package, so it runs inside the Slicer application and headless (slicer-core).

Frames: everything here is in Slicer's world frame (RAS, mm). The ventricle model node's
polydata is taken to world through its parent transforms, the suture points are the curve's
world control point positions, and the outputs are written in world coordinates. The
library is frame-agnostic as long as surface and points agree. The one exception is a
segmentation ventricle: its segments go to `baffle prepare` as files in LPS (as Slicer
writes model files, and as the prepare step's label-map path works), and the capped
ventricle it writes is turned back into RAS (BaffleDesignerLib.prepare).

Per-candidate state lives on the suture curve node, as BafflePlanner does: the target and
CFD parameters and the latest results are node attributes ("BaffleDesigner.*"), the input
and output nodes are node references ("BaffleDesigner*"). One scene can therefore hold
several candidate baffles, one per closed curve.
"""

import math
import time
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np
import slicer
import vtk
from vtkmodules.util import numpy_support

from BaffleDesignerLib import environment, prepare, process, rims, simulation
from BaffleDesignerLib import plan as planrun
from BaffleDesignerLib.candidate import (  # the candidate's scene names, parameters and errors (logic.X still works)
    ATTRIBUTE_PREFIX, BaffleDesignerError, CANDIDATE_ATTRIBUTE, DesignCancelled, DesignParameters,
    FOLDER_ATTRIBUTE, FOLDER_SUFFIX, OUTPUT_ROLES, REF_AORTIC_RIM, REF_BAFFLE, REF_CENTERLINE, REF_CHART,
    REF_DOMAIN, REF_FLAT_TEMPLATE, REF_RIM_CAPPED, REF_SECTIONS, REF_SERIES_FINAL, REF_SERIES_RAW,
    REF_SERIES_TARGET, REF_SURFACE, REF_TABLE, REF_VOLUME_MESH, REF_VOLUME_MESH_QUALITY, REF_VSD_RIM,
    ROLE_ATTRIBUTE, batched_modify, check_curve, library, read_written_file, vtk_double_array,
)

MODULE_NAME = "BaffleDesigner"
BAFFLE_PLANNER = "BafflePlanner"  # SlicerHeart's module: its parameter node names the curve
PARAM_INPUT_CURVE = "InputCurve"  # the parameter node reference, as BafflePlanner names it
PARAM_VENTRICLE = "Ventricle"
BAFFLE_PLANNER_MODEL_REF = "BaffleModel"  # BafflePlanner's baffle, referenced by its curve

# What a `baffle plan --out DIR` run leaves that the scene can show: (file under DIR, name).
PLAN_GEOMETRY = (
    ("prepare/capped_ventricle.vtp", "capped ventricle"),
    ("design/domain.vtp", "domain"),
    ("design/baffle.vtp", "baffle"),
    ("extend/extended.vtp", "extended domain"),
    ("centerline/centerline.vtp", "flow centerline"),
)


# Section table columns (name, unit, description).
COL_S = "s"
COL_TARGET = "Target area"
COL_RAW = "Raw area"
COL_FINAL = "Final area"
COL_MEASURED = "Measured area"
COL_ALPHA = "Amplitude"
COL_STATUS = "Status"
SECTION_COLUMNS = (
    (COL_S, "mm", "arc length along the centerline"),
    (COL_TARGET, "mm2", "target cross-section area"),
    (COL_RAW, "mm2", "section area of the initial patch (library)"),
    (COL_FINAL, "mm2", "section area of the final baffle (library)"),
    (COL_MEASURED, "mm2", "area of the section loop cut from the domain model here (VTK)"),
    (COL_ALPHA, "mm", "regularized parabolic arc amplitude"),
)


def singleton_parameter_node(scene, module_name: str):
    """A module's parameter node as ScriptedLoadableModuleLogic.getParameterNode() keeps it:
    the singleton vtkMRMLScriptedModuleNode tagged and attributed (ModuleName) with the
    module's name; created when the scene has none."""
    node = scene.GetSingletonNode(module_name, "vtkMRMLScriptedModuleNode")
    if node is None:
        node = scene.CreateNodeByClass("vtkMRMLScriptedModuleNode")
        node.UnRegister(None)
        node.SetSingletonTag(module_name)
        node.SetName(scene.GenerateUniqueName(module_name))
        node.SetAttribute("ModuleName", module_name)
        node = scene.AddNode(node)
    return node


def defined_points_key(curve) -> tuple:
    """The defined control points of the curve (world), as a comparable value. In place
    mode Slicer moves a preview point (PositionPreview) on every mouse move, firing
    PointModifiedEvent; the design ignores preview points, so such events change nothing."""
    key = []
    for i in range(curve.GetNumberOfControlPoints()):
        if curve.GetNthControlPointPositionStatus(i) != curve.PositionDefined:
            continue
        position = [0.0, 0.0, 0.0]
        curve.GetNthControlPointPositionWorld(i, position)
        key.append(tuple(position))
    return tuple(key)


class DesignJob(process.LibraryJob):
    """One candidate's design without blocking the GUI (process.LibraryJob): the inputs are
    read at start() (MRML, on the caller's thread), baffle.design runs on the worker
    thread, and poll() writes the outputs once it is done. cancel() makes the library's
    progress callback return False, which the library honours at its next report. `error`
    is the BaffleDesignerError of a failed or cancelled design."""

    what = "design"
    poll_interval = 0.02

    def __init__(self, logic, curve, allow_prepare: bool = False, progress=None, parameters=None, ventricle=None):
        super().__init__(logic, curve, "design")
        self.given_parameters = parameters
        self.ventricle = ventricle
        self.allow_prepare = allow_prepare
        self.user_progress = progress
        self.error: Optional[BaffleDesignerError] = None
        self.points_key: tuple = ()
        self._parameters = None
        self._started = 0.0
        # Time spent on the caller's (GUI) thread: reading the inputs, writing the outputs.
        self.gui_ms = 0.0

    def start(self) -> "DesignJob":
        self._started = time.perf_counter()
        self.state = process.RUNNING
        try:
            self._parameters, points, mesh = self.logic._design_inputs(
                self.curve, self.allow_prepare, self.user_progress, self.given_parameters, self.ventricle)
        except BaffleDesignerError as error:
            self._end_with(error)
            return self
        finally:
            self.gui_ms += 1000.0 * (time.perf_counter() - self._started)
        self.points_key = defined_points_key(self.curve)
        self.start_worker(self.curve.GetName(), self._parameters, points, mesh)
        return self

    def _work(self, name, parameters, points, mesh) -> None:
        try:
            self._outcome = self.logic._run_library(name, parameters, points, mesh, self._report)
        except BaffleDesignerError as error:
            self._outcome = error
        except Exception as error:  # a bug must end the job, not leave it running forever
            self._outcome = BaffleDesignerError(f"design failed: {type(error).__name__}: {error}")

    def ended(self, outcome) -> str:
        """The outputs written into the scene, or the failure recorded on the curve."""
        curve = self.logic.scene.GetNodeByID(self.curve_id) if self.curve_id else None
        if curve is None or curve is not self.curve:
            return self._finish(process.CANCELLED, "the candidate's curve was removed during the design")
        if isinstance(outcome, BaffleDesignerError):
            return self._end_with(outcome)
        if self._cancel.is_set():
            return self._end_with(DesignCancelled("design cancelled"))
        writing = time.perf_counter()
        elapsed_ms = 1000.0 * (writing - self._started)
        self.logic._finish_design(curve, outcome, self._parameters, elapsed_ms, self.ventricle)
        self.gui_ms += 1000.0 * (time.perf_counter() - writing)
        self.result = outcome
        return self._finish(process.COMPLETED, f"{curve.GetName()}: designed in {elapsed_ms:.0f} ms")

    def _end_with(self, error: BaffleDesignerError) -> str:
        self.error = error
        if self.curve is not None and not isinstance(error, DesignCancelled):
            valid = self._parameters if self._parameters is not None else None
            self.logic._record_failure(self.curve, error, valid)
        return self._finish(process.CANCELLED if isinstance(error, DesignCancelled) else process.FAILED, str(error))

    def _finish(self, state: str, message: str) -> str:
        self.state, self.message = state, message
        if self.error is None and state == process.CANCELLED:
            self.error = DesignCancelled(message)
        return state


def _nan(value) -> float:
    return float("nan") if value is None else float(value)



def rv_outflow_attributes(report):
    """The RV outflow figures of a design report as (attribute, text) pairs: the smallest
    section after the baffle and the section the baffle narrows most ("" where not
    measured), and RvOutflowNote: why they are missing."""
    narrowed = report.get("rv_outflow_most_narrowed") or {}
    text = lambda value, digits: "" if value is None else f"{value:.{digits}f}"
    return (
        ("RvOutflowMinSectionMm2", text(report.get("rv_outflow_min_section_mm2"), 1)),
        ("RvOutflowMostNarrowedBeforeMm2", text(narrowed.get("area_before_mm2"), 1)),
        ("RvOutflowMostNarrowedAfterMm2", text(narrowed.get("area_after_mm2"), 1)),
        ("RvOutflowMostNarrowedAfterOverBefore", text(narrowed.get("after_over_before"), 3)),
        ("RvOutflowMostNarrowedFromPulmonaryEndMm", text(narrowed.get("distance_from_pulmonary_end_mm"), 1)),
        ("RvOutflowNote", report.get("rv_outflow_unavailable") or ""),
    )


def rv_outflow_line(attribute):
    """The RV outflow in one line from a candidate's attributes (`attribute(name)`)."""
    after = attribute("RvOutflowMostNarrowedAfterMm2")
    note = attribute("RvOutflowNote") or ""
    if not after:
        return f"RV outflow not measured: {note}" if note else "RV outflow not measured"
    return (
        f"RV outflow: smallest section {attribute('RvOutflowMinSectionMm2')} mm2; the baffle narrows it most "
        f"{attribute('RvOutflowMostNarrowedFromPulmonaryEndMm')} mm from the pulmonary end: "
        f"{attribute('RvOutflowMostNarrowedBeforeMm2')} -> {after} mm2 "
        f"({100.0 * float(attribute('RvOutflowMostNarrowedAfterOverBefore')):.0f} % left)"
    )


def estimate_attributes(report):
    """The design's reduced-order estimate (report["hemodynamics_estimate"]) as (attribute,
    text) pairs: dp and v_max at peak flow with their measured error ("" where there is no
    estimate), and DpEstimateNote: why there is none."""
    estimate = report.get("hemodynamics_estimate") or {}
    text = lambda key, digits: "" if estimate.get(key) is None else f"{estimate[key]:.{digits}f}"
    return (
        ("DpEstimateMmhg", text("dp_estimate_mmhg", 2)),
        ("VMaxEstimateMS", text("v_max_estimate_m_s", 2)),
        ("EstimatePeakFlowMlS", text("peak_flow_ml_s", 1)),
        ("DpEstimateUncertainty", estimate.get("dp_uncertainty") or ""),
        ("DpEstimateNote", estimate.get("absent_because") or ""),
    )


def estimate_line(attribute):
    """The estimate in words from a candidate's attributes (`attribute(name)`), marked as an
    estimate: the verdict is the simulation's (the library's judgement), never the estimate's."""
    dp = attribute("DpEstimateMmhg")
    if not dp:
        note = attribute("DpEstimateNote") or ""
        return f"no dp estimate: {note}" if note else "no dp estimate"
    return (
        f"dp estimate {dp} mmHg, v_max estimate {attribute('VMaxEstimateMS')} m/s at {attribute('EstimatePeakFlowMlS')} ml/s "
        f"(reduced-order estimate, not CFD: {attribute('DpEstimateUncertainty')})"
    )


def _surface_area(polydata) -> float:
    triangles = vtk.vtkTriangleFilter()
    triangles.SetInputData(polydata)
    mass = vtk.vtkMassProperties()
    mass.SetInputConnection(triangles.GetOutputPort())
    mass.Update()
    return float(mass.GetSurfaceArea())


def _distances_to(source, target) -> np.ndarray:
    """Distance (mm) from every point of `source` to the surface `target`."""
    locator = vtk.vtkCellLocator()
    locator.SetDataSet(target)
    locator.BuildLocator()
    closest, cell, sub, dist2 = [0.0, 0.0, 0.0], vtk.reference(0), vtk.reference(0), vtk.reference(0.0)
    out = np.empty(source.GetNumberOfPoints())
    for i in range(source.GetNumberOfPoints()):
        locator.FindClosestPoint(source.GetPoint(i), closest, cell, sub, dist2)
        out[i] = math.sqrt(float(dist2))
    return out


def polygon_area(loop: np.ndarray) -> float:
    """Area of a closed planar polygon (points in order, first not repeated)."""
    origin = loop.mean(axis=0)
    rel = loop - origin
    return 0.5 * float(np.linalg.norm(np.cross(rel, np.roll(rel, -1, axis=0)).sum(axis=0)))


def section_loop(domain: vtk.vtkPolyData, origin, normal) -> Optional[np.ndarray]:
    """The loop where the plane (origin, normal) cuts the closed domain, on the connected
    piece nearest the origin: (n, 3) points in order, or None when the plane misses."""
    _, vtk_adapters = library()
    loop_data = vtk_adapters.joined_lines(vtk_adapters.plane_cut(domain, origin, normal, nearest=True))
    if loop_data.GetNumberOfLines() != 1 or loop_data.GetNumberOfPoints() < 3:
        return None
    points = numpy_support.vtk_to_numpy(loop_data.GetPoints().GetData())
    ids = vtk.vtkIdList()
    lines = loop_data.GetLines()
    lines.InitTraversal()
    lines.GetNextCell(ids)
    index = [ids.GetId(i) for i in range(ids.GetNumberOfIds())]
    if len(index) < 4 or index[0] != index[-1]:  # not closed
        return None
    return np.asarray(points[index[:-1]], dtype=np.float64)


class BaffleDesignerLogic:
    """Designs candidate baffles for the closed curve nodes of a scene.

    Without Qt: the widget drives the debounced auto-update by calling
    processPendingUpdates() from a single-shot QTimer that it restarts on every
    `onUpdateRequested` call; tests call processPendingUpdates() directly."""

    def __init__(self, scene, debounce_seconds: float = 0.3, **kwargs):
        # Cooperative: in Slicer this class is mixed with ScriptedLoadableModuleLogic,
        # whose __init__ calls super().__init__() (Slicer >= 5.0); keep the chain going.
        super().__init__(**kwargs)
        if scene is None:
            raise BaffleDesignerError("no MRML scene")
        self.scene = scene
        self.debounce_seconds = debounce_seconds
        # Called with the curve node whenever an observed curve changes (widget: restart timer).
        self.onUpdateRequested: Optional[Callable] = None
        # Called after every auto-update attempt: (curve node, error message or None).
        self.onAutoUpdated: Optional[Callable] = None
        self._observations: Dict[str, List[Tuple[object, int]]] = {}
        self._pending: Dict[str, float] = {}
        self._dragging: set = set()  # IDs of curves with a control point being dragged
        # The defined points last seen of each auto-updating curve (defined_points_key).
        self._points_keys: Dict[str, tuple] = {}
        self.design_count = 0
        # The latest patch template of each candidate (curve ID -> baffle.Template).
        self._templates: Dict[str, object] = {}
        self.prepare_count = 0
        # `baffle prepare` runs for segmentation inputs: the program (None: found on first
        # use), its environment (None: this process's) and the folder of its work folders
        # (None: the system's temporary folder).
        self.executable: Optional[str] = None
        self.child_env: Optional[dict] = None
        self.work_root: Optional[str] = None
        # A removed candidate takes its outputs along: their IDs are taken while the curve
        # is still in the scene (its references resolve), removed once it has gone.
        self._leaving: Dict[str, List[str]] = {}
        self._name_tags: Dict[str, Tuple[object, int]] = {}  # curve ID -> (curve, observer tag)
        self._scene_tags = [
            scene.AddObserver(scene.NodeAboutToBeRemovedEvent, self._on_node_about_to_be_removed),
            scene.AddObserver(scene.NodeRemovedEvent, self._on_node_removed),
        ]

    # ---- the parameter node: what the panel shows, saved with the scene ------------------

    def parameterNode(self):
        """The module's parameter node: the singleton vtkMRMLScriptedModuleNode that
        Slicer's ScriptedLoadableModuleLogic.getParameterNode() returns too (tag and
        ModuleName "BaffleDesigner"); created when the scene has none. slicer-core has no
        parameterNodeWrapper, so this is the plain node with named references."""
        return singleton_parameter_node(self.scene, MODULE_NAME)

    def bafflePlannerCurve(self):
        """The closed curve SlicerHeart's BafflePlanner works on (its parameter node's
        InputCurve), or None."""
        collection = self.scene.GetNodesByClass("vtkMRMLScriptedModuleNode")
        for i in range(collection.GetNumberOfItems()):
            node = collection.GetItemAsObject(i)
            if node.GetAttribute("ModuleName") == BAFFLE_PLANNER or node.GetSingletonTag() == BAFFLE_PLANNER:
                curve = node.GetNodeReference(PARAM_INPUT_CURVE)
                if curve is not None and curve.IsA("vtkMRMLMarkupsClosedCurveNode"):
                    return curve
        return None

    def defaultInputCurve(self):
        """The curve to show: the parameter node's, else BafflePlanner's InputCurve."""
        curve = self.parameterNode().GetNodeReference(PARAM_INPUT_CURVE)
        return curve if curve is not None else self.bafflePlannerCurve()

    def setInputCurve(self, curve) -> None:
        self.parameterNode().SetNodeReferenceID(PARAM_INPUT_CURVE, curve.GetID() if curve is not None else None)

    def inputVentricle(self):
        return self.parameterNode().GetNodeReference(PARAM_VENTRICLE)

    def setInputVentricle(self, node) -> None:
        self.parameterNode().SetNodeReferenceID(PARAM_VENTRICLE, node.GetID() if node is not None else None)

    def isOutputNode(self, node) -> bool:
        """Whether the node is one of this module's outputs (never a ventricle to offer)."""
        return node is not None and bool(node.GetAttribute(ROLE_ATTRIBUTE))

    # ---- inputs and parameters -------------------------------------------------------

    def setSurfaceNode(self, curve, surface_node) -> None:
        """The candidate's ventricle; no write (no ModifiedEvent) when it is already that."""
        check_curve(curve)
        surface_id = surface_node.GetID() if surface_node else None
        if curve.GetNodeReferenceID(REF_SURFACE) == surface_id and curve.GetAttribute(CANDIDATE_ATTRIBUTE) == "1":
            return
        with batched_modify(curve):
            curve.SetNodeReferenceID(REF_SURFACE, surface_id)
            curve.SetAttribute(CANDIDATE_ATTRIBUTE, "1")

    def surfaceNode(self, curve):
        return curve.GetNodeReference(REF_SURFACE)

    def setParameters(self, curve, parameters: DesignParameters) -> None:
        """Store the parameters on the candidate: one ModifiedEvent, none when unchanged."""
        check_curve(curve)
        parameters.validate()
        if curve.GetAttribute(CANDIDATE_ATTRIBUTE) == "1" and DesignParameters.read(curve) == parameters:
            return
        with batched_modify(curve):
            parameters.write(curve)
            curve.SetAttribute(CANDIDATE_ATTRIBUTE, "1")

    def parameters(self, curve) -> DesignParameters:
        return DesignParameters.read(curve)

    @staticmethod
    def suturePointsWorld(curve) -> np.ndarray:
        """Defined control points of the curve in world coordinates (RAS), (n, 3)."""
        points = defined_points_key(curve)
        if len(points) < 3:
            raise BaffleDesignerError(
                f"{curve.GetName()}: {len(points)} defined suture points; place at least 3 (BafflePlanner uses 12-15)"
            )
        return np.asarray(points, dtype=np.float64)

    # ---- segmentation input: the prepare step (BaffleDesignerLib.prepare) ---------------

    def preparedVentricle(self, curve):
        """The capped ventricle prepared from the candidate's segmentation as it is now
        (same segments, surfaces and transform), or None when it needs preparing."""
        segmentation = self.surfaceNode(curve)
        return prepare.prepared_node(self.scene, curve, prepare.fingerprint(segmentation, self.parameters(curve)))

    def needsPrepare(self, curve) -> bool:
        surface = self.surfaceNode(curve)
        return surface is not None and surface.IsA("vtkMRMLSegmentationNode") and self.preparedVentricle(curve) is None

    def startPrepare(self, curve, executable: Optional[str] = None, work_dir: Optional[str] = None, env: Optional[dict] = None):
        """Start `baffle prepare` on the candidate's segmentation; returns the running
        prepare.PrepareJob (poll() it from a timer). Defaults: the logic's executable,
        a new folder under work_root, the logic's child_env."""
        import tempfile

        if executable is None:
            executable = self.executable or environment.find_baffle_executable()
        if work_dir is None:
            work_dir = tempfile.mkdtemp(prefix="BaffleDesigner-prepare-", dir=self.work_root)
        job = prepare.PrepareJob(self, curve, executable, work_dir, self.child_env if env is None else env).start()
        self.prepare_count += 1
        return job

    def prepareVentricle(self, curve, progress=None, poll_interval: float = 0.05):
        """Run `baffle prepare` for the candidate and wait for it; progress(fraction, stage)
        is called while it runs (no fractions: 0) and cancels it by returning False.
        Returns the prepared model node; BaffleDesignerError says why it failed."""
        job = self.startPrepare(curve)
        while job.poll() == process.RUNNING:
            if progress is not None and progress(0.0, f"{job.stage}: baffle prepare") is False:
                job.cancel()
            time.sleep(poll_interval)
        if job.state != process.COMPLETED:
            raise BaffleDesignerError(job.message)
        return job.node

    def ventricleModel(self, curve, allow_prepare: bool = True, progress=None):
        """The model node the candidate is designed on: the selected model, or the capped
        ventricle prepared from the selected segmentation (prepared now when it is missing
        or outdated and allow_prepare; else an error saying to prepare it)."""
        surface = self.surfaceNode(curve)
        if surface is not None and surface.IsA("vtkMRMLModelNode") and self.needsRims(surface):
            return self.rimCappedVentricle(curve)
        if surface is None or not surface.IsA("vtkMRMLSegmentationNode"):
            return surface
        prepared = self.preparedVentricle(curve)
        if prepared is not None:
            return prepared
        if not allow_prepare:
            raise BaffleDesignerError(
                f"{surface.GetName()}: the segmentation is not prepared for this candidate, or changed since; "
                "press Design to run the prepare step"
            )
        return self.prepareVentricle(curve, progress=progress)

    # ---- a plain RV model and its rims (BaffleDesignerLib.rims) ---------------------------

    @staticmethod
    def needsRims(model) -> bool:
        """A model with a surface but no caps: BafflePlanner's plain RV model (no ModelFaceID),
        or a segment's surface exported with the wall label alone."""
        polydata = model.GetPolyData()
        if polydata is None or polydata.GetNumberOfPoints() == 0:
            return False
        labels = polydata.GetCellData().GetArray("ModelFaceID")
        if labels is None:
            return True
        present = set(np.unique(numpy_support.vtk_to_numpy(labels)).astype(int).tolist())
        return not ({11, 16} & present)

    def setRims(self, curve, vsd_rim, aortic_rim) -> None:
        """The closed curves the user marked around the VSD and the aortic annulus on the
        plain RV model; no write when unchanged."""
        check_curve(curve)
        wanted = {REF_VSD_RIM: vsd_rim.GetID() if vsd_rim else None, REF_AORTIC_RIM: aortic_rim.GetID() if aortic_rim else None}
        if all(curve.GetNodeReferenceID(role) == node_id for role, node_id in wanted.items()):
            return
        with batched_modify(curve):
            for role, node_id in wanted.items():
                curve.SetNodeReferenceID(role, node_id)

    def rimCappedVentricle(self, curve):
        """The capped ventricle cut from the candidate's plain RV model at its two rims (made
        now when missing or when the model, its transform or a rim changed)."""
        model = self.surfaceNode(curve)
        vsd, aortic = curve.GetNodeReference(REF_VSD_RIM), curve.GetNodeReference(REF_AORTIC_RIM)
        if vsd is None or aortic is None:
            raise BaffleDesignerError(
                f"{model.GetName()}: a plain RV model (no ModelFaceID): mark the VSD rim and the aortic-annulus rim "
                "on it as closed curves and select them, or select the capped ventricle or a segmentation instead")
        surface = self.worldPolyData(model)
        key = repr((model.GetID(), surface.GetNumberOfPoints(), float(np.asarray(surface.GetBounds()).sum()),
                    model.GetPolyData().GetMTime(), defined_points_key(vsd), defined_points_key(aortic)))
        node = curve.GetNodeReference(REF_RIM_CAPPED)
        if node is not None and node.GetAttribute(ATTRIBUTE_PREFIX + "MadeFrom") == key:
            return node
        capped = rims.capped_ventricle(surface, [
            ("VSD", rims.VSD_CAP, np.asarray(defined_points_key(vsd))),
            ("aortic-annulus", rims.AORTIC_CAP, np.asarray(defined_points_key(aortic))),
        ])
        node = self._model(curve, REF_RIM_CAPPED, "capped ventricle (rims)", capped, (0.9, 0.6, 0.6), opacity=0.4)
        node.SetAttribute(ATTRIBUTE_PREFIX + "MadeFrom", key)
        return node

    @staticmethod
    def worldPolyData(model_node) -> vtk.vtkPolyData:
        """A model's surface in world coordinates (through its parent transforms)."""
        polydata = model_node.GetPolyData()
        parent = model_node.GetParentTransformNode()
        if parent is None:
            return polydata
        to_world = vtk.vtkGeneralTransform()
        slicer.vtkMRMLTransformNode.GetTransformBetweenNodes(parent, None, to_world)
        transformer = vtk.vtkTransformPolyDataFilter()
        transformer.SetTransform(to_world)
        transformer.SetInputData(polydata)
        transformer.Update()
        return transformer.GetOutput()

    @classmethod
    def surfacePolyDataWorld(cls, surface_node) -> vtk.vtkPolyData:
        """The ventricle model's surface in world coordinates."""
        if surface_node is None:
            raise BaffleDesignerError("select the ventricle (a model node with ModelFaceID, or a segmentation)")
        if not surface_node.IsA("vtkMRMLModelNode"):
            raise BaffleDesignerError(f"{surface_node.GetName()}: {surface_node.GetClassName()} is not a model or segmentation")
        polydata = surface_node.GetPolyData()
        if polydata is None or polydata.GetNumberOfPoints() == 0:
            raise BaffleDesignerError(f"{surface_node.GetName()}: the model has no surface")
        _, vtk_adapters = library()
        if polydata.GetCellData().GetArray(vtk_adapters.LABEL_ARRAY) is None:
            raise BaffleDesignerError(
                f"{surface_node.GetName()}: no {vtk_adapters.LABEL_ARRAY} cell array; the capped ventricle needs "
                "labels 2 (RV wall), 11 (VSD cap) and 16 (aortic-annulus cap)"
            )
        return cls.worldPolyData(surface_node)

    # ---- design ----------------------------------------------------------------------

    def design(self, curve, progress=None, allow_prepare: bool = True) -> "baffle.DesignResult":
        """Design the candidate of `curve` and update its output nodes, waiting for it
        (scripts, tests; the widget uses startDesign). On failure the previous outputs
        stay, the curve's Status/Error attributes say why, and BaffleDesignerError carries
        the library's message. A segmentation ventricle is prepared first when needed (see
        ventricleModel). progress(fraction, stage) is called on this thread; returning
        False cancels."""
        job = self.startDesign(curve, allow_prepare=allow_prepare, progress=progress)
        job.wait()
        if job.state != process.COMPLETED:
            raise job.error
        return job.result

    def startDesign(self, curve, allow_prepare: bool = False, progress=None,
                    parameters: Optional[DesignParameters] = None, ventricle=None) -> "DesignJob":
        """Start designing the candidate: its inputs are read now, the library runs on a
        worker thread, and the outputs are written by the job's poll() on the caller's
        thread (MRML is not thread-safe). `parameters` (default: the curve's) and a
        ventricle model node (default: the curve's) are stored on the curve with the
        outputs, in the same one ModifiedEvent. Raises nothing: a failure is the job's state."""
        return DesignJob(self, curve, allow_prepare, progress, parameters, ventricle).start()

    def _design_inputs(self, curve, allow_prepare, progress, parameters=None, ventricle=None):
        """(parameters, suture points, the ventricle as a baffle mesh), read on the GUI thread."""
        check_curve(curve)
        parameters = self.parameters(curve) if parameters is None else parameters
        parameters.validate()
        points = self.suturePointsWorld(curve)
        _, vtk_adapters = library()
        model = ventricle if ventricle is not None else self.ventricleModel(curve, allow_prepare, progress)
        surface = self.surfacePolyDataWorld(model)
        try:
            mesh = vtk_adapters.polydata_to_mesh(surface)
        except ValueError as error:
            raise BaffleDesignerError(f"{model.GetName()}: {error}") from error
        return parameters, points, mesh

    @staticmethod
    def _run_library(curve_name, parameters, points, mesh, progress):
        """baffle.design on the inputs: a pure function of them, safe off the GUI thread."""
        baffle, _ = library()
        try:
            # The reduced-order dp estimate at the flow the CFD step would use (BSA x CI).
            peak_flow = baffle.peak_flow_ml_s(parameters.cfd_bsa_m2(), parameters.cardiac_index_l_min_m2)
            return baffle.design(mesh.points, mesh.triangles, mesh.labels, points, progress=progress,
                                 peak_flow_ml_s=peak_flow, **parameters.design_kwargs())
        except baffle.Cancelled as error:
            raise DesignCancelled(f"design cancelled: {error}") from error
        except baffle.BaffleError as error:
            failure = BaffleDesignerError(f"design failed: {error}")
            # The largest target this suture line admits, when the target is out of reach.
            failure.max_feasible_area_mm2 = getattr(error, "max_feasible_area_mm2", None)
            raise failure from error

    @staticmethod
    def _record_failure(curve, error, parameters: Optional[DesignParameters] = None) -> None:
        largest = getattr(error, "max_feasible_area_mm2", None)
        with batched_modify(curve):
            if parameters is not None:
                parameters.write(curve)
            curve.SetAttribute(CANDIDATE_ATTRIBUTE, "1")
            curve.SetAttribute(ATTRIBUTE_PREFIX + "MaxFeasibleAreaMm2", "" if largest is None else f"{largest:.1f}")
            curve.SetAttribute(ATTRIBUTE_PREFIX + "Status", "failed")
            curve.SetAttribute(ATTRIBUTE_PREFIX + "Error", str(error))

    def _finish_design(self, curve, result, parameters, elapsed_ms, ventricle=None) -> None:
        """The outputs and figures of a finished design onto the scene, one ModifiedEvent on the curve."""
        with batched_modify(curve):
            if ventricle is not None:
                curve.SetNodeReferenceID(REF_SURFACE, ventricle.GetID())
            parameters.write(curve)  # what it was designed with (the same unless the GUI passed others)
            curve.SetAttribute(CANDIDATE_ATTRIBUTE, "1")
            self._write_outputs(curve, result, parameters)
            if curve.GetAttribute(ATTRIBUTE_PREFIX + "SimulationStatus") == "completed":
                # Its results describe the previous geometry; kept, but marked.
                curve.SetAttribute(ATTRIBUTE_PREFIX + "SimulationStatus", "outdated")
            report = result.report
            for name, value in (
                ("Status", "designed"),
                ("Error", ""),
                ("MaxFeasibleAreaMm2", ""),
                ("TargetAreaMm2", report["target_area_mm2"]),
                ("TargetDescription", report["target"]),
                ("BaffleAreaMm2", report["baffle_area_mm2"]),
                ("MinSectionAreaMm2", report["min_constrained_final_area_mm2"]),
                ("ConstrainedSections", report["constrained_sections"]),
                ("CenterlineLengthMm", report["centerline_length_mm"]),
                ("RvVolumeBeforeMl", f"{report['rv_volume_before_ml']:.3f}"),
                ("RvVolumeAfterMl", f"{report['rv_volume_after_ml']:.3f}"),
                ("BaffleAreaOutsideVentricleMm2", f"{report['baffle_area_outside_ventricle_mm2']:.1f}"),
                *rv_outflow_attributes(report),
                *estimate_attributes(report),
                ("DesignTimeMs", f"{elapsed_ms:.0f}"),
            ):
                curve.SetAttribute(ATTRIBUTE_PREFIX + name, str(value))
        self.design_count += 1

    def _output_node(self, curve, role: str, class_name: str, suffix: str):
        node = curve.GetNodeReference(role)
        if node is None or not node.IsA(class_name):
            node = self.scene.AddNewNodeByClass(class_name, f"{curve.GetName()} {suffix}")
            if node is None:  # class not registered with this scene (headless scenes)
                node = getattr(slicer, class_name)()
                node.SetName(f"{curve.GetName()} {suffix}")
                self.scene.AddNode(node)
            node.SetAttribute(ROLE_ATTRIBUTE, role)
            if hasattr(node, "CreateDefaultDisplayNodes"):
                node.CreateDefaultDisplayNodes()
            curve.SetNodeReferenceID(role, node.GetID())
            self._into_folder(curve, node)
            self._follow_name(curve)
        return node

    def _follow_name(self, curve) -> None:
        """Observe the curve's renaming (once per curve): its outputs and folder follow."""
        if curve.GetID() not in self._name_tags:
            self._name_tags[curve.GetID()] = (curve, curve.AddObserver(vtk.vtkCommand.ModifiedEvent, self._on_curve_modified))

    def _on_curve_modified(self, curve, _event=None) -> None:
        folder = self.candidateFolder(curve, create=False)
        if not folder:
            return
        sh = slicer.vtkMRMLSubjectHierarchyNode.GetSubjectHierarchyNode(self.scene)
        old = sh.GetItemName(folder)[: -len(FOLDER_SUFFIX)]
        new = curve.GetName()
        if old == new:
            return
        sh.SetItemName(folder, new + FOLDER_SUFFIX)
        for role in OUTPUT_ROLES:
            node = curve.GetNodeReference(role)
            if node is not None and node.GetName().startswith(old + " "):
                node.SetName(new + node.GetName()[len(old):])

    # ---- a candidate's outputs: one subject hierarchy folder, removed with the curve --------

    def candidateFolder(self, curve, create: bool = True) -> int:
        """The subject hierarchy folder of the candidate's outputs (item ID; 0 when there
        is none and not create), found by its attribute naming the curve."""
        sh = slicer.vtkMRMLSubjectHierarchyNode.GetSubjectHierarchyNode(self.scene)
        children = vtk.vtkIdList()
        sh.GetItemChildren(sh.GetSceneItemID(), children)
        for i in range(children.GetNumberOfIds()):
            item = children.GetId(i)
            if sh.GetItemAttribute(item, FOLDER_ATTRIBUTE) == curve.GetID():
                return item
        if not create:
            return 0
        folder = sh.CreateFolderItem(sh.GetSceneItemID(), curve.GetName() + FOLDER_SUFFIX)
        sh.SetItemAttribute(folder, FOLDER_ATTRIBUTE, curve.GetID())
        return folder

    def _into_folder(self, curve, node) -> None:
        sh = slicer.vtkMRMLSubjectHierarchyNode.GetSubjectHierarchyNode(self.scene)
        folder = self.candidateFolder(curve)
        item = sh.GetItemByDataNode(node)
        if item:
            sh.SetItemParent(item, folder)
        else:  # Slicer's subject hierarchy logic makes the item; a bare MRML scene does not
            sh.CreateItem(folder, node)

    def _on_node_about_to_be_removed(self, scene, _event) -> None:
        # No call data in a plain Python observer: check the candidates still in the scene.
        if scene.IsClosing() or scene.IsBatchProcessing():
            return
        for curve in self.candidates():
            if curve.GetID() not in self._leaving:
                self._leaving[curve.GetID()] = [curve.GetNodeReferenceID(role) for role in OUTPUT_ROLES
                                                if curve.GetNodeReferenceID(role)]

    def _on_node_removed(self, scene, _event) -> None:
        if scene.IsClosing() or scene.IsBatchProcessing():
            self._leaving.clear()
            return
        leaving, self._leaving = self._leaving, {}
        for curve_id, output_ids in leaving.items():
            if scene.GetNodeByID(curve_id) is not None:
                continue  # still there: another node was removed
            for node_id in output_ids:
                node = scene.GetNodeByID(node_id)
                if node is not None:
                    scene.RemoveNode(node)
            sh = slicer.vtkMRMLSubjectHierarchyNode.GetSubjectHierarchyNode(scene)
            children = vtk.vtkIdList()
            sh.GetItemChildren(sh.GetSceneItemID(), children)
            for i in range(children.GetNumberOfIds()):
                if sh.GetItemAttribute(children.GetId(i), FOLDER_ATTRIBUTE) == curve_id:
                    sh.RemoveItem(children.GetId(i), True, True)
                    break

    def removeSceneObservers(self) -> None:
        for tag in self._scene_tags:
            self.scene.RemoveObserver(tag)
        self._scene_tags = []
        for curve, tag in self._name_tags.values():
            curve.RemoveObserver(tag)
        self._name_tags.clear()

    def _model(self, curve, role, suffix, polydata, color, opacity=1.0):
        node = self._output_node(curve, role, "vtkMRMLModelNode", suffix)
        was_new = node.GetPolyData() is None
        node.SetAndObservePolyData(polydata)
        display = node.GetDisplayNode()
        if display is not None and was_new:
            display.SetColor(*color)
            display.SetOpacity(opacity)
            display.SetVisibility2D(True)
        return node

    def _write_outputs(self, curve, result, parameters) -> None:
        _, vtk_adapters = library()
        baffle_polydata = vtk_adapters.mesh_to_polydata(result.baffle)
        domain_polydata = vtk_adapters.mesh_to_polydata(result.domain)
        self._model(curve, REF_BAFFLE, "baffle", baffle_polydata, (0.85, 0.25, 0.2))
        self._model(curve, REF_DOMAIN, "domain", domain_polydata, (0.95, 0.85, 0.6), opacity=0.3)
        self._write_centerline(curve, result)
        measured = self._write_sections(curve, result, domain_polydata)
        table = self._write_table(curve, result, measured)
        self._write_plot(curve, table)

    def _write_centerline(self, curve, result) -> None:
        node = self._output_node(curve, REF_CENTERLINE, "vtkMRMLMarkupsCurveNode", "centerline")
        node.SetCurveTypeToLinear()
        points = vtk.vtkPoints()
        points.SetData(vtk_double_array("points", result.centerline_points_mm))
        node.SetLocked(False)
        node.SetControlPointPositionsWorld(points)
        node.SetLocked(True)  # an output: the surgeon drags the suture points, not this
        display = node.GetDisplayNode()
        if display is not None and hasattr(display, "SetPointLabelsVisibility"):
            display.SetPointLabelsVisibility(False)

    def _write_sections(self, curve, result, domain_polydata) -> List[float]:
        """Cut every section plane of the report from the domain; the loops go into the
        sections model (cell arrays s_mm, area_mm2, constrained), their areas (an
        independent re-measurement) into the table."""
        append_points, lines, s_values, areas, constrained = [], [], [], [], []
        measured = []
        offset = 0
        for section in result.report["sections"]:
            loop = section_loop(domain_polydata, section["origin_mm"], section["normal"])
            if loop is None:
                measured.append(float("nan"))
                continue
            area = polygon_area(loop)
            measured.append(area)
            append_points.append(loop)
            lines.append(list(range(offset, offset + len(loop))) + [offset])
            offset += len(loop)
            s_values.append(section["s_mm"])
            areas.append(area)
            # 1 constrained, 2 checked only (its arc crosses a constrained one), 0 dropped.
            constrained.append(1 if section["status"] == "constrained" else 2 if section["final_area_mm2"] is not None else 0)
        polydata = vtk.vtkPolyData()
        points = vtk.vtkPoints()
        if append_points:
            points.SetData(vtk_double_array("points", np.vstack(append_points)))
        polydata.SetPoints(points)
        cells = vtk.vtkCellArray()
        for line in lines:
            cells.InsertNextCell(len(line))
            for index in line:
                cells.InsertCellPoint(index)
        polydata.SetLines(cells)
        for name, values in (("s_mm", s_values), ("area_mm2", areas)):
            polydata.GetCellData().AddArray(vtk_double_array(name, values))
        flag = numpy_support.numpy_to_vtk(np.asarray(constrained, dtype=np.int32), deep=1)
        flag.SetName("constrained")
        polydata.GetCellData().AddArray(flag)
        self._model(curve, REF_SECTIONS, "sections", polydata, (0.2, 0.5, 0.95))
        return measured

    def _write_table(self, curve, result, measured):
        node = self._output_node(curve, REF_TABLE, "vtkMRMLTableNode", "sections")
        sections = result.report["sections"]
        target = result.report["target_area_mm2"]
        columns = {
            COL_S: [s["s_mm"] for s in sections],
            COL_TARGET: [target] * len(sections),
            COL_RAW: [_nan(s["raw_area_mm2"]) for s in sections],
            COL_FINAL: [_nan(s["final_area_mm2"]) for s in sections],
            COL_MEASURED: measured,
            COL_ALPHA: [_nan(s["alpha_regularized_mm"]) for s in sections],
        }
        table = vtk.vtkTable()
        for name, _, _ in SECTION_COLUMNS:
            table.AddColumn(vtk_double_array(name, columns[name]))
        status = vtk.vtkStringArray()
        status.SetName(COL_STATUS)
        for s in sections:
            status.InsertNextValue(s["status"])
        table.AddColumn(status)
        node.SetAndObserveTable(table)
        for name, unit, description in SECTION_COLUMNS:
            node.SetColumnUnitLabel(name, unit)
            node.SetColumnDescription(name, description)
        node.SetColumnDescription(COL_STATUS, "constrained, or why the section was dropped")
        return node

    def _write_plot(self, curve, table_node) -> None:
        chart = self._output_node(curve, REF_CHART, "vtkMRMLPlotChartNode", "area along centerline")
        chart.SetTitle(f"{curve.GetName()}: section area along the centerline")
        chart.SetXAxisTitle("s (mm)")
        chart.SetYAxisTitle("area (mm2)")
        styles = (
            (REF_SERIES_FINAL, COL_FINAL, (0.85, 0.25, 0.2), slicer.vtkMRMLPlotSeriesNode.LineStyleSolid),
            (REF_SERIES_RAW, COL_RAW, (0.5, 0.5, 0.5), slicer.vtkMRMLPlotSeriesNode.LineStyleDot),
            (REF_SERIES_TARGET, COL_TARGET, (0.1, 0.6, 0.2), slicer.vtkMRMLPlotSeriesNode.LineStyleDash),
        )
        for role, column, color, line_style in styles:
            series = self._output_node(curve, role, "vtkMRMLPlotSeriesNode", column.lower())
            series.SetAndObserveTableNodeID(table_node.GetID())
            series.SetXColumnName(COL_S)
            series.SetYColumnName(column)
            series.SetPlotType(slicer.vtkMRMLPlotSeriesNode.PlotTypeScatter)
            series.SetLineStyle(line_style)
            series.SetMarkerStyle(slicer.vtkMRMLPlotSeriesNode.MarkerStyleNone)
            series.SetColor(*color)
            if not chart.HasPlotSeriesNodeID(series.GetID()):
                chart.AddAndObservePlotSeriesNodeID(series.GetID())

    # ---- patch template ---------------------------------------------------------------

    @staticmethod
    def suturePointLabels(curve) -> List[str]:
        """Labels of the defined control points, in the order of suturePointsWorld."""
        return [
            curve.GetNthControlPointLabel(i)
            for i in range(curve.GetNumberOfControlPoints())
            if curve.GetNthControlPointPositionStatus(i) == curve.PositionDefined
        ]

    def flattenTemplate(self, curve, method: str = "lscm", patient_label: Optional[str] = None):
        """Flatten the candidate's designed baffle into the true-scale patch template
        (baffle.template): the flat model node (u, v, 0 in mm, cell array area_ratio), the
        template's figures as curve attributes, and the template kept for saveTemplate.
        Needs a design; the suture points are named as in the curve."""
        check_curve(curve)
        domain_node = curve.GetNodeReference(REF_DOMAIN)
        if domain_node is None or domain_node.GetPolyData() is None:
            raise BaffleDesignerError(f"{curve.GetName()}: design the baffle first (no domain to flatten)")
        baffle, vtk_adapters = library()
        mesh = vtk_adapters.polydata_to_mesh(domain_node.GetPolyData())
        label = curve.GetName() if patient_label is None else patient_label
        try:
            template = baffle.template(
                mesh, self.suturePointsWorld(curve), point_labels=self.suturePointLabels(curve), patient_label=label, method=method
            )
        except baffle.BaffleError as error:
            raise BaffleDesignerError(f"{curve.GetName()}: template failed: {error}") from error
        with batched_modify(curve):
            polydata = vtk_adapters.mesh_to_polydata(template.flat)
            polydata.GetCellData().AddArray(vtk_double_array("area_ratio", template.area_ratio))
            node = self._model(curve, REF_FLAT_TEMPLATE, "flat template", polydata, (0.85, 0.25, 0.2))
            node.SetAttribute(ATTRIBUTE_PREFIX + "DomainMTime", str(domain_node.GetPolyData().GetMTime()))
            f = template.report["flattening"]
            for name, value in (
                ("TemplateMethod", method),
                ("TemplateSeamLengthMm", f"{f['seam_length_3d_mm']:.2f}"),
                ("TemplatePerimeterErrorPct", f"{100 * f['perimeter_error']:.2g}"),
                ("TemplateAreaChangeMedianPct", f"{100 * f['area_distortion_median']:.1f}"),
                ("TemplateAreaChangeMaxPct", f"{100 * f['area_distortion_max']:.1f}"),
                ("TemplateAngleChangeMaxDeg", f"{f['angle_distortion_max_deg']:.1f}"),
            ):
                curve.SetAttribute(ATTRIBUTE_PREFIX + name, value)
        self._templates[curve.GetID()] = template
        return template

    def saveTemplate(self, curve, path, method: str = "lscm", patient_label: Optional[str] = None) -> str:
        """Write the candidate's patch template to `path` (.pdf or .svg, A4, 1:1 at 100 %;
        .png, A4 at 300 dpi stored in the file), flattening first when there is no
        template of the current design."""
        if not str(path).lower().endswith((".pdf", ".svg", ".png")):
            raise BaffleDesignerError(f"{path}: save the template as .pdf, .svg or .png")
        template = self._templates.get(curve.GetID()) if curve is not None else None
        flat = curve.GetNodeReference(REF_FLAT_TEMPLATE) if curve is not None else None
        domain = curve.GetNodeReference(REF_DOMAIN) if curve is not None else None
        current = (
            template is not None
            and flat is not None
            and domain is not None
            and flat.GetAttribute(ATTRIBUTE_PREFIX + "DomainMTime") == str(domain.GetPolyData().GetMTime())
            and curve.GetAttribute(ATTRIBUTE_PREFIX + "TemplateMethod") == method
        )
        if not current:
            template = self.flattenTemplate(curve, method, patient_label)
        try:
            saved = str(template.save(path))
        except OSError as error:
            raise BaffleDesignerError(f"{path}: {error}") from error
        curve.SetAttribute(ATTRIBUTE_PREFIX + "TemplatePath", saved)
        return saved

    # ---- auto-update ------------------------------------------------------------------

    def setAutoUpdate(self, curve, enabled: bool) -> None:
        """Observe the curve's control points: a change of its defined points (an add, a
        remove, a move from a script, the end of a drag) marks the candidate pending;
        processPendingUpdates() designs it once it has been quiet for debounce_seconds.
        Moves during a drag do not: Slicer fires PointModifiedEvent on every mouse move,
        and a design would start whenever the surgeon paused mid-drag. Nor do preview
        points: in place mode Slicer moves one on every mouse move, with no drag events,
        and the design ignores it (defined_points_key)."""
        check_curve(curve)
        curve_id = curve.GetID()
        for node, tag in self._observations.pop(curve_id, []):
            node.RemoveObserver(tag)
        self._pending.pop(curve_id, None)
        self._dragging.discard(curve_id)
        curve.SetAttribute(ATTRIBUTE_PREFIX + "AutoUpdate", "1" if enabled else "0")
        if not enabled:
            self._points_keys.pop(curve_id, None)
            return
        self._points_keys[curve_id] = defined_points_key(curve)
        handlers = (
            (curve.PointModifiedEvent, self._on_curve_changed),
            (curve.PointAddedEvent, self._on_curve_changed),
            (curve.PointRemovedEvent, self._on_curve_changed),
            (curve.PointPositionDefinedEvent, self._on_curve_changed),
            (curve.PointPositionUndefinedEvent, self._on_curve_changed),
            (curve.PointStartInteractionEvent, self._on_drag_start),
            (curve.PointEndInteractionEvent, self._on_drag_end),
        )
        self._observations[curve_id] = [(curve, curve.AddObserver(event, handler)) for event, handler in handlers]

    def rearmAutoUpdates(self) -> List[str]:
        """Observe again every candidate saved with auto-update on (a reopened scene keeps
        the attribute, not the observers). Returns their IDs."""
        armed = []
        for curve in self.candidates():
            self._follow_name(curve)
            if curve.GetAttribute(ATTRIBUTE_PREFIX + "AutoUpdate") == "1" and not self.isAutoUpdating(curve):
                self.setAutoUpdate(curve, True)
                armed.append(curve.GetID())
        return armed

    def isAutoUpdating(self, curve) -> bool:
        return curve.GetID() in self._observations

    def _points_changed(self, curve) -> bool:
        """True (and remembered) when the defined points differ from the last ones seen."""
        key = defined_points_key(curve)
        if self._points_keys.get(curve.GetID()) == key:
            return False
        self._points_keys[curve.GetID()] = key
        return True

    def _on_curve_changed(self, curve, _event=None) -> None:
        if curve.GetID() not in self._dragging and self._points_changed(curve):
            self.requestUpdate(curve)

    def _on_drag_start(self, curve, _event=None) -> None:
        self._dragging.add(curve.GetID())
        self._pending.pop(curve.GetID(), None)  # the drag supersedes an earlier change

    def _on_drag_end(self, curve, _event=None) -> None:
        self._dragging.discard(curve.GetID())
        if self._points_changed(curve):
            self.requestUpdate(curve)

    def requestUpdate(self, curve) -> None:
        """Mark the candidate for a debounced redesign (point drags, parameter edits)."""
        self._pending[curve.GetID()] = time.monotonic()
        if self.onUpdateRequested is not None:
            self.onUpdateRequested(curve)

    def pendingUpdates(self) -> List[str]:
        return list(self._pending)

    def takeReadyUpdate(self, now: Optional[float] = None, force: bool = False):
        """The next pending candidate that has been quiet for debounce_seconds (any with
        force), no longer pending; None when there is none."""
        now = time.monotonic() if now is None else now
        for curve_id, changed in list(self._pending.items()):
            if not force and now - changed < self.debounce_seconds:
                continue
            del self._pending[curve_id]
            curve = self.scene.GetNodeByID(curve_id)
            if curve is not None:
                return curve
        return None

    def processPendingUpdates(self, now: Optional[float] = None, force: bool = False) -> Dict[str, Optional[str]]:
        """Design every pending candidate that has been quiet for debounce_seconds (all
        of them with force), waiting for each (the widget starts DesignJobs instead).
        Returns {curve ID: None or the error message}; errors are also left on the curve
        (Status/Error attributes), never raised, so a point dragged off the wall just
        leaves the last good baffle in place."""
        done = {}
        while True:
            curve = self.takeReadyUpdate(now, force)
            if curve is None:
                return done
            try:
                self.design(curve, allow_prepare=False)  # live: never a prepare run
                done[curve.GetID()] = None
            except BaffleDesignerError as error:
                done[curve.GetID()] = str(error)
            if self.onAutoUpdated is not None:
                self.onAutoUpdated(curve, done[curve.GetID()])

    def cleanup(self) -> None:
        """Remove all observers (module widget cleanup / scene close)."""
        for observations in self._observations.values():
            for node, tag in observations:
                node.RemoveObserver(tag)
        self._observations.clear()
        self._pending.clear()
        self._dragging.clear()
        self._points_keys.clear()

    # ---- BafflePlanner's baffle beside ours ------------------------------------------------

    def compareWithBafflePlanner(self, curve) -> Dict[str, float]:
        """Our designed baffle against BafflePlanner's on the same curve (its 'BaffleModel'
        reference): both areas (mm2) and the distance from each surface to the other
        (mean and largest over the points of both, mm). Stored as curve attributes
        (BafflePlanner*) for the comparison table."""
        ours = curve.GetNodeReference(REF_BAFFLE)
        theirs = curve.GetNodeReference(BAFFLE_PLANNER_MODEL_REF)
        if ours is None or ours.GetPolyData() is None or ours.GetPolyData().GetNumberOfCells() == 0:
            raise BaffleDesignerError(f"{curve.GetName()}: design the baffle first")
        if theirs is None or theirs.GetPolyData() is None or theirs.GetPolyData().GetNumberOfCells() == 0:
            raise BaffleDesignerError(f"{curve.GetName()}: BafflePlanner has no baffle model on this curve (reference 'BaffleModel')")
        a, b = ours.GetPolyData(), theirs.GetPolyData()
        to_a, to_b = _distances_to(a, b), _distances_to(b, a)
        both = np.concatenate([to_a, to_b])
        figures = {
            "BafflePlannerAreaMm2": _surface_area(b),
            "BaffleDesignerAreaMm2": _surface_area(a),
            "BafflePlannerMeanDistanceMm": float(both.mean()),
            "BafflePlannerMaxDistanceMm": float(both.max()),
        }
        with batched_modify(curve):
            for name, value in figures.items():
                curve.SetAttribute(ATTRIBUTE_PREFIX + name, f"{value:.3f}")
        return figures

    # ---- a `baffle plan` run's geometry -------------------------------------------------

    def loadPlanGeometry(self, folder: str) -> list:
        """The surfaces a `baffle plan --out folder` run wrote (PLAN_GEOMETRY: the capped
        ventricle it prepared, the domain and baffle it designed, the extended domain, the
        flow centerline), as model nodes in one subject hierarchy folder named after the run.
        The files are read as Slicer reads model files (LPS unless the file says RAS), so a
        plan run on surfaces Slicer exported lands on them. Errors when there is none."""
        import os

        found = [(relative, name) for relative, name in PLAN_GEOMETRY if os.path.isfile(os.path.join(folder, relative))]
        if not found:
            raise BaffleDesignerError(
                f"{folder}: no plan geometry (looked for {', '.join(relative for relative, _ in PLAN_GEOMETRY)})")
        sh = slicer.vtkMRMLSubjectHierarchyNode.GetSubjectHierarchyNode(self.scene)
        run = os.path.basename(os.path.normpath(folder))
        parent = sh.CreateFolderItem(sh.GetSceneItemID(), f"plan {run}")
        nodes = []
        for relative, name in found:
            path = os.path.join(folder, relative)
            node = self.scene.AddNewNodeByClass("vtkMRMLModelNode", f"plan {run} {name}")
            storage = self.scene.AddNewNodeByClass("vtkMRMLModelStorageNode")
            storage.SetFileName(path)
            node.SetAndObserveStorageNodeID(storage.GetID())
            if not storage.ReadData(node):
                self.scene.RemoveNode(node)
                self.scene.RemoveNode(storage)
                raise BaffleDesignerError(f"{path}: could not be read as a model")
            node.CreateDefaultDisplayNodes()
            item = sh.GetItemByDataNode(node)
            if item:
                sh.SetItemParent(item, parent)
            else:
                sh.CreateItem(parent, node)
            nodes.append(node)
        return nodes

    # ---- the whole plan through the library (BaffleDesignerLib.plan) ----------------------

    def startPlan(self, curve, out_dir: str, parameters: Optional[DesignParameters] = None,
                  single_mesh: bool = False, env: Optional[dict] = None) -> "planrun.PlanJob":
        """Start the candidate's whole plan (baffle.plan: [prepare ->] design, centerline,
        mesh, simulate, report) into out_dir on a worker thread; returns the running
        plan.PlanJob (poll() it from a timer). Its inputs are the candidate's ventricle
        (model, plain RV model with rims, or segmentation), suture points and parameters
        (`parameters`: the panel's, else the stored ones), written as files into
        `out_dir`-inputs beside it; `env`: where BAFFLE_GMSH and BAFFLE_PYTHON are taken
        from (default: the logic's child_env, else this process's environment)."""
        return planrun.PlanJob(self, curve, out_dir, parameters, single_mesh, self.child_env if env is None else env).start()

    def runPlan(self, curve, out_dir: str, timeout: Optional[float] = None, **kwargs) -> "planrun.PlanJob":
        """startPlan and wait for it (scripts, tests); the ended job says how it went."""
        job = self.startPlan(curve, out_dir, **kwargs)
        job.wait(timeout)
        return job

    def storePlan(self, curve, state: str, message: str, result, out_dir: str) -> None:
        """The latest whole plan's outcome onto the parameter node and the candidate's curve
        (when it is still in the scene), one ModifiedEvent each: the library's verdict, its
        text and reasons, dp, v_max and the threshold it judged against (PLAN_ATTRIBUTES); a
        cancelled or failed run leaves the previous plan's figures and says why in
        PlanStatus / PlanMessage."""
        values = {"PlanStatus": state, "PlanMessage": message, "PlanFolder": out_dir}
        if result is not None:
            values.update({
                "PlanVerdict": result.verdict,
                "PlanVerdictText": result.verdict_text,
                "PlanDpMmhg": repr(float(result.dp_mmhg)),
                "PlanVMaxMS": repr(float(result.v_max_m_s)),
                "PlanDpThresholdMmhg": repr(float(result.dp_threshold_mmhg)),
                "PlanReasons": "; ".join(result.reasons),
            })
        for node in (self.parameterNode(), curve):
            if node is None:
                continue
            with batched_modify(node):
                for name, value in values.items():
                    node.SetAttribute(ATTRIBUTE_PREFIX + name, str(value))

    # ---- candidates ---------------------------------------------------------------------

    def candidates(self) -> list:
        """Closed curve nodes of the scene that are BaffleDesigner candidates."""
        nodes = []
        collection = self.scene.GetNodesByClass("vtkMRMLMarkupsClosedCurveNode")
        for i in range(collection.GetNumberOfItems()):
            node = collection.GetItemAsObject(i)
            if node.GetAttribute(CANDIDATE_ATTRIBUTE) == "1":
                nodes.append(node)
        return nodes

    def updateCompareTable(self, simulation_note: str = "not simulated"):
        """One table of all candidates: target area, baffle area, smallest constrained
        section, RV volume left after the baffle, status, and the simulation's peak pressure difference, v_max and the
        library's verdict; dp and v_max stay empty (NaN) with `simulation_note` for candidates
        without a simulation result."""
        node = None
        collection = self.scene.GetNodesByClass("vtkMRMLTableNode")
        for i in range(collection.GetNumberOfItems()):
            candidate = collection.GetItemAsObject(i)
            if candidate.GetAttribute(ROLE_ATTRIBUTE) == "Compare":
                node = candidate
                break
        if node is None:
            node = slicer.vtkMRMLTableNode()
            node.SetName("BaffleDesigner candidates")
            node.SetAttribute(ROLE_ATTRIBUTE, "Compare")
            self.scene.AddNode(node)
        rows = self.candidates()
        table = vtk.vtkTable()
        name_column = vtk.vtkStringArray()
        name_column.SetName("Candidate")
        status_column = vtk.vtkStringArray()
        status_column.SetName("Status")
        simulation_column = vtk.vtkStringArray()
        simulation_column.SetName("Simulation")
        numeric = {
            "Target area": "TargetAreaMm2",
            "Baffle area": "BaffleAreaMm2",
            "Min section area": "MinSectionAreaMm2",
            "Constrained sections": "ConstrainedSections",
            "Max feasible area": "MaxFeasibleAreaMm2",  # set when the target is out of reach
            "RV after": "RvVolumeAfterMl",  # the capped ventricle's volume outside the pathway
            "BafflePlanner area": "BafflePlannerAreaMm2",  # compareWithBafflePlanner
            "Distance to BafflePlanner": "BafflePlannerMeanDistanceMm",
            "dp estimate": "DpEstimateMmhg",  # reduced-order, with the design (not CFD)
            "v_max estimate": "VMaxEstimateMS",
            "dp": "SimulationDpMmhg",
            "v_max": "SimulationMaxVelocityMS",
        }
        values = {column: [] for column in numeric}
        for curve in rows:
            name_column.InsertNextValue(curve.GetName())
            status = curve.GetAttribute(ATTRIBUTE_PREFIX + "Status") or "not designed"
            error = curve.GetAttribute(ATTRIBUTE_PREFIX + "Error")
            status_column.InsertNextValue(f"{status}: {error}" if error else status)
            simulation_column.InsertNextValue(self.simulationSummary(curve) or simulation_note)
            for column, attribute in numeric.items():
                text = curve.GetAttribute(ATTRIBUTE_PREFIX + attribute)
                values[column].append(float(text) if text else float("nan"))
        table.AddColumn(name_column)
        for column in numeric:
            table.AddColumn(vtk_double_array(column, values[column]))
        table.AddColumn(status_column)
        table.AddColumn(simulation_column)
        node.SetAndObserveTable(table)
        node.SetColumnUnitLabel("Distance to BafflePlanner", "mm")
        for column in ("Target area", "Baffle area", "Min section area", "Max feasible area", "BafflePlanner area"):
            node.SetColumnUnitLabel(column, "mm2")
        node.SetColumnUnitLabel("RV after", "mL")
        for column in ("dp", "dp estimate"):
            node.SetColumnUnitLabel(column, "mmHg")
        for column in ("v_max", "v_max estimate"):
            node.SetColumnUnitLabel(column, "m/s")
        return node

    @staticmethod
    def simulationSummary(curve) -> str:
        """'pass, steady (outdated)'-style text of the stored simulation result and the
        latest run when that did not complete; '' when never simulated."""
        attribute = lambda name: curve.GetAttribute(ATTRIBUTE_PREFIX + name)
        parts = []
        if attribute("SimulationVerdict"):
            parts.append(f"{attribute('SimulationVerdict')}, {attribute('SimulationMode')}")
            if attribute("SimulationStatus") == "outdated":
                parts[-1] += " (outdated: redesigned since)"
        last_run = attribute("SimulationLastRun")
        if last_run and last_run != "completed":
            parts.append(f"last run {last_run}")
        return "; ".join(parts)

    # ---- simulation (`baffle mesh` then `baffle simulate`, separate processes) -----------

    def startSimulation(self, curve, executable: Optional[str], work_dir: str, env: Optional[dict] = None):
        """Start meshing and simulating the candidate in work_dir; returns the running
        simulation.SimulationJob (poll() it from a timer). `env`: the child processes'
        environment (default: this process's). Raises BaffleDesignerError when it
        cannot start."""
        return simulation.SimulationJob(self, curve, executable, work_dir, env).start()

    # ---- volume mesh (the step before CFD; `baffle mesh` as a separate process) ----------

    def volumeMeshCommand(self, curve, executable: str, work_dir: str, edge_length_mm: float = 1.25) -> List[str]:
        """Write the candidate's domain (world coordinates) into work_dir and return the
        `baffle mesh` command line that meshes it into work_dir/volume.vtu. The boundary
        is remeshed at the edge length too: otherwise the design's finer surface
        triangles set the size near the wall (the phantom meshes the same at 1.25 and
        2 mm) and leave slivers (scaled Jacobian 0.003 against 0.15 remeshed)."""
        import os

        domain = curve.GetNodeReference(REF_DOMAIN)
        if domain is None or domain.GetPolyData() is None:
            raise BaffleDesignerError(f"{curve.GetName()}: design the baffle first (no domain model)")
        os.makedirs(work_dir, exist_ok=True)
        surface_path = os.path.join(work_dir, "domain.vtp")
        writer = vtk.vtkXMLPolyDataWriter()
        writer.SetFileName(surface_path)
        writer.SetInputData(domain.GetPolyData())
        if not writer.Write():
            raise BaffleDesignerError(f"could not write {surface_path}")
        return [
            executable, "mesh", "--surface", surface_path, "--out", os.path.join(work_dir, "volume.vtu"),
            "--edge-length-mm", repr(float(edge_length_mm)), "--remesh-surface",
        ]

    def loadVolumeMesh(self, curve, work_dir: str):
        """Load work_dir/volume.vtu (an unstructured grid, shown by a model node) and its
        quality figures (a table node) onto the candidate."""
        import json
        import os

        volume_path = os.path.join(work_dir, "volume.vtu")
        quality_path = os.path.join(work_dir, "volume-quality.json")
        grid = read_written_file(vtk.vtkXMLUnstructuredGridReader(), volume_path)
        if grid.GetNumberOfCells() == 0:
            raise BaffleDesignerError(f"{volume_path} holds no cells")
        node = self._output_node(curve, REF_VOLUME_MESH, "vtkMRMLModelNode", "volume mesh")
        node.SetAndObserveMesh(grid)
        with open(quality_path, encoding="utf-8") as handle:
            quality = json.load(handle)
        table_node = self._output_node(curve, REF_VOLUME_MESH_QUALITY, "vtkMRMLTableNode", "volume mesh quality")
        table = vtk.vtkTable()
        names = vtk.vtkStringArray()
        names.SetName("Measure")
        numbers = vtk.vtkDoubleArray()
        numbers.SetName("Value")
        for key, value in quality.items():
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                names.InsertNextValue(key)
                numbers.InsertNextValue(float(value))
        table.AddColumn(names)
        table.AddColumn(numbers)
        table_node.SetAndObserveTable(table)
        return node, table_node
