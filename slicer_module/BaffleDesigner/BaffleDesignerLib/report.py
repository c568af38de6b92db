"""A `baffle plan` folder as the module shows it: the verdict of its report.json and the
pictures the plan rendered (pictures/pictures.json: the PNGs report.html embeds, made by
python/baffle/render.py), or why it has none. Qt-free, so the tests read it headless."""

import json
import os
from dataclasses import dataclass, field
from typing import List

VERDICTS = ("passes", "fails", "inconclusive")


class PlanReportError(ValueError):
    """The folder is not a completed plan; the message names the file and what is wrong."""


@dataclass
class PlanPicture:
    path: str
    title: str
    caption: str


@dataclass
class PlanReport:
    folder: str
    verdict: str  # "passes", "fails" or "inconclusive"
    verdict_line: str  # as the command line's last line: PASSES / FAILS / INCONCLUSIVE and why
    warnings: List[str] = field(default_factory=list)
    pictures: List[PlanPicture] = field(default_factory=list)
    pictures_missing: str = ""  # why there are no pictures ("" when there are)

    @property
    def html(self) -> str:
        return os.path.join(self.folder, "report.html")


def _read_json(path: str) -> dict:
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError) as error:
        raise PlanReportError(f"{path}: {error}") from error


def read_plan(folder: str) -> PlanReport:
    """The plan in `folder` (the --out of `baffle plan`)."""
    path = os.path.join(folder, "report.json")
    report = _read_json(path)
    if report.get("status") != "completed":
        raise PlanReportError(f"{path}: the plan did not complete: stage {report.get('failed_stage')} failed: {report.get('error')}")
    verdict = report.get("verdict", {})
    if verdict.get("verdict") not in VERDICTS:
        raise PlanReportError(f"{path}: no three-state verdict (written by an older baffle?)")
    result = PlanReport(folder=folder, verdict=verdict["verdict"], verdict_line=verdict.get("text", ""), warnings=list(verdict.get("warnings", [])))
    rendered = report.get("pictures", {})
    if not rendered.get("rendered"):
        result.pictures_missing = rendered.get("reason") or "the report holds no pictures (written by an older baffle?)"
        return result
    manifest_path = os.path.join(folder, "pictures", "pictures.json")
    for entry in _read_json(manifest_path).get("pictures", []):
        picture = os.path.join(folder, "pictures", entry["file"])
        if not os.path.isfile(picture):
            raise PlanReportError(f"{manifest_path}: lists {entry['file']}, which is not in {os.path.dirname(picture)}")
        result.pictures.append(PlanPicture(picture, entry.get("title", entry["file"]), entry.get("caption", "")))
    return result
