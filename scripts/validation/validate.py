"""Regenerates the CFD rows of docs/validation.md from the patient data.

Each row runs the chain of paper 2.5 with the `baffle` command:
  published: published_M_final.vtp (cm -> mm, outward) -> `baffle mesh --remesh-surface`
             (its faces are the remeshed designed domain) -> `baffle extend`
  designed:  `baffle prepare` (segmentations) -> `baffle design` (the paper's suture
             points, its BSA) -> `baffle extend`
  input:     `baffle design` on the paper's own design input (the published capped
             ventricle and suture points) at an annulus z-score -> `baffle extend`
             (--only area: dp against the baffle's size, to compare with Table 4's areas)
  (mesh study: `baffle extend --remesh-domain-edge-mm H` on either domain instead, so the
  whole boundary is at H)
then `baffle mesh --interior-labels 11,16` -> `baffle simulate` (paper settings, from
rest to the first peak of flow, t = 0.164 s) -> `baffle centerline --results`.
Every stage's output is kept under OUT/work and reused by later rows (a stage's wall time
is stored beside its output, so a row's wall_time_s is the sum of its stages' times even
when a stage was run for an earlier row). Writes OUT/results.json, results.csv,
results.md (and gci.json / gci.md when a mesh study ran).

--only same-mesh: the published p1 and p3 domains at 1.25 and 0.75 mm and our p2 design at 1.25 mm through the same chain,
each mesh run to the first peak by both engines, ours (`baffle simulate --steps 170`) and
svMultiPhysics (`--engine svmultiphysics --mpi-processes 2`, the same steps); rows are
skipped, saying so, where svMultiPhysics is not on PATH (SAME_MESH_MPI_PROCESSES sets the ranks).
"""
import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import centerline_defs  # noqa: E402
import gci  # noqa: E402
import planes  # noqa: E402
import published  # noqa: E402
import sections  # noqa: E402

FIRST_PEAK_STEPS = 170  # peak of the built-in waveform at t = 0.164 s (dt 1 ms)
FIRST_PEAK_TIME_S = 0.164
DESIGN_BOUNDARY_MM = 0.85  # the paper's surface remesh edge (patients.json)


class Row(dict):
    """One result row; the key names are the table's columns."""


def log(msg):
    print(msg, flush=True)


class NotRun(Exception):
    """--tables-only: a stage of the row has no output yet."""


class Runner:
    def __init__(self, baffle, data, work, nice, tables_only=False):
        self.baffle, self.data, self.work, self.nice = baffle, data, work, nice
        self.tables_only = tables_only

    def stage(self, out_marker: Path, argv):
        """Run `baffle argv` unless out_marker's stage already finished; its wall time (s)."""
        stamp = out_marker.with_name(out_marker.name + ".stage.json")
        if out_marker.exists() and stamp.exists():
            return json.loads(stamp.read_text())["wall_time_s"]
        if self.tables_only:
            raise NotRun(str(out_marker))
        out_marker.parent.mkdir(parents=True, exist_ok=True)
        cmd = (["nice", "-n", str(self.nice)] if self.nice else []) + [str(self.baffle)] + [str(a) for a in argv]
        log("  $ " + " ".join(cmd))
        t0 = time.monotonic()
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        wall = time.monotonic() - t0
        (out_marker.parent / (out_marker.name + ".log")).write_text(proc.stdout)
        if proc.returncode != 0:
            tail = "\n".join(proc.stdout.strip().splitlines()[-5:])
            raise RuntimeError(f"baffle {argv[0]} failed ({proc.returncode}) for {out_marker}:\n{tail}")
        stamp.write_text(json.dumps({"wall_time_s": wall, "argv": cmd}))
        return wall


def published_domain(r: Runner, patient, boundary_mm):
    """The published designed domain in mm, outward, and (at the design's 0.85 mm) its
    boundary remeshed by `baffle mesh --remesh-surface`, whose faces file is the surface."""
    d = r.work / patient / "published"
    d.mkdir(parents=True, exist_ok=True)
    mm = d / "published_mm.vtp"
    if not mm.exists():
        published.convert(r.data / patient / "published_M_final.vtp", mm)
    if boundary_mm != DESIGN_BOUNDARY_MM:
        return mm, {}  # `baffle extend --remesh-domain-edge-mm` remeshes it
    remeshed = d / f"remesh-{boundary_mm}.vtu"
    t = r.stage(remeshed, ["mesh", "--surface", mm, "--remesh-surface", "--edge-length-mm", boundary_mm, "--out", remeshed])
    return d / f"remesh-{boundary_mm}-faces.vtp", {"remesh": t}


def designed_domain(r: Runner, patient, info):
    d = r.work / patient / "designed"
    capped = d / "capped_ventricle.vtp"
    times = {"prepare": r.stage(capped, ["prepare", "--segmentations", r.data / patient / "segmentations", "--out", capped])}
    design = d / "design"
    times["design"] = r.stage(
        design / "domain.vtp",
        ["design", "--surface", capped, "--points", r.data / patient / "design_input" / "suture_points.mrk.json", "--bsa", info["bsa_m2"], "--out", design],
    )
    return design / "domain.vtp", times


