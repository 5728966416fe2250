#!/usr/bin/python3
"""pneu_plots: the figures of a pneud run, after Brun et al. 2005 (Fig. 8, 7/10/11 and 13).

Reads either pneud's own output (--trajectory T.csv [--events E.jsonl], the events of the same
run: checked, refused otherwise) or the CSV files that pneu-log2csv converts from an LCM log
(--log-csv DIR), and writes, <name> being the run's configuration, backend, 'held' when the hold
was on, and the date and time of the run (or --name):

  OUT/<name>_time.png/.svg   time traces: set point and position, chamber pressures, control
                             voltage and pressure force, with the stops, the forecast restarts
                             (one marker per method; those of the law that a hold or reach took
                             over before are left out, the reaches' own drawn), the actual
                             restarts, and the holds and reaches from hold_start to hold_end;
  OUT/<name>_plane.png/.svg  the pressure-force plane: x = S_P p_P, y = S_N p_N + S_r p_E [N],
                             with the stop area (Eq. 12), the no-restarting area (Eq. 13), the
                             null-flow curve and the run's trajectory, plus a zoom on the longest
                             sticking phase;
  OUT/<name>_forecast.png/.svg  the longest sticking phase with forecast columns (cf. Fig. 13):
                             measured chamber pressures and pressure force against what the two
                             forecasts made at the stop expected (linearized, Eq. 24/17; nonlinear,
                             Eq. 19 integrated), their difference, the stiction bounds, the forecast
                             and actual restarts, and the restart time forecast again while stuck
                             (reforecast events). Only from pneud's output with the forecast
                             columns: older trajectories and --log-csv input (the LCM STATE channel
                             carries no forecast) skip it with a note on stderr.

Each title names the run: the YAML it started from, its backend and clock, the hold, the date
(of the trajectory file; of the first STATE row in an LCM log). Geometry and friction come from
the run's own configuration: the effective configuration pneud wrote beside its output
(T.csv.config.yaml, E.jsonl.config.yaml: --set applied), or else, for a run that recorded none,
--config, or else config/sim.yaml of the source tree; the null-flow curve from --null-flow
CURVE.csv or, without it, from running `pneu-plant null-flow` on the same configuration. Exit
codes: 0 written, 2 bad input (missing file, missing column, malformed value, events of another
run), 1 anything else.
"""

import argparse
import csv
import io
import itertools
import json
import math
import os
import re
import shutil
import subprocess
import sys
import textwrap
import tempfile
from datetime import datetime, timezone

EXIT_BAD_INPUT = 2


class InputError(Exception):
    """Bad user input: reported on stderr with exit code 2."""


# --------------------------------------------------------------------------------------------
# Reading


def _require_file(path, what):
    if not os.path.isfile(path):
        raise InputError(f"{what}: no such file: {path}")


def _parse_float(text, path, line, column):
    text = text.strip()
    if text == "" or text.lower() in ("nan", "null", "none"):
        return math.nan
    if text.lower() == "true":
        return 1.0
    if text.lower() == "false":
        return 0.0
    try:
        return float(text)
    except ValueError:
        raise InputError(f"{path}:{line}: column '{column}': not a number: '{text}'") from None


def _parse_bool(text, path, line, column):
    t = text.strip().lower()
    if t in ("1", "true", "yes"):
        return True
    if t in ("0", "false", "no", ""):
        return False
    raise InputError(f"{path}:{line}: column '{column}': not a boolean: '{text}'")


def read_csv_columns(path, numeric, text=(), what="CSV", optional=(), older_spellings=None):
    """Returns {column: list} for the numeric columns (floats) and text columns (str), and for
    the optional numeric columns the file has (absent from the result otherwise). A header
    column named as older_spellings says is read under its name of today."""
    _require_file(path, what)
    with open(path, newline="", encoding="utf-8") as f:
        # comment lines may precede the header (pneu-plant's tables); quoted cells after it may
        # span lines (pneu-log2csv's event text), so only leading comments are skipped
        rows = itertools.dropwhile(lambda line: line.startswith("#"), f)
        reader = csv.reader(rows)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise InputError(f"{path}: empty file (no header)") from None
        if older_spellings:
            header = [older_spellings.get(h, h) for h in header]
        missing = [c for c in list(numeric) + list(text) if c not in header]
        if missing:
            raise InputError(f"{path}: missing column(s) {', '.join(missing)} "
                             f"(header has: {', '.join(header)})")
        numeric = list(numeric) + [c for c in optional if c in header]
        index = {c: header.index(c) for c in numeric + list(text)}
        out = {c: [] for c in index}
        for n, row in enumerate(reader, start=2):
            if not row:
                continue
            if len(row) < len(header):
                raise InputError(f"{path}:{n}: {len(row)} fields, the header has {len(header)}")
            for c in numeric:
                out[c].append(_parse_float(row[index[c]], path, n, c))
            for c in text:
                out[c].append(row[index[c]].strip())
    return out


class Run:
    """One run: per-tick arrays (SI) and its events."""

    def __init__(self):
        self.t = self.y_d = self.y = self.p_p = self.p_n = self.force = self.u = self.stuck = None
        self.stops = []        # dicts: index, t, y, force
        self.starts = []       # dicts: index, t, y, restart, direction
        self.predictions = []  # dicts: stop, t, t_stop, method, will_restart, direction,
        #                               t_restart (None), u_star, p_p_e/p_n_e (None if unknown)
        self.reforecasts = []  # the same made again while stuck, plus update (1, 2, ...)
        self.held = None       # per tick: the in-position hold drove the valves (mode hold); None
        #                        when the input has no mode
        self.holds = []        # dicts: t, stop, reach (0: holding within the window, +-1:
        #                        reaching), end (the hold_end's time; None: held to the end)
        self.hold_ends = []    # the hold_end events' times
        self.end_t = None      # the end event's time, if the events have one
        self.date = None       # when the run was made (UTC datetime), None if unknown
        self.forecast = None   # {method: {"p_p", "p_n", "force": per-tick arrays, NaN where
        #                        no forecast is followed}}, None when the input has no such columns
        self.source = ""
        self.seq = None        # the trajectory's tick numbers, None when it has none


MODE_HOLD = 3  # the trajectory's and state_t's mode while the in-position hold drives the valves

# The trajectory's forecast columns: what the forecast made at the stop expects at each tick.
FORECAST_COLUMNS = {m: tuple(f"{c}_{m}" for c in ("p_p", "p_n", "force"))
                    for m in ("linearized", "nonlinear")}
# The trajectory's columns as pneud wrote them before they were spelled as state_t's fields.
OLDER_TRAJECTORY_SPELLINGS = {old: new for m in ("", "_linearized", "_nonlinear")
                              for old, new in (("p_P" + m, "p_p" + m), ("p_N" + m, "p_n" + m),
                                               ("F" + m, "force" + m))}


def _prediction(ev, update=0):
    """A prediction or reforecast record from an event (pneud) or a PREDICTION row (LCM)."""
    return {"stop": ev.get("stop", 0), "t": ev.get("t", ev["t_stop"]), "t_stop": ev["t_stop"],
            "update": update, "method": ev["method"], "will_restart": bool(ev["will_restart"]),
            "direction": ev.get("direction", 0), "t_restart": ev["t_restart"],
            "u_star": ev.get("u_star"), "p_p_e": ev.get("p_p_e"), "p_n_e": ev.get("p_n_e"),
            "tau_p": ev.get("tau_p"), "tau_n": ev.get("tau_n"), "force": ev.get("force"),
            "stop_forecast_force": ev.get("stop_forecast_force")}


def load_pneud_output(trajectory_path, events_path):
    import numpy as np

    forecast_cols = [c for cs in FORECAST_COLUMNS.values() for c in cs]
    cols = read_csv_columns(trajectory_path, ["t", "y_d", "y", "p_p", "p_n", "force", "u", "stuck"],
                            what="--trajectory", optional=forecast_cols + ["mode", "seq"],
                            older_spellings=OLDER_TRAJECTORY_SPELLINGS)
    run = Run()
    run.t, run.y_d, run.y = (np.array(cols[c]) for c in ("t", "y_d", "y"))
    run.p_p, run.p_n, run.force, run.u = (np.array(cols[c]) for c in ("p_p", "p_n", "force", "u"))
    run.stuck = np.array(cols["stuck"]) > 0.5
    if "mode" in cols:
        run.held = np.array(cols["mode"]) == MODE_HOLD
    if "seq" in cols:
        run.seq = np.array(cols["seq"])
    missing = [c for c in forecast_cols if c not in cols]
    if len(missing) < len(forecast_cols):  # older pneud writes none of them
        if missing:
            raise InputError(f"{trajectory_path}: missing column(s) {', '.join(missing)} "
                             f"(the forecast columns come all together)")
        run.forecast = {m: {k: np.array(cols[c]) for k, c in zip(("p_p", "p_n", "force"), cs)}
                        for m, cs in FORECAST_COLUMNS.items()}
    run.source = os.path.basename(trajectory_path)
    run.date = datetime.fromtimestamp(os.stat(trajectory_path).st_mtime, timezone.utc)
    if events_path:
        _load_events(run, events_path)
        run.source += " + " + os.path.basename(events_path)
    _pair_holds(run)
    return run


def _load_events(run, events_path):
    """pneud's --events file into run: stops, starts, holds, the end, forecasts."""
    _require_file(events_path, "--events")
    with open(events_path, encoding="utf-8") as f:
        for n, line in enumerate(f, start=1):
            if not line.strip():
                continue
            try:
                ev = json.loads(line)
            except json.JSONDecodeError as e:
                raise InputError(f"{events_path}:{n}: not JSON: {e}") from None
            kind = ev.get("event")

            def need(*keys, ev=ev, n=n, kind=kind):
                for k in keys:
                    if k not in ev:
                        raise InputError(f"{events_path}:{n}: '{kind}' event without '{k}'")

            if kind == "stop":
                need("t", "y", "force")
                run.stops.append({"index": ev.get("stop", len(run.stops) + 1), "t": ev["t"],
                                  "y": ev["y"], "force": ev["force"]})
            elif kind == "start":
                need("t", "restart", "y")
                run.starts.append({"index": ev.get("stop", 0), "t": ev["t"], "y": ev["y"],
                                   "restart": bool(ev["restart"]),
                                   "direction": ev.get("direction", 0)})
            elif kind == "hold_start":
                need("t")
                run.holds.append({"t": ev["t"], "stop": ev.get("stop", 0),
                                  "reach": ev.get("reach", 0), "end": None})
            elif kind == "hold_end":
                need("t")
                run.hold_ends.append(ev["t"])
            elif kind == "end":
                need("t")
                run.end_t = ev["t"]
            elif kind == "prediction":  # the forecast made at the stop
                need("t_stop", "method", "will_restart", "t_restart")
                run.predictions.append(_prediction(ev))
            elif kind == "reforecast":  # the same made again while stuck (live predictor)
                need("t", "t_stop", "update", "method", "will_restart", "t_restart")
                run.reforecasts.append(_prediction(ev, update=ev["update"]))


def _pair_holds(run):
    """Each hold's end: the first hold_end after it (None: held to the end of the record)."""
    ends = sorted(run.hold_ends)
    for h in sorted(run.holds, key=lambda h: h["t"]):
        h["end"] = next((e for e in ends if e >= h["t"]), None)
        if h["end"] is not None:
            ends.remove(h["end"])


