#!/usr/bin/env bash
# The real fulcrum-server binary on an ephemeral loopback port, driven by the fulcrum CLI:
# create, step (hash equal to a local `fulcrum sim`), errors with the server's message and exit
# code 1, quantized frames through `fulcrum watch`, a token file, `fulcrum stats`, `fulcrum
# health` and the refused-request log, SIGTERM while a watch stream is open (server exits 0, the
# watcher is told the server is stopping), and TLS.
# usage: cli_server_test.sh BIN_DIR SCENES_DIR WORK_DIR
set -euo pipefail
BIN="$1"
SCENES="$2"
WORK="$3/cli_server_test.$$"
mkdir -p "$WORK"
PID=""
trap 'if [ -n "$PID" ]; then kill -TERM "$PID" 2>/dev/null || true; fi; rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*" >&2; cat "$WORK"/*.err >&2 2>/dev/null || true; exit 1; }

start_server() {  # start_server NAME [FLAGS...]: sets PID and ADDR
  local name="$1"
  shift
  # The output files exist before the server starts: the loop below may read them before the
  # background shell has opened its redirections.
  : >"$WORK/$name.out"
  : >"$WORK/$name.err"
  "$BIN/fulcrum-server" --listen 127.0.0.1:0 "$@" >"$WORK/$name.out" 2>"$WORK/$name.err" &
  PID=$!
  ADDR=""
  for _ in $(seq 1 100); do
    ADDR="$(sed -n 's/^listening on //p' "$WORK/$name.out")"
    [ -n "$ADDR" ] && return 0
    sleep 0.1
  done
  fail "$name: no 'listening on' line"
}

stop_server() {  # SIGTERM, and the exit code must be 0
  kill -TERM "$PID"
  local rc=0
  wait "$PID" || rc=$?
  PID=""
  [ "$rc" -eq 0 ] || fail "fulcrum-server exited with $rc after SIGTERM"
}

F="$BIN/fulcrum"
start_server plain
out="$("$F" create --server "$ADDR" --scene "$SCENES/pyramid.json")"
echo "$out"
[[ "$out" == "world 1 created from "*"211 bodies, tick 0"* ]] || fail "create: $out"
out="$("$F" step 1 90 --server "$ADDR")"
echo "$out"
remote_hash="$(echo "$out" | sed -n 's/.*state hash \([0-9a-f]*\).*/\1/p')"
local_hash="$("$F" sim --scene "$SCENES/pyramid.json" --ticks 90 | sed -n 's/^state hash: *//p')"
[ "$remote_hash" = "$local_hash" ] || fail "server hash $remote_hash, local $local_hash"

if "$F" step 42 1 --server "$ADDR" 2>"$WORK/err.txt"; then fail "step on world 42 succeeded"; fi
grep -q "world_id: no world 42" "$WORK/err.txt" || fail "unknown world: $(cat "$WORK/err.txt")"
if "$F" step 1 1 --expected-tick 5 --server "$ADDR" 2>"$WORK/err.txt"; then
  fail "stale expected tick accepted"
fi
grep -q "expected_tick: the world is at tick 90, not 5" "$WORK/err.txt" ||
  fail "expected tick: $(cat "$WORK/err.txt")"
echo '{"edits": []}' >"$WORK/empty.json"
if "$F" edit 1 --file "$WORK/empty.json" --server "$ADDR" 2>"$WORK/err.txt"; then
  fail "empty batch accepted"
fi
grep -q "batch.edits: must not be empty" "$WORK/err.txt" || fail "empty: $(cat "$WORK/err.txt")"
"$F" worlds --server "$ADDR" | grep -q "^1 .*pyramid .* 90 .* 211 .*$remote_hash" ||
  fail "worlds does not list world 1 at tick 90"