def input_domain(r: Runner, patient, info, z, flow_sections=False):
    """Our design on the paper's design input (published capped ventricle, its suture
    points) at annulus z-score z: the baffle's size varies while the anatomy is the paper's.
    flow_sections: with `--flow-sections` (the target applied to the flow-normal sections too)."""
    design = r.work / patient / "input" / (f"z{z:+g}" + ("-flow" if flow_sections else "")) / "design"
    inputs = r.data / patient / "design_input"
    argv = ["design", "--surface", inputs / "capped_ventricle.vtp", "--points", inputs / "suture_points.mrk.json", "--bsa", info["bsa_m2"], "--z-score", z, "--out", design]
    argv += ["--flow-sections"] if flow_sections else []
    return design / "domain.vtp", {"design": r.stage(design / "domain.vtp", argv)}


def baffle_figures(r: Runner, spec, domain):
    """The baffle's size: our design's report, or the published baffle file (cm2 -> mm2)."""
    if spec["domain"] == "published":
        return {"baffle_area_mm2": published.surface_area(r.data / spec["patient"] / "published_baffle.vtp") * 100.0}
    report = json.loads((domain.parent / "report.json").read_text())
    return {k: report[k] for k in ("target_area_mm2", "baffle_area_mm2", "min_constrained_final_area_mm2", "domain_volume_mm3")}


def write_case(path: Path, info, profile, cardiac_index, steps, cycles=1):
    case = {
        "mesh": {"volume": "../mesh.vtu", "faces": "../mesh-faces.vtp", "format": "baffle", "units": "mm"},
        "faces": {"inlet": 20, "outlets": [21], "walls": [2, 10], "planes": [11, 16]},
        "fluid": {"density_g_cm3": 1.06, "viscosity_g_cm_s": 0.04},
        "inflow": {"bsa_m2": info["bsa_m2"], "cardiac_index_l_min_m2": cardiac_index, "period_s": 0.682, "profile": profile},
        "outlet": {"sbp_mmhg": info["sbp_mmhg"], "dbp_mmhg": info["dbp_mmhg"]},
        # One cycle cut at `steps` (the first peak), or whole cycles (steps None).
        "time": {"mode": "transient", "dt_s": 0.001, "cycles": cycles, **({"steps": steps} if steps else {})},
        "output": {"vtu_every_steps": 0, "checkpoint_every_steps": 0},
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(case, indent=2))


def first_peak_dp_mmhg(sim: Path):
    """dp (VSD plane - aortic plane) at the first peak of flow, from a run's timeseries.csv."""
    with open(sim / "timeseries.csv") as f:
        rows = list(csv.DictReader(f))
    row = min(rows, key=lambda r: abs(float(r["time_s"]) - FIRST_PEAK_TIME_S))
    return float(row["p_plane1_11_mmhg"]) - float(row["p_plane2_16_mmhg"])


