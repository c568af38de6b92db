"""Simulate one candidate: `baffle mesh` (gmsh) then `baffle simulate` (the CFD worker),
both as separate processes, on the case the library writes (the plan's own, through
baffle.write_case), driven without blocking: SimulationJob.poll() advances the
chain and is called from a QTimer in the widget (or a loop in tests). Results are read
and checked in full before any scene node changes, so a failed or cancelled run leaves
the candidate's earlier results (and its design outputs) as they were.

Units: `baffle simulate` writes peak.vtu in the scene's units: points mm, point arrays
velocity_m_s, speed_m_s and pressure_mmhg.
"""

import csv
import json
import math
import os
import re
import time
from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple

import numpy as np
import vtk

from BaffleDesignerLib import candidate
from BaffleDesignerLib import process

# The run's verdict on its dp, as `baffle simulate` writes it in summary.json (the
# library judges; this module only shows it), in the module's words.
VERDICT_WORDS = {"passes": "pass", "fails": "fail", "inconclusive": "inconclusive"}
# The point arrays of baffle simulate's peak.vtu (baffle_cfd::vtu).
FIELD_ARRAYS = {"velocity_m_s": 3, "speed_m_s": 1, "pressure_mmhg": 1}

MESH_STAGE, SIMULATE_STAGE = "volume mesh", "simulation"
# Grace period between SIGTERM and SIGKILL: gmsh has nothing to save; the CFD worker
# finishes its current step and writes the results so far.
KILL_AFTER_S = {MESH_STAGE: 3.0, SIMULATE_STAGE: 60.0}

# Summary table rows: (summary.json key, quantity, unit).
SUMMARY_ROWS = (
    ("dp_peak_mmhg", "Pressure difference at peak flow", "mmHg"),
    ("max_velocity_m_s", "Max velocity at peak flow", "m/s"),
    ("max_velocity_run_m_s", "Max velocity over the run", "m/s"),
    ("q_peak_ml_s", "Peak flow", "mL/s"),
    ("outlet_mean_pressure_mmhg", "Outlet pressure (mean over the run)", "mmHg"),
    ("mass_imbalance", "Mass imbalance", "fraction"),
    ("wall_time_s", "Wall time", "s"),
)
SUMMARY_INPUT_ROWS = (
    ("q_mean_ml_s", "Mean flow (BSA x cardiac index)", "mL/s"),
    ("resistance_dyn_s_cm5", "Outlet resistance", "dyn s/cm5"),
    ("map_mmhg", "Mean arterial pressure", "mmHg"),
    ("period_s", "Cardiac period", "s"),
)
COL_DP = "dp_mmhg"


# ---- the case file ------------------------------------------------------------------


# The volume mesh `baffle mesh` writes into the work folder (logic.volumeMeshCommand).
MESH_VOLUME, MESH_FACES = "volume.vtu", "volume-faces.vtp"


def write_case(work_dir: str, parameters: "candidate.DesignParameters") -> str:
    """The library writes the plan's `baffle simulate` case into work_dir (the one case
    definition, baffle-plan's: the designed domain's VSD cap in, aortic cap out, flow BSA x
    cardiac index, outlet resistance from SBP/DBP, the flow mode) for the volume mesh beside
    it, after checking it as `baffle simulate` will (e.g. DBP below SBP). Returns its path."""
    baffle, _ = candidate.library()
    try:
        return str(baffle.write_case(work_dir, mesh_volume=MESH_VOLUME, mesh_faces=MESH_FACES, **parameters.case_kwargs()))
    except baffle.BaffleError as error:
        raise candidate.BaffleDesignerError(f"the CFD case: {error}") from error


# ---- reading the results (no scene access) ---------------------------------------------


# summary.json's mode of each run, in the GUI's words (logic.FLOW_MODES).
GUI_MODES = {"quick": "quick", "steady": "steady", "transient": "pulsatile"}


