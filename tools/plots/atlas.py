#!/usr/bin/python3
"""atlas: the restart-risk maps of a pneu-sweep atlas (pneu-sweep --design lhs|grid), as figures.

Each --run LABEL=DIR names one merged sweep: DIR holds its stops file sweep.csv and its scenarios
file scenarios.csv (what tools/cluster/parallel-sweep.sh writes; --run LABEL=STOPS.csv,SCENARIOS.csv
names the files themselves). Typically two runs: the atlas without the in-position hold and with
it (controller.hold.enabled). The axes are the scenarios file's: the set point y_d_m and each bench
column that varies over the runs (F_S+, the dead volume of chamber P, the valve null offset, the
thermal time constant, the spool lag), cut in --bins bins of equal width. Writes, in --out-dir:

  PREFIX_profiles.png     one column per axis; rows: the probability of a restart after a judged
                          stop (restart / (restart + stuck to the end), +- one binomial standard
                          error); the sticking time before each restart (median, 10-90 % band);
                          the final error |y_d - y| at the end of each scenario that ran (median,
                          90th percentile); each scenario's outcome (settled, end-stop,
                          never-settled, fault, not run: identification failed), as fractions of
                          the bin's scenarios, one bar per run: every scenario is counted
  PREFIX_restart_map.png  the probability of a restart after a judged stop over set point x each
                          tolerance, one column per run (grey: no judged stop in the cell)
  PREFIX_final_error_map.png  the median final error over set point x each tolerance (grey:
                          no scenario that ran)
  PREFIX_sticking.png     the distribution of the sticking time before a restart, per run, with
                          the stops stuck to the end and those not judged counted in the legend

and with --summary-json FILE the figures drawn, per run: the scenarios by outcome, the stops by
fate, and per axis and bin the scenarios, the judged stops, the restarts and the probability.

Exit codes: 0 written, 2 bad input (missing file or column, malformed value, an empty run), 1
anything else.
"""

import argparse
import csv
import json
import os
import sys

EXIT_BAD_INPUT = 2
OUTCOMES = ("settled", "end-stop", "never-settled", "fault", "identification_failed")
OUTCOME_LABELS = {"identification_failed": "not run (identification failed)"}
OUTCOME_COLORS = {"settled": "tab:green", "end-stop": "tab:orange", "never-settled": "tab:red",
                  "fault": "tab:purple", "identification_failed": "tab:gray"}
# The stops file's fates: judged (restart or stuck to the end) and not judged.
JUDGED_FATES = ("restart", "stuck_to_end")
# Candidate axes: scenarios-file column, label, scale to the unit shown.
AXES = (("y_d_m", "set point y_d [mm]", 1e3),
        ("bench_static_positive_n", "bench friction F_S+ [N]", 1.0),
        ("bench_dead_volume_p_m3", "bench dead volume P [cm^3]", 1e6),
        ("bench_null_offset_v", "bench valve null offset [mV]", 1e3),
        ("bench_thermal_time_constant_s", "bench thermal time constant [s]", 1.0),
        ("bench_spool_time_constant_s", "bench spool lag [ms]", 1e3))
STOP_COLUMNS = ("scenario", "outcome", "sticking_s")
SCENARIO_COLUMNS = ("scenario", "outcome", "final_error_m", "y_d_m")


class BadInput(Exception):
    pass


def read_csv(path, needed):
    try:
        with open(path, newline="") as f:
            reader = csv.DictReader(f)
            rows = list(reader)
            fields = reader.fieldnames or []
    except OSError as e:
        raise BadInput(f"cannot read {path}: {e.strerror}")
    missing = [c for c in needed if c not in fields]
    if missing:
        raise BadInput(f"{path} lacks the column(s) {', '.join(missing)}")
    return rows


def number(text, path, column):
    """A cell as a float; empty and nan are None."""
    if text is None or text == "" or text == "nan":
        return None
    try:
        return float(text)
    except ValueError:
        raise BadInput(f"{path}: '{text}' in column {column} is not a number")


def load_run(spec):
    if "=" not in spec:
        raise BadInput(f"--run '{spec}' is not LABEL=DIR or LABEL=STOPS.csv,SCENARIOS.csv")
    label, where = spec.split("=", 1)
    if "," in where:
        stops_path, scenarios_path = where.split(",", 1)
    else:
        stops_path, scenarios_path = os.path.join(where, "sweep.csv"), os.path.join(where, "scenarios.csv")
    scenarios = read_csv(scenarios_path, SCENARIO_COLUMNS)
    stops = read_csv(stops_path, STOP_COLUMNS)
    if not scenarios:
        raise BadInput(f"{scenarios_path} has no scenario")
    by_index = {}
    for row in scenarios:
        if row["outcome"] not in OUTCOMES:
            raise BadInput(f"{scenarios_path}: unknown outcome '{row['outcome']}' of scenario {row['scenario']}")
        by_index[row["scenario"]] = row
    for s in stops:
        if s["scenario"] not in by_index:
            raise BadInput(f"{stops_path}: stop of scenario {s['scenario']}, which {scenarios_path} lacks")
    return {"label": label, "scenarios": scenarios, "stops": stops, "by_index": by_index,
            "paths": (stops_path, scenarios_path)}