def run_row(r: Runner, spec, patients, common):
    patient, domain_kind = spec["patient"], spec["domain"]
    info = patients[patient]
    boundary, interior = spec["boundary_mm"], spec["interior_mm"]
    cycles = spec.get("cycles", 1)
    variant = variant_name(spec)
    length = f"{cycles} cycles" if cycles > 1 else f"{spec['steps']} steps"
    log(f"== {patient} {domain_kind} boundary {boundary} mm, interior {interior} mm, {spec['flow']} flow, {spec['profile']} inflow, {length}, extension {variant}")
    if domain_kind == "published":
        domain, times = published_domain(r, patient, boundary)
    elif domain_kind == "input":
        domain, times = input_domain(r, patient, info, spec["z"], spec.get("flow_sections", False))
    else:
        domain, times = designed_domain(r, patient, info)
    # Beside the published domain, or beside the design's domain.vtp.
    base = (r.work / patient / "published" if domain_kind == "published" else domain.parent) / (f"b{boundary}" + chain_suffix(spec))
    extended = base / "extended.vtp"
    extend_argv = ["extend", "--domain", domain, "--segmentations", r.data / patient / "segmentations", "--out", extended] + chain_argv(spec)
    if boundary != DESIGN_BOUNDARY_MM:
        # The whole boundary at this size, the planes conforming (mesh study).
        extend_argv += ["--remesh-domain-edge-mm", boundary]
    times["extend"] = r.stage(extended, extend_argv)
    mesh_dir = base / f"mesh-{interior}"
    mesh = mesh_dir / "mesh.vtu"
    times["mesh"] = r.stage(mesh, ["mesh", "--surface", extended, "--interior-labels", "11,16", "--edge-length-mm", interior, "--out", mesh])
    ci = common["elevated_cardiac_index_l_min_m2"] if spec["flow"] == "elevated" else common["cardiac_index_l_min_m2"]
    sim = mesh_dir / f"sim-{spec['flow']}-{spec['profile']}-{length.replace(' ', '') if cycles > 1 else spec['steps']}"
    write_case(sim / "case.json", info, spec["profile"], ci, None if cycles > 1 else spec["steps"], cycles)
    times["simulate"] = r.stage(sim / "summary.json", ["simulate", sim / "case.json", "--out", sim])
    # A run stopped before the peak (the smoke run) has no peak.vtu; its largest flow is
    # its last step, final.vtu, which is also the step summary.json's dp is taken at.
    fields = sim / "peak.vtu" if (sim / "peak.vtu").exists() else sim / "final.vtu"
    cl = sim / "centerline.vtp"
    times["centerline"] = r.stage(
        cl, ["centerline", "--surface", extended, "--ends", "20,21", "--plane-faces", mesh_dir / "mesh-faces.vtp", "--results", fields, "--out", cl]
    )
    # The whole path, inflow cap to outflow cap, for the other length definitions.
    whole = base / "centerline-ends.vtp"
    try:
        times["centerline_whole"] = r.stage(whole, ["centerline", "--surface", extended, "--ends", "20,21", "--planes", "20,21", "--out", whole])
    except RuntimeError as e:
        # It only feeds the other length definitions: the row stands without them.
        log(f"  whole-path centerline failed, other lengths left out: {e}")
        whole = None
    summary = json.loads((sim / "summary.json").read_text())
    quality = json.loads((mesh_dir / "mesh-quality.json").read_text())
    centerline = json.loads((sim / "centerline.json").read_text())
    defs = planes.dp_definitions(fields, mesh_dir / "mesh-faces.vtp", offsets_mm=spec.get("vsd_offsets_mm", ()))
    ext = json.loads((base / "extended-report.json").read_text())
    _, points, _, _, tris, labels = planes.load(fields, mesh_dir / "mesh-faces.vtp")
    path = planes.points_of(whole) if whole else None
    lengths = centerline_defs.lengths(path, (points, tris[labels == 11]), (points, tris[labels == 16]))
    # The tunnel's sections along the flow centerline, re-cut by VTK (the baffle-size rows).
    tunnel = sections.profile_summary(sections.section_areas(domain, planes.points_of(cl))) if spec.get("study") == "area" else None
    paper_dp = info["cfd_dp_peak_mmhg"] if spec["flow"] == "nominal" else None
    paper_v = info["cfd_centerline_vmax_m_s"] if spec["flow"] == "nominal" else None
    return Row(
        patient=patient,
        domain=domain_kind,
        z=spec.get("z"),
        flow_sections=spec.get("flow_sections", False),
        **baffle_figures(r, spec, domain),
        paper_baffle_area_mm2=info["baffle_area_mm2"],
        tunnel_sections=tunnel,
        mesh=f"{boundary} mm boundary, {interior} mm interior" + (f", {cycles} cycles" if cycles > 1 else "") + ("" if variant == "default" else f", {variant}"),
        variant=variant,
        cycles=cycles,
        # Several cycles: the first peak's dp beside the last cycle's (the quick estimate's error).
        dp_first_peak_mmhg=first_peak_dp_mmhg(sim) if cycles > 1 else summary["dp_peak_mmhg"],
        periodicity_nrmsd=summary.get("periodicity_nrmsd"),
        boundary_mm=boundary,
        interior_mm=interior,
        flow=spec["flow"],
        inflow_profile=spec["profile"],
        steps=summary.get("steps_done"),
        peak_time_s=summary.get("peak_time_s"),
        tets=quality["tetrahedra"],
        volume_mm3=quality["volume_mm3"],
        h_mm=gci.representative_h(quality["volume_mm3"], quality["tetrahedra"]),
        min_scaled_jacobian=quality["min_scaled_jacobian"],
        p1_scaled_jacobian=quality["p1_scaled_jacobian"],
        p99_aspect_ratio=quality["p99_aspect_ratio"],
        surface_triangles=ext["triangles"],
        vsd_cap_mm2=ext["vsd_cap"]["area_mm2"],
        aortic_cap_mm2=ext["aortic_cap"]["area_mm2"],
        inflow_cap_mm2=ext["inflow_cap"]["area_mm2"],
        inflow_cap_from_vsd_mm=ext["mid_lv_plane"]["distance_from_vsd_mm"],
        inflow_offset_mm=spec.get("inflow_offset_mm"),
        outflow_diameters=spec.get("outflow_diameters"),
        annulus_diameter_mm=ext["stj"]["annulus_diameter_mm"],
        outflow_cap_mm2=ext["outflow_cap"]["area_mm2"],
        stj_found=ext["stj"]["found"],
        stj_from_annulus_mm=ext["stj"]["distance_from_annulus_mm"],
        q_peak_ml_s=summary.get("q_peak_ml_s"),
        dp_mmhg=summary["dp_peak_mmhg"],
        dp_static_nodes_mmhg=defs["static_nodes"],
        dp_total_area_mmhg=defs["total_area"],
        dp_total_flux_mmhg=defs["total_flux"],
        vsd_plane_shifted=defs["vsd_plane_shifted"],
        aortic_plane_shifted=defs["aortic_plane_shifted"],
        vmax_centerline_m_s=centerline["v_max_m_s"],
        vmax_domain_m_s=summary["max_velocity_m_s"],
        centerline_length_mm=centerline["length_mm"],
        centerline_lengths_mm=lengths,
        paper_centerline_length_mm=info["flow_centerline_length_mm"],
        paper_dp_mmhg=paper_dp,
        paper_vmax_m_s=paper_v,
        stage_wall_time_s={k: round(v, 1) for k, v in times.items()},
        wall_time_s=round(sum(times.values()), 1),
    )


def moved_caps(spec, inflow_fmt, outflow_fmt):
    """The row's moved caps, each formatted with its value (none for the default extension)."""
    return [
        fmt_.format(spec[key])
        for key, fmt_ in (("inflow_offset_mm", inflow_fmt), ("outflow_diameters", outflow_fmt))
        if spec.get(key) is not None
    ]


def chain_suffix(spec):
    """The extension's directory suffix for a moved inflow or outflow cap ("" for the default)."""
    return "".join(moved_caps(spec, "-in{:+g}", "-out{:g}d"))


