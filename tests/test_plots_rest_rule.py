#!/usr/bin/env python3
"""tools/plots/pneu_plots.py's check that events belong to a trajectory follows the stop
detector's own rule for when a stop is confirmed (t - t_stop >= hold_s - 1e-9 period) on a real
clock's ticks: a tick 8 ns short of hold_s after the stop does not confirm it, the next one does
(a HIL run under load did exactly that, and the check refused its own events). A rest one tick
later than the rule says is still refused.
Usage: test_plots_rest_rule.py SOURCE_DIR   (exit 77: skipped, saying why)"""
import sys
import types

sys.path.insert(0, sys.argv[1] + "/tools/plots")
try:
    import numpy as np
    import pneu_plots
except ImportError as e:
    print(f"SKIPPED: /usr/bin/python3 cannot import what the plotting tool needs ({e}; Debian packages "
          "python3-numpy, python3-matplotlib, python3-yaml)", file=sys.stderr)
    sys.exit(77)

HOLD_S = 0.005


class Bench:
    def key(self, *path, default=None):
        return HOLD_S if path == ("controller", "stop_detector", "hold_s") else default


def run_with_rest_at(rest_index):
    """Ticks of a real clock (1 ms, jitter of microseconds), a stop at tick 10, the tick 5 ms
    later 8 ns short of it; the trajectory comes to rest at tick `rest_index`."""
    t = 1.0 + np.arange(30) * 1e-3 + np.array([(k * 7919 % 13) * 1e-6 for k in range(30)])
    t[15] = t[10] + HOLD_S - 8e-9
    stuck = np.zeros(30, dtype=bool)
    stuck[rest_index:] = True
    return types.SimpleNamespace(t=t, stuck=stuck, y=np.zeros(30), seq=np.arange(30), end_t=float(t[-1]),
                                 stops=[{"index": 1, "t": float(t[10]), "y": 0.0}])


def verdict(rest_index):
    try:
        pneu_plots.check_events_belong(run_with_rest_at(rest_index), Bench(), "traj.csv", "events.jsonl")
        return "accepted"
    except pneu_plots.InputError as e:
        return f"refused: {e}"


failures = []
if verdict(16) != "accepted":
    failures.append(f"the rest on the first tick at hold_s or more after the stop: {verdict(16)}")
if not verdict(17).startswith("refused") or "comes to rest" not in verdict(17):
    failures.append(f"a rest a tick later than the rule: {verdict(17)}")
if not verdict(15).startswith("refused"):
    failures.append(f"a rest on the tick 8 ns short of hold_s: {verdict(15)}")
for f in failures:
    print("FAIL:", f, file=sys.stderr)
print("the rest rule: the first tick at hold_s or more after the stop accepted; 8 ns short and a tick late refused")
sys.exit(1 if failures else 0)
