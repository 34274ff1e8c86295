#!/usr/bin/env bash
# The real fulcrum-server binary on an ephemeral loopback port, driven by the fulcrum CLI:
# create, step (hash equal to a local `fulcrum sim`), errors with the server's message and exit
# code 1, a token file, `fulcrum stats` and the refused-request log, SIGTERM while a watch
# stream is open (server exits 0, the watcher is told the server is stopping), and TLS.
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
stop_server

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