def chain_argv(spec):
    """`baffle extend` options placing the inflow / outflow cap as the row asks."""
    argv = []
    if spec.get("inflow_offset_mm") is not None:
        argv += ["--inflow-offset-mm", spec["inflow_offset_mm"]]
    if spec.get("outflow_diameters") is not None:
        argv += ["--outflow-diameters", spec["outflow_diameters"]]
    return argv


SAME_MESH_ROWS = (
    ("p3", "published", 1.25),
    ("p1", "published", 1.25),
    ("p2", "designed", 1.25),
    ("p3", "published", 0.75),
    ("p1", "published", 0.75),
)
SVMP_ENGINES = ("svmultiphysics", "svMultiPhysics")


def svmp_engine():
    """The svMultiPhysics executable on PATH, or None."""
    return next((shutil.which(n) for n in SVMP_ENGINES if shutil.which(n)), None)


def engine_figures(sim: Path, steps):
    """dp at the first peak (t = 0.164 s) and the largest over the run, v_max and seconds
    a step, of one engine's run in `sim`."""
    summary = json.loads((sim / "summary.json").read_text())
    with open(sim / "timeseries.csv") as f:
        rows = list(csv.DictReader(f))
    dps = [float(r["p_plane1_11_mmhg"]) - float(r["p_plane2_16_mmhg"]) for r in rows]
    return {
        "dp_mmhg": first_peak_dp_mmhg(sim),
        "dp_largest_mmhg": max(dps),
        "vmax_m_s": summary.get("max_velocity_m_s"),
        "converged": summary.get("converged"),
        "s_per_step": summary["wall_time_s"] / steps,
    }


def same_mesh_row(r: Runner, patient, kind, interior, patients, common):
    """One mesh of the published or our designed domain run by both engines to the first peak."""
    info = patients[patient]
    if kind == "published":
        domain, _ = published_domain(r, patient, DESIGN_BOUNDARY_MM)
        base = r.work / patient / "published" / f"b{DESIGN_BOUNDARY_MM}"
    else:
        domain, _ = designed_domain(r, patient, info)
        base = domain.parent / f"b{DESIGN_BOUNDARY_MM}"
    extended = base / "extended.vtp"
    r.stage(extended, ["extend", "--domain", domain, "--segmentations", r.data / patient / "segmentations", "--out", extended])
    mesh_dir = base / f"mesh-{interior}"
    mesh = mesh_dir / "mesh.vtu"
    r.stage(mesh, ["mesh", "--surface", extended, "--interior-labels", "11,16", "--edge-length-mm", interior, "--out", mesh])
    steps = FIRST_PEAK_STEPS
    row = Row(patient=patient, domain=kind, mesh=f"{DESIGN_BOUNDARY_MM} / {interior} mm", tets=json.loads((mesh_dir / "mesh-quality.json").read_text())["tetrahedra"])
    ours = mesh_dir / f"same-mesh-ours-{steps}"
    write_case(ours / "case.json", info, "plug", common["cardiac_index_l_min_m2"], steps)
    r.stage(ours / "summary.json", ["simulate", ours / "case.json", "--out", ours])
    row["ours"] = engine_figures(ours, steps)
    if svmp_engine() is None:
        log(f"  svMultiPhysics is not on PATH (build it with ../shared/engines/svmultiphysics/build.sh): {patient} {interior} mm runs our engine only")
        row["svmp"] = None
        return row
    theirs = mesh_dir / f"same-mesh-svmp-{steps}"
    write_case(theirs / "case.json", info, "plug", common["cardiac_index_l_min_m2"], steps)
    ranks = os.environ.get("SAME_MESH_MPI_PROCESSES", "2")
    r.stage(theirs / "summary.json", ["simulate", theirs / "case.json", "--out", theirs, "--engine", "svmultiphysics", "--mpi-processes", ranks])
    row["svmp"] = engine_figures(theirs, steps)
    return row


def same_mesh_markdown(rows):
    head = "| patient | domain | mesh | tets | dp ours / svMP (mmHg) | ours - svMP | largest dp ours / svMP | v_max ours / svMP (m/s) | s a step ours / svMP | svMP converged |"
    return "\n".join([head, "|" + "---|" * 10] + ["| " + " | ".join(same_mesh_cells(x)) + " |" for x in rows]) + "\n"


def same_mesh_cells(x):
    """A same-mesh row's cells: each figure as ours / svMultiPhysics' ('-' where it did not run)."""
    o, t = x["ours"], x.get("svmp")
    pair = lambda k, nd=2: f"{fmt(o[k], nd)} / " + (fmt(t[k], nd) if t else "-")
    diff = f"{100 * (o['dp_mmhg'] / t['dp_mmhg'] - 1):+.1f}%" if t else "svMultiPhysics not run"
    return [x["patient"], x.get("domain", "published"), x["mesh"], f"{x['tets']:,}", pair("dp_mmhg"), diff, pair("dp_largest_mmhg"), pair("vmax_m_s"), pair("s_per_step", 3), str(t["converged"]) if t else ""]


def same_mesh(r: Runner, patients, common, wanted, out: Path):
    rows = []
    for patient, kind, interior in SAME_MESH_ROWS:
        if patient not in wanted:
            continue
        log(f"== same mesh: {patient} {kind}, interior {interior} mm, both engines")
        try:
            rows.append(same_mesh_row(r, patient, kind, interior, patients, common))
        except NotRun as e:
            log(f"  not run yet ({e}): left out")
        except (RuntimeError, ValueError, OSError, KeyError) as e:
            log(f"  FAILED: {e}")
            return 1
    (out / "same-mesh.json").write_text(json.dumps(rows, indent=1))
    (out / "same-mesh.md").write_text("## Same mesh, both engines, first peak of flow\n\n" + same_mesh_markdown(rows))
    return 0


