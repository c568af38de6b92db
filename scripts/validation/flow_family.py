#!/usr/bin/env python3
"""Issue 31's flow family: the reduced-order dp estimate against the 3D first-peak dp on synthetic
hearts (`cargo run --release -p baffle-prepare --example flow_family DIR`), each planned with
`baffle plan --quick --single-mesh` at its drawn body size, target z-score and cardiac index.

    python3 scripts/validation/flow_family.py run DIR [--baffle B] [--edge-length-mm 0.6]
    python3 scripts/validation/flow_family.py table DIR [DIR ...] [--patients OUT] [--baffle B]

`run` plans every member folder of DIR not yet in DIR/results.jsonl and writes one line of
results per member there (failures with their error; the 3D planes re-measured with VTK);
`table` prints (markdown) the planes' kinetic-energy coefficients against the model's uniform
flow, the planes' pressure coefficients A and B (plane_coefficients), and the error distribution
of the derived stenosis model (the code's estimate before the planes' coefficients) and of
three models fitted on the fit part (`--fit-part`, by default the even seeds; the median plane coefficients are the code's estimate), on the held-out seeds and, with --patients, on p1-p3's 21 rows of hemodynamics_estimate.py
(their estimates made into OUT).
"""
import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

BP_MMHG = "100/60"


def plan_member(baffle, member_dir, edge_mm):
    """Plan one member; returns its results row (the 3D run's and the estimate's figures)."""
    inputs = json.loads((member_dir / "member.json").read_text())
    p = inputs["plan"]
    out = member_dir / "plan"
    argv = [baffle, "plan", "--segmentations", member_dir, "--points", member_dir / "suture_points.mrk.json",
            "--bsa", p["bsa_m2"], "--z-score", p["z_score"], "--cardiac-index", p["cardiac_index_l_min_m2"],
            "--bp", BP_MMHG, "--quick", "--single-mesh", "--edge-length-mm", edge_mm, "--out", out]
    start = time.monotonic()
    run = subprocess.run([str(a) for a in argv], capture_output=True, text=True)
    row = {"seed": inputs["seed"], "shape": inputs["shape"], "plan": p, "edge_length_mm": edge_mm,
           "wall_s": round(time.monotonic() - start, 1)}
    if run.returncode != 0:
        lines = run.stderr.strip().splitlines() or ["failed"]
        row["error"] = next((l for l in lines if l.startswith("baffle: error")), lines[-1])[:600]
        return row
    report = json.loads((out / "report.json").read_text())
    estimate = report["hemodynamics_estimate"]
    row["estimate"] = estimate["design"]
    row["comparison"] = estimate["comparison_with_3d"]
    row["verdict"] = report["verdict"]
    row["planes"] = plane_figures(out)
    return row


def plane_figures(plan_dir):
    """The 3D run's planes 11 and 16 re-measured with VTK (plane_energy.py): area-mean static
    pressure, flow-weighted total pressure, kinetic-energy flux (mmHg) and flow (ml/s)."""
    import plane_energy
    faces = plane_energy.read(plan_dir / "mesh-nominal" / "mesh-faces.vtp", plane_energy.vtk.vtkXMLPolyDataReader)
    peak = plan_dir / "simulate-nominal" / "peak.vtu"
    return {str(k): {name: float(v) for name, v in plane_energy.face_integrals(faces, peak, k).items()} for k in (20, 11, 16)}


def vector_angle_deg(a, b):
    import numpy as np
    return math.degrees(math.acos(max(-1.0, min(1.0, float(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b))))))


