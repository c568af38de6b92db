"""Cross-section areas of a lumen along its centerline, measured with VTK, independently
of `baffle`'s own section code (issue 13: compare our designed tunnel with the published
one section by section).

Each section is the cut of the closed surface (mm) by the plane normal to the centerline
(its chord over 1 mm each side) at one of its points (vtkCutter + vtkStripper); of the
closed loops the cut makes, the section is the smallest one that encloses the centerline
point (a plane through a bent lumen also cuts it elsewhere). Its area is the loop's vector
area along the normal (Newell), exact for a planar polygon. A plane that crosses the VSD or
aortic cap is not a section of the tunnel and is left out. `baffle centerline` measures the
same sections by its own code (a raster of the cut): this is the independent check.
"""
import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

import planes
import published


def tangents(points, half_width_mm=1.0):
    """Unit tangents of a polyline: the chord over half_width_mm each side (shorter at the ends)."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    k = np.arange(len(points))
    # At least the neighbours, however sparse the points.
    before = np.minimum(np.searchsorted(s, s - half_width_mm, side="left"), np.maximum(k - 1, 0))
    after = np.maximum(np.searchsorted(s, s + half_width_mm, side="right") - 1, np.minimum(k + 1, len(points) - 1))
    t = points[after] - points[before]
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


def cap_points(surface, labels):
    """The points of each cap (ModelFaceID in labels) of the surface."""
    points = vtk_to_numpy(surface.GetPoints().GetData()).astype(float)
    tris = published.triangles(surface)
    face_ids = vtk_to_numpy(surface.GetCellData().GetArray("ModelFaceID"))
    return [points[np.unique(tris[face_ids == label])] for label in labels]


def crosses(points, origin, normal):
    d = (points - origin) @ normal
    return len(d) > 0 and d.min() < 0 < d.max()


def section_areas(surface_path, centerline_points, caps=(11, 16)):
    """(s_mm, area_mm2) at each centerline point; NaN where no loop encloses it or where
    the plane crosses one of the caps (the VSD and aortic planes lie oblique to the flow:
    such a plane would measure the cap's cut, not the tunnel)."""
    surface = published.read_vtp(surface_path)
    cap_sets = cap_points(surface, caps)
    pts = np.asarray(centerline_points, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    out = []
    for point, normal, s_mm in zip(pts, tangents(pts), s):
        if any(crosses(c, point, normal) for c in cap_sets):
            out.append((float(s_mm), float("nan")))
            continue
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
