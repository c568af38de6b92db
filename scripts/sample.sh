#!/usr/bin/env bash
# Build the `baffle` command and run the main job on the built-in sample: the
# area-constrained baffle design on the synthetic phantom (BSA 0.37 m2), its volume
# mesh at 1.25 mm (gmsh) and a quick steady simulation at peak flow, printing the
# pressure difference. Results go to out/sample (domain.vtp, baffle.vtp,
# centerline.vtp, sections.vtp, seam.vtp, report.json, mesh.vtu, cfd/summary.json).
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v cargo >/dev/null; then
  echo "cargo not found: install the Rust toolchain (rustup) first" >&2
  exit 1
fi
# gmsh (PyPI wheel) is the volume mesher `baffle mesh` runs as a child process.
python3 -c "import gmsh" >/dev/null 2>&1 || command -v gmsh >/dev/null || bash scripts/install_gmsh.sh
cargo build --release -p baffle-cli
./target/release/baffle design --phantom --out out/sample
./target/release/baffle mesh --surface out/sample/domain.vtp --edge-length-mm 1.25 --out out/sample/mesh.vtu
cat > out/sample/case.json <<'EOF'
{
  "mesh": { "volume": "mesh.vtu", "units": "mm" },
  "faces": { "inlet": 11, "outlets": [16], "walls": [2, 10] },
  "inflow": { "bsa_m2": 0.37, "cardiac_index_l_min_m2": 3.48 },
  "outlet": { "sbp_mmhg": 107, "dbp_mmhg": 78 }
}
EOF
./target/release/baffle simulate out/sample/case.json --out out/sample/cfd --steady | grep -v filter-progress