@dataclass
class SimulationResults:
    """Everything loaded from one `baffle simulate` output directory, checked."""

    summary: dict
    dp_mmhg: float
    max_velocity_m_s: float
    fields: vtk.vtkUnstructuredGrid  # mm, velocity_m_s, speed_m_s, pressure_mmhg
    series: Dict[str, np.ndarray]  # timeseries.csv columns plus dp_mmhg
    series_order: List[str]

    @property
    def steady(self) -> bool:
        return self.summary.get("mode") == "steady"

    @property
    def mode(self) -> str:
        """The GUI's word for the run: quick, steady or pulsatile."""
        return GUI_MODES.get(self.summary.get("mode"), "pulsatile")

    @property
    def doubts(self) -> List[str]:
        return list(self.summary.get("doubts") or [])

    @property
    def verdict(self) -> str:
        """'pass', 'fail' or 'inconclusive': summary.json's verdict, the library's judgement
        of dp against its planning threshold given the run's doubts (checked on reading)."""
        return VERDICT_WORDS[self.summary["verdict"]]

    @property
    def dp_threshold_mmhg(self) -> float:
        return float(self.summary["dp_threshold_mmhg"])


def _finite(summary: dict, key: str, path: str) -> float:
    value = summary.get(key)
    if not isinstance(value, (int, float)) or not math.isfinite(value):
        raise candidate.BaffleDesignerError(f"{path}: {key} is {value!r}, not a finite number")
    return float(value)


def read_summary(path: str) -> dict:
    try:
        with open(path, encoding="utf-8") as handle:
            summary = json.load(handle)
    except (OSError, ValueError) as error:
        raise candidate.BaffleDesignerError(f"{path}: {error}") from error
    if summary.get("status") != "completed":
        raise candidate.BaffleDesignerError(
            f"{path}: the simulation {summary.get('status')}: {summary.get('message') or 'no message'}"
        )
    if summary.get("verdict") not in VERDICT_WORDS:
        raise candidate.BaffleDesignerError(
            f"{path}: no verdict ({summary.get('verdict')!r}); the baffle program is older than this module, update it"
        )
    _finite(summary, "dp_threshold_mmhg", path)
    return summary


def read_fields(path: str) -> vtk.vtkUnstructuredGrid:
    """peak.vtu as written (points mm, velocity_m_s vector, speed_m_s, pressure_mmhg), checked."""
    source = candidate.read_written_file(vtk.vtkXMLUnstructuredGridReader(), path)
    data = source.GetPointData()
    missing = [
        name for name, components in FIELD_ARRAYS.items()
        if data.GetArray(name) is None or data.GetArray(name).GetNumberOfComponents() != components
    ]
    if source.GetNumberOfCells() == 0 or missing:
        raise candidate.BaffleDesignerError(
            f"{path}: expected tetrahedra with point arrays {', '.join(FIELD_ARRAYS)}; missing or malformed: {', '.join(missing)}"
        )
    grid = vtk.vtkUnstructuredGrid()
    grid.DeepCopy(source)
    grid.GetPointData().SetActiveScalars("speed_m_s")
    grid.GetPointData().SetActiveVectors("velocity_m_s")
    return grid


def read_series(path: str, dp_faces) -> Tuple[Dict[str, np.ndarray], List[str]]:
    """timeseries.csv as numeric columns, plus dp_mmhg = p(first dp face) - p(second)."""
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except OSError as error:
        raise candidate.BaffleDesignerError(f"{path}: {error}") from error
    if len(rows) < 2:
        raise candidate.BaffleDesignerError(f"{path}: no time steps")
    header = rows[0]
    try:
        values = np.array([[float(v) for v in row] for row in rows[1:]], dtype=np.float64)
    except ValueError as error:
        raise candidate.BaffleDesignerError(f"{path}: {error}") from error
    series = {name: values[:, k] for k, name in enumerate(header)}

    def pressure_column(face_id):
        pattern = re.compile(rf"^p_.*_{face_id}_mmhg$")
        names = [name for name in header if pattern.match(name)]
        if len(names) != 1:
            raise candidate.BaffleDesignerError(f"{path}: no pressure column of face {face_id} in {header}")
        return series[names[0]]

    first, second = dp_faces
    series[COL_DP] = pressure_column(first) - pressure_column(second)
    return series, header + [COL_DP]


