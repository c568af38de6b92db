"""What every step on one candidate shares: the names its state has in the scene (the
"BaffleDesigner.*" attributes and the "BaffleDesigner*" node references on its suture curve),
its parameters, the error shown to the user, the suture curve check and the base of its
command line jobs. The design (logic.py), the prepare step (prepare.py), the simulation
(simulation.py) and the rim capping (rims.py) all build on this module, and it on none of
them; logic.py re-exports these names, so `logic.REF_DOMAIN` and the like still work."""

import contextlib
import math
from dataclasses import dataclass, fields
from typing import Optional

import numpy as np
import vtk
from vtkmodules.util import numpy_support

from BaffleDesignerLib import environment, process

ATTRIBUTE_PREFIX = "BaffleDesigner."
CANDIDATE_ATTRIBUTE = ATTRIBUTE_PREFIX + "Candidate"
ROLE_ATTRIBUTE = ATTRIBUTE_PREFIX + "Role"

# Node reference roles on the suture curve node.
REF_SURFACE = "BaffleDesignerSurface"
REF_BAFFLE = "BaffleDesignerBaffleModel"
REF_DOMAIN = "BaffleDesignerDomainModel"
REF_CENTERLINE = "BaffleDesignerCenterline"
REF_SECTIONS = "BaffleDesignerSectionsModel"
REF_TABLE = "BaffleDesignerSectionsTable"
REF_CHART = "BaffleDesignerAreaChart"
REF_SERIES_FINAL = "BaffleDesignerSeriesFinalArea"
REF_SERIES_RAW = "BaffleDesignerSeriesRawArea"
REF_SERIES_TARGET = "BaffleDesignerSeriesTarget"
REF_PREPARED = "BaffleDesignerPreparedVentricle"  # capped ventricle made from a segmentation
REF_FLAT_TEMPLATE = "BaffleDesignerFlatTemplate"  # the baffle flattened at true scale
REF_VOLUME_MESH = "BaffleDesignerVolumeMesh"
# A plain RV model (no ModelFaceID, as BafflePlanner's) with the rims the user marks on it.
REF_VSD_RIM = "BaffleDesignerVsdRim"
REF_AORTIC_RIM = "BaffleDesignerAorticRim"
REF_RIM_CAPPED = "BaffleDesignerRimCappedVentricle"  # the capped ventricle made from them
REF_VOLUME_MESH_QUALITY = "BaffleDesignerVolumeMeshQuality"
# Simulation results (BaffleDesignerLib.simulation).
REF_SIM_SUMMARY = "BaffleDesignerSimulationSummary"
REF_SIM_FIELDS = "BaffleDesignerSimulationFields"
REF_SIM_SERIES_TABLE = "BaffleDesignerSimulationTimeSeries"
REF_SIM_CHART = "BaffleDesignerSimulationChart"
REF_SIM_SERIES_DP = "BaffleDesignerSeriesPressureDifference"
REF_SIM_SERIES_FLOW = "BaffleDesignerSeriesInflow"
REF_SIM_SECTION = "BaffleDesignerSimulationSection"  # the peak fields on a cross-section

# The roles of a candidate's outputs: they go with their curve.
OUTPUT_ROLES = (
    REF_BAFFLE, REF_DOMAIN, REF_CENTERLINE, REF_SECTIONS, REF_TABLE, REF_CHART, REF_SERIES_FINAL, REF_SERIES_RAW,
    REF_SERIES_TARGET, REF_PREPARED, REF_RIM_CAPPED, REF_FLAT_TEMPLATE, REF_VOLUME_MESH, REF_VOLUME_MESH_QUALITY, REF_SIM_SUMMARY,
    REF_SIM_FIELDS, REF_SIM_SECTION, REF_SIM_SERIES_TABLE, REF_SIM_CHART, REF_SIM_SERIES_DP, REF_SIM_SERIES_FLOW,
)
FOLDER_ATTRIBUTE = ATTRIBUTE_PREFIX + "CandidateCurve"  # on a candidate's subject hierarchy folder
FOLDER_SUFFIX = " BaffleDesigner"  # the folder is named after the curve

TARGET_MODES = ("bsa", "height_weight", "area", "diameter")
# "quick": pulsatile from rest to the first flow peak (`baffle simulate --quick`; within
# 0.6 % of the 4-cycle peak dp on p2 and p3's extended domains), the default;
# "steady": flow held at Q_peak (does not always converge: then inconclusive);
# "pulsatile": the paper's transient run over cardiac cycles.
FLOW_MODES = ("quick", "steady", "pulsatile")


class BaffleDesignerError(RuntimeError):
    """An error to show the user; str() carries the library's message where there is one."""


