#!/usr/bin/env bash
# Overload: pneud's real-clock loop (sim backend, LCM on) with the other core saturated by a busy
# loop and the command channel flooded (garbage and valid commands, as fast as one sender can),
# beside the same run unloaded, each with cyclictest measuring the machine's wake-up floor at the
# same time. Inside a private network namespace (root), so the flood stays in it.
# Usage: bench/overload.sh [SECONDS] [--rt]   (--rt: the loop thread SCHED_FIFO 80 on CPU 0, and
#                                             cyclictest at priority 80 too)
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-20}
rt=${2:-}
[ "$(id -u)" -eq 0 ] || { echo "needs root (a private network namespace for the flood)" >&2; exit 1; }
command -v cyclictest >/dev/null || { echo "needs cyclictest (apt-get install rt-tests)" >&2; exit 1; }
if [ "${INSIDE_NETNS:-}" != 1 ]; then
  exec env INSIDE_NETNS=1 tests/in_private_netns.sh bash "$0" "$@"
fi
tmp=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null; wait 2>/dev/null; rm -rf "$tmp"' EXIT
pneud_rt=()
cyc_rt=()
if [ "$rt" = "--rt" ]; then
  pneud_rt=(--set controller.realtime.priority=80 --set controller.realtime.cpu=0 --set controller.realtime.lock_memory=true --require-rt)
  cyc_rt=(-p 80 -a 0)
fi

run() {  # LABEL LOADED
  local label=$1 loaded=$2 pids=()
  cyclictest -m --default-system -i 1000 -l $((secs * 1000)) -q -h 2000 "${cyc_rt[@]}" >"$tmp/cyc.txt" 2>&1 &
  local cyc=$!
  build/bin/pneud --clock real --duration "$secs" --require-telemetry --set "controller.setpoints.schedule=[]" \
    --set commands.max_rate_hz=1000 --set commands.burst=100 "${pneud_rt[@]}" >"$tmp/pneud.txt" 2>&1 &
  local pneud=$!
  if [ "$loaded" = 1 ]; then
    sleep 0.5
    taskset -c 1 sh -c 'while :; do :; done' & pids+=($!)
    # Garbage on the command channel from a second sender, valid commands from a third.
    /usr/bin/python3 - <<'PY' & pids+=($!)
import socket, time
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 0)
d = b"LC02\0\0\0\1PNEU_COMMAND\0" + b"\1\2\3"
while True:
    for _ in range(1000):
        s.sendto(d, ("239.255.76.67", 7667))
PY
    (while :; do build/bin/pneu-command step 0 >/dev/null 2>&1 || true; done) & pids+=($!)
  fi
  wait "$pneud"
  wait "$cyc" || true
  [ ${#pids[@]} -gt 0 ] && kill "${pids[@]}" 2>/dev/null
  wait 2>/dev/null || true
  echo "== $label (${secs} s at 1 kHz)"
  grep -E "^loop:|wake-up|compute|^telemetry|dropped" "$tmp/pneud.txt" | sed 's/^/  /'
  grep -q "dropped" "$tmp/pneud.txt" || echo "  no tick record or event dropped"
  grep -E "warning" "$tmp/pneud.txt" | sed 's/^/  /' || true
  awk '/^[0-9]/ {n=$1+0; c=$2+0; if (c>0) {h[n]=c; tot+=c; if (n>mx) mx=n}}
       /# Max Latencies/ {mxl=$4+0}
       END {
         s=0; p50=-1; p99=-1; late=0;
         for (i=0;i<=mx;i++) { s+=h[i]; if (p50<0 && s>=0.5*tot) p50=i; if (p99<0 && s>=0.99*tot) p99=i; if (i>=1000) late+=h[i] }
         printf "  cyclictest, same time: median %d us, p99 %d us, max %d us, %d wake-ups later than 1 ms\n", p50, p99, mxl, late
       }' "$tmp/cyc.txt"
}
run "unloaded" 0
run "other core saturated, command channel flooded" 1