# Queries: the top box of the 20-row pyramid is hit by a ray straight down; a negative
# coordinate is a number, not a flag; --mask 0 sees nothing; bad numbers are usage errors.
out="$("$F" query 1 ray 0 50 0 -10 --server "$ADDR")"
[[ "$out" == "1 hit"* ]] || fail "query ray: $out"
out="$("$F" query 1 ray -30 0.5 30 0.5 --all --server "$ADDR")"
[[ "$out" == "20 hits"* ]] || fail "query ray --all through the bottom row: $out"
out="$("$F" query 1 aabb -1 0 1 1 --mask 0 --server "$ADDR")"
[ "$out" = "0 shapes" ] || fail "query aabb --mask 0: $out"
rc=0
"$F" query 1 point x 1 --server "$ADDR" 2>"$WORK/err.txt" || rc=$?
[ "$rc" -eq 2 ] || fail "query point x: exit $rc"

# Replays need --replay-dir on the server: the server's message, exit code 1.
if "$F" replay start 1 --server "$ADDR" 2>"$WORK/err.txt"; then fail "recording without a dir"; fi
grep -q "replay-dir" "$WORK/err.txt" || fail "replay start: $(cat "$WORK/err.txt")"

# Quantized frames while world 1 steps from tick 90 to 210: two watchers, every body at full
# precision and quantized. Lines come with increasing ticks; the last one is the world's tick
# and exact hash as `fulcrum worlds` lists it; a quantized frame is under half the bytes of a
# full one (a double field takes 9 bytes, a fixed-point one 1 to 4: measured here 8.3 kB
# against 3.2 kB for the 211 resting bodies). The watchers outlast the three steps by seconds
# even when each CLI call takes over a second (sanitizer builds on a loaded machine); a
# watcher prints a line only for new frames, so the wait adds no lines.
"$F" watch 1 --seconds 8 --bodies all --server "$ADDR" >"$WORK/full.out" 2>"$WORK/full.err" &
FULL=$!
"$F" watch 1 --seconds 8 --bodies all --quantized --server "$ADDR" >"$WORK/q.out" 2>"$WORK/q.err" &
QUANT=$!
sleep 0.3
for _ in 1 2 3; do
  "$F" step 1 40 --server "$ADDR" >/dev/null
  sleep 1
done
wait "$FULL" || fail "watch --bodies all failed"
wait "$QUANT" || fail "watch --quantized failed"
cat "$WORK/full.out" "$WORK/q.out"
hash_210="$("$F" worlds --server "$ADDR" | sed -n 's/^1 .* 210 .* \([0-9a-f]\{16\}\) .*/\1/p')"
[ -n "$hash_210" ] || fail "worlds does not list world 1 at tick 210"
ticks="$(sed -n 's/^tick \([0-9]*\) .*/\1/p' "$WORK/q.out" | tr '\n' ' ')"
[ "$(echo "$ticks" | wc -w)" -ge 2 ] || fail "watch --quantized: one line or none: $ticks"
echo "$ticks" | tr ' ' '\n' | sed '/^$/d' | sort -n -c -u || fail "ticks do not increase: $ticks"
tail -n 1 "$WORK/q.out" | grep -q "^tick 210 .* hash $hash_210 " ||
  fail "watch --quantized ends at $(tail -n 1 "$WORK/q.out"), worlds has tick 210 $hash_210"
per_frame() { sed -n 's/.*(\([0-9]*\) B\/frame)$/\1/p' "$1" | tail -n 1; }
full_bytes="$(per_frame "$WORK/full.out")"
quant_bytes="$(per_frame "$WORK/q.out")"
[ -n "$full_bytes" ] && [ -n "$quant_bytes" ] && [ $((2 * quant_bytes)) -lt "$full_bytes" ] ||
  fail "quantized $quant_bytes B/frame, full $full_bytes B/frame"

