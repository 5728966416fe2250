#!/usr/bin/env bash
# Soak of online learning in simulated time: the default bench (the embedded config/sim.yaml) with
# controller.predictor.learn_online on and a set-point change every 5 s, for HOURS of bench time
# (default 24) on the simulated clock. Samples pneud's resident memory (VmRSS and its peak VmHWM,
# /proc/<pid>/status) at 10 min, every hour and at the end, dated by the bench time of the last
# line pneud wrote to its events file; then checks that the memory at 1 h and at the end lie within
# 5 % of each other and that the counters of --summary-json agree with themselves and with the
# events file (ticks = duration x rate + 1, every tick drained, nothing dropped, one start per stop,
# the stops' forecasts all made).
#
#   bench/soak_online_learning.sh BUILD_DIR [HOURS] [OUT_DIR]
#
# Exit 0 when everything holds, 1 otherwise. The events file (about 15 MB per bench hour) is
# removed at the end unless KEEP_EVENTS=1.
set -euo pipefail

build=${1:?usage: soak_online_learning.sh BUILD_DIR [HOURS] [OUT_DIR]}
hours=${2:-24}
out=${3:-$(mktemp -d /tmp/pneu_soak.XXXXXX)}
mkdir -p "$out"
here=$(cd "$(dirname "$0")" && pwd)
duration=$(/usr/bin/python3 -c "print(int(round($hours * 3600)))")

