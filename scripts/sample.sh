#!/usr/bin/env bash
# Build the `baffle` command and run the main job on the built-in sample: the
# area-constrained baffle design on the synthetic phantom (BSA 0.37 m2).
# Results go to out/sample (domain.vtp, baffle.vtp, centerline.vtp, sections.vtp,
# seam.vtp, report.json).
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v cargo >/dev/null; then
  echo "cargo not found: install the Rust toolchain (rustup) first" >&2
  exit 1
fi
cargo build --release -p baffle-cli
./target/release/baffle design --phantom --out out/sample