def _dp_faces(summary: dict, path: str) -> Tuple[int, int]:
    """The faces dp is measured between (summary.json's dp_faces: the case's)."""
    faces = summary.get("dp_faces")
    if not (isinstance(faces, list) and len(faces) == 2):
        raise candidate.BaffleDesignerError(f"{path}: dp_faces is {faces!r}, not two face ids")
    return int(faces[0]), int(faces[1])


def read_results(out_dir: str) -> SimulationResults:
    summary_path = os.path.join(out_dir, "summary.json")
    summary = read_summary(summary_path)
    series, order = read_series(os.path.join(out_dir, "timeseries.csv"), _dp_faces(summary, summary_path))
    return SimulationResults(
        summary=summary,
        dp_mmhg=_finite(summary, "dp_peak_mmhg", summary_path),
        max_velocity_m_s=_finite(summary, "max_velocity_m_s", summary_path),
        fields=read_fields(os.path.join(out_dir, "peak.vtu")),
        series=series,
        series_order=order,
    )


# ---- results into the scene -------------------------------------------------------------


def _summary_table(results: SimulationResults) -> vtk.vtkTable:
    quantity, unit = vtk.vtkStringArray(), vtk.vtkStringArray()
    quantity.SetName("Quantity")
    unit.SetName("Unit")
    values = []
    rows = [(results.summary, key, name, u) for key, name, u in SUMMARY_ROWS]
    rows += [(results.summary.get("inputs", {}), key, name, u) for key, name, u in SUMMARY_INPUT_ROWS]
    rows.append((results.summary, "dp_threshold_mmhg", "Planning threshold (pass below)", "mmHg"))
    for source, key, name, u in rows:
        value = source.get(key)
        quantity.InsertNextValue(name)
        unit.InsertNextValue(u)
        values.append(float(value) if isinstance(value, (int, float)) else float("nan"))
    table = vtk.vtkTable()
    table.AddColumn(quantity)
    table.AddColumn(candidate.vtk_double_array("Value", values))
    table.AddColumn(unit)
    return table


def _series_table(results: SimulationResults) -> vtk.vtkTable:
    table = vtk.vtkTable()
    for name in results.series_order:
        table.AddColumn(candidate.vtk_double_array(name, results.series[name]))
    return table


def _show_speed(display, opacity: float) -> None:
    if display is None:
        return
    display.SetActiveScalar("speed_m_s", vtk.vtkAssignAttribute.POINT_DATA)
    display.SetAndObserveColorNodeID("vtkMRMLColorTableNodeFileViridis.txt")
    display.SetScalarVisibility(True)
    display.SetOpacity(opacity)


def speed_section(fields: vtk.vtkUnstructuredGrid, centerline_node) -> Optional[vtk.vtkPolyData]:
    """The peak-flow fields on the cross-section at the middle of the centerline (plane
    normal to it there): the speed inside the pathway, which the wall (no slip: zero
    speed) hides on the outer surface. None without a centerline of 3 or more points."""
    if centerline_node is None or centerline_node.GetNumberOfControlPoints() < 3:
        return None
    count = centerline_node.GetNumberOfControlPoints()
    middle = count // 2
    at = lambda i: np.asarray(centerline_node.GetNthControlPointPositionWorld(i))
    tangent = at(middle + 1) - at(middle - 1)
    if not np.linalg.norm(tangent) > 0:
        return None
    _, vtk_adapters = candidate.library()
    # The pathway's section, not another crossing.
    section = vtk_adapters.plane_cut(fields, at(middle), tangent / np.linalg.norm(tangent), nearest=True)
    return section if section.GetNumberOfCells() > 0 else None