def load_log_csv(directory, prefix):
    import numpy as np

    if not os.path.isdir(directory):
        raise InputError(f"--log-csv: no such directory: {directory}")
    state = read_csv_columns(os.path.join(directory, prefix + "STATE.csv"),
                             ["t", "y_d", "y", "p_p", "p_n", "force", "u", "stuck"],
                             what=f"--log-csv ({prefix}STATE.csv)", optional=["mode", "utime"])
    event_path = os.path.join(directory, prefix + "EVENT.csv")
    if os.path.isfile(event_path):
        events = read_csv_columns(event_path, ["t", "stop", "y", "force", "direction"],
                                  ["kind_name"], what=f"--log-csv ({prefix}EVENT.csv)")
    else:
        print(f"pneu_plots: note: no {event_path}: no stops, restarts or holds drawn",
              file=sys.stderr)
        events = {"kind_name": []}
    pred_path = os.path.join(directory, prefix + "PREDICTION.csv")
    run = Run()
    order = np.argsort(np.array(state["t"]), kind="stable")
    run.t, run.y_d, run.y = (np.array(state[c])[order] for c in ("t", "y_d", "y"))
    run.p_p, run.p_n, run.force, run.u = (np.array(state[c])[order]
                                          for c in ("p_p", "p_n", "force", "u"))
    run.stuck = np.array(state["stuck"])[order] > 0.5
    if "mode" in state:
        run.held = np.array(state["mode"])[order] == MODE_HOLD
    if "utime" in state and state["utime"] and math.isfinite(state["utime"][0]):
        run.date = datetime.fromtimestamp(min(state["utime"]) / 1e6, timezone.utc)
    for i, kind in enumerate(events["kind_name"]):
        if kind == "stop":
            run.stops.append({"index": int(events["stop"][i]), "t": events["t"][i],
                              "y": events["y"][i], "force": events["force"][i]})
        elif kind == "hold_start":
            run.holds.append({"t": events["t"][i], "stop": int(events["stop"][i]),
                              "reach": events["direction"][i], "end": None})
        elif kind == "hold_end":
            run.hold_ends.append(events["t"][i])
        elif kind == "end":
            run.end_t = events["t"][i]
        elif kind in ("start", "restart"):
            run.starts.append({"index": int(events["stop"][i]), "t": events["t"][i],
                               "y": events["y"][i], "restart": kind == "restart",
                               "direction": events["direction"][i]})
    if os.path.isfile(pred_path):
        pred = read_csv_columns(pred_path, ["t", "stop", "t_stop", "direction", "t_restart",
                                            "u_star", "p_p_equilibrium", "p_n_equilibrium",
                                            "tau_p", "tau_n"],
                                ["method_name", "will_restart"],
                                what=f"--log-csv ({prefix}PREDICTION.csv)",
                                optional=["update", "force", "stop_forecast_force"])
        rows = len(pred["method_name"])
        forces = pred.get("force", [None] * rows)
        stop_forecast_forces = pred.get("stop_forecast_force", [None] * rows)
        for i, method in enumerate(pred["method_name"]):
            t_restart = pred["t_restart"][i]
            # update 0 (or no such column: older logs) is the forecast made at the stop; the
            # others are the live predictor's re-forecasts
            update = pred["update"][i] if "update" in pred else 0.0
            update = 0 if math.isnan(update) else int(update)
            record = _prediction({
                "stop": int(pred["stop"][i]), "t": pred["t"][i], "t_stop": pred["t_stop"][i],
                "method": method,
                "will_restart": _parse_bool(pred["will_restart"][i], pred_path, i + 2,
                                            "will_restart"),
                "direction": pred["direction"][i],
                "t_restart": None if math.isnan(t_restart) else t_restart,
                "u_star": pred["u_star"][i], "p_p_e": pred["p_p_equilibrium"][i],
                "p_n_e": pred["p_n_equilibrium"][i], "tau_p": pred["tau_p"][i],
                "tau_n": pred["tau_n"][i], "force": forces[i],
                "stop_forecast_force": stop_forecast_forces[i]}, update=update)
            (run.reforecasts if update > 0 else run.predictions).append(record)
    else:
        print(f"pneu_plots: note: no {pred_path}: no forecasts drawn", file=sys.stderr)
    run.source = os.path.basename(os.path.normpath(directory)) + "/" + prefix + "*.csv"
    _pair_holds(run)
    return run


def restrict_to_time_range(run, t0, t1):
    keep = (run.t >= t0) & (run.t <= t1)
    for name in ("t", "y_d", "y", "p_p", "p_n", "force", "u", "stuck"):
        setattr(run, name, getattr(run, name)[keep])
    if run.held is not None:
        run.held = run.held[keep]
    run.holds = [h for h in run.holds  # those that overlap the range
                 if h["t"] <= t1 and (h["end"] is None or h["end"] >= t0)]
    if run.forecast:
        run.forecast = {m: {k: v[keep] for k, v in cols.items()}
                        for m, cols in run.forecast.items()}
    run.stops = [s for s in run.stops if t0 <= s["t"] <= t1]
    run.starts = [s for s in run.starts if t0 <= s["t"] <= t1]
    run.predictions = [p for p in run.predictions if t0 <= p["t_stop"] <= t1]
    run.reforecasts = [p for p in run.reforecasts
                       if t0 <= p["t_stop"] <= t1 and t0 <= p["t"] <= t1]


class Bench:
    """Areas [m^2], exhaust pressure [Pa] and dry friction [N] of the configuration."""

    def __init__(self, config_path):
        try:
            import yaml
        except ImportError:
            raise InputError("PyYAML is missing (Debian package python3-yaml)") from None
        _require_file(config_path, "--config")
        try:
            with open(config_path, encoding="utf-8") as f:
                cfg = yaml.safe_load(f)
        except yaml.YAMLError as e:
            raise InputError(f"{config_path}: not valid YAML: {e}") from None

        def get(*keys):
            node = cfg
            for k in keys:
                if not isinstance(node, dict) or k not in node:
                    raise InputError(f"{config_path}: missing key {'.'.join(keys)}")
                node = node[k]
            try:
                return float(node)
            except (TypeError, ValueError):
                raise InputError(f"{config_path}: {'.'.join(keys)}: not a number: {node!r}") from None

        bore = get("plant", "geometry", "bore_diameter_m")
        rod = get("plant", "geometry", "rod_diameter_m")
        self.area_p = math.pi / 4 * bore ** 2
        self.area_rod = math.pi / 4 * rod ** 2
        self.area_n = self.area_p - self.area_rod
        self.p_e = get("plant", "gas", "exhaust_pressure_pa")
        self.fs_pos = get("plant", "friction", "static_positive_n")
        self.fc_pos = get("plant", "friction", "coulomb_positive_n")
        self.fs_neg = get("plant", "friction", "static_negative_n")
        self.fc_neg = get("plant", "friction", "coulomb_negative_n")
        self.path = config_path
        self.cfg = cfg
        with open(config_path, encoding="utf-8") as f:
            self.header = f.readline()

    def key(self, *keys, default=None):
        """A value of the configuration by its dotted path, default where it is absent."""
        node = self.cfg
        for k in keys:
            if not isinstance(node, dict) or k not in node:
                return default
            node = node[k]
        return node

    def plane(self, p_p, p_n):
        """Eq. 14 split in two: x = S_P p_P, y = S_N p_N + S_r p_E [N]."""
        return self.area_p * p_p, self.area_n * p_n + self.area_rod * self.p_e


class RunIdentity:
    """What names a run in the figures' titles and file names: the configuration it started
    from, its backend and clock, whether it held, when it was made, its files."""

    def __init__(self, run, bench, origin):
        # pneud's effective configuration says on its first line which YAML the run started from
        m = re.search(r"what its loop ran with \((.*), --set applied", bench.header) \
            if origin == "run" else None
        if m:
            start = m.group(1)
            self.config = ("sim.yaml (embedded)" if start == "the embedded sim.yaml"
                           else os.path.basename(start))
        else:
            self.config = os.path.basename(bench.path) + {
                "run": "", "config": " (--config: the run recorded none)",
                "default": " (assumed: the run recorded no configuration)"}[origin]
        self.config_stem = re.sub(r"\.ya?ml\b.*", "", self.config) or "run"
        self.backend = str(bench.key("hal", "backend", default="sim"))
        self.clock = str(bench.key("controller", "clock", default="simulated"))
        self.hold = bench.key("controller", "hold", "enabled", default=False) is True
        self.window_m = bench.key("controller", "hold", "window_m")
        self.reach_m = bench.key("controller", "hold", "reach_m")
        self.date = run.date
        self.source = run.source

    def hold_text(self):
        if not self.hold:
            return "hold off"
        parts = [f"{k} {float(v) * 1e3:g} mm" for k, v in (("window", self.window_m),
                                                             ("reach", self.reach_m))
                 if v is not None and float(v) > 0]
        return "hold on" + (f" ({', '.join(parts)})" if parts else "")

    def label(self):
        """One title line: configuration, backend, clock, hold, date."""
        when = f", run of {self.date:%Y-%m-%d %H:%M} UTC" if self.date else ""
        return (f"{self.config} on the {self.backend} backend, {self.clock} clock, "
                f"{self.hold_text()}{when}")

    def stem(self):
        """The default file stem: configuration, backend, held or not, date and time."""
        parts = [self.config_stem, self.backend] + (["held"] if self.hold else [])
        if self.date:
            parts.append(f"{self.date:%Y%m%d-%H%M%S}")
        return re.sub(r"[^A-Za-z0-9._-]+", "-", "_".join(parts))