def axes_of(runs):
    """The axes whose column is there and varies over the runs."""
    axes = []
    for column, label, scale in AXES:
        values = set()
        for run in runs:
            for row in run["scenarios"]:
                v = number(row.get(column), run["paths"][1], column)
                if v is not None:
                    values.add(v)
        if len(values) > 1:
            axes.append({"column": column, "label": label, "scale": scale,
                         "lo": min(values) * scale, "hi": max(values) * scale})
    if not axes:
        raise BadInput("no column varies over the scenarios: not an atlas")
    return axes


def bin_of(value, axis, bins):
    """The bin of a scenario's value on an axis; None when it has none."""
    if value is None:
        return None
    lo, hi = axis["lo"], axis["hi"]
    k = int((value * axis["scale"] - lo) / (hi - lo) * bins)
    return min(max(k, 0), bins - 1)


def tally(run, axes, bins):
    """Per axis and bin: scenarios (by outcome), judged stops, restarts, sticking times, final errors."""
    path = run["paths"][1]
    per_axis = []
    for axis in axes:
        cells = [{"scenarios": 0, "outcomes": {o: 0 for o in OUTCOMES}, "judged_stops": 0, "restarts": 0,
                  "sticking_s": [], "final_error_m": [], "no_value": 0} for _ in range(bins)]
        scenario_bin = {}
        for row in run["scenarios"]:
            k = bin_of(number(row.get(axis["column"]), path, axis["column"]), axis, bins)
            if k is None:  # (a run without the column's values: counted apart, never dropped)
                scenario_bin[row["scenario"]] = None
                continue
            scenario_bin[row["scenario"]] = k
            c = cells[k]
            c["scenarios"] += 1
            c["outcomes"][row["outcome"]] += 1
            e = number(row["final_error_m"], path, "final_error_m")
            if e is not None:
                c["final_error_m"].append(e)
        unplaced = sum(1 for k in scenario_bin.values() if k is None)
        for s in run["stops"]:
            k = scenario_bin[s["scenario"]]
            if k is None or s["outcome"] not in JUDGED_FATES:
                continue
            cells[k]["judged_stops"] += 1
            if s["outcome"] == "restart":
                cells[k]["restarts"] += 1
                cells[k]["sticking_s"].append(number(s["sticking_s"], run["paths"][0], "sticking_s"))
        per_axis.append({"cells": cells, "unplaced": unplaced})
    return per_axis


def grid_tally(run, x_axis, y_axis, bins):
    """Over set point x a tolerance: judged stops, restarts, final errors per cell."""
    path = run["paths"][1]
    judged = [[0] * bins for _ in range(bins)]
    restarts = [[0] * bins for _ in range(bins)]
    errors = [[[] for _ in range(bins)] for _ in range(bins)]
    cell = {}
    for row in run["scenarios"]:
        i = bin_of(number(row.get(x_axis["column"]), path, x_axis["column"]), x_axis, bins)
        j = bin_of(number(row.get(y_axis["column"]), path, y_axis["column"]), y_axis, bins)
        if i is None or j is None:
            continue
        cell[row["scenario"]] = (i, j)
        e = number(row["final_error_m"], path, "final_error_m")
        if e is not None:
            errors[j][i].append(e)
    for s in run["stops"]:
        if s["scenario"] in cell and s["outcome"] in JUDGED_FATES:
            i, j = cell[s["scenario"]]
            judged[j][i] += 1
            restarts[j][i] += s["outcome"] == "restart"
    return judged, restarts, errors


def percentile(values, q):
    import numpy as np
    return float(np.percentile(values, q)) if values else float("nan")


def summary(runs, axes, tallies, bins):
    out = {"bins": bins, "axes": [{k: a[k] for k in ("column", "label", "lo", "hi")} for a in axes], "runs": []}
    for run, per_axis in zip(runs, tallies):
        fates = {}
        for s in run["stops"]:
            fates[s["outcome"]] = fates.get(s["outcome"], 0) + 1
        outcomes = {o: sum(1 for r in run["scenarios"] if r["outcome"] == o) for o in OUTCOMES}
        r = {"label": run["label"], "stops_file": run["paths"][0], "scenarios_file": run["paths"][1],
             "scenarios": len(run["scenarios"]), "outcomes": outcomes, "stops": len(run["stops"]),
             "stops_by_fate": fates, "axes": []}
        for axis, t in zip(axes, per_axis):
            r["axes"].append({
                "column": axis["column"], "unplaced": t["unplaced"],
                "bins": [{"scenarios": c["scenarios"], "outcomes": c["outcomes"], "judged_stops": c["judged_stops"],
                          "restarts": c["restarts"],
                          "restart_probability": c["restarts"] / c["judged_stops"] if c["judged_stops"] else None,
                          "final_error_p50_m": percentile(c["final_error_m"], 50) if c["final_error_m"] else None,
                          "sticking_p50_s": percentile(c["sticking_s"], 50) if c["sticking_s"] else None}
                         for c in t["cells"]]})
        out["runs"].append(r)
    return out