# The set points: y_i = 0.2 m sin(2.4 i) from t = 5 i s (i = 1, 2, ...): every step a different
# size and direction, within the soft limits (tests/test_pneud_memory.cpp uses the same).
/usr/bin/python3 - "$here/../config/sim.yaml" "$duration" "$out/soak.yaml" <<'EOF'
import math, re, sys
src, duration, dst = sys.argv[1], int(sys.argv[2]), sys.argv[3]
text = open(src).read()
rows = "".join("      - {t_s: %d, position_m: %.6f}\n" % (5 * i, 0.2 * math.sin(2.4 * i))
               for i in range(1, duration // 5 + 1))
new, n = re.subn(r"(\n    schedule:[^\n]*\n)(      - [^\n]*\n)+", lambda m: m.group(1) + rows, text, count=1)
assert n == 1, "config/sim.yaml: no controller.setpoints.schedule to replace"
open(dst, "w").write(new)
EOF

echo "soak: $hours h of bench time ($duration s), set point every 5 s, learning online; in $out"
start=$(date +%s)
/usr/bin/time -v -o "$out/time.txt" "$build/bin/pneud" --config "$out/soak.yaml" --clock simulated \
  --duration "$duration" --set controller.predictor.learn_online=true --events "$out/events.jsonl" \
  --summary-json "$out/summary.json" >"$out/stdout.txt" 2>"$out/stderr.txt" &
timer=$!
# The memory, by bench time (the events file's last line), until pneud ends.
/usr/bin/python3 - "$timer" "$out/events.jsonl" "$duration" "$out/memory.csv" <<'EOF'
import os, re, sys, time
timer, events, duration, csv = int(sys.argv[1]), sys.argv[2], int(sys.argv[3]), sys.argv[4]
pid = None
for _ in range(500):  # pneud is /usr/bin/time's child
    try:
        kids = open(f"/proc/{timer}/task/{timer}/children").read().split()
        if kids: pid = int(kids[0]); break
    except OSError:
        pass
    time.sleep(0.01)
# pneud's events file grows beside its path while the run lasts (renamed into place at the end).
events = f"{events}.partial-{pid}"
# 10 min, every hour, and 30 s before the end (the last lines come just before it).
marks = sorted(set(m for m in [600] + list(range(3600, duration, 3600)) + [duration - 30] if 0 < m <= duration - 30))
t_re = re.compile(rb'"t":([0-9.eE+-]+)')
with open(csv, "w") as f:
    f.write("bench_s,wall_s,vm_rss_kb,vm_hwm_kb\n")
    t0 = time.time()
    while marks and pid:
        try:
            status = open(f"/proc/{pid}/status").read()
        except OSError:
            break  # it ended
        if "VmRSS" not in status: break  # it ended, not reaped yet
        try:  # (none yet while pneud reads its configuration)
            with open(events, "rb") as e:
                e.seek(0, 2); size = e.tell(); e.seek(max(0, size - 8192))
                tail = e.read().split(b"\n")[:-1]
        except OSError:
            tail = []
        t = float(t_re.search(tail[-1]).group(1)) if tail and t_re.search(tail[-1]) else 0.0
        if t >= marks[0]:
            rss = int(re.search(r"VmRSS:\s+(\d+)", status).group(1))
            hwm = int(re.search(r"VmHWM:\s+(\d+)", status).group(1))
            f.write(f"{t:.1f},{time.time() - t0:.1f},{rss},{hwm}\n"); f.flush()
            print(f"  bench {t / 3600:6.2f} h: VmRSS {rss} kB, VmHWM {hwm} kB ({time.time() - t0:.0f} s of wall time)", flush=True)
            while marks and marks[0] <= t: marks.pop(0)
        time.sleep(0.05)
EOF
status=0
wait "$timer" || status=$?
echo "pneud exited $status after $(( $(date +%s) - start )) s of wall time"
grep -E "User time|System time|Maximum resident" "$out/time.txt" | sed 's/^\s*/  /'
grep "online identification" "$out/stdout.txt" | sed 's/^/  /' || true

# The checks.
result=0
/usr/bin/python3 - "$out" "$duration" "$status" <<'EOF' || result=$?
import csv, json, sys
out, duration, status = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
ok = True
def check(holds, what):
    global ok
    print(("  ok    " if holds else "  FAIL  ") + what)
    ok = ok and holds
check(status == 0, f"pneud exited 0 (got {status})")
mem = list(csv.DictReader(open(f"{out}/memory.csv")))
hour = [r for r in mem if float(r["bench_s"]) >= 3600]
if len(hour) >= 2:
    a, b = hour[0], hour[-1]
    for key in ("vm_rss_kb", "vm_hwm_kb"):
        x, y = int(a[key]), int(b[key])
        check(abs(y - x) <= 0.05 * x, f"{key} at {float(a['bench_s']) / 3600:.2f} h {x} kB and at "
              f"{float(b['bench_s']) / 3600:.2f} h {y} kB: within 5 % ({100.0 * (y - x) / x:+.2f} %)")
else:
    check(False, "memory sampled at 1 h and later")
s = json.load(open(f"{out}/summary.json"))
loop, rt = s["loop"], s["runtime"]
rate = loop["rate_hz"]
check(loop["ticks"] == round(duration * rate) + 1, f"loop ticks {loop['ticks']} = duration x rate + 1 = {round(duration * rate) + 1}")
check(rt["ticks_seen"] == loop["ticks"], f"runtime ticks_seen {rt['ticks_seen']} = loop ticks")
check(rt["sequence_gaps"] == 0, f"sequence gaps {rt['sequence_gaps']} = 0")
check(loop["tick_records_dropped"] == 0 and loop["events_dropped"] == 0,
      f"nothing dropped (tick records {loop['tick_records_dropped']}, events {loop['events_dropped']})")
check(loop["overruns"] == 0 and loop["deadlines_skipped"] == 0, "no overrun, no deadline skipped (simulated clock)")
check(s["faults"] == [], f"no fault ({len(s['faults'])})")
counts = {}
starts_after_stop = restarts = 0
stop_ids = set(); start_ids = set(); predicted = set()
for line in open(f"{out}/events.jsonl"):
    e = json.loads(line)
    counts[e["event"]] = counts.get(e["event"], 0) + 1
    if e["event"] == "stop": stop_ids.add(e["stop"])
    elif e["event"] == "start" and e["stop"]:
        start_ids.add(e["stop"]); restarts += e["restart"]
    elif e["event"] == "prediction": predicted.add((e["stop"], e["method"]))
print("  events:", ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
stops = counts.get("stop", 0)
check(rt["stops"] == stops, f"summary stops {rt['stops']} = stop events {stops}")
check(stop_ids == set(range(1, stops + 1)), "the stops numbered 1.. without a gap")
open_stops = stop_ids - start_ids
check(start_ids <= stop_ids and len(open_stops) <= 1,
      f"every stop but the last ended by a start ({len(start_ids)} starts after a stop, {restarts} of them restarts)")
methods = ("linearized", "nonlinear")
check(counts.get("prediction", 0) == len(methods) * stops and all((k, m) in predicted for k in stop_ids for m in methods),
      f"each stop forecast by both methods ({counts.get('prediction', 0)} = 2 x {stops})")
check(rt["stops"] - rt["stops_forgotten"] <= 4096, f"stops kept {rt['stops'] - rt['stops_forgotten']} <= 4096")
print("soak:", "PASS" if ok else "FAIL")
sys.exit(0 if ok else 1)
EOF
[ "${KEEP_EVENTS:-0}" = 1 ] || rm -f "$out/events.jsonl"
exit $result