def spec(patient, domain, boundary=DESIGN_BOUNDARY_MM, interior=1.25, flow="nominal", profile="plug", steps=FIRST_PEAK_STEPS, **kw):
    return dict(patient=patient, domain=domain, boundary_mm=boundary, interior_mm=interior, flow=flow, profile=profile, steps=steps, **kw)


# The paper's coarse, nominal and fine sizes and one finer; boundary and interior alike.
# The GCI takes the three finest.
MESH_LEVELS_MM = (1.25, 0.95, 0.75, 0.6)
VSD_OFFSETS_MM = (-2.0, -1.0, 0.0, 1.0, 2.0)
# The extension's caps moved (issue 13): the mid-LV inflow cap along the VSD normal from
# the LV centroid (mm; positive: away from the VSD), the outflow cap at fixed heights
# (annulus diameters; p2's aortic root sections end at 1.39, p1's and p3's at 1.5).
INFLOW_OFFSETS_MM = (-5.0, -2.5, 2.5, 5.0)
OUTFLOW_DIAMETERS = (0.75, 1.35)


def chain_specs(patients):
    """Published domains, 0.85 / 1.25 mm, first peak: the default extension (baseline of
    the same run), then each inflow offset and each outflow height, one at a time."""
    rows = []
    for p in patients:
        rows.append(spec(p, "published", study="chain"))
        rows += [spec(p, "published", inflow_offset_mm=o, study="chain") for o in INFLOW_OFFSETS_MM]
        rows += [spec(p, "published", outflow_diameters=k, study="chain") for k in OUTFLOW_DIAMETERS]
    return rows


# Annulus z-scores of the designs on the paper's design input (--only area). p2's dp
# changes by 2.3 mmHg between z = -1 and 0 (measured), so that interval is sampled in
# quarter steps. Finer meshes (boundary and interior) on some designs, per patient:
# (z-scores, edge lengths); p3's Table 4 baffle lies near z = 3.
AREA_Z_SCORES = (-1.0, 0.0, 1.0, 2.0, 3.0, 4.0)
AREA_Z_SCORES_BETWEEN = {"p2": (-0.75, -0.5, -0.25)}
AREA_FINE = {"p3": ((0.0, 3.0), (0.75, 0.6)), "p2": ((-1.0, 0.0), (0.6,))}


def area_specs(patients):
    """dp against the baffle's size on the paper's anatomy: the published domain as it is,
    then our designs on its design input at each z-score (0.85 / 1.25 mm, first peak)."""
    rows = []
    for p in patients:
        rows.append(spec(p, "published", study="area"))
        rows += [spec(p, "input", z=z, study="area") for z in sorted(AREA_Z_SCORES + AREA_Z_SCORES_BETWEEN.get(p, ()))]
        # The paper's target (z = 0) applied to the flow-normal sections too.
        rows.append(spec(p, "input", z=0.0, flow_sections=True, study="area"))
        zs, levels = AREA_FINE.get(p, ((), ()))
        rows += [spec(p, "input", z=z, boundary=h, interior=h, study="area") for z in zs for h in levels]
    return rows


def row_specs(mode, patients_wanted, only=None):
    """The rows of a run; `only` keeps the mesh study ("gci"), the four-cycle runs
    ("cycles"), the moved extension caps ("chain"), the baffle sizes ("area") or the rest
    ("base")."""
    rows = all_row_specs(mode, patients_wanted)
    if only == "base":
        return [r for r in rows if not r.get("study")]
    return [r for r in rows if only is None or r.get("study") == only]


def all_row_specs(mode, patients_wanted):
    rows = []
    ps = patients_wanted
    if mode == "smoke":
        return [spec("p2", "published", steps=20)]
    for p in ps:
        rows.append(spec(p, "published", vsd_offsets_mm=VSD_OFFSETS_MM))
    for p in ps:
        rows.append(spec(p, "designed", vsd_offsets_mm=VSD_OFFSETS_MM))
    if mode == "quick":
        return rows
    # The modelling choices around the flow chain, one at a time, on the published
    # domains; then elevated flow and the mesh study (boundary refined too, GCI) on p2
    # and p3, the rows the issue asks about; p1 last (the largest mesh).
    first = [p for p in ("p2", "p3") if p in ps]
    variants = lambda p: [spec(p, "published", profile="poiseuille"), spec(p, "published", interior=0.75), spec(p, "published", flow="elevated")]
    study = lambda p, d: [spec(p, d, boundary=h, interior=h, study="gci") for h in MESH_LEVELS_MM]
    for p in first:
        rows += variants(p)
    for p in first:
        rows += study(p, "published")
    if "p1" in ps:
        rows += variants("p1")
    # Four cycles on the published domains (the quick estimate's first peak against the
    # fourth cycle's), then the same study on our designs, smallest first; p1 published last.
    rows += [spec(p, "published", cycles=4, study="cycles") for p in ("p2", "p3", "p1") if p in ps]
    rows += [r for p in ("p2", "p3", "p1") if p in ps for r in study(p, "designed")]
    if "p1" in ps:
        rows += study("p1", "published")
    rows += chain_specs([p for p in ("p2", "p3", "p1") if p in ps])
    rows += area_specs([p for p in ("p3", "p2", "p1") if p in ps])
    return rows


