#!/usr/bin/python3
"""side_by_side: the stops of two pneud runs of the same step, one line each: where the carriage
stopped, the restart forecast at the stop (the nonlinear method's, else the first made) and what
came: a restart, or the in-position hold from then to the end of the run.

    side_by_side.py WITHOUT.jsonl WITH.jsonl   (pneud --events files: without and with the hold)

Exit codes: 0 printed, 2 bad input (a file missing or not pneud's events).
"""

import json
import sys


def stops(path):
    """Each stop of the run, in order: t, y, y_d, forecast (t_restart or None), restart t, held t."""
    try:
        events = [json.loads(line) for line in open(path) if line.strip()]
    except (OSError, ValueError) as e:
        raise SystemExit(f"side_by_side: {path}: {e}") from None
    by_index, end = {}, None
    for e in events:
        kind, i = e.get("event"), e.get("stop")
        if kind == "stop":
            by_index[i] = {"t": e["t"], "y": e["y"], "y_d": e["y_d"], "forecast": None, "method": None,
                           "restart": None, "held": None}
        elif i in by_index and kind == "prediction" and by_index[i]["method"] != "nonlinear":
            by_index[i].update(forecast=e["t_restart"] if e["will_restart"] else None, method=e["method"])
        elif i in by_index and kind == "start" and by_index[i]["restart"] is None:
            by_index[i]["restart"] = e["t"]
        elif i in by_index and kind == "hold_start" and e.get("reach") == 0 and by_index[i]["held"] is None:
            by_index[i]["held"] = e["t"]
        elif kind == "end":
            end = e["t"]
    if end is None:
        raise SystemExit(f"side_by_side: {path}: no end event: not a whole pneud run's --events file")
    return [by_index[i] for i in sorted(by_index)], end


def line(s, end):
    forecast = "none" if s["forecast"] is None else f"at {s['forecast']:.3f} s"
    if s["held"] is not None and s["restart"] is None:
        came = f"held from {s['held']:.3f} s to the end ({end:g} s): no restart"
    elif s["restart"] is not None:
        came = f"restart at {s['restart']:.3f} s, after {s['restart'] - s['t']:.3f} s stuck"
        if s["held"] is not None:
            came += f" (held from {s['held']:.3f} s)"
    else:
        came = f"at rest to the end ({end:g} s)"
    return f"{s['t']:7.3f} s  {s['y'] * 1e3:8.3f} mm   {forecast:<17} {came}"


def main():
    if len(sys.argv) != 3:
        print(__doc__.strip().split("\n\n")[1].strip(), file=sys.stderr)
        return 2
    print("each stop: when, where, the restart forecast at it, and what came")
    print(f"{'':18}{'stop':>9}  {'rest at':>11}   {'forecast':<17} what happened")
    for label, path in (("without the hold", sys.argv[1]), ("with the hold", sys.argv[2])):
        run, end = stops(path)
        for k, s in enumerate(run):
            print(f"{label if k == 0 else '':18}{line(s, end)}")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except SystemExit as e:
        if isinstance(e.code, str):
            print(e.code, file=sys.stderr)
            sys.exit(2)
        raise
