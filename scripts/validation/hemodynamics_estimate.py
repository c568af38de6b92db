#!/usr/bin/env python3
"""The reduced-order dp / v_max estimate (baffle_core::analyses::hemodynamics_estimate) against the 3D
first-peak rows of docs/validation.md ("dp against the baffle's size on the paper's design
input", 0.85 mm boundary / 1.25 mm interior): the published domains via `baffle centerline
--peak-flow-ml-s`, our designs on the paper's design input via `baffle design --z-score z
--peak-flow-ml-s`. Writes the markdown table of docs/hemodynamics_estimate.md to stdout, with
the jet's recovery term (the unrecovered jet, its distance and area) and two readings of it that
the code does not use (`jet_variants_mmhg`), and the counts per patient.

    python3 scripts/validation/hemodynamics_estimate.py [--out DIR] [--baffle target/release/baffle]
"""
import argparse
import json
import math
import os
import subprocess
from pathlib import Path

RHO_G_CM3, DYN_CM2_PER_MMHG = 1.06, 1333.22

# (patient, row, extra design args) -> 3D first peak from docs/validation.md (area study):
# dp static (mmHg), dp total flow-weighted (mmHg), v_max on the centerline (m/s).
CFD_ROWS = [
    ("p1", "published", (5.00, 2.80, 1.59)), ("p2", "published", (-0.02, 1.72, 1.60)), ("p3", "published", (6.15, 2.61, 1.72)),
    ("p1", "-1", (15.84, 8.36, 2.46)), ("p1", "0", (11.83, 5.71, 1.98)), ("p1", "1", (7.85, 3.68, 1.79)),
    ("p2", "-1", (2.22, 2.66, 1.88)), ("p2", "-0.75", (1.38, 2.35, 1.79)), ("p2", "-0.5", (0.80, 2.15, 1.72)), ("p2", "-0.25", (0.09, 1.92, 1.63)),
    ("p2", "0", (0.12, 1.79, 1.66)), ("p2", "1", (-0.80, 1.48, 1.52)), ("p2", "2", (-1.23, 1.43, 1.42)), ("p2", "3", (-0.92, 1.83, 1.54)), ("p2", "4", (-0.63, 2.04, 1.49)),
    ("p3", "-1", (4.79, 2.23, 1.68)), ("p3", "1", (3.70, 1.81, 1.55)), ("p3", "2", (2.59, 1.52, 1.40)), ("p3", "3", (1.53, 1.38, 1.25)), ("p3", "4", (1.03, 1.45, 1.23)),
    ("p3", "0 --flow-sections", (4.51, 2.12, 1.60)),
]


def data_dir():
    """The patient data: $BAFFLE_DATA_DIR, or ../shared/data beside the repository."""
    return Path(os.environ.get("BAFFLE_DATA_DIR", Path(__file__).resolve().parents[2] / ".." / "shared" / "data"))


def within(est, ref, rel=0.20, abs_mmhg=1.0):
    return abs(est - ref) <= max(rel * abs(ref), abs_mmhg)


def output_of(out, patient, row):
    """Where a row's `baffle` output goes under `out`, and the JSON report holding its
    estimate: the published domain's centerline (.vtp, its .json beside it) or the design's
    folder (its report.json)."""
    if row == "published":
        dest = out / patient / "published" / "centerline.vtp"
        return dest, dest.with_suffix(".json")
    dest = out / patient / ("z" + "".join(row.split()))
    return dest, dest / "report.json"


def estimate_for(baffle, data, out, patient, row, info):
    q = info["q_peak_ml_s"]
    dest, report = output_of(out, patient, row)
    if row == "published":
        argv = [baffle, "centerline", "--surface", data / patient / "published_M_final.vtp", "--scale", "10", "--peak-flow-ml-s", q, "--out", dest]
    else:
        z, *extra = row.split()
        inputs = data / patient / "design_input"
        argv = [baffle, "design", "--surface", inputs / "capped_ventricle.vtp", "--points", inputs / "suture_points.mrk.json", "--bsa", info["bsa_m2"], "--z-score", z, *extra, "--peak-flow-ml-s", q, "--out", dest]
    return baffle_report(argv, report)


def baffle_report(argv, report):
    """Run a `baffle` command and read the JSON report it writes: (report, None), or (None,
    the last line of its error) when it fails."""
    run = subprocess.run([str(a) for a in argv], capture_output=True, text=True)
    if run.returncode != 0:
        return None, (run.stderr.strip().splitlines() or ["failed"])[-1]
    return json.loads(Path(report).read_text()), None


def no_recovery_mmhg(e):
    """The variant with the jet unmixed at the aortic plane: rho/2 (U_t^2 - U_vsd^2) + friction."""
    u = lambda a_mm2: e["peak_flow_ml_s"] / (a_mm2 * 1e-2)
    return RHO_G_CM3 / 2 * (u(e["throat_area_mm2"]) ** 2 - u(e["vsd_area_mm2"]) ** 2) / DYN_CM2_PER_MMHG + e["friction_mmhg"]