def check_events_belong(run, bench, trajectory_path, events_path):
    """Refuses events that another run wrote: the two files' effective configurations must be
    the same; each stop must fall on one of the trajectory's ticks, where it reads the stop's
    position and comes to rest when the stop is confirmed; the end on its last tick."""
    import numpy as np
    if len(run.t) < 2:
        return
    period = float(np.median(np.diff(run.t)))
    where = f"--events {events_path} does not belong to --trajectory {trajectory_path}"
    ca, cb = effective_config_beside(trajectory_path), effective_config_beside(events_path)
    if ca and cb:
        with open(ca, encoding="utf-8") as fa, open(cb, encoding="utf-8") as fb:
            if fa.read() != fb.read():
                raise InputError(f"{where}: their effective configurations differ "
                                 f"({ca} and {cb}): two runs")
    if run.end_t is not None and abs(run.end_t - float(run.t[-1])) > 1.5 * period:
        raise InputError(f"{where}: the events end at t = {run.end_t:.4f} s, the trajectory at "
                         f"t = {float(run.t[-1]):.4f} s")
    # the trajectory's stuck flag rises where the detector confirms a stop, hold_s after it
    confirm_s = float(bench.key("controller", "stop_detector", "hold_s", default=0.0) or 0.0)
    rises = run.t[1:][run.stuck[1:] & ~run.stuck[:-1]]
    confirmed = [s for s in run.stops if s["t"] + confirm_s <= float(run.t[-1])]
    if len(rises) != len(confirmed):
        raise InputError(f"{where}: the trajectory comes to rest {len(rises)} times after its "
                         f"first tick, the events have {len(confirmed)} stops")
    def rows_lost(t_a, t_b):
        """Whether the trajectory lost rows between t_a and t_b (pneud counts ticks_dropped)."""
        if run.seq is None:
            return False
        i, j = np.searchsorted(run.t, [t_a, t_b])
        return bool(np.any(np.diff(run.seq[max(i - 1, 0):j + 1]) > 1))

    # The detector confirms on the first tick hold_s or more after the stop's tick, by its own
    # rule (t - t_stop >= hold_s - 1e-9 period: a real clock's tick 8 ns short of hold_s does not
    # confirm). The files hold times to the nanosecond: a tick within 2 ns of that boundary may
    # have fallen on either side of it.
    rounding_s = 2e-9
    for s, rise in zip(sorted(confirmed, key=lambda s: s["t"]), rises):
        anchor = float(run.t[int(np.argmin(np.abs(run.t - s["t"])))])
        i = int(np.searchsorted(run.t, anchor + confirm_s - 1e-9 * period - rounding_s))
        confirming = [float(run.t[i])] if i < len(run.t) else []
        if confirming and confirming[0] - anchor < confirm_s + rounding_s and i + 1 < len(run.t):
            confirming.append(float(run.t[i + 1]))
        if all(abs(float(rise) - c) > 1e-7 for c in confirming) and not rows_lost(s["t"], float(rise)):
            raise InputError(f"{where}: stop {s['index']} at t = {s['t']:.4f} s, the trajectory "
                             f"comes to rest at t = {float(rise):.4f} s (stop_detector.hold_s = "
                             f"{confirm_s:g} s)")
    for s in run.stops:
        i = int(np.argmin(np.abs(run.t - s["t"])))
        if abs(float(run.t[i]) - s["t"]) > 0.5 * period and not rows_lost(s["t"], s["t"]):
            raise InputError(f"{where}: stop {s['index']} at t = {s['t']:.4f} s falls on no "
                             f"tick of the trajectory (t = {float(run.t[0]):.4f} to "
                             f"{float(run.t[-1]):.4f} s)")
        if abs(float(run.y[i]) - s["y"]) > STOP_POSITION_TOLERANCE_M:
            raise InputError(f"{where}: stop {s['index']} at t = {s['t']:.4f} s is at "
                             f"y = {s['y'] * 1e3:.3f} mm, the trajectory reads "
                             f"{float(run.y[i]) * 1e3:.3f} mm there")


# A stop's position (the rest position the detector reports) and the trajectory's reading at the
# stop's tick: equal on the simulated bench, within the sensor's noise and steps on a real one.
STOP_POSITION_TOLERANCE_M = 1e-4


def find_pneu_plant(explicit):
    if explicit:
        if not (os.path.isfile(explicit) and os.access(explicit, os.X_OK)):
            raise InputError(f"--pneu-plant: not an executable file: {explicit}")
        return explicit
    here = os.path.dirname(os.path.realpath(__file__))
    candidates = [os.path.join(here, "pneu-plant"), shutil.which("pneu-plant"),
                  os.path.join(here, "..", "..", "build", "bin", "pneu-plant")]
    for c in candidates:
        if c and os.path.isfile(c) and os.access(c, os.X_OK):
            return os.path.normpath(c)
    raise InputError("pneu-plant not found (looked next to this script, on PATH and in "
                     "build/bin of the source tree): pass --pneu-plant PATH or --null-flow CURVE.csv")


def null_flow_curve(args, config_path):
    cols = ["u_v", "p_null_p_pa", "p_null_n_pa", "x_n", "y_n"]
    if args.null_flow:
        return read_csv_columns(args.null_flow, cols, what="--null-flow")
    plant = find_pneu_plant(args.pneu_plant)
    with tempfile.TemporaryDirectory(prefix="pneu_plots.") as tmp:
        out = os.path.join(tmp, "null_flow.csv")
        cmd = [plant, "null-flow", "--config", config_path, "--out", out,
               "--voltage-step-v", "0.002"]
        r = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if r.returncode != 0:
            raise InputError(f"'{' '.join(cmd)}' failed (exit {r.returncode}): "
                             f"{r.stderr.strip() or r.stdout.strip()}")
        return read_csv_columns(out, cols, what="pneu-plant null-flow output")


def effective_config_beside(*outputs):
    """The effective configuration pneud wrote beside one of its outputs, if any."""
    for path in outputs:
        if path and os.path.isfile(path + ".config.yaml"):
            return path + ".config.yaml"
    return None


def run_configuration(args):
    """(Bench, where it came from: 'run', 'config' or 'default'): the effective configuration
    pneud wrote beside the run's output when there is one (--set applied), else --config, else
    sim.yaml."""
    own = effective_config_beside(args.trajectory, args.events)
    if own:
        if args.config:
            print(f"pneu_plots: note: drawing the run's own effective configuration {own}, "
                  f"not --config {args.config}", file=sys.stderr)
        return Bench(own), "run"
    if args.config:
        return Bench(args.config), "config"
    return Bench(default_config()), "default"


def default_config():
    here = os.path.dirname(os.path.realpath(__file__))
    for c in (os.path.join(here, "..", "..", "config", "sim.yaml"),  # the source tree
              os.path.join(here, "..", "etc", "pneu", "sim.yaml"),    # installed in a prefix
              "/etc/pneu/sim.yaml"):
        if os.path.isfile(c):
            return os.path.normpath(c)
    raise InputError("no configuration: pass --config FILE (the run's YAML configuration)")


# --------------------------------------------------------------------------------------------
# Figures

METHOD_STYLE = {  # forecast markers, one per method
    "linearized": {"marker": "v", "color": "#e66100", "label": "forecast restart, linearized (Eq. 17/25)"},
    "nonlinear": {"marker": "D", "color": "#1a9641", "label": "forecast restart, nonlinear (Eq. 19)"},
    "held": {"marker": "P", "color": "#008080",
             "label": "forecast breakaway under the hold's commands (a reach)"},
}
C_HELD = "#00897b"  # the trajectory while the in-position hold drives the valves
HOLD_LABELS = {"hold": "hold began (at rest within the window)",
               "reach": "reach began (at rest outside the window: the force ramped towards "
                        "the set point)"}
HOLD_SHORT_LABELS = {"hold": "hold began (within the window)",
                     "reach": "reach began (outside the window)"}
OTHER_METHOD = {"marker": "s", "color": "#7b3294"}
C_Y, C_YD = "#1f4e9c", "#555555"
C_PP, C_PN = "#c0392b", "#2471a3"
C_U, C_F = "#6c3483", "#117a65"
C_STOP, C_RESTART = "black", "#d7191c"
C_STUCK_SPAN = "#f4d03f"


def _setup_matplotlib():
    try:
        import matplotlib
    except ImportError:
        raise InputError("matplotlib is missing (Debian package python3-matplotlib)") from None
    matplotlib.use("Agg")
    matplotlib.rcParams.update({
        "svg.hashsalt": "pneu_plots",  # deterministic SVG ids
        "svg.fonttype": "none",        # text stays text (searchable, smaller)
        "font.size": 9.5,
        "axes.titlesize": 10.5,
        "legend.fontsize": 8.2,
        "axes.grid": True,
        "grid.alpha": 0.3,
        "path.simplify": True,
    })
    import matplotlib.pyplot as plt
    return plt


def _method_style(method):
    return METHOD_STYLE.get(method, dict(OTHER_METHOD, label=f"forecast restart, {method}"))


def sticking_phases(run):
    """(stop dict, end time, ended by a restart start event or None) for each stop."""
    phases = []
    for s in run.stops:
        later = [st for st in run.starts if st["t"] > s["t"]]
        nxt = min(later, key=lambda st: st["t"]) if later else None
        end = nxt["t"] if nxt else float(run.t[-1])
        phases.append((s, end, nxt if nxt and nxt["restart"] else None))
    return phases


def law_forecasts(run):
    """The restarts forecast at the stops that still applied, and those superseded: a forecast is
    made under the law's commands; once a hold or reach of its stop began before the forecast
    time, the hold's commands replaced the law's and the forecast no longer says anything."""
    shown, superseded = [], []
    for p in run.predictions:
        if p["will_restart"] and p["t_restart"] is not None:
            took_over = any(h["stop"] == p["stop"] and h["t"] <= p["t_restart"] for h in run.holds)
            (superseded if took_over else shown).append(p)
    return shown, superseded


def reach_forecasts(run):
    """Per stop with a reach, the breakaway forecast under the hold's commands made when the
    reach began (its first 'held' re-forecast)."""
    first = {}
    for r in run.reforecasts:
        if r["method"] == "held" and r["will_restart"] and r["t_restart"] is not None:
            if r["stop"] not in first or r["update"] < first[r["stop"]]["update"]:
                first[r["stop"]] = r
    return [first[k] for k in sorted(first)]


def drawn_forecasts(run):
    """The forecast restarts a figure marks: the law's that still applied, the reaches'."""
    return law_forecasts(run)[0] + reach_forecasts(run)


def holds_summary(run):
    """One line on the holds and reaches and the forecasts they superseded, or ''."""
    if not run.holds:
        return ""
    held = [h for h in run.holds if h["reach"] == 0]
    to_end = sum(1 for h in held if h["end"] is None)
    reaches = len(run.holds) - len(held)
    superseded = len(law_forecasts(run)[1])
    parts = [f"{len(held)} hold{'s' if len(held) != 1 else ''} ({to_end} held to the end)"]
    if reaches:
        parts.append(f"{reaches} reach{'es' if reaches != 1 else ''}")
    text = ", ".join(parts)
    if superseded:
        text += (f"; {superseded} forecast restart{'s' if superseded != 1 else ''} superseded "
                 "by a hold or reach, not drawn")
    return text


def _index_ranges(indices):
    """1, 2, 3, 5 -> '1-3, 5'."""
    out, run_start, prev = [], None, None
    for i in list(indices) + [None]:
        if run_start is not None and (i is None or i != prev + 1):
            out.append(str(run_start) if prev == run_start else f"{run_start}-{prev}")
            run_start = None
        if i is not None and run_start is None:
            run_start = i
        prev = i
    return ", ".join(out)


def label_stops(ax, points, min_px=24.0, **style):
    """Numbers the stops (index, x, y) where they are in view, one label per cluster of stops
    closer than min_px on screen ('3-12'), so that labels never sit on each other."""
    import numpy as np
    x_lo, x_hi = sorted(ax.get_xlim())
    y_lo, y_hi = sorted(ax.get_ylim())
    groups = []  # [anchor in pixels, data point, indices]
    for index, x, y in points:
        if not (x_lo < x < x_hi and y_lo < y < y_hi):
            continue
        d = ax.transData.transform((x, y))
        near = next((g for g in groups if np.hypot(*(d - g[0])) < min_px), None)
        if near:
            near[2].append(index)
        else:
            groups.append([d, (x, y), [index]])
    for _, xy, indices in groups:
        ax.annotate(_index_ranges(sorted(indices)), xy, **style)
    return groups


def _interp(run, t, values):
    import numpy as np
    return float(np.interp(t, run.t, values))