def fmt(x, nd=2):
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    return f"{x:.{nd}f}" if isinstance(x, float) else str(x)


def markdown(rows):
    head = "| patient | domain | mesh | flow | inflow | tets | dp (mmHg) | paper | dp total, flow-weighted | v_max centerline (m/s) | paper | v_max domain | centerline (mm) | wall time (s) |"
    out = [head, "|" + "---|" * (head.count("|") - 1)]
    # The moved-cap rows and the baffle sizes have their own tables (chain_markdown, area_markdown).
    for r in (r for r in rows if r.get("study") not in ("chain", "area")):
        if "error" in r:
            out.append(f"| {r['patient']} | {r['domain']} | {r.get('mesh', '')} | | | | failed: {r['error'].splitlines()[0]} | | | | | | | |")
            continue
        out.append(
            f"| {r['patient']} | {r['domain']} | {r['mesh']} | {r['flow']} | {r['inflow_profile']} | {r['tets']:,} | {fmt(r['dp_mmhg'])} | {fmt(r['paper_dp_mmhg'])} | "
            f"{fmt(r['dp_total_flux_mmhg'])} | {fmt(r['vmax_centerline_m_s'])} | {fmt(r['paper_vmax_m_s'])} | {fmt(r['vmax_domain_m_s'])} | {fmt(r['centerline_length_mm'])} | {fmt(r['wall_time_s'], 0)} |"
        )
    return "\n".join(out) + "\n"


def geometry_markdown(rows):
    """Table 4's side: the extended domain, its mesh and centerline lengths (one line per
    distinct domain and mesh)."""
    head = ("| patient | domain | mesh | tets | scaled Jacobian min / 1st pct | VSD / aortic cap (mm2) | inflow cap (mm2, mm from VSD) | outflow cap (mm2, mm above annulus, STJ found) "
            "| centerline (mm): ours / infinite planes / whole path between discs / cap centroids | paper (mm) |")
    out = [head, "|" + "---|" * (head.count("|") - 1)]
    seen = set()
    for r in rows:
        key = (r["patient"], r["domain"], r.get("mesh"))
        if "error" in r or key in seen:
            continue
        seen.add(key)
        L = r["centerline_lengths_mm"]
        out.append(
            f"| {r['patient']} | {r['domain']} | {r['mesh']} | {r['tets']:,} | {r['min_scaled_jacobian']:.3f} / {r['p1_scaled_jacobian']:.3f} | {r['vsd_cap_mm2']:.1f} / {r['aortic_cap_mm2']:.1f} | "
            f"{r['inflow_cap_mm2']:.0f}, {r['inflow_cap_from_vsd_mm']:.1f} | {r['outflow_cap_mm2']:.0f}, {r['stj_from_annulus_mm']:.1f}, {'yes' if r['stj_found'] else 'no'} | "
            f"{r['centerline_length_mm']:.2f} / {fmt(L.get('infinite_planes'))} / {fmt(L.get('discs'))} / {L['centroids']:.2f} | {r['paper_centerline_length_mm']} |"
        )
    return "\n".join(out) + "\n"


def shifted_markdown(rows, key):
    """dp with one plane moved along the flow (static and flow-weighted total)."""
    out = []
    for r in rows:
        sh = r.get(key) or {}
        if "error" in r or not sh:
            continue
        if not out:
            offs = list(sh.keys())
            head = "| patient | domain | mesh | " + " | ".join(f"{o} mm: static / total" for o in offs) + " |"
            out = [head, "|" + "---|" * (head.count("|") - 1)]
        out.append(f"| {r['patient']} | {r['domain']} | {r['mesh']} | " + " | ".join(f"{v['dp_static_area']:.2f} / {v['dp_total_flux']:.2f}" for v in sh.values()) + " |")
    return "\n".join(out) + "\n" if out else ""


def chain_markdown(rows):
    """dp and v_max with the extension's inflow or outflow cap moved (the "chain" rows)."""
    head = ("| patient | extension | inflow cap (mm from VSD, mm2) | outflow cap (mm above annulus, mm2) | tets | dp static (mmHg) | dp total, flow-weighted "
            "| v_max centerline (m/s) | paper dp / v_max |")
    out = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        if r.get("study") != "chain":
            continue
        if "error" in r:
            out.append(f"| {r['patient']} | {r.get('variant', '')} | failed: {r['error'].splitlines()[-1]} | | | | | | |")
            continue
        out.append(
            f"| {r['patient']} | {variant_name(r)} | {r['inflow_cap_from_vsd_mm']:.1f}, {r['inflow_cap_mm2']:.0f} | {r['stj_from_annulus_mm']:.1f}, {r['outflow_cap_mm2']:.0f} | {r['tets']:,} | "
            f"{fmt(r['dp_mmhg'])} | {fmt(r['dp_total_flux_mmhg'])} | {fmt(r['vmax_centerline_m_s'])} | {fmt(r['paper_dp_mmhg'])} / {fmt(r['paper_vmax_m_s'])} |"
        )
    return "\n".join(out) + "\n" if len(out) > 2 else ""


