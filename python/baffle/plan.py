"""baffle.plan(): the whole plan (design, centerline, mesh, simulate, report) through the
library, as `baffle plan` runs it, with its verdict as a `PlanResult`; and
baffle.write_case(): the CFD case the plan simulates, for a caller that meshes and runs
`baffle simulate` itself (the Slicer module), so the case is defined once, in the library.

    import baffle
    result = baffle.plan("out/plan", phantom=True, sbp_mmhg=107, dbp_mmhg=78, mode="quick",
                         single_mesh=True, edge_length_mm=1.25,
                         progress=lambda fraction, stage: print(f"{fraction:.0%} {stage}"))
    result.verdict, result.dp_mmhg, result.dp_threshold_mmhg, result.report_html
"""

from ctypes import byref, c_double, c_int32, c_size_t, c_void_p
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, List, Optional

from . import _lib
from ._lib import check, lib, take_string
from .design import Progress, _ProgressBridge

# () -> stop now? Asked between the stages and while the design and the simulation run.
Cancel = Callable[[], bool]


@dataclass
class PlanResult:
    """A finished plan: the verdict on the nominal run's peak pressure difference against
    the planning threshold ("passes", "fails", or "inconclusive" with its `reasons`), the
    numbers it judged, and where the report is."""

    verdict: str
    dp_mmhg: float
    v_max_m_s: float
    dp_threshold_mmhg: float
    reasons: List[str]
    verdict_text: str
    report_json: Path
    report_html: Path

    @property
    def passes(self) -> bool:
        """True only for a trusted run below the threshold (never when inconclusive)."""
        return self.verdict == "passes"


class _CancelBridge:
    """Asks the Python callable from C; an exception it raises stops the plan and is
    re-raised once the call has returned (it cannot cross the C ABI)."""

    def __init__(self, cancel: Optional[Cancel]):
        self.cancel = cancel
        self.error: Optional[BaseException] = None
        self.c_function = _lib.CANCEL(self._call) if cancel else _lib.CANCEL()

    def _call(self, _user):
        try:
            return 1 if self.cancel() else 0
        except BaseException as error:  # noqa: BLE001 - re-raised after the call
            self.error = error
            return 1


def _encoded(path) -> Optional[bytes]:
    return None if path is None else str(path).encode("utf-8")


def _plan_options(paths: dict, values: dict, mode: str) -> _lib.PlanOptions:
    """The library's plan defaults with the given paths and values (None keeps a default)."""
    options = _lib.default_plan_options()
    if mode not in _lib.PLAN_MODES:
        raise ValueError(f"mode must be one of {sorted(_lib.PLAN_MODES)}, not {mode!r}")
    options.mode = _lib.PLAN_MODES[mode]
    for name, path in paths.items():
        setattr(options, name, _encoded(path))
    for name, value in values.items():
        if value is not None:
            setattr(options, name, value)
    return options


def _flow_values(bsa_m2, sbp_mmhg, dbp_mmhg, heart_rate_bpm, cardiac_index_l_min_m2, cycles) -> dict:
    """The options the CFD case is made from (None keeps the library's default)."""
    return {
        "bsa_m2": bsa_m2,
        "sbp_mmhg": float(sbp_mmhg),
        "dbp_mmhg": float(dbp_mmhg),
        "heart_rate_bpm": heart_rate_bpm,
        "cardiac_index_l_min_m2": cardiac_index_l_min_m2,
        "cycles": cycles,
    }


def _result(handle) -> PlanResult:
    verdict, count = c_int32(), c_size_t()
    numbers = {name: c_double() for name in ("dp_mmhg", "v_max_m_s", "dp_threshold_mmhg")}
    check(lib.baffle_plan_result_verdict(handle, byref(verdict)))
    for name, value in numbers.items():
        check(getattr(lib, f"baffle_plan_result_{name}")(handle, byref(value)))
    check(lib.baffle_plan_result_reason_count(handle, byref(count)))

    def text(getter, *args) -> str:
        pointer = c_void_p()
        check(getter(handle, *args, byref(pointer)))
        return take_string(pointer)

    return PlanResult(
        verdict=_lib.VERDICTS[verdict.value],
        reasons=[text(lib.baffle_plan_result_reason, k) for k in range(count.value)],
        verdict_text=text(lib.baffle_plan_result_verdict_text),
        report_json=Path(text(lib.baffle_plan_result_report_json_path)),
        report_html=Path(text(lib.baffle_plan_result_report_html_path)),
        **{name: value.value for name, value in numbers.items()},
    )


