"""The ventricle from a segmentation node: Slicer exports the LV, RV and aorta segments'
closed surfaces (STL in LPS, as Slicer writes model files) into a work folder, `baffle
prepare --segmentations` joins, clips and caps them in a separate process, and the capped
ventricle (ModelFaceID 2 RV wall, 11 VSD cap, 16 aortic cap; written in the LPS frame of
its inputs) comes back into the scene (RAS) as a model node referenced from the candidate.

The prepared model is tagged with a fingerprint of its inputs (the three segments'
surfaces, the segmentation's transform to world and the chosen segment names), so a
redesign reuses it until the segmentation or the choice of segments changes."""

import hashlib
import json
import os
import shutil
import time
from typing import Dict, List, Optional

import numpy as np
import slicer
import vtk
from vtkmodules.util import numpy_support

from BaffleDesignerLib import candidate
from BaffleDesignerLib import process

# (structure, DesignParameters field naming its segment); the structure is also the file
# stem `baffle prepare --segmentations DIR` looks for (DIR/LV.stl, DIR/RV.stl, DIR/aorta.stl).
STRUCTURES = (("LV", "lv_segment"), ("RV", "rv_segment"), ("aorta", "aorta_segment"))
PREPARED_LABELS = {2, 11, 16}
OUTPUT_NAME = "capped_ventricle.vtp"
STAGE = "prepare"
FINGERPRINT_ATTRIBUTE = candidate.ATTRIBUTE_PREFIX + "PreparedFingerprint"
KILL_AFTER_S = 3.0
# LPS (files) <-> RAS (scene): x and y change sign; a rotation, so winding is kept.
LPS_RAS = (-1.0, -1.0, 1.0)


# ---- the segments ---------------------------------------------------------------------


def segment_id(segmentation_node, name: str, structure: str) -> str:
    """The ID of the segment called `name` (case-insensitive); the error names the
    structure, the name looked for and the segments there are."""
    segmentation = segmentation_node.GetSegmentation()
    names = []
    for i in range(segmentation.GetNumberOfSegments()):
        segment = segmentation.GetNthSegment(i)
        if segment.GetName().strip().lower() == name.strip().lower():
            return segmentation.GetNthSegmentID(i)
        names.append(segment.GetName())
    there = ", ".join(repr(n) for n in names) if names else "none"
    raise candidate.BaffleDesignerError(
        f"{segmentation_node.GetName()}: no segment named {name!r} for the {structure} (segments: {there}); "
        f"choose the {structure} segment"
    )


def segment_ids(segmentation_node, parameters: "candidate.DesignParameters") -> Dict[str, str]:
    """{structure: segment ID} for the LV, RV and aorta; each a different segment."""
    ids = {structure: segment_id(segmentation_node, getattr(parameters, field), structure) for structure, field in STRUCTURES}
    if len(set(ids.values())) < len(ids):
        chosen = ", ".join(f"{s} = {getattr(parameters, f)!r}" for s, f in STRUCTURES)
        raise candidate.BaffleDesignerError(f"{segmentation_node.GetName()}: LV, RV and aorta need three different segments ({chosen})")
    return ids


def closed_surfaces(segmentation_node, ids: Dict[str, str]) -> Dict[str, vtk.vtkPolyData]:
    """Each segment's closed-surface representation (made from the source representation
    if needed), in the segmentation's own coordinates; an empty one is an error."""
    if not segmentation_node.CreateClosedSurfaceRepresentation():
        raise candidate.BaffleDesignerError(f"{segmentation_node.GetName()}: could not make the closed-surface representation")
    surfaces = {}
    for structure, sid in ids.items():
        polydata = segmentation_node.GetClosedSurfaceInternalRepresentation(sid)
        if polydata is None or polydata.GetNumberOfPolys() == 0:
            name = segmentation_node.GetSegmentation().GetSegment(sid).GetName()
            raise candidate.BaffleDesignerError(f"{segmentation_node.GetName()}: the {structure} segment {name!r} is empty")
        surfaces[structure] = polydata
    return surfaces


def _world_transform_key(node) -> str:
    parent = node.GetParentTransformNode()
    if parent is None:
        return "identity"
    if parent.IsTransformToWorldLinear():
        matrix = vtk.vtkMatrix4x4()
        parent.GetMatrixTransformToWorld(matrix)
        return repr([matrix.GetElement(i, j) for i in range(4) for j in range(4)])
    return f"non-linear {parent.GetID()} {parent.GetMTime()}"


