"""The capped ventricle from a plain RV model (BafflePlanner's, no ModelFaceID) and two rims
the user marks on its wall as closed curves: the VSD rim and the aortic-annulus rim.

For each rim: its best-fit plane, the normal pointing out of the ventricle; the part of the
surface beyond the plane and within 1.5 rim radii of the rim's axis is cut away (what the
segmentation holds of the LV or the aorta there), the cut's one new boundary loop is checked
against the rim (the rim was marked on the wall, so the loop must follow it), and closed by a
planar cap of near-wall-sized triangles (constrained Delaunay of the loop plus a lattice
inside). Labels: 2 wall, 11 VSD cap, 16 aortic cap. vtk + numpy (no scipy in Slicer), and
the baffle package's joined_lines (the design that follows needs the package anyway)."""

from typing import List, Sequence, Tuple

import numpy as np
import vtk
from vtkmodules.util import numpy_support

from BaffleDesignerLib.candidate import BaffleDesignerError, library

LABEL_ARRAY = "ModelFaceID"
WALL, VSD_CAP, AORTIC_CAP = 2, 11, 16
CUT_RADIUS_FACTOR = 1.5  # how far from the rim's axis the cut reaches, in rim radii
# The loop the cut leaves must follow the rim: each within this fraction of the rim radius
# of the other (a rim marked on the wall lies on it; one marked off the wall, or a surface
# that does not reach the rim's plane, leaves a loop far from it).
RIM_MATCH_FRACTION = 0.25
LATTICE_CLEARANCE = 0.6  # lattice points at least this many edge lengths from the loop


def _points(polydata) -> np.ndarray:
    return numpy_support.vtk_to_numpy(polydata.GetPoints().GetData()).astype(np.float64)


def _triangles(polydata) -> np.ndarray:
    return numpy_support.vtk_to_numpy(polydata.GetPolys().GetConnectivityArray()).reshape(-1, 3)


def _polydata(points: np.ndarray, triangles: np.ndarray, label: int) -> vtk.vtkPolyData:
    polydata = vtk.vtkPolyData()
    vtk_points = vtk.vtkPoints()
    vtk_points.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float64), deep=1))
    polydata.SetPoints(vtk_points)
    cells = vtk.vtkCellArray()
    offsets = np.arange(0, 3 * len(triangles) + 1, 3, dtype=np.int64)
    cells.SetData(numpy_support.numpy_to_vtkIdTypeArray(offsets, deep=1),
                  numpy_support.numpy_to_vtkIdTypeArray(np.ascontiguousarray(triangles, dtype=np.int64).ravel(), deep=1))
    polydata.SetPolys(cells)
    _label(polydata, label)
    return polydata


def _label(polydata, value: int) -> None:
    labels = vtk.vtkIntArray()
    labels.SetName(LABEL_ARRAY)
    labels.SetNumberOfTuples(polydata.GetNumberOfCells())
    labels.Fill(value)
    polydata.GetCellData().AddArray(labels)


def boundary_loops(polydata) -> List[np.ndarray]:
    """The surface's boundary loops, each (n, 3) in order."""
    edges = vtk.vtkFeatureEdges()
    edges.SetInputData(polydata)
    edges.BoundaryEdgesOn()
    for off in (edges.FeatureEdgesOff, edges.ManifoldEdgesOff, edges.NonManifoldEdgesOff):
        off()
    edges.Update()
    _, vtk_adapters = library()
    out = vtk_adapters.joined_lines(edges.GetOutput())
    if out.GetNumberOfPoints() == 0:
        return []
    points = _points(out)
    loops, ids = [], vtk.vtkIdList()
    out.GetLines().InitTraversal()
    while out.GetLines().GetNextCell(ids):
        index = [ids.GetId(i) for i in range(ids.GetNumberOfIds())]
        if len(index) > 1 and index[0] == index[-1]:
            index = index[:-1]
        loops.append(points[index])
    return loops


def _distance_to_polyline(points: np.ndarray, loop: np.ndarray) -> np.ndarray:
    """Distance of each point to the closed polyline `loop`."""
    a, b = loop, np.roll(loop, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("pkj,kj->pk", points[:, None, :] - a[None], ab) / np.maximum((ab * ab).sum(1), 1e-300), 0, 1)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - closest, axis=2).min(axis=1)


