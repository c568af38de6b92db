"""The README's Python example runs as written (from the repository's root, with the
patient data beside it)."""

import os
import re

import pytest

from conftest import REPO, data_dir


def readme_python_blocks():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    return [re.sub(r"^  ", "", block, flags=re.M) for block in re.findall(r"```python\n(.*?)```", text, flags=re.S)]


def test_the_readme_python_example_runs(capsys, monkeypatch):
    pytest.importorskip("vtkmodules.vtkIOXML")
    if not (data_dir() / "p2" / "design_input" / "capped_ventricle.vtp").exists():
        pytest.skip(f"patient data not found at {data_dir()} (set BAFFLE_DATA_DIR)")
    blocks = readme_python_blocks()
    assert blocks, "README.md has no ```python example"
    monkeypatch.chdir(REPO)
    if os.environ.get("BAFFLE_DATA_DIR"):
        blocks = [b.replace("../shared/data", os.environ["BAFFLE_DATA_DIR"]) for b in blocks]
    for block in blocks:
        exec(compile(block, "README.md", "exec"), {})
    out = capsys.readouterr().out
    assert re.search(r"target \d+\.\d mm2, baffle \d+\.\d mm2", out), out
