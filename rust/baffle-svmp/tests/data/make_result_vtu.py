"""Writes result_016.vtu the way svMultiPhysics' VTK writer does (vtkXMLUnstructuredGridWriter
defaults: appended, zlib-compressed data): 5 points, 2 tets, point arrays GlobalNodeID
(Int32, permuted), Velocity (Float64 x3) and Pressure (Float64). Node k (GlobalNodeID k+1)
has velocity (k, 10k, 100k) cm/s and pressure 1000k dyn/cm^2."""
import vtk

order = [2, 0, 4, 1, 3]  # file point i is volume node order[i]
coords = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)]
grid = vtk.vtkUnstructuredGrid()
pts = vtk.vtkPoints()
pts.SetDataTypeToDouble()
for node in order:
    pts.InsertNextPoint(coords[node])
grid.SetPoints(pts)
where = {node: i for i, node in enumerate(order)}
for tet in [(0, 1, 2, 3), (1, 4, 2, 3)]:
    ids = vtk.vtkIdList()
    for node in tet:
        ids.InsertNextId(where[node])
    grid.InsertNextCell(vtk.VTK_TETRA, ids)
gid = vtk.vtkIntArray(); gid.SetName("GlobalNodeID")
vel = vtk.vtkDoubleArray(); vel.SetName("Velocity"); vel.SetNumberOfComponents(3)
prs = vtk.vtkDoubleArray(); prs.SetName("Pressure")
for node in order:
    gid.InsertNextValue(node + 1)
    vel.InsertNextTuple3(node, 10 * node, 100 * node)
    prs.InsertNextValue(1000 * node)
for a in (gid, vel, prs):
    grid.GetPointData().AddArray(a)
w = vtk.vtkXMLUnstructuredGridWriter()
w.SetFileName("result_016.vtu")
w.SetInputData(grid)
w.Write()
