#!/usr/bin/env python3
"""Whether inviscid flow already gives the planes' kinetic energy: potential flow (Laplace for
the velocity potential, P1 finite elements on a run's own tetrahedra) through a `baffle mesh`
domain, with the CFD's plug inflow Q at the inlet (20), the potential held at 0 at the outlet
(21) and no flow through the walls. Its velocity and Bernoulli pressure (p = -rho/2 |u|^2,
total pressure 0 everywhere) are written as potential.vtu beside the mesh, in the names of a
`baffle simulate` result, so plane_energy.py's face integrals measure both alike.

    python3 scripts/validation/potential_flow.py MESH_DIR Q_ML_S [RUN_DIR]

prints, for the potential flow and (with RUN_DIR) the run's peak, dp between planes 11 and 16
and each plane's static pressure below plane 11's flow-weighted total (mmHg)."""
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sparse
import scipy.sparse.linalg as sparse_linalg
import vtk
from vtk.util.numpy_support import vtk_to_numpy

sys.path.insert(0, str(Path(__file__).resolve().parent))
import plane_energy  # noqa: E402

RHO_G_CM3, DYN_CM2_PER_MMHG = plane_energy.RHO_G_CM3, plane_energy.DYN_CM2_PER_MMHG


def barycentric_gradients(x_cm, tets):
    """Per tetrahedron: the gradients (1/cm) of its four P1 shape functions, and its volume."""
    x = x_cm[tets]
    edges = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]], axis=1)
    grads = np.zeros((len(tets), 4, 3))
    grads[:, 1:, :] = np.transpose(np.linalg.inv(edges), (0, 2, 1))
    grads[:, 0, :] = -grads[:, 1:, :].sum(1)
    return grads, np.abs(np.linalg.det(edges)) / 6


def potential_velocity(x_cm, tets, inlet_tris, outlet_nodes, q_ml_s):
    """Nodal velocity (cm/s) of the potential flow: -grad phi with laplace(phi) = 0, a uniform
    normal velocity Q / A_inlet entering through `inlet_tris`, phi = 0 on `outlet_nodes`; the
    tetrahedra's constant gradients averaged to the nodes by volume."""
    n = len(x_cm)
    grads, vol = barycentric_gradients(x_cm, tets)
    local = np.einsum("mik,mjk->mij", grads, grads) * vol[:, None, None]
    stiffness = sparse.csr_matrix((local.ravel(), (np.repeat(tets, 4, axis=1).ravel(), np.tile(tets, (1, 4)).ravel())), shape=(n, n))
    xi = x_cm[inlet_tris]
    tri_area = np.linalg.norm(np.cross(xi[:, 1] - xi[:, 0], xi[:, 2] - xi[:, 0]), axis=1) / 2
    inflow = np.zeros(n)
    for k in range(3):
        np.add.at(inflow, inlet_tris[:, k], q_ml_s / tri_area.sum() * tri_area / 3)
    free = np.setdiff1d(np.arange(n), outlet_nodes)
    phi = np.zeros(n)
    phi[free] = sparse_linalg.spsolve(stiffness[free][:, free].tocsc(), inflow[free])
    u_tet = -np.einsum("mi,mik->mk", phi[tets], grads)
    u_sum, weight = np.zeros((n, 3)), np.zeros(n)
    for k in range(4):
        np.add.at(u_sum, tets[:, k], u_tet * vol[:, None])
        np.add.at(weight, tets[:, k], vol)
    return u_sum / weight[:, None]


def solve_mesh(mesh_dir, q_ml_s, inlet=20, outlet=21):
    """potential.vtu for one `baffle mesh` output folder (mesh.vtu in mm, mesh-faces.vtp)."""
    grid = plane_energy.read(mesh_dir / "mesh.vtu", vtk.vtkXMLUnstructuredGridReader)
    x_cm = vtk_to_numpy(grid.GetPoints().GetData()) * 0.1
    tets = vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(-1, 4)
    faces = plane_energy.read(mesh_dir / "mesh-faces.vtp", vtk.vtkXMLPolyDataReader)
    locator = vtk.vtkPointLocator()
    locator.SetDataSet(grid)
    locator.BuildLocator()
    node = np.array([locator.FindClosestPoint(p) for p in vtk_to_numpy(faces.GetPoints().GetData())])
    tris = node[vtk_to_numpy(faces.GetPolys().GetConnectivityArray()).reshape(-1, 3)]
    labels = vtk_to_numpy(faces.GetCellData().GetArray("ModelFaceID"))
    start = time.monotonic()
    u = potential_velocity(x_cm, tets, tris[labels == inlet], np.unique(tris[labels == outlet]), q_ml_s)
    seconds = time.monotonic() - start
    pressure_mmhg = -0.5 * RHO_G_CM3 * (u ** 2).sum(1) / DYN_CM2_PER_MMHG
    path = plane_energy.write_result(grid, u / 100.0, pressure_mmhg, mesh_dir / "potential.vtu")
    return path, seconds, len(x_cm), len(tets)


def plane_line(name, faces, result):
    f = {k: plane_energy.face_integrals(faces, result, k) for k in (11, 16)}
    total11 = f[11]["total"]
    return (f"{name}: dp 11-16 {f[11]['p'] - f[16]['p']:.2f}, P11 - p11 {total11 - f[11]['p']:.2f}, P11 - p16 {total11 - f[16]['p']:.2f}, "
            f"KE flux 11 {f[11]['ke']:.2f} / 16 {f[16]['ke']:.2f} mmHg")


def main(argv):
    if len(argv) < 2:
        print(__doc__)
        return 2
    mesh_dir = Path(argv[0])
    result, seconds, nodes, tets = solve_mesh(mesh_dir, float(argv[1]))
    faces = plane_energy.read(mesh_dir / "mesh-faces.vtp", vtk.vtkXMLPolyDataReader)
    print(f"{mesh_dir}: {nodes} nodes, {tets} tetrahedra, potential solved in {seconds:.2f} s")
    print(plane_line("potential flow", faces, result))
    if len(argv) > 2:
        print(plane_line("3D run", faces, Path(argv[2]) / "peak.vtu"))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
