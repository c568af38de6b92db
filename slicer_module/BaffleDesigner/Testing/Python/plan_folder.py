"""A small `baffle plan` --out folder as the plan writes it (report.json, and pictures/ with
pictures.json and PNGs), for the report tests without running a plan."""

import json
from pathlib import Path


def write_png(path: Path, width: int, height: int, rgb) -> None:
    import vtk

    image = vtk.vtkImageData()
    image.SetDimensions(width, height, 1)
    image.AllocateScalars(vtk.VTK_UNSIGNED_CHAR, 3)
    for k in range(3):
        image.GetPointData().GetScalars().FillComponent(k, rgb[k])
    writer = vtk.vtkPNGWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(image)
    writer.Write()


def plan_folder(root: Path, rendered=True, verdict="inconclusive") -> Path:
    """Two pictures when `rendered`, else the reason the plan gives for none."""
    pictures = root / "pictures"
    pictures.mkdir(parents=True)
    entries = []
    if rendered:
        for name, rgb in (("context_anterior.png", (200, 60, 60)), ("speed_cut_face_on.png", (40, 60, 190))):
            write_png(pictures / name, 80, 60, rgb)
            entries.append({"file": name, "title": name[:-4], "caption": f"caption of {name}", "section": "anatomy"})
        (pictures / "pictures.json").write_text(json.dumps({"frame": "LPS", "pictures": entries, "notes": []}))
    report = {
        "status": "completed",
        "verdict": {"verdict": verdict, "text": f"{verdict.upper()}: dp 1.72 mmHg (the steady solve did not reach its residual target)", "warnings": ["poor mesh"]},
        "pictures": {"rendered": True, "files": [str(pictures / e["file"]) for e in entries]} if rendered
        else {"rendered": False, "reason": "python3 could not be started"},
    }
    (root / "report.json").write_text(json.dumps(report))
    (root / "report.html").write_text("<html></html>")
    return root