def rim_plane(rim: np.ndarray, inside_point: np.ndarray) -> Tuple[np.ndarray, np.ndarray, float]:
    """(centre, unit normal out of the ventricle, radius in the plane) of a rim."""
    centre = rim.mean(axis=0)
    normal = np.linalg.svd(rim - centre)[2][2]
    if np.dot(inside_point - centre, normal) > 0:
        normal = -normal
    offsets = rim - centre
    radius = float(np.linalg.norm(offsets - np.outer(offsets @ normal, normal), axis=1).max())
    return centre, normal, radius


def _cut(surface, centre, normal, radius):
    """The surface without what lies beyond the plane within CUT_RADIUS_FACTOR radii of the axis."""
    cylinder = vtk.vtkCylinder()
    cylinder.SetCenter(*centre)
    cylinder.SetAxis(*normal)
    cylinder.SetRadius(CUT_RADIUS_FACTOR * radius)
    behind = vtk.vtkPlane()
    behind.SetOrigin(*centre)
    behind.SetNormal(*(-normal))
    keep = vtk.vtkImplicitBoolean()  # max(behind, cylinder) > 0: on the ventricle's side, or off the axis
    keep.SetOperationTypeToIntersection()
    keep.AddFunction(behind)
    keep.AddFunction(cylinder)
    clip = vtk.vtkClipPolyData()
    clip.SetInputData(surface)
    clip.SetClipFunction(keep)
    triangles = vtk.vtkTriangleFilter()
    triangles.SetInputConnection(clip.GetOutputPort())
    # The clip puts points a rounding error apart where it cuts through a vertex or an edge
    # twice; one point within a millionth of the rim radius, so the loop has no null edges.
    merge = vtk.vtkCleanPolyData()
    merge.SetInputConnection(triangles.GetOutputPort())
    merge.ToleranceIsAbsoluteOn()
    merge.SetAbsoluteTolerance(1e-6 * radius)
    merge.ConvertPolysToLinesOff()  # a triangle that collapses is dropped, not kept as a line
    merge.ConvertLinesToPointsOff()
    largest = vtk.vtkPolyDataConnectivityFilter()
    largest.SetInputConnection(merge.GetOutputPort())
    largest.SetExtractionModeToLargestRegion()
    clean = vtk.vtkCleanPolyData()
    clean.SetInputConnection(largest.GetOutputPort())
    clean.Update()
    return clean.GetOutput()


