#!/usr/bin/env python3
"""The estimate's VSD-plane coefficient A (dp = B K_throat - A K_vsd; docs/hemodynamics_estimate.md,
"Which plane decides dp") against what the 3D runs need of it (issue 31's criterion on p2):

    needed ROWS.jsonl... ESTIMATES_DIR   the A that puts each p1-p3 row's estimate on its 3D dp,
                                         and the A's for which one patient's rows are all within
                                         20 % or 1 mmHg (ROWS: {"patient", "row", "dp_0_6"} per
                                         line, later files win; ESTIMATES_DIR as written by
                                         hemodynamics_estimate.py --out)
    pairs OLD_FAMILY NEW_FAMILY          the 3D A of the same seeds designed twice (same LV and
                                         VSD, another tunnel) against the throat's change
    funnel EXTEND_DIR...                 the LV extension behind the VSD, cut parallel to the VSD
                                         plane: each cut's area and how far its centre lies to the
                                         side (the funnel that feeds the VSD and its tilt)

    python3 scripts/validation/vsd_plane_coefficient.py needed /work/p06/rows.jsonl /work/p06new/rows.jsonl out/hemodynamics-estimate
"""
import json
import math
import sys
from pathlib import Path

import numpy as np

import flow_family
import hemodynamics_estimate as he


def needed_a(e, dp3_mmhg):
    """The A for which the estimate `e` equals the 3D dp, its B unchanged."""
    return (e["throat_coefficient_b"] * e["k_throat_mmhg"] - dp3_mmhg) / e["k_vsd_mmhg"]


def a_window(rows):
    """The interval of A over which every (estimate, 3D dp) row is within 20 % or 1 mmHg, or
    None. Each row allows A within its tolerance / K_vsd of `needed_a`; the window is where
    all of them overlap."""
    lo, hi = -math.inf, math.inf
    for e, dp3 in rows:
        tolerance = max(0.2 * abs(dp3), 1.0) / e["k_vsd_mmhg"]
        lo, hi = max(lo, needed_a(e, dp3) - tolerance), min(hi, needed_a(e, dp3) + tolerance)
    return (lo, hi) if lo <= hi else None


def count_within(rows, a):
    """How many rows are within the criterion with A = a."""
    return sum(he.within(e["throat_coefficient_b"] * e["k_throat_mmhg"] - a * e["k_vsd_mmhg"], dp3) for e, dp3 in rows)


def estimate_of(estimates, patient, row):
    """The estimate hemodynamics_estimate.py wrote for one row."""
    return json.loads(he.output_of(estimates, patient, row)[1].read_text())["hemodynamics_estimate"]


def needed(row_files, estimates):
    dp3 = {}
    for f in row_files:
        for line in Path(f).read_text().splitlines():
            r = json.loads(line)
            if r.get("dp_0_6") is not None:
                dp3[(r["patient"], r["row"])] = r["dp_0_6"]
    by_patient = {}
    print("| patient | row | 3D dp (mmHg) | K_throat / K_vsd (mmHg) | B | A needed |")
    print("|---|---|---|---|---|---|")
    for patient, row, _ in he.CFD_ROWS:
        if (patient, row) not in dp3:
            continue
        e = estimate_of(estimates, patient, row)
        by_patient.setdefault(patient, []).append((e, dp3[(patient, row)]))
        print(f"| {patient} | {row} | {dp3[(patient, row)]:.2f} | {e['k_throat_mmhg']:.2f} / {e['k_vsd_mmhg']:.2f} | {e['throat_coefficient_b']:.3f} | {needed_a(e, dp3[(patient, row)]):.3f} |")
    print()
    for patient, rows in sorted(by_patient.items()):
        window = a_window(rows)
        first = rows[0][0]
        print(f"{patient}: all {len(rows)} rows within for A in " + (f"{window[0]:.3f}..{window[1]:.3f}" if window else "no interval")
              + f"; the code's A {first['vsd_plane_coefficient_a']}: {count_within(rows, first['vsd_plane_coefficient_a'])} of {len(rows)}")


def seeds_a_and_throat(family):
    """seed -> (3D A, designed throat mm2) of one family folder's planned members."""
    out = {}
    for line in (Path(family) / "results.jsonl").read_text().splitlines():
        r = json.loads(line)
        if "estimate" in r and "11" in r.get("planes", {}):
            out[r["seed"]] = (flow_family.plane_coefficients(r)[0], r["estimate"]["throat_area_mm2"])
    return out


