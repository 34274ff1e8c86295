#!/usr/bin/env bash
# Determinism across CPUs: builds the golden scenarios (tests/golden) for aarch64 with Debian's
# cross compiler, runs them under qemu-user and compares every line of their output with the
# native build's fulcrum_golden. Prints PASS or FAIL and exits non-zero on FAIL.
#
# Installs g++-aarch64-linux-gnu and qemu-user when missing (through sudo when not root). The
# cross build (only engine/, scenes/ and tests/golden/, through tools/engine_only/CMakeLists.txt: no
# protobuf or gRPC, which cannot be installed for a foreign architecture) lands in
# build-cross-aarch64/; the native reference is $FULCRUM_BUILD/bin/fulcrum_golden (build/ by
# default), built here when missing or out of date. FULCRUM_JOBS sets the build parallelism.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"

CROSS_BUILD="${FULCRUM_CROSS_BUILD:-$FULCRUM_ROOT/build-cross-aarch64}"
JOBS="${FULCRUM_JOBS:-$(nproc)}"
SYSROOT=/usr/aarch64-linux-gnu
started=$SECONDS

fail() {
  echo "cross-aarch64: FAIL: $*"
  exit 1
}

# Runs a command silently; on failure shows its output and fails.
quiet() {
  local output
  output=$("$@" 2>&1) || {
    echo "$output" | tail -40
    fail "command failed: $*"
  }
}

# --- Packages: the native ones (for the reference build), then the cross ones ----------------
fulcrum_install_packages
FULCRUM_PACKAGES=(g++-aarch64-linux-gnu qemu-user)
fulcrum_install_packages
installed=$SECONDS

# --- Native reference ------------------------------------------------------------------------
if [ ! -f "$FULCRUM_BUILD/build.ninja" ]; then
  quiet cmake -S "$FULCRUM_ROOT" -B "$FULCRUM_BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DFULCRUM_WERROR=ON $(fulcrum_launcher)
fi
quiet cmake --build "$FULCRUM_BUILD" -j "$JOBS" --target fulcrum_golden

# --- Cross build -----------------------------------------------------------------------------
if [ ! -f "$CROSS_BUILD/build.ninja" ]; then
  quiet cmake -S "$FULCRUM_ROOT/tools/engine_only" -B "$CROSS_BUILD" -G Ninja \
    -DCMAKE_BUILD_TYPE=Release -DFULCRUM_WERROR=ON \
    -DCMAKE_TOOLCHAIN_FILE="$FULCRUM_ROOT/tools/toolchain-aarch64.cmake" $(fulcrum_launcher)
fi
quiet cmake --build "$CROSS_BUILD" -j "$JOBS" --target fulcrum_golden
built=$SECONDS

# The determinism flags must reach every translation unit (they are PUBLIC on fulcrum_engine),
# and no fused multiply-add may be left in the code: aarch64 gcc contracts a * b + c into one
# fmadd (rounded once instead of twice) by default, even with -std=c++20.
commands="$CROSS_BUILD/compile_commands.json"
compiled=$(grep -c '"command"' "$commands")
without=$(grep '"command"' "$commands" | grep -vc -- '-ffp-contract=off' || true)
[ "$compiled" -gt 0 ] && [ "$without" -eq 0 ] ||
  fail "$without of $compiled translation units compiled without -ffp-contract=off"
# One object is exempt: reference.cpp, the reference solver (a ruler for the sweep, never run by
# World::step), whose Eigen sparse kernels call NEON's fused multiply-add intrinsics on aarch64
# whatever the flag says. Its results are bit-identical run to run on one build, not across
# architectures; docs/accuracy.md says so.
fused=$(aarch64-linux-gnu-objdump -d "$CROSS_BUILD"/lib/*.a "$CROSS_BUILD/bin/fulcrum_golden" |
  awk '/file format/ { member = $1 }
       member != "reference.cpp.o:" && /\t(fmadd|fmsub|fnmadd|fnmsub|fmla|fmls)\t/ { n++ }
       END { print n + 0 }')
[ "$fused" -eq 0 ] || fail "$fused fused multiply-add instructions in the aarch64 code"
echo "cross-aarch64: all $compiled translation units built with -ffp-contract=off;" \
  "no fused multiply-add instructions outside the reference solver"

# --- Run and compare -------------------------------------------------------------------------
native_bin="$FULCRUM_BUILD/bin/fulcrum_golden"
cross_bin="$CROSS_BUILD/bin/fulcrum_golden"
cross_run() { qemu-aarch64 -L "$SYSROOT" "$cross_bin" "$@"; }
reference=$("$native_bin")

failed=0
passed=0
# Every instruction path of the contact solver: scalar, NEON's 2 lanes, and the 4-lane code
# built for the baseline (each 4-lane operation split in two).
for simd in scalar lanes2 lanes4; do
  threads=1
  [ "$simd" = lanes2 ] && threads=3  # NEON, with the step shared among three threads
  got=$(cross_run --simd "$simd" --threads "$threads") || fail "fulcrum_golden --simd $simd exited with an error under qemu-aarch64"
  fulcrum_compare_golden "cross-aarch64 ($simd, $threads threads)" "$reference" "$got" \
    cross_run --simd "$simd" --threads "$threads"
  [ "$(wc -l <<< "$got")" -eq "$(wc -l <<< "$reference")" ] || {
    failed=$((failed + 1))
    echo "cross-aarch64: aarch64 ($simd) printed $(wc -l <<< "$got") lines, x86-64 $(wc -l <<< "$reference")"
  }
done
ran=$SECONDS

echo "cross-aarch64: $passed scenarios identical, $failed differ (install $((installed - started)) s," \
  "build $((built - installed)) s, run $((ran - built)) s)"
[ "$failed" -eq 0 ] || fail "aarch64 and x86-64 differ"
echo "cross-aarch64: PASS"
