#!/usr/bin/env bash
# Tests of the 3D Slicer module (slicer_module/BaffleDesigner): its logic on real MRML
# classes from the PyPI wheel slicer-core (headless scene, model / markups / table / plot
# nodes), the command line process runner, and the module's files; then the module's
# Widget, Logic and self-test on the headless harness (Testing/Python/slicer_harness.py:
# PySide6 on Qt's offscreen platform standing in for Slicer's PythonQt).
#
# slicer-core pins an exact vtk (5.13.31053.0 -> vtk==9.6.2), so it goes into its own
# virtual environment ($BAFFLE_SLICER_VENV, default target/slicer-venv) that sees the
# system packages (numpy, pytest) but keeps its vtk away from the interpreter the other
# test suites use. The baffle package is taken from ./python with the freshly built
# libbaffle (BAFFLE_LIBRARY) and the baffle executable (BAFFLE_EXECUTABLE); test_packaging.py
# also installs the extension's package layout (CMake, cargo already built here) and runs
# the installed module without them.
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
# wheel: test_packaging.py builds the Python package's wheel without build isolation.
if ! "$venv/bin/python" -c "import pytest, numpy, wheel" >/dev/null 2>&1; then
  "$venv/bin/python" -m pip install --quiet pytest numpy wheel
fi
# 6.12.0 loses a reference on every Signal.emit from Python (True/False are freed and the
# interpreter aborts); 6.9.3 does not.
pyside="PySide6-Essentials==6.9.3"
if ! "$venv/bin/python" -c "import PySide6, sys; sys.exit(PySide6.__version__ != '${pyside#*==}')" >/dev/null 2>&1; then
  step "pip install $pyside (Qt for the widget harness, about 100 MB)"
  "$venv/bin/python" -m pip install --quiet "$pyside"
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
"$venv/bin/python" -m pytest -q -p no:cacheprovider --ignore=test_widget.py .

# Its own process: the harness sets up `qt`, `slicer.app` and `slicer.mrmlScene` for good.
step "pytest test_widget.py (headless widget harness, QT_QPA_PLATFORM=offscreen)"
QT_QPA_PLATFORM=offscreen "$venv/bin/python" -m pytest -q -p no:cacheprovider test_widget.py