def area_markdown(rows):
    """dp and v_max against the baffle's size (the "area" rows), the published baffle first,
    and dp read at Table 4's baffle area between the two designs that bracket it."""
    head = ("| patient | domain | z | mesh | target (mm2) | baffle (mm2) | smallest constrained section (mm2) | smallest flow-normal section, VTK (mm2, at mm; planes crossing a cap left out) "
            "| tets | dp static (mmHg) | dp total, flow-weighted "
            "| v_max centerline (m/s) | paper: baffle (mm2) / dp / v_max |")
    out = [head, "|" + "---|" * (head.count("|") - 1)]
    area_rows = [r for r in rows if r.get("study") == "area"]
    for r in area_rows:
        if "error" in r:
            why = "infeasible" if infeasible_design(r) else "failed"
            out.append(f"| {r['patient']} | {domain_cell(r)} | {z_cell(r)} | {r.get('mesh', '')} | {why}: {r['error'].splitlines()[-1]} | | | | | | | | |")
            continue
        out.append(
            f"| {r['patient']} | {domain_cell(r)} | {z_cell(r)} | {r['mesh']} | {fmt(r.get('target_area_mm2'), 1)} | {r['baffle_area_mm2']:.1f} | {fmt(r.get('min_constrained_final_area_mm2'), 1)} | "
            f"{tunnel_cell(r.get('tunnel_sections'))} | {r['tets']:,} | {fmt(r['dp_mmhg'])} | {fmt(r['dp_total_flux_mmhg'])} | {fmt(r['vmax_centerline_m_s'])} | "
            f"{r['paper_baffle_area_mm2']} / {fmt(r['paper_dp_mmhg'])} / {fmt(r['paper_vmax_m_s'])} |"
        )
    notes = [line for line in (at_paper_area(area_rows, p) for p in sorted({r["patient"] for r in area_rows})) if line]
    return "\n".join(out) + "\n" + ("\n" + "\n".join(notes) + "\n" if notes else "") if area_rows else ""


def z_cell(row):
    return "-" if row.get("z") is None else f"{row['z']:g}"


def domain_cell(row):
    return row["domain"] + (", --flow-sections" if row.get("flow_sections") else "")


def infeasible_design(row):
    """Whether a row failed because `baffle design` found its target out of the suture line's reach."""
    return row.get("domain") == "input" and "could not reach the target area" in row.get("error", "")


def tunnel_cell(t):
    if not t or not t["sections"]:
        return "-"
    return f"{t['min_section_mm2']:.1f}, {t['min_at_mm']:.1f} ({t['sections']} of {t['of']})"


def at_paper_area(rows, patient):
    """dp and v_max at Table 4's baffle area, linear between the two base-mesh designs whose
    baffles bracket it (None when none do)."""
    designs = sorted(
        (r for r in rows if r["patient"] == patient and r["domain"] == "input" and "error" not in r and not r.get("flow_sections")
         and r["boundary_mm"] == DESIGN_BOUNDARY_MM and r["interior_mm"] == 1.25),
        key=lambda r: r["baffle_area_mm2"],
    )
    for a, b in zip(designs, designs[1:]):
        area = a["paper_baffle_area_mm2"]
        if a["baffle_area_mm2"] <= area <= b["baffle_area_mm2"] and b["baffle_area_mm2"] > a["baffle_area_mm2"]:
            t = (area - a["baffle_area_mm2"]) / (b["baffle_area_mm2"] - a["baffle_area_mm2"])
            lerp = lambda k: a[k] + t * (b[k] - a[k])
            return (f"- {patient}: at Table 4's baffle area ({area} mm2, between z = {a['z']:g} and {b['z']:g}): dp {lerp('dp_mmhg'):.2f} mmHg "
                    f"(paper {fmt(a['paper_dp_mmhg'])}), v_max on the centerline {lerp('vmax_centerline_m_s'):.2f} m/s (paper {fmt(a['paper_vmax_m_s'])}).")
    return None


def variant_name(spec):
    """How a row's extension differs from the default (mid-LV centroid, STJ or 1 diameter)."""
    return ", ".join(moved_caps(spec, "inflow cap {:+g} mm", "outflow cap at {:g} annulus diameters")) or "default"


