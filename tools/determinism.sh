#!/usr/bin/env bash
# Determinism across builds: the same scenes, stepped by gcc -O0 and clang -O2 builds of the
# `fulcrum` CLI, must end with the same state hash as the main build (gcc -O2); and the golden
# scenarios (tests/golden: edits between ticks, sleeping, every joint type) must give the main
# build's fulcrum_golden output line for line, i.e. the same hash at every tick; and a bot player
# of each variant follows a multiplayer session on a main-build server for 3000 ticks, checking
# every confirmed tick's hash. Run by tools/test.sh after the test suite; builds land in
# build-det-VARIANT/. A clang -O0 variant ran here until 2026-11-29: with gcc at -O0 and -O2 and
# clang at -O2 it added no compiler and no optimisation level, and cost 8 minutes of CI.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"

SCENES=(
  "--scene $FULCRUM_ROOT/scenes/pyramid.json --ticks 300"
  "--scene $FULCRUM_ROOT/scenes/particles.json --ticks 300"
  "--builtin mixed --ticks 300"
  "--builtin bounce --ticks 300"
  "--builtin overlap_recovery --ticks 200"
  "--builtin tumbler --ticks 60"
  "--builtin rope --ticks 200"
  "--builtin cloth --ticks 120"
)

build_variant() {  # name, then extra cmake arguments
  local dir="$FULCRUM_ROOT/build-det-$1"
  shift
  # Tests on: fulcrum_golden lives in tests/golden (only the two targets below are built). A
  # directory configured before that (tests off) is reconfigured once.
  if [ ! -f "$dir/build.ninja" ] || grep -q '^FULCRUM_BUILD_TESTS:BOOL=OFF' "$dir/CMakeCache.txt"; then
    cmake -S "$FULCRUM_ROOT" -B "$dir" -G Ninja -DFULCRUM_BUILD_TESTS=ON \
      -DFULCRUM_BUILD_BENCH=OFF "$@" > /dev/null
  fi
  local output
  output=$(cmake --build "$dir" -j "$(nproc)" --target fulcrum fulcrum_golden 2>&1) || {
    echo "$output" | tail -40
    echo "determinism: building the $(basename "$dir") variant failed"
    return 1
  }
}

VARIANTS=(gcc-O0 clang-O2)
build_variant gcc-O0 -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_COMPILER=g++
build_variant clang-O2 -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=clang++

# No fused multiply-add in the x86-64 engine either: the 4-lane contact path is built with
# -mavx2 (which allows AVX instructions but not FMA); a flag that enabled FMA would show here.
fused=$(objdump -d "$FULCRUM_BUILD/lib/libfulcrum_engine.a" | grep -cE '\svfn?m(add|sub)' || true)
if [ "$fused" -ne 0 ]; then
  echo "determinism: $fused fused multiply-add instructions in libfulcrum_engine.a"
  exit 1
fi

hash_of() { "$1" sim $2 | awk '/state hash/ {print $3}'; }

failed=0
passed=0
for scene in "${SCENES[@]}"; do
  reference=$(hash_of "$FULCRUM_BUILD/bin/fulcrum" "$scene")
  for variant in "${VARIANTS[@]}"; do
    got=$(hash_of "$FULCRUM_ROOT/build-det-$variant/bin/fulcrum" "$scene")
    if [ "$got" = "$reference" ] && [ -n "$got" ]; then
      passed=$((passed + 1))
    else
      echo "determinism: $variant differs on '$scene': $got, gcc -O2 gives $reference"
      failed=$((failed + 1))
    fi
  done
done

# The golden scenarios: every line (name ticks final_hash combined_hash) must match, for every
# build, every instruction path of the contact solver this CPU runs (scalar, 2 lanes, and 4
# lanes where the CPU has AVX2, and their AVX-512 build where it has that) and 1 to 4 threads:
# all must give the same bits.
golden_reference=$("$FULCRUM_BUILD/bin/fulcrum_golden")
for variant in main "${VARIANTS[@]}"; do
  golden_bin="$FULCRUM_ROOT/build-det-$variant/bin/fulcrum_golden"
  [ "$variant" = main ] && golden_bin="$FULCRUM_BUILD/bin/fulcrum_golden"
  for run in scalar:1 lanes2:1 lanes4:1 avx512:1 avx512:2 auto:2 auto:3 lanes2:4; do
    simd=${run%:*}
    threads=${run#*:}
    status=0
    got=$("$golden_bin" --simd "$simd" --threads "$threads" 2>&1) || status=$?
    if [ "$status" -eq 2 ] && { [ "$simd" = lanes4 ] || [ "$simd" = avx512 ]; }; then
      echo "determinism: $variant: this CPU cannot run the $simd path, it is not compared"
      continue
    fi
    [ "$status" -eq 0 ] || got=""
    fulcrum_compare_golden "determinism: $variant ($simd, $threads threads)" \
      "$golden_reference" "$got" "$golden_bin" --simd "$simd" --threads "$threads"
  done
done
# A multiplayer session across builds: a server of the main build (gcc -O2) and a bot player
# built by each variant, each stepping its own copy of the world with every confirmed tick
# and checking the server's state hash at each (`fulcrum session bot` exits 1 at the first that
# differs). Turn by turn (--seal all-inputs), so every tick waits for every bot's input.
session_ticks=${FULCRUM_DET_SESSION_TICKS:-3000}
server_log=$(mktemp)
"$FULCRUM_BUILD/bin/fulcrum-server" --listen 127.0.0.1:0 > "$server_log" 2>&1 &
server=$!
trap 'kill "$server" 2> /dev/null || true; rm -f "$server_log"' EXIT
address=""
for _ in $(seq 100); do
  address=$(grep -oE 'listening on [0-9.]+:[0-9]+' "$server_log" | awk '{print $3}' || true)
  [ -n "$address" ] && break
  sleep 0.1
done
cli="$FULCRUM_BUILD/bin/fulcrum"
if [ -z "$address" ] ||
  ! "$cli" create --server "$address" --scene "$FULCRUM_ROOT/scenes/pyramid.json" > /dev/null ||
  ! "$cli" session open 1 --server "$address" --players "${#VARIANTS[@]}" --seal all-inputs > /dev/null; then
  cat "$server_log"
  echo "determinism: could not open the session on a main-build server"
  failed=$((failed + 1))
else
  bot_pids=()
  body=210
  for variant in "${VARIANTS[@]}"; do
    "$FULCRUM_ROOT/build-det-$variant/bin/fulcrum" session bot 1 --server "$address" \
      --bodies "$body" --name "$variant" --ticks "$session_ticks" \
      > "$FULCRUM_ROOT/build-det-$variant/session-bot.log" 2>&1 &
    bot_pids+=($!)
    body=$((body - 1))
  done
  for variant in "${VARIANTS[@]}"; do
    if wait "${bot_pids[0]}"; then
      passed=$((passed + 1))
      tail -n 1 "$FULCRUM_ROOT/build-det-$variant/session-bot.log" | sed "s/^/determinism: $variant bot: /"
    else
      tail -n 5 "$FULCRUM_ROOT/build-det-$variant/session-bot.log"
      echo "determinism: the $variant bot lost the gcc -O2 server's hashes"
      failed=$((failed + 1))
    fi
    bot_pids=("${bot_pids[@]:1}")
  done
fi

echo "determinism: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
