#!/usr/bin/env bash
# The main job: install what is missing, build, then run the whole loop over the network:
# start fulcrum-server on loopback (an ephemeral port), create a world from scenes/pyramid.json
# with the CLI, record it to a replay ON THE SERVER, watch its frame stream while stepping 10 s
# of simulation, save a snapshot from the server, check the server's hash against a local
# replay of the same ticks, run the world 2 s in real time on the server's clock while watching
# and pause it, download the server's replay with the CLI and verify it (re-simulated here, its
# final hash must be the world's), and stop the server with SIGTERM (it must exit 0). Prints a
# summary; exits non-zero on any failure. Extra arguments go to fulcrum-server (e.g.
# --max-bodies 500).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
fulcrum_install_packages
fulcrum_build

BIN="$FULCRUM_BUILD/bin"
SCENE="$FULCRUM_ROOT/scenes/pyramid.json"
SECONDS_OF_WATCH=5
TICKS_PER_SECOND=120  # 2 s of simulated time (60 Hz) per wall second: 600 ticks in all
TICKS=$((SECONDS_OF_WATCH * TICKS_PER_SECOND))
REAL_TIME_SECONDS=2
WORK="$(mktemp -d "${TMPDIR:-/tmp}/fulcrum-run.XXXXXX")"
SERVER_PID=""
WATCH_PID=""

cleanup() {
  if [ -n "$WATCH_PID" ] && kill -0 "$WATCH_PID" 2>/dev/null; then kill "$WATCH_PID" || true; fi
  if [ -n "$SERVER_PID" ] && kill -0 "$SERVER_PID" 2>/dev/null; then
    kill -TERM "$SERVER_PID" || true
    wait "$SERVER_PID" 2>/dev/null || true
  fi
  rm -rf "$WORK"
}
trap cleanup EXIT

fail() {
  echo "run.sh: $*" >&2
  for f in server.err watch.out; do
    if [ -s "$WORK/$f" ]; then echo "--- $f" >&2; cat "$WORK/$f" >&2; fi
  done
  exit 1
}

# 1. The server, on a port the kernel picks; it prints "listening on HOST:PORT" when ready.
# Its output files exist first, so the loop never reads before the redirections are open.
: >"$WORK/server.out"
: >"$WORK/server.err"
"$BIN/fulcrum-server" --listen 127.0.0.1:0 --replay-dir "$WORK/replays" "$@" \
  >"$WORK/server.out" 2>"$WORK/server.err" &
SERVER_PID=$!
ADDR=""
for _ in $(seq 1 100); do
  ADDR="$(sed -n 's/^listening on //p' "$WORK/server.out")"
  [ -n "$ADDR" ] && break
  kill -0 "$SERVER_PID" 2>/dev/null || fail "fulcrum-server exited before listening"
  sleep 0.1
done
[ -n "$ADDR" ] || fail "fulcrum-server did not start listening within 10 s"
echo "fulcrum-server pid $SERVER_PID listening on $ADDR"
CLI=("$BIN/fulcrum")
S=(--server "$ADDR")

# 2. A world from the scene file.
CREATED="$("${CLI[@]}" create "${S[@]}" --scene "$SCENE")" || fail "create failed"
echo "$CREATED"
WORLD="$(echo "$CREATED" | awk '/^world /{print $2; exit}')"
[ -n "$WORLD" ] || fail "no world id in: $CREATED"
"${CLI[@]}" replay start "$WORLD" "${S[@]}" || fail "replay start failed"

# 3. Watch the stream while stepping, about one batch of ticks per wall second.
"${CLI[@]}" watch "$WORLD" "${S[@]}" --seconds $((SECONDS_OF_WATCH + 1)) >"$WORK/watch.out" 2>&1 &
WATCH_PID=$!
sleep 0.5
STEP_OUT=""
for _ in $(seq 1 "$SECONDS_OF_WATCH"); do
  STEP_OUT="$("${CLI[@]}" step "$WORLD" "$TICKS_PER_SECOND" "${S[@]}")" || fail "step failed"
  echo "$STEP_OUT"
  sleep 1
done
wait "$WATCH_PID" || fail "watch failed"
WATCH_PID=""
echo "--- watch $WORLD (one line per second)"
cat "$WORK/watch.out"
SERVER_HASH="$(echo "$STEP_OUT" | sed -n 's/.*state hash \([0-9a-f]\{16\}\).*/\1/p')"
[ -n "$SERVER_HASH" ] || fail "no state hash in: $STEP_OUT"