def fingerprint(segmentation_node, parameters: "candidate.DesignParameters") -> str:
    """A digest of what `baffle prepare` would be given: the chosen segments' surfaces,
    their transform to world and the segment names."""
    ids = segment_ids(segmentation_node, parameters)
    digest = hashlib.sha1(_world_transform_key(segmentation_node).encode())
    for structure, polydata in closed_surfaces(segmentation_node, ids).items():
        digest.update(f"{structure}={ids[structure]}".encode())
        digest.update(numpy_support.vtk_to_numpy(polydata.GetPoints().GetData()).tobytes())
        polys = polydata.GetPolys()
        for array in (polys.GetOffsetsArray(), polys.GetConnectivityArray()):
            digest.update(numpy_support.vtk_to_numpy(array).tobytes())
    return digest.hexdigest()


def export_segments(segmentation_node, ids: Dict[str, str], folder: str) -> None:
    """Slicer's own closed-surface export (world coordinates, LPS, STL) of each segment,
    renamed to the structure's file name that `baffle prepare --segmentations` reads."""
    os.makedirs(folder, exist_ok=True)
    logic = slicer.vtkSlicerSegmentationsModuleLogic
    for structure, sid in ids.items():
        staging = os.path.join(folder, f"export-{structure}")
        os.makedirs(staging, exist_ok=True)
        one = vtk.vtkStringArray()
        one.InsertNextValue(sid)
        if not logic.ExportSegmentsClosedSurfaceRepresentationToFiles(staging, segmentation_node, one, "STL", True, 1.0, False):
            raise candidate.BaffleDesignerError(f"{segmentation_node.GetName()}: exporting the {structure} segment to {staging} failed")
        written = [name for name in os.listdir(staging) if name.lower().endswith(".stl")]
        if len(written) != 1:
            raise candidate.BaffleDesignerError(f"exporting the {structure} segment wrote {written or 'nothing'} into {staging}")
        os.replace(os.path.join(staging, written[0]), os.path.join(folder, f"{structure}.stl"))
        os.rmdir(staging)


def prepare_command(executable: str, segmentations_dir: str, out_path: str) -> List[str]:
    return [executable, "prepare", "--segmentations", segmentations_dir, "--out", out_path]


# ---- the result -------------------------------------------------------------------------


def flip_lps_ras(polydata: vtk.vtkPolyData) -> vtk.vtkPolyData:
    """The same surface in the other of LPS and RAS (its own inverse)."""
    transform = vtk.vtkTransform()
    transform.Scale(*LPS_RAS)
    flip = vtk.vtkTransformPolyDataFilter()
    flip.SetTransform(transform)
    flip.SetInputData(polydata)
    flip.Update()
    return flip.GetOutput()


def read_prepared(path: str) -> vtk.vtkPolyData:
    """The capped ventricle `baffle prepare` wrote (LPS), checked, in RAS."""
    polydata = candidate.read_written_file(vtk.vtkXMLPolyDataReader(), path)
    labels = polydata.GetCellData().GetArray("ModelFaceID")
    if polydata.GetNumberOfPolys() == 0 or labels is None:
        raise candidate.BaffleDesignerError(f"{path}: expected a surface with a ModelFaceID cell array")
    found = set(int(v) for v in np.unique(numpy_support.vtk_to_numpy(labels)))
    if found != PREPARED_LABELS:
        raise candidate.BaffleDesignerError(f"{path}: labels {sorted(found)}, expected {sorted(PREPARED_LABELS)}")
    return flip_lps_ras(polydata)


def read_report(path: str) -> dict:
    try:
        with open(path, encoding="utf-8") as handle:
            return json.load(handle)
    except (OSError, ValueError) as error:
        raise candidate.BaffleDesignerError(f"{path}: {error}") from error


def _shared(logic, curve, node) -> bool:
    """Whether another candidate designs on `node` too."""
    return any(c is not curve and c.GetNodeReferenceID(candidate.REF_PREPARED) == node.GetID() for c in logic.candidates())


def store_prepared(logic, curve, segmentation_node, polydata, report: dict, digest: str):
    """The capped ventricle onto the candidate (REF_PREPARED model node, its figures as
    node attributes). A model that other candidates share is left to them."""
    node = curve.GetNodeReference(candidate.REF_PREPARED)
    if node is not None and _shared(logic, curve, node):
        curve.SetNodeReferenceID(candidate.REF_PREPARED, None)
        node = None
    if node is None or not node.IsA("vtkMRMLModelNode"):
        node = logic._output_node(curve, candidate.REF_PREPARED, "vtkMRMLModelNode", "capped ventricle")
        display = node.GetDisplayNode()
        if display is not None:
            display.SetColor(0.9, 0.6, 0.6)
            display.SetOpacity(0.4)
    node.SetAndObservePolyData(polydata)
    node.SetAttribute(FINGERPRINT_ATTRIBUTE, digest)
    node.SetAttribute(candidate.ATTRIBUTE_PREFIX + "PreparedFrom", segmentation_node.GetName())
    for name, value in (
        ("PrepareTriangles", report.get("triangles")),
        ("PrepareVsdCapAreaMm2", report.get("vsd_cap", {}).get("area_mm2")),
        ("PrepareAorticCapAreaMm2", report.get("aortic_cap", {}).get("area_mm2")),
        ("PrepareTimeMs", report.get("timings", {}).get("total_ms")),
    ):
        node.SetAttribute(candidate.ATTRIBUTE_PREFIX + name, str(value))
    return node


