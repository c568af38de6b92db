"""Pressure on a measurement plane at peak flow, by several definitions.

The solver's dp (summary.json) is the area-weighted mean static pressure over each
interior face set. To find which reading of "the pressure difference between the VSD
and aortic planes" (paper 2.5) a result depends on, this module recomputes it from
peak.vtu (point arrays pressure_mmhg, velocity_m_s; mm) and the mesh's faces
(ModelFaceID, GlobalNodeID = 1-based volume point index):

- static_area: area-weighted mean static pressure (the solver's definition),
- static_nodes: plain mean over the plane's nodes (what a node-averaging tool gives),
- total_area: area-weighted mean of p + rho |u|^2 / 2,
- total_flux: flow-weighted mean of p + rho |u|^2 / 2 (mechanical energy flux / flow),
- static on a plane shifted along the cap's normal (a cut of the volume mesh).
"""
import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

RHO_KG_M3 = 1060.0
PA_PER_MMHG = 133.322387415


def dynamic_mmhg(speed_m_s):
    return 0.5 * RHO_KG_M3 * np.asarray(speed_m_s) ** 2 / PA_PER_MMHG


def triangle_geometry(points, tris):
    """Area (mm2) and unit normal of each triangle."""
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    n = 0.5 * np.cross(b - a, c - a)
    area = np.linalg.norm(n, axis=1)
    return area, n / area[:, None]


def plane_means(points, tris, pressure, velocity):
    """The four plane figures (mmHg) of one triangulated plane; P1 fields on its nodes.
    Zero-area triangles (a cut running through mesh faces makes them) are dropped."""
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    tris = tris[np.linalg.norm(np.cross(b - a, c - a), axis=1) > 0]
    area, normal = triangle_geometry(points, tris)
    # One orientation for the plane: its mean normal; flow through it in that sense.
    n = (normal * area[:, None]).sum(axis=0)
    n /= np.linalg.norm(n)
    p_tri = pressure[tris].mean(axis=1)
    speed = np.linalg.norm(velocity, axis=1)
    total = pressure + dynamic_mmhg(speed)
    total_tri = total[tris].mean(axis=1)
    un = velocity @ n
    # Exact P1 integral of total * (u.n) over a triangle: (sum_i t_i u_i + sum t_i sum u_i) / 12 * 2A.
    t3, u3 = total[tris], un[tris]
    flux_total = area * ((t3 * u3).sum(axis=1) + t3.sum(axis=1) * u3.sum(axis=1)) / 12.0
    flux = (area * u3.mean(axis=1)).sum()
    nodes = np.unique(tris)
    return {
        "static_area": float((area * p_tri).sum() / area.sum()),
        "static_nodes": float(pressure[nodes].mean()),
        "total_area": float((area * total_tri).sum() / area.sum()),
        "total_flux": float(flux_total.sum() / flux) if flux != 0 else float("nan"),
        "area_mm2": float(area.sum()),
        # mm2 x m/s = 1e-6 m3/s = mL/s
        "flow_ml_s": float(flux),
        "centroid": ((points[tris].mean(axis=1) * area[:, None]).sum(axis=0) / area.sum()).tolist(),
        "normal": n.tolist(),
    }


def read_xml(path):
    reader = vtk.vtkXMLUnstructuredGridReader() if str(path).endswith(".vtu") else vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    return reader.GetOutput()


def points_of(path):
    return vtk_to_numpy(read_xml(path).GetPoints().GetData()).astype(float)


