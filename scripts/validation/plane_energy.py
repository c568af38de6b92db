#!/usr/bin/env python3
"""Where two runs on the same mesh differ: at each labelled face of `mesh-faces.vtp`, the
area-averaged static pressure, the flow-weighted total pressure and the kinetic-energy flux
of a run's `peak.vtu` (points in mm, `velocity_m_s`, `pressure_mmhg`), re-measured here with
VTK rather than read from either engine's summary.

    python3 scripts/validation/plane_energy.py MESH_DIR RUN_DIR [RUN_DIR ...]

prints, per run, dp between the planes 11 and 16, the total-pressure loss between them,
the kinetic-energy flux at each, and the losses from the inlet (20) to plane 11 and from
plane 16 to the outlet (21), and the static pressure at planes 11 and 16 below plane 11's
flow-weighted total P11 (flow_family.py's plane coefficients A and B times K_vsd and K_throat), in mmHg. Triangle integrals use the edge-midpoint rule (exact
for the quadratic products of P1 fields)."""
import sys
from pathlib import Path

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

RHO_G_CM3 = 1.06
DYN_CM2_PER_MMHG = 1333.22


def read(path, reader):
    r = reader()
    r.SetFileName(str(path))
    r.Update()
    return r.GetOutput()


def write_result(grid, velocity_m_s, pressure_mmhg, path):
    """`grid` (a vtkUnstructuredGrid, points in mm) with nodal velocity and pressure in the
    names of a `baffle simulate` result, written to `path` (.vtu)."""
    from vtk.util.numpy_support import numpy_to_vtk
    out = vtk.vtkUnstructuredGrid()
    out.DeepCopy(grid)
    out.GetPointData().Initialize()
    for name, values in (("velocity_m_s", velocity_m_s), ("pressure_mmhg", pressure_mmhg)):
        array = numpy_to_vtk(np.ascontiguousarray(values, dtype=float), deep=1)
        array.SetName(name)
        out.GetPointData().AddArray(array)
    writer = vtk.vtkXMLUnstructuredGridWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(out)
    writer.Write()
    return path


def face_integrals(faces, run_vtu, label):
    """Area, flow (ml/s), area-mean p, flow-weighted p and KE flux (mmHg) over one face, and the
    angle between the face's normal and the flow crossing it (flux-weighted mean in-plane speed
    against normal speed, degrees)."""
    grid = read(run_vtu, vtk.vtkXMLUnstructuredGridReader)
    locator = vtk.vtkPointLocator()
    locator.SetDataSet(grid)
    locator.BuildLocator()
    points = vtk_to_numpy(faces.GetPoints().GetData())
    tris = vtk_to_numpy(faces.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    labels = vtk_to_numpy(faces.GetCellData().GetArray("ModelFaceID"))
    node = np.array([locator.FindClosestPoint(p) for p in points])
    u = vtk_to_numpy(grid.GetPointData().GetArray("velocity_m_s")) * 100.0
    p = vtk_to_numpy(grid.GetPointData().GetArray("pressure_mmhg")) * DYN_CM2_PER_MMHG
    t = tris[labels == label]
    if len(t) == 0:
        raise ValueError(f"no face {label} in the faces file")
    x = points[t] * 0.1
    normal2 = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    area = np.linalg.norm(normal2, axis=1) / 2
    unit = normal2 / (2 * area[:, None])
    ids = node[t]
    p_mean = flux = ke = pq = np.zeros(len(t))
    # |u_n| u_n and |u_n| |u_t| summed: the flow's mean normal and in-plane speeds, weighted by flux.
    normal_weighted = tangential_weighted = np.zeros(len(t))
    for i, j in ((0, 1), (1, 2), (2, 0)):
        um = (u[ids[:, i]] + u[ids[:, j]]) / 2
        pm = (p[ids[:, i]] + p[ids[:, j]]) / 2
        un = (um * unit).sum(1)
        p_mean = p_mean + pm / 3
        flux = flux + un / 3
        ke = ke + 0.5 * RHO_G_CM3 * (um ** 2).sum(1) * un / 3
        pq = pq + pm * un / 3
        normal_weighted = normal_weighted + un * np.abs(un) / 3
        tangential_weighted = tangential_weighted + np.abs(un) * np.linalg.norm(um - un[:, None] * unit, axis=1) / 3
    q = (flux * area).sum()
    return {
        "crossing_angle_deg": float(np.degrees(np.arctan2((tangential_weighted * area).sum(), abs((normal_weighted * area).sum())))),
        "p": (p_mean * area).sum() / area.sum() / DYN_CM2_PER_MMHG,
        "total": ((pq + ke) * area).sum() / q / DYN_CM2_PER_MMHG,
        "ke": (ke * area).sum() / q / DYN_CM2_PER_MMHG,
        "flow_ml_s": abs(q),
    }


def main(argv):
    if len(argv) < 2:
        print(__doc__)
        return 2
    faces = read(Path(argv[0]) / "mesh-faces.vtp", vtk.vtkXMLPolyDataReader)
    for run in argv[1:]:
        f = {k: face_integrals(faces, Path(run) / "peak.vtu", k) for k in (20, 11, 16, 21)}
        print(f"{run}: dp 11-16 {f[11]['p'] - f[16]['p']:.3f}, total-pressure loss 11-16 {f[11]['total'] - f[16]['total']:.3f}, "
              f"KE flux 11 {f[11]['ke']:.3f} / 16 {f[16]['ke']:.3f}, loss 20-11 {f[20]['total'] - f[11]['total']:.3f}, "
              f"loss 16-21 {f[16]['total'] - f[21]['total']:.3f}, P11 - p11 {f[11]['total'] - f[11]['p']:.3f}, "
              f"P11 - p16 {f[11]['total'] - f[16]['p']:.3f} mmHg; flow at 16 {f[16]['flow_ml_s']:.2f} ml/s; "
              f"the flow crosses 11 at {f[11]['crossing_angle_deg']:.1f} and 16 at {f[16]['crossing_angle_deg']:.1f} degrees from their normals")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
