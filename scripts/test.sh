#!/usr/bin/env bash
# Runs every test of the project: Rust (cargo test + the design and solver benchmarks' smoke modes, a 20 s fuzz run, one pass of the kernel bench),
# the check that no crate or Python package has an import cycle between its modules,
# the C/C++/VTK integration tests (CMake + ctest, incl. valgrind) and the Python
# package's tests (pip install ./python + pytest) and the 3D Slicer module's tests on
# slicer-core (scripts/test_slicer.sh). Exits non-zero on any failure.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo"
build_dir="$repo/build"
jobs="$(nproc 2>/dev/null || echo 2)"
python="${PYTHON:-python3}"

step() { printf '\n==> %s\n' "$*"; }

step "cargo test --workspace --release"
cargo test --workspace --release

step "no import cycles (scripts/check_import_cycles.py)"
"$python" scripts/check_import_cycles.py --self-test
"$python" scripts/check_import_cycles.py

if [[ -f rust/baffle-cli/benches/design.rs ]]; then
  step "cargo bench -p baffle-cli --bench design -- --smoke"
  cargo bench -p baffle-cli --bench design -- --smoke
else
  step "skipping the benchmark smoke run: rust/baffle-cli/benches/design.rs does not exist yet"
fi

step "cargo bench -p baffle-cli --bench fuzz -- --seconds 20 (readers and design on perturbed surfaces: no panic, no hang)"
cargo bench -p baffle-cli --bench fuzz -- --seconds 20

step "cargo bench -p baffle-cfd --bench solver -- --smoke"
cargo bench -p baffle-cfd --bench solver -- --smoke
step "cargo bench -p baffle-cfd --bench kernels -- --reps 1 (p2's pattern: the kernels still run)"
cargo bench -p baffle-cfd --bench kernels -- --reps 1

step "cmake configure + build + ctest ($build_dir)"
cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release
cmake --build "$build_dir" --parallel "$jobs"
ctest --test-dir "$build_dir" --output-on-failure

step "pip install ./python + pytest"
"$python" -m pip install --quiet ./python
# Run from the tests folder so `import baffle` is the installed package, not ./python/baffle.
(cd python/tests && "$python" -m pytest -q .)

step "3D Slicer module tests (slicer-core, own venv)"
bash scripts/test_slicer.sh

step "validation helpers (pytest scripts/validation) and the smoke row (scripts/validate.sh --smoke: p2 published, 20 steps)"
(cd scripts/validation && "$python" -m pytest -q -p no:cacheprovider .)
data_dir="${BAFFLE_DATA_DIR:-$repo/../shared/data}"
if [[ -f "$data_dir/patients.json" || "${CI:-}" == "true" ]]; then
  bash scripts/validate.sh --smoke --out "$build_dir/validation-smoke"
else
  echo "skipping the validation smoke row: no patient data at $data_dir"
fi

step "all tests passed"