def title_of(runs):
    return "; ".join(f"{r['label']}: {len(r['scenarios'])} scenarios, {len(r['stops'])} stops" for r in runs)


def plot_profiles(plt, np, runs, axes, tallies, bins, path):
    ncol = len(axes)
    fig, grid = plt.subplots(4, ncol, figsize=(2.9 * ncol + 0.8, 10.5), squeeze=False, sharex="col")
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for a, axis in enumerate(axes):
        edges = np.linspace(axis["lo"], axis["hi"], bins + 1)
        mids = 0.5 * (edges[1:] + edges[:-1])
        width = edges[1] - edges[0]
        for r, (run, per_axis) in enumerate(zip(runs, tallies)):
            cells = per_axis[a]["cells"]
            color = colors[r % len(colors)]
            n = np.array([c["judged_stops"] for c in cells], float)
            k = np.array([c["restarts"] for c in cells], float)
            with np.errstate(invalid="ignore", divide="ignore"):
                p = np.where(n > 0, k / n, np.nan)
                se = np.where(n > 0, np.sqrt(p * (1 - p) / np.maximum(n, 1)), np.nan)
            grid[0][a].errorbar(mids, p, yerr=se, color=color, marker="o", ms=3, capsize=2, label=run["label"])
            for row, key, scale, qs in ((1, "sticking_s", 1.0, (10, 50, 90)), (2, "final_error_m", 1e6, (50, 50, 90))):
                lo = np.array([percentile(c[key], qs[0]) for c in cells]) * scale
                mid = np.array([percentile(c[key], qs[1]) for c in cells]) * scale
                hi = np.array([percentile(c[key], qs[2]) for c in cells]) * scale
                if key == "sticking_s":
                    grid[row][a].fill_between(mids, lo, hi, color=color, alpha=0.2, step="mid")
                    grid[row][a].plot(mids, mid, color=color, marker="o", ms=3)
                else:
                    grid[row][a].plot(mids, mid, color=color, marker="o", ms=3)
                    grid[row][a].plot(mids, hi, color=color, ls="--", lw=1)
            # Outcomes: stacked fractions, one bar per run side by side in the bin.
            bar_w = width / (len(runs) + 0.5)
            x = edges[:-1] + bar_w * (r + 0.25)
            total = np.array([max(c["scenarios"], 1) for c in cells], float)
            bottom = np.zeros(bins)
            for o in OUTCOMES:
                f = np.array([c["outcomes"][o] for c in cells], float) / total
                grid[3][a].bar(x, f, width=bar_w * 0.95, bottom=bottom, align="edge", color=OUTCOME_COLORS[o],
                               edgecolor=color, linewidth=0.6,
                               label=(OUTCOME_LABELS.get(o, o) if a == 0 and r == 0 else None))
                bottom += f
        grid[0][a].set_ylim(-0.02, 1.02)
        grid[1][a].set_yscale("log")
        grid[2][a].set_ylim(bottom=0)
        grid[3][a].set_ylim(0, 1)
        grid[3][a].set_xlabel(axis["label"])
    grid[0][0].set_ylabel("P(restart | judged stop)")
    grid[1][0].set_ylabel("sticking before a restart [s]\n(median, 10-90 %)")
    grid[2][0].set_ylabel("final error [um]\n(median; p90 dashed)")
    grid[3][0].set_ylabel("outcome, fraction of scenarios\n(bars: " + ", ".join(r["label"] for r in runs) + ")")
    grid[0][0].legend(fontsize=8)
    grid[3][0].legend(fontsize=7, loc="lower left")
    fig.suptitle("Restart-risk atlas by set point and bench tolerance\n" + title_of(runs), fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=72)
    plt.close(fig)


