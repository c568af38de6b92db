"""BafflePlanner's input as a user has it, made from the library's phantom: a plain RV model
(a closed surface without ModelFaceID, bulging past the VSD and the aortic annulus, as a
segmentation's RV does there) and the two rims a user marks on its wall around them
(the phantom caps' boundaries). The phantom's caps are flat, so cutting the plain model at
the rims and capping gives back the phantom itself."""

import numpy as np
import vtk

import baffle
from baffle import vtk_adapters
from BaffleDesignerLib import rims

DOME_HEIGHT_RIM_RADII = 0.5  # how far the bulge rises past each rim's plane, in rim radii


def cap_rim(polydata, label):
    threshold = vtk.vtkThreshold()
    threshold.SetInputData(polydata)
    threshold.SetInputArrayToProcess(0, 0, 0, vtk.vtkDataObject.FIELD_ASSOCIATION_CELLS, "ModelFaceID")
    threshold.SetLowerThreshold(label - 0.5)
    threshold.SetUpperThreshold(label + 0.5)
    surface = vtk.vtkGeometryFilter()
    surface.SetInputConnection(threshold.GetOutputPort())
    surface.Update()
    (rim,) = rims.boundary_loops(surface.GetOutput())
    return rim


def plain_phantom():
    """(plain RV polydata, VSD rim (n, 3), aortic rim (m, 3), suture points, BSA, the phantom mesh)."""
    mesh, points, bsa = baffle.phantom()
    labelled = vtk_adapters.mesh_to_polydata(mesh)
    domed = mesh.points.copy()
    rim_points = {}
    for label in (rims.VSD_CAP, rims.AORTIC_CAP):
        rim = cap_rim(labelled, label)
        rim_points[label] = rim
        centre, normal, radius = rims.rim_plane(rim, mesh.points.mean(axis=0))
        on_rim = {tuple(p) for p in np.round(rim, 9)}
        for vertex in np.unique(mesh.triangles[mesh.labels == label]):
            if tuple(np.round(mesh.points[vertex], 9)) in on_rim:
                continue
            offset = mesh.points[vertex] - centre
            d = np.linalg.norm(offset - (offset @ normal) * normal)
            domed[vertex] += normal * DOME_HEIGHT_RIM_RADII * radius * max(0.0, 1.0 - (d / radius) ** 2)
    plain = vtk_adapters.mesh_to_polydata(type(mesh)(domed, mesh.triangles, mesh.labels))
    plain.GetCellData().RemoveArray("ModelFaceID")
    return plain, rim_points[rims.VSD_CAP], rim_points[rims.AORTIC_CAP], points, bsa, mesh
