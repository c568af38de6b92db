"""Cross-section areas of a lumen along its centerline, measured with VTK, independently
of `baffle`'s own section code (issue 13: compare our designed tunnel with the published
one section by section).

Each section is the cut of the closed surface (mm) by the plane normal to the centerline
at one of its points (vtkCutter + vtkStripper); of the closed loops the cut makes, the
section is the smallest one that encloses the centerline point (a plane through a bent
lumen also cuts it elsewhere). Its area is the loop's vector area along the normal
(Newell), which is exact for a planar polygon.
"""
import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

import planes
import published


def tangents(points):
    """Unit tangents of a polyline by central differences (one-sided at the ends)."""
    t = np.gradient(points, axis=0)
    return t / np.linalg.norm(t, axis=1)[:, None]


def loop_area_mm2(loop, normal):
    """Area of a closed planar polygon (its points in order) seen along `normal`."""
    nxt = np.roll(loop, -1, axis=0)
    return float(abs(0.5 * np.cross(loop, nxt).sum(axis=0) @ normal))


def encloses(loop, point, normal):
    """Whether the planar polygon encloses `point` (even-odd rule in the plane)."""
    u = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    xy = np.stack([(loop - point) @ u, (loop - point) @ v], axis=1)
    a, b = xy, np.roll(xy, -1, axis=0)
    crosses = (a[:, 1] > 0) != (b[:, 1] > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = a[:, 0] + (0 - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return bool(np.count_nonzero(crosses & (x_at > 0)) % 2)


def cut_loops(surface, origin, normal):
    """The closed loops (point arrays) where the plane cuts the surface."""
    # Held in a local: the connection alone does not keep the cutter alive in Python.
    cutter = planes.plane_cutter(surface, origin, normal)
    stripper = vtk.vtkStripper()
    stripper.SetInputConnection(cutter.GetOutputPort())
    stripper.JoinContiguousSegmentsOn()
    stripper.Update()
    lines = stripper.GetOutput()
    if lines.GetNumberOfPoints() == 0:
        return []
    points = vtk_to_numpy(lines.GetPoints().GetData()).astype(float)
    offsets = vtk_to_numpy(lines.GetLines().GetOffsetsArray())
    ids = vtk_to_numpy(lines.GetLines().GetConnectivityArray())
    loops = []
    for a, b in zip(offsets[:-1], offsets[1:]):
        idx = ids[a:b]
        # A closed strip repeats its first point last; an open one is not a section.
        if len(idx) > 3 and idx[0] == idx[-1]:
            loops.append(points[idx[:-1]])
    return loops


def section_areas(surface_path, centerline_points):
    """(s_mm, area_mm2) at each centerline point; area NaN where no loop encloses it."""
    surface = published.read_vtp(surface_path)
    pts = np.asarray(centerline_points, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    out = []
    for point, normal, s_mm in zip(pts, tangents(pts), s):
        around = [loop for loop in cut_loops(surface, point, normal) if encloses(loop, point, normal)]
        area = min((loop_area_mm2(loop, normal) for loop in around), default=float("nan"))
        out.append((float(s_mm), area))
    return out


def profile_summary(areas, trim_mm=0.0):
    """Smallest section (mm2) and where (mm along the centerline), mean and sections found,
    over the sections at least trim_mm from either end: a plane through the centerline's
    end points is tilted against the measurement cap there and cuts it, not the tunnel."""
    length = areas[-1][0] if areas else 0.0
    areas = [(s, a) for s, a in areas if trim_mm <= s <= length - trim_mm]
    found = [(s, a) for s, a in areas if np.isfinite(a)]
    if not found:
        return {"min_section_mm2": float("nan"), "min_at_mm": float("nan"), "mean_section_mm2": float("nan"), "sections": 0, "of": len(areas)}
    s_min, a_min = min(found, key=lambda x: x[1])
    return {"min_section_mm2": a_min, "min_at_mm": s_min, "mean_section_mm2": float(np.mean([a for _, a in found])), "sections": len(found), "of": len(areas)}
