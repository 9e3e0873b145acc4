#!/bin/sh
# Fuzzes the readers of outside files with libFuzzer under AddressSanitizer + UBSan.
#
#   scripts/fuzz.sh [SECONDS] [TARGET…]    (default 30 s each; targets: graph_format submaps_jsonl
#                                        dataset_manifest dataset_text)
#
# Builds each target in fuzz/ with clang (Debian's clang-14 and its libFuzzer) into
# build-fuzz/, seeds its corpus from test data the tool writes (a short simulated world's
# graph in every format and its local maps; the Victoria Park graph's first lines when
# ../shared is there), and runs it for SECONDS. A crash leaves its input in
# build-fuzz/TARGET-crash-* and fails the script; each one found becomes a test case.
# FUZZ_RUNS=N stops each target after N executions if that comes first (a campaign:
# FUZZ_RUNS=10000000 scripts/fuzz.sh 3600 TARGET).
set -eu
cd "$(dirname "$0")/.."
seconds=${1:-30}
[ $# -gt 0 ] && shift
targets=${*:-graph_format submaps_jsonl dataset_manifest dataset_text}
out=build-fuzz
mkdir -p "$out"
command -v clang++ >/dev/null || { echo "fuzz.sh: clang++ is missing (apt-get install clang)" >&2; exit 1; }
tool=build/apps/subslam
[ -x "$tool" ] || { echo "fuzz.sh: build the tool first (scripts/setup.sh): it writes the seeds" >&2; exit 1; }

sources_graph_format="posegraph/src/graph_format.cc posegraph/src/graph_text.cc posegraph/src/g2o_format.cc
  posegraph/src/toro_format.cc posegraph/src/isam_format.cc posegraph/src/pose_graph.cc
  posegraph/src/measurement_residuals.cc graph/src/pose2.cc io/src/text_table.cc"
sources_submaps_jsonl="io/src/submaps_jsonl.cc graph/src/local_submap.cc graph/src/pose2.cc"
sources_dataset="io/src/dataset_reader.cc io/src/dataset.cc io/src/steps.cc io/src/text_table.cc io/src/input_screening.cc
  models/src/range_bearing_model.cc models/src/motion_model.cc models/src/unicycle_model.cc
  models/src/ackermann_model.cc graph/src/pose2.cc graph/src/check.cc"
sources_dataset_manifest=$sources_dataset
sources_dataset_text=$sources_dataset
absl="-labsl_strings -labsl_strings_internal -labsl_status -labsl_statusor -labsl_raw_hash_set -labsl_hash
  -labsl_city -labsl_low_level_hash -labsl_int128 -labsl_throw_delegate -labsl_raw_logging_internal
  -labsl_str_format_internal -labsl_cord -labsl_cord_internal -labsl_cordz_info -labsl_cordz_functions
  -labsl_cordz_handle -labsl_synchronization -labsl_time -labsl_time_zone -labsl_base -labsl_spinlock_wait
  -labsl_malloc_internal -labsl_stacktrace -labsl_symbolize -labsl_debugging_internal -labsl_demangle_internal"

# The seeds: a 3 s simulated world's graph files and local maps.
world="$out/seed_world"
if [ ! -f "$world/graph.isam" ]; then
  "$tool" simulate --scenario hybrid-120m --duration 3 --out "$world" >/dev/null
  "$tool" run --dataset "$world" --frontend rbpf --submap_max_duration 0.5 --submap_min_duration 0.2 \
    --quiet --progress=false --out "$world/run" >/dev/null
fi
seed_graph_format() {  # the first byte picks the format (0 g2o, 1 toro, 2 isam, 3 gtsam; +4·k the noise)
  seed() { { printf "\\$(printf '%03o' "$2")"; head -n "$4" "$3"; } > "$1/$5"; }
  seed "$1" 0 "$world/graph.g2o" 60 g2o
  seed "$1" 1 "$world/graph.toro" 40 toro
  seed "$1" 2 "$world/graph.isam" 60 isam
  seed "$1" 10 "$world/graph.isam" 30 isam_information
  vp=../shared/data/graphs/victoria_park.txt
  if [ -f "$vp" ]; then
    seed "$1" 3 "$vp" 60 gtsam
    seed "$1" 2 "$vp" 30 gtsam_as_isam
  fi
}
seed_dataset_manifest() {  # the simulated world's manifest; Victoria Park's when ../shared is there
  cp "$world/dataset.json" "$1/simulated"
  vp=../shared/data/victoria_park/dataset.json
  [ -f "$vp" ] && cp "$vp" "$1/victoria_park"
  return 0
}
seed_dataset_text() {  # the first byte picks the file (0 controls … 4 true landmarks; +8 Ackermann)
  seed() { { printf "\\$(printf '%03o' "$2")"; head -n 20 "$3"; } > "$1/$4"; }
  seed "$1" 0 "$world/controls.dat" controls
  seed "$1" 1 "$world/observations.dat" observations
  seed "$1" 3 "$world/truth_poses.dat" truth_poses
  seed "$1" 4 "$world/truth_landmarks.dat" truth_landmarks
  seed "$1" 2 "$world/truth_poses.dat" gps_like
  seed "$1" 8 "$world/controls.dat" controls_ackermann
}
seed_submaps_jsonl() {
  head -n 3 "$world/run/submaps.jsonl" > "$1/maps"
  head -n 1 "$world/run/submaps.jsonl" > "$1/one_map"
}

status=0
for target in $targets; do
  eval "sources=\$sources_$target"
  binary="$out/${target}_fuzzer"
  # shellcheck disable=SC2086
  if [ ! -x "$binary" ] || [ -n "$(find fuzz/${target}_fuzzer.cc fuzz/*.h $sources posegraph/include graph/include io/include models/include \
      -newer "$binary" | head -1)" ]; then
    echo "fuzz.sh: building $binary"
    # shellcheck disable=SC2086
    clang++ -std=c++20 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
      -fno-omit-frame-pointer -I/usr/include/eigen3 -Iposegraph/include -Igraph/include -Iio/include -Iio/src -Imodels/include \
      "fuzz/${target}_fuzzer.cc" $sources -o "$binary" $absl
  fi
  corpus="$out/corpus_$target"
  mkdir -p "$corpus"
  [ -n "$(ls -A "$corpus")" ] || "seed_$target" "$corpus"
  echo "fuzz.sh: $target for $seconds s"
  "$binary" -max_total_time="$seconds" ${FUZZ_RUNS:+-runs="$FUZZ_RUNS"} -max_len=8192 -print_final_stats=1 \
    -artifact_prefix="$out/$target-" "$corpus" || status=1
done
exit $status