def jet_variants_mmhg(e):
    """Two readings of the jet term, not in the code, for the table only (same published B_u = 5.8):
    "free jet": a free round jet keeps its momentum flux, so the plane recovers nothing until the
    jet's top-hat (radius r_t + x / B_u) fills it, then everything; "vena contracta": the code's
    top-hat recovery but from the vena contracta's area 0.62 A_t (the model's v_max jet)."""
    q, b_u, cc = e["peak_flow_ml_s"], 5.8, 0.62
    u = lambda a_mm2: q / (a_mm2 * 1e-2)
    a_t, a_ao, a_vsd = e["throat_area_mm2"], e["aortic_area_mm2"], e["vsd_area_mm2"]
    x_mm = e["aortic_plane_at_mm"] - e["throat_at_mm"]
    mixed = e["bernoulli_mmhg"] + e["expansion_loss_mmhg"] + e["friction_mmhg"]
    fills = (a_t / math.pi) ** 0.5 + x_mm / b_u >= (a_ao / math.pi) ** 0.5
    free_jet = mixed if fills else no_recovery_mmhg(e)
    a_0 = cc * a_t
    a_j = min(math.pi * ((a_0 / math.pi) ** 0.5 + x_mm / b_u) ** 2, a_ao)
    recovered = (1 / a_0 - 1 / a_j) / (1 / a_0 - 1 / a_ao)
    unmixed = RHO_G_CM3 / 2 * (u(a_0) ** 2 - u(a_vsd) ** 2) / DYN_CM2_PER_MMHG + e["friction_mmhg"]
    return free_jet, unmixed + recovered * (mixed - unmixed)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", type=Path, default=Path("out/hemodynamics-estimate"))
    ap.add_argument("--baffle", default="target/release/baffle")
    args = ap.parse_args()
    data = data_dir()
    patients = json.loads((data / "patients.json").read_text())["patients"]
    print("| patient | row (z) | 3D dp static (mmHg) | estimate (mmHg) | error (mmHg) | within 20 % / 1 mmHg | Bernoulli / expansion / friction / unrecovered jet (mmHg) | fully mixed, before (mmHg) | throat to aortic plane (mm, throat diameters) | jet area at the plane (mm2), recovered fraction | no-recovery variant (mmHg) | free-jet / vena-contracta variants (mmHg) | 3D dp total, flow-weighted | expansion + friction | 3D v_max (m/s) | estimate (m/s) | error | throat (mm2, at mm) | VSD / aortic plane (mm2) | estimate wall time (ms) | baffle now (mm2) |")
    print("|" + "---|" * 21)
    counts = {"dp": 0, "loss": 0, "v": 0, "rows": 0}
    per_patient, errors, variants = {}, [], {}
    for patient, row, (dp3, dpt3, v3) in CFD_ROWS:
        report, err = estimate_for(args.baffle, data, args.out, patient, row, patients[patient])
        e = report and report["hemodynamics_estimate"]
        if e is None:
            print(f"| {patient} | {row} | {dp3} | not made: {err} |" + " |" * 17)
            continue
        wall_ms = f"{e['wall_time_ms']:.0f}" if row != "published" else "- (centerline)"
        baffle = f"{report['baffle_area_mm2']:.1f}" if "baffle_area_mm2" in report else "-"
        dp, v, loss = e["dp_estimate_mmhg"], e["v_max_estimate_m_s"], e["expansion_loss_mmhg"] + e["friction_mmhg"]
        counts["rows"] += 1
        counts["dp"] += within(dp, dp3)
        hits, rows = per_patient.get(patient, (0, 0))
        per_patient[patient] = (hits + within(dp, dp3), rows + 1)
        errors.append(dp - dp3)
        jet = e.get("unrecovered_jet_mmhg", 0.0)
        distance = e.get("aortic_plane_at_mm", float("nan")) - e["throat_at_mm"]
        throat_d_mm = 2 * (e["throat_area_mm2"] / math.pi) ** 0.5
        free_jet, vena_contracta = jet_variants_mmhg(e)
        for name, value in (("free_jet", free_jet), ("vena_contracta", vena_contracta)):
            hits, rows = variants.get((name, patient), (0, 0))
            variants[(name, patient)] = (hits + within(value, dp3), rows + 1)
        counts["loss"] += within(loss, dpt3)
        counts["v"] += abs(v - v3) <= 0.2 * v3
        print(
            f"| {patient} | {row} | {dp3:.2f} | {dp:.2f} | {dp - dp3:+.2f} | {'yes' if within(dp, dp3) else 'no'} | "
            f"{e['bernoulli_mmhg']:.2f} / {e['expansion_loss_mmhg']:.2f} / {e['friction_mmhg']:.2f} / {jet:.2f} | {dp - jet:.2f} | "
            f"{distance:.1f}, {distance / throat_d_mm:.2f} | {e.get('jet_area_at_aortic_plane_mm2', float('nan')):.1f}, {e.get('recovered_fraction', 1.0):.2f} | {no_recovery_mmhg(e):.2f} | {free_jet:.2f} / {vena_contracta:.2f} | {dpt3:.2f} | {loss:.2f} | "
            f"{v3:.2f} | {v:.2f} | {100 * (v - v3) / v3:+.0f} % | {e['throat_area_mm2']:.1f}, {e['throat_at_mm']:.1f} | {e['vsd_area_mm2']:.1f} / {e['aortic_area_mm2']:.1f} | {wall_ms} | {baffle} |"
        )
    n = counts["rows"]
    by_patient = ", ".join(f"{p} {h} of {r}" for p, (h, r) in sorted(per_patient.items()))
    print(f"\nrows estimated: {n}; dp static within 20 % or 1 mmHg: {counts['dp']} of {n} ({by_patient}), error {min(errors):+.2f} to {max(errors):+.2f} mmHg; expansion + friction against the 3D total-pressure loss within 20 % or 1 mmHg: {counts['loss']} of {n}; v_max within 20 %: {counts['v']} of {n}")
    for name in ("free_jet", "vena_contracta"):
        hits = {p: h for (v, p), (h, _) in variants.items() if v == name}
        print(f"{name} variant within 20 % or 1 mmHg: {sum(hits.values())} of {n} (" + ", ".join(f"{p} {h}" for p, h in sorted(hits.items())) + ")")


if __name__ == "__main__":
    main()
