#!/usr/bin/env bash
# Checks that a change leaves every output the same to the bit: runs the same commands
# with two builds of the tool (e.g. the one before a restructuring and the one after) and
# compares every file they write. report.json is compared without its wall-clock figures
# (time sections, *_seconds, memory, and scans_with_fewer_threads, which depends on
# thread timing), the build and the command line, with each suite's directory read as
# one; joins.csv without its `seconds` column; a key only one side has is listed. Exits
# 1 when anything differs.
#
#   scripts/outputs_unchanged.sh OLD_SUBSLAM NEW_SUBSLAM [VICTORIA_PARK_DIR]
set -euo pipefail
OLD=$1; NEW=$2
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VP="${3:-$ROOT/../shared/data/victoria_park}"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT

run_suite() {  # BIN OUT
  local bin=$1 out=$2 q="--quiet --progress=false"
  "$bin" run --scenario hybrid-120m --seed 1 --frontend rbpf --particles 300 --backend eif --out "$out/demo" $q
  for f in ekfslam seif iseif odometry fastslam; do
    "$bin" run --scenario hybrid-120m --seed 1 --frontend $f --out "$out/h_$f" $q
  done
  "$bin" run --scenario hybrid-120m --seed 2 --alpha 0.7 --beta 0.02 --frontend ekf --backend ceres --out "$out/h_ekf_ceres" $q
  "$bin" run --scenario combined-2km --seed 1 --frontend rbpf --backend eif --out "$out/c2km" $q
  "$bin" run --scenario combined-2km --seed 2 --frontend rbpf --known_association --backend eif --duration 300 --out "$out/known" $q
  "$bin" run --scenario hybrid-120m --seed 3 --alpha 0.7 --beta 0.02 --frontend ekfslam --association jcbb --gate 0.95 \
      --existence_alpha 0.8 --out "$out/jcbb" $q
  "$bin" run --scenario hybrid-120m --seed 3 --frontend rbpf --particles 50 --sample_association --submap_max_duration 5 \
      --backend ekf --ekf_fusion conditional --out "$out/sampled" $q
  "$bin" run --scenario hybrid-120m --seed 3 --frontend ekf --backend tree-eif --single_linearization \
      --eif_ordering nested_dissection --out "$out/tree" $q
  for b in eif ekf tree-ekf tree-eif; do
    "$bin" join --submaps "$out/demo/submaps.jsonl" --backend $b --scenario hybrid-120m --seed 1 --out "$out/join_$b" --quiet
  done
  "$bin" join --submaps "$out/c2km/submaps.jsonl" --backend eif --scenario combined-2km --seed 1 --out "$out/c2km_join" --quiet
  "$bin" simulate --scenario hybrid-120m --seed 4 --duration 200 --out "$out/sim4" --quiet
  "$bin" solve --graph "$out/sim4/graph.g2o" --methods submaps,submaps-lm,eif --write_local_maps \
      --out "$out/solve_sim4" --noplots --quiet
  if [ -f "$VP/../graphs/victoria_park.txt" ]; then
    "$bin" solve --graph "$VP/../graphs/victoria_park.txt" --format gtsam --methods submaps,submaps-lm \
        --write_local_maps --out "$out/solve_vp" --noplots --quiet
  fi
  if [ -f "$VP/dataset.json" ]; then
    "$bin" run --dataset "$VP" --frontend rbpf --backend eif --sensor_yaw -0.0182 --out "$out/vp_rbpf" $q
    "$bin" run --dataset "$VP" --frontend ekfslam --out "$out/vp_ekfslam" $q
  fi
}

run_suite "$OLD" "$WORK/old"
run_suite "$NEW" "$WORK/new"
python3 - "$WORK/old" "$WORK/new" <<'PY'
import filecmp, json, os, sys
old, new = sys.argv[1], sys.argv[2]
# Wall-clock figures: the time sections, memory, and counts that depend on thread timing;
# and what names the build and the two suites' own directories.
VOLATILE = {'time_seconds', 'seconds', 'peak_rss_kb', 'peak_rss_mb', 'rss_kb_by_tenth_of_steps', 'scans_with_fewer_threads', 'build',
            'command_line'}
def volatile(key):
    return key in VOLATILE or key.endswith('_seconds')
def strip(x, here=old):
    if isinstance(x, dict):
        return {k: strip(v, here) for k, v in x.items() if not volatile(k)}
    if isinstance(x, list):
        return [strip(v, here) for v in x]
    return x.replace(here, "DIR") if isinstance(x, str) else x
def diff(a, b, path, out):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{path}/{k}: only in {'new' if k in b else 'old'}")
            else:
                diff(a[k], b[k], f"{path}/{k}", out)
    elif a != b:
        out.append(f"{path}: {a!r} -> {b!r}")
differing, compared = 0, 0
for root, _, files in os.walk(old):
    for name in sorted(files):
        a = os.path.join(root, name)
        b = os.path.join(new, os.path.relpath(a, old))
        compared += 1
        if not os.path.exists(b):
            print("missing:", os.path.relpath(b, new)); differing += 1
        elif name == "report.json":
            out = []
            diff(strip(json.load(open(a)), old), strip(json.load(open(b)), new), "", out)
            if out:
                differing += 1
                print(os.path.relpath(a, old) + ":"); [print("  " + line) for line in out[:20]]
        elif name == "joins.csv":  # without its wall-clock `seconds` column
            rows = lambda p: [l.split(",")[:1] + l.split(",")[2:] for l in open(p).read().splitlines()]
            if rows(a) != rows(b):
                print("differs:", os.path.relpath(a, old)); differing += 1
        elif not filecmp.cmp(a, b, shallow=False):
            print("differs:", os.path.relpath(a, old)); differing += 1
print(f"{compared} files compared, {differing} differ")
sys.exit(1 if differing else 0)
PY
