#!/usr/bin/env bash
# The studies' small-trial summaries against the stored ones (tests/data/study_summaries/):
#
#   scripts/study_summary_check.sh check|write STUDY... [--tool PATH]
#
# check: runs each study's small trial and compares its summary.md with the stored one byte
# for byte (the test StudySummariesAreCurrent); write: stores it (scripts/update_reproducing.sh).
# The small trial is two trials of the study's methods whose runs do not draw random numbers
# of their own (the particle filters' draws, repeatable on one build, may round differently
# on another instruction set, and a stored figure must hold on every machine CI runs on).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
mode=$1
shift
BIN="${BUILD_DIR:-$ROOT/build}/apps/subslam"
studies=()
while (($#)); do
  if [[ "$1" == --tool ]]; then BIN=$2; shift 2; else studies+=("$1"); shift; fi
done
methods() {
  case "$1" in
    hybridslam) echo ekf ;;
    combined-slam) echo ekf-eif,ekfslam,odometry ;;
    fmj) echo fmj,fmj-fixed,ekfslam ;;
    iseif) echo ekfslam,seif,iseif ;;
    *) echo "study_summary_check: unknown study $1" >&2; exit 2 ;;
  esac
}
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
status=0
for study in "${studies[@]}"; do
  "$BIN" study "$study" --trials 2 --methods "$(methods "$study")" --workers 2 --plots=false --quiet \
    --progress=false --out "$work/$study"
  stored="$ROOT/tests/data/study_summaries/$study.md"
  if [[ "$mode" == write ]]; then
    mkdir -p "$(dirname "$stored")"
    cp "$work/$study/summary.md" "$stored"
    echo "study_summary_check: wrote $stored"
  elif ! diff -u "$stored" "$work/$study/summary.md"; then
    echo "study_summary_check: $study's figures moved: run scripts/update_reproducing.sh $study, which" \
         "updates docs/reproducing.md and $stored" >&2
    status=1
  fi
done
exit $status
