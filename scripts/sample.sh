#!/usr/bin/env bash
# Build the `baffle` command and run its main job on the built-in synthetic heart (LV, RV
# and aorta as segment surfaces, and suture points): `baffle plan` prepares the capped
# ventricle, designs the baffle, extends the domain (mid-LV inflow, STJ outflow), meshes it
# at 1.25 mm (gmsh) and runs the quick CFD estimate (pulsatile from rest to the first flow
# peak), then prints the
# verdict (PASSES / FAILS / INCONCLUSIVE with its reason) and where report.html is.
# Results go to out/sample (heart/: the inputs; plan/: one subfolder per stage, report.json,
# report.html).
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v cargo >/dev/null; then
  echo "cargo not found: install the Rust toolchain (rustup) first" >&2
  exit 1
fi
# gmsh (PyPI wheel) is the volume mesher `baffle mesh` runs as a child process.
python3 -c "import gmsh" >/dev/null 2>&1 || command -v gmsh >/dev/null || bash scripts/install_gmsh.sh
# vtk (PyPI wheel) renders the report's 3D pictures offscreen; without it the report says so.
python3 -c "import vtk" >/dev/null 2>&1 || python3 -m pip install --quiet --disable-pip-version-check vtk numpy \
  || echo "sample: could not install vtk (pip install vtk): the report will have no 3D pictures" >&2
cargo build --release -p baffle-cli
rm -rf out/sample/plan
./target/release/baffle phantom --heart --out out/sample/heart
./target/release/baffle plan --segmentations out/sample/heart --points out/sample/heart/suture_points.mrk.json \
  --bsa 0.2 --bp 107/78 --quick --edge-length-mm 1.25 --out out/sample/plan