def _save(fig, out_dir, stem, dpi):
    """PNG (palette of 256 colours when Pillow allows: a third of the size) and SVG."""
    png = os.path.join(out_dir, f"{stem}.png")
    svg = os.path.join(out_dir, f"{stem}.svg")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    try:
        from PIL import Image
        img = Image.open(io.BytesIO(buf.getvalue())).convert("RGB")
        img.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE) \
            .save(png, optimize=True)
    except (ImportError, AttributeError):  # no Pillow, or one older than 9.1: keep RGBA
        with open(png, "wb") as f:
            f.write(buf.getvalue())
    fig.savefig(svg, metadata={"Date": None})
    return [png, svg]


def _event_markers(ax, run, yscale):
    """Stops, forecast restarts (per method) and actual restarts on a position axis."""
    first = set()

    def label(key, text):
        if key in first:
            return None
        first.add(key)
        return text

    for s in run.stops:
        ax.plot(s["t"], s["y"] * yscale, "o", color=C_STOP, ms=5.5, zorder=5,
                label=label("stop", "stop (t_stop, y*)"))
    for p in drawn_forecasts(run):
        st = _method_style(p["method"])
        y_star = next((s["y"] for s in run.stops if s["index"] == p["stop"]),
                      _interp(run, p["t_stop"], run.y))
        ax.plot(p["t_restart"], y_star * yscale, st["marker"], color=st["color"], ms=6,
                mfc="none", mew=1.4, zorder=6, label=label(p["method"], st["label"]))
    for h in run.holds:
        reach = h["reach"] != 0
        ax.plot(h["t"], _interp(run, h["t"], run.y) * yscale, ">" if reach else "h",
                color=C_HELD, ms=6.5 if reach else 7.5, mfc="white" if reach else C_HELD,
                mec="0.15", mew=0.9, zorder=6.5,
                label=label("reach" if reach else "hold", HOLD_SHORT_LABELS["reach" if reach else "hold"]))
    for st in run.starts:
        if st["restart"]:
            ax.plot(st["t"], st["y"] * yscale, "x", color=C_RESTART, ms=8, mew=1.8, zorder=7,
                    label=label("restart", "actual restart"))


def _law_phase_end(run, stop, end):
    """Where a sticking phase stops being the law's: its first hold or reach, else its end."""
    return min([end] + [h["t"] for h in run.holds if h["stop"] == stop["index"]
                        and stop["t"] <= h["t"] <= end])


def _hold_spans(ax, run, legend):
    """The holds (within the window) and reaches, from their start to their end or the record's."""
    t_last = float(run.t[-1])
    for h in run.holds:
        reach = h["reach"] != 0
        end = h["end"] if h["end"] is not None else t_last
        key = "reaching" if reach else "held"
        ax.axvspan(h["t"], end, facecolor=C_HELD, alpha=0.12 if reach else 0.3, lw=0,
                   hatch="////" if reach else None, edgecolor=C_HELD if reach else None,
                   label=legend(key, "reaching for the window (the hold's reach)" if reach
                                else "held within the window (to hold_end)"))


def time_figure(run, bench, ident, plt):
    import numpy as np
    from mpl_toolkits.axes_grid1.inset_locator import mark_inset

    fig, axes = plt.subplots(4, 1, sharex=True, figsize=(10.0, 10.4),
                             gridspec_kw={"height_ratios": [2.3, 1.5, 1.2, 1.5]})
    ax_y, ax_p, ax_u, ax_f = axes
    phases = sticking_phases(run)
    for ax in axes:
        for i, (s, end, _) in enumerate(phases):
            ax.axvspan(s["t"], _law_phase_end(run, s, end), color=C_STUCK_SPAN, alpha=0.28, lw=0,
                       label="sticking phase (stop to start or hold)" if i == 0 and ax is ax_y
                       else None)
            ax.axvline(s["t"], color=C_STOP, lw=0.7, ls=":", alpha=0.8)
        _hold_spans(ax, run, _FirstLabels() if ax is ax_y else lambda key, text: None)

    ax_y.plot(run.t, run.y_d * 1e3, color=C_YD, lw=1.3, ls="--", label="set point y_d")
    ax_y.plot(run.t, run.y * 1e3, color=C_Y, lw=1.6, label="position y")
    _event_markers(ax_y, run, 1e3)
    ax_y.set_ylabel("position [mm]")
    ax_y.legend(loc="lower left", bbox_to_anchor=(0.0, 1.02, 1.0, 0.2), mode="expand", ncol=3,
                borderaxespad=0.0, framealpha=0.92, fontsize=7.8)

    # Inset: the stops around the final set point, where millimetres matter.
    if run.stops:
        t_first = min(s["t"] for s in run.stops)
        t_last = max(end for _, end, _ in phases)
        span = max(t_last - t_first, 0.5)
        t0 = max(t_first - 0.08 * span, float(run.t[0]))
        t1 = min(t_last + 0.12 * span, float(run.t[-1]))
        # the rest positions and the set points held meanwhile; the moving trajectory may clip
        sel = (run.t >= t_first) & (run.t <= t_last)
        ys = np.concatenate([run.y_d[sel], [s["y"] for s in run.stops]]) * 1e3
        lo, hi = float(np.nanmin(ys)), float(np.nanmax(ys))
        pad = max(0.15 * (hi - lo), 0.3)
        full_lo, full_hi = ax_y.get_ylim()
        if (hi - lo + 2 * pad) < 0.5 * (full_hi - full_lo):
            ins = ax_y.inset_axes([0.36, 0.3, 0.62, 0.64])
            ins.plot(run.t, run.y_d * 1e3, color=C_YD, lw=1.1, ls="--")
            ins.plot(run.t, run.y * 1e3, color=C_Y, lw=1.4)
            for s, end, _ in phases:
                ins.axvspan(s["t"], _law_phase_end(run, s, end), color=C_STUCK_SPAN, alpha=0.28,
                            lw=0)
            _hold_spans(ins, run, lambda key, text: None)
            _event_markers(ins, run, 1e3)
            ins.set_xlim(t0, t1)
            ins.set_ylim(lo - pad, hi + pad)
            label_stops(ins, [(s["index"], s["t"], s["y"] * 1e3) for s in run.stops],
                        xytext=(-3, 6), textcoords="offset points", fontsize=8, ha="right")
            ins.set_title("zoom on the stops (numbered) [mm]", fontsize=8.5, pad=3)
            ins.tick_params(labelsize=7.5)
            ins.set_facecolor("white")
            mark_inset(ax_y, ins, loc1=3, loc2=4, fc="none", ec="0.55", lw=0.7)

    ax_p.plot(run.t, run.p_p / 1e5, color=C_PP, lw=1.4, label="p_P (chamber P, bore side)")
    ax_p.plot(run.t, run.p_n / 1e5, color=C_PN, lw=1.4, label="p_N (chamber N, rod side)")
    ax_p.set_ylabel("pressure [bar abs]")
    ax_p.legend(loc="upper right", framealpha=0.92)

    ax_u.plot(run.t, run.u, color=C_U, lw=1.3, label="control u = u_P = -u_N")
    ax_u.set_ylabel("control u [V]")
    ax_u.legend(loc="lower right", framealpha=0.92)

    ax_f.plot(run.t, run.force, color=C_F, lw=1.4, label="pressure force F (Eq. 14)")
    for v, ls, lab in ((bench.fs_pos, "--", "stiction bounds F_S+, F_S-"),
                       (bench.fs_neg, "--", None),
                       (bench.fc_pos, ":", "Coulomb levels F_C+, F_C-"),
                       (bench.fc_neg, ":", None)):
        ax_f.axhline(v, color="0.25", lw=1.0, ls=ls, label=lab)
    ax_f.set_ylabel("force [N]")
    ax_f.set_xlabel("time t [s]")
    ax_f.legend(loc="upper right", ncol=3, framealpha=0.92)
    ax_f.set_xlim(float(run.t[0]), float(run.t[-1]))

    marks = holds_summary(run) or "stops, forecast restarts per method and actual restarts"
    fig.suptitle("Set-point step, sticking and restarting (cf. Brun et al. 2005, Fig. 8)\n"
                 f"{ident.label()}\n{ident.source}: {marks}", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.955))
    return fig


def _draw_areas(ax, bench, x_lo, x_hi):
    """Eq. 13 (hatched, underneath) and Eq. 12 (opaque on top): the hatch shows where a stuck
    carriage stays stuck although a sliding one would not have stopped."""
    import numpy as np
    xs = np.array([x_lo, x_hi])
    ax.fill_between(xs, xs - bench.fs_pos, xs - bench.fs_neg, facecolor="#fcf3cf",
                    edgecolor="#b7950b", hatch="////", lw=0.0, zorder=0.4,
                    label=f"no-restarting area (Eq. 13): {bench.fs_neg:g} N <= x - y <= "
                          f"{bench.fs_pos:g} N (it contains the stop area)")
    ax.fill_between(xs, xs - bench.fc_pos, xs - bench.fc_neg, color="#d6eaf8", lw=0, zorder=0.5,
                    label=f"stop area (Eq. 12): {bench.fc_neg:g} N <= x - y <= {bench.fc_pos:g} N")
    for f, ls in ((bench.fs_pos, "-"), (bench.fs_neg, "-"), (bench.fc_pos, "--"), (bench.fc_neg, "--")):
        ax.plot(xs, xs - f, color="0.35", lw=0.8, ls=ls, zorder=1.5)


def _label_band_lines(ax, bench, x_lo, x_hi, y_lo, y_hi):
    """Names the four lines x - y = F_S+/F_C+/F_C-/F_S- where they leave the view."""
    for f, text in ((bench.fs_pos, "F_S+"), (bench.fs_neg, "F_S-"), (bench.fc_pos, "F_C+"),
                    (bench.fc_neg, "F_C-")):
        # the line y = x - f: label it near the top edge, or the right edge if it leaves there
        x = min(x_hi - 0.01 * (x_hi - x_lo), y_hi - 0.02 * (y_hi - y_lo) + f)
        y = x - f
        if x_lo < x < x_hi and y_lo < y < y_hi:
            ax.annotate(f"x - y = {text}", (x, y), fontsize=7.2, color="0.15", ha="right",
                        va="top", xytext=(-3, -2), textcoords="offset points", zorder=9,
                        bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none",
                              "alpha": 0.8})


def _seconds(t):
    """A time [s] for a title: milliseconds at most, no exponent ('0.000', '12.000')."""
    return f"{float(t):.3f}"


def _positive(v):
    return v is not None and not math.isnan(v) and v > 0


def _equilibrium_point(bench, curve, prediction):
    """Complete equilibrium under u* (Eq. 11): (x_e, y_e), or None."""
    import numpy as np
    p_p_e = prediction.get("p_p_e")
    if p_p_e is not None and not math.isnan(p_p_e):
        return bench.plane(p_p_e, prediction["p_n_e"])
    u_star = prediction.get("u_star")
    if u_star is None or not (curve["u"][0] <= u_star <= curve["u"][-1]):
        return None
    return (float(np.interp(u_star, curve["u"], curve["x"])),
            float(np.interp(u_star, curve["u"], curve["y"])))


