#!/usr/bin/env bash
# Telemetry throughput and cost: pneud on the real clock for SECONDS with LCM telemetry on and off,
# inside a private network namespace (tests/in_private_netns.sh), recorded by lcm-logger.
# Reports the states the logger received against the ticks run, the drops, and the CPU time
# telemetry adds per second of running (user + system time of pneud, on minus off).
# Usage: bench/telemetry_throughput.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-10}
if [ -z "${PNEU_IN_NETNS:-}" ]; then
  PNEU_IN_NETNS=1 exec tests/in_private_netns.sh env PNEU_IN_NETNS=1 "$0" "$@"
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cpu() {  # user+system seconds of a command, from /proc via bash's times is not per child: use /usr/bin/time
  /usr/bin/time -f "%U %S" -o "$tmp/time.txt" "$@" >"$tmp/out.txt"
  awk '{print $1 + $2}' "$tmp/time.txt"
}
lcm-logger -q -f --lcm-url='udpm://239.255.76.67:7667?ttl=0' -c 'PNEU_.*' "$tmp/run.lcm" &
logger=$!
sleep 0.5
on=$(cpu build/bin/pneud --clock real --duration "$secs" --require-telemetry)
cp "$tmp/out.txt" "$tmp/on.txt"
sleep 0.5
kill -INT $logger; wait $logger || true
off=$(cpu build/bin/pneud --clock real --duration "$secs" --set telemetry.enabled=false)
build/bin/pneu-log2csv "$tmp/run.lcm" "$tmp/csv" >/dev/null
states=$(($(wc -l <"$tmp/csv/PNEU_STATE.csv") - 1))
ticks=$(sed -n 's/^loop: \([0-9]*\) ticks.*/\1/p' "$tmp/on.txt")
dropped=$(awk -F, 'NR==1{for(i=1;i<=NF;i++) if($i=="telemetry_dropped") c=i} NR>1{d=$c} END{print d+0}' "$tmp/csv/PNEU_HEALTH.csv")
echo "pneud ${secs} s on the real clock at 1 kHz, telemetry to lcm-logger in a private netns:"
echo "  ticks run ${ticks}, states logged ${states}, telemetry_dropped ${dropped} (last health message)"
grep -E "^telemetry:" "$tmp/on.txt" | sed 's/^/  /'
awk -v on="$on" -v off="$off" -v s="$secs" 'BEGIN {
  printf "  CPU time of pneud: %.3f s with telemetry, %.3f s without: telemetry costs %.1f ms of CPU per second of running (%.2f %% of one core)\n",
         on, off, 1000 * (on - off) / s, 100 * (on - off) / s }'
