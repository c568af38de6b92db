"""Run the whole plan of one candidate through the library (baffle.plan: [prepare ->]
design -> centerline -> mesh -> simulate -> report), as `baffle plan` runs it, without
blocking the GUI: PlanJob.start() writes the scene's inputs to files (the ventricle and
the suture points in LPS, as Slicer writes model and markups files, or the segmentation's
LV, RV and aorta surfaces as the prepare step exports them), baffle.plan runs on a worker
thread (the ctypes call releases the GIL) and poll(), called from the widget's timer (or a
loop in tests), takes the result once it is done. progress / stage follow the library's
progress callback; cancel() makes the library's cancel callback say stop, which it asks
between the stages and while the design and the simulation run: the stages finished
before keep their folders.

The verdict, dp, v_max and threshold are the library's PlanResult: this module shows and
stores them and has no threshold or rule of its own. `state` is process.RUNNING /
COMPLETED / FAILED / CANCELLED, `message` says what happened (the library's message on
failure)."""

import os
import re
from typing import Optional

import numpy as np
import slicer
import vtk

from BaffleDesignerLib import candidate, prepare, process

# What the parameter node and the candidate's curve keep of the latest whole plan
# (attribute name after candidate.ATTRIBUTE_PREFIX).
PLAN_ATTRIBUTES = ("PlanStatus", "PlanVerdict", "PlanVerdictText", "PlanDpMmhg", "PlanVMaxMS",
                   "PlanDpThresholdMmhg", "PlanReasons", "PlanFolder", "PlanMessage")
SURFACE_NAME, POINTS_NAME, SEGMENTATIONS_NAME = "capped_ventricle.vtp", "suture_points.mrk.json", "segmentations"
# The gmsh and Python the library's mesh stage and pictures run (baffle-mesh's gmsh.rs
# reads them from the process environment): the child processes' ones, as for Simulate.
LIBRARY_ENV = ("BAFFLE_GMSH", "BAFFLE_PYTHON")


def folder_name(curve_name: str) -> str:
    """A file name from the curve's name (the plan's folder, shown as "plan <name>")."""
    return re.sub(r"[^A-Za-z0-9._-]+", "-", curve_name).strip("-") or "candidate"


def plan_kwargs(parameters: "candidate.DesignParameters", single_mesh: bool, patient_label: str) -> dict:
    """baffle.plan()'s options from the candidate's parameters: the CFD inputs as Simulate
    uses them (bsa_m2 is the flow's: the BSA, or Haycock's from height and weight), and the
    panel's target as the live design uses it (design_kwargs): the z-score of the BSA's
    annulus, or the explicit area or diameter (the plan's --z-score, --target-area-mm2,
    --annulus-diameter-mm). Height and weight reach the plan as their Haycock BSA, the
    design's own formula, so the annulus is the same."""
    target = plan_target(parameters)
    case = parameters.case_kwargs()  # checks the CFD inputs as Simulate does
    return {
        **case,
        **target,
        "edge_length_mm": parameters.mesh_edge_length_mm,
        "single_mesh": bool(single_mesh),
        "flow_sections": bool(parameters.flow_sections),
        "patient_label": patient_label,
    }


# The live design's target arguments the plan takes as its own (the body size is the flow's
# bsa_m2 there).
PLAN_TARGET_KEYS = ("z_score", "target_area_mm2", "annulus_diameter_mm")


def plan_target(parameters: "candidate.DesignParameters") -> dict:
    """The design's target (validated) as baffle.plan's target arguments."""
    target = parameters.design_kwargs()
    return {key: float(target[key]) for key in PLAN_TARGET_KEYS if key in target}


def write_surface_lps(polydata: vtk.vtkPolyData, path: str) -> str:
    """The capped ventricle (world RAS) as an LPS .vtp, as Slicer writes model files and the
    plan reads them (its surface frame is LPS), labels included."""
    writer = vtk.vtkXMLPolyDataWriter()
    writer.SetFileName(path)
    writer.SetInputData(prepare.flip_lps_ras(polydata))
    if not writer.Write():
        raise candidate.BaffleDesignerError(f"could not write {path}")
    return path


def write_points(points_world: np.ndarray, path: str, name: str) -> str:
    """The suture points (world RAS) as a closed-curve .mrk.json, by Slicer's own markups
    writer (which stores LPS and says so; the plan converts to its surface frame)."""
    curve = slicer.vtkMRMLMarkupsClosedCurveNode()
    curve.SetName(name)
    for p in points_world:
        curve.AddControlPoint(float(p[0]), float(p[1]), float(p[2]))
    storage = slicer.vtkMRMLMarkupsJsonStorageNode()
    storage.SetFileName(path)
    if not storage.WriteData(curve):
        raise candidate.BaffleDesignerError(f"could not write {path}")
    return path