def _view(xs, ys, margin, min_span, min_aspect=0.62):
    """Limits around the points; neither side shorter than min_aspect of the other so the
    +45 degree bands still read as bands."""
    import numpy as np
    xs, ys = np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)
    x_lo, x_hi = float(np.nanmin(xs)), float(np.nanmax(xs))
    y_lo, y_hi = float(np.nanmin(ys)), float(np.nanmax(ys))
    span = max(x_hi - x_lo, y_hi - y_lo, min_span)
    xc, yc = 0.5 * (x_lo + x_hi), 0.5 * (y_lo + y_hi)
    sx = max(x_hi - x_lo, min_aspect * span) * (1 + 2 * margin)
    sy = max(y_hi - y_lo, min_aspect * span) * (1 + 2 * margin)
    return xc - sx / 2, xc + sx / 2, yc - sy / 2, yc + sy / 2


class _FirstLabels:
    """label(key, text): text the first time key is asked for, None after (one legend entry)."""

    def __init__(self):
        self.seen = set()

    def __call__(self, key, text):
        if key in self.seen:
            return None
        self.seen.add(key)
        return text


def _with_neighbours(mask):
    """1.0 where mask or a neighbour is set, else NaN: each stretch joined to the ticks by it."""
    import numpy as np
    joined = mask.copy()
    joined[1:] |= mask[:-1]
    joined[:-1] |= mask[1:]
    return np.where(joined, 1.0, np.nan)


def _trajectory_masks(run):
    """Multipliers (1.0 or NaN) of the moving, stuck and held ticks; held None without a hold."""
    import numpy as np
    held = run.held is not None and run.held.any()
    return {"moving": np.where(run.stuck, np.nan, 1.0), "stuck": _with_neighbours(run.stuck),
            "held": _with_neighbours(run.held) if held else None}


def _longest_phase_panels(run, bench, curve, x, y, longest):
    """The longest sticking phase's panel and the close-up on how it ends."""
    band = bench.fs_pos - bench.fs_neg
    s, end, restart = longest
    sel = (run.t >= s["t"]) & (run.t <= end)
    pred = [p for p in run.predictions if p["stop"] == s["index"]]
    eq = _equilibrium_point(bench, curve, pred[0]) if pred else None
    zx, zy = list(x[sel]), list(y[sel])
    if eq:
        zx.append(eq[0])
        zy.append(eq[1])
    phase = {"view": _view(zx, zy, 0.14, 0.35 * band), "phase": longest, "pred": pred, "eq": eq,
             "title": f"sticking phase {s['index']}: {end - s['t']:.3f} s at rest "
                      f"(t = {s['t']:.3f} to {end:.3f} s)"}
    # close-up: the last tenth of the phase, its forecasts and the equilibrium it aims at
    tail = sel & (run.t >= end - 0.1 * (end - s["t"]))
    cx, cy = list(x[tail]), list(y[tail])
    for p in drawn_forecasts(run):
        if p["stop"] == s["index"]:
            cx.append(_interp(run, p["t_restart"], x))
            cy.append(_interp(run, p["t_restart"], y))
    if eq:
        cx.append(eq[0])
        cy.append(eq[1])
    held = any(h["stop"] == s["index"] and h["reach"] == 0 and h["end"] is None
               for h in run.holds)
    what = "restart" if restart else "hold, to the end of the record," if held else "end"
    view = _close_up_within(_view(cx, cy, 0.3, 0.03 * band, min_aspect=0.8), phase["view"],
                            (_interp(run, end, x), _interp(run, end, y)))
    close_up = {"view": view, "phase": longest, "pred": pred, "eq": eq,
                "title": f"close-up: the {what} of sticking phase {s['index']}"}
    return [phase, close_up]


CLOSE_UP_MAX = 0.35  # a close-up spans at most this fraction of the panel it zooms into


def _close_up_within(view, outer, end_point):
    """The close-up's view, or, where it would span more than CLOSE_UP_MAX of the panel it
    zooms into (a phase whose pressures moved over most of its path until it ended), a view of
    that size around where the phase ended."""
    x_lo, x_hi, y_lo, y_hi = view
    ox = outer[1] - outer[0]
    oy = outer[3] - outer[2]
    if x_hi - x_lo <= CLOSE_UP_MAX * ox and y_hi - y_lo <= CLOSE_UP_MAX * oy:
        return view
    side = CLOSE_UP_MAX * min(ox, oy)
    # centred where the phase ended, moved inside the panel it zooms into
    x0 = min(max(end_point[0] - side / 2, outer[0]), outer[1] - side)
    y0 = min(max(end_point[1] - side / 2, outer[2]), outer[3] - side)
    return x0, x0 + side, y0, y0 + side


def plane_panels(run, bench, curve, x, y):
    """The plane's panels (view, phase, title): the whole run; the longest phase and its end."""
    phases = sticking_phases(run)
    longest = max(phases, key=lambda ph: ph[1] - ph[0]["t"]) if phases else None
    band = bench.fs_pos - bench.fs_neg
    panels = [{"view": _view(x, y, 0.08, 1.6 * band), "phase": None,
               "title": f"the whole record, t = {_seconds(run.t[0])} to {_seconds(run.t[-1])} s"}]
    if longest:
        panels += _longest_phase_panels(run, bench, curve, x, y, longest)
    return panels


def _plane_axes(plt, n_panels):
    """The figure, its panels' axes and the axes the legend fills: 2 x 2, or 2 x 1 for one panel."""
    ncols = 2 if n_panels > 1 else 1
    fig, grid = plt.subplots(2, ncols, figsize=(12.0, 11.6) if ncols == 2 else (7.6, 11.6),
                             squeeze=False)
    cells = [grid[0, 0], grid[0, 1], grid[1, 0]] if ncols == 2 else [grid[0, 0]]
    return fig, cells, grid[1, 1] if ncols == 2 else grid[1, 0]


def _null_flow_layer(ax, bench, curve):
    """The null-flow curve, thick where it is a complete equilibrium (inside the stiction band)."""
    import numpy as np
    f_eq = curve["x"] - curve["y"]
    inside = np.where((f_eq >= bench.fs_neg) & (f_eq <= bench.fs_pos), 1.0, np.nan)
    ax.plot(curve["x"], curve["y"], color="0.1", lw=1.0, ls="-.", zorder=2,
            label="null-flow curve (S_P p_null(u), S_N p_null(-u) + S_r p_E)")
    ax.plot(curve["x"] * inside, curve["y"] * inside, color="0.1", lw=3.2, zorder=2,
            solid_capstyle="butt", label="complete-equilibrium line (null flow, no restart)")


def _trajectory_layer(ax, x, y, masks):
    """The trajectory, moving and stuck."""
    ax.plot(x * masks["moving"], y * masks["moving"], color=C_Y, lw=1.3, zorder=3,
            label="trajectory, moving")
    ax.plot(x * masks["stuck"], y * masks["stuck"], color="#c0392b", lw=2.0, zorder=3.5,
            label="trajectory, stuck (the pressures drift at rest)")


def _hold_layer(ax, run, bench, x, y, held, x_span, label):
    """The held trajectory, the hold's target line over x_span, where each hold and reach began."""
    import numpy as np
    ax.plot(x * held, y * held, color=C_HELD, lw=3.0, zorder=3.7,
            label="trajectory, held (controller.hold: the pressure force driven, measured, "
                  "to the stiction band's middle)")
    target = 0.5 * (bench.fs_pos + bench.fs_neg)
    xs = np.array(x_span)
    ax.plot(xs, xs - target, color=C_HELD, lw=1.0, ls=(0, (6, 3)), zorder=1.6,
            label=f"the hold's target: x - y = (F_S+ + F_S-) / 2 = {target:g} N")
    for h in run.holds:
        reach = h["reach"] != 0
        ax.plot(_interp(run, h["t"], x), _interp(run, h["t"], y), ">" if reach else "h",
                color=C_HELD, ms=7.5 if reach else 9, mfc="white" if reach else C_HELD,
                mec="0.15", mew=1.0, zorder=7.2,
                label=label("reach" if reach else "hold", HOLD_LABELS["reach" if reach else "hold"]))


def _event_layer(ax, run, x, y, label):
    """The stops (numbered where in view), the actual restarts and the forecast ones."""
    points = []
    for s in run.stops:
        xs, ys = _interp(run, s["t"], x), _interp(run, s["t"], y)
        ax.plot(xs, ys, "o", color=C_STOP, ms=6.5, zorder=7, label=label("stop", "stop"))
        points.append((s["index"], xs, ys))
    label_stops(ax, points, xytext=(-5, 4), textcoords="offset points", fontsize=9,
                fontweight="bold", ha="right", zorder=8)
    for st in run.starts:
        if st["restart"]:
            ax.plot(_interp(run, st["t"], x), _interp(run, st["t"], y), "x", color=C_RESTART,
                    ms=9, mew=2.0, zorder=8, label=label("restart", "actual restart"))
    for p in drawn_forecasts(run):
        stl = _method_style(p["method"])
        ax.plot(_interp(run, p["t_restart"], x), _interp(run, p["t_restart"], y),
                stl["marker"], color=stl["color"], ms=8, mfc="none", mew=1.6, zorder=7.5,
                label=label(p["method"], stl["label"] + ": where the pressures were "
                            "at the forecast time"))


def _linearized_path(ax, run, x, y, stop, eq, lin):
    """The linearized forecast's path in the plane (Eq. 24) towards the equilibrium eq."""
    import numpy as np
    # from the pressures at the forecast (the stop's confirmation): each coordinate relaxes
    # towards the equilibrium with its own time constant
    x_c, y_c = _interp(run, lin["t"], x), _interp(run, lin["t"], y)
    s_grid = np.linspace(0.0, 8.0 * max(lin["tau_p"], lin["tau_n"]), 800)
    ax.plot(eq[0] + (x_c - eq[0]) * np.exp(-s_grid / lin["tau_p"]),
            eq[1] + (y_c - eq[1]) * np.exp(-s_grid / lin["tau_n"]),
            color=METHOD_STYLE["linearized"]["color"], lw=1.2, ls="--", zorder=3.2,
            label=f"linearized forecast path of stop {stop['index']} (Eq. 24)")


def _tick_step(duration):
    """A round time step [s] putting at most 16 ticks on the duration."""
    return next((d for d in (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.25, 0.5, 1, 2, 5,
                             10, 20, 60, 120, 300, 600, 1800, 3600)
                 if duration / d <= 16), 7200)


def _stuck_time_ticks(ax, run, x, y, phase, view, label):
    """Time along the stuck path where it is in view; labels only where they do not crowd."""
    import numpy as np
    s, end, _ = phase
    x_lo, x_hi, y_lo, y_hi = view
    in_view = (run.t >= s["t"]) & (run.t <= end) & (x > x_lo) & (x < x_hi) \
        & (y > y_lo) & (y < y_hi)
    if not np.any(in_view):
        return
    t_a, t_b = float(run.t[in_view][0]), float(run.t[in_view][-1])
    step = _tick_step(t_b - t_a)
    last = None
    for tt in np.arange(math.ceil(t_a / step) * step, t_b, step):
        px, py = _interp(run, tt, x), _interp(run, tt, y)
        ax.plot(px, py, ".", color="0.1", ms=5, zorder=6,
                label=label("tick", "time along the stuck path (ticks)"))
        d = ax.transData.transform((px, py))
        if last is None or np.hypot(*(d - last)) > 34:
            ax.annotate(f"{tt:g} s", (px, py), xytext=(3, 4), textcoords="offset points",
                        fontsize=7.2, color="0.2", zorder=6)
            last = d


