#!/usr/bin/env bash
# Sanitizer runs, after the test suite (tools/test.sh):
#   1. build-asan/: clang with AddressSanitizer, LeakSanitizer and UndefinedBehaviorSanitizer,
#      every target but the benchmarks; every ctest entry runs but five long physics runs (see
#      below), the scripts that drive the built fulcrum and fulcrum-server binaries (cli.*,
#      server.*, python.*) included. Then every fuzz target (tests/fuzz/, built here with
#      libFuzzer) fuzzes for 20 s (tools/fuzz.sh --smoke).
#   2. build-tsan/: clang with ThreadSanitizer; the tests of Fulcrum's threaded code that does not
#      go through gRPC (see below).
# Both are -O1 with assertions on (a Debug build whose -O0 is replaced) and -fno-sanitize-recover,
# through the FULCRUM_SANITIZE option (CMakeLists.txt), which leaves the engine's determinism
# flags alone: the golden hash tests run under ASan/UBSan too. The first report stops the
# process; every report is also written to build-*/sanitizer-logs/ (so that a report from a
# process whose failure a test expects, or whose output it keeps to itself, is not lost), and
# any file there fails this script. Run locally: bash tools/sanitize.sh (docs/robustness.md).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"

build() {  # directory, then targets (none: all)
  local dir=$1 output targets=()
  shift
  [ $# -eq 0 ] || targets=(--target "$@")
  output=$(cmake --build "$dir" -j "$(nproc)" "${targets[@]}" 2>&1) || {
    echo "$output" | tail -40
    echo "sanitize: building $(basename "$dir") failed"
    return 1
  }
}

# Runs ctest in a directory (remaining arguments go to ctest); sets `entries` to the number of
# entries run and returns non-zero when an entry failed or a sanitizer wrote a report.
run_ctest() {
  local dir=$1 status=0 reports
  shift
  rm -rf "$dir/sanitizer-logs"
  mkdir -p "$dir/sanitizer-logs"
  (cd "$dir" && ctest --output-on-failure -j "$(nproc)" --timeout 900 "$@") 2>&1 |
    tee "$dir/ctest.log" || status=$?
  entries=$(grep -oE 'tests failed out of [0-9]+' "$dir/ctest.log" | grep -oE '[0-9]+$' || echo 0)
  reports=$(find "$dir/sanitizer-logs" -type f | sort)
  if [ -n "$reports" ]; then
    for f in $reports; do
      echo "sanitize: report in $f:"
      cat "$f"
    done
    status=1
  fi
  return "$status"
}

failed=0
summary=()

# --- 1. AddressSanitizer + LeakSanitizer + UndefinedBehaviorSanitizer: every ctest entry --------
start=$SECONDS
asan="$FULCRUM_ROOT/build-asan"
fulcrum_configure_asan "$asan"
build "$asan"
built=$((SECONDS - start))
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:detect_stack_use_after_return=1:strict_string_checks=1:check_initialization_order=1:log_path=$asan/sanitizer-logs/asan"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:log_path=$asan/sanitizer-logs/ubsan"
export LSAN_OPTIONS="suppressions=$FULCRUM_ROOT/tools/lsan.supp:print_suppressions=0"
entries=0
# The relay test plays 300 ticks here instead of 1800, and each random-worlds shard 100 worlds
# instead of 250: the same checks on less data. Left out: the five tests that step one large
# scene for hundreds of ticks to judge its physics (1 to 2.5 minutes each here, a fifth of the
# run); the main build runs them, and the solver loops they go through run here in the golden,
# snapshot, lane and random-world tests.
long_physics='^(JointCases\.Case09JointGrid|JointCases\.Case18Tumbler|HardCases\.Case02LargePyramid|HardCases\.Case03ManyPyramids|V3Scenes\.SpinnerTurnsAtItsMotorSpeed)$'
FULCRUM_RELAY_TICKS=300 FULCRUM_RANDOM_WORLDS=100 run_ctest "$asan" -E "$long_physics" || failed=1
summary+=("ASan+UBSan: $entries ctest entries, build ${built} s, run $((SECONDS - start - built)) s")
unset ASAN_OPTIONS UBSAN_OPTIONS LSAN_OPTIONS

# --- 1b. A fuzzing smoke: every fuzz target for a few seconds, in the same build ---------------
# (ctest above already ran each target once over its seeds and kept findings.) Longer runs are
# by hand: tools/fuzz.sh TARGET SECONDS (docs/fuzzing.md).
start=$SECONDS
smoke=${FULCRUM_FUZZ_SMOKE_SECONDS:-20}
bash "$FULCRUM_ROOT/tools/fuzz.sh" --smoke "$smoke" || failed=1
fuzz_targets=$(bash "$FULCRUM_ROOT/tools/fuzz.sh" --list | wc -l)
summary+=("fuzz smoke: $fuzz_targets targets, ${smoke} s each, two at a time: $((SECONDS - start)) s")

# --- 2. ThreadSanitizer: Fulcrum's own threads, without gRPC ---------------------------------
# The engine's worker pool and multi-threaded step (and the 2000 random worlds, a fifth of which
# step on two threads), and the server's sessions, real-time pool and frames driven from many
# threads (session_test). Not the tests through gRPC (server_test,
# realtime_test, fault_test, cli, python): Debian's gRPC is not built with TSan, so TSan does not
# see the locks and atomics with which gRPC hands a call from one of its threads to another, and
# reports races on everything handed over, Fulcrum's objects included (hundreds per run; details
# in docs/robustness.md). Suppressing those would hide Fulcrum's own races in the same code.
start=$SECONDS
tsan="$FULCRUM_ROOT/build-tsan"
fulcrum_configure_sanitized "$tsan" thread
build "$tsan" session_test frames_test worker_pool_test contact_lanes_test joint_lanes_test \
  random_worlds_test
built=$((SECONDS - start))
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:log_path=$tsan/sanitizer-logs/tsan"
entries=0
run_ctest "$tsan" -R \
  '^(SessionThreads|Frames|QuantizedFrames|SharedEncoding|WorkerPool|ContactLanes|JointLanes)\.|^Shards/RandomWorlds\.' ||
  failed=1
summary+=("TSan: $entries ctest entries, build ${built} s, run $((SECONDS - start - built)) s")
unset TSAN_OPTIONS

for line in "${summary[@]}"; do echo "sanitize: $line"; done
if [ "$failed" -ne 0 ]; then
  echo "sanitize: FAILED (see the reports and failed entries above)"
  exit 1
fi
echo "sanitize: OK"
