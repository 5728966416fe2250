#!/usr/bin/python3
"""paired_window_times: the time to come to rest within controller.hold.window_m, two sweeps of the
same scenarios side by side (pneu-sweep --scenarios-out, column in_window_after_s), e.g. without
and with the in-position hold.

  paired_window_times.py BASELINE.csv OTHER.csv

Prints, for each file, p50 and p90 over the scenarios that came to rest within the window and
over all scenarios run (those that never did counted as never); then both over the scenarios the
baseline brought into the window (paired: the same scenarios in both). Percentiles interpolate
linearly, as pneu-sweep's do. Exit code 2 on bad input.
"""

import csv
import math
import sys

NEVER = math.inf


def percentile(values, q):
    v = sorted(values)
    if not v:
        return math.nan
    pos = q * (len(v) - 1)
    i = int(pos)
    f = pos - i
    if i + 1 < len(v) and f > 0:
        return NEVER if math.isinf(v[i + 1]) else v[i] * (1 - f) + v[i + 1] * f
    return v[i]


def load(path):
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        sys.exit(f"paired_window_times: {e}")
    if not rows or "in_window_after_s" not in rows[0] or "scenario" not in rows[0]:
        print(f"paired_window_times: {path}: no scenario or in_window_after_s column", file=sys.stderr)
        sys.exit(2)
    return {r["scenario"]: (float(r["in_window_after_s"]) if r["in_window_after_s"] else NEVER)
            for r in rows if r.get("outcome") != "identification_failed"}


def text(v):
    return "never" if math.isinf(v) else f"{v:.3f} s"


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    base, other = (load(p) for p in argv)
    for name, d in zip(argv, (base, other)):
        came = [v for v in d.values() if not math.isinf(v)]
        print(f"{name}: {len(came)} of {len(d)} at rest within the window: p50 {text(percentile(came, 0.5))}, "
              f"p90 {text(percentile(came, 0.9))}; over all {len(d)}: p50 {text(percentile(d.values(), 0.5))}, "
              f"p90 {text(percentile(d.values(), 0.9))}")
    paired = [k for k, v in base.items() if not math.isinf(v) and k in other]
    for name, d in zip(argv, (base, other)):
        v = [d[k] for k in paired]
        print(f"paired on the baseline's {len(paired)}: {name}: p50 {text(percentile(v, 0.5))}, "
              f"p90 {text(percentile(v, 0.9))}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
