#!/usr/bin/env bash
# The screenshot of pneu-spy in docs/img/lcm_spy.png: pneud on the real clock (the paper's step,
# then two set points from pneu-command), pneu-spy watching it under Xvfb with each channel's
# decoded view open, all inside a private network namespace (no datagram leaves it).
# Needs root, and xvfb, xdotool and imagemagick (not in scripts/deps: nothing in the tests uses them).
#   tools/spy/screenshot.sh BUILD_DIR OUT.png
set -euo pipefail
build=$(readlink -f "$1"); out=$(readlink -f "$2")
if [ -z "${PNEU_IN_NETNS:-}" ]; then
  exec "$(dirname "$(readlink -f "$0")")/../../tests/in_private_netns.sh" env PNEU_IN_NETNS=1 bash "$0" "$@"
fi
work=$(mktemp -d); trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT
"$build/bin/pneud" --clock real --duration 120 --quiet --set controller.supervisor.overruns_in_a_row=0 \
  --set controller.supervisor.max_tick_interval_s=0 > "$work/pneud.out" 2>&1 &
export DISPLAY=:97
Xvfb :97 -screen 0 1400x900x24 > /dev/null 2>&1 &
sleep 1
"$build/bin/pneu-spy" > "$work/spy.out" 2>&1 &
sleep 6
for y in 0.10 0.12; do "$build/bin/pneu-command" set-point "$y" || true; sleep 0.5; done
# lcm-spy's channel table on top, then each channel's decoded view (a double click on its row;
# there is no window manager, so each view opens at 0,0 and is moved away before the next click).
# The rows, sorted by name: LCM_SELF_TEST (the datagram LCM sends itself when pneu-command starts
# listening for its verdict: text, no type), then our five channels.
main=$(xdotool search --name "^LCM Spy$" | head -1)
xdotool windowsize "$main" 790 140
sleep 0.5
open_view() {  # ROW CHANNEL X Y WIDTH HEIGHT (a busy machine may miss a double click: up to 5 tries)
  local w="" try
  for try in 1 2 3 4 5; do
    xdotool mousemove --window "$main" 60 $((28 + 16 * $1)) click --repeat 2 --delay 60 1
    sleep 1.5
    w=$(xdotool search --name "^$2\$" | head -1 || true)
    [ -n "$w" ] && break
  done
  [ -n "$w" ] || { echo "screenshot.sh: the view of $2 did not open" >&2; exit 1; }
  xdotool windowmove "$w" "$3" "$4" windowsize "$w" "$5" "$6"
  sleep 0.5
}
open_view 1 PNEU_COMMAND 0 700 460 190
open_view 2 PNEU_EVENT 940 510 460 380
open_view 3 PNEU_HEALTH 470 150 460 740
open_view 4 PNEU_PREDICTION 940 0 460 500
open_view 5 PNEU_STATE 0 150 460 540
sleep 20
import -window root "$out"
echo "screenshot: $out"
cat "$work/spy.out"