def inflow_and_outflow_angles(plan_dir):
    """From the extended domain's report: how far off the VSD plane's normal (into the tunnel)
    the mid-LV inflow cap's centre lies behind the VSD, and the aortic plane's centre ahead of
    it (degrees). The first is the LV's obliquity, which the design's inputs do not hold."""
    import numpy as np
    ext = json.loads((plan_dir / "extend" / "extended-report.json").read_text())
    vsd, aortic, inflow = (np.array(ext[k]["centroid_mm"]) for k in ("vsd_cap", "aortic_cap", "inflow_cap"))
    normal = np.array(ext["vsd_cap"]["normal"])
    normal = normal if normal @ (aortic - vsd) > 0 else -normal
    return {"inflow_deg": vector_angle_deg(normal, vsd - inflow), "outflow_deg": vector_angle_deg(normal, aortic - vsd)}


def run(args):
    family = Path(args.dir)
    results = family / "results.jsonl"
    done = set()
    if results.exists():
        done = {json.loads(line)["seed"] for line in results.read_text().splitlines() if line.strip()}
    members = sorted(d for d in family.iterdir() if (d / "member.json").exists())
    with results.open("a") as sink:
        for d in members:
            seed = json.loads((d / "member.json").read_text())["seed"]
            if seed in done:
                continue
            row = plan_member(args.baffle, d, args.edge_length_mm)
            sink.write(json.dumps(row) + "\n")
            sink.flush()
            dp = row.get("comparison", {}) or {}
            print(f"m{seed:03d}: {row.get('error') or 'dp 3D %.2f, estimate %.2f' % (dp.get('dp_3d_mmhg', float('nan')), dp.get('dp_estimate_mmhg', float('nan')))} ({row['wall_s']} s)", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run")
    r.add_argument("dir")
    r.add_argument("--baffle", default="target/release/baffle")
    r.add_argument("--edge-length-mm", type=float, default=0.6)
    t = sub.add_parser("table")
    t.add_argument("dir", nargs="+", help="one or more family folders; the fit takes the seeds of --fit-part of all")
    t.add_argument("--fit-part", default="2:0", metavar="M:R",
                   help="the fit part is the members whose seed is R modulo M (default 2:0, the even seeds; 4:1 for folders that hold odd seeds only); the rest are held out")
    t.add_argument("--patients", type=Path, help="also the 21 p1-p3 rows of hemodynamics_estimate.py, estimated into this folder")
    t.add_argument("--baffle", default="target/release/baffle")
    t.add_argument("--re-estimate", action="store_true",
                   help="estimate every member's designed domain again with --baffle (baffle centerline --peak-flow-ml-s) instead of reading its plan's report")
    args = ap.parse_args()
    if args.command == "run":
        run(args)
    else:
        table(args)


RHO_G_CM3, DYN_CM2_PER_MMHG = 1.06, 1333.22


def dynamic_mmhg(e, area_key):
    """rho/2 (Q/A)^2 of one section of the estimate `e` (mmHg)."""
    u_cm_s = e["peak_flow_ml_s"] / (e[area_key] * 1e-2)
    return RHO_G_CM3 / 2 * u_cm_s ** 2 / DYN_CM2_PER_MMHG


def regressors(e):
    """The dynamic pressures of the throat, the aortic plane and the VSD plane, and the friction."""
    return [dynamic_mmhg(e, "throat_area_mm2"), dynamic_mmhg(e, "aortic_area_mm2"), -dynamic_mmhg(e, "vsd_area_mm2"), e["friction_mmhg"]]


def tolerance_mmhg(dp):
    """Issue 31's criterion: within 20 % or 1 mmHg, whichever is larger."""
    return max(0.2 * abs(dp), 1.0)


def dynamic_regressors(e):
    """The throat's, the aortic plane's and (minus) the VSD plane's dynamic pressures."""
    return regressors(e)[:3]


def jet_regressors(e):
    """The dynamic pressure of the model's jet at the aortic plane (a top-hat of the jet's area
    there: the throat's, spread as a free round jet, at most the plane's) and the VSD plane's."""
    return [dynamic_mmhg(e, "jet_area_at_aortic_plane_mm2"), -dynamic_mmhg(e, "vsd_area_mm2")]


def fit_weights(rows, regressors_of):
    """Least squares of dp_3D - friction on `regressors_of(estimate)`, each row weighted by its
    tolerance, so the fit minimises the error in units of the criterion."""
    import numpy as np
    x = np.array([regressors_of(e) for e, _ in rows])
    y = np.array([dp - e["friction_mmhg"] for e, dp in rows])
    w = np.array([1 / tolerance_mmhg(dp) for _, dp in rows])
    coef, *_ = np.linalg.lstsq(x * w[:, None], y * w, rcond=None)
    return coef


def predicted_mmhg(coef, regressors_of, e):
    return sum(c * v for c, v in zip(coef, regressors_of(e))) + e["friction_mmhg"]


def fit_dynamic_weights(rows):
    """dp_3D = a K_t + b K_ao + c (-K_vsd) + friction."""
    return fit_weights(rows, dynamic_regressors)


def fitted_mmhg(coef, e):
    return predicted_mmhg(coef, dynamic_regressors, e)


def fit_jet_weights(rows):
    """dp_3D = a K_jet - b K_vsd + friction: a and b are the planes' kinetic-energy
    coefficients the 3D flow shows on average."""
    return fit_weights(rows, jet_regressors)


def jet_fitted_mmhg(coef, e):
    return predicted_mmhg(coef, jet_regressors, e)


def stenosis_model_mmhg(e):
    """The derived one-throat stenosis model's dp: `stenosis_model_dp_mmhg`, or
    `dp_estimate_mmhg` in reports written while it was the code's estimate."""
    return e.get("stenosis_model_dp_mmhg", e["dp_estimate_mmhg"])


def plane_coefficients(r):
    """The 3D run's static pressure at each plane below the VSD plane's flow-weighted total
    pressure P11, in units of a section's dynamic pressure: A = (P11 - p11) / K_vsd at the VSD
    plane, B = (P11 - p16) / K_throat at the aortic plane (the losses and the kinetic energy
    left there), so that the 3D dp = p11 - p16 = B K_throat - A K_vsd exactly. A 1D model of
    the tunnel has to predict these two numbers."""
    e, planes = r["estimate"], r["planes"]
    total11 = planes["11"]["total"]
    return ((total11 - planes["11"]["p"]) / dynamic_mmhg(e, "vsd_area_mm2"),
            (total11 - planes["16"]["p"]) / dynamic_mmhg(e, "throat_area_mm2"))


def fit_plane_coefficients(fit_rows):
    """The median A and B (plane_coefficients) over the fit part's members."""
    import numpy as np
    a, b = zip(*(plane_coefficients(r) for r in fit_rows))
    return float(np.median(a)), float(np.median(b))


def fit_plane_line(fit_rows):
    """A's median and B = B0 + B1 sigma + B2 rho by least squares over the fit part's members,
    sigma the estimate's `contraction_ratio` (the throat over the widest flow-normal section)
    and rho its `mean_section_aspect_ratio` (the sections' mean minor over major radius of
    gyration): the code's rule (VSD_PLANE_COEFFICIENT_A, THROAT_COEFFICIENT_B0/1/2)."""
    import numpy as np
    a, b = zip(*(plane_coefficients(r) for r in fit_rows))
    x = np.array([line_regressors(r["estimate"]) for r in fit_rows])
    coef, *_ = np.linalg.lstsq(x, np.array(b), rcond=None)
    return (float(np.median(a)), *(float(c) for c in coef))


def line_regressors(e):
    """1, sigma and rho of an estimate (`fit_plane_line`)."""
    return [1.0, e["contraction_ratio"], e["mean_section_aspect_ratio"]]


def plane_line_mmhg(coef, e):
    """dp = (B0 + B1 sigma + B2 rho) K_throat - A K_vsd with `fit_plane_line`'s coefficients."""
    a, *b = coef
    return sum(c * x for c, x in zip(b, line_regressors(e))) * dynamic_mmhg(e, "throat_area_mm2") - a * dynamic_mmhg(e, "vsd_area_mm2")


def plane_model_mmhg(coef, e):
    """dp = B K_throat - A K_vsd with the fitted plane coefficients (friction is in B)."""
    a, b = coef
    return b * dynamic_mmhg(e, "throat_area_mm2") - a * dynamic_mmhg(e, "vsd_area_mm2")


def summary(name, pairs):
    """One markdown row: count within the criterion, error quantiles."""
    import numpy as np
    if not pairs:
        return f"| {name} | 0 | - | - | - |"
    err = np.array([est - dp for est, dp in pairs])
    hits = sum(abs(est - dp) <= tolerance_mmhg(dp) for est, dp in pairs)
    rel = np.array([(est - dp) / abs(dp) for est, dp in pairs if abs(dp) > 1.0])
    q = np.percentile(err, [0, 5, 50, 95, 100])
    rel_q = np.percentile(rel, [5, 50, 95]) if len(rel) else [float("nan")] * 3
    return (f"| {name} | {hits} of {len(pairs)} ({100 * hits / len(pairs):.0f} %) | {q[0]:+.2f} / {q[1]:+.2f} / {q[2]:+.2f} / {q[3]:+.2f} / {q[4]:+.2f} | "
            f"{100 * rel_q[0]:+.0f} / {100 * rel_q[1]:+.0f} / {100 * rel_q[2]:+.0f} % |")


def where_the_estimate_misses(ok):
    """Quantiles over the members of what the 3D planes show against the model's plug flow:
    the kinetic-energy coefficients alpha = (3D kinetic-energy flux) / (rho/2 (Q/A)^2) at the
    VSD and aortic planes, the 3D total-pressure loss between them against the model's losses,
    and the flow the 3D run carries through each plane against the inflow."""
    import numpy as np
    def q(values):
        v = np.percentile(values, [5, 50, 95])
        return f"{v[0]:.2f} / {v[1]:.2f} / {v[2]:.2f}"
    a11 = [r["planes"]["11"]["ke"] / dynamic_mmhg(r["estimate"], "vsd_area_mm2") for r in ok]
    a16 = [r["planes"]["16"]["ke"] / dynamic_mmhg(r["estimate"], "aortic_area_mm2") for r in ok]
    loss3 = [r["planes"]["11"]["total"] - r["planes"]["16"]["total"] for r in ok]
    loss_model = [r["estimate"]["expansion_loss_mmhg"] + r["estimate"]["friction_mmhg"] for r in ok]
    flow = lambda r, k: r["planes"][k]["flow_ml_s"] / r["planes"]["20"]["flow_ml_s"]
    a_b = [plane_coefficients(r) for r in ok]
    lines = ["\n| over the members (5 % / median / 95 %) | value |", "|---|---|",
             f"| A = (P11 - p11) / K_vsd | {q([a for a, _ in a_b])} |", f"| B = (P11 - p16) / K_throat | {q([b for _, b in a_b])} |",
             f"| angle of the flow to the VSD plane's normal (degrees) | {q([r['planes']['11']['crossing_angle_deg'] for r in ok])} |",
             f"| A cos^2 of that angle | {q([a * math.cos(math.radians(r['planes']['11']['crossing_angle_deg'])) ** 2 for (a, _), r in zip(a_b, ok)])} |",
             f"| mid-LV inflow cap's centre off the VSD plane's normal (degrees) | {q([r['angles']['inflow_deg'] for r in ok])} |",
             f"| aortic plane's centre off the VSD plane's normal (degrees) | {q([r['angles']['outflow_deg'] for r in ok])} |",
             f"| alpha at the VSD plane (11) | {q(a11)} |", f"| alpha at the aortic plane (16) | {q(a16)} |",
             f"| 3D total-pressure loss 11-16 (mmHg) | {q(loss3)} |", f"| model's expansion + friction loss (mmHg) | {q(loss_model)} |",
             f"| 3D flow through plane 11 / inflow | {q([flow(r, '11') for r in ok])} |",
             f"| 3D flow through plane 16 / inflow | {q([flow(r, '16') for r in ok])} |"]
    return "\n".join(lines)


def crossing_angle_fit(fit_rows, held_rows):
    """Least squares of the angle at which the flow crosses the VSD plane on the mid-LV inflow's
    and the aortic plane's angles off its normal (inflow_and_outflow_angles), on the fit part,
    with its residual on the held-out part: how much of A's spread the LV's direction explains."""
    import numpy as np
    x = lambda rows: np.array([[r["angles"]["inflow_deg"], r["angles"]["outflow_deg"], 1.0] for r in rows])  # noqa: E731
    y = lambda rows: np.array([r["planes"]["11"]["crossing_angle_deg"] for r in rows])  # noqa: E731
    coef, *_ = np.linalg.lstsq(x(fit_rows), y(fit_rows), rcond=None)
    residual = y(held_rows) - x(held_rows) @ coef
    return (f"\ncrossing angle (degrees) = {coef[0]:.3f} inflow + {coef[1]:.3f} outflow + {coef[2]:.2f} on the fit part; "
            f"held-out residual 5 / 50 / 95 %: {' / '.join(f'{v:+.1f}' for v in np.percentile(residual, [5, 50, 95]))}")


def patient_parts(args):
    """p1-p3's 21 rows (docs/hemodynamics_estimate.md: the 3D first peak at 0.85 / 1.25 mm), as
    (estimate, 3D dp) per patient."""
    import hemodynamics_estimate as he
    data = he.data_dir()
    patients = json.loads((data / "patients.json").read_text())["patients"]
    by_patient = {}
    for patient, row, (dp3, _, _) in he.CFD_ROWS:
        report, err = he.estimate_for(args.baffle, data, args.patients, patient, row, patients[patient])
        if report is None:
            print(f"- {patient} {row}: no estimate ({err})")
            continue
        by_patient.setdefault(patient, []).append((report["hemodynamics_estimate"], dp3))
    return [(f"{p} (1.25 mm 3D rows)", rows) for p, rows in sorted(by_patient.items())]


def re_estimated(baffle, plan_dir, q_ml_s):
    """The estimate of the plan's designed domain by `baffle` (its centerline stage, as for the
    published domains), for members planned with an earlier binary."""
    import hemodynamics_estimate as he
    dest = plan_dir / "re-estimate" / "centerline.vtp"
    argv = [baffle, "centerline", "--surface", plan_dir / "design" / "domain.vtp", "--peak-flow-ml-s", q_ml_s, "--out", dest]
    report, why = he.baffle_report(argv, dest.with_suffix(".json"))
    if report is None:
        raise RuntimeError(f"{plan_dir}: {why}")
    return report["hemodynamics_estimate"]


def family_rows(family, baffle=None):
    """The planned members of one family folder (with their planes), and its failures; with
    `baffle`, each member estimated again by it."""
    rows = [json.loads(line) for line in (family / "results.jsonl").read_text().splitlines() if line.strip()]
    ok = [r for r in rows if "estimate" in r]
    for r in ok:
        plan = family / f"m{r['seed']:03d}" / "plan"
        if "crossing_angle_deg" not in r.get("planes", {}).get("11", {}):
            # Rows written before the planes had all of today's figures are re-measured.
            r["planes"] = plane_figures(plan)
        r["angles"] = inflow_and_outflow_angles(plan)
        if baffle:
            r["estimate"] = re_estimated(baffle, plan, r["estimate"]["peak_flow_ml_s"])
    failed = [r for r in rows if "error" in r]
    dp3 = [r["comparison"]["dp_3d_mmhg"] for r in ok]
    print(f"{family}: members {len(rows)}; planned {len(ok)}; failed {len(failed)}; 3D dp {min(dp3):.2f} to {max(dp3):.2f} mmHg")
    for r in failed:
        print(f"- m{r['seed']:03d}: {r['error'][:200]}")
    return ok


def table(args):
    families = {Path(d).name: family_rows(Path(d), args.baffle if args.re_estimate else None) for d in args.dir}
    ok = [r for rows in families.values() for r in rows]
    pair = lambda r: (r["estimate"], r["comparison"]["dp_3d_mmhg"])
    modulus, remainder = (int(x) for x in args.fit_part.split(":"))
    in_fit = lambda r: r["seed"] % modulus == remainder
    part_name = f"seeds {remainder} mod {modulus}"
    fit_rows = [r for r in ok if in_fit(r)]
    held_rows = [r for r in ok if not in_fit(r)]
    fit, held = [pair(r) for r in fit_rows], [pair(r) for r in held_rows]
    coef = fit_dynamic_weights(fit)
    jet_coef = fit_jet_weights(fit)
    plane_coef = fit_plane_coefficients(fit_rows)
    print(f"\nfitted on the {len(fit)} {part_name}: dp = {coef[0]:.3f} K_throat {coef[1]:+.3f} K_aortic {-coef[2]:+.3f} K_vsd + friction")
    print(f"fitted on the {len(fit)} {part_name}: dp = {jet_coef[0]:.3f} K_jet {-jet_coef[1]:+.3f} K_vsd + friction")
    print(f"plane coefficients, medians of the {len(fit)} {part_name}: A = {plane_coef[0]:.3f}, B = {plane_coef[1]:.3f} (dp = B K_throat - A K_vsd)")
    # Reports written before the sections' aspect ratio was estimated have no B plane (--re-estimate).
    line_coef = fit_plane_line(fit_rows) if all("mean_section_aspect_ratio" in r["estimate"] for r in ok) else None
    if line_coef:
        print(f"plane coefficients on the {len(fit)} {part_name}: A = {line_coef[0]:.3f} (median), B = {line_coef[1]:.3f} {line_coef[2]:+.3f} sigma {line_coef[3]:+.3f} rho "
              "(least squares; sigma = throat / widest flow-normal section, rho = the sections' mean aspect ratio)")
    for name, rows in families.items():
        print(f"\n{name}:" + where_the_estimate_misses(rows))
    print(crossing_angle_fit(fit_rows, held_rows))
    print("\n| model, rows | within 20 % or 1 mmHg | error min / 5 % / median / 95 % / max (mmHg) | relative error 5 / 50 / 95 % (rows with 3D dp > 1 mmHg) |")
    print("|---|---|---|---|")
    parts = [(f"fit part ({part_name})", fit), ("held-out part (the other seeds)", held)]
    if len(families) > 1:
        parts += [(f"held-out part of {name}", [pair(r) for r in rows if not in_fit(r)]) for name, rows in families.items()]
    # The code's coefficients were fitted on some families' even seeds only: a family made
    # after them is held out whole.
    parts += [(f"every member of {name}", [pair(r) for r in rows]) for name, rows in families.items()]
    if args.patients:
        parts += patient_parts(args)
    for name, part in parts:
        print(summary(f"the reports' dp_estimate_mmhg (the code's with --re-estimate), {name}", [(e["dp_estimate_mmhg"], dp) for e, dp in part]))
        print(summary(f"the derived stenosis model, {name}", [(stenosis_model_mmhg(e), dp) for e, dp in part]))
        print(summary(f"fitted dynamic weights, {name}", [(fitted_mmhg(coef, e), dp) for e, dp in part]))
        print(summary(f"fitted jet and VSD coefficients, {name}", [(jet_fitted_mmhg(jet_coef, e), dp) for e, dp in part]))
        print(summary(f"median plane coefficients, {name}", [(plane_model_mmhg(plane_coef, e), dp) for e, dp in part]))
        if line_coef and all("mean_section_aspect_ratio" in e for e, _ in part):
            print(summary(f"plane coefficients, B on the contraction and aspect ratios, {name}", [(plane_line_mmhg(line_coef, e), dp) for e, dp in part]))


if __name__ == "__main__":
    sys.exit(main())
