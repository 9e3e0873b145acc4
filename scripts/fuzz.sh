#!/bin/sh
# Fuzzes the graph-file readers with libFuzzer under AddressSanitizer + UBSan.
#
#   scripts/fuzz.sh [SECONDS] [extra libFuzzer flags…]    (default 30 s)
#
# Builds fuzz/graph_format_fuzzer.cc with clang (Debian's clang-14 and its libFuzzer)
# into build-fuzz/, seeds a corpus from the test data (a short simulated world's graph in
# every format, and the Victoria Park graph's first lines when ../shared is there), and
# runs the target for SECONDS. A crash leaves its input in build-fuzz/ (crash-*) and fails
# the script; each one found becomes a case of tests/posegraph/graph_format_test.cc.
set -eu
cd "$(dirname "$0")/.."
seconds=${1:-30}
[ $# -gt 0 ] && shift
out=build-fuzz
mkdir -p "$out"
command -v clang++ >/dev/null || { echo "fuzz.sh: clang++ is missing (apt-get install clang)" >&2; exit 1; }

sources="fuzz/graph_format_fuzzer.cc posegraph/src/graph_format.cc posegraph/src/graph_text.cc
  posegraph/src/g2o_format.cc posegraph/src/toro_format.cc posegraph/src/isam_format.cc
  posegraph/src/pose_graph.cc posegraph/src/measurement_residuals.cc graph/src/pose2.cc io/src/text_table.cc"
if [ ! -x "$out/graph_format_fuzzer" ] || [ -n "$(find $sources posegraph/include graph/include -newer "$out/graph_format_fuzzer" | head -1)" ]; then
  echo "fuzz.sh: building $out/graph_format_fuzzer"
  # shellcheck disable=SC2086
  clang++ -std=c++20 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
    -fno-omit-frame-pointer -I/usr/include/eigen3 -Iposegraph/include -Igraph/include -Iio/include \
    $sources -o "$out/graph_format_fuzzer" \
    -labsl_strings -labsl_strings_internal -labsl_status -labsl_statusor -labsl_raw_hash_set -labsl_hash \
    -labsl_city -labsl_low_level_hash -labsl_int128 -labsl_throw_delegate -labsl_raw_logging_internal \
    -labsl_str_format_internal -labsl_cord -labsl_cord_internal -labsl_cordz_info -labsl_cordz_functions \
    -labsl_cordz_handle -labsl_synchronization -labsl_time -labsl_time_zone -labsl_base -labsl_spinlock_wait \
    -labsl_malloc_internal -labsl_stacktrace -labsl_symbolize -labsl_debugging_internal -labsl_demangle_internal
fi

# The seed corpus: the first byte picks the format (0 g2o, 1 toro, 2 isam, 3 gtsam; +4·k
# the noise convention), the rest is a graph file's beginning.
corpus="$out/corpus"
mkdir -p "$corpus"
if [ -z "$(ls -A "$corpus")" ]; then
  tool=build/apps/subslam
  [ -x "$tool" ] || { echo "fuzz.sh: build the tool first (scripts/setup.sh) to seed the corpus" >&2; exit 1; }
  world="$out/seed_world"
  "$tool" simulate --scenario hybrid-120m --duration 3 --out "$world" >/dev/null
  seed() {  # seed NAME FORMAT_BYTE FILE LINES
    { printf "\\$(printf '%03o' "$2")"; head -n "$4" "$3"; } > "$corpus/$1"
  }
  seed g2o 0 "$world/graph.g2o" 60
  seed toro 1 "$world/graph.toro" 40
  seed isam 2 "$world/graph.isam" 60
  seed isam_information 10 "$world/graph.isam" 30
  vp=../shared/data/graphs/victoria_park.txt
  if [ -f "$vp" ]; then
    seed gtsam 3 "$vp" 60
    seed gtsam_as_isam 2 "$vp" 30
  fi
fi
"$out/graph_format_fuzzer" -max_total_time="$seconds" -max_len=4096 -print_final_stats=1 \
  -artifact_prefix="$out/" "$@" "$corpus"
