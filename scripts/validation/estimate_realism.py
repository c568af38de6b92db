"""How far the design's dp estimate moves when p1-p3's design input looks like another
acquisition of the same heart (issue 31: the estimate on anatomy as it comes, not as the
paper's files hold it).

    python3 scripts/validation/estimate_realism.py [--baffle target/release/baffle] [--out DIR] [--flow-sections]

For each patient the capped ventricle and suture points of design_input/ are perturbed as a
segmentation or a scene may differ, and designed at z = 0 with the paper's BSA and peak flow:

- turned: the scene rotated by (37, -23, 61) degrees and moved by (12, -40, 25) mm;
- caps off plane: each cap's points moved along its normal by a saddle of +-0.75 % of its
  diameter (planar to 1.5 %, as the held-back patient's caps);
- walls noisy: every wall point not on a cap moved by up to 0.1 mm along each axis;
- walls smoothed: 10 rounds of Taubin smoothing (0.5, -0.53) of the wall points, caps fixed;
- subdivided: every triangle split in four (finer than the segmentation's voxels);
- decimated: the wall's triangles cut by 75 % (median edge 0.40 -> 0.74 mm, as a coarser
  segmentation gives), the caps unchanged.

It prints dp_estimate_mmhg and the throat's area for each, and the change from the
unperturbed design, to be read against the estimate's stated error range. `--flow-sections`
designs with `baffle design --flow-sections` (the sections the area constraint holds normal
to the flow, the sections the estimate reads its throat from).
"""
import argparse
import json
import sys
from pathlib import Path

import numpy as np
import vtk
from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy

sys.path.insert(0, str(Path(__file__).resolve().parent))
import hemodynamics_estimate as he  # noqa: E402
from published import polydata, read_vtp, triangles, write_poly  # noqa: E402

CAPS = (11, 16)


def triangles_and_labels(poly):
    return triangles(poly), vtk_to_numpy(poly.GetCellData().GetArray("ModelFaceID"))


def with_points(poly, points):
    out = vtk.vtkPolyData()
    out.DeepCopy(poly)
    out.GetPoints().SetData(numpy_to_vtk(np.ascontiguousarray(points), deep=True))
    return out


def cap_points(poly):
    tris, labels = triangles_and_labels(poly)
    return {label: np.unique(tris[labels == label]) for label in CAPS}


def turned(poly, markups):
    a = np.radians([37.0, -23.0, 61.0])
    c, s = np.cos(a), np.sin(a)
    rotation = (np.array([[1, 0, 0], [0, c[0], -s[0]], [0, s[0], c[0]]]) @ np.array([[c[1], 0, s[1]], [0, 1, 0], [-s[1], 0, c[1]]])
                @ np.array([[c[2], -s[2], 0], [s[2], c[2], 0], [0, 0, 1]]))
    shift = np.array([12.0, -40.0, 25.0])
    move = lambda p: p @ rotation.T + shift  # noqa: E731
    # The surface is in LPS (Slicer's files); RAS markups are turned in the same frame.
    flip = np.diag([-1.0, -1.0, 1.0]) if markups["markups"][0].get("coordinateSystem") == "RAS" else np.eye(3)
    for point in markups["markups"][0]["controlPoints"]:
        point["position"] = (flip @ move(flip @ np.array(point["position"]))).tolist()
    return with_points(poly, move(vtk_to_numpy(poly.GetPoints().GetData()))), markups


def caps_off_plane(poly, markups, fraction=0.0075):
    """Each cap's points moved along its best-fit normal by fraction * diameter * cos(2 phi)."""
    points = vtk_to_numpy(poly.GetPoints().GetData()).copy()
    for ids in cap_points(poly).values():
        p = points[ids]
        centre = p.mean(axis=0)
        _, _, vt = np.linalg.svd(p - centre)
        u, v, normal = vt
        radius = np.linalg.norm(p - centre, axis=1).max()
        phi = np.arctan2((p - centre) @ v, (p - centre) @ u)
        points[ids] = p + np.outer(fraction * 2 * radius * np.cos(2 * phi), normal)
    return with_points(poly, points), markups


def wall_points(poly):
    on_cap = np.zeros(poly.GetNumberOfPoints(), bool)
    for ids in cap_points(poly).values():
        on_cap[ids] = True
    return ~on_cap


def walls_noisy(poly, markups, amplitude_mm=0.1, seed=31):
    points = vtk_to_numpy(poly.GetPoints().GetData()).copy()
    free = wall_points(poly)
    points[free] += np.random.default_rng(seed).uniform(-amplitude_mm, amplitude_mm, (free.sum(), 3))
    return with_points(poly, points), markups


def walls_smoothed(poly, markups, rounds=10):
    points = vtk_to_numpy(poly.GetPoints().GetData()).copy()
    free = wall_points(poly)
    tris, _ = triangles_and_labels(poly)
    edges = np.unique(np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1), axis=0)
    degree = np.bincount(edges.ravel(), minlength=len(points)).astype(float)
    for _ in range(rounds):
        for factor in (0.5, -0.53):
            summed = np.zeros_like(points)
            np.add.at(summed, edges[:, 0], points[edges[:, 1]])
            np.add.at(summed, edges[:, 1], points[edges[:, 0]])
            step = summed / np.maximum(degree, 1)[:, None] - points
            points[free] += factor * step[free]
    return with_points(poly, points), markups


