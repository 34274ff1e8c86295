#!/usr/bin/env bash
# Determinism across builds: the same scenes, stepped by a gcc -O0 build and a clang -O2 build of
# the `fulcrum` CLI, must end with the same state hash as the main build (gcc -O2). Run by
# tools/test.sh after the test suite; builds land in build-det-gcc-O0/ and build-det-clang-O2/.
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
  if [ ! -f "$dir/build.ninja" ]; then
    cmake -S "$FULCRUM_ROOT" -B "$dir" -G Ninja -DFULCRUM_BUILD_TESTS=OFF \
      -DFULCRUM_BUILD_BENCH=OFF "$@" > /dev/null
  fi
  cmake --build "$dir" -j "$(nproc)" --target fulcrum > /dev/null
}

build_variant gcc-O0 -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_COMPILER=g++
build_variant clang-O2 -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=clang++

hash_of() { "$1" sim $2 | awk '/state hash/ {print $3}'; }

failed=0
passed=0
for scene in "${SCENES[@]}"; do
  reference=$(hash_of "$FULCRUM_BUILD/bin/fulcrum" "$scene")
  for variant in gcc-O0 clang-O2; do
    got=$(hash_of "$FULCRUM_ROOT/build-det-$variant/bin/fulcrum" "$scene")
    if [ "$got" = "$reference" ] && [ -n "$got" ]; then
      passed=$((passed + 1))
    else
      echo "determinism: $variant differs on '$scene': $got, gcc -O2 gives $reference"
      failed=$((failed + 1))
    fi
  done
done
echo "determinism: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
