"""baffle.design(): numpy arrays in, a DesignResult of numpy arrays out."""

import ctypes
import json
from ctypes import POINTER, byref, c_double, c_int32, c_int64, c_size_t, c_void_p
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from . import _lib
from ._lib import check, lib

# (fraction done, stage name) -> keep going? (None counts as yes)
Progress = Callable[[float, str], Optional[bool]]


@dataclass
class Mesh:
    """A labelled triangle surface: points (n, 3) mm, triangles (m, 3) int64, labels (m,) int32."""

    points: np.ndarray
    triangles: np.ndarray
    labels: np.ndarray


@dataclass
class DesignResult:
    domain: Mesh
    baffle: Mesh
    centerline_points_mm: np.ndarray
    centerline_tangents: np.ndarray
    centerline_s_mm: np.ndarray
    seam_points_mm: np.ndarray
    report: dict = field(repr=False)

    @property
    def target_area_mm2(self) -> float:
        return self.report["target_area_mm2"]

    @property
    def constrained_sections(self) -> list:
        """Sections the design holds at or above the target area (the others were
        dropped, e.g. mostly on the RV wall or at the degenerate cap planes)."""
        return [s for s in self.report["sections"] if s["status"] == "constrained"]

    @property
    def checked_sections(self) -> list:
        """Sections whose final area is held at or above the target: the constrained
        ones and those only checked (their baffle arc crosses a constrained section's,
        where the centerline bends more sharply than the tunnel is wide)."""
        return [s for s in self.report["sections"] if s["final_area_mm2"] is not None]


def _array(values, dtype, name: str, columns: Optional[int] = None) -> np.ndarray:
    array = np.ascontiguousarray(values, dtype=dtype)
    if columns is not None and (array.ndim != 2 or array.shape[1] != columns):
        raise ValueError(f"{name} must have shape (n, {columns}), not {array.shape}")
    return array


def _ptr(array: np.ndarray, ctype):
    return array.ctypes.data_as(POINTER(ctype))


def _new_mesh(points, triangles, labels) -> c_void_p:
    points = _array(points, np.float64, "surface_points", 3)
    triangles = _array(triangles, np.int64, "triangles", 3)
    labels = _array(labels, np.int32, "labels").ravel()
    handle = c_void_p()
    check(
        lib.baffle_mesh_new(
            _ptr(points, c_double), points.size, _ptr(triangles, c_int64), triangles.size,
            _ptr(labels, c_int32), labels.size, byref(handle),
        )
    )
    return handle


def _copy_out(handle, count_fn, copy_fn, dtype, ctype, columns: int) -> np.ndarray:
    n = c_size_t()
    check(count_fn(handle, byref(n)))
    out = np.empty((n.value, columns), dtype=dtype)
    check(copy_fn(handle, _ptr(out, ctype), out.size))
    return out


def _mesh_from_handle(handle) -> Mesh:
    try:
        return Mesh(
            points=_copy_out(handle, lib.baffle_mesh_point_count, lib.baffle_mesh_copy_points, np.float64, c_double, 3),
            triangles=_copy_out(handle, lib.baffle_mesh_triangle_count, lib.baffle_mesh_copy_triangles, np.int64, c_int64, 3),
            labels=_copy_out(handle, lib.baffle_mesh_triangle_count, lib.baffle_mesh_copy_labels, np.int32, c_int32, 1).ravel(),
        )
    finally:
        lib.baffle_mesh_free(handle)


def _result_mesh(result, getter) -> Mesh:
    handle = c_void_p()
    check(getter(result, byref(handle)))
    return _mesh_from_handle(handle)


def _report(result) -> dict:
    text = c_void_p()
    check(lib.baffle_result_report_json(result, byref(text)))
    return json.loads(_lib.take_string(text))


def _centerline(result):
    n = c_size_t()
    check(lib.baffle_result_centerline_count(result, byref(n)))
    points, tangents, s_mm = np.empty((n.value, 3)), np.empty((n.value, 3)), np.empty(n.value)
    check(lib.baffle_result_copy_centerline(result, _ptr(points, c_double), _ptr(tangents, c_double), _ptr(s_mm, c_double), n.value))
    return points, tangents, s_mm


def _collect(result) -> DesignResult:
    points, tangents, s_mm = _centerline(result)
    return DesignResult(
        domain=_result_mesh(result, lib.baffle_result_domain),
        baffle=_result_mesh(result, lib.baffle_result_baffle),
        centerline_points_mm=points,
        centerline_tangents=tangents,
        centerline_s_mm=s_mm,
        seam_points_mm=_copy_out(result, lib.baffle_result_seam_count, lib.baffle_result_copy_seam, np.float64, c_double, 3),
        report=_report(result),
    )


def _options(target: dict, tunables: dict) -> _lib.DesignOptions:
    options = _lib.default_options()
    given = [k for k, v in target.items() if v is not None]
    kinds = {
        ("target_area_mm2",): "area_mm2",
        ("annulus_diameter_mm",): "annulus_diameter_mm",
        ("bsa_m2",): "bsa",
        ("height_cm", "weight_kg"): "height_weight",
    }
    kind = kinds.get(tuple(given))
    if kind is None:
        raise ValueError(
            "give exactly one target: target_area_mm2, annulus_diameter_mm, bsa_m2, or height_cm with weight_kg"
        )
    options.target_kind = _lib.TARGET_KINDS[kind]
    for name in given:
        setattr(options, name, float(target[name]))
    known = {name for name, _ in _lib.DesignOptions._fields_} - {"struct_size", "target_kind"} - set(target)
    for name, value in tunables.items():
        if name not in known:
            raise TypeError(f"unknown design option {name!r}; known: {sorted(known)}")
        setattr(options, name, value)
    return options


