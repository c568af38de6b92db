"""vtkPolyData <-> baffle arrays (points, triangle polys, ModelFaceID), and the plane cuts
the package, its tests and the Slicer module measure sections with. Needs the `vtk` module
(the PyPI wheel, or Slicer's VTK); uses only APIs of VTK 9.1-9.5."""

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkIdTypeArray, vtkPoints
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
from vtkmodules.vtkFiltersCore import vtkStripper

from .design import DesignResult, Mesh, design
from .render import plane_cut  # noqa: F401  (render.py runs as a script on its own, so the cut lives there)

LABEL_ARRAY = "ModelFaceID"
# vtkIdType is 64-bit in the wheels and Slicer, but VTK can be built with 32-bit ids.
_ID_DTYPE = np.int64 if vtkIdTypeArray().GetDataTypeSize() == 8 else np.int32


def polydata_to_mesh(polydata: vtkPolyData, label_array: str = LABEL_ARRAY) -> Mesh:
    """Points, triangles and labels of polydata made of triangle polys only."""
    if polydata.GetNumberOfCells() != polydata.GetNumberOfPolys():
        raise ValueError("polydata has vertices, lines or strips besides polygons")
    labels = polydata.GetCellData().GetArray(label_array)
    if labels is None:
        raise ValueError(f"polydata has no cell array {label_array!r}")
    polys = polydata.GetPolys()
    offsets = numpy_support.vtk_to_numpy(polys.GetOffsetsArray()).astype(np.int64)
    connectivity = numpy_support.vtk_to_numpy(polys.GetConnectivityArray()).astype(np.int64)
    sizes = np.diff(offsets)
    if np.any(sizes != 3):
        bad = int(np.argmax(sizes != 3))
        raise ValueError(f"cell {bad} has {sizes[bad]} points; only triangles are accepted (vtkTriangleFilter)")
    return Mesh(
        points=numpy_support.vtk_to_numpy(polydata.GetPoints().GetData()).astype(np.float64).reshape(-1, 3),
        triangles=connectivity.reshape(-1, 3),
        labels=numpy_support.vtk_to_numpy(labels).astype(np.int32).ravel(),
    )


def mesh_to_polydata(mesh: Mesh, label_array: str = LABEL_ARRAY) -> vtkPolyData:
    """Polydata with the mesh's points, triangles and an int32 cell label array."""
    points = vtkPoints()
    points.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(mesh.points, dtype=np.float64), deep=1))
    offsets = np.arange(0, 3 * len(mesh.triangles) + 1, 3, dtype=np.int64)
    polys = vtkCellArray()
    polys.SetData(
        numpy_support.numpy_to_vtkIdTypeArray(offsets.astype(_ID_DTYPE), deep=1),
        numpy_support.numpy_to_vtkIdTypeArray(
            np.ascontiguousarray(mesh.triangles).ravel().astype(_ID_DTYPE), deep=1
        ),
    )
    labels = numpy_support.numpy_to_vtk(np.ascontiguousarray(mesh.labels, dtype=np.int32), deep=1)
    labels.SetName(label_array)
    polydata = vtkPolyData()
    polydata.SetPoints(points)
    polydata.SetPolys(polys)
    polydata.GetCellData().AddArray(labels)
    return polydata


def design_polydata(surface: vtkPolyData, suture_points, label_array: str = LABEL_ARRAY, **kwargs) -> DesignResult:
    """baffle.design() on a labelled vtkPolyData surface."""
    mesh = polydata_to_mesh(surface, label_array)
    return design(mesh.points, mesh.triangles, mesh.labels, suture_points, **kwargs)


def centerline_polydata(result: DesignResult) -> vtkPolyData:
    """The centerline as one polyline with point arrays s_mm and tangent (unit)."""
    points = vtkPoints()
    points.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(result.centerline_points_mm), deep=1))
    n = len(result.centerline_s_mm)
    line = vtkCellArray()
    line.SetData(
        numpy_support.numpy_to_vtkIdTypeArray(np.array([0, n], dtype=_ID_DTYPE), deep=1),
        numpy_support.numpy_to_vtkIdTypeArray(np.arange(n, dtype=_ID_DTYPE), deep=1),
    )
    polydata = vtkPolyData()
    polydata.SetPoints(points)
    polydata.SetLines(line)
    for name, values in (("s_mm", result.centerline_s_mm), ("tangent", result.centerline_tangents)):
        array = numpy_support.numpy_to_vtk(np.ascontiguousarray(values), deep=1)
        array.SetName(name)
        polydata.GetPointData().AddArray(array)
    return polydata


def joined_lines(lines: vtkPolyData) -> vtkPolyData:
    """The line segments of `lines` (a cut) joined into polylines, a closed one repeating its
    first point last."""
    stripper = vtkStripper()
    stripper.SetInputData(lines)
    stripper.JoinContiguousSegmentsOn()
    stripper.Update()
    return stripper.GetOutput()
