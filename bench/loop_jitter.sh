#!/usr/bin/env bash
# Wake-up latency of pneud's real-clock loop beside the floors it is measured against, all running
# at the same time on this machine at the same 1 ms interval:
#   - bare_loop (bench/bare_loop.cpp): a loop that only sleeps to each absolute deadline, with a
#     1 ns timer slack as pneud's loop thread sets; and the same with the default 50 us slack that
#     a thread under normal scheduling has (--slack-ns 0), to show what the slack costs;
#   - cyclictest (rt-tests), which moves more from run to run on this machine.
# Prints each one's figures and pneud's median over the 1 ns bare loop's (target: at most 1.15).
# Usage: bench/loop_jitter.sh [SECONDS] [--rt]
#   --rt: every loop at SCHED_FIFO priority 80 (pneud --require-rt), where the slack plays no part.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-10}
rt=${2:-}
command -v cyclictest >/dev/null || { echo "needs cyclictest (apt-get install rt-tests)" >&2; exit 1; }
[ -x build/bin/bare_loop ] || { echo "needs build/bin/bare_loop (built with PNEU_BUILD_BENCHMARKS=ON)" >&2; exit 1; }
pneud_rt=() cyc_rt=() bare_rt=()
if [ "$rt" = "--rt" ]; then
  pneud_rt=(--set controller.realtime.priority=80 --require-rt)
  cyc_rt=(-p 80)
  bare_rt=(--priority 80)
fi
tmp=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null; wait 2>/dev/null; rm -rf "$tmp"' EXIT
cyclictest -m --default-system -i 1000 -l $((secs * 1000)) -q -h 2000 "${cyc_rt[@]}" >"$tmp/cyclic.txt" 2>&1 &
cyc=$!
build/bin/bare_loop "$secs" --slack-ns 1 "${bare_rt[@]}" >"$tmp/bare1.txt" &
bare1=$!
build/bin/bare_loop "$secs" --slack-ns 0 "${bare_rt[@]}" >"$tmp/bare0.txt" &
bare0=$!
build/bin/pneud --clock real --duration "$secs" --set telemetry.enabled=false "${pneud_rt[@]}" >"$tmp/pneud.txt"
wait $cyc $bare1 $bare0
echo "pneud (real clock, ${secs} s at 1 kHz, timer slack 1 ns):"
grep -E "overruns|wake-up|compute" "$tmp/pneud.txt"
cat "$tmp/bare1.txt" "$tmp/bare0.txt"
# cyclictest's histogram: one line per microsecond bucket, "bucket count"; compute percentiles.
awk '/^[0-9]/ {n=$1+0; c=$2+0; if (c>0) {h[n]=c; tot+=c; if (n>mx) mx=n}}
     /# Min Latencies/ {mn=$4+0} /# Max Latencies/ {mxl=$4+0}
     END {
       s=0; p50=-1; p99=-1;
       for (i=0;i<=mx;i++) { s+=h[i]; if (p50<0 && s>=0.5*tot) p50=i; if (p99<0 && s>=0.99*tot) p99=i }
       printf "cyclictest (same interval, same time): %d samples\n  wake-up latency [us]  min %8d  median %8d  p99 %8d  max %8d\n", tot, mn, p50, p99, mxl
     }' "$tmp/cyclic.txt"
median() { awk '/wake-up latency/ {print $7; exit}' "$1"; }
awk -v p="$(median "$tmp/pneud.txt")" -v b="$(median "$tmp/bare1.txt")" \
  'BEGIN {printf "pneud median / bare loop (1 ns slack) median: %.2f (target: at most 1.15)\n", p / b}'