class _ProgressBridge:
    """Calls the Python callback from C; an exception it raises cancels the call and
    is re-raised once the call has returned (it cannot cross the C ABI)."""

    def __init__(self, progress: Optional[Progress]):
        self.progress = progress
        self.error: Optional[BaseException] = None
        self.c_function = _lib.PROGRESS(self._call) if progress else _lib.PROGRESS()

    def _call(self, fraction, stage, _user):
        try:
            keep_going = self.progress(fraction, stage.decode("utf-8", "replace"))
            return 0 if keep_going is False else 1
        except BaseException as error:  # noqa: BLE001 - re-raised after the call
            self.error = error
            return 0


def design(
    surface_points,
    triangles,
    labels,
    suture_points,
    target_area_mm2: Optional[float] = None,
    bsa_m2: Optional[float] = None,
    z_score: float = 0.0,
    annulus_diameter_mm: Optional[float] = None,
    height_cm: Optional[float] = None,
    weight_kg: Optional[float] = None,
    progress: Optional[Progress] = None,
    peak_flow_ml_s: Optional[float] = None,
    flow_sections: bool = False,
    **tunables,
) -> DesignResult:
    """Design the area-constrained baffle.

    surface_points (n, 3) mm, triangles (m, 3) point indices and labels (m,)
    ModelFaceIDs describe the closed capped ventricle (2 wall, 11 VSD cap, 16 aortic
    cap by default); suture_points (k, 3) are in the surface's frame. Give one
    target. `tunables` set other BaffleDesignOptions fields (seam_samples,
    remesh_edge_mm, wall_label, ...). `progress(fraction, stage)` returning False
    cancels (raises Cancelled). Errors raise BaffleError with the library's message.
    `peak_flow_ml_s`, the patient's peak flow, adds report["hemodynamics_estimate"]:
    the reduced-order dp at peak flow and v_max with their measured error (not a CFD
    result, docs/hemodynamics_estimate.md); without it that object says why there is none.
    `flow_sections=True` (the command line's --flow-sections) also holds the tunnel's
    sections normal to the flow at the target: the design is run again at a raised target
    until they reach it, and report["flow_sections"] says how.
    """
    target = {
        "target_area_mm2": target_area_mm2,
        "annulus_diameter_mm": annulus_diameter_mm,
        "bsa_m2": bsa_m2,
        "height_cm": height_cm,
        "weight_kg": weight_kg,
    }
    options = _options(target, tunables)
    options.z_score = float(z_score)
    options.peak_flow_ml_s = float("nan") if peak_flow_ml_s is None else float(peak_flow_ml_s)
    options.flow_sections = int(bool(flow_sections))
    suture = _array(suture_points, np.float64, "suture_points", 3)
    surface = _new_mesh(surface_points, triangles, labels)
    bridge = _ProgressBridge(progress)
    result = c_void_p()
    try:
        status = lib.baffle_design(surface, _ptr(suture, c_double), suture.size, byref(options), bridge.c_function, None, byref(result))
        if bridge.error is not None:
            raise bridge.error
        check(status)
        return _collect(result)
    finally:
        lib.baffle_result_free(result)
        lib.baffle_mesh_free(surface)


def peak_flow_ml_s(bsa_m2: float, cardiac_index_l_min_m2: float = 3.48) -> float:
    """The paper's peak flow (ml/s) for design(..., peak_flow_ml_s=): 3.26 x BSA x cardiac
    index (L/min/m2; 3.48 is the paper's normal), the peak of the CFD's default waveform.
    Raises BaffleError naming a BSA or cardiac index that is not positive and finite."""
    q = c_double()
    check(lib.baffle_peak_flow_ml_s(float(bsa_m2), float(cardiac_index_l_min_m2), byref(q)))
    return q.value


def phantom(suture_half_angle_deg=None):
    """The built-in synthetic phantom: (surface Mesh, suture points (k, 3), BSA m2).

    suture_half_angle_deg: how far the suture loop wraps round the tunnel from its
    outermost line (degrees; None keeps the default phantom's 70). A wider loop leaves
    less baffle near the caps, so large targets become infeasible.
    """
    handle, points, length, bsa_m2 = c_void_p(), POINTER(c_double)(), c_size_t(), c_double()
    outputs = (byref(handle), byref(points), byref(length), byref(bsa_m2))
    if suture_half_angle_deg is None:
        check(lib.baffle_phantom(*outputs))
    else:
        check(lib.baffle_phantom_with_suture_half_angle(float(suture_half_angle_deg), *outputs))
    try:
        suture = np.ctypeslib.as_array(points, shape=(length.value,)).reshape(-1, 3).copy()
    finally:
        lib.baffle_free(ctypes.cast(points, c_void_p))
    return _mesh_from_handle(handle), suture, bsa_m2.value
