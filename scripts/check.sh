#!/usr/bin/env bash
# The checks to run before submitting a change to threaded or memory-heavy code:
#
#   scripts/check.sh [rules] [asan] [tsan] [fuzz]   (default: all four, in that order)
#   scripts/check.sh ci                             (the subset CI runs, a few minutes)
#
#   rules the rules that can be counted: every tracked .cc and .h formatted as
#         .clang-format says (clang-format --dry-run --Werror), and scripts/house_rules.py
#         (file and function length, module boundaries, document length);
#   asan  the whole test suite under AddressSanitizer + UndefinedBehaviorSanitizer
#         (RelWithDebInfo in build-asan/);
#   tsan  the test programs with threads — frontend_test (the particle update on oneTBB),
#         pipeline_test (background joins, every submap run) and study_test (the study
#         runner's workers) — under ThreadSanitizer (build-tsan/);
#   fuzz  every reader's fuzz target for FUZZ_SECONDS (default 30) each (scripts/fuzz.sh);
#   ci    the rules, then a subset that fits CI's time: io_test (every data-set and local-map reader on
#         malformed input) under ASan + UBSan, and the particle filter's threaded tests
#         (WorkerPool, FastSlam's thread-count tests, KnownAssociation on two threads)
#         under TSan. The whole sanitizer steps run for the better part of an hour.
#
# A sanitizer report fails the test that caused it, and that fails the script. One
# statistical test is left out of the sanitizer builds (NEAR_BOUND below): its particle
# draws depend on the build's floating-point arithmetic, and its count sits within a few
# maps of its binomial bound (tests/pipeline/local_maps_test.cc), so another build's
# arithmetic is another trial; the Release suite runs it. Under TSan one more test is
# left out (BITWISE below): it compares a study's in-process runs with the tool's runs of
# the same commands to the bit, and the TSan-built test program and tool round
# differently (no race is reported; the particle methods then drift apart). TSan
# ignores races inside libgomp, whose OpenMP threads (CHOLMOD's, in the SEIF tests) it
# cannot see synchronise: scripts/tsan.supp. Environment: JOBS (default nproc).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
JOBS="${JOBS:-$(nproc)}"
steps=("$@")
NEAR_BOUND=RbpfLocalMaps.Hybrid120mJointNeesIsConsistentAtTheDefaultParticleCount
BITWISE=HybridSlamStudy.EachMethodIsItsRecordedCommand
((${#steps[@]})) || steps=(rules asan tsan fuzz)

build() {  # build DIR SANITIZER [TARGET…]
  local dir=$1 sanitizer=$2
  shift 2
  if [[ ! -f "$dir/CMakeCache.txt" ]]; then
    cmake -S "$ROOT" -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSUBSLAM_SANITIZE="$sanitizer" \
      -DSUBSLAM_BUILD_BENCHMARKS=OFF -DSUBSLAM_BUILD_EXAMPLES=OFF >/dev/null
  fi
  if (($#)); then
    cmake --build "$dir" -j "$JOBS" --target "$@"
  else
    cmake --build "$dir" -j "$JOBS"
  fi
}
tsan_run() {  # tsan_run TEST [GTEST_FILTER]
  echo "check.sh: $1 under ThreadSanitizer"
  (cd "$ROOT/build-tsan/tests" &&
    TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 suppressions=$ROOT/scripts/tsan.supp" \
    ./"$1" --gtest_brief=1 --gtest_filter="${2:--$NEAR_BOUND:$BITWISE}")
}

rules() {
  echo "check.sh: format (.clang-format) and house rules"
  (cd "$ROOT" && git ls-files -z '*.cc' '*.h' | xargs -0 clang-format --dry-run --Werror)
  /usr/bin/python3 "$ROOT/scripts/house_rules.py" --self-test
  /usr/bin/python3 "$ROOT/scripts/house_rules.py" "$ROOT"
}

for step in "${steps[@]}"; do
  start=$SECONDS
  case "$step" in
    rules)
      rules
      ;;
    asan)
      build "$ROOT/build-asan" address
      ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
        ctest --test-dir "$ROOT/build-asan" --output-on-failure -j "$JOBS" -E "^$NEAR_BOUND\$"
      ;;
    tsan)
      build "$ROOT/build-tsan" thread
      for t in frontend_test pipeline_test study_test; do tsan_run "$t"; done
      ;;
    ci)
      rules
      build "$ROOT/build-asan" address io_test
      (cd "$ROOT/build-asan/tests" && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 ./io_test --gtest_brief=1)
      build "$ROOT/build-tsan" thread frontend_test
      tsan_run frontend_test "WorkerPool.*:FastSlam.*Thread*:KnownAssociation.*"
      ;;
    fuzz)
      [[ -x "$ROOT/build/apps/subslam" ]] || "$ROOT/scripts/setup.sh"  # it writes the seeds
      "$ROOT/scripts/fuzz.sh" "${FUZZ_SECONDS:-30}"
      ;;
    *)
      echo "check.sh: unknown step '$step' (rules, asan, tsan, fuzz or ci)" >&2
      exit 2
      ;;
  esac
  echo "check.sh: $step clean in $((SECONDS - start)) s"
done
