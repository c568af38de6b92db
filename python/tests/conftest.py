"""Shared fixtures: the patient data directory (BAFFLE_DATA_DIR, else ../shared/data
beside the repository); tests that need it skip with a note when it is absent
(and fail under CI=true)."""

import json
import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def data_dir() -> Path:
    return Path(os.environ.get("BAFFLE_DATA_DIR") or REPO.parent / "shared" / "data")


def missing_data(folder: Path) -> None:
    """Skip a real-data test, with a note; under CI=true fail it instead, so a broken
    path cannot turn the real-data checks into silent passes."""
    if os.environ.get("CI", "").lower() in ("true", "1"):
        pytest.fail(f"patient data not found at {folder} (CI=true: the real-data checks must run; set BAFFLE_DATA_DIR)")
    pytest.skip(f"patient data not found at {folder} (set BAFFLE_DATA_DIR)")


@pytest.fixture
def patient_input():
    """(design_input directory, BSA m2) of a patient, or skip."""

    def load(patient: str):
        root = data_dir()
        folder = root / patient / "design_input"
        if not (folder / "capped_ventricle.vtp").exists():
            missing_data(folder)
        bsa_m2 = json.loads((root / "patients.json").read_text())["patients"][patient]["bsa_m2"]
        return folder, bsa_m2

    return load


def read_vtp(path):
    """A .vtp file through VTK's own reader (needs the vtk wheel); fails on an empty read."""
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    assert reader.GetOutput().GetNumberOfCells() > 0, f"cannot read {path}"
    return reader.GetOutput()


def plane_cut(polydata, origin, normal):
    """The plane's cut through a surface as polylines: vtkCutter, joined by vtkStripper."""
    from baffle.vtk_adapters import joined_lines, plane_cut

    return joined_lines(plane_cut(polydata, origin, normal))