def subdivided(poly, markups):
    f = vtk.vtkLinearSubdivisionFilter()
    f.SetInputData(poly)
    f.SetNumberOfSubdivisions(1)
    f.Update()
    return f.GetOutput(), markups


def decimated(poly, markups, reduction=0.75):
    """The wall re-triangulated coarser (p1-p3's median edge 0.40 -> about 0.74 mm), as a
    segmentation at coarser voxels gives; the caps and the wall's rim on them unchanged, so
    the labels stay exact. At 0.8 vtkDecimatePro folds p3's wall near the VSD rim (the input
    then crosses itself, and the design refuses it there)."""
    tris, labels = triangles_and_labels(poly)
    wall = labels == 2
    coarse = vtk.vtkDecimatePro()
    coarse.SetInputData(cells(poly, np.nonzero(wall)[0]))
    coarse.SetTargetReduction(reduction)
    coarse.PreserveTopologyOn()
    coarse.BoundaryVertexDeletionOff()
    coarse.SplittingOff()
    coarse.Update()
    kept = vtk.vtkPolyData()
    kept.DeepCopy(coarse.GetOutput())
    wall_tris = triangles(kept)
    caps = cells(poly, np.nonzero(~wall)[0])
    points = np.concatenate([vtk_to_numpy(kept.GetPoints().GetData()), vtk_to_numpy(caps.GetPoints().GetData())])
    faces = np.concatenate([wall_tris, triangles(caps) + kept.GetNumberOfPoints()])
    face_ids = np.concatenate([np.full(len(wall_tris), 2), labels[~wall]])
    # The rim's points are the same coordinates on both sides: merged exactly.
    _, first, inverse = np.unique(points, axis=0, return_index=True, return_inverse=True)
    faces = inverse.ravel()[faces]
    # vtkDecimatePro leaves a few folded fins (a triangle and its reverse): no surface.
    _, back, count = np.unique(np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True)
    single = count[back.ravel()] == 1
    used, faces = np.unique(faces[single], return_inverse=True)
    return polydata(points[first][used], faces.reshape(-1, 3), face_ids[single]), markups


def cells(poly, ids):
    keep = vtk.vtkIdList()
    for i in ids:
        keep.InsertNextId(int(i))
    extract = vtk.vtkExtractCells()
    extract.SetInputData(poly)
    extract.SetCellList(keep)
    surface = vtk.vtkGeometryFilter()
    surface.SetInputConnection(extract.GetOutputPort())
    surface.Update()
    return surface.GetOutput()


PERTURBATIONS = {"turned": turned, "caps off plane": caps_off_plane, "walls noisy": walls_noisy,
                 "walls smoothed": walls_smoothed, "subdivided": subdivided, "decimated": decimated}


def design(baffle, folder, info, out, extra):
    argv = [baffle, "design", "--surface", folder / "capped_ventricle.vtp", "--points", folder / "suture_points.mrk.json",
            "--bsa", info["bsa_m2"], "--z-score", 0, "--peak-flow-ml-s", info["q_peak_ml_s"], "--out", out, *extra]
    report, why = he.baffle_report(argv, out / "report.json")
    return (report["hemodynamics_estimate"] if report else None), why


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baffle", default="target/release/baffle")
    parser.add_argument("--out", default="out/estimate-realism", type=Path)
    parser.add_argument("--flow-sections", action="store_true")
    args = parser.parse_args()
    extra = ["--flow-sections"] if args.flow_sections else []
    data = he.data_dir()
    patients = json.loads((data / "patients.json").read_text())["patients"]
    print("| patient | input | dp estimate (mmHg) | change (mmHg) | throat (mm2) | change |")
    print("|---|---|---|---|---|---|")
    for patient in ("p1", "p2", "p3"):
        source = data / patient / "design_input"
        base, why = design(args.baffle, source, patients[patient], args.out / patient / "as-given", extra)
        if base is None:
            print(f"| {patient} | as given | no design: {why} | | | |")
            continue
        print(f"| {patient} | as given | {base['dp_estimate_mmhg']:.2f} | | {base['throat_area_mm2']:.1f} | |")
        for name, perturb in PERTURBATIONS.items():
            folder = args.out / patient / name.replace(" ", "-")
            folder.mkdir(parents=True, exist_ok=True)
            poly, markups = perturb(read_vtp(source / "capped_ventricle.vtp"), json.loads((source / "suture_points.mrk.json").read_text()))
            write_poly(poly, folder / "capped_ventricle.vtp")
            (folder / "suture_points.mrk.json").write_text(json.dumps(markups))
            e, why = design(args.baffle, folder, patients[patient], folder / "design", extra)
            if e is None:
                print(f"| {patient} | {name} | refused: {why} | | | |")
                continue
            print(f"| {patient} | {name} | {e['dp_estimate_mmhg']:.2f} | {e['dp_estimate_mmhg'] - base['dp_estimate_mmhg']:+.2f} | "
                  f"{e['throat_area_mm2']:.1f} | {e['throat_area_mm2'] / base['throat_area_mm2'] - 1:+.1%} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
