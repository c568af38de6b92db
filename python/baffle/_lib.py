"""Loads libbaffle with ctypes and declares the C ABI's signatures (baffle.h)."""

import ctypes
import math
import os
from ctypes import POINTER, c_char_p, c_double, c_int, c_int32, c_int64, c_size_t, c_uint32, c_void_p
from pathlib import Path
from typing import Optional

from ._library_file import library_name

# The header's BAFFLE_ABI_VERSION this module was written against.
ABI_VERSION = 1

# BaffleStatus values.
STATUS_OK = 0
STATUS_CANCELLED = 7
STATUS_PLAN_FAILED = 10
# BafflePlanMode and BaffleVerdict values.
PLAN_MODES = {"pulsatile": 0, "quick": 1, "steady": 2}
VERDICTS = ("passes", "fails", "inconclusive")
FRAMES = {"LPS": 0, "RAS": 1}
FLATTEN_METHODS = {"lscm": 0, "arap": 1}
TEMPLATE_FORMATS = {"pdf": 0, "svg": 1, "png": 2}
TARGET_KINDS = {"area_mm2": 0, "annulus_diameter_mm": 1, "bsa": 2, "height_weight": 3}


class BaffleError(RuntimeError):
    """A failed library call: `status` is the BaffleStatus code, str() the library's message.
    `max_feasible_area_mm2` is the largest target area the suture line admits when the
    design failed because the target cannot be reached (0.0: no tunnel at all), else None."""

    def __init__(self, status: int, message: str, max_feasible_area_mm2: Optional[float] = None):
        super().__init__(message)
        self.status = status
        self.max_feasible_area_mm2 = max_feasible_area_mm2


class Cancelled(BaffleError):
    """The progress callback asked to stop."""


def _library_path() -> Path:
    """BAFFLE_LIBRARY, else the copy installed with the package, else a development
    tree's cargo build (python/baffle -> ../../target/release)."""
    given = os.environ.get("BAFFLE_LIBRARY")
    if given:
        return Path(given)
    here = Path(__file__).resolve().parent
    candidates = [here / library_name(), here.parent.parent / "target" / "release" / library_name()]
    for candidate in candidates:
        if candidate.exists():
            return candidate
    raise ImportError(
        "baffle: shared library not found (looked at %s); reinstall with `pip install ./python` "
        "or set BAFFLE_LIBRARY" % ", ".join(str(c) for c in candidates)
    )


class DesignOptions(ctypes.Structure):
    """BaffleDesignOptions, field for field."""

    _fields_ = [
        ("struct_size", c_uint32),
        ("target_kind", c_int32),
        ("target_area_mm2", c_double),
        ("annulus_diameter_mm", c_double),
        ("bsa_m2", c_double),
        ("height_cm", c_double),
        ("weight_kg", c_double),
        ("z_score", c_double),
        ("wall_label", c_int32),
        ("baffle_label", c_int32),
        ("vsd_cap_label", c_int32),
        ("aortic_cap_label", c_int32),
        ("seam_samples", c_uint32),
        ("interior_control_points", c_uint32),
        ("max_correction_rounds", c_uint32),
        ("remesh", c_int32),
        ("max_point_distance_mm", c_double),
        ("remesh_edge_mm", c_double),
        ("baffle_edge_mm", c_double),
        ("centerline_spacing_mm", c_double),
        ("area_margin", c_double),
        ("max_wall_fraction", c_double),
        ("tps_regularization", c_double),
        # Appended after the first layout: NaN or 0 = no reduced-order estimate.
        ("peak_flow_ml_s", c_double),
        # Appended after peak_flow_ml_s: nonzero = hold the flow-normal sections at the target too.
        ("flow_sections", c_int32),
    ]


class PlanOptions(ctypes.Structure):
    """BafflePlanOptions, field for field (strings: UTF-8 paths, None = not given)."""

    _fields_ = [
        ("struct_size", c_uint32),
        ("surface_path", c_char_p),
        ("segmentations_dir", c_char_p),
        ("points_path", c_char_p),
        ("phantom", c_int32),
        ("out_dir", c_char_p),
        ("bsa_m2", c_double),
        ("sbp_mmhg", c_double),
        ("dbp_mmhg", c_double),
        ("heart_rate_bpm", c_double),
        ("cardiac_index_l_min_m2", c_double),
        ("mode", c_int32),
        ("cycles", c_uint32),
        ("edge_length_mm", c_double),
        ("single_mesh", c_int32),
        ("elevated_flow", c_int32),
        ("flow_sections", c_int32),
        ("patient_label", c_char_p),
        # Appended after the first layout: the design's target (NaN: not given).
        ("z_score", c_double),
        ("target_area_mm2", c_double),
        ("annulus_diameter_mm", c_double),
    ]


PROGRESS = ctypes.CFUNCTYPE(c_int32, c_double, c_char_p, c_void_p)
CANCEL = ctypes.CFUNCTYPE(c_int32, c_void_p)