# A lossless trajectory to CSV from a new world: ticks 5 and 10 of bodies 3 and 1, in that
# order, and the hash of tick 10 equal to a local run's.
"$F" create --server "$ADDR" --scene "$SCENES/pyramid.json" >/dev/null
out="$("$F" step 2 10 --trajectory "$WORK/t.csv" --every 5 --bodies 3,1:1 --server "$ADDR")"
echo "$out"
[[ "$out" == *"2 samples written to $WORK/t.csv"* ]] || fail "trajectory: $out"
[ "$(wc -l <"$WORK/t.csv")" -eq 5 ] || fail "trajectory rows: $(cat "$WORK/t.csv")"
head -1 "$WORK/t.csv" | grep -q "^tick,state_hash,body_index,body_generation,x,y,angle," ||
  fail "trajectory header: $(head -1 "$WORK/t.csv")"
[ "$(cut -d, -f1,3 "$WORK/t.csv" | tail -4 | tr '\n' ' ')" = "5,3 5,1 10,3 10,1 " ] ||
  fail "trajectory order: $(cat "$WORK/t.csv")"
local10="$("$F" sim --scene "$SCENES/pyramid.json" --ticks 10 | sed -n 's/^state hash: *//p')"
[ "$(tail -1 "$WORK/t.csv" | cut -d, -f2)" = "$local10" ] ||
  fail "trajectory hash $(tail -1 "$WORK/t.csv" | cut -d, -f2), local $local10"
if "$F" step 2 1 --trajectory - --bodies 3,x --server "$ADDR" 2>"$WORK/err.txt"; then
  fail "a bad --bodies list was accepted"
fi
grep -q -- "--bodies: 'x'" "$WORK/err.txt" || fail "bad bodies: $(cat "$WORK/err.txt")"

# A multiplayer session turn by turn: two bots push their own boxes and check every confirmed
# hash on their own copy of the world, a spectator follows; the bot that stops first leaves, and
# the other goes on alone.
"$F" create --server "$ADDR" --scene "$SCENES/pyramid.json" >/dev/null
out="$("$F" session open 3 --players 2 --seal all-inputs --input-delay 2 --server "$ADDR")"
[[ "$out" == "world 3: a session from tick 0, at most 2 players"* ]] || fail "session open: $out"
"$F" session watch 3 --ticks 60 --server "$ADDR" >"$WORK/sw.out" 2>"$WORK/sw.err" &
SW=$!
"$F" session bot 3 --bodies 210 --ticks 60 --server "$ADDR" >"$WORK/b1.out" 2>"$WORK/b1.err" &
B1=$!
"$F" session bot 3 --bodies 209 --ticks 90 --seed 2 --report-every 30 --server "$ADDR" \
  >"$WORK/b2.out" 2>&1 ||
  fail "bot 2: $(cat "$WORK/b2.out")"
wait "$B1" || fail "bot 1: $(cat "$WORK/b1.out" "$WORK/b1.err")"
wait "$SW" || fail "session watch: $(cat "$WORK/sw.out" "$WORK/sw.err")"
grep -q "every state hash matched" "$WORK/b1.out" || fail "bot 1: $(cat "$WORK/b1.out")"
grep -q "^player [12]: 90 ticks confirmed, every state hash matched.*; 3 hash reports, 3 matched" \
  "$WORK/b2.out" || fail "bot 2: $(cat "$WORK/b2.out")"
grep -q "^world 3: 60 ticks confirmed from tick [0-9]*, every state hash matched" "$WORK/sw.out" ||
  fail "session watch: $(cat "$WORK/sw.out")"
if "$F" session bot 3 --bodies 210 --server "$ADDR" 2>"$WORK/err.txt"; then
  fail "a third player joined a session of two"
fi
grep -q "the session has its 2 players" "$WORK/err.txt" || fail "third: $(cat "$WORK/err.txt")"

