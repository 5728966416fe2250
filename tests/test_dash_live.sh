#!/usr/bin/env bash
# pneu-dash end to end: pneud on the real clock publishes LCM (inside tests/in_private_netns.sh: a
# network namespace with only loopback), pneu-dash serves it on 127.0.0.1, and a client subscribes
# to every channel and holds every message to the JSON Schema its channel advertised.
#   test_dash_live.sh BIN_DIR SOURCE_DIR python
#       the client tests/dash_client.py; then the run's LCM log (lcm-logger) played by
#       pneu-dash --log: the same channels, and time messages
#   test_dash_live.sh BIN_DIR SOURCE_DIR foxglove NODE_DIR
#       the independent client tests/dash_client/foxglove_client.mjs (@foxglove/ws-protocol),
#       installed into NODE_DIR by the test DashFoxgloveClientInstall (npm ci)
set -u
B=$1
S=$2
MODE=$3
NODE_DIR=${4:-}
PY=/usr/bin/python3
D=$(mktemp -d /tmp/pneu_dash_live.XXXXXX)
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null; done
  wait 2>/dev/null
  rm -rf "$D"
}
trap cleanup EXIT
fail() {
  echo "FAIL: $*"
  for f in "$D"/*.out "$D"/*.err; do [ -s "$f" ] && { echo "--- $f"; tail -20 "$f"; }; done
  exit 1
}
if [ "$MODE" = foxglove ]; then
  [ -f "$NODE_DIR/node_modules/.package-lock.json" ] ||
    { echo "SKIPPED: the npm packages are not installed in $NODE_DIR (the test DashFoxgloveClientInstall: npm ci failed or was skipped)"; exit 77; }
  command -v node >/dev/null || { echo "SKIPPED: node (nodejs) is missing"; exit 77; }
fi

# Until 127.0.0.1:PORT takes connections, up to 10 s.
wait_port() {
  for _ in $(seq 200); do
    (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null && return 0
    sleep 0.05
  done
  fail "nothing listens on 127.0.0.1:$1"
}

lcm-logger -f "$D/run.lcmlog" >"$D/logger.out" 2>&1 &
PIDS+=($!)
"$B/pneu-dash" --listen 127.0.0.1:8765 >"$D/dash.out" 2>"$D/dash.err" &
DASH=$!
PIDS+=($DASH)
wait_port 8765

# Online learning on: a run of 8 s brings every channel (identification after the first stop). The
# loop-timing supervision is off: a stall of the shared machine would latch a fault (timing is not
# this test's subject).
"$B/pneud" --clock real --duration 8 --require-telemetry --summary-json "$D/summary.json" \
  --set controller.predictor.learn_online=true \
  --set controller.supervisor.overruns_in_a_row=0 --set controller.supervisor.max_tick_interval_s=0 \
  >"$D/pneud.out" 2>"$D/pneud.err" &
PNEUD=$!
PIDS+=($PNEUD)

want=(PNEU_STATE:2000 PNEU_HEALTH:2 PNEU_EVENT:1 PNEU_PREDICTION:1 PNEU_IDENTIFICATION:1)
if [ "$MODE" = foxglove ]; then
  # Beside its node_modules: an ES module resolves its imports from where it is.
  cp "$S/tests/dash_client/foxglove_client.mjs" "$NODE_DIR/" || fail "copying the client into $NODE_DIR"
  node "$NODE_DIR/foxglove_client.mjs" ws://127.0.0.1:8765/ws 30 "${want[@]}" >"$D/client.out" 2>&1
else
  "$PY" "$S/tests/dash_client.py" ws://127.0.0.1:8765/ws 30 "${want[@]}" >"$D/client.out" 2>&1
fi
rc=$?
cat "$D/client.out"
[ $rc -eq 0 ] || fail "the client against the live bench exited $rc"
wait "$PNEUD" || fail "pneud exited $?"
# Where messages were lost, if any were (the client counts what is missing by the sequence): what
# pneud published, what pneu-dash received from LCM, queued and dropped.
"$PY" - "$D/summary.json" <<'PYEOF'
import json, sys, urllib.request
s = json.load(open(sys.argv[1]))
print("pneud: %d ticks, %d publish errors" % (s["loop"]["ticks"], s["telemetry"]["publish_errors"]))
for line in urllib.request.urlopen("http://127.0.0.1:8765/metrics").read().decode().splitlines():
    if 'channel="PNEU_STATE"' in line:
        print("pneu-dash: " + line)
PYEOF
kill "$DASH"
wait "$DASH"
rc=$?
[ $rc -eq 0 ] || fail "pneu-dash stopped by SIGTERM exited $rc"
[ "$MODE" = foxglove ] && { echo PASSED; exit 0; }

# The run's log, played: every channel again, with the time cursor.
sleep 0.3
"$B/pneu-dash" --log "$D/run.lcmlog" --listen 127.0.0.1:8766 >"$D/dash_log.out" 2>"$D/dash_log.err" &
PIDS+=($!)
wait_port 8766
"$PY" "$S/tests/dash_client.py" ws://127.0.0.1:8766/ws 30 "${want[@]}" --time >"$D/client_log.out" 2>&1
rc=$?
cat "$D/client_log.out"
[ $rc -eq 0 ] || fail "the client against the log played exited $rc"
echo PASSED