def gci_markdown(study):
    lines = [
        "| patient | quantity | levels (edge mm, h mm: value, off the extrapolated) | observed order (3 finest) | extrapolated | GCI fine (Fs 1.25) | in the asymptotic range | reported band (GCI, or Fs 3 at order 2) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, e in study.items():
        for q in ("dp_mmhg", "vmax_centerline_m_s", "dp_total_flux_mmhg"):
            g = e[q]
            off = g.get("relative_to_extrapolated") or [float("nan")] * len(e["levels"])
            lv = ", ".join(f"{l['boundary_mm']}, {l['h_mm']:.3f}: {l[q]:.3f} ({100 * o:.0f}%)" for l, o in zip(e["levels"], off))
            if "error" in g:
                lines.append(f"| {name} | {q} | {lv} | {g['error']} | | | | |")
            else:
                lines.append(
                    f"| {name} | {q} | {lv} | {g['observed_order']:.2f} | {g['extrapolated']:.3f} | {100 * g['gci_fine']:.1f}% | {'yes' if g['asymptotic'] else 'no'} | "
                    f"{100 * g['gci_reported']:.1f}% (+-{g['band_abs']:.3f}) |"
                )
    return "\n".join(lines) + "\n"


def study_tables(rows):
    """GCI of dp and centerline v_max per patient and domain over the study's three levels."""
    out = {}
    groups = {}
    for r in rows:
        if r.get("study") == "gci" and "error" not in r:
            groups.setdefault((r["patient"], r["domain"]), []).append(r)
    for (p, d), rs in groups.items():
        if len(rs) < 3:
            continue
        rs.sort(key=lambda r: r["h_mm"])
        h = tuple(r["h_mm"] for r in rs[:3])
        entry = {"levels": [{"boundary_mm": r["boundary_mm"], "tets": r["tets"], "h_mm": r["h_mm"], "dp_mmhg": r["dp_mmhg"], "vmax_centerline_m_s": r["vmax_centerline_m_s"], "dp_total_flux_mmhg": r["dp_total_flux_mmhg"]} for r in rs]}
        for q in ("dp_mmhg", "vmax_centerline_m_s", "dp_total_flux_mmhg"):
            try:
                entry[q] = gci.gci(h, tuple(r[q] for r in rs[:3]))
                # Each level against the extrapolated value: where is it within 5%?
                entry[q]["relative_to_extrapolated"] = [abs(r[q] / entry[q]["extrapolated"] - 1.0) for r in rs]
            except ValueError as e:
                entry[q] = {"error": str(e)}
        out[f"{p} {d}"] = entry
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mode", choices=("smoke", "quick", "full"), default="full")
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--baffle", type=Path, required=True)
    ap.add_argument("--patients", default="p1,p2,p3")
    ap.add_argument("--nice", type=int, default=5)
    ap.add_argument("--only", choices=("gci", "cycles", "chain", "area", "base", "same-mesh"),
                    help="run only the mesh-study rows, the four-cycle rows, the moved extension caps, the baffle sizes, the others, or both engines on the same meshes")
    ap.add_argument("--tables-only", action="store_true", help="rebuild the tables from the stages already run; rows with a stage missing are left out")
    args = ap.parse_args(argv)
    meta = json.loads((args.data / "patients.json").read_text())
    # The smoke row needs p2 only.
    wanted = ["p2"] if args.mode == "smoke" else [p for p in args.patients.split(",") if p]
    missing = [p for p in wanted if not (args.data / p).is_dir()]
    if missing:
        sys.exit(f"{args.data}: no patient folder {', '.join(missing)}")
    args.out.mkdir(parents=True, exist_ok=True)
    r = Runner(args.baffle.resolve(), args.data.resolve(), (args.out / "work").resolve(), args.nice, args.tables_only)
    if args.only == "same-mesh":
        return same_mesh(r, meta["patients"], meta["common"], wanted, args.out)
    rows = []
    for s in row_specs(args.mode, wanted, args.only):
        try:
            row = run_row(r, s, meta["patients"], meta["common"])
        except NotRun as e:
            log(f"  not run yet ({e}): left out")
            continue
        except (RuntimeError, ValueError, OSError, KeyError) as e:
            log(f"  FAILED: {e}")
            row = Row(patient=s["patient"], domain=s["domain"], z=s.get("z"), mesh=f"{s['boundary_mm']} / {s['interior_mm']} mm", variant=variant_name(s), error=str(e))
        if "study" in s:
            row["study"] = s["study"]
        rows.append(row)
        log(f"  -> {json.dumps({k: row.get(k) for k in ('tets', 'dp_mmhg', 'dp_total_flux_mmhg', 'vmax_centerline_m_s', 'wall_time_s', 'error') if k in row})}")
        write_outputs(args.out, rows)
    # A target the suture line cannot reach is the baffle-size study's answer, not a failure.
    failed = [x for x in rows if "error" in x and not infeasible_design(x)]
    # A row without a finite dp, v_max or mesh is a failure too (the smoke run's check).
    failed += [x for x in rows if "error" not in x and not (x["tets"] > 0 and all(math.isfinite(x[k]) for k in ("dp_mmhg", "vmax_centerline_m_s", "dp_total_flux_mmhg")))]
    for x in failed:
        log(f"FAILED row: {x['patient']} {x['domain']} {x.get('mesh')}: {x.get('error', 'a figure is not finite')}")
    return 1 if failed else 0


def write_outputs(out, rows):
    (out / "results.json").write_text(json.dumps(rows, indent=1))
    keys = [k for k in rows[0].keys()] if rows else []
    for r in rows:
        keys += [k for k in r.keys() if k not in keys]
    with open(out / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: (json.dumps(v) if isinstance(v, dict) else v) for k, v in r.items()})
    (out / "results.md").write_text(
        "## Table 5: dp and v_max at the first peak of flow\n\n" + markdown(rows)
        + "\n## The extended domains, meshes and centerline lengths\n\n" + geometry_markdown(rows)
        + "\n## dp with the VSD plane moved along the flow (negative: into the LV)\n\n" + shifted_markdown(rows, "vsd_plane_shifted")
        + "\n## dp with the aortic plane moved along the flow (positive: into the aorta)\n\n" + shifted_markdown(rows, "aortic_plane_shifted")
        + "\n## dp with the extension's inflow or outflow cap moved\n\n" + chain_markdown(rows)
        + "\n## dp against the baffle's size on the paper's design input\n\n" + area_markdown(rows)
    )
    study = study_tables(rows)
    if study:
        (out / "gci.json").write_text(json.dumps(study, indent=1))
        (out / "gci.md").write_text(gci_markdown(study))


if __name__ == "__main__":
    sys.exit(main())
