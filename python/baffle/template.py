"""baffle.template(): the true-scale patch template of a designed domain, over the C ABI.

    result = baffle.design(...)
    t = baffle.template(result.domain, points, patient_label="p2")
    t.save("template.pdf")            # A4, prints 1:1 at 100 % (or .svg, or .png at `dpi`)
    t.flat.points                     # the flattened baffle (u, v, 0) in mm
    t.report["flattening"]["perimeter_error"], t.area_ratio
"""

import ctypes
import json
import os
import tempfile
from ctypes import byref, c_char_p, c_double, c_int32, c_size_t, c_void_p
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from . import _lib
from ._lib import check, lib
from .design import Mesh, _array, _mesh_from_handle, _new_mesh, _ptr


@dataclass
class Template:
    """The flattened baffle (`flat`: points (u, v, 0) mm, triangles, labels), the
    template's report (`report["flattening"]`: seam length, perimeter and its error,
    area and angle distortion median / max) and the page as PDF, SVG and PNG (at the
    dpi asked for, stored in the file)."""

    flat: Mesh
    report: dict = field(repr=False)
    pdf: bytes = field(repr=False)
    svg: bytes = field(repr=False)
    png: bytes = field(repr=False)

    @property
    def area_ratio(self) -> np.ndarray:
        """Per flat triangle: flat area / 3D area (1 = no change)."""
        return np.asarray(self.report["area_ratio"])

    def save(self, path) -> Path:
        """Write the page to `path` (.pdf, .svg or .png), atomically."""
        path = Path(path)
        pages = {".pdf": self.pdf, ".svg": self.svg, ".png": self.png}
        data = pages.get(path.suffix.lower())
        if data is None:
            raise ValueError(f"{path}: the template is saved as .pdf, .svg or .png")
        handle, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        try:
            with os.fdopen(handle, "wb") as f:
                f.write(data)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return path


def _labels_text(point_labels: Optional[Sequence[str]], count: int) -> Optional[bytes]:
    if point_labels is None:
        return None
    labels = [str(label) for label in point_labels]
    if len(labels) != count:
        raise ValueError(f"{len(labels)} point labels for {count} suture points")
    if any("\n" in label for label in labels):
        raise ValueError("a point label holds a line break")
    return "\n".join(labels).encode("utf-8")


def _document(handle, fmt: str, dpi: float) -> bytes:
    data, size = c_void_p(), c_size_t()
    if fmt == "png":
        check(lib.baffle_template_png(handle, c_double(dpi), byref(data), byref(size)))
    else:
        check(lib.baffle_template_document(handle, _lib.TEMPLATE_FORMATS[fmt], byref(data), byref(size)))
    try:
        return ctypes.string_at(data, size.value)
    finally:
        lib.baffle_free(data)


def template(
    domain: Mesh,
    suture_points,
    point_labels: Optional[Sequence[str]] = None,
    patient_label: str = "",
    date: Optional[str] = None,
    method: str = "lscm",
    baffle_label: int = 10,
    vsd_cap_label: int = 11,
    aortic_cap_label: int = 16,
    dpi: float = 300.0,
) -> Template:
    """Flatten the baffle of a designed `domain` (a Mesh as baffle.design returns, or any
    object with points, triangles and labels) into a true-scale patch template.

    suture_points (k, 3) mm are in the domain's frame and are drawn at their nearest seam
    vertex, named by `point_labels` (k strings; default 1, 2, ...). `date` defaults to
    today (UTC). `method` is "lscm" (conformal, the default) or "arap". `dpi` is the PNG
    page's resolution (10 to 1200, stored in its pHYs chunk). Errors raise
    BaffleError with the library's message (e.g. a domain without baffle triangles).
    """
    if method not in _lib.FLATTEN_METHODS:
        raise ValueError(f"method must be one of {sorted(_lib.FLATTEN_METHODS)}, not {method!r}")
    points = _array(suture_points, np.float64, "suture_points", 3) if len(suture_points) else np.empty((0, 3))
    names = _labels_text(point_labels, len(points))
    labels = (c_int32 * 3)(baffle_label, vsd_cap_label, aortic_cap_label)
    mesh = _new_mesh(domain.points, domain.triangles, domain.labels)
    handle = c_void_p()
    try:
        check(
            lib.baffle_template(
                mesh, _ptr(points, c_double), points.size, c_char_p(names),
                c_char_p(patient_label.encode("utf-8")), c_char_p(date.encode("utf-8") if date else None),
                ctypes.cast(labels, ctypes.POINTER(c_int32)), _lib.FLATTEN_METHODS[method], byref(handle),
            )
        )
    finally:
        lib.baffle_mesh_free(mesh)
    try:
        flat = c_void_p()
        check(lib.baffle_template_flat_mesh(handle, byref(flat)))
        text = c_void_p()
        check(lib.baffle_template_report_json(handle, byref(text)))
        try:
            report = json.loads(ctypes.string_at(text).decode("utf-8"))
        finally:
            lib.baffle_free(text)
        pages = {fmt: _document(handle, fmt, dpi) for fmt in ("pdf", "svg", "png")}
        return Template(flat=_mesh_from_handle(flat), report=report, **pages)
    finally:
        lib.baffle_template_free(handle)
