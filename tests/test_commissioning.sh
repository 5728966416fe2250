#!/usr/bin/env bash
# Issue 32: docs/commissioning.md, followed to the letter. The commands of the guide's blocks
# marked `<!-- commissioning: NAME -->` are read from the guide itself (so the guide and this test
# cannot drift) and run in order, in the source tree, with the guide's own variables BIN, CONFIG
# and OUT set to this build's programs and a temporary directory; nothing else of them is changed.
# The bench is `pneu-plant serve` on 127.0.0.1 (a free port), playing a bench that is not
# config/bench.yaml: stiction and Coulomb friction 15 % high, dead volumes 30 % larger, a valve
# null offset of 40 mV (hal.sim.plant), 16-bit sensors with hil.yaml's noise. Step 1's hand edit
# is played here: the module at 127.0.0.1 and the free port, no GPIO lines.
# It passes when the guide's last step ends with a held carriage: a hold begun within the window
# after the step, no breakaway of the plant after it on serve's own record (CLOCK_MONOTONIC; a
# carriage still sliding within the rest band as the stop was confirmed may move on without one:
# pneud sees a start, the plant none), the last hold's rest position within
# controller.hold.window_m of the set point, no end after it, the run's last tick in mode hold.
# The real clock on a loaded machine: a run ended by a comms or overrun fault (samples or ticks
# late), or a step run whose loop skipped deadlines and did not end held, is run again on a fresh
# plant, up to 3 runs; when all 3 were robbed so, skipped saying why.
#   test_commissioning.sh BINARY_DIR SOURCE_DIR   (PNEU_KEEP_TEST_FILES=1: the files kept, their directory said)
set -euo pipefail
build=$(cd "$1" && pwd); src=$(cd "$2" && pwd)
guide=$src/docs/commissioning.md
tmp=$(mktemp -d)
serve_pid=
cleanup() {
  if [ -n "$serve_pid" ]; then kill -INT "$serve_pid" 2>/dev/null || true; wait "$serve_pid" 2>/dev/null || true; fi
  if [ -n "${PNEU_KEEP_TEST_FILES:-}" ]; then echo "files kept in $tmp"; else rm -rf "$tmp"; fi
}
trap cleanup EXIT
fail() { echo "FAIL: $*"; exit 1; }

# The guide's marked blocks, each into $tmp/blocks/NAME.sh; their names in order.
mkdir "$tmp/blocks"
names=$(/usr/bin/python3 - "$guide" "$tmp/blocks" <<'EOF'
import re, sys
lines = open(sys.argv[1]).read().split("\n")
names = []
for i, line in enumerate(lines):
    m = re.fullmatch(r"<!-- commissioning: ([a-z]+) -->", line)
    if not m:
        continue
    if i + 1 >= len(lines) or lines[i + 1] != "```sh":
        sys.exit(f"{sys.argv[1]}:{i + 1}: the marker is not followed by a ```sh block")
    end = lines.index("```", i + 2)
    open(f"{sys.argv[2]}/{m.group(1)}.sh", "w").write("\n".join(lines[i + 2:end]) + "\n")
    names.append(m.group(1))
print(" ".join(names))
EOF
)
expected="variables config check readings movement identify tune sweep step"
[ "$names" = "$expected" ] || fail "the guide's marked blocks are '$names', this test follows '$expected'"

# The variables block sets exactly BIN, CONFIG and OUT; the test sets them instead.
[ "$(sed -n 's/^\([A-Z_]*\)=.*/\1/p' "$tmp/blocks/variables.sh" | tr '\n' ' ')" = "BIN CONFIG OUT " ] \
  || fail "the variables block does not set exactly BIN, CONFIG, OUT: $(cat "$tmp/blocks/variables.sh")"
export BIN=$build/bin CONFIG=$tmp/my-bench.yaml OUT=$tmp/out