class PlanJob(process.LibraryJob):
    """One candidate's whole plan through the library into `out_dir`, without blocking
    (process.LibraryJob); `result` is the baffle.PlanResult once completed. cancel()
    reaches the library through baffle.plan's `cancel`."""

    what = "plan"

    def __init__(self, logic, curve, out_dir: str, parameters=None, single_mesh: bool = False, env: Optional[dict] = None):
        super().__init__(logic, curve, "inputs")
        self.out_dir = out_dir
        self.inputs_dir = out_dir + "-inputs"
        self.given_parameters = parameters
        self.single_mesh = single_mesh
        self.env = env  # the child processes' environment: BAFFLE_GMSH / BAFFLE_PYTHON from it

    # ---- the inputs, on the caller's (GUI) thread -----------------------------------------

    def _inputs(self) -> dict:
        candidate.check_curve(self.curve)
        logic = self.logic
        parameters = self.given_parameters if self.given_parameters is not None else logic.parameters(self.curve)
        kwargs = plan_kwargs(parameters, self.single_mesh, self.curve.GetName())
        os.makedirs(self.inputs_dir, exist_ok=True)
        kwargs["points"] = write_points(logic.suturePointsWorld(self.curve), os.path.join(self.inputs_dir, POINTS_NAME), self.curve.GetName())
        surface = logic.surfaceNode(self.curve)
        if surface is not None and surface.IsA("vtkMRMLSegmentationNode"):
            # The plan prepares it itself and runs the CFD on the extended domain.
            folder = os.path.join(self.inputs_dir, SEGMENTATIONS_NAME)
            prepare.export_segments(surface, prepare.segment_ids(surface, parameters), folder)
            kwargs["segmentations"] = folder
        else:
            model = logic.ventricleModel(self.curve, allow_prepare=False)  # a plain RV model: capped at its rims
            kwargs["surface"] = write_surface_lps(logic.surfacePolyDataWorld(model), os.path.join(self.inputs_dir, SURFACE_NAME))
        return kwargs

    def start(self) -> "PlanJob":
        """Read the inputs and start the library; a bad input ends the job FAILED at once
        (nothing in the scene changes)."""
        self.state = process.RUNNING
        try:
            kwargs = self._inputs()
        except (candidate.BaffleDesignerError, OSError) as error:
            self._end(process.FAILED, f"the plan could not start: {error}")
            return self
        self.start_worker(kwargs)
        return self

    # ---- the library, on the worker thread ------------------------------------------------

    def _report(self, fraction, stage) -> bool:
        super()._report(fraction, stage)
        return True  # cancelling goes through baffle.plan's own `cancel`

    def _work(self, kwargs) -> None:
        baffle, _ = candidate.library()
        saved = {name: os.environ.get(name) for name in LIBRARY_ENV}
        try:
            for name in LIBRARY_ENV:
                if self.env and self.env.get(name):
                    os.environ[name] = self.env[name]
            self._outcome = baffle.plan(self.out_dir, progress=self._report, cancel=self._cancel.is_set, **kwargs)
        except Exception as error:  # Cancelled, BaffleError (the library's message), or a bug: ends the job
            self._outcome = error
        finally:
            for name, value in saved.items():
                if value is None:
                    os.environ.pop(name, None)
                else:
                    os.environ[name] = value

    # ---- the end, on the caller's thread --------------------------------------------------

    def ended(self, outcome) -> str:
        """The result stored here and on the candidate, or why there is none."""
        baffle, _ = candidate.library()
        if isinstance(outcome, baffle.Cancelled):
            return self._end(process.CANCELLED, f"{outcome}; the finished stages are kept in {self.out_dir}")
        if isinstance(outcome, baffle.BaffleError):
            kept = f" (its folder: {self.out_dir})" if os.path.isdir(self.out_dir) else ""
            return self._end(process.FAILED, f"the plan failed: {outcome}{kept}")
        if isinstance(outcome, BaseException):
            return self._end(process.FAILED, f"the plan failed: {type(outcome).__name__}: {outcome}")
        self.result = outcome
        return self._end(process.COMPLETED, result_line(outcome))

    def _end(self, state: str, message: str) -> str:
        self.state, self.message = state, message
        self.logic.storePlan(self.curve if self._curve_in_scene() else None, state, message, self.result, self.out_dir)
        return state

    def _curve_in_scene(self) -> bool:
        return self.curve is not None and self.logic.scene.GetNodeByID(self.curve_id or "") is self.curve


def result_line(result) -> str:
    """The library's verdict in one line, marked as the library's: its text (PASSES / FAILS /
    INCONCLUSIVE and why), the dp and v_max it judged and the threshold it judged against."""
    line = (
        f"the library's verdict: {result.verdict_text} "
        f"(dp {result.dp_mmhg:.2f} mmHg against its threshold {result.dp_threshold_mmhg:g} mmHg, "
        f"v_max {result.v_max_m_s:.2f} m/s)"
    )
    return line
