#!/usr/bin/env bash
# Determinism across builds. The golden scenarios (tests/golden: edits between ticks, sleeping,
# every joint type) built by gcc -O0 and clang -O2 must give the main build's (gcc -O2)
# fulcrum_golden output line for line, i.e. the same hash at every tick, on every instruction
# path of the contact solver and 1 to 4 threads. Those two variants are builds of the engine
# alone (tools/engine_only: engine, scene builders, golden scenarios; build-det-VARIANT/).
# The `fulcrum` CLI of a third compilation, the clang -O1 ASan+UBSan build that tools/sanitize.sh
# runs the suite in (build-asan/, built here when missing), must step the scenes below to the
# main build's state hashes, and a bot player of it follows a multiplayer session on a
# main-build server for 3000 ticks, checking every confirmed tick's hash. Run by tools/test.sh
# after the test suite. Until 2026-11-29 both variants built the whole project for their CLI (12
# minutes of CI for the gRPC code, which steps nothing itself), and a clang -O0 variant ran too:
# with gcc at -O0 and -O2 and clang at -O2 it added no compiler and no optimisation level.
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
  # A directory configured from the whole project (before 2026-11-29) is configured afresh.
  if [ ! -f "$dir/build.ninja" ] ||
    ! grep -q '^CMAKE_PROJECT_NAME:.*=fulcrum_engine_only$' "$dir/CMakeCache.txt"; then
    rm -rf "$dir"
    cmake -S "$FULCRUM_ROOT/tools/engine_only" -B "$dir" -G Ninja $(fulcrum_launcher) "$@" > /dev/null
  fi
  local output
  output=$(cmake --build "$dir" -j "$(nproc)" --target fulcrum_golden 2>&1) || {
    echo "$output" | tail -40
    echo "determinism: building the $(basename "$dir") variant failed"
    return 1
  }
}

VARIANTS=(gcc-O0 clang-O2)
build_variant gcc-O0 -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG=-O0 -DCMAKE_CXX_COMPILER=g++
build_variant clang-O2 -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=clang++
# The sanitized build's CLI (the directory and settings of tools/sanitize.sh, so neither script
# builds it twice). Its leaks are sanitize.sh's to report, not this script's.
asan="$FULCRUM_ROOT/build-asan"
[ -f "$asan/build.ninja" ] || fulcrum_configure_asan "$asan"
output=$(cmake --build "$asan" -j "$(nproc)" --target fulcrum 2>&1) || {
  echo "$output" | tail -40
  echo "determinism: building build-asan's fulcrum failed"
  exit 1
}
export ASAN_OPTIONS=detect_leaks=0
asan_cli="$asan/bin/fulcrum"

# No fused multiply-add in the x86-64 engine either. The 4-lane contact path is built with -mavx2
# (AVX without FMA), but its AVX-512 build's -mavx512f also allows FMA instructions, and GCC 12's
# vectorizer has emitted one there (a vfmaddsub for a pair of a * b -/+ c, in a draft of
# integrate_lanes on 2026-12-07) despite -ffp-contract=off: the golden hashes of that path
# changed. This check names such a build before any hash does.
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
  got=$(hash_of "$asan_cli" "$scene")
  if [ "$got" = "$reference" ] && [ -n "$got" ]; then
    passed=$((passed + 1))
  else
    echo "determinism: clang -O1 (build-asan) differs on '$scene': $got, gcc -O2 gives $reference"
    failed=$((failed + 1))
  fi
done

