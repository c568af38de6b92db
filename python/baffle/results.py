"""Readers of the command line's outputs, so a script gets numbers and arrays without
writing VTK code: `read_report` (a `baffle plan` report.json, with its three-state
verdict), `read_fields` (a `baffle simulate` peak.vtu / final.vtu: mm, m/s, mmHg),
`read_points` (suture points: .mrk.json, .fcsv, .csv, through the library's reader) and `read_surface` (a labelled
.vtp/.vtk/.stl as a `Mesh`). `read_fields` and `read_surface` need the `vtk` module.

    import baffle
    report = baffle.read_report("out/plan")          # the folder or its report.json
    print(report.verdict, report.reason, report.dp_peak_mmhg)
    fields = baffle.read_fields("out/plan/simulate-nominal/peak.vtu")
    fields["speed_m_s"].max()
"""

import ctypes
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional

import numpy as np

from . import _lib
from .design import Mesh

VERDICTS = ("passes", "fails", "inconclusive")
# The point arrays `baffle simulate` writes (baffle_cfd::vtu), with their components.
FIELD_ARRAYS = {"velocity_m_s": 3, "speed_m_s": 1, "pressure_mmhg": 1}


@dataclass
class PlanReport:
    """A completed plan's report.json: the verdict ("passes", "fails" or "inconclusive",
    with `reason` when inconclusive), the paper's quantities by their report.json keys,
    the centerline profile as arrays (NaN where a point was not sampled; pressures
    relative to the aortic plane's mean at peak flow) and the whole document as `raw`."""

    verdict: str
    reason: Optional[str]
    dp_peak_mmhg: float
    threshold_mmhg: float
    warnings: List[str]
    quantities: Dict[str, Optional[float]]
    centerline: Dict[str, np.ndarray]
    path: Path
    raw: dict = field(repr=False)

    @property
    def passes(self) -> bool:
        """True only for a trusted run below the threshold (never when inconclusive)."""
        return self.verdict == "passes"


def _report_path(path) -> Path:
    path = Path(path)
    return path / "report.json" if path.is_dir() else path


def _array(values) -> np.ndarray:
    return np.array([math.nan if v is None else float(v) for v in values], dtype=np.float64)


def read_report(path) -> PlanReport:
    """The report.json of `baffle plan` (give the file or the plan's --out folder). A
    plan that stopped at a failed stage raises ValueError naming the stage and its error."""
    path = _report_path(path)
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise ValueError(f"{path}: {error}") from error
    if document.get("status") != "completed":
        raise ValueError(
            f"{path}: the plan did not complete: stage {document.get('failed_stage')} failed: {document.get('error')}"
        )
    verdict = document.get("verdict", {})
    if verdict.get("verdict") not in VERDICTS:
        raise ValueError(f"{path}: no three-state verdict (verdict.verdict is {verdict.get('verdict')!r}); written by an older baffle?")
    line = document.get("centerline", {})
    arrays = ("s_mm", "pressure_rel_aortic_plane_mmhg", "speed_m_s")
    return PlanReport(
        verdict=verdict["verdict"],
        reason=verdict.get("reason"),
        dp_peak_mmhg=float(verdict["dp_peak_mmhg"]),
        threshold_mmhg=float(verdict["threshold_mmhg"]),
        warnings=list(verdict.get("warnings", [])),
        quantities=dict(document.get("quantities", {})),
        centerline={name: _array(line.get(name, [])) for name in arrays},
        path=path,
        raw=document,
    )


def read_fields(path) -> Dict[str, np.ndarray]:
    """A `baffle simulate` result (.vtu) as arrays: points_mm (n, 3), tetrahedra (m, 4),
    velocity_m_s (n, 3), speed_m_s (n,), pressure_mmhg (n,). Needs `vtk`."""
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

    from .render import read_with

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: file not found")
    grid = read_with(vtkXMLUnstructuredGridReader, path)
    data = grid.GetPointData()
    missing = [n for n, c in FIELD_ARRAYS.items() if data.GetArray(n) is None or data.GetArray(n).GetNumberOfComponents() != c]
    if grid.GetNumberOfPoints() == 0 or missing:
        raise ValueError(f"{path}: not a baffle simulate result: missing point arrays {', '.join(missing) or '(no points)'}")
    cells = numpy_support.vtk_to_numpy(grid.GetCells().GetConnectivityArray()).astype(np.int64)
    fields = {"points_mm": numpy_support.vtk_to_numpy(grid.GetPoints().GetData()).astype(np.float64), "tetrahedra": cells.reshape(-1, 4)}
    for name, components in FIELD_ARRAYS.items():
        values = numpy_support.vtk_to_numpy(data.GetArray(name)).astype(np.float64)
        fields[name] = values.reshape(-1, 3) if components == 3 else values
    return fields


def read_points(path, frame: str = "LPS") -> np.ndarray:
    """Suture points (n, 3) in mm, in `frame` ("LPS", as Slicer writes models, or "RAS"),
    from a Slicer markups file (.mrk.json), a Slicer .fcsv, a .csv/.txt of x,y,z or a
    JSON list, read by the library's own reader (the one `baffle design` uses)."""
    frame = frame.upper()
    if frame not in _lib.FRAMES:
        raise ValueError(f"frame must be LPS or RAS, not {frame!r}")
    points, length = ctypes.POINTER(ctypes.c_double)(), ctypes.c_size_t()
    _lib.check(_lib.lib.baffle_read_suture_points(str(path).encode(), _lib.FRAMES[frame], ctypes.byref(points), ctypes.byref(length)))
    try:
        return np.ctypeslib.as_array(points, shape=(length.value,)).reshape(-1, 3).copy()
    finally:
        _lib.lib.baffle_free(ctypes.cast(points, ctypes.c_void_p))


def read_surface(path, label_array: str = "ModelFaceID") -> Mesh:
    """A closed, labelled triangle surface (.vtp, .vtk or .stl; mm) as a `Mesh` for
    `baffle.design`. Needs `vtk`; an .stl has no labels, so it is refused."""
    from vtkmodules.vtkFiltersCore import vtkTriangleFilter
    from vtkmodules.vtkIOLegacy import vtkPolyDataReader
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    from .vtk_adapters import polydata_to_mesh

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: file not found")
    readers = {".vtp": vtkXMLPolyDataReader, ".vtk": vtkPolyDataReader}
    reader_class = readers.get(path.suffix.lower())
    if reader_class is None:
        raise ValueError(f"{path}: needs a labelled surface (.vtp or .vtk with cell array {label_array}); "
                         "for an .stl use `baffle design --vsd-cap-point/--aortic-cap-point`")
    reader = reader_class()
    reader.SetFileName(str(path))
    triangles = vtkTriangleFilter()
    triangles.SetInputConnection(reader.GetOutputPort())
    triangles.Update()
    try:
        return polydata_to_mesh(triangles.GetOutput(), label_array)
    except ValueError as error:
        raise ValueError(f"{path}: {error}") from error