def _phase_layer(ax, run, x, y, panel, label):
    """A zoomed phase: its linearized forecast path, its complete equilibrium, time along it."""
    s = panel["phase"][0]
    pred, eq = panel["pred"], panel["eq"]
    lin = next((p for p in pred if p["method"] == "linearized"), None)
    if eq and lin and _positive(lin.get("tau_p")) and _positive(lin.get("tau_n")):
        _linearized_path(ax, run, x, y, s, eq, lin)
    if eq:
        ax.plot(*eq, "*", color="#f39c12", mec="0.2", ms=15, zorder=7,
                label=f"complete equilibrium of stop {s['index']}: null flow under "
                      f"u* = {pred[0]['u_star']:+.4f} V (Eq. 11)")
    _stuck_time_ticks(ax, run, x, y, panel["phase"], panel["view"], label)


def _plane_panel(ax, run, bench, curve, x, y, masks, panel):
    """One panel of the plane: the areas, the null-flow curve, the trajectory and its events."""
    x_lo, x_hi, y_lo, y_hi = panel["view"]
    ax.set_xlim(x_lo, x_hi)
    ax.set_ylim(y_lo, y_hi)
    label = _FirstLabels()
    pad = 10 * (x_hi - x_lo + y_hi - y_lo)
    _draw_areas(ax, bench, x_lo - pad, x_hi + pad)
    _null_flow_layer(ax, bench, curve)
    _trajectory_layer(ax, x, y, masks)
    if masks["held"] is not None:
        _hold_layer(ax, run, bench, x, y, masks["held"], [x_lo - pad, x_hi + pad], label)
    ax.plot(x[0], y[0], "s", color="0.3", ms=6, mfc="white", mew=1.3, zorder=6,
            label=f"start of the record (t = {_seconds(run.t[0])} s)")
    _event_layer(ax, run, x, y, label)
    if panel["phase"]:
        _phase_layer(ax, run, x, y, panel, label)
    _label_band_lines(ax, bench, x_lo, x_hi, y_lo, y_hi)
    ax.set_xlabel("x = S_P p_P [N]")
    ax.set_ylabel("y = S_N p_N + S_r p_E [N]")
    ax.set_title(panel["title"])


def _number_panel(ax, k, panels):
    """Panel k's number in its corner, and a frame on where the next panel zooms in."""
    from matplotlib.patches import Rectangle
    if k + 1 < len(panels):
        nx_lo, nx_hi, ny_lo, ny_hi = panels[k + 1]["view"]
        ax.add_patch(Rectangle((nx_lo, ny_lo), nx_hi - nx_lo, ny_hi - ny_lo, fill=False,
                               ec="0.2", lw=1.1, ls="--", zorder=9))
        ax.annotate(f"panel {k + 2}", (nx_hi, ny_lo), xytext=(2, 2),
                    textcoords="offset points", fontsize=7.5, zorder=9)
    ax.annotate(f"{k + 1}", (0.985, 0.015), xycoords="axes fraction", ha="right",
                va="bottom", fontsize=11, fontweight="bold", zorder=10,
                bbox={"boxstyle": "circle,pad=0.2", "fc": "white", "ec": "0.3"})


def _plane_legend(legend_ax, axes):
    """The panels' legend entries, each once, filling legend_ax."""
    handles, labels = {}, []
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in handles:
                handles[lab] = h
                labels.append(lab)
    legend_ax.axis("off")
    legend_ax.legend([handles[lab] for lab in labels],
                     [textwrap.fill(lab, 58, subsequent_indent="  ") for lab in labels],
                     loc="center", fontsize=8.3, framealpha=1.0, borderpad=0.9, labelspacing=0.75,
                     title="panels 1-3 (numbered in their lower right corners)",
                     title_fontsize=8.8)


def plane_figure(run, bench, curve, ident, plt):
    """The pressure-force plane (cf. Fig. 7, 10, 11): the whole run, the longest phase, its end."""
    x, y = bench.plane(run.p_p, run.p_n)
    panels = plane_panels(run, bench, curve, x, y)
    fig, cells, legend_ax = _plane_axes(plt, len(panels))
    masks = _trajectory_masks(run)
    for k, (ax, panel) in enumerate(zip(cells, panels)):
        _plane_panel(ax, run, bench, curve, x, y, masks, panel)
        _number_panel(ax, k, panels)
    _plane_legend(legend_ax, cells[:len(panels)])
    marks = holds_summary(run)
    fig.suptitle("The pressure-force plane (cf. Brun et al. 2005, Fig. 7, 10, 11); "
                 "the pressure force is F = x - y (Eq. 14)\n"
                 f"{ident.label()}\n{ident.source}: "
                 f"S_P = {bench.area_p * 1e4:.3f} cm^2, S_N = {bench.area_n * 1e4:.3f} cm^2, "
                 f"S_r = {bench.area_rod * 1e4:.3f} cm^2, p_E = {bench.p_e / 1e5:g} bar"
                 + (f"\n{marks}" if marks else ""), fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.94 if marks else 0.95))
    return fig


FORECAST_STYLE = {  # the forecast figure's curves, in the colours of METHOD_STYLE
    "linearized": {"ls": (0, (5.0, 2.2)), "lw": 1.5,
                   "label": "linearized forecast (Eq. 24/17), made at the stop"},
    "nonlinear": {"ls": (0, (1.0, 1.6)), "lw": 2.1,
                  "label": "nonlinear forecast (Eq. 19), made at the stop"},
}


def _newtons(f):
    """A small force difference [N], signed, without a '-0.00'."""
    return f"{f:+.2f}" if abs(f) >= 0.095 else f"{f:+.3f}" if abs(f) >= 0.0005 else "0"


def _ms(dt):
    """A time difference [s] in signed milliseconds, with a decimal when small."""
    return f"{dt * 1e3:+.1f}" if abs(dt) < 0.01 else f"{dt * 1e3:+.0f}"


def forecast_phase(run):
    """The longest sticking phase whose forecast columns hold values: (stop, end, restart,
    ticks of its forecast), or None. Its forecast runs from the stop's confirmation until the
    start is seen, which may be a little after the start's time; it ends before the next stop."""
    import numpy as np
    if not run.forecast:
        return None
    held = np.zeros(len(run.t), dtype=bool)
    for cols in run.forecast.values():
        held |= np.isfinite(cols["force"])
    best = None
    for s, end, restart in sticking_phases(run):
        later = [o["t"] for o in run.stops if o["t"] > s["t"]]
        ticks = held & (run.t >= s["t"]) & (run.t < (min(later) if later else math.inf))
        longer = best is None or end - s["t"] > best[1] - best[0]["t"]
        if longer and np.any(ticks & (run.t <= end)):
            best = (s, end, restart, ticks)
    return best


def _forecast_style(m):
    """A method's curve here: METHOD_STYLE's colour and marker, FORECAST_STYLE's line."""
    return dict(_method_style(m), **FORECAST_STYLE.get(
        m, {"ls": "--", "lw": 1.3, "label": f"{m} forecast, made at the stop"}))


def _forecast_curves(run, ticks, win):
    """Each method's forecast on the phase's ticks in the window; the methods with values."""
    import numpy as np
    fc = {m: {c: np.where(ticks, v, np.nan)[win] for c, v in cols.items()}
          for m, cols in run.forecast.items()}
    methods = [m for m in list(FORECAST_STYLE) + sorted(set(fc) - set(FORECAST_STYLE))
               if m in fc and np.any(np.isfinite(fc[m]["force"]))]
    return fc, methods


def _restart_forecasts_made(methods, pred, refc):
    """Per method, (when made, restart time forecast): at the stop, then while stuck."""
    made = {m: sorted((p["t"], p["t_restart"]) for p in ([pred[m]] if m in pred else [])
                      + [r for r in refc if r["method"] == m]
                      if p["will_restart"] and p["t_restart"] is not None) for m in methods}
    return {m: pts for m, pts in made.items() if pts}


class ForecastWindow:
    """What the forecast figure draws: a sticking phase, the window around it, its forecasts."""

    def __init__(self, run, bench, phase):
        s, end, restart, ticks = phase
        self.stop, self.end, self.restart = s, end, restart  # as forecast_phase() gives them
        self.span = end - s["t"]                             # time at rest [s]
        t_last = max(end, float(run.t[ticks][-1]))
        self.t0 = max(s["t"] - 0.05 * self.span, float(run.t[0]))  # the window drawn [s]
        self.t1 = min(t_last + 0.05 * self.span, float(run.t[-1]))
        win = (run.t >= self.t0) & (run.t <= self.t1)
        self.t = run.t[win]                                  # the window's ticks and measures
        self.p_p, self.p_n, self.force = run.p_p[win], run.p_n[win], run.force[win]
        self.fc, self.methods = _forecast_curves(run, ticks, win)  # {method: {column: values}}
        # the ticks whose gaps matter: the forecasts assume v = 0
        self.stuck = (self.t >= s["t"]) & (self.t <= end)
        self.pred = {p["method"]: p for p in run.predictions if p["stop"] == s["index"]}
        self.refc = [p for p in run.reforecasts if p["stop"] == s["index"]]
        self.direction = (restart or {}).get("direction") or next(
            (p["direction"] for p in self.pred.values() if p["will_restart"]), 0)
        self.bound = bench.fs_pos if self.direction > 0 else bench.fs_neg  # the restart's bound [N]
        self.t_act = restart["t"] if restart else None       # the actual restart, if any
        self.restarts = {p["method"]: p["t_restart"] for p in law_forecasts(run)[0]
                         if p["stop"] == s["index"]}  # forecast at the stop, still applying
        self.made = _restart_forecasts_made(self.methods, self.pred, self.refc)


def _forecast_axes(w, plt):
    """The figure and its three panels, four with the re-forecasts, on one time axis."""
    panels = 4 if w.refc and w.made else 3
    return plt.subplots(panels, 1, sharex=True, figsize=(10.0, 11.2 if w.refc else 9.4),
                        gridspec_kw={"height_ratios": [1.45, 2.1, 1.1, 1.3][:panels]})


def _restart_lines(ax, w):
    """Vertical lines at each forecast restart and at the actual one."""
    for m, tr in w.restarts.items():
        ax.axvline(tr, color=_forecast_style(m)["color"], lw=1.1, ls="--", zorder=1.8)
    if w.t_act is not None:
        ax.axvline(w.t_act, color=C_RESTART, lw=1.2, zorder=1.9)


def _phase_marks(axes, w):
    """Every panel: the sticking phase, its stop and (but on the re-forecast panel) the restarts."""
    s = w.stop
    for ax in axes:
        ax.axvspan(s["t"], w.end, color=C_STUCK_SPAN, alpha=0.28, lw=0,
                   label="sticking phase (stop to start)" if ax is axes[0] else None)
        ax.axvline(s["t"], color=C_STOP, lw=0.9, ls=":",
                   label=f"stop {s['index']}: t_stop = {s['t']:.3f} s at y* = {s['y'] * 1e3:.2f} mm"
                   if ax is axes[0] else None)
        if len(axes) == 4 and ax is axes[-1]:
            continue  # the last panel shows these times on its y axis
        _restart_lines(ax, w)