_D, _I64, _I32, _SZ = POINTER(c_double), POINTER(c_int64), POINTER(c_int32), POINTER(c_size_t)
_SIGNATURES = {
    "baffle_version": ([], c_char_p),
    "baffle_abi_version": ([], c_uint32),
    "baffle_last_error": ([], c_char_p),
    "baffle_last_max_feasible_area_mm2": ([], c_double),
    "baffle_free": ([c_void_p], None),
    "baffle_design_options_init": ([c_void_p], c_int),
    "baffle_mesh_new": ([_D, c_size_t, _I64, c_size_t, _I32, c_size_t, POINTER(c_void_p)], c_int),
    "baffle_mesh_free": ([c_void_p], None),
    "baffle_mesh_point_count": ([c_void_p, _SZ], c_int),
    "baffle_mesh_triangle_count": ([c_void_p, _SZ], c_int),
    "baffle_mesh_copy_points": ([c_void_p, _D, c_size_t], c_int),
    "baffle_mesh_copy_triangles": ([c_void_p, _I64, c_size_t], c_int),
    "baffle_mesh_copy_labels": ([c_void_p, _I32, c_size_t], c_int),
    "baffle_peak_flow_ml_s": ([c_double, c_double, _D], c_int),
    "baffle_design": ([c_void_p, _D, c_size_t, POINTER(DesignOptions), PROGRESS, c_void_p, POINTER(c_void_p)], c_int),
    "baffle_result_free": ([c_void_p], None),
    "baffle_result_domain": ([c_void_p, POINTER(c_void_p)], c_int),
    "baffle_result_baffle": ([c_void_p, POINTER(c_void_p)], c_int),
    "baffle_result_report_json": ([c_void_p, POINTER(c_void_p)], c_int),
    "baffle_result_centerline_count": ([c_void_p, _SZ], c_int),
    "baffle_result_copy_centerline": ([c_void_p, _D, _D, _D, c_size_t], c_int),
    "baffle_result_seam_count": ([c_void_p, _SZ], c_int),
    "baffle_result_copy_seam": ([c_void_p, _D, c_size_t], c_int),
    "baffle_phantom": ([POINTER(c_void_p), POINTER(_D), _SZ, _D], c_int),
    "baffle_phantom_with_suture_half_angle": ([c_double, POINTER(c_void_p), POINTER(_D), _SZ, _D], c_int),
    "baffle_read_suture_points": ([c_char_p, c_int32, POINTER(_D), _SZ], c_int),
    "baffle_template": ([c_void_p, _D, c_size_t, c_char_p, c_char_p, c_char_p, _I32, c_int32, POINTER(c_void_p)], c_int),
    "baffle_template_free": ([c_void_p], None),
    "baffle_template_flat_mesh": ([c_void_p, POINTER(c_void_p)], c_int),
    "baffle_template_report_json": ([c_void_p, POINTER(c_void_p)], c_int),
    "baffle_template_document": ([c_void_p, c_int32, POINTER(c_void_p), _SZ], c_int),
    "baffle_template_png": ([c_void_p, c_double, POINTER(c_void_p), _SZ], c_int),
    "baffle_plan_options_init": ([c_void_p], c_int),
    "baffle_plan": ([POINTER(PlanOptions), PROGRESS, CANCEL, c_void_p, POINTER(c_void_p)], c_int),
    "baffle_plan_result_free": ([c_void_p], None),
    "baffle_plan_result_verdict": ([c_void_p, _I32], c_int),
    "baffle_plan_result_dp_mmhg": ([c_void_p, _D], c_int),
    "baffle_plan_result_v_max_m_s": ([c_void_p, _D], c_int),
    "baffle_plan_result_dp_threshold_mmhg": ([c_void_p, _D], c_int),
    "baffle_plan_result_reason_count": ([c_void_p, _SZ], c_int),
    "baffle_plan_result_reason": ([c_void_p, c_size_t, POINTER(c_void_p)], c_int),
    "baffle_plan_result_verdict_text": ([c_void_p, POINTER(c_void_p)], c_int),
    "baffle_plan_result_report_json_path": ([c_void_p, POINTER(c_void_p)], c_int),
    "baffle_plan_result_report_html_path": ([c_void_p, POINTER(c_void_p)], c_int),
    "baffle_plan_write_case": ([POINTER(PlanOptions), c_char_p, c_char_p, c_char_p, POINTER(c_void_p)], c_int),
}


def _load() -> ctypes.CDLL:
    lib = ctypes.CDLL(str(_library_path()))
    for name, (argtypes, restype) in _SIGNATURES.items():
        function = getattr(lib, name)
        function.argtypes = argtypes
        function.restype = restype
    if lib.baffle_abi_version() != ABI_VERSION:
        raise ImportError(f"libbaffle has ABI {lib.baffle_abi_version()}, this package expects {ABI_VERSION}")
    return lib


lib = _load()


def check(status: int) -> None:
    """Raise the library's error for a non-OK status."""
    if status == STATUS_OK:
        return
    message = lib.baffle_last_error().decode("utf-8", "replace")
    largest = lib.baffle_last_max_feasible_area_mm2()
    largest = None if math.isnan(largest) else largest
    raise (Cancelled if status == STATUS_CANCELLED else BaffleError)(status, message, largest)


def version() -> str:
    """The shared library's version."""
    return lib.baffle_version().decode()


def _initialised(init, structure):
    """`structure` filled by the library's `init`, after checking it fills a struct of our
    size (into a generous scratch buffer, so a mismatch cannot overrun memory)."""
    scratch = ctypes.create_string_buffer(4096)
    check(init(ctypes.cast(scratch, c_void_p)))
    size = c_uint32.from_buffer(scratch).value
    if size != ctypes.sizeof(structure):
        raise BaffleError(4, f"libbaffle's {structure.__name__} struct has {size} bytes, this package knows {ctypes.sizeof(structure)}")
    return structure.from_buffer_copy(scratch.raw[:size])


def default_options() -> DesignOptions:
    """The design's defaults from the library."""
    return _initialised(lib.baffle_design_options_init, DesignOptions)


def default_plan_options() -> PlanOptions:
    """The plan's defaults from the library (no ventricle, blood pressure or output folder)."""
    return _initialised(lib.baffle_plan_options_init, PlanOptions)


def take_string(pointer: c_void_p) -> str:
    """A string the library handed out, freed."""
    try:
        return ctypes.string_at(pointer).decode("utf-8")
    finally:
        lib.baffle_free(pointer)