def _made_from(node, digest: str) -> bool:
    return node is not None and node.GetAttribute(FINGERPRINT_ATTRIBUTE) == digest and node.GetPolyData() is not None


def prepared_node(scene, curve, digest: str):
    """The capped ventricle made from the same inputs: the candidate's own, else one that
    another candidate on the same segmentation made (then referenced from this one too,
    so several candidates share one prepare run), else None."""
    own = curve.GetNodeReference(candidate.REF_PREPARED)
    if _made_from(own, digest):
        return own
    nodes = scene.GetNodesByClass("vtkMRMLModelNode")
    for i in range(nodes.GetNumberOfItems()):
        node = nodes.GetItemAsObject(i)
        if node.GetAttribute(candidate.ROLE_ATTRIBUTE) == candidate.REF_PREPARED and _made_from(node, digest):
            curve.SetNodeReferenceID(candidate.REF_PREPARED, node.GetID())
            return node
    return None


# ---- the job ------------------------------------------------------------------------------


class PrepareJob(candidate.CandidateJob):
    """`baffle prepare` for one candidate whose ventricle is a segmentation, without
    blocking: start() exports the segments and starts the process, poll() (from a timer)
    loads the capped ventricle when it is done, cancel() stops it. A failed or cancelled
    run leaves the scene as it was; the work folder is removed after a successful load."""

    def __init__(self, logic, curve, executable: Optional[str], work_dir: str, env: Optional[dict] = None):
        super().__init__(logic, curve, executable, work_dir, env)
        self.stage = STAGE
        self.node = None  # the loaded model node
        self._segmentation = None
        self._digest = ""

    def start(self) -> "PrepareJob":
        candidate.check_curve(self.curve)
        candidate.require_executable(self.executable)
        segmentation = self.logic.surfaceNode(self.curve)
        if segmentation is None or not segmentation.IsA("vtkMRMLSegmentationNode"):
            raise candidate.BaffleDesignerError(f"{self.curve.GetName()}: the ventricle is not a segmentation; nothing to prepare")
        parameters = self.logic.parameters(self.curve)
        ids = segment_ids(segmentation, parameters)
        self._digest = fingerprint(segmentation, parameters)
        self._segmentation = segmentation
        folder = os.path.join(self.work_dir, "segmentations")
        export_segments(segmentation, ids, folder)
        command = prepare_command(self.executable, folder, os.path.join(self.work_dir, OUTPUT_NAME))
        try:
            self.start_process(command, cwd=self.work_dir, env=self.env)
        except OSError as error:
            raise candidate.BaffleDesignerError(f"could not start {' '.join(command[:2])}: {error}") from error
        return self

    def cancel(self) -> None:
        self.cancel_process(KILL_AFTER_S)

    def poll(self) -> str:
        """Advance; call it from the GUI thread (it changes the scene at the end)."""
        if self.running and self.curve_removed():
            return self.stop_for_removed_curve()
        if not self.running or self.run.running:
            return self.state
        if self.run.state == process.CANCELLED:
            return self.finish(process.CANCELLED, f"{STAGE} cancelled; the ventricle is unchanged")
        if self.run.state == process.FAILED:
            return self.finish(process.FAILED, f"{STAGE} failed: {self.run.error_message()}")
        try:
            out_path = os.path.join(self.work_dir, OUTPUT_NAME)
            polydata = read_prepared(out_path)
            report = read_report(os.path.join(self.work_dir, "capped_ventricle-report.json"))
        except candidate.BaffleDesignerError as error:
            return self.finish(process.FAILED, str(error))
        self.node = store_prepared(self.logic, self.curve, self._segmentation, polydata, report, self._digest)
        shutil.rmtree(self.work_dir, ignore_errors=True)
        return self.finish(process.COMPLETED, self._result_line(report))

    def _result_line(self, report: dict) -> str:
        return (
            f"{self._segmentation.GetName()} prepared: {report.get('triangles')} triangles, "
            f"VSD cap {report['vsd_cap']['area_mm2']:.1f} mm2, aortic cap {report['aortic_cap']['area_mm2']:.1f} mm2 "
            f"({time.monotonic() - self.started_at:.1f} s)"
        )
