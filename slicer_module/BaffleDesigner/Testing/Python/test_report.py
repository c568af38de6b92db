"""BaffleDesignerLib.report: a `baffle plan` folder's verdict and pictures as the module shows them."""

import json

import pytest

from BaffleDesignerLib import report as bdreport
from plan_folder import plan_folder


def test_a_plan_gives_its_verdict_and_pictures_in_order(tmp_path):
    report = bdreport.read_plan(str(plan_folder(tmp_path)))
    assert report.verdict == "inconclusive" and report.verdict_line.startswith("INCONCLUSIVE: ")
    assert report.warnings == ["poor mesh"] and report.pictures_missing == ""
    assert [p.title for p in report.pictures] == ["context_anterior", "speed_cut_face_on"]
    assert all(p.path.endswith(".png") and p.caption for p in report.pictures)
    assert report.html == str(tmp_path / "report.html")


def test_a_plan_without_pictures_says_why(tmp_path):
    report = bdreport.read_plan(str(plan_folder(tmp_path, rendered=False)))
    assert report.pictures == [] and "python3" in report.pictures_missing


def test_a_failed_plan_or_a_missing_picture_is_named(tmp_path):
    (tmp_path / "report.json").write_text(json.dumps({"status": "failed", "failed_stage": "mesh-nominal", "error": "gmsh not found"}))
    with pytest.raises(bdreport.PlanReportError, match="mesh-nominal failed: gmsh not found"):
        bdreport.read_plan(str(tmp_path))
    folder = plan_folder(tmp_path / "plan")
    (folder / "pictures" / "speed_cut_face_on.png").unlink()
    with pytest.raises(bdreport.PlanReportError, match="speed_cut_face_on.png"):
        bdreport.read_plan(str(folder))
    with pytest.raises(bdreport.PlanReportError, match="report.json"):
        bdreport.read_plan(str(tmp_path / "nowhere"))