def plan(
    out_dir,
    *,
    surface=None,
    segmentations=None,
    points=None,
    phantom: bool = False,
    bsa_m2: Optional[float] = None,
    z_score: Optional[float] = None,
    target_area_mm2: Optional[float] = None,
    annulus_diameter_mm: Optional[float] = None,
    sbp_mmhg: float,
    dbp_mmhg: float,
    heart_rate_bpm: Optional[float] = None,
    cardiac_index_l_min_m2: Optional[float] = None,
    mode: str = "pulsatile",
    cycles: Optional[int] = None,
    edge_length_mm: Optional[float] = None,
    single_mesh: bool = False,
    elevated_flow: bool = False,
    flow_sections: bool = False,
    patient_label: Optional[str] = None,
    progress: Optional[Progress] = None,
    cancel: Optional[Cancel] = None,
) -> PlanResult:
    """Run the plan into `out_dir` (one subfolder per stage, report.json, report.html).

    The ventricle: `surface` (capped, labelled .vtp/.vtk/.stl) with `points` (suture points
    file), or `segmentations` (a folder of LV/RV/aorta surfaces, prepared first; the CFD
    then runs on the extended domain) with `points`, or `phantom=True`. `bsa_m2` (the
    phantom's unless given) sets the flow and, at `z_score` (default 0), the target's
    Boston annulus; or the target is `target_area_mm2` or `annulus_diameter_mm` (as
    `baffle plan --target-area-mm2/--annulus-diameter-mm`; `bsa_m2` then sets the flow
    only). Two targets (an area and a diameter, or either with a nonzero z_score) are
    refused with BaffleError. `sbp_mmhg`/`dbp_mmhg` set the outlet.
    `mode`: "pulsatile" (over `cycles`), "quick" (rest to the first flow peak) or "steady".
    `single_mesh` skips the mesh study; `flow_sections` holds the flow-normal sections at
    the target too. Unset values are `baffle plan`'s defaults.

    `progress(fraction, stage)` gets the whole plan's fraction done and the running stage
    (returning False cancels); `cancel()` is asked between the stages and while the design
    and the simulation run, and returning True stops the plan: `Cancelled` is raised and
    the stages finished before keep their folders. Bad options raise BaffleError (status
    InvalidArgument) naming them before any stage runs; a failed stage raises BaffleError
    (status 10, plan failed) naming the stage.
    """
    paths = {"out_dir": out_dir, "surface_path": surface, "segmentations_dir": segmentations, "points_path": points}
    paths["patient_label"] = patient_label
    values = {
        **_flow_values(bsa_m2, sbp_mmhg, dbp_mmhg, heart_rate_bpm, cardiac_index_l_min_m2, cycles),
        "phantom": int(bool(phantom)),
        "edge_length_mm": edge_length_mm,
        "single_mesh": int(bool(single_mesh)),
        "elevated_flow": int(bool(elevated_flow)),
        "flow_sections": int(bool(flow_sections)),
        "z_score": z_score,
        "target_area_mm2": target_area_mm2,
        "annulus_diameter_mm": annulus_diameter_mm,
    }
    options = _plan_options(paths, values, mode)
    progress_bridge, cancel_bridge = _ProgressBridge(progress), _CancelBridge(cancel)
    handle = c_void_p()
    try:
        status = lib.baffle_plan(byref(options), progress_bridge.c_function, cancel_bridge.c_function, None, byref(handle))
        for error in (progress_bridge.error, cancel_bridge.error):
            if error is not None:
                raise error
        check(status)
        return _result(handle)
    finally:
        lib.baffle_plan_result_free(handle)


def write_case(
    case_dir,
    *,
    mesh_volume="volume.vtu",
    mesh_faces="volume-faces.vtp",
    bsa_m2: float,
    sbp_mmhg: float,
    dbp_mmhg: float,
    heart_rate_bpm: Optional[float] = None,
    cardiac_index_l_min_m2: Optional[float] = None,
    mode: str = "pulsatile",
    cycles: Optional[int] = None,
) -> Path:
    """Write the CFD case the plan simulates (`baffle simulate`'s case.json) into
    `case_dir` for the designed domain's volume mesh `mesh_volume` with its labelled faces
    `mesh_faces` (as `baffle mesh` writes them; relative to case_dir): inflow at the VSD
    cap, outflow at the aortic cap, the flow BSA x cardiac index, the outlet from the blood
    pressure, the run's `mode` ("pulsatile", "quick" or "steady"). The library checks the
    case as `baffle simulate` will; a bad value raises BaffleError naming it. Returns the
    written file's path."""
    values = _flow_values(float(bsa_m2), sbp_mmhg, dbp_mmhg, heart_rate_bpm, cardiac_index_l_min_m2, cycles)
    options = _plan_options({}, values, mode)
    written = c_void_p()
    check(lib.baffle_plan_write_case(byref(options), _encoded(mesh_volume), _encoded(mesh_faces), _encoded(case_dir), byref(written)))
    return Path(take_string(written))