# The golden scenarios: every line (name ticks final_hash combined_hash) must match, for every
# build, every instruction path of the contact solver this CPU runs (scalar, 2 lanes, and 4
# lanes where the CPU has AVX2, and their AVX-512 build where it has that) and 1 to 4 threads:
# all must give the same bits.
golden_reference=$("$FULCRUM_BUILD/bin/fulcrum_golden")
golden_runs=(scalar:1 lanes2:1 lanes4:1 avx512:1 avx512:2 auto:2 auto:3 lanes2:4)
golden_bin() {  # variant
  if [ "$1" = main ]; then echo "$FULCRUM_BUILD/bin/fulcrum_golden"; else
    echo "$FULCRUM_ROOT/build-det-$1/bin/fulcrum_golden"; fi
}
# The runs go $(nproc) at a time (the gcc -O0 build takes 14 s a run here), each into a file
# with its exit status; then they are compared in order.
golden_out=$(mktemp -d)
for variant in main "${VARIANTS[@]}"; do
  for run in "${golden_runs[@]}"; do
    while [ "$(jobs -pr | wc -l)" -ge "$(nproc)" ]; do wait -n || true; done
    status=0
    ("$(golden_bin "$variant")" --simd "${run%:*}" --threads "${run#*:}" \
      > "$golden_out/$variant-$run" 2>&1 || status=$?
    echo "$status" > "$golden_out/$variant-$run.status") &
  done
done
wait
for variant in main "${VARIANTS[@]}"; do
  for run in "${golden_runs[@]}"; do
    simd=${run%:*}
    threads=${run#*:}
    status=$(cat "$golden_out/$variant-$run.status")
    if [ "$status" -eq 2 ] && { [ "$simd" = lanes4 ] || [ "$simd" = avx512 ]; }; then
      echo "determinism: $variant: this CPU cannot run the $simd path, it is not compared"
      continue
    fi
    got=""
    [ "$status" -ne 0 ] || got=$(cat "$golden_out/$variant-$run")
    fulcrum_compare_golden "determinism: $variant ($simd, $threads threads)" \
      "$golden_reference" "$got" "$(golden_bin "$variant")" --simd "$simd" --threads "$threads"
  done
done
rm -rf "$golden_out"

# A multiplayer session across builds: a server of the main build (gcc -O2) and two bot players,
# one of build-asan (clang -O1) and one of the main build, each stepping its own copy of the
# world with every confirmed tick and checking the server's state hash at each (`fulcrum session
# bot` exits 1 at the first that differs). Turn by turn (--seal all-inputs), so every tick waits
# for both bots' inputs.
session_ticks=${FULCRUM_DET_SESSION_TICKS:-3000}
bot_names=(clang-O1 gcc-O2)
bot_clis=("$asan_cli" "$FULCRUM_BUILD/bin/fulcrum")
bot_logs=$(mktemp -d)
server_log=$(mktemp)
"$FULCRUM_BUILD/bin/fulcrum-server" --listen 127.0.0.1:0 > "$server_log" 2>&1 &
server=$!
trap 'kill "$server" 2> /dev/null || true; rm -rf "$server_log" "$bot_logs"' EXIT
address=""
for _ in $(seq 100); do
  address=$(grep -oE 'listening on [0-9.]+:[0-9]+' "$server_log" | awk '{print $3}' || true)
  [ -n "$address" ] && break
  sleep 0.1
done
cli="$FULCRUM_BUILD/bin/fulcrum"
if [ -z "$address" ] ||
  ! "$cli" create --server "$address" --scene "$FULCRUM_ROOT/scenes/pyramid.json" > /dev/null ||
  ! "$cli" session open 1 --server "$address" --players "${#bot_names[@]}" --seal all-inputs > /dev/null; then
  cat "$server_log"
  echo "determinism: could not open the session on a main-build server"
  failed=$((failed + 1))
else
  bot_pids=()
  for i in "${!bot_names[@]}"; do
    "${bot_clis[$i]}" session bot 1 --server "$address" --bodies "$((210 - i))" \
      --name "${bot_names[$i]}" --ticks "$session_ticks" > "$bot_logs/${bot_names[$i]}" 2>&1 &
    bot_pids+=($!)
  done
  for i in "${!bot_names[@]}"; do
    log="$bot_logs/${bot_names[$i]}"
    if wait "${bot_pids[$i]}"; then
      passed=$((passed + 1))
      tail -n 1 "$log" | sed "s/^/determinism: ${bot_names[$i]} bot: /"
    else
      tail -n 5 "$log"
      echo "determinism: the ${bot_names[$i]} bot lost the gcc -O2 server's hashes"
      failed=$((failed + 1))
    fi
  done
fi

echo "determinism: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
