#!/usr/bin/env bash
# Regenerates the studies' tables in docs/reproducing.md and the small-trial summaries the
# test suite compares against (tests/data/study_summaries/), from the code as it is:
#
#   scripts/update_reproducing.sh [STUDY...]     (default: every study)
#
# Each study runs in full (its paper's trials; iseif with the Victoria Park data set in
# VICTORIA_PARK_DIR, default ../shared/data/victoria_park) into runs/reproducing/STUDY, and
# its summary.md replaces the block between the doc's markers
#   <!-- BEGIN STUDY summary.md ... -->  and  <!-- END STUDY summary.md -->.
# Then the study's small trial (scripts/study_summary_check.sh's command) is written to
# tests/data/study_summaries/STUDY.md; the test StudySummariesAreCurrent fails when the
# code's figures move without this script being run. HybridSLAM's full table takes about
# 20 minutes on 2 cores, the others a few minutes together.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BIN="${BUILD_DIR:-$ROOT/build}/apps/subslam"
VP="${VICTORIA_PARK_DIR:-$ROOT/../shared/data/victoria_park}"
DOC="$ROOT/docs/reproducing.md"
studies=("$@")
((${#studies[@]})) || studies=(hybridslam combined-slam fmj iseif)
for study in "${studies[@]}"; do
  out="$ROOT/runs/reproducing/$study"
  extra=()
  [[ "$study" == iseif ]] && extra=(--dataset "$VP")
  echo "update_reproducing: $study (full) -> $out"
  "$BIN" study "$study" "${extra[@]}" --quiet --progress=false --out "$out"
  python3 - "$DOC" "$study" "$out/summary.md" <<'PY'
import sys
doc, study, summary = sys.argv[1:]
text = open(doc).read()
begin = f"<!-- BEGIN {study} summary.md"
end = f"<!-- END {study} summary.md -->"
i, j = text.find(begin), text.find(end)
if i < 0 or j < 0:
    sys.exit(f"{doc}: no markers for {study}")
i = text.index("-->", i) + len("-->\n")
body = open(summary).read()
# The summary's own title is the doc's section heading.
body = body.split("\n", 2)[2] if body.startswith("# ") else body
open(doc, "w").write(text[:i] + body.strip("\n") + "\n" + text[j:])
PY
  "$ROOT/scripts/study_summary_check.sh" write "$study"
done
