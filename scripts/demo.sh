#!/usr/bin/env bash
# Installs what is missing, builds, and runs the main job on the embedded default
# scenario hybrid-120m (seed 1): RBPF local maps (FastSLAM 2.0, 300 particles, each map
# moment-matched into one Gaussian and checked against ground truth) joined by the sparse
# EIF back-end; then, on the same data for comparison, single-map EKF-SLAM, SEIF, ISEIF
# and dead reckoning. Prints each run's summary table and where its outputs went
# (runs/demo/{rbpf_eif,ekfslam,seif,iseif,odometry}/; OUT overrides runs/demo).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh" > "${TMPDIR:-/tmp}/subslam_demo_build.log" 2>&1 || {
  cat "${TMPDIR:-/tmp}/subslam_demo_build.log"; exit 1; }
BIN="${BUILD_DIR:-$ROOT/build}/apps/subslam"
OUT="${OUT:-$ROOT/runs/demo}"
"$BIN" run --scenario hybrid-120m --seed 1 --frontend rbpf --particles 300 --backend eif \
  --out "$OUT/rbpf_eif"
echo
"$BIN" run --scenario hybrid-120m --seed 1 --frontend ekfslam --out "$OUT/ekfslam"
echo
"$BIN" run --scenario hybrid-120m --seed 1 --frontend seif --out "$OUT/seif"
echo
"$BIN" run --scenario hybrid-120m --seed 1 --frontend iseif --out "$OUT/iseif"
echo
"$BIN" run --scenario hybrid-120m --seed 1 --frontend odometry --out "$OUT/odometry"