# `session create` is `open`; `join` takes a player slot for another program and prints its id,
# secret and what it owns; a body another player owns is refused with the field named.
"$F" create --server "$ADDR" --scene "$SCENES/pyramid.json" >/dev/null
out="$("$F" session create 4 --players 2 --server "$ADDR")"
[[ "$out" == "world 4: a session from tick 0, at most 2 players"* ]] || fail "create: $out"
out="$("$F" session join 4 --bodies 210 --name ui --server "$ADDR")" || fail "join: $out"
[ "$(sed -n 1p <<<"$out")" = "player 1 joined world 4 at tick 0; first input for tick 0" ] &&
  grep -qE "^secret: [0-9a-f]{64}$" <<<"$out" && grep -qx "bodies: 210:1" <<<"$out" &&
  grep -qx "joints:" <<<"$out" || fail "join: $out"
if "$F" session join 4 --bodies 210 --server "$ADDR" 2>"$WORK/err.txt"; then
  fail "a second player took player 1's body"
fi
grep -q "bodies\[0\]: body {210, 1} is player 1's" "$WORK/err.txt" ||
  fail "join taken: $(cat "$WORK/err.txt")"

# SIGTERM with a watcher attached: the stream ends, the server exits 0.
"$F" watch 1 --server "$ADDR" >"$WORK/watch.out" 2>"$WORK/watch.err" &
WATCH=$!
sleep 0.5
stop_server
rc=0
wait "$WATCH" || rc=$?
[ "$rc" -eq 1 ] || fail "watch exited with $rc after the server stopped"
grep -q "UNAVAILABLE: the server is stopping" "$WORK/watch.err" ||
  fail "watch: $(cat "$WORK/watch.err")"

# A token file: calls without it are refused, with it they pass.
echo "t0ken" >"$WORK/token"
start_server token --token-file "$WORK/token"
if "$F" worlds --server "$ADDR" 2>"$WORK/err.txt"; then fail "no token accepted"; fi
grep -q "UNAUTHENTICATED" "$WORK/err.txt" || fail "no token: $(cat "$WORK/err.txt")"
"$F" worlds --server "$ADDR" --token-file "$WORK/token" >/dev/null || fail "token refused"
# The counters, through `fulcrum stats`: the refused `worlds` call above is counted.
"$F" stats --server "$ADDR" --token-file "$WORK/token" >"$WORK/stats.txt" || fail "stats failed"
grep -q "^refused.UNAUTHENTICATED *1$" "$WORK/stats.txt" || fail "stats: $(cat "$WORK/stats.txt")"
grep -q "event=refused rpc=ListWorlds code=UNAUTHENTICATED field=authorization" "$WORK/token.err" ||
  fail "no refused log line: $(cat "$WORK/token.err")"
# `fulcrum health` (the container's HEALTHCHECK) needs no token: SERVING, exit 0, for the
# server and for the Physics service; an unknown service exits 1, and so does a stopped server.
[ "$("$F" health --server "$ADDR")" = "SERVING" ] || fail "health"
[ "$("$F" health --server "$ADDR" --service fulcrum.v1.Physics)" = "SERVING" ] ||
  fail "health of fulcrum.v1.Physics"
if "$F" health --server "$ADDR" --service fulcrum.v1.Nothing 2>"$WORK/err.txt"; then
  fail "health of an unknown service"
fi
HEALTH_ADDR="$ADDR"
stop_server
if "$F" health --server "$HEALTH_ADDR" --deadline-ms 2000 >/dev/null 2>&1; then
  fail "health of a stopped server"
fi

