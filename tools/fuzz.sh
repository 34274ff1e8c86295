#!/usr/bin/env bash
# Fuzzing with libFuzzer (docs/fuzzing.md).
#   tools/fuzz.sh TARGET SECONDS   fuzz one target (scene_json, scene_proto, edits, snapshot,
#                                  replay, frames, requests, sessions, snapshot_stream) for
#                                  SECONDS
#   tools/fuzz.sh --smoke SECONDS  every target for SECONDS, two at a time (CI)
#   tools/fuzz.sh --list           the targets
# Builds in build-asan/ (clang, ASan + UBSan, libFuzzer's instrumentation; the directory
# tools/sanitize.sh uses), writes fresh seeds to build-asan/fuzz-seeds/, and keeps what each
# target's fuzzing finds in build-asan/fuzz-corpus/TARGET/ between runs. An input that fails
# is saved in build-asan/fuzz-artifacts/TARGET/; the script prints how to re-run it and where a
# finding goes (tests/fuzz/findings/TARGET/, re-run by every ctest).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"

targets=(scene_json scene_proto edits snapshot replay frames requests sessions snapshot_stream)
dir="$FULCRUM_ROOT/build-asan"

usage() {
  sed -n '2,12p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  exit 2
}

[ $# -ge 1 ] || usage
if [ "$1" = "--list" ]; then
  printf '%s\n' "${targets[@]}"
  exit 0
fi
[ $# -eq 2 ] || usage
[[ "$2" =~ ^[0-9]+$ ]] && [ "$2" -gt 0 ] || {
  echo "fuzz: SECONDS must be a whole number > 0 (got '$2')"
  exit 2
}
seconds=$2
if [ "$1" = "--smoke" ]; then
  run=("${targets[@]}")
else
  [[ " ${targets[*]} " == *" $1 "* ]] || {
    echo "fuzz: unknown target '$1' (known: ${targets[*]})"
    exit 2
  }
  run=("$1")
fi

if ! grep -q '^FULCRUM_FUZZ:BOOL=ON' "$dir/CMakeCache.txt" 2>/dev/null; then
  fulcrum_configure_asan "$dir"
fi
build_targets=(fulcrum_fuzz_seeds)
for t in "${run[@]}"; do build_targets+=("fulcrum_fuzz_$t"); done
cmake --build "$dir" -j "$(nproc)" --target "${build_targets[@]}" > "$dir/fuzz-build.log" 2>&1 || {
  tail -40 "$dir/fuzz-build.log"
  echo "fuzz: building the fuzz targets failed"
  exit 1
}
rm -rf "$dir/fuzz-seeds"
"$dir/bin/fulcrum_fuzz_seeds" "$dir/fuzz-seeds" > /dev/null

export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:detect_stack_use_after_return=1:strict_string_checks=1:check_initialization_order=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export LSAN_OPTIONS="suppressions=$FULCRUM_ROOT/tools/lsan.supp:print_suppressions=0"

# One target for $seconds; its log in build-asan/fuzz-logs/TARGET.log. Returns libFuzzer's status.
fuzz_one() {
  local t=$1 corpus="$dir/fuzz-corpus/$1" artifacts="$dir/fuzz-artifacts/$1" inputs=()
  mkdir -p "$corpus" "$artifacts" "$dir/fuzz-logs"
  inputs=("$dir/fuzz-seeds/$t")
  [ -d "$FULCRUM_ROOT/tests/fuzz/findings/$t" ] && inputs+=("$FULCRUM_ROOT/tests/fuzz/findings/$t")
  # The first directory receives the new inputs; the others are only read. -timeout: an input
  # that takes 20 s under ASan is a finding (slow-unit); FULCRUM_FUZZ_TIMEOUT raises it for long
  # runs on a loaded machine. -rss_limit_mb: the same for memory. No -max_len: libFuzzer takes
  # the largest seed's, so no seed is cut short.
  "$dir/bin/fulcrum_fuzz_$t" "$corpus" "${inputs[@]}" -max_total_time="$seconds" \
    -timeout="${FULCRUM_FUZZ_TIMEOUT:-20}" \
    -rss_limit_mb=2560 -artifact_prefix="$artifacts/" -print_final_stats=1 \
    > "$dir/fuzz-logs/$t.log" 2>&1
}

# The run's figures from a log: executions, coverage (edges), features, corpus size.
figures() {
  local log=$1 execs cov corp
  execs=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -oE '[0-9]+$' || echo '?')
  cov=$(grep -oE 'cov: [0-9]+' "$log" | tail -1 | grep -oE '[0-9]+' || echo '?')
  corp=$(grep -oE 'corp: [0-9]+/[0-9]+[a-zA-Z]*' "$log" | tail -1 | cut -d' ' -f2 || echo '?')
  echo "$execs executions, $cov edges covered, corpus $corp"
}

failed=0
pids=()
names=()
wait_one() {  # waits for the oldest running target and reports it
  local t=${names[0]} status=0
  wait "${pids[0]}" || status=$?
  pids=("${pids[@]:1}")
  names=("${names[@]:1}")
  local log="$dir/fuzz-logs/$t.log"
  if [ "$status" -eq 0 ]; then
    echo "fuzz: $t: ${seconds} s, $(figures "$log"), no findings"
  else
    failed=1
    grep -E 'ERROR: |fuzz check failed|SUMMARY:|Test unit written to' "$log" | head -12 || true
    tail -5 "$log"
    echo "fuzz: $t FAILED after $(figures "$log"); log: $log"
    echo "fuzz: re-run the input: $dir/bin/fulcrum_fuzz_$t <the file named above>"
    echo "fuzz: keep it as a regression: copy it to tests/fuzz/findings/$t/ with the fix"
  fi
}

jobs=1
[ ${#run[@]} -gt 1 ] && jobs=$(nproc)
for t in "${run[@]}"; do
  [ ${#pids[@]} -lt "$jobs" ] || wait_one
  fuzz_one "$t" &
  pids+=($!)
  names+=("$t")
done
while [ ${#pids[@]} -gt 0 ]; do wait_one; done
exit "$failed"
