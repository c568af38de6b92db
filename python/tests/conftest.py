"""Shared fixtures: the patient data directory (BAFFLE_DATA_DIR, else ../shared/data
beside the repository); tests that need it skip with a note when it is absent."""

import json
import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def data_dir() -> Path:
    return Path(os.environ.get("BAFFLE_DATA_DIR") or REPO.parent / "shared" / "data")


@pytest.fixture
def patient_input():
    """(design_input directory, BSA m2) of a patient, or skip."""

    def load(patient: str):
        root = data_dir()
        folder = root / patient / "design_input"
        if not (folder / "capped_ventricle.vtp").exists():
            pytest.skip(f"patient data not found at {folder} (set BAFFLE_DATA_DIR)")
        bsa_m2 = json.loads((root / "patients.json").read_text())["patients"][patient]["bsa_m2"]
        return folder, bsa_m2

    return load