def load(peak_vtu, faces_vtp):
    grid = read_xml(peak_vtu)
    faces = read_xml(faces_vtp)
    points = vtk_to_numpy(grid.GetPoints().GetData()).astype(float)
    pressure = vtk_to_numpy(grid.GetPointData().GetArray("pressure_mmhg")).astype(float)
    velocity = vtk_to_numpy(grid.GetPointData().GetArray("velocity_m_s")).astype(float)
    gid = vtk_to_numpy(faces.GetPointData().GetArray("GlobalNodeID")).astype(np.int64) - 1
    conn = vtk_to_numpy(faces.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    labels = vtk_to_numpy(faces.GetCellData().GetArray("ModelFaceID"))
    return grid, points, pressure, velocity, gid[conn], labels


def plane_cutter(data, origin, normal):
    """A vtkCutter of `data` by the plane through `origin` with `normal` (not yet run)."""
    plane = vtk.vtkPlane()
    plane.SetOrigin(*origin)
    plane.SetNormal(*normal)
    cutter = vtk.vtkCutter()
    cutter.SetCutFunction(plane)
    cutter.SetInputData(data)
    return cutter


def shifted_plane(grid, centroid, normal, offset_mm, radius_mm):
    """plane_means on the cut of the volume by the plane through centroid + offset *
    normal, kept within radius_mm of the shifted centroid (the cut of a curved domain
    can reach other parts of it)."""
    origin = np.asarray(centroid) + offset_mm * np.asarray(normal)
    cutter = plane_cutter(grid, origin, normal)
    conn = vtk.vtkPolyDataConnectivityFilter()
    conn.SetInputConnection(cutter.GetOutputPort())
    conn.SetExtractionModeToClosestPointRegion()
    conn.SetClosestPoint(*origin)
    tri = vtk.vtkTriangleFilter()
    tri.SetInputConnection(conn.GetOutputPort())
    tri.Update()
    cut = tri.GetOutput()
    if cut.GetNumberOfCells() == 0:
        raise ValueError(f"the plane {offset_mm:+.1f} mm from {np.round(centroid, 2).tolist()} does not cut the mesh")
    pts = vtk_to_numpy(cut.GetPoints().GetData()).astype(float)
    tris = vtk_to_numpy(cut.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    tris = tris[np.linalg.norm(pts[tris].mean(axis=1) - origin, axis=1) <= radius_mm]
    p = vtk_to_numpy(cut.GetPointData().GetArray("pressure_mmhg")).astype(float)
    v = vtk_to_numpy(cut.GetPointData().GetArray("velocity_m_s")).astype(float)
    return plane_means(pts, tris, p, v)


def dp_definitions(peak_vtu, faces_vtp, planes=(11, 16), offsets_mm=()):
    """dp = plane 1 - plane 2 (mmHg) by each definition; with offsets, dp with either
    plane shifted along its flow direction (positive: downstream) by each offset."""
    grid, points, pressure, velocity, tris, labels = load(peak_vtu, faces_vtp)
    per_plane = {}
    for label in planes:
        sel = tris[labels == label]
        if len(sel) == 0:
            raise ValueError(f"{faces_vtp}: no face set with ModelFaceID {label}")
        per_plane[label] = plane_means(points, sel, pressure, velocity)
    a, b = (per_plane[p] for p in planes)
    out = {k: a[k] - b[k] for k in ("static_area", "static_nodes", "total_area", "total_flux")}
    out["planes"] = {str(k): v for k, v in per_plane.items()}
    out["vsd_plane_shifted"] = shifted_dp(grid, a, b, offsets_mm, move_first=True)
    out["aortic_plane_shifted"] = shifted_dp(grid, a, b, offsets_mm, move_first=False)
    return out


def shifted_dp(grid, a, b, offsets_mm, move_first):
    """dp with one of the two planes (a: first, b: second) moved along its flow direction
    (positive: downstream), static (area-weighted) and total (flow-weighted)."""
    moved, fixed = (a, b) if move_first else (b, a)
    # The normal points with the flow through the plane (positive flux).
    n = (1.0 if moved["flow_ml_s"] >= 0 else -1.0) * np.asarray(moved["normal"])
    radius = 1.5 * np.sqrt(moved["area_mm2"] / np.pi)
    shifted = {}
    for off in offsets_mm:
        # At offset 0 the cut runs through the face set's own triangles, where it is
        # degenerate (both neighbouring tets); the face set itself is that plane.
        m = moved if off == 0 else shifted_plane(grid, moved["centroid"], n, off, radius)
        first, second = (m, fixed) if move_first else (fixed, m)
        shifted[f"{off:+.1f}"] = {
            "dp_static_area": first["static_area"] - second["static_area"],
            "dp_total_flux": first["total_flux"] - second["total_flux"],
            "area_mm2": m["area_mm2"],
            "flow_ml_s": abs(m["flow_ml_s"]),
        }
    return shifted
