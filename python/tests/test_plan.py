"""baffle.plan() through the library: a quick plan on the built-in phantom gives the
report's verdict as a PlanResult, cancelling stops it with the earlier stages kept, bad
options are named before any stage, and write_case() writes the plan's own CFD case.
The plan meshes with gmsh; BAFFLE_SKIP_GMSH=1 skips those tests."""

import json
import math
import os

import pytest

import baffle
from baffle import _lib

needs_gmsh = pytest.mark.skipif(os.environ.get("BAFFLE_SKIP_GMSH") == "1", reason="BAFFLE_SKIP_GMSH=1")
# The phantom at p2's blood pressure: a quick run on one coarse mesh (seconds).
QUICK = dict(phantom=True, sbp_mmhg=107, dbp_mmhg=78, mode="quick", single_mesh=True, edge_length_mm=1.5)


@needs_gmsh
def test_a_quick_phantom_plan_returns_the_reports_verdict(tmp_path):
    seen = []
    result = baffle.plan(tmp_path / "plan", progress=lambda fraction, stage: seen.append((fraction, stage)), **QUICK)
    report = json.loads(result.report_json.read_text())
    verdict = report["verdict"]
    assert result.verdict == verdict["verdict"] and result.verdict in ("passes", "fails", "inconclusive")
    assert result.dp_mmhg == verdict["dp_peak_mmhg"] and result.dp_threshold_mmhg == verdict["threshold_mmhg"] == 10.0
    assert result.verdict_text == verdict["text"]
    assert result.reasons == (verdict["reason"].split("; ") if verdict["reason"] else [])
    assert result.passes == verdict["passes"]
    assert result.v_max_m_s == report["runs"][0]["max_velocity_m_s"] > 0
    assert result.report_json == tmp_path / "plan" / "report.json" and result.report_html.is_file()
    assert (tmp_path / "plan" / "simulate-nominal" / "summary.json").is_file()
    # Progress: the whole plan's fraction, stage by stage, ending with the report.
    assert seen[0][1] == "design" and seen[-1] == (1.0, "report")
    assert "mesh-nominal" in {stage for _, stage in seen} and all(0.0 <= f <= 1.0 for f, _ in seen)


@needs_gmsh
def test_cancelling_stops_the_plan_and_keeps_the_finished_stages(tmp_path):
    out = tmp_path / "plan"
    design_done = lambda: (out / "design" / "report.json").exists()
    with pytest.raises(baffle.Cancelled, match="plan cancelled at stage centerline") as error:
        baffle.plan(out, cancel=design_done, **QUICK)
    assert error.value.status == _lib.STATUS_CANCELLED
    assert (out / "design" / "domain.vtp").is_file()
    assert not (out / "centerline").exists() and not (out / "report.json").exists()


@needs_gmsh
def test_a_progress_callback_that_raises_stops_the_plan_and_reraises(tmp_path):
    def progress(fraction, stage):
        if stage == "centerline":
            raise KeyboardInterrupt("stop")

    with pytest.raises(KeyboardInterrupt):
        baffle.plan(tmp_path / "plan", progress=progress, **QUICK)
    assert (tmp_path / "plan" / "design" / "report.json").is_file()
    assert not (tmp_path / "plan" / "report.json").exists()


def test_bad_plan_options_are_named_before_any_stage(tmp_path):
    seen = []
    with pytest.raises(baffle.BaffleError, match=r"DBP 107 mmHg exceeds SBP 78 mmHg") as error:
        baffle.plan(tmp_path / "plan", progress=lambda f, s: seen.append(s), **{**QUICK, "sbp_mmhg": 78, "dbp_mmhg": 107})
    assert error.value.status == 2
    with pytest.raises(baffle.BaffleError, match="needs the ventricle"):
        baffle.plan(tmp_path / "plan", **{**QUICK, "phantom": False})
    with pytest.raises(ValueError, match="mode must be one of"):
        baffle.plan(tmp_path / "plan", **{**QUICK, "mode": "fast"})
    assert seen == [] and not (tmp_path / "plan").exists()


def test_write_case_writes_the_plans_case(tmp_path):
    path = baffle.write_case(tmp_path, bsa_m2=0.37, sbp_mmhg=107, dbp_mmhg=78, heart_rate_bpm=120, mode="steady")
    assert path == tmp_path / "case.json"
    case = json.loads(path.read_text())
    assert case["mesh"]["volume"] == "volume.vtu" and case["mesh"]["faces"] == "volume-faces.vtp"
    assert (case["faces"]["inlet"], case["faces"]["outlets"]) == (11, [16])
    assert case["inflow"]["bsa_m2"] == 0.37 and case["inflow"]["heart_rate_bpm"] == 120
    assert case["time"]["mode"] == "steady"
    with pytest.raises(baffle.BaffleError, match="exceeds SBP"):
        baffle.write_case(tmp_path / "bad", bsa_m2=0.37, sbp_mmhg=78, dbp_mmhg=107)
    assert not (tmp_path / "bad").exists()


def test_flow_sections_reach_the_design(tmp_path):
    surface, points, bsa_m2 = baffle.phantom()
    plain = baffle.design(surface.points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2)
    assert plain.report.get("flow_sections") is None
    ruled = baffle.design(surface.points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2, flow_sections=True)
    flow = ruled.report["flow_sections"]
    assert flow["goal_area_mm2"] == pytest.approx(plain.target_area_mm2) and len(flow["rounds"]) >= 1


def _designed_target_mm2(out, **target):
    """The quick phantom plan with `target`, stopped once its design is written: the
    design report's target area (mm2)."""
    design_report = out / "design" / "report.json"
    with pytest.raises(baffle.Cancelled):
        baffle.plan(out, cancel=design_report.exists, **QUICK, **target)
    return json.loads(design_report.read_text())["target_area_mm2"]


def test_the_plans_target_is_the_z_score_area_or_diameter_given(tmp_path):
    z0 = _designed_target_mm2(tmp_path / "z0")
    z1 = _designed_target_mm2(tmp_path / "z1", z_score=1)
    assert z1 > z0
    assert _designed_target_mm2(tmp_path / "area", bsa_m2=0.37, target_area_mm2=120) == 120
    assert _designed_target_mm2(tmp_path / "diameter", annulus_diameter_mm=12) == pytest.approx(math.pi * 36)


def test_two_targets_are_refused_with_the_librarys_words(tmp_path):
    seen = []
    with pytest.raises(baffle.BaffleError, match="give one target: --target-area-mm2 or --annulus-diameter-mm, not both") as error:
        baffle.plan(tmp_path / "plan", progress=lambda f, s: seen.append(s), target_area_mm2=120, annulus_diameter_mm=12, **QUICK)
    assert error.value.status == 2
    with pytest.raises(baffle.BaffleError, match="--z-score 1 applies to the BSA's annulus"):
        baffle.plan(tmp_path / "plan", z_score=1, target_area_mm2=120, **QUICK)
    assert seen == [] and not (tmp_path / "plan").exists()
