#!/usr/bin/env bash
# Tests of the 3D Slicer module (slicer_module/BaffleDesigner): its logic on real MRML
# classes from the PyPI wheel slicer-core (headless scene, model / markups / table / plot
# nodes), the command line process runner, and the module's files.
#
# slicer-core pins an exact vtk (5.13.31053.0 -> vtk==9.6.2), so it goes into its own
# virtual environment ($BAFFLE_SLICER_VENV, default target/slicer-venv) that sees the
# system packages (numpy, pytest) but keeps its vtk away from the interpreter the other
# test suites use. The baffle package is taken from ./python with the freshly built
# libbaffle (BAFFLE_LIBRARY) and the baffle executable (BAFFLE_EXECUTABLE).
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo"
python="${PYTHON:-python3}"
venv="${BAFFLE_SLICER_VENV:-$repo/target/slicer-venv}"

step() { printf '\n==> %s\n' "$*"; }

step "cargo build --release -p baffle-capi -p baffle-cli"
cargo build --release -p baffle-capi -p baffle-cli

if [[ ! -x "$venv/bin/python" ]]; then
  step "python venv for slicer-core: $venv"
  "$python" -m venv --system-site-packages "$venv"
fi
if ! "$venv/bin/python" -c "import slicer; slicer.vtkMRMLScene" >/dev/null 2>&1; then
  step "pip install slicer-core (about 45 MB, plus its pinned vtk, about 150 MB)"
  "$venv/bin/python" -m pip install --quiet slicer-core
fi
if ! "$venv/bin/python" -c "import pytest, numpy" >/dev/null 2>&1; then
  "$venv/bin/python" -m pip install --quiet pytest numpy
fi

export BAFFLE_LIBRARY="$repo/target/release/libbaffle.so"
export BAFFLE_EXECUTABLE="$repo/target/release/baffle"
export PYTHONPATH="$repo/python${PYTHONPATH:+:$PYTHONPATH}"

step "pytest slicer_module/BaffleDesigner/Testing/Python"
"$venv/bin/python" - <<'PY'
import slicer, vtk, baffle
print(f"slicer-core MRML from {slicer.__file__}; vtk {vtk.vtkVersion.GetVTKVersion()}; baffle {baffle.__file__}")
PY
cd slicer_module/BaffleDesigner/Testing/Python
"$venv/bin/python" -m pytest -q -p no:cacheprovider .
