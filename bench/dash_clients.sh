#!/usr/bin/env bash
# pneu-dash with WebSocket clients beside pneud on the real clock, inside a private network namespace
# (tests/in_private_netns.sh): pneud publishes LCM, pneu-dash serves it on 127.0.0.1, and
# build/bin/dash_client (bench/dash_client.cpp) subscribes to every channel and decodes every
# message frame's JSON. Each repetition runs, one after the other, with the same pneu-dash:
#   A  0 clients          pneud SECONDS s, cyclictest beside it
#   B  8 clients          the same, every state (1 kHz)
#   D  8 clients at 60 Hz the same, each asking the states at most at 60 Hz ("maxRateHz": 60, as a
#                         page on a 60 Hz display would): pneu-dash sends each the newest state at
#                         most every 1/60 s and reports what it skipped; every other message all
#   C  8 clients + 1 that stops reading once subscribed, before pneud starts (and reads again 3 s before it
#      ends, to take the status message in which pneu-dash tells its drops); pneud 2*SECONDS s
# and prints, for each phase: pneud's overruns and wake-up latency median/p99 (--summary-json),
# cyclictest's (the floor, same interval, same time); pneu-dash's CPU time over pneud's run
# (/proc/PID/stat utime+stime) and its resident memory (VmRSS); for B and C the latency from the
# loop's tick to the clients' receipt of its state message (see bench/dash_clients.py for exactly
# what is measured); for C the RSS over time and the drops; for D each client's states received,
# skipped (pneu-dash's report) and lost. Then the medians over the repetitions, and pneu-dash's CPU
# per client, (B - A) / 8 at every state and (D - A) / 8 at 60 Hz, each from the same repetition.
# The loop-timing supervision is off (a stall of a shared machine would latch a fault and change
# what the loop does between phases); nothing else is changed from pneud's defaults.
# Usage: bench/dash_clients.sh [SECONDS] [REPEATS]    (defaults 20 and 3; needs root for the netns)
#   SECONDS of 15 or more: the stopped client's queue (4 MiB) and socket buffers take some 20 s of
#   states to fill; with less, C ends before pneu-dash drops anything for it.
#   PNEU_BENCH_KEEP=1: the run directory is kept (bench/dash_clients.py DIR REPEATS 8 prints it again)
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-20}
reps=${2:-3}
if [ -z "${PNEU_IN_NETNS:-}" ]; then
  PNEU_IN_NETNS=1 exec tests/in_private_netns.sh env PNEU_IN_NETNS=1 "$0" "$@"
fi
command -v cyclictest >/dev/null || { echo "needs cyclictest (apt-get install rt-tests)" >&2; exit 1; }
for b in pneud pneu-dash dash_client; do
  [ -x "build/bin/$b" ] || { echo "needs build/bin/$b (dash_client: PNEU_BUILD_BENCHMARKS=ON, PNEU_WITH_DASH=ON)" >&2; exit 1; }
done
clients=8
port=8765
tmp=$(mktemp -d)
dash=
cleanup() {
  set +e
  [ -n "$dash" ] && kill "$dash" 2>/dev/null
  kill $(jobs -p) 2>/dev/null
  wait 2>/dev/null
  if [ -n "${PNEU_BENCH_KEEP:-}" ]; then echo "run directory kept: $tmp" >&2; else rm -rf "$tmp"; fi
}
trap cleanup EXIT

cpu_ticks() { awk '{print $14 + $15}' "/proc/$1/stat"; }  # utime + stime [clock ticks]
rss_kb() { awk '/^VmRSS/ {print $2}' "/proc/$1/status"; }
# pneu-dash's frames dropped so far, all channels (/metrics, over bash's /dev/tcp: no process to start)
dropped_now() {
  (exec 3<>"/dev/tcp/127.0.0.1/$port" && printf 'GET /metrics HTTP/1.0\r\n\r\n' >&3 && cat <&3) 2>/dev/null |
    awk '/^pneu_dash_messages_dropped_total/ {n += $NF} END {print n + 0}'
}
wait_port() {
  for _ in $(seq 200); do
    (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null && return 0
    sleep 0.05
  done
  echo "nothing listens on 127.0.0.1:$1" >&2
  exit 1
}

# phase DIR NCLIENTS STALLED PNEUD_SECONDS [CLIENT OPTIONS...]
phase() {
  local dir=$1 n=$2 stalled=$3 s=$4 pids=() i
  shift 4
  mkdir -p "$dir"
  for i in $(seq "$n"); do
    build/bin/dash_client $port $((s + 6)) "$dir/client$i.txt" "$@" &
    pids+=($!)
  done
  if [ "$stalled" = 1 ]; then
    build/bin/dash_client $port $((s + 6)) "$dir/stalled.txt" --stop-reading-after 0.5 --resume-s 3 &
    pids+=($!)
  fi
  sleep 1
  (while kill -0 "$dash" 2>/dev/null; do echo "$(date +%s.%N) $(rss_kb "$dash")"; sleep 0.25; done) >"$dir/rss.txt" &
  local sampler=$! dropper=
  if [ "$stalled" = 1 ]; then  # when pneu-dash starts dropping for it: its dropped counter every second
    (while kill -0 "$dash" 2>/dev/null; do echo "$(date +%s.%N) $(dropped_now)"; sleep 1; done) >"$dir/dropped.txt" &
    dropper=$!
  fi
  local c0 c1
  c0=$(cpu_ticks "$dash")
  cyclictest -m --default-system -i 1000 -l $((s * 1000)) -q -h 2000 >"$dir/cyclic.txt" 2>&1 &
  local cyc=$!
  date +%s.%N >"$dir/start.txt"
  build/bin/pneud --clock real --duration "$s" --require-telemetry --summary-json "$dir/summary.json" \
    --set controller.supervisor.overruns_in_a_row=0 --set controller.supervisor.max_tick_interval_s=0 \
    >"$dir/pneud.out" 2>"$dir/pneud.err"
  date +%s.%N >"$dir/end.txt"
  c1=$(cpu_ticks "$dash")
  wait "$cyc"
  [ ${#pids[@]} -gt 0 ] && wait "${pids[@]}"
  kill "$sampler" $dropper 2>/dev/null; wait "$sampler" $dropper 2>/dev/null || true
  /usr/bin/python3 -c "import sys, urllib.request; sys.stdout.write(urllib.request.urlopen(sys.argv[1]).read().decode())" \
    "http://127.0.0.1:$port/metrics" >"$dir/metrics.txt"
  echo "$c0 $c1 $(getconf CLK_TCK)" >"$dir/cpu.txt"
}

for rep in $(seq "$reps"); do
  build/bin/pneu-dash --listen 127.0.0.1:$port >"$tmp/dash$rep.out" 2>"$tmp/dash$rep.err" &
  dash=$!
  wait_port $port
  sleep 1
  phase "$tmp/$rep/A" 0 0 "$secs"
  phase "$tmp/$rep/B" "$clients" 0 "$secs"
  phase "$tmp/$rep/D" "$clients" 0 "$secs" --max-rate-hz 60
  phase "$tmp/$rep/C" "$clients" 1 $((2 * secs))
  kill "$dash"; wait "$dash" || true
  dash=
  echo "repetition $rep of $reps done" >&2
done
/usr/bin/python3 bench/dash_clients.py "$tmp" "$reps" "$clients"
