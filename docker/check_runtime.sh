#!/usr/bin/env bash
# What can be checked of docker/Dockerfile's runtime stage without a Docker daemon, against the
# binaries built in BIN_DIR:
#   1. every shared library fulcrum-server and fulcrum load belongs to a Debian package listed
#      in docker/runtime-packages.txt (ldd, then dpkg -S), which the runtime stage installs;
#   2. the runtime stage installs that list, runs as a non-root user, and copies both binaries;
#   3. the ENTRYPOINT, as written, starts the server (its flags parse; the address is moved to
#      127.0.0.1:0 for the test), the HEALTHCHECK command, as written, reports SERVING against
#      it, and SIGTERM (the STOPSIGNAL) stops it with exit code 0.
# Not checked: that the image builds (no daemon), that debian:12-slim still provides what apt
# needs, and anything about the network inside a container.
# usage: check_runtime.sh BIN_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
DOCKERFILE="$HERE/Dockerfile"
fail() { echo "FAIL: $*" >&2; exit 1; }

mapfile -t listed < <(grep -v '^#' "$HERE/runtime-packages.txt" | grep -v '^$')
mapfile -t libs < <(for b in fulcrum-server fulcrum; do ldd "$BIN/$b" | awk '/=>/ { print $3 }'; done |
  sort -u)
# One dpkg -S for all: Debian 12 is merged-/usr, so a library may be registered under /lib or
# /usr/lib; each is asked under both names and its real path.
candidates=()
for lib in "${libs[@]}"; do
  candidates+=("$lib" "$(realpath "$lib")" "${lib#/usr}" "/usr${lib#/usr}")
done
owners=$(dpkg -S "${candidates[@]}" 2>/dev/null || true)
for lib in "${libs[@]}"; do
  pkg=""
  for path in "$lib" "$(realpath "$lib")" "${lib#/usr}" "/usr${lib#/usr}"; do
    # A here-string, not a pipe: awk's early exit would give echo SIGPIPE, and with pipefail
    # and set -e that ended the script silently about one run in ten.
    pkg=$(awk -v p="$path" '$2 == p { sub(/:.*/, "", $1); print $1; exit }' <<<"$owners")
    [ -n "$pkg" ] && break
  done
  [ -n "$pkg" ] || fail "$lib (loaded by fulcrum-server or fulcrum) is in no Debian package"
  [[ " ${listed[*]} " == *" $pkg "* ]] ||
    fail "$lib comes from $pkg, which docker/runtime-packages.txt does not list"
done
libraries=${#libs[@]}

grep -q 'runtime-packages.txt' "$DOCKERFILE" || fail "the Dockerfile does not install the list"
grep -qE '^USER [1-9][0-9]*' "$DOCKERFILE" || fail "the runtime stage does not run as non-root"
grep -qE '^COPY --from=build .*/fulcrum-server .*/fulcrum ' "$DOCKERFILE" ||
  fail "the runtime stage does not copy both binaries"

# The JSON arrays of ENTRYPOINT and of the HEALTHCHECK's CMD, as words.
json_words() { python3 -c 'import json,sys; print("\n".join(json.loads(sys.argv[1])))' "$1"; }
entry=$(grep -E '^ENTRYPOINT \[' "$DOCKERFILE" | sed 's/^ENTRYPOINT //')
health=$(grep -E '^ +CMD \["fulcrum", "health"' "$DOCKERFILE" | sed 's/^ *CMD //')
[ -n "$entry" ] && [ -n "$health" ] || fail "no ENTRYPOINT or HEALTHCHECK CMD in exec form"
mapfile -t entry_words < <(json_words "$entry")
mapfile -t health_words < <(json_words "$health")
entry_words=("${entry_words[@]/0.0.0.0:50051/127.0.0.1:0}")
WORK=$(mktemp -d)
trap 'kill "$pid" 2>/dev/null || true; rm -rf "$WORK"' EXIT
PATH="$BIN:$PATH" "${entry_words[@]}" >"$WORK/out" 2>"$WORK/err" &
pid=$!
for _ in $(seq 100); do
  grep -q "^listening on" "$WORK/out" && break
  kill -0 "$pid" 2>/dev/null || fail "the entry point exited: $(cat "$WORK/err")"
  sleep 0.1
done
addr=$(sed -n 's/^listening on //p' "$WORK/out")
[ -n "$addr" ] || fail "the entry point did not start listening: $(cat "$WORK/err")"
health_words=("${health_words[@]/127.0.0.1:50051/$addr}")
out=$(PATH="$BIN:$PATH" "${health_words[@]}") || fail "the health check failed: $out"
[ "$out" = "SERVING" ] || fail "the health check printed '$out'"
kill -TERM "$pid"
status=0
wait "$pid" || status=$?
[ "$status" -eq 0 ] || fail "SIGTERM: exit code $status"
echo "runtime image check: $libraries shared libraries the two binaries load, all from" \
  "the ${#listed[@]} listed packages; the entry point serves, the health check says SERVING," \
  "SIGTERM exits 0"
