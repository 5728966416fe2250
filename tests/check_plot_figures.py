#!/usr/bin/python3
"""Draws a run's figures with pneu_plots.py's own functions and checks them as matplotlib objects:
each title names the run (the --title strings) and writes no time with an exponent; the file
stem is the run's (--stem, a regular expression); no two stop labels of a panel overlap and the
whole record's panel numbers every stop; the plane's close-up stays a close-up of its panel; with
--held, the time figure marks the holds and reaches and draws none of the law's forecast
restarts a hold or reach superseded (and there are some: the check is not vacuous).

Usage: check_plot_figures.py TOOL [--title TEXT ...] [--stem REGEX] [--held] -- PNEU_PLOTS_ARGS...
Exit 0 when every check holds, 1 naming the first that fails.
"""

import argparse
import importlib.util
import itertools
import re
import sys


def fail(what):
    print(f"check_plot_figures: FAIL: {what}", file=sys.stderr)
    sys.exit(1)


def load_tool(path):
    spec = importlib.util.spec_from_file_location("pneu_plots", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


STOP_LABEL = re.compile(r"^\d+(-\d+)?(, \d+(-\d+)?)*$")
EXPONENT = re.compile(r"\d[eE][-+]?\d")


def stop_labels(ax):
    return [t for t in ax.texts if STOP_LABEL.match(t.get_text())]


def indices_of(text):
    out = set()
    for part in text.split(", "):
        a, _, b = part.partition("-")
        out |= set(range(int(a), int(b or a) + 1))
    return out


def check_titles(made, titles):
    for suffix, fig in made.figures:
        title = fig._suptitle.get_text() if fig._suptitle else ""
        for text in titles:
            if text not in title:
                fail(f"the {suffix} figure's title lacks '{text}': {title!r}")
        for ax in fig.axes:
            for t in [title, ax.get_title(), ax.get_title("left")]:
                if EXPONENT.search(t):
                    fail(f"the {suffix} figure writes a number with an exponent: {t!r}")


def check_stop_labels(made):
    for suffix, fig in made.figures:
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        for ax in fig.axes:
            boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in stop_labels(ax)]
            for (ta, a), (tb, b) in itertools.combinations(boxes, 2):
                if a.overlaps(b):
                    fail(f"the {suffix} figure's stop labels '{ta}' and '{tb}' overlap")
    plane = dict(made.figures)["plane"]
    labelled = set()
    for t in stop_labels(plane.axes[0]):
        labelled |= indices_of(t.get_text())
    every = {s["index"] for s in made.run.stops}
    if labelled != every:
        fail(f"the whole record's panel numbers stops {sorted(labelled)}, the run has {sorted(every)}")


def check_close_up(made, tool):
    axes = dict(made.figures)["plane"].axes
    if len(made.run.stops) == 0:
        return
    outer, close = axes[1], axes[2]
    for lim in ("get_xlim", "get_ylim"):
        o, c = getattr(outer, lim)(), getattr(close, lim)()
        if c[1] - c[0] > tool.CLOSE_UP_MAX * (o[1] - o[0]) * 1.001:
            fail(f"the plane's close-up spans {c[1] - c[0]:.2f} N of its panel's {o[1] - o[0]:.2f} N")


def check_held(made, tool):
    run = made.run
    if not run.holds:
        fail("the held run has no holds")
    time_fig = dict(made.figures)["time"]
    ax_y = time_fig.axes[0]
    labels = ax_y.get_legend_handles_labels()[1]
    kinds = {"hold" if h["reach"] == 0 else "reach" for h in run.holds}
    for kind in kinds:
        if tool.HOLD_SHORT_LABELS[kind] not in labels:
            fail(f"the time figure's legend lacks '{tool.HOLD_SHORT_LABELS[kind]}': {labels}")
    if "held within the window (to hold_end)" not in labels and "hold" in kinds:
        fail(f"the time figure does not mark the holds' spans: {labels}")
    superseded = tool.law_forecasts(run)[1]
    if not superseded:
        fail("no forecast restart was superseded by a hold: the check would be vacuous")
    markers = [(line.get_marker(), x) for line in ax_y.get_lines() for x in line.get_xdata()]
    for p in superseded:
        style = tool.METHOD_STYLE[p["method"]]["marker"]
        if (style, p["t_restart"]) in markers:
            fail(f"the time figure draws stop {p['stop']}'s {p['method']} forecast restart at "
                 f"t = {p['t_restart']} s although a hold or reach took over before it")
    title = time_fig._suptitle.get_text()
    if "held to the end" not in title:
        fail(f"the time figure's title does not say what was held: {title!r}")


def main(argv):
    split = argv.index("--")
    p = argparse.ArgumentParser()
    p.add_argument("tool")
    p.add_argument("--title", action="append", default=[])
    p.add_argument("--stem")
    p.add_argument("--held", action="store_true")
    args = p.parse_args(argv[:split])
    tool = load_tool(args.tool)
    made = tool.make_figures(tool.parse_args(argv[split + 1:]))
    check_titles(made, args.title)
    if args.stem and not re.fullmatch(args.stem, made.name):
        fail(f"the file stem is {made.name!r}, not {args.stem!r}")
    check_stop_labels(made)
    check_close_up(made, tool)
    if args.held:
        check_held(made, tool)
    print(f"check_plot_figures: {made.name}: {', '.join(s for s, _ in made.figures)}: "
          f"{len(made.run.stops)} stops, {len(made.run.holds)} holds and reaches")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