def pairs(old_family, new_family):
    old, new = seeds_a_and_throat(old_family), seeds_a_and_throat(new_family)
    seeds = sorted(set(old) & set(new))
    da = np.array([new[s][0] - old[s][0] for s in seeds])
    dt = np.array([new[s][1] / old[s][1] - 1 for s in seeds])
    print(f"{Path(old_family).name} -> {Path(new_family).name}: {len(seeds)} seeds; A change 5 / 50 / 95 %: "
          + " / ".join(f"{x:+.3f}" for x in np.percentile(da, [5, 50, 95]))
          + "; throat change " + " / ".join(f"{100 * x:+.0f} %" for x in np.percentile(dt, [5, 50, 95]))
          + f"; correlation {np.corrcoef(da, dt)[0, 1]:.2f}")


def funnel_cuts(surface, vsd_centroid, normal, depth_mm, count=16):
    """Cuts of the closed surface by planes parallel to the VSD plane, 0.2 mm to depth_mm - 0.2
    behind it (`normal` pointing back into the LV): (t mm, loop area mm2, the loop's centre
    minus the VSD's centroid, projected on the plane). The loop followed is the one that holds
    the previous cut's centre (first the VSD's centroid), else the nearest."""
    import sections
    cuts, centre = [], np.asarray(vsd_centroid, float)
    for t in np.linspace(0.2, depth_mm - 0.2, count):
        origin = vsd_centroid + t * normal
        loops = sections.cut_loops(surface, origin, normal)
        if not loops:
            break
        here = centre + ((origin - centre) @ normal) * normal
        holding = [loop for loop in loops if sections.encloses(loop, here, normal)]
        loop = min(holding, key=lambda lp: sections.loop_area_mm2(lp, normal)) if holding else min(loops, key=lambda lp: np.linalg.norm(lp.mean(0) - here))
        centre = loop.mean(0)
        side = centre - vsd_centroid
        cuts.append((float(t), sections.loop_area_mm2(loop, normal), side - (side @ normal) * normal))
    return cuts


def funnel_tilt_deg(cuts, vsd_area_mm2, area_factor=2.0):
    """The angle to the VSD's normal of the cuts' centres, by least squares through the VSD's
    centroid, over the cuts up to area_factor times the VSD's area (at least the first two):
    the direction of the funnel where the flow is already near the VSD's speed."""
    near = [c for c in cuts if c[1] <= area_factor * vsd_area_mm2]
    if len(near) < 2:
        near = cuts[:2]
    t = np.array([c[0] for c in near])
    side = np.array([c[2] for c in near])
    slope = (t @ side) / (t @ t)
    return math.degrees(math.atan(np.linalg.norm(slope)))


def funnel(extend_dirs):
    import plane_energy
    for d in map(Path, extend_dirs):
        report = json.loads((d / "extended-report.json").read_text())
        vsd, inflow = (np.array(report[k]["centroid_mm"]) for k in ("vsd_cap", "inflow_cap"))
        normal = np.array(report["vsd_cap"]["normal"])
        normal = normal if normal @ (inflow - vsd) > 0 else -normal
        surface = plane_energy.read(d / "extended.vtp", plane_energy.vtk.vtkXMLPolyDataReader)
        cuts = funnel_cuts(surface, vsd, normal, float(normal @ (inflow - vsd)))
        vsd_area = report["vsd_cap"]["area_mm2"]
        print(f"{d}: VSD {vsd_area:.1f} mm2, inflow plane {normal @ (inflow - vsd):.1f} mm behind; tilt over the cuts up to 2x / 3x the VSD's area "
              f"{funnel_tilt_deg(cuts, vsd_area, 2.0):.1f} / {funnel_tilt_deg(cuts, vsd_area, 3.0):.1f} deg; cuts (mm, mm2, mm aside): "
              + ", ".join(f"{t:.1f} {a:.0f} {np.linalg.norm(s):.1f}" for t, a, s in cuts))


def main(argv):
    if len(argv) >= 3 and argv[0] == "needed":
        needed(argv[1:-1], Path(argv[-1]))
    elif len(argv) == 3 and argv[0] == "pairs":
        pairs(argv[1], argv[2])
    elif len(argv) >= 2 and argv[0] == "funnel":
        funnel(argv[1:])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main(sys.argv[1:])
