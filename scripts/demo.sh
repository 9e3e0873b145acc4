#!/usr/bin/env bash
# Installs what is missing, builds, and runs the main job on the embedded default
# scenario: EKF-SLAM with unknown data association on hybrid-120m (seed 1), next to
# dead reckoning on the same data. Prints the summary tables and where the outputs went.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh" > "${TMPDIR:-/tmp}/subslam_demo_build.log" 2>&1 || {
  cat "${TMPDIR:-/tmp}/subslam_demo_build.log"; exit 1; }
BIN="${BUILD_DIR:-$ROOT/build}/apps/subslam"
OUT="${OUT:-$ROOT/runs/demo}"
"$BIN" run --scenario hybrid-120m --seed 1 --frontend ekfslam --out "$OUT/ekfslam"
echo
"$BIN" run --scenario hybrid-120m --seed 1 --frontend odometry --out "$OUT/odometry"
