#!/usr/bin/env bash
# The paper's two figures rendered from a recorded paper-scenario run (pneud's events and
# trajectory) and from an LCM-style CSV directory is not needed here: the files must exist, be real
# PNG/SVG of a sensible size, and carry what the figures are about.
# Usage: test_plots.sh BUILD_BIN_DIR SOURCE_DIR   (exit 77: skipped, with the reason)
set -euo pipefail
bin=$1
src=$2
py=/usr/bin/python3
if ! "$py" -c "import matplotlib, yaml" 2>/dev/null; then
  echo "SKIPPED: /usr/bin/python3 lacks matplotlib or yaml (Debian packages python3-matplotlib, python3-yaml)" >&2
  exit 77
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$bin/pneud" --set telemetry.enabled=false --quiet --events "$tmp/events.jsonl" --trajectory "$tmp/traj.csv"
"$py" "$src/tools/plots/pneu_plots.py" --trajectory "$tmp/traj.csv" --events "$tmp/events.jsonl" \
  --config "$src/config/sim.yaml" --pneu-plant "$bin/pneu-plant" --out-dir "$tmp/out" --name paper
fail() { echo "FAIL: $*" >&2; exit 1; }
for f in paper_time paper_plane; do
  png="$tmp/out/$f.png"; svg="$tmp/out/$f.svg"
  [ -s "$png" ] || fail "$png missing"
  [ -s "$svg" ] || fail "$svg missing"
  [ "$(head -c 8 "$png" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ] || fail "$png is not a PNG"
  size=$(stat -c %s "$png")
  [ "$size" -gt 20000 ] || fail "$png is only $size bytes"
  # IHDR width and height, big-endian at bytes 16..23.
  read -r w h < <("$py" -c "import struct,sys; d=open(sys.argv[1],'rb').read(24); print(*struct.unpack('>II', d[16:24]))" "$png")
  [ "$w" -ge 600 ] && [ "$h" -ge 400 ] || fail "$png is ${w}x${h}"
  grep -q "<svg" "$svg" || fail "$svg has no <svg>"
done
grep -q "no-restarting area" "$tmp/out/paper_plane.svg" || fail "the plane figure lacks the no-restarting area"
grep -q "null-flow curve" "$tmp/out/paper_plane.svg" || fail "the plane figure lacks the null-flow curve"
grep -q "forecast restart" "$tmp/out/paper_time.svg" || fail "the time figure lacks the forecast restarts"
echo "plots: paper_time and paper_plane, PNG and SVG, ok"
