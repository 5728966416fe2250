#!/usr/bin/env bash
# HIL soak: pneu-plant serve and pneud over Modbus TCP on loopback for SECONDS (default 60), with
# cyclictest measuring the machine's wake-up latency floor at the same time, and the time the
# hypervisor stole from each CPU meanwhile (/proc/stat's steal column: 0 on bare metal).
# Usage: bench/hil_soak.sh [SECONDS] [--rt]   (--rt: pneud's loop thread SCHED_FIFO 80 on CPU 0
#                                              with memory locked, cyclictest at priority 80)
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
pneud_rt=()
cyc_rt=()
if [ "${2:-}" = "--rt" ]; then
  pneud_rt=(--set controller.realtime.priority=80 --set controller.realtime.cpu=0 --set controller.realtime.lock_memory=true --require-rt)
  cyc_rt=(-p 80 -a 1)
fi
port=$((20000 + RANDOM % 20000))
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"; kill $(jobs -p) 2>/dev/null || true' EXIT
build/bin/pneu-plant serve --config config/hil.yaml --set hal.modbus.port=$port --duration $((secs + 5)) --quiet \
  >"$tmp/serve.txt" 2>&1 &
sleep 0.5
cyclictest -m --default-system -i 1000 -l $((secs * 1000)) -q -h 20000 "${cyc_rt[@]}" >"$tmp/cyclic.txt" 2>&1 &
grep -E '^cpu[0-9]' /proc/stat >"$tmp/stat0"
build/bin/pneud --config config/hil.yaml --set hal.modbus.port=$port --set telemetry.enabled=false \
  --set controller.duration_s=$secs "${pneud_rt[@]}" >"$tmp/pneud.txt"
grep -E '^cpu[0-9]' /proc/stat >"$tmp/stat1"
wait %2 || true
echo "pneud over Modbus TCP (HIL), ${secs} s at 1 kHz:"
grep -E "^loop:|wake-up|compute|^modbus:|^fault" "$tmp/pneud.txt" | sed 's/^/  /'
awk '/^[0-9]/ {n=$1+0; c=$2+0; if (c>0) {h[n]=c; tot+=c; if (n>mx) mx=n}}
     /# Max Latencies/ {mxl=$4+0}
     END { s=0; p50=-1; p99=-1; over=0;
       for (i=0;i<=mx;i++) { s+=h[i]; if (p50<0 && s>=0.5*tot) p50=i; if (p99<0 && s>=0.99*tot) p99=i; if (i>1000) over+=h[i] }
       printf "cyclictest at the same time: median %d us, p99 %d us, max %d us, %d wake-ups later than 1 ms\n", p50, p99, mxl, over }' "$tmp/cyclic.txt"
hz=$(getconf CLK_TCK)
paste -d' ' "$tmp/stat0" "$tmp/stat1" | awk -v hz="$hz" '{n=NF/2; printf "%s%s %.0f ms", (NR>1 ? ", " : "time stolen by the hypervisor meanwhile: "), $1, ($(n+9)-$9)*1000/hz} END {print ""}'