# 4. A snapshot from the server, and a local replay of the same ticks to check it against.
"${CLI[@]}" snapshot get "$WORLD" "${S[@]}" --out "$WORK/world.snapshot" || fail "snapshot failed"
"${CLI[@]}" replay record --scene "$SCENE" --ticks "$TICKS" --out "$WORK/pyramid.replay" \
  >"$WORK/record.out" || fail "replay record failed"
VERIFY="$("${CLI[@]}" replay verify "$WORK/pyramid.replay")" || fail "replay verify: $VERIFY"
LOCAL_HASH="$(sed -n 's/.*state hash \([0-9a-f]\{16\}\).*/\1/p' "$WORK/record.out")"
# Rollback round trip: restore the snapshot into a fork and check it lands on the same hash.
FORK="$("${CLI[@]}" snapshot restore new "${S[@]}" --file "$WORK/world.snapshot")" ||
  fail "fork failed"
echo "$FORK"
case "$FORK" in *"state hash $SERVER_HASH"*) ;; *) fail "the fork's hash is not $SERVER_HASH" ;; esac

# 5. Real time: the server steps the world at 60 Hz on its own clock while we watch; then pause.
"${CLI[@]}" run "$WORLD" "${S[@]}" || fail "run failed"
"${CLI[@]}" watch "$WORLD" "${S[@]}" --seconds "$REAL_TIME_SECONDS" >"$WORK/watch_rt.out" 2>&1 ||
  fail "watch (real time) failed"
echo "--- watch $WORLD in real time"
cat "$WORK/watch_rt.out"
PAUSE_OUT="$("${CLI[@]}" pause "$WORLD" "${S[@]}")" || fail "pause failed"
echo "$PAUSE_OUT"
PAUSED_TICK="$(echo "$PAUSE_OUT" | sed -n 's/.*paused at tick \([0-9]*\),.*/\1/p')"
PAUSED_HASH="$(echo "$PAUSE_OUT" | sed -n 's/.*state hash \([0-9a-f]\{16\}\);.*/\1/p')"
[ -n "$PAUSED_HASH" ] || fail "no state hash in: $PAUSE_OUT"
REAL_TIME_TICKS=$((PAUSED_TICK - TICKS))
"${CLI[@]}" worlds "${S[@]}"

# 6. The replay the server recorded: stop, download with the CLI, verify it here.
"${CLI[@]}" replay stop "$WORLD" "${S[@]}" || fail "replay stop failed"
"${CLI[@]}" replay download "$WORLD" "${S[@]}" --out "$WORK/server.replay" ||
  fail "replay download failed"
SERVER_VERIFY="$("${CLI[@]}" replay verify "$WORK/server.replay")" ||
  fail "the server's replay does not verify: $SERVER_VERIFY"
echo "$SERVER_VERIFY"
case "$SERVER_VERIFY" in
  *"final tick $PAUSED_TICK, state hash $PAUSED_HASH") ;;
  *) fail "the server's replay ends elsewhere than the world (tick $PAUSED_TICK, $PAUSED_HASH)" ;;
esac

# 7. Stop the server the way an operator would.
kill -TERM "$SERVER_PID"
SERVER_RC=0
wait "$SERVER_PID" || SERVER_RC=$?
SERVER_PID=""

echo
echo "summary"
echo "  scene               $SCENE"
echo "  server              $ADDR, stopped by SIGTERM with exit code $SERVER_RC"
echo "  ticks stepped       $TICKS (over the wire, $TICKS_PER_SECOND per call)"
echo "  server state hash   $SERVER_HASH"
echo "  local replay hash   $LOCAL_HASH ($VERIFY)"
echo "  frames watched      $(tail -n 1 "$WORK/watch.out")"
echo "  real time           $REAL_TIME_TICKS ticks in ${REAL_TIME_SECONDS} s at 60 Hz, paused at tick $PAUSED_TICK"
echo "  server replay       $(ls -l "$WORK/server.replay" | awk '{print $5}') bytes: $SERVER_VERIFY"
if [ "$SERVER_HASH" != "$LOCAL_HASH" ]; then fail "the server and the local replay diverge"; fi
echo "  determinism         the server's world matches the local replay bit for bit"
[ "$SERVER_RC" -eq 0 ] || fail "fulcrum-server exited with $SERVER_RC"