def planar_cap(loop: np.ndarray, normal: np.ndarray, edge_mm: float) -> Tuple[np.ndarray, np.ndarray]:
    """(points, triangles) closing the planar loop: its points first, then a triangular
    lattice at edge_mm inside; triangles wound with `normal` (out of the ventricle)."""
    centre = loop.mean(axis=0)
    e1 = np.cross(normal, [1.0, 0.0, 0.0])
    if np.linalg.norm(e1) < 0.1:
        e1 = np.cross(normal, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    uv = np.c_[(loop - centre) @ e1, (loop - centre) @ e2]
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    rows = np.arange(lo[1], hi[1], edge_mm * np.sqrt(3) / 2)
    lattice = np.array([(x, y) for j, y in enumerate(rows) for x in np.arange(lo[0] + (edge_mm / 2 if j % 2 else 0), hi[0], edge_mm)])
    if len(lattice):
        a, b = uv, np.roll(uv, -1, axis=0)
        x, y = lattice[:, :1], lattice[:, 1:]
        crossings = ((a[:, 1] > y) != (b[:, 1] > y)) & (x < (b[:, 0] - a[:, 0]) * (y - a[:, 1]) / (b[:, 1] - a[:, 1] + 1e-300) + a[:, 0])
        lattice = lattice[crossings.sum(axis=1) % 2 == 1]
    if len(lattice):
        lattice = lattice[_distance_to_polyline(np.c_[lattice, np.zeros(len(lattice))], np.c_[uv, np.zeros(len(uv))]) > LATTICE_CLEARANCE * edge_mm]
    flat = np.vstack([uv, lattice]) if len(lattice) else uv
    points = vtk.vtkPoints()
    points.SetData(numpy_support.numpy_to_vtk(np.c_[flat, np.zeros(len(flat))], deep=1))
    boundary = vtk.vtkCellArray()
    order = range(len(uv)) if np.sum(uv[:, 0] * np.roll(uv[:, 1], -1) - np.roll(uv[:, 0], -1) * uv[:, 1]) > 0 else reversed(range(len(uv)))
    boundary.InsertNextCell(len(uv))
    for i in order:  # counter-clockwise: Delaunay2D keeps the inside
        boundary.InsertCellPoint(i)
    source = vtk.vtkPolyData()
    source.SetPoints(points)
    source.SetPolys(boundary)
    cloud = vtk.vtkPolyData()
    cloud.SetPoints(points)
    delaunay = vtk.vtkDelaunay2D()
    delaunay.SetInputData(cloud)
    delaunay.SetSourceData(source)
    delaunay.Update()
    triangles = _triangles(delaunay.GetOutput()).copy()
    points_3d = np.vstack([loop, centre + np.outer(lattice[:, 0], e1) + np.outer(lattice[:, 1], e2)]) if len(lattice) else loop
    p = points_3d
    flip = np.einsum("ij,j->i", np.cross(p[triangles[:, 1]] - p[triangles[:, 0]], p[triangles[:, 2]] - p[triangles[:, 0]]), normal) < 0
    triangles[flip] = triangles[flip][:, [0, 2, 1]]
    return points_3d, triangles


def capped_ventricle(surface: vtk.vtkPolyData, rims: Sequence[Tuple[str, int, np.ndarray]]) -> vtk.vtkPolyData:
    """The closed surface with each rim's cap cut in: rims are (name, label, (n, 3) points).
    BaffleDesignerError when a rim is not on the surface or its cut is not one loop."""
    triangles = vtk.vtkTriangleFilter()
    triangles.SetInputData(surface)
    triangles.Update()
    result = vtk.vtkPolyData()
    result.DeepCopy(triangles.GetOutput())
    result.GetCellData().Initialize()
    _label(result, WALL)
    points, cells = _points(result), _triangles(result)
    if len(cells) == 0 or boundary_loops(result):
        raise BaffleDesignerError("the RV model must be a closed triangulated surface (it has open edges or no triangles)")
    edge_mm = float(np.median(np.linalg.norm(points[cells[:, 0]] - points[cells[:, 1]], axis=1)))
    mass = vtk.vtkCenterOfMass()
    mass.SetInputData(result)
    mass.Update()
    inside = np.asarray(mass.GetCenter())
    for name, label, rim in rims:
        rim = np.asarray(rim, dtype=np.float64)
        if len(rim) < 3:
            raise BaffleDesignerError(f"the {name} rim has {len(rim)} points; mark it as a closed curve of at least 3")
        centre, normal, radius = rim_plane(rim, inside)
        cut = _cut(result, centre, normal, radius)
        loops = boundary_loops(cut)
        on_plane = [loop for loop in loops if np.abs((loop - centre) @ normal).max() < 1e-3 * radius + 1e-6]
        if len(loops) != 1 or len(on_plane) != 1:
            raise _loop_count_error(name, len(loops), radius)
        loop = loops[0]
        loop_off = float(_distance_to_polyline(loop, rim).max())
        rim_off = float(_distance_to_polyline(rim, loop).max())
        if max(loop_off, rim_off) > RIM_MATCH_FRACTION * radius:
            raise BaffleDesignerError(
                f"the {name} rim is not on the RV model: the model's cut at the rim's plane is up to "
                f"{max(loop_off, rim_off):.1f} mm from the rim (allowed {RIM_MATCH_FRACTION * radius:.1f} mm, a quarter of its "
                f"{radius:.1f} mm radius); mark the rim on the RV wall, where the model reaches it")
        cap_points, cap_triangles = planar_cap(loop, normal, edge_mm)
        append = vtk.vtkAppendPolyData()
        append.AddInputData(cut)
        append.AddInputData(_polydata(cap_points, cap_triangles, label))
        merge = vtk.vtkCleanPolyData()  # the cap's loop points are the cut's own: merged exactly
        merge.SetInputConnection(append.GetOutputPort())
        merge.SetTolerance(0.0)
        merge.Update()
        result = merge.GetOutput()
    open_loops = boundary_loops(result)
    if open_loops:
        raise BaffleDesignerError(f"capping left {len(open_loops)} open loops in the surface (a bug: please report it with the model)")
    return result


def _loop_count_error(name: str, count: int, radius: float) -> BaffleDesignerError:
    return BaffleDesignerError(
        f"the {name} rim's cut (its plane, within {CUT_RADIUS_FACTOR:g} rim radii = {CUT_RADIUS_FACTOR * radius:.1f} mm "
        f"of its axis) leaves {count} open loops in the RV model instead of one on the plane; mark the rim on the "
        "RV wall, around the opening")
