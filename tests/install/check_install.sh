#!/usr/bin/env bash
# Fulcrum as a library (docs/library.md), from an installed copy only: `cmake --install` of this
# build into an empty prefix, then
#   1. the example project (example/) configured with find_package(Fulcrum) against that prefix
#      and built; its compile lines carry the engine's determinism flags;
#   2. with pkg-config and nothing else: falling_body.cpp (`pkg-config --cflags --libs
#      fulcrum-engine`, whose Cflags carry the same flags) and the example's lockstep.cpp
#      (fulcrum-client and fulcrum-convert);
#   3. the programs run: scene_hash (the scene loader and the engine) prints the state hash the
#      in-tree `fulcrum sim` prints for the same scene and ticks, bit for bit; both lockstep
#      builds step the scene on the installed fulcrum-server and locally, and the hashes agree;
#      falling_body's ball, dropped from 10 m, is at 5 m after one second within 0.1 m
#      (symplectic Euler at 60 Hz drops it g dt t / 2 = 0.083 m further than the exact parabola,
#      substeps less).
# The compiler, generator and flags come from the environment (CXX, CMAKE_GENERATOR, CXXFLAGS,
# CMAKE_CXX_COMPILER_LAUNCHER: tests/CMakeLists.txt sets them to this build's), so that a
# sanitized build's libraries are linked into sanitized programs.
# usage: check_install.sh BUILD_DIR SOURCE_DIR WORK_DIR FULCRUM_CLI
set -euo pipefail
BUILD="$1"
SOURCE="$2"
WORK="$3"
CLI="$4"
HERE="$SOURCE/tests/install"
PREFIX="$WORK/prefix"
SCENE=pyramid.json
TICKS=90
PID=""
trap 'if [ -n "$PID" ]; then kill -TERM "$PID" 2>/dev/null || true; fi' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
# Runs a command with its output in $WORK/NAME.log, shown only when it fails.
logged() {
  local name="$1"
  shift
  "$@" >"$WORK/$name.log" 2>&1 || { cat "$WORK/$name.log" >&2; fail "$name: $*"; }
}
rm -rf "$WORK"
mkdir -p "$WORK"

logged install cmake --install "$BUILD" --prefix "$PREFIX"
for f in bin/fulcrum bin/fulcrum-server include/fulcrum/world.h include/fulcrum/client.h \
  include/fulcrum/scenes.h include/fulcrum/convert/scene_convert.h \
  include/fulcrum/v1/scene.pb.h "share/fulcrum/scenes/$SCENE"; do
  [ -e "$PREFIX/$f" ] || fail "not installed: $f"
done
# Programs and libraries only: a header may be named for what it tests (fulcrum/sync_test.h).
stray="$(cd "$PREFIX" && find . -not -path './include/*' \( -name '*_test*' -o -name '*fuzz*' \
  -o -name '*bench*' \))"
[ -z "$stray" ] || fail "tests, fuzz targets or benchmarks installed: $stray"
config="$(find "$PREFIX" -name FulcrumConfig.cmake)"
[ -n "$config" ] || fail "no FulcrumConfig.cmake under $PREFIX"

# --- 1. find_package(Fulcrum) ------------------------------------------------------------------
example="$WORK/example"
logged configure cmake -S "$HERE/example" -B "$example" -DCMAKE_PREFIX_PATH="$PREFIX" \
  -DCMAKE_EXPORT_COMPILE_COMMANDS=ON
found="$(sed -n 's/^Fulcrum_DIR:PATH=//p' "$example/CMakeCache.txt")"
[ "$found" = "$(dirname "$config")" ] || fail "find_package(Fulcrum) found '$found', not $PREFIX"
logged build cmake --build "$example" -j 2
for flag in -ffp-contract=off -fno-fast-math -DEIGEN_DONT_PARALLELIZE; do
  for src in scene_hash.cpp lockstep.cpp; do
    grep "$src" "$example/compile_commands.json" | grep -q -e "$flag" ||
      fail "$src is compiled without $flag"
  done
done

# --- 2. pkg-config -----------------------------------------------------------------------------
PKG_CONFIG_PATH="$(dirname "$(find "$PREFIX" -name fulcrum-engine.pc)")"
export PKG_CONFIG_PATH
for pc in fulcrum-engine fulcrum-scenes fulcrum-proto fulcrum-convert fulcrum-client; do
  logged "pkg-config-$pc" pkg-config --print-errors --cflags --libs "$pc"
done
cflags="$(pkg-config --cflags fulcrum-engine)"
for flag in -ffp-contract=off -fno-fast-math -DEIGEN_DONT_PARALLELIZE "-I$PREFIX/"; do
  [[ " $cflags" == *" $flag"* ]] || fail "pkg-config --cflags fulcrum-engine lacks $flag: $cflags"
done
compile() {  # compile NAME SOURCE PACKAGES...: $WORK/NAME from SOURCE with pkg-config's flags
  local name="$1" source="$2"
  shift 2
  # shellcheck disable=SC2046,SC2086  # the launcher and the flags are words
  logged "$name" ${CMAKE_CXX_COMPILER_LAUNCHER:-} ${CXX:-c++} -std=c++20 ${CXXFLAGS:-} \
    "$source" -o "$WORK/$name" $(pkg-config --cflags --libs "$@")
}
compile falling_body "$HERE/falling_body.cpp" fulcrum-engine
compile lockstep_pc "$HERE/example/lockstep.cpp" fulcrum-client fulcrum-convert

# --- 3. The programs ---------------------------------------------------------------------------
installed_scene="$PREFIX/share/fulcrum/scenes/$SCENE"
want="$("$CLI" sim --scene "$SOURCE/scenes/$SCENE" --ticks "$TICKS" </dev/null |
  sed -n 's/^state hash: *//p')"
got="$("$example/scene_hash" "$installed_scene" "$TICKS" </dev/null |
  sed -n 's/^state hash: *//p')"
echo "scene_hash: $SCENE after $TICKS ticks: $got (in-tree fulcrum sim: $want)"
if [ -z "$want" ] || [ "$got" != "$want" ]; then
  fail "scene_hash printed '$got', fulcrum sim '$want'"
fi

: >"$WORK/server.out"
"$PREFIX/bin/fulcrum-server" --listen 127.0.0.1:0 </dev/null >"$WORK/server.out" \
  2>"$WORK/server.err" &
PID=$!
address=""
for _ in $(seq 1 100); do
  address="$(sed -n 's/^listening on //p' "$WORK/server.out")"
  [ -n "$address" ] && break
  sleep 0.1
done
if [ -z "$address" ]; then
  cat "$WORK/server.err" >&2
  fail "installed fulcrum-server: no 'listening on' line"
fi
for program in "$example/lockstep" "$WORK/lockstep_pc"; do
  echo "$(basename "$program"):"
  "$program" "$address" "$installed_scene" "$TICKS" </dev/null ||
    fail "$program: the server's and the local state differ (or a call failed)"
done
kill -TERM "$PID"
rc=0
wait "$PID" || rc=$?
PID=""
[ "$rc" -eq 0 ] || fail "installed fulcrum-server exited with $rc after SIGTERM"

height="$("$WORK/falling_body" </dev/null | sed -n 's/^height: //p')"
echo "falling_body: height after 1 s from 10 m: $height m"
awk -v h="$height" 'BEGIN { exit !(h != "" && h > 4.9 && h < 5.1) }' ||
  fail "falling_body: height '$height' m, expected 5 m within 0.1 m"
echo "OK"