# step NAME: runs the guide's block NAME in the source tree; its output in $tmp/NAME.out/.err.
step() {
  echo "=== $1 (at ${SECONDS} s): $(tr '\n' ' ' < "$tmp/blocks/$1.sh" | sed 's/  */ /g')"
  local rc=0
  (cd "$src" && bash -euo pipefail "$tmp/blocks/$1.sh") > "$tmp/$1.out" 2> "$tmp/$1.err" || rc=$?
  if [ "$(wc -l < "$tmp/$1.out")" -gt 40 ]; then head -n 20 "$tmp/$1.out"; echo "  ..."; fi
  tail -n 20 "$tmp/$1.out"; grep -v '^pneu-sweep: [0-9]*/[0-9]* scenarios' "$tmp/$1.err" | tail -n 15 || true
  return $rc
}

step config || fail "step 1's copy"
# Step 1's hand edit, as a bench owner makes it: the module's address, no GPIO lines.
port=$(/usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
/usr/bin/python3 - "$CONFIG" "$port" <<'EOF'
import re, sys
path, port = sys.argv[1], sys.argv[2]
text = open(path).read()
edits = [(r"(\n    host: *)192\.168\.1\.10", r"\g<1>127.0.0.1"), (r"(\n    port: *)502", r"\g<1>" + port),
         (r"(\n  gpio:[^\n]*\n    enabled: *)true", r"\g<1>false")]
for pattern, repl in edits:
    text, n = re.subn(pattern, repl, text)
    if n != 1:
        sys.exit(f"{path}: the edit {pattern} matched {n} times")
open(path, "w").write(text)
EOF

# The bench: not the configuration's. It answers as a module does, whatever else the host runs:
# where this user may use SCHED_FIFO, at real-time priority 41, below the guide's pneud (bench.yaml's
# controller.realtime.priority, 80, pinned to CPU 1), where the HilOnTime tests run serve above
# their pneud's 40: here the loop's own priority is the guide's, not the test's.
answering=()
chrt -f 1 true 2>/dev/null && answering=(chrt -f 41)
serve() {
  "${answering[@]}" "$BIN/pneu-plant" serve --config "$CONFIG" --events "$tmp/plant.jsonl" \
    --set hal.sim.plant.friction.static_positive_n=51.75 --set hal.sim.plant.friction.coulomb_positive_n=40.25 \
    --set hal.sim.plant.friction.static_negative_n=-57.5 --set hal.sim.plant.friction.coulomb_negative_n=-43.7 \
    --set hal.sim.plant.geometry.dead_volume_p_m3=1.3e-5 --set hal.sim.plant.geometry.dead_volume_n_m3=1.3e-5 \
    --set hal.sim.plant.valve.null_offset_v=0.04 \
    --set sensors.position.noise_std_v=2e-5 --set sensors.position.adc_bits=16 \
    --set sensors.pressure_p.noise_std_v=2e-4 --set sensors.pressure_p.adc_bits=16 \
    --set sensors.pressure_n.noise_std_v=2e-4 --set sensors.pressure_n.adc_bits=16 \
    > "$tmp/serve.out" 2> "$tmp/serve.err" &
  serve_pid=$!
  for _ in $(seq 100); do
    grep -q "listening on 127.0.0.1:$port" "$tmp/serve.out" && return 0
    kill -0 "$serve_pid" 2>/dev/null || break
    sleep 0.1
  done
  cat "$tmp/serve.out" "$tmp/serve.err"; fail "pneu-plant serve did not start on 127.0.0.1:$port"
}
stop_serve() { kill -INT "$serve_pid"; wait "$serve_pid" || fail "pneu-plant serve: $(cat "$tmp/serve.err")"; serve_pid=; }
serve

# robbed NAME: whether step NAME ended on a fault the machine's load makes (samples late over the
# link: comms; the loop late: overrun), not one of the bench's.
robbed() { grep -qE "FAULT at [^:]*: (comms|overrun):" "$tmp/$1.err"; }
# real_step NAME: step NAME on the real clock; a run the load ended by such a fault is run again
# on a fresh plant, up to 3 runs; 3 so robbed: skipped, saying why.
real_step() {
  for run in 1 2 3; do
    step "$1" && return 0
    robbed "$1" || return 1
    echo "run $run of $1: ended by a comms or overrun fault, the machine's load: run again on a fresh plant"
    stop_serve; serve
  done
  echo "SKIPPED: $1: 3 runs, each ended by a comms or overrun fault the machine's load made"; exit 77
}

step check || fail "step 1: pneud --check-config refused the edited bench.yaml"
real_step readings || fail "step 2: the disarmed run"
[ "$(head -1 "$OUT/readings.csv" | cut -d, -f1-4)" = "seq,t,y_d,y" ] || fail "step 2: $OUT/readings.csv has no trajectory header"
real_step movement || fail "step 2: the movement test did not pass"
grep -q "movement test passed" "$tmp/movement.err" || fail "step 2: stderr does not say the movement test passed"
# Steps 3 to 5. An identification the load spoiled (THE MODEL DOES NOT FIT: samples and commands
# late over the link) may give a model on which the verifying sweep shows restarts after the hold
# began: the guide says to identify again, which is done, up to 3 identifications.
for identification in 1 2 3; do
  real_step identify || fail "step 3: the identification"
  [ -f "$OUT/identified.yaml" ] || fail "step 3: no $OUT/identified.yaml"
  # What was identified is the served bench, not the configuration's: stiction within 5 %.
  read -r fs_pos fs_neg window < <("$BIN/pneud" --config "$OUT/identified.yaml" --check-config | /usr/bin/python3 -c '
import sys, yaml
c = yaml.safe_load(sys.stdin)
print(c["plant"]["friction"]["static_positive_n"], c["plant"]["friction"]["static_negative_n"], c["controller"]["hold"]["window_m"])')
  echo "identified: F_S+ $fs_pos N (served 51.75 N), F_S- $fs_neg N (served -57.5 N); the hold's window $window m"
  /usr/bin/python3 -c "import sys; sys.exit(not (abs($fs_pos - 51.75) < 0.05 * 51.75 and abs($fs_neg + 57.5) < 0.05 * 57.5))" \
    || fail "step 3: the identified stiction is not the served bench's"
  step tune || fail "step 4: pneu-plant tune or the stability map"
  grep -q "unstable, continuous: nowhere; sampled: nowhere" "$tmp/tune.out" || fail "step 4: the identified law is not stable everywhere"
  [ -s "$OUT/stability_map.png" ] || fail "step 4: no $OUT/stability_map.png"
  step sweep || fail "step 5: the verifying sweep"
  # What the guide says to look at: the hold on, begun in every scenario that came to rest within
  # the window (those never at rest within it: said, not judged), and its restarts after it began:
  # 0 passes; some, on a model that fits, are reported (the hold's limit on this bench, which the
  # guide states; step 6 judges the bench itself); some on a model that does not fit: identify again.
  rc=0
  /usr/bin/python3 - "$tmp/sweep.out" <<'PY' || rc=$?
import re, sys
out = open(sys.argv[1]).read()
at_rest = re.search(r"at rest within \+-[\d.]+ mm of the set point \(controller.hold.window_m\), from the step \((\d+) of (\d+) run\)", out)
hold = re.search(r"the in-position hold \(on\): began in (\d+) scenarios; restarts after it began \([^)]*\): (\d+), in (\d+) scenarios", out)
outcomes = re.search(r"outcomes \(the first rest after the step\): (\d+) settled, (\d+) never settled, (\d+) at rest against an end stop, (\d+) faults", out)
if not at_rest or not hold or not outcomes:
    sys.exit("the sweep's summary has no outcome, hold or window line")
within, run, began, restarts, scenarios = int(at_rest[1]), int(at_rest[2]), int(hold[1]), int(hold[2]), int(hold[3])
print(f"step 5: {outcomes[0]}; {within} of {run} scenarios at rest within the window, the hold began in {began}, "
      f"{restarts} restarts after it began in {scenarios} scenarios; {run - within} never at rest within the window")
if int(outcomes[1]) != run or began != within or within == 0:
    sys.exit(1)
sys.exit(3 if restarts else 0)
PY
  [ "$rc" -eq 0 ] && break
  [ "$rc" -eq 3 ] || fail "step 5: the sweep on the identified model: not every scenario settled, or the hold did not begin in every scenario at rest within its window"
  if ! grep -q "THE MODEL DOES NOT FIT" "$tmp/identify.out"; then
    echo "NOTE: step 5: restarts after the hold began in the sweep on a model that fits: the hold's limit on this bench (docs/commissioning.md, step 5), reported; step 6 judges the bench"
    break
  fi
  [ "$identification" -lt 3 ] || { echo "SKIPPED: 3 identifications the load spoiled (the model does not fit), the hold restarting in each's sweep"; exit 77; }
  echo "identification $identification: the model does not fit, and on it the hold restarts: identify again"
  rm -f "$OUT/identified.yaml"
done

# Step 6, judged on the plant's own record.
held() {
  /usr/bin/python3 - "$OUT/step.jsonl" "$OUT/step.json" "$OUT/step.csv" "$tmp/plant.jsonl" "$window" <<'EOF'
import csv, json, sys
events, summary, trajectory, plant, window = sys.argv[1:5] + [float(sys.argv[5])]
lines = [json.loads(l) for l in open(events) if l.strip()]
holds = [e for e in lines if e["event"] == "hold_start" and e["reach"] == 0 and e["t"] > 1.0]
if not holds:
    print("never held within the window after the step")
    sys.exit(2)
first, last = holds[0], holds[-1]
after = [e for e in lines if e["t"] > first["t"] and e["event"] in ("start", "hold_end", "hold_start")]
epoch = json.load(open(summary))["loop"]["epoch_monotonic_s"]
breakaways = [json.loads(l) for l in open(plant) if '"event":"breakaway"' in l]
later = [b for b in breakaways if b["monotonic_s"] > epoch + first["t"]]
ended = [e for e in lines if e["t"] > last["t"] and e["event"] == "hold_end"]
rows = list(csv.DictReader(open(trajectory)))
error = abs(last["y"] - last["y_d"])
print(f"held from {first['t']:.3f} s; {len(later)} breakaways of the plant after it (of {len(breakaways)}); held "
      f"last from {last['t']:.3f} s at {last['y'] * 1e3:.3f} mm, {error * 1e3:.3f} mm from the set point "
      f"{last['y_d'] * 1e3:.3f} mm, {len(ended)} ends after it; the last tick's mode {rows[-1]['mode']}")
# pneud's own view after the hold began (a carriage still sliding slowly within the rest band when
# the stop was confirmed moves on without a breakaway: a start to pneud, none of the plant's).
for e in after:
    print("  after the hold began:", json.dumps(e))
if error > window + 1e-9 or ended or rows[-1]["mode"] != "3":
    sys.exit(2)
sys.exit(1 if later or not breakaways else 0)
EOF
}
skipped_deadlines() { /usr/bin/python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["loop"]["deadlines_skipped"])' "$OUT/step.json"; }
for run in 1 2 3; do
  [ "$run" = 1 ] || { stop_serve; serve; }  # a fresh plant, at rest where the step starts
  if ! step step; then
    robbed step || fail "step 6: the step with the hold (run $run)"
    echo "run $run: ended by a comms or overrun fault, the machine's load: run again"
    continue
  fi
  rc=0; held || rc=$?
  if [ "$rc" = 0 ]; then
    echo "ok: the guide's steps end with a held carriage (run $run)"
    exit 0
  fi
  [ "$rc" = 1 ] || fail "step 6: the carriage does not end held within the window (run $run)"
  skipped=$(skipped_deadlines)
  [ "$skipped" -gt 0 ] || fail "step 6: the plant broke away after the hold began (run $run, no deadline skipped)"
  echo "run $run: the plant broke away after the hold began, and the loop skipped $skipped deadlines: the machine's load, run again"
done
echo "SKIPPED: 3 runs of step 6, each robbed by the machine's load (deadlines skipped, or a comms or overrun fault), none ended held"
exit 77