# Real time and a replay recorded on the server: run, step refused while running, pause (the
# tick stays put), download while recording and after, verify; then SIGTERM closes a recording
# still open and the file verifies.
start_server replays --replay-dir "$WORK/replays" --worker-threads 2
"$F" create --server "$ADDR" --scene "$SCENES/pyramid.json" >/dev/null
out="$("$F" replay start 1 --server "$ADDR" --keyframes 20)"
[ "$out" = "world 1: recording world1-1.replay from tick 0" ] || fail "replay start: $out"
"$F" step 1 30 --server "$ADDR" >/dev/null
"$F" run 1 --server "$ADDR" | grep -q "real time at 60 Hz from tick 30" || fail "run"
if "$F" step 1 1 --server "$ADDR" 2>"$WORK/err.txt"; then fail "step while running"; fi
grep -q "runs in real time" "$WORK/err.txt" || fail "step while running: $(cat "$WORK/err.txt")"
sleep 0.5
"$F" replay download 1 --out "$WORK/mid.replay" --server "$ADDR" >/dev/null || fail "download"
"$F" replay verify "$WORK/mid.replay" >/dev/null || fail "the replay downloaded mid-run"
out="$("$F" pause 1 --server "$ADDR")"
paused_tick="$(echo "$out" | sed -n 's/.*paused at tick \([0-9]*\),.*/\1/p')"
paused_hash="$(echo "$out" | sed -n 's/.*state hash \([0-9a-f]*\);.*/\1/p')"
[ -n "$paused_tick" ] && [ "$paused_tick" -gt 30 ] || fail "pause: $out"
sleep 0.3
"$F" worlds --server "$ADDR" | grep -q "^1 .* $paused_tick .* paused .*world1-1.replay (on)" ||
  fail "worlds after pause: $("$F" worlds --server "$ADDR")"
"$F" replay stop 1 --server "$ADDR" | grep -q "closed: $paused_tick ticks" || fail "replay stop"
"$F" replay download world1-1.replay --out "$WORK/full.replay" --server "$ADDR" >/dev/null ||
  fail "download by name"
out="$("$F" replay verify "$WORK/full.replay")"
[[ "$out" == *"final tick $paused_tick, state hash $paused_hash" ]] || fail "verify: $out"
if "$F" replay download nothing.replay --out "$WORK/x" --server "$ADDR" 2>"$WORK/err.txt"; then
  fail "download of an unknown replay"
fi
grep -q "no replay nothing.replay" "$WORK/err.txt" || fail "unknown: $(cat "$WORK/err.txt")"
"$F" replay start 1 --server "$ADDR" >/dev/null
"$F" step 1 7 --server "$ADDR" >/dev/null
stop_server
out="$("$F" replay verify "$WORK/replays/world1-2.replay")" || fail "after SIGTERM: $out"
[[ "$out" == *"7 ticks match"* ]] || fail "after SIGTERM: $out"
# TLS: a missing certificate file is named; a self-signed certificate made here serves TLS
# only: the CLI with --tls-ca passes, without it (plaintext) it fails.
if "$BIN/fulcrum-server" --listen 127.0.0.1:0 --tls-cert "$WORK/none.pem" --tls-key "$WORK/none.pem" \
  2>"$WORK/err.txt"; then
  fail "a missing certificate was accepted"
fi
grep -q -- "--tls-cert: cannot read $WORK/none.pem" "$WORK/err.txt" || fail "tls: $(cat "$WORK/err.txt")"
if command -v openssl >/dev/null; then
  openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 2 \
    -subj /CN=localhost -addext subjectAltName=DNS:localhost,IP:127.0.0.1 \
    -keyout "$WORK/key.pem" -out "$WORK/cert.pem" >/dev/null 2>&1 || fail "openssl failed"
  start_server tls --tls-cert "$WORK/cert.pem" --tls-key "$WORK/key.pem"
  "$F" worlds --server "$ADDR" --tls-ca "$WORK/cert.pem" >/dev/null || fail "TLS client refused"
  "$F" worlds --server "localhost:${ADDR##*:}" --tls-ca "$WORK/cert.pem" --tls-name localhost \
    >/dev/null || fail "TLS client with --tls-name refused"
  if "$F" worlds --server "$ADDR" --deadline-ms 3000 2>"$WORK/err.txt"; then
    fail "a plaintext client reached a TLS server"
  fi
  stop_server
else
  echo "openssl is not installed (tools/setup.sh installs it): TLS part skipped"
fi
echo "OK"