def _largest_pressure_gap(w, m):
    """The largest gap [Pa] of a method's forecast pressures to the measured ones while stuck."""
    import numpy as np
    fc = w.fc[m]
    return np.nanmax(np.abs(np.concatenate([fc["p_p"] - w.p_p, fc["p_n"] - w.p_n])[
        np.concatenate([w.stuck, w.stuck])]))


def _pressure_panel(ax, w):
    """Panel a: the measured chamber pressures against the forecast ones."""
    for values, c, lab in ((w.p_p, C_PP, "p_P measured (chamber P, bore side)"),
                           (w.p_n, C_PN, "p_N measured (chamber N, rod side)")):
        ax.plot(w.t, values / 1e5, color=c, lw=2.6, alpha=0.55, zorder=2, label=lab)
    gaps = []
    for m in w.methods:
        st = _forecast_style(m)
        for i, key in enumerate(("p_p", "p_n")):
            ax.plot(w.t, w.fc[m][key] / 1e5, color=st["color"], ls=st["ls"], lw=st["lw"],
                    zorder=3, label=st["label"] if i == 0 else None)
        gaps.append(f"{m} {_largest_pressure_gap(w, m) / 100:.2f} mbar")
    ax.set_ylabel("pressure [bar abs]")
    ax.ticklabel_format(axis="y", useOffset=False)
    ax.set_title("a/ chamber pressures; the forecasts' largest gap to the measure while "
                 "stuck: " + ", ".join(gaps), loc="left", fontsize=9.5)
    _name_chambers(ax, w)
    t_zero = w.stop["t"]
    top = ax.secondary_xaxis("top", functions=(lambda x: x - t_zero, lambda x: x + t_zero))
    top.set_xlabel("time since the stop t - t_stop [s] (Fig. 13's time reference)", fontsize=8.5)
    top.tick_params(labelsize=8)


def _name_chambers(ax, w):
    """Which curve is which chamber: named half-way through the sticking phase, between the two."""
    import numpy as np
    i = int(np.searchsorted(w.t, w.stop["t"] + 0.5 * w.span))
    if i < len(w.t):
        upper = w.p_n[i] > w.p_p[i]
        for values, c, text, high in ((w.p_p, C_PP, "p_P", not upper), (w.p_n, C_PN, "p_N", upper)):
            ax.annotate(text, (w.t[i], values[i] / 1e5), xytext=(0, -5 if high else 5),
                        textcoords="offset points", color=c, fontsize=9, fontweight="bold",
                        ha="center", va="top" if high else "bottom")


def _force_curves(ax, run, w, lw_scale=1.0):
    """Measured and forecast pressure force, the forecast restarts on the bound, the actual one."""
    ax.plot(w.t, w.force, color=C_F, lw=2.6 * lw_scale, alpha=0.55, zorder=2,
            label="F measured (Eq. 14, from the measured pressures)")
    for m in w.methods:
        st = _forecast_style(m)
        ax.plot(w.t, w.fc[m]["force"], color=st["color"], ls=st["ls"], lw=st["lw"] * lw_scale,
                zorder=3)
    for m, tr in w.restarts.items():
        st = _forecast_style(m)
        ax.plot(tr, w.bound, st["marker"], color=st["color"], ms=7, mfc="white", mew=1.5, zorder=6)
    if w.t_act is not None:
        ax.plot(w.t_act, _interp(run, w.t_act, run.force), "x", color=C_RESTART, ms=9, mew=2.0,
                zorder=7)


def _force_range(w, bench):
    """The forces' range, its margin, and the stiction bounds worth drawing."""
    import numpy as np
    lo = min(float(np.nanmin(w.force)), *(float(np.nanmin(w.fc[m]["force"])) for m in w.methods))
    hi = max(float(np.nanmax(w.force)), *(float(np.nanmax(w.fc[m]["force"])) for m in w.methods))
    pad = 0.06 * (hi - lo)
    # the bound the restart is forecast (or seen) at and any other one near the force; both
    # when no restart is forecast: the force staying between them is the point (Eq. 16)
    shown = [(f, n) for f, n in ((bench.fs_pos, "F_S+"), (bench.fs_neg, "F_S-"))
             if lo - 4 * pad <= f <= hi + 4 * pad or not w.direction or f == w.bound]
    return lo, hi, pad, shown


def _force_panel(ax, run, bench, w):
    """Panel b: the pressure force, the bound it restarts at, the restarts, a zoom on them."""
    _force_curves(ax, run, w)
    lo, hi, pad, shown = _force_range(w, bench)
    for f, _ in shown:
        ax.axhline(f, color="0.25", lw=1.0, ls="--", zorder=1.5)
    if shown:
        ax.plot([], [], color="0.25", lw=1.0, ls="--",
                label=("stiction bounds " if len(shown) > 1 else "stiction bound ")
                + ", ".join(f"{n} = {f:g} N" for f, n in shown))
    lo, hi = min([lo] + [f for f, _ in shown]), max([hi] + [f for f, _ in shown])
    ax.set_ylim(lo - pad, hi + pad)
    ax.ticklabel_format(axis="y", useOffset=False)
    ax.set_ylabel("pressure force F [N]")
    ax.set_title("b/ pressure force F = S_P p_P - S_N p_N - S_r p_E, and "
                 + (f"the restart at {'F_S+' if w.bound > 0 else 'F_S-'} = {w.bound:g} N "
                    f"(Eq. 16-17, 25)" if w.direction else
                    "the stiction bounds (Eq. 16): no restart forecast"),
                 loc="left", fontsize=9.5)
    _restart_legend_entries(ax, w)
    if w.t_act is not None and w.restarts:
        _restart_zoom(ax, run, w, hi - lo)


def _restart_legend_entries(ax, w):
    """Legend entries of the forecast restarts (how far from the actual one) and the actual one."""
    for m, tr in w.restarts.items():
        st = _method_style(m)
        late = f", {_ms(tr - w.t_act)} ms from the actual one" if w.t_act is not None else ""
        ax.plot([], [], st["marker"], color=st["color"], ms=7, mfc="white", mew=1.5, ls="--",
                lw=1.1, label=f"{st['label']}: t = {tr:.3f} s{late}")
    if w.t_act is not None:
        ax.plot([], [], "x", color=C_RESTART, ms=9, mew=2.0, ls="-", lw=1.2,
                label=f"actual restart: t = {w.t_act:.4f} s, {w.t_act - w.stop['t']:.3f} s after "
                      "the stop")


def _restart_zoom_view(w):
    """The zoom's limits (t0, t1, F_lo, F_hi) around the forecast and actual restarts."""
    import numpy as np
    times = list(w.restarts.values()) + [w.t_act]
    z_pad = max(0.35 * (max(times) - min(times)), 0.01)
    z0, z1 = max(min(times) - z_pad, w.t0), min(max(times) + z_pad, w.t1)
    zsel = (w.t >= z0) & (w.t <= z1)
    zvals = np.concatenate([w.force[zsel]] + [w.fc[m]["force"][zsel] for m in w.methods]
                           + [[w.bound]])
    z_lo, z_hi = float(np.nanmin(zvals)), float(np.nanmax(zvals))
    return z0, z1, z_lo - 0.12 * (z_hi - z_lo), z_hi + 0.12 * (z_hi - z_lo)


def _restart_zoom(ax, run, w, f_span):
    """An inset zoom on how much earlier each forecast reaches the bound, when f_span dwarfs it."""
    from mpl_toolkits.axes_grid1.inset_locator import mark_inset
    z0, z1, z_lo, z_hi = _restart_zoom_view(w)
    if not (z_hi - z_lo) < 0.25 * f_span:
        return
    falling = w.bound < 0
    ins = ax.inset_axes([0.52, 0.37, 0.46, 0.56] if falling else [0.52, 0.07, 0.46, 0.56])
    ins.axhline(w.bound, color="0.25", lw=1.0, ls="--", zorder=1.5)
    _restart_lines(ins, w)
    _force_curves(ins, run, w, lw_scale=1.15)
    ins.set_xlim(z0, z1)
    ins.set_ylim(z_lo, z_hi)
    ins.set_facecolor("white")
    ins.tick_params(labelsize=7.5)
    ins.ticklabel_format(useOffset=False)
    ins.set_title("zoom on the restart [N]", fontsize=8.5, pad=3)
    # beside the inset, where the force has already left (falling) or not yet reached (rising)
    # that height
    ax.text(0.075, 0.93 if falling else 0.07,
            "forecast at the actual restart (zoom):\n" + "\n".join(_restart_zoom_notes(run, w)),
            transform=ax.transAxes,
            fontsize=7.8, va="top" if falling else "bottom", ha="left", zorder=9,
            bbox={"boxstyle": "round,pad=0.35", "fc": "white", "ec": "0.7", "alpha": 0.92})
    # the connectors leave the inset's edge that faces the zoomed region
    mark_inset(ax, ins, loc1=3 if falling else 2, loc2=4 if falling else 1,
               fc="none", ec="0.55", lw=0.7)


def _restart_zoom_notes(run, w):
    """Beside the zoom: each forecast's gap and timing at the actual restart, in sticking time."""
    import numpy as np
    notes, worst = [], 0.0
    for m, tr in w.restarts.items():
        gap = (_interp(run, w.t_act, run.forecast[m]["force"]) if m in run.forecast
               else math.nan) - _interp(run, w.t_act, run.force)
        if not math.isnan(gap):
            worst = max(worst, abs(gap))
        dt = abs(tr - w.t_act) * 1e3
        notes.append(f"{m}: " + ("" if math.isnan(gap) else f"{_newtons(gap)} N off, ")
                     + f"crosses {w.bound:g} N {dt:.{1 if dt < 10 else 0}f} ms "
                     + ("early" if tr < w.t_act else "late"))
    i0 = int(np.searchsorted(run.t, w.t_act - 0.02))
    i1 = min(int(np.searchsorted(run.t, w.t_act)), len(run.t) - 1)
    if i1 > i0 and worst >= 0.01:
        slope = (run.force[i1] - run.force[i0]) / (run.t[i1] - run.t[i0])
        notes.append(f"F moves only {slope:+.2f} N/s there: a gap of\n{worst:.2f} N "
                     f"is {worst / max(abs(slope), 1e-9):.2f} s of sticking time")
    return notes


def _largest_force_gap(w, err):
    """The tick of the largest |forecast - measured| force while stuck, or None."""
    import numpy as np
    if not np.any(np.isfinite(err[w.stuck])):
        return None
    return int(np.nanargmax(np.where(w.stuck, np.abs(err), np.nan)))