def store_results(logic, curve, results: SimulationResults, out_dir: str, outdated: bool = False) -> None:
    """The checked results onto the candidate: summary table, peak fields model, time
    series table and chart (node references on the curve), the verdict (attributes).
    `outdated`: the candidate was redesigned while it ran."""
    with candidate.batched_modify(curve):  # one ModifiedEvent on the curve (BafflePlanner observes it)
        summary_node = logic._output_node(curve, candidate.REF_SIM_SUMMARY, "vtkMRMLTableNode", "simulation summary")
        summary_node.SetAndObserveTable(_summary_table(results))
        summary_node.SetAttribute(candidate.ATTRIBUTE_PREFIX + "Verdict", results.verdict)

        fields_node = logic._output_node(curve, candidate.REF_SIM_FIELDS, "vtkMRMLModelNode", "peak flow fields")
        fields_node.SetAndObserveMesh(results.fields)
        _show_speed(fields_node.GetDisplayNode(), opacity=0.5)
        display = fields_node.GetDisplayNode()
        if display is not None:
            display.SetVisibility2D(True)  # the slice views cut the volume: speed inside, not only at the wall
        section = speed_section(results.fields, curve.GetNodeReference(candidate.REF_CENTERLINE))
        if section is not None:
            section_node = logic._output_node(curve, candidate.REF_SIM_SECTION, "vtkMRMLModelNode", "peak flow section")
            section_node.SetAndObservePolyData(section)
            _show_speed(section_node.GetDisplayNode(), opacity=1.0)

        series_node = logic._output_node(curve, candidate.REF_SIM_SERIES_TABLE, "vtkMRMLTableNode", "simulation time series")
        series_node.SetAndObserveTable(_series_table(results))
        _write_series_chart(logic, curve, series_node, results)

        for name, value in (
            ("SimulationStatus", "outdated" if outdated else "completed"),
            ("SimulationDpMmhg", results.dp_mmhg),
            ("SimulationMaxVelocityMS", results.max_velocity_m_s),
            ("SimulationVerdict", results.verdict),
            ("SimulationMode", results.mode),  # the GUI's words
            ("SimulationConverged", "1" if results.summary.get("converged") else "0"),
            ("SimulationDir", out_dir),
        ):
            curve.SetAttribute(candidate.ATTRIBUTE_PREFIX + name, str(value))


CHART_TITLES = {"quick": "from rest to the first flow peak", "steady": "steady solve at peak flow", "pulsatile": "pulsatile run"}


def _write_series_chart(logic, curve, table_node, results) -> None:
    chart = logic._output_node(curve, candidate.REF_SIM_CHART, "vtkMRMLPlotChartNode", "simulation chart")
    x_column, x_title = ("step", "iteration") if results.steady else ("time_s", "t (s)")
    chart.SetTitle(f"{curve.GetName()}: {CHART_TITLES[results.mode]}")
    chart.SetXAxisTitle(x_title)
    chart.SetYAxisTitle("dp (mmHg), Q (mL/s)")
    styles = (
        (candidate.REF_SIM_SERIES_DP, COL_DP, (0.85, 0.25, 0.2)),
        (candidate.REF_SIM_SERIES_FLOW, "inflow_ml_s", (0.2, 0.5, 0.95)),
    )
    for role, column, color in styles:
        series = logic._output_node(curve, role, "vtkMRMLPlotSeriesNode", column)
        series.SetAndObserveTableNodeID(table_node.GetID())
        series.SetXColumnName(x_column)
        series.SetYColumnName(column)
        series.SetPlotType(series.PlotTypeScatter)
        series.SetMarkerStyle(series.MarkerStyleNone)
        series.SetColor(*color)
        if not chart.HasPlotSeriesNodeID(series.GetID()):
            chart.AddAndObservePlotSeriesNodeID(series.GetID())


# ---- the job: mesh, then simulate -------------------------------------------------------