class DesignCancelled(BaffleDesignerError):
    """The design was cancelled (Cancel, or a progress callback that returned False)."""


@dataclass
class DesignParameters:
    """Target area and CFD conditions of one candidate, stored as curve node attributes.

    target_mode: "bsa" (BSA + z-score, Boston aortic annulus), "height_weight" (Haycock
    BSA + z-score), "area" (explicit mm2) or "diameter" (explicit annulus diameter mm).
    The CFD step uses the blood pressure, heart rate, cardiac index (CO = BSA x CI), the
    flow mode (FLOW_MODES) and the volume mesh edge length; its BSA is bsa_m2, or the
    Haycock BSA in the height_weight mode. When the ventricle is a segmentation node,
    lv_segment / rv_segment / aorta_segment name its segments (case-insensitive) that
    `baffle prepare` joins into the capped ventricle. flow_sections: the design also holds
    the tunnel's sections normal to the flow at the target (the library's flow-section
    rule, the command line's --flow-sections)."""

    target_mode: str = "bsa"
    bsa_m2: float = 0.37
    height_cm: float = 60.0
    weight_kg: float = 6.0
    z_score: float = 0.0
    target_area_mm2: float = 70.0
    annulus_diameter_mm: float = 9.4
    systolic_mmhg: float = 80.0
    diastolic_mmhg: float = 45.0
    heart_rate_bpm: float = 120.0
    cardiac_index_l_min_m2: float = 3.48  # the paper's normal cardiac index
    flow_mode: str = "quick"
    mesh_edge_length_mm: float = 1.25  # the coarsest of the paper's meshes (1.25 / 0.95 / 0.75)
    lv_segment: str = "LV"
    rv_segment: str = "RV"
    aorta_segment: str = "aorta"
    flow_sections: bool = False

    def validate(self) -> None:
        if self.target_mode not in TARGET_MODES:
            raise BaffleDesignerError(f"target mode must be one of {', '.join(TARGET_MODES)}, not {self.target_mode!r}")
        positive = {
            "bsa": ("bsa_m2",),
            "height_weight": ("height_cm", "weight_kg"),
            "area": ("target_area_mm2",),
            "diameter": ("annulus_diameter_mm",),
        }[self.target_mode]
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise BaffleDesignerError(f"{name} must be a positive number, not {value}")
        if not math.isfinite(self.z_score):
            raise BaffleDesignerError("z_score must be a finite number")
        for name in ("lv_segment", "rv_segment", "aorta_segment"):
            if not getattr(self, name).strip():
                raise BaffleDesignerError(f"{name} must name a segment")

    def cfd_bsa_m2(self) -> float:
        """The BSA the flow is scaled with: Haycock's from height and weight in that mode
        (the library's target.rs formula), else bsa_m2."""
        if self.target_mode == "height_weight":
            return 0.024265 * self.weight_kg**0.5378 * self.height_cm**0.3964
        return self.bsa_m2

    def validate_cfd(self) -> None:
        """What the GUI's CFD inputs need to be at all; their physiological consistency
        (DBP below SBP, ...) is the library's check when it writes the case (write_case)."""
        if self.flow_mode not in FLOW_MODES:
            raise BaffleDesignerError(f"flow mode must be one of {', '.join(FLOW_MODES)}, not {self.flow_mode!r}")
        for name in ("systolic_mmhg", "diastolic_mmhg", "heart_rate_bpm", "cardiac_index_l_min_m2", "mesh_edge_length_mm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise BaffleDesignerError(f"{name} must be a positive number, not {value}")
        bsa = self.cfd_bsa_m2()
        if not (math.isfinite(bsa) and bsa > 0):
            raise BaffleDesignerError(f"the BSA for the flow must be a positive number, not {bsa}")

    def design_kwargs(self) -> dict:
        """The arguments of baffle.design(): the target, and whether the flow-normal
        sections are held at it too."""
        return {**self._target_kwargs(), "flow_sections": bool(self.flow_sections)}

    def _target_kwargs(self) -> dict:
        self.validate()
        if self.target_mode == "bsa":
            return {"bsa_m2": self.bsa_m2, "z_score": self.z_score}
        if self.target_mode == "height_weight":
            return {"height_cm": self.height_cm, "weight_kg": self.weight_kg, "z_score": self.z_score}
        if self.target_mode == "area":
            return {"target_area_mm2": self.target_area_mm2}
        return {"annulus_diameter_mm": self.annulus_diameter_mm}

    def case_kwargs(self) -> dict:
        """The arguments of baffle.write_case() (the library writes the CFD case)."""
        self.validate_cfd()
        return {
            "bsa_m2": self.cfd_bsa_m2(),
            "sbp_mmhg": self.systolic_mmhg,
            "dbp_mmhg": self.diastolic_mmhg,
            "heart_rate_bpm": self.heart_rate_bpm,
            "cardiac_index_l_min_m2": self.cardiac_index_l_min_m2,
            "mode": self.flow_mode,
        }

    def write(self, node) -> None:
        with batched_modify(node):
            for f in fields(self):
                node.SetAttribute(ATTRIBUTE_PREFIX + f.name, str(getattr(self, f.name)))

    @classmethod
    def read(cls, node) -> "DesignParameters":
        """Parameters stored on the node; defaults for those it does not hold."""
        parameters = cls()
        for f in fields(cls):
            text = node.GetAttribute(ATTRIBUTE_PREFIX + f.name)
            if text is None:
                continue
            try:
                setattr(parameters, f.name, _attribute_value(f.type, text))
            except ValueError as error:
                raise BaffleDesignerError(f"{node.GetName()}: attribute {ATTRIBUTE_PREFIX + f.name} = {text!r}: {error}")
        return parameters


def library():
    """(baffle, baffle.vtk_adapters), imported on first use: the module must load, and its
    first-run check say what is missing, in a Slicer whose Python lacks the package."""
    try:
        import baffle
        from baffle import vtk_adapters
    except ImportError as error:
        raise BaffleDesignerError(f"the baffle Python package cannot be imported ({error}). {environment.install_hint()}") from error
    return baffle, vtk_adapters


def _attribute_value(kind, text: str):
    """A parameter from its node attribute text (as write() stores it)."""
    if kind in (str, "str"):
        return text
    if kind in (bool, "bool"):
        if text not in ("True", "False"):
            raise ValueError("not True or False")
        return text == "True"
    return float(text)


def require_executable(executable: Optional[str]) -> None:
    """Errors unless `executable` is the path of an executable file."""
    import os

    if not executable:
        raise BaffleDesignerError("the baffle command line program was not found (set BAFFLE_EXECUTABLE or put baffle on PATH)")
    if not (os.path.isfile(executable) and os.access(executable, os.X_OK)):
        raise BaffleDesignerError(f"the baffle command line program {executable} is not an executable file")


@contextlib.contextmanager
def batched_modify(node):
    """Hold back the node's ModifiedEvent until the block ends: one event for all the
    attribute and reference writes in it. BafflePlanner's logic rebuilds its baffle on
    every ModifiedEvent of its curve, and a design writes some 25 attributes there."""
    was_modifying = node.StartModify()
    try:
        yield node
    finally:
        node.EndModify(was_modifying)


def check_curve(curve) -> None:
    """Errors unless `curve` is a closed curve node (the candidate's suture points)."""
    if curve is None:
        raise BaffleDesignerError("select the suture points (a closed curve node)")
    if not curve.IsA("vtkMRMLMarkupsClosedCurveNode"):
        raise BaffleDesignerError(
            f"{curve.GetName()}: the suture points must be a closed curve (vtkMRMLMarkupsClosedCurveNode), "
            f"not {curve.GetClassName()}"
        )


def read_written_file(reader, path: str):
    """The output of a VTK reader for `path`, a file a child process was to write."""
    import os

    if not os.path.exists(path):
        raise BaffleDesignerError(f"{path} was not written")
    reader.SetFileName(path)
    reader.Update()
    return reader.GetOutput()


class CandidateJob(process.PolledJob):
    """A command line job for one candidate: the logic and curve it works for, the
    program, its work folder and its environment (None: this process's; in Slicer the
    startup environment, without the launcher's Python settings)."""

    def __init__(self, logic, curve, executable: Optional[str], work_dir: str, env: Optional[dict] = None):
        super().__init__()
        self.logic = logic
        self.curve = curve
        self.executable = executable
        self.work_dir = work_dir
        self.env = env

    def curve_removed(self) -> bool:
        """Whether the candidate's curve has left the scene (its results have nowhere to go)."""
        return self.logic.scene.GetNodeByID(self.curve.GetID()) is not self.curve

    def stop_for_removed_curve(self) -> str:
        """Cancel the running process and end the job: the curve was removed meanwhile."""
        self.cancel_process(3.0)
        return self.finish(process.CANCELLED, f"{self.curve.GetName()} was removed: the run was stopped, nothing loaded")


def vtk_double_array(name: str, values) -> vtk.vtkDoubleArray:
    array = numpy_support.numpy_to_vtk(np.ascontiguousarray(values, dtype=np.float64), deep=1)
    array.SetName(name)
    return array
