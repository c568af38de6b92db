"""Lengths of the flow-domain centerline between the VSD and aortic planes by several
definitions, to measure why ours is longer than the paper's (Table 4).

From an untrimmed path (`baffle centerline --ends 20,21 --planes 20,21`, inflow to
outflow cap) and the two planes' triangles (interior face sets of `baffle mesh`):
- discs: the path between its crossings of the two plane discs (what `baffle
  centerline --planes 11,16` reports),
- infinite_planes: between its first crossing of the VSD plane's infinite plane and its
  first crossing, after that, of the aortic plane's infinite plane (a clip by plane
  functions, as a vtkClipPolyData with vtkPlane would do),
- centroids: the straight distance between the two planes' centroids,
- closest_nodes: the shortest distance between the two planes' nodes.
"""
import numpy as np

import planes as plane_tools


def polyline_length(p):
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def crossings(path, origin, normal):
    """Parameters t (segment index + fraction) where the path crosses a plane."""
    d = (path - origin) @ normal
    out = []
    for i in range(len(d) - 1):
        if d[i] == 0.0:
            out.append(float(i))
        elif d[i] * d[i + 1] < 0:
            out.append(i + d[i] / (d[i] - d[i + 1]))
    return out


def point_at(path, t):
    i = min(int(t), len(path) - 2)
    f = t - i
    return path[i] * (1 - f) + path[i + 1] * f


def length_between(path, t0, t1):
    i0, i1 = int(np.ceil(t0)), int(np.floor(t1))
    pts = [point_at(path, t0)] + [path[i] for i in range(i0, i1 + 1) if t0 < i < t1] + [point_at(path, t1)]
    return polyline_length(np.array(pts))


def in_disc(x, points, tris):
    """x (on the plane) lies in one of the plane's triangles (barycentric, with slack)."""
    for tri in tris:
        a, b, c = points[tri]
        v0, v1, v2 = b - a, c - a, x - a
        d00, d01, d11, d20, d21 = v0 @ v0, v0 @ v1, v1 @ v1, v2 @ v0, v2 @ v1
        den = d00 * d11 - d01 * d01
        if den == 0:
            continue
        v = (d11 * d20 - d01 * d21) / den
        w = (d00 * d21 - d01 * d20) / den
        if v >= -1e-6 and w >= -1e-6 and v + w <= 1 + 1e-6:
            return True
    return False


def plane_frame(points, tris):
    area, normal = plane_tools.triangle_geometry(points, tris)
    n = (normal * area[:, None]).sum(axis=0)
    n /= np.linalg.norm(n)
    c = (points[tris].mean(axis=1) * area[:, None]).sum(axis=0) / area.sum()
    return c, n


def lengths(path, vsd, aortic):
    """vsd, aortic: (points, triangles) of each plane. Lengths in the path's units; without
    a path (None) only those of the planes themselves."""
    (cv, nv), (ca, na) = plane_frame(*vsd), plane_frame(*aortic)
    out = {"centroids": float(np.linalg.norm(cv - ca))}
    pv, pa = vsd[0][np.unique(vsd[1])], aortic[0][np.unique(aortic[1])]
    out["closest_nodes"] = float(np.min(np.linalg.norm(pv[:, None, :] - pa[None, :, :], axis=2)))
    if path is None:
        return out
    tv = crossings(path, cv, nv)
    ta = crossings(path, ca, na)
    if tv and any(t > tv[0] for t in ta):
        out["infinite_planes"] = length_between(path, tv[0], next(t for t in ta if t > tv[0]))
    dv = [t for t in tv if in_disc(point_at(path, t), *vsd)]
    da = [t for t in ta if in_disc(point_at(path, t), *aortic)]
    if dv and any(t > dv[0] for t in da):
        out["discs"] = length_between(path, dv[0], next(t for t in da if t > dv[0]))
    return out