class SimulationJob(candidate.CandidateJob):
    """Mesh and simulate one candidate in `work_dir` without blocking. start() checks the
    inputs and starts `baffle mesh`; poll() (from a timer) starts `baffle simulate` when
    the mesh is done and loads the results when the simulation is; cancel() stops the
    running process. `state` is process.RUNNING / COMPLETED / FAILED / CANCELLED,
    `message` says what happened (the program's own error line on failure)."""

    def __init__(self, logic, curve, executable: Optional[str], work_dir: str, env: Optional[dict] = None):
        super().__init__(logic, curve, executable, work_dir, env)
        self.out_dir = os.path.join(work_dir, "results")
        self.results: Optional[SimulationResults] = None
        self._case_path: Optional[str] = None
        self._domain = None  # the domain polydata that was meshed
        self._cancel_requested = False
        self.simulate_started_at = 0.0

    def start(self) -> "SimulationJob":
        """Raises BaffleDesignerError when the run cannot start (no executable, no
        design, bad parameters); nothing in the scene changes then."""
        candidate.check_curve(self.curve)
        candidate.require_executable(self.executable)
        domain = self.curve.GetNodeReference(candidate.REF_DOMAIN)
        if domain is None or domain.GetPolyData() is None:
            raise candidate.BaffleDesignerError(f"{self.curve.GetName()}: design the baffle first (no domain model)")
        parameters = self.logic.parameters(self.curve)
        self._case_path = write_case(self.work_dir, parameters)
        self._domain = (domain.GetPolyData(), domain.GetPolyData().GetMTime())
        command = self.logic.volumeMeshCommand(self.curve, self.executable, self.work_dir, parameters.mesh_edge_length_mm)
        self._start_stage(MESH_STAGE, command)
        return self

    def _start_stage(self, stage: str, command: List[str]) -> None:
        self.stage = stage
        try:
            self.start_process(command, cwd=self.work_dir, env=self.env)
        except OSError as error:
            raise candidate.BaffleDesignerError(f"could not start the {stage}: {error}") from error

    @property
    def progress(self) -> Optional[float]:
        """Fraction of the simulation done; None while meshing (gmsh reports no fractions)."""
        if self.stage == SIMULATE_STAGE and self.run is not None:
            return self.run.progress
        return None

    def cancel(self) -> None:
        if self.running:
            self._cancel_requested = True
            self.run.cancel(kill_after=KILL_AFTER_S[self.stage])

    def poll(self) -> str:
        """Advance the chain; call it from the GUI thread (it changes the scene at the end)."""
        if self.running and self.curve_removed():
            return self.stop_for_removed_curve()
        if not self.running or self.run.running:
            return self.state
        run = self.run
        if run.state == process.CANCELLED or self._cancel_requested:
            return self._finish(process.CANCELLED, f"{self.stage} cancelled; the earlier results are unchanged")
        if run.state == process.FAILED:
            return self._finish(process.FAILED, f"{self.stage} failed: {run.error_message()}")
        try:
            if self.stage == MESH_STAGE:
                self._start_simulation()
                return self.state
            self.results = read_results(self.out_dir)
        except candidate.BaffleDesignerError as error:
            return self._finish(process.FAILED, str(error))
        store_results(self.logic, self.curve, self.results, self.out_dir, outdated=self._redesigned())
        return self._finish(process.COMPLETED, self._result_line())

    def _result_line(self) -> str:
        results = self.results
        line = (
            f"dp {results.dp_mmhg:.2f} mmHg ({results.verdict}: threshold {results.dp_threshold_mmhg:g} mmHg), "
            f"v_max {results.max_velocity_m_s:.2f} m/s"
        )
        if results.doubts:
            line += "; inconclusive because " + "; ".join(results.doubts)
        if self._redesigned():
            line += "; the baffle was redesigned meanwhile, so these results are outdated"
        return line

    def _redesigned(self) -> bool:
        """Whether the candidate's domain changed since it was meshed (a redesign while running)."""
        node = self.curve.GetNodeReference(candidate.REF_DOMAIN)
        polydata = node.GetPolyData() if node is not None else None
        return polydata is not self._domain[0] or polydata.GetMTime() != self._domain[1]

    def _start_simulation(self) -> None:
        self.simulate_started_at = time.monotonic()
        self._start_stage(SIMULATE_STAGE, [self.executable, "simulate", self._case_path, "--out", self.out_dir, "--progress-tags"])

    def _finish(self, state: str, message: str) -> str:
        # The outcome of the latest run; the stored results change only on completion.
        last_run = state if state == process.COMPLETED else f"{state}: {message}"
        self.curve.SetAttribute(candidate.ATTRIBUTE_PREFIX + "SimulationLastRun", last_run)
        return self.finish(state, message)
