#!/usr/bin/env bash
# Wake-up latency of pneud's real-clock loop beside cyclictest's floor, measured at the same time
# on this machine (same interval, same default scheduling policy unless --rt is given).
# Usage: bench/loop_jitter.sh [SECONDS] [--rt]
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-10}
prio=()
[ "${2:-}" = "--rt" ] && prio=(-p 80)
command -v cyclictest >/dev/null || { echo "needs cyclictest (apt-get install rt-tests)" >&2; exit 1; }
loops=$((secs * 1000))
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cyclictest -m --default-system -i 1000 -l "$loops" -q -h 2000 "${prio[@]}" >"$tmp/cyclic.txt" 2>&1 &
cpid=$!
build/bin/pneud --clock real --duration "$secs" --set telemetry.enabled=false >"$tmp/pneud.txt"
wait $cpid
echo "pneud (real clock, ${secs} s at 1 kHz):"
grep -E "overruns|wake-up|compute" "$tmp/pneud.txt"
# cyclictest's histogram: one line per microsecond bucket, "bucket count"; compute percentiles.
awk '/^[0-9]/ {n=$1+0; c=$2+0; if (c>0) {h[n]=c; tot+=c; if (n>mx) mx=n}}
     /# Min Latencies/ {mn=$4+0} /# Max Latencies/ {mxl=$4+0}
     END {
       s=0; p50=-1; p99=-1;
       for (i=0;i<=mx;i++) { s+=h[i]; if (p50<0 && s>=0.5*tot) p50=i; if (p99<0 && s>=0.99*tot) p99=i }
       printf "cyclictest (same interval, same time): %d samples\n  wake-up latency [us]  min %8d  median %8d  p99 %8d  max %8d\n", tot, mn, p50, p99, mxl
     }' "$tmp/cyclic.txt"
