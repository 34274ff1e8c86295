#!/usr/bin/env bash
# Shared set-up for tools/run.sh and tools/test.sh: installs the Debian 12 packages Fulcrum
# needs (only those missing; through sudo when not root), then configures and builds into
# build/. Idempotent: a second run with nothing changed installs nothing and builds nothing.
set -euo pipefail

FULCRUM_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
FULCRUM_BUILD="${FULCRUM_BUILD:-$FULCRUM_ROOT/build}"

FULCRUM_PACKAGES=(
  build-essential cmake ninja-build pkg-config clang clang-format
  libeigen3-dev
  libprotobuf-dev protobuf-compiler libgrpc++-dev protobuf-compiler-grpc libabsl-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libbox2d-dev
  # the Prometheus metrics endpoint's HTTP server (server/src/metrics.cpp)
  libcpp-httplib-dev
  # clang's sanitizer and libFuzzer runtimes (tools/sanitize.sh, tools/fuzz.sh)
  libclang-rt-14-dev
  # the linker of the sanitized builds (CMakeLists.txt)
  lld
  openssl
  # The Python client (client/python) and its tests, for /usr/bin/python3; venv, setuptools
  # and wheel install it into a virtual environment without the network (tests/python).
  python3-grpcio python3-protobuf python3-numpy python3-pytest
  python3-venv python3-setuptools python3-wheel
  # a compiler cache for the builds (fulcrum_launcher below)
  ccache
  # the Kubernetes manifests' check (tests/deploy/check_manifests.py)
  python3-yaml
  # `fulcrum view`'s browser test (tests/cli/view_test.py): headless Chromium, driven over the
  # DevTools protocol from /usr/bin/python3
  chromium python3-websocket
)

fulcrum_install_packages() {
  local missing=()
  for p in "${FULCRUM_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then return 0; fi
  echo "fulcrum: installing missing packages: ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

# The cmake arguments that make a build directory compile through ccache, when it is installed:
# a build of sources compiled before -- by another clone, or into a build directory since
# removed -- then takes the objects from the cache (~/.cache/ccache) instead of compiling them
# again, and the test command's six builds take most of its time. Every configure below passes
# them. Paths below the checkout are hashed relative to it, so clones in other directories share
# entries; the sloppiness lets files that use precompiled headers be cached. FULCRUM_CCACHE=OFF
# does without (for directories configured afresh).
fulcrum_launcher() {
  if [ "${FULCRUM_CCACHE:-ON}" = ON ] && command -v ccache > /dev/null; then
    echo "-DCMAKE_CXX_COMPILER_LAUNCHER=ccache"
  fi
}
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$FULCRUM_ROOT}"
export CCACHE_NOHASHDIR="${CCACHE_NOHASHDIR:-true}"
export CCACHE_SLOPPINESS="${CCACHE_SLOPPINESS:-pch_defines,time_macros,include_file_mtime,include_file_ctime}"

fulcrum_build() {
  if [ ! -f "$FULCRUM_BUILD/build.ninja" ]; then
    cmake -S "$FULCRUM_ROOT" -B "$FULCRUM_BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DFULCRUM_WERROR=ON $(fulcrum_launcher)
  fi
  cmake --build "$FULCRUM_BUILD" -j "$(nproc)"
}

# A clang build at -O1 with assertions on and the sanitizers of $2 (FULCRUM_SANITIZE), in $1;
# further arguments go to cmake. Shared by tools/sanitize.sh and tools/fuzz.sh: build-asan/ is
# one directory for both, with libFuzzer's instrumentation (FULCRUM_FUZZ) on. The project is C++
# only, so no C compiler is named.
fulcrum_configure_sanitized() {
  local dir=$1 sanitize=$2
  shift 2
  cmake -S "$FULCRUM_ROOT" -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Debug \
    "-DCMAKE_CXX_FLAGS_DEBUG=-O1 -gline-tables-only" -DCMAKE_CXX_COMPILER=clang++ \
    -DFULCRUM_BUILD_TESTS=ON -DFULCRUM_BUILD_BENCH=OFF -DFULCRUM_SANITIZE="$sanitize" \
    $(fulcrum_launcher) "$@" > /dev/null
}

# build-asan/ (or $1): ASan+LeakSanitizer+UBSan with libFuzzer's instrumentation, the build of
# tools/sanitize.sh, tools/fuzz.sh and the clang -O1 CLI of tools/determinism.sh.
fulcrum_configure_asan() {
  fulcrum_configure_sanitized "${1:-$FULCRUM_ROOT/build-asan}" address,undefined -DFULCRUM_FUZZ=ON
}

# Every C++ file as clang-format (Debian's 14) would write it, per .clang-format.
fulcrum_check_format() {
  local files
  files=$(cd "$FULCRUM_ROOT" && git ls-files '*.cpp' '*.h' 2>/dev/null ||
    find engine proto scenes client server tests bench tools -name '*.cpp' -o -name '*.h')
  (cd "$FULCRUM_ROOT" && clang-format --dry-run -Werror $files)
}

# Compares fulcrum_golden output GOT with REFERENCE (the native build's) line by line, adding to
# the caller's `passed` and `failed`. For each scenario that differs it says so, prefixed with
# LABEL, and names the first differing tick, running the remaining arguments (a command, or a
# shell function, that prints fulcrum_golden output) with --per-tick NAME against the native
# build. Usage: fulcrum_compare_golden LABEL REFERENCE GOT COMMAND...
fulcrum_compare_golden() {
  local label=$1 reference=$2 got=$3
  shift 3
  local name ticks final combined line first
  while read -r name ticks final combined; do
    line=$(grep "^$name " <<< "$got" || true)
    if [ "$line" = "$name $ticks $final $combined" ]; then
      passed=$((passed + 1))
      continue
    fi
    failed=$((failed + 1))
    echo "$label differs on golden scenario '$name': got '${line:-no line}'," \
      "the native gcc -O2 build gives '$name $ticks $final $combined'"
    first=$(diff <("$FULCRUM_BUILD/bin/fulcrum_golden" --per-tick "$name") \
      <("$@" --per-tick "$name") | grep -m1 '^<' || true)
    [ -z "$first" ] || echo "$label:   first differing tick: $(cut -d' ' -f3 <<< "$first") of $ticks"
  done <<< "$reference"
}