def plot_maps(plt, np, runs, axes, bins, path, what):
    x_axis = axes[0] if axes[0]["column"] == "y_d_m" else None
    if x_axis is None:
        return False
    others = axes[1:]
    if not others:
        return False
    fig, grid = plt.subplots(len(others), len(runs), figsize=(3.6 * len(runs) + 1.2, 2.9 * len(others) + 0.8),
                             squeeze=False)
    cmap = plt.get_cmap("viridis").copy()
    cmap.set_bad("0.8")
    # Every panel's values first: one colour scale for the whole figure, so that runs compare.
    panels = {}
    for j, y_axis in enumerate(others):
        for r, run in enumerate(runs):
            judged, restarts, errors = grid_tally(run, x_axis, y_axis, bins)
            if what == "restart":
                n = np.array(judged, float)
                panels[j, r] = np.where(n > 0, np.array(restarts, float) / np.maximum(n, 1), np.nan)
            else:
                panels[j, r] = np.array([[percentile(c, 50) * 1e6 if c else np.nan for c in row] for row in errors])
    if what == "restart":
        norm, label = plt.Normalize(0, 1), "P(restart | judged stop)"
    else:
        every = np.concatenate([z[np.isfinite(z)] for z in panels.values()])
        norm = plt.Normalize(0, every.max()) if every.size and every.max() > 0 else None
        label = "median final error [um]"
    for (j, r), z in panels.items():
        y_axis, ax = others[j], grid[j][r]
        image = ax.pcolormesh(np.linspace(x_axis["lo"], x_axis["hi"], bins + 1),
                              np.linspace(y_axis["lo"], y_axis["hi"], bins + 1),
                              np.ma.masked_invalid(z), cmap=cmap, norm=norm, shading="flat")
        fig.colorbar(image, ax=ax, label=label)
        ax.set_xlabel(x_axis["label"])
        ax.set_ylabel(y_axis["label"])
        if j == 0:
            ax.set_title(runs[r]["label"], fontsize=10)
    kind = "Probability of a restart after a stop" if what == "restart" else "Final error"
    fig.suptitle(f"{kind} over set point x bench tolerance (grey: no value)\n" + title_of(runs), fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=72)
    plt.close(fig)
    return True


def plot_sticking(plt, np, runs, path):
    fig, ax = plt.subplots(figsize=(8, 4.5))
    every = [float(s["sticking_s"]) for run in runs for s in run["stops"] if s["outcome"] == "restart"]
    positive = [v for v in every if v > 0]
    if positive:
        edges = np.logspace(np.log10(min(positive)), np.log10(max(positive)), 40)
    else:
        edges = np.linspace(0, 1, 40)
    for run in runs:
        times = [float(s["sticking_s"]) for s in run["stops"] if s["outcome"] == "restart"]
        stuck = sum(1 for s in run["stops"] if s["outcome"] == "stuck_to_end")
        other = len(run["stops"]) - len(times) - stuck
        ax.hist([max(t, edges[0]) for t in times], bins=edges, histtype="step", lw=1.5,
                label=f"{run['label']}: {len(times)} restarts; {stuck} stuck to the end, {other} not judged")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("sticking time before the restart [s]")
    ax.set_ylabel("restarts")
    ax.legend(fontsize=8)
    ax.set_title("The sticking time's distribution\n" + title_of(runs), fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=72)
    plt.close(fig)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--run", action="append", required=True, metavar="LABEL=DIR",
                    help="a merged sweep: DIR with sweep.csv and scenarios.csv, or STOPS.csv,SCENARIOS.csv")
    ap.add_argument("--out-dir", required=True)
    ap.add_argument("--prefix", default="atlas")
    ap.add_argument("--bins", type=int, default=10)
    ap.add_argument("--summary-json", metavar="FILE")
    args = ap.parse_args(argv)
    try:
        if args.bins < 2:
            raise BadInput("--bins must be >= 2")
        runs = [load_run(spec) for spec in args.run]
        axes = axes_of(runs)
        tallies = [tally(run, axes, args.bins) for run in runs]
    except BadInput as e:
        print(f"atlas.py: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    os.makedirs(args.out_dir, exist_ok=True)
    written = []
    stem = os.path.join(args.out_dir, args.prefix)
    plot_profiles(plt, np, runs, axes, tallies, args.bins, stem + "_profiles.png")
    written.append(stem + "_profiles.png")
    for what, name in (("restart", "_restart_map.png"), ("error", "_final_error_map.png")):
        if plot_maps(plt, np, runs, axes, args.bins, stem + name, what):
            written.append(stem + name)
    plot_sticking(plt, np, runs, stem + "_sticking.png")
    written.append(stem + "_sticking.png")
    if args.summary_json:
        with open(args.summary_json, "w") as f:
            json.dump(summary(runs, axes, tallies, args.bins), f, indent=1)
        written.append(args.summary_json)
    for run in runs:
        counts = ", ".join(f"{OUTCOME_LABELS.get(o, o)} {sum(1 for r in run['scenarios'] if r['outcome'] == o)}"
                           for o in OUTCOMES)
        print(f"atlas.py: {run['label']}: {len(run['scenarios'])} scenarios ({counts}), {len(run['stops'])} stops")
    for w in written:
        print(f"  wrote {w}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