def _gap_panel(ax, w):
    """Panel c: forecast minus measured force, each method's largest gap while stuck named."""
    ax.axhline(0.0, color="0.3", lw=0.8)
    worst_gaps = []
    for m in w.methods:
        st = _forecast_style(m)
        err = w.fc[m]["force"] - w.force
        ax.plot(w.t, err, color=st["color"], ls=st["ls"], lw=st["lw"], zorder=3)
        i = _largest_force_gap(w, err)
        if i is not None:
            ax.plot(w.t[i], err[i], "o", color=st["color"], ms=4.5, zorder=4)
            worst_gaps.append((m, w.t[i], err[i]))
    # the largest gaps (the dots) named on the side the curves leave free
    low = max((e for _, _, e in worst_gaps), key=abs, default=1.0) > 0
    for n, (m, tw, ew) in enumerate(worst_gaps):
        ax.text(0.3, (0.05 + 0.13 * (len(worst_gaps) - 1 - n)) if low else (0.95 - 0.13 * n),
                f"{m}: largest gap while stuck {_newtons(ew)} N, at t = {tw:.3f} s (dot)",
                transform=ax.transAxes, fontsize=8, color=_forecast_style(m)["color"],
                va="bottom" if low else "top", zorder=5)
    e_lim = max([abs(e) for _, _, e in worst_gaps] + [0.0])
    ax.set_ylim(-1.45 * max(e_lim, 0.05), 1.45 * max(e_lim, 0.05))
    ax.set_ylabel("forecast - measured\nforce [N]")
    ax.set_title("c/ forecast minus measured force: where each forecast leaves the measure",
                 loc="left", fontsize=9.5)


def _reforecast_panel(ax, w):
    """Panel d, the live predictor: the restart time forecast again while stuck."""
    for m, pts in w.made.items():
        st = _forecast_style(m)
        ax.plot(*zip(*pts), color=st["color"], ls="-", lw=1.0, marker=st["marker"],
                ms=4, mfc="white", mew=1.1, zorder=3,
                label=f"{m} (first point: the forecast made at the stop)")
    none = sum(1 for r in w.refc if not (r["will_restart"] and r["t_restart"] is not None))
    if w.t_act is not None:
        t_act = w.t_act
        ax.axhline(t_act, color=C_RESTART, lw=1.2, zorder=2)
        ax.secondary_yaxis("right", functions=(lambda x: (x - t_act) * 1e3,
                                               lambda x: x / 1e3 + t_act)) \
            .set_ylabel("minus actual\nrestart [ms]")
    ax.set_ylabel("forecast restart\ntime [s]")
    ax.set_title("d/ forecast restart time vs when it was made (the stop's forecast, then "
                 "the re-forecasts while stuck)"
                 + (f"; {none} forecast no restart" if none else ""),
                 loc="left", fontsize=9.5)
    ax.legend(loc="lower right", fontsize=7.8, framealpha=0.92)


def _forecast_title(run, w, ident):
    """The title: the phase, the run, when the forecasts were made, how the phase ended."""
    s, end = w.stop, w.end
    how_it_ends = "" if w.restart else \
        " (then a start, not a restart)" if any(s["t"] < o["t"] <= end for o in run.starts) else \
        " (no start before the record ends)"
    return (f"Sticking phase {s['index']}, measured vs forecast pressures and force "
            f"(cf. Brun et al. 2005, Fig. 13)\n{ident.label()}\n{ident.source}: forecasts made at the stop "
            f"(t = {next(iter(w.pred.values()))['t'] if w.pred else s['t']:.3f} s), "
            f"stuck {w.span:.3f} s{how_it_ends}")


def _forecast_legend(fig, axes, top):
    """One legend of these panels' curves: measured first, then the forecasts, then the rest."""
    handles, labels = [], []
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    order = sorted(range(len(labels)), key=lambda i: (0 if "measured" in labels[i] else
                                                      1 if "forecast (" in labels[i] else 2, i))
    return fig.legend([handles[i] for i in order], [labels[i] for i in order], loc="upper center",
                      bbox_to_anchor=(0.5, top), ncol=2, framealpha=0.95, fontsize=8.2)


def _fit_below_legend(fig, leg, ax_top):
    """Lay the panels out below the legend, the top panel's title meeting it."""
    fig.canvas.draw()
    to_fig = fig.transFigure.inverted()
    below_legend = leg.get_window_extent().transformed(to_fig).y0 - 0.008
    fig.tight_layout(rect=(0, 0, 1, below_legend))
    # tight_layout leaves room above the top panel as if its secondary axis were not there:
    # lift the panels until the top panel's title meets the legend
    top = ax_top.get_tightbbox(fig.canvas.get_renderer()).transformed(to_fig).y1
    fig.subplots_adjust(top=fig.subplotpars.top + below_legend - top)


def forecast_figure(run, bench, ident, plt):
    """The longest sticking phase against the forecasts made at its stop (cf. Fig. 13), or None
    when the run has no forecast columns or no sticking phase with forecast values."""
    phase = forecast_phase(run)
    if phase is None:
        return None
    w = ForecastWindow(run, bench, phase)
    fig, axes = _forecast_axes(w, plt)
    _phase_marks(axes, w)
    _pressure_panel(axes[0], w)
    _force_panel(axes[1], run, bench, w)
    _gap_panel(axes[2], w)
    if len(axes) == 4:
        _reforecast_panel(axes[3], w)
    axes[-1].set_xlabel("time t [s]")
    axes[-1].set_xlim(w.t0, w.t1)
    title = fig.suptitle(_forecast_title(run, w, ident), fontsize=11)
    fig.canvas.draw()  # the legend's top meets the title's last line
    leg = _forecast_legend(fig, axes[:2], title.get_window_extent().transformed(
        fig.transFigure.inverted()).y0 - 0.006)
    _fit_below_legend(fig, leg, axes[0])
    return fig


# --------------------------------------------------------------------------------------------


def parse_args(argv):
    p = argparse.ArgumentParser(
        description="Figures of a pneud run: time traces (Fig. 8), the pressure-force plane "
                    "(Fig. 7/10/11) and the forecasts against the measure during the longest "
                    "sticking phase (Fig. 13) of Brun et al. 2005.")
    src = p.add_argument_group("input (one of)")
    src.add_argument("--trajectory", metavar="T.csv", help="pneud --trajectory output")
    src.add_argument("--events", metavar="E.jsonl", help="pneud --events output of the same run "
                     "(optional: without it, no stops, restarts, holds or forecast figure)")
    src.add_argument("--log-csv", metavar="DIR", help="directory of pneu-log2csv output")
    src.add_argument("--prefix", default="PNEU_", help="channel prefix of the --log-csv files "
                     "(default PNEU_)")
    p.add_argument("--config", metavar="FILE", help="YAML configuration of a run that recorded "
                   "none (the effective configuration pneud wrote beside --trajectory or "
                   "--events, --set applied, is drawn whenever it is there; without either, "
                   "config/sim.yaml of the source tree)")
    p.add_argument("--null-flow", metavar="CURVE.csv", help="output of pneu-plant null-flow "
                   "(default: run pneu-plant null-flow on --config)")
    p.add_argument("--pneu-plant", metavar="PATH", help="pneu-plant executable (default: next "
                   "to this script, on PATH, or build/bin of the source tree)")
    p.add_argument("--time-range", nargs=2, type=float, metavar=("T0", "T1"),
                   help="plot only loop times T0 <= t <= T1 [s]")
    p.add_argument("--out-dir", required=True, metavar="DIR", help="where the figures go")
    p.add_argument("--name", help="file stem (default: from the run: configuration, backend, "
                   "'held' when the hold was on, date and time, e.g. sim_sim_held_20260101-120000)")
    p.add_argument("--dpi", type=float, default=110, help="PNG resolution (default 110)")
    args = p.parse_args(argv)
    if args.log_csv and (args.trajectory or args.events):
        p.error("give either --trajectory/--events or --log-csv, not both")
    if not args.log_csv and not args.trajectory:
        p.error("give --trajectory T.csv [--events E.jsonl], or --log-csv DIR (the figures "
                "draw the trajectory's pressures: --events alone is not enough)")
    if args.name is not None and (not args.name or "/" in args.name):
        p.error("--name must be a non-empty file stem without '/'")
    if not 20 <= args.dpi <= 600:
        p.error("--dpi must be in [20, 600]")
    return args


class Figures:
    """A run's figures, drawn and not yet written: (file suffix, matplotlib figure) in order."""

    def __init__(self, run, ident, name, figures):
        self.run, self.ident, self.name, self.figures = run, ident, name, figures


def make_figures(args):
    """Reads the run args name and draws its figures (InputError on bad input)."""
    try:
        import numpy as np
    except ImportError:
        raise InputError("numpy is missing (Debian package python3-numpy)") from None
    plt = _setup_matplotlib()
    bench, origin = run_configuration(args)
    if args.log_csv:
        run = load_log_csv(args.log_csv, args.prefix)
    else:
        run = load_pneud_output(args.trajectory, args.events)
        if args.events:
            check_events_belong(run, bench, args.trajectory, args.events)
    ident = RunIdentity(run, bench, origin)
    if args.time_range:
        restrict_to_time_range(run, *args.time_range)
    if len(run.t) < 2:
        raise InputError("fewer than two samples to plot")
    raw = null_flow_curve(args, bench.path)
    order = np.argsort(raw["u_v"])
    curve = {"u": np.array(raw["u_v"])[order], "x": np.array(raw["x_n"])[order],
             "y": np.array(raw["y_n"])[order]}
    x, y = bench.plane(run.p_p, run.p_n)
    mismatch = float(np.nanmax(np.abs(x - y - run.force)))
    if mismatch > 0.5 + 0.01 * float(np.nanmax(np.abs(run.force))):
        print(f"pneu_plots: warning: the recorded force differs from S_P p_P - S_N p_N - S_r p_E "
              f"of {bench.path} by up to {mismatch:.2f} N: is it the run's configuration?",
              file=sys.stderr)
    figures = [("time", time_figure(run, bench, ident, plt)),
               ("plane", plane_figure(run, bench, curve, ident, plt))]
    fig = forecast_figure(run, bench, ident, plt)
    if fig is not None:
        figures.append(("forecast", fig))
    elif args.log_csv:
        print("pneu_plots: note: no forecast figure: the LCM STATE channel carries no "
              "forecast columns (draw it from pneud --trajectory/--events output)",
              file=sys.stderr)
    elif not args.events:
        print("pneu_plots: note: no forecast figure: no --events (the forecasts are events)",
              file=sys.stderr)
    elif run.forecast is None:
        print(f"pneu_plots: note: no forecast figure: {args.trajectory} has no forecast "
              f"columns (p_p_linearized ... force_nonlinear: the trajectory of an older pneud)",
              file=sys.stderr)
    else:
        print("pneu_plots: note: no forecast figure: no sticking phase with forecast values "
              "in the plotted range", file=sys.stderr)
    return Figures(run, ident, args.name or ident.stem(), figures)


def main(argv):
    args = parse_args(argv)  # argparse exits 2 on a bad command line
    try:
        made = make_figures(args)
        plt = _setup_matplotlib()
        os.makedirs(args.out_dir, exist_ok=True)
        written = []
        for suffix, fig in made.figures:
            written += _save(fig, args.out_dir, f"{made.name}_{suffix}", args.dpi)
            plt.close(fig)
    except InputError as e:
        print(f"pneu_plots: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as e:
        print(f"pneu_plots: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT if isinstance(e, (FileNotFoundError, PermissionError)) else 1
    run = made.run
    print(f"pneu_plots: {len(run.stops)} stops, {sum(s['restart'] for s in run.starts)} restarts, "
          f"{len(run.predictions)} forecasts, {len(run.reforecasts)} re-forecasts; "
          f"wrote {', '.join(written)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
