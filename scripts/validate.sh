#!/usr/bin/env bash
# Regenerates the CFD rows of docs/validation.md (paper 2.5 chain on the published and
# on our designed domains, p1-p3) with target/release/baffle; see
# scripts/validation/validate.py for what each row runs.
#   bash scripts/validate.sh [--quick|--smoke] [--out DIR] [--patients p1,p2,p3] [--only gci|cycles|chain|area|base] [--tables-only]
#   --smoke: p2 published, 1.25 mm, 20 time steps (about a minute; scripts/test.sh)
#   --quick: published and designed domains of every patient to the first peak at 1.25 mm
#   (default, full): plus inflow profile, fine interior mesh, elevated flow and the
#   mesh study with GCI on every patient's published and designed domain, four cycles and the
#   extension's inflow/outflow caps moved, and our designs on the paper's design input at
#   z = -1..4 (--only gci: just the study, --only cycles: the four-cycle runs, --only chain:
#   the moved caps, --only area: the baffle sizes, --only base: everything else,
#   --only same-mesh: p1 and p3 published at 1.25 and 0.75 mm and p2 designed at 1.25 mm run by our engine and by
#   svMultiPhysics (skipped, saying so, where svmultiphysics is not on PATH))
# A stage whose output exists under OUT/work is reused (delete OUT after changing the
# code); --smoke always starts from an empty OUT. --tables-only rebuilds the tables from
# the stages already run (rows with a stage missing are left out).
# Patient data: BAFFLE_DATA_DIR, else ../shared/data beside the repository.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
mode=full
out=""
patients=p1,p2,p3
extra=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --quick) mode=quick ;;
    --smoke) mode=smoke ;;
    --full) mode=full ;;
    --tables-only) extra+=(--tables-only) ;;
    --out) out="$2"; shift ;;
    --patients) patients="$2"; shift ;;
    --only) extra+=(--only "$2"); shift ;;
    -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
    *) echo "validate.sh: unknown argument $1" >&2; exit 2 ;;
  esac
  shift
done
data="${BAFFLE_DATA_DIR:-$repo/../shared/data}"
if [[ ! -f "$data/patients.json" ]]; then
  echo "validate.sh: no patient data at $data (set BAFFLE_DATA_DIR)" >&2
  exit 2
fi
out="${out:-$repo/out/validation-$mode}"
baffle="$repo/target/release/baffle"
if [[ ! -x "$baffle" ]]; then
  (cd "$repo" && nice -n 10 cargo build --release -p baffle-cli)
fi
if [[ "$mode" == smoke ]]; then rm -rf "$out"; fi
start=$(date +%s)
python3 "$repo/scripts/validation/validate.py" --mode "$mode" --data "$data" --out "$out" --baffle "$baffle" --patients "$patients" "${extra[@]}"
echo "validate.sh: $mode done in $(( $(date +%s) - start )) s; tables in $out/results.md, results.csv, results.json"
