"""The paper's published designed domain as a `baffle` input: cm -> mm, wound outward.

published_M_final.vtp is in cm with its triangles wound inward (SimVascular); the
`baffle` commands take mm and outward surfaces. Labels (ModelFaceID) are kept.
"""
import sys

import numpy as np
import vtk
from vtk.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray, vtk_to_numpy

CM_TO_MM = 10.0


def read_vtp(path):
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    poly = reader.GetOutput()
    if poly.GetNumberOfPoints() == 0:
        raise ValueError(f"{path}: no points (not a readable .vtp)")
    return poly


def triangles(poly):
    """(n, 3) point indices of the polys; anything but triangles is an error."""
    offsets = vtk_to_numpy(poly.GetPolys().GetOffsetsArray())
    if np.any(np.diff(offsets) != 3):
        raise ValueError("the surface holds polygons other than triangles")
    return vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).reshape(-1, 3).copy()


def signed_volume(points, tris):
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    return np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0


def surface_area(path):
    """Area of a triangulated surface file, in its own units squared (cm2 for the paper's)."""
    poly = read_vtp(path)
    points = vtk_to_numpy(poly.GetPoints().GetData()).astype(float)
    tris = triangles(poly)
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())


def outward_mm(points_cm, tris):
    """Points in mm and triangles wound so that the enclosed volume is positive."""
    points = np.asarray(points_cm, dtype=float) * CM_TO_MM
    tris = np.asarray(tris)
    if signed_volume(points, tris) < 0:
        tris = tris[:, [0, 2, 1]]
    return points, tris


def write_vtp(path, points, tris, labels):
    write_poly(polydata(points, tris, labels), path)


def polydata(points, tris, labels):
    """A triangle surface from numpy points, triangles and ModelFaceID labels."""
    poly = vtk.vtkPolyData()
    pts = vtk.vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(points, dtype=float), deep=True))
    poly.SetPoints(pts)
    offsets = np.arange(0, 3 * len(tris) + 1, 3, dtype=np.int64)
    polys = vtk.vtkCellArray()
    polys.SetData(numpy_to_vtkIdTypeArray(offsets, deep=True), numpy_to_vtkIdTypeArray(np.ascontiguousarray(tris, dtype=np.int64).ravel(), deep=True))
    poly.SetPolys(polys)
    arr = numpy_to_vtk(np.ascontiguousarray(labels, dtype=np.int32), deep=True)
    arr.SetName("ModelFaceID")
    poly.GetCellData().AddArray(arr)
    return poly


def write_poly(poly, path):
    writer = vtk.vtkXMLPolyDataWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(poly)
    if not writer.Write():
        raise OSError(f"{path}: could not write")


def convert(src, dst):
    poly = read_vtp(src)
    labels = poly.GetCellData().GetArray("ModelFaceID")
    if labels is None:
        raise ValueError(f"{src}: no ModelFaceID cell array")
    points, tris = outward_mm(vtk_to_numpy(poly.GetPoints().GetData()), triangles(poly))
    write_vtp(dst, points, tris, vtk_to_numpy(labels))
    return signed_volume(points, tris)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: published.py published_M_final.vtp out.vtp")
    volume = convert(sys.argv[1], sys.argv[2])
    print(f"wrote {sys.argv[2]} (mm, outward, volume {volume:.1f} mm3)")
