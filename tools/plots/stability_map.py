#!/usr/bin/python3
"""stability_map: the stability map of the law of Eq. 4 over the stroke, as a figure.

Reads the map that `pneu-plant tune --csv MAP.csv` writes (one row per law and position: the
gains, the largest real part of the continuous 4th-order closed loop's poles, the largest |z| of
the sampled loop's and its gain margin) or, without --map, runs `pneu-plant tune` on --config
itself, and writes

  OUT.png/.svg   top: max Re(s) of the continuous closed loop [1/s] against the position, one
                 line per law (the paper's fixed gains, the designed schedule); middle: max |z|
                 of the sampled loop (pneud's period, differentiator and timing); bottom: the
                 sampled loop's gain margin. Where a law is unstable the stroke is shaded.
                 The title names the map file or tune's configuration and --set; fixed gains
                 are named by their values (the paper's as such).

Exit codes: 0 written, 2 bad input (missing file, missing column, malformed value), 1 anything
else.
"""

import argparse
import csv
import os
import shutil
import subprocess
import sys
import tempfile

EXIT_BAD_INPUT = 2
COLUMNS = ("law", "y_m", "max_real_part_1_per_s", "max_abs_z", "gain_margin", "position_gain_v_per_m")
STYLE = {"fixed": "tab:red", "scheduled": "tab:blue"}
PAPER_GAINS = (80.0, 1.5, 0.002)  # Brun et al. 2005: K_p [V/m], K_v [V/(m/s)], K_a [V/(m/s^2)]
GAIN_COLUMNS = ("position_gain_v_per_m", "velocity_gain_v_s_per_m", "acceleration_gain_v_s2_per_m")


def law_label(law, rows):
    """The law's legend entry: fixed gains with their values (the paper's named as such)."""
    if law == "scheduled":
        return "designed schedule"
    if law == "fixed" and all(c in rows[0] for c in GAIN_COLUMNS):
        gains = tuple(rows[0][c] for c in GAIN_COLUMNS)
        text = f"{gains[0]:g} V/m, {gains[1]:g} V/(m/s), {gains[2]:g} V/(m/s$^2$)"
        paper = all(abs(g - p) <= 1e-9 * p for g, p in zip(gains, PAPER_GAINS))
        return ("paper's fixed gains" if paper else "fixed gains") + f" ({text})"
    return law


class InputError(Exception):
    """Bad user input: reported on stderr with exit code 2."""


def read_map(path):
    if not os.path.isfile(path):
        raise InputError(f"map: no such file: {path}")
    laws = {}
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        missing = [c for c in COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise InputError(f"{path}: missing column(s) {', '.join(missing)}")
        for line, row in enumerate(reader, start=2):
            try:
                values = {c: float(row[c]) for c in COLUMNS + GAIN_COLUMNS
                          if c != "law" and row.get(c) not in (None, "")}
            except (TypeError, ValueError):
                raise InputError(f"{path}:{line}: malformed number")
            laws.setdefault(row["law"], []).append(values)
    if not laws:
        raise InputError(f"{path}: no rows")
    return laws


def run_tune(pneu_plant, config, step_mm, extra):
    exe = pneu_plant or shutil.which("pneu-plant")
    if not exe:
        raise InputError("pneu-plant not found: put it on PATH or give --pneu-plant")
    out = tempfile.NamedTemporaryFile(suffix=".csv", delete=False).name
    cmd = [exe, "tune", "--step-mm", str(step_mm), "--csv", out] + (["--config", config] if config else [])
    for s in extra:
        cmd += ["--set", s]
    done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        raise InputError(f"{' '.join(cmd)}: exit {done.returncode}: {done.stderr.strip()}")
    return out


def figure(laws, source, out_stem, dpi):
    try:
        import matplotlib
    except ImportError:
        raise InputError("matplotlib is missing (Debian package python3-matplotlib)") from None
    matplotlib.use("Agg")
    # As pneu_plots.py: reproducible files (no date, fixed SVG ids), text kept as text.
    matplotlib.rcParams.update({"svg.hashsalt": "stability_map", "svg.fonttype": "none"})
    import matplotlib.pyplot as plt

    fig, (ax_s, ax_z, ax_m) = plt.subplots(3, 1, figsize=(10, 9.5), sharex=True)
    for law, rows in laws.items():
        color, label = STYLE.get(law, "tab:gray"), law_label(law, rows)
        y_mm = [r["y_m"] * 1e3 for r in rows]
        ax_s.plot(y_mm, [r["max_real_part_1_per_s"] for r in rows], "o-", ms=3, color=color, label=label)
        ax_z.plot(y_mm, [r["max_abs_z"] for r in rows], "o-", ms=3, color=color, label=label)
        ax_m.plot(y_mm, [r["gain_margin"] if r["gain_margin"] > 0 else float("nan") for r in rows], "o-", ms=3,
                  color=color, label=label)
        # The stretches where this law is unstable (continuous or sampled), shaded on every panel.
        for i, r in enumerate(rows):
            if r["max_real_part_1_per_s"] >= 0 or r["max_abs_z"] >= 1:
                lo = (rows[i - 1]["y_m"] + r["y_m"]) / 2 if i > 0 else r["y_m"]
                hi = (rows[i + 1]["y_m"] + r["y_m"]) / 2 if i + 1 < len(rows) else r["y_m"]
                for ax in (ax_s, ax_z, ax_m):
                    ax.axvspan(lo * 1e3, hi * 1e3, color=color, alpha=0.08, lw=0)
    ax_s.axhline(0.0, color="k", lw=0.8)
    ax_s.set_ylabel("max Re(s) [1/s]")
    ax_s.set_title("Continuous 4th-order closed loop, exact v and a (stable below 0)")
    ax_z.axhline(1.0, color="k", lw=0.8)
    ax_z.set_ylabel("max |z|")
    ax_z.set_title("Sampled loop as pneud runs it: 1 kHz, zero-order hold, differentiator (stable below 1)")
    ax_z.ticklabel_format(axis="y", useOffset=False)
    ax_m.set_ylabel("gain margin [x]")
    ax_m.set_title("Sampled loop: the factor by which all three gains may grow before it is unstable")
    ax_m.set_xlabel("position y [mm] (from mid-stroke)")
    ax_m.set_ylim(bottom=0)
    ax_m.legend(loc="center", fontsize=9)
    for ax in (ax_s, ax_z, ax_m):
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"Stability map of Eq. 4 over the stroke ({source})")
    fig.tight_layout()
    fig.savefig(f"{out_stem}.png", dpi=dpi, metadata={"Software": None})
    fig.savefig(f"{out_stem}.svg", metadata={"Date": None})
    plt.close(fig)


def map_source(args):
    """What the map was computed on, for the title: the map file, or tune's configuration."""
    if args.map:
        return f"the map {os.path.basename(args.map)} of pneu-plant tune --csv"
    bench = os.path.basename(args.config) if args.config else "the embedded sim.yaml"
    return f"pneu-plant tune on {bench}" + "".join(f" --set {s}" for s in args.set) \
        + f", every {args.step_mm:g} mm"


def main(argv):
    p = argparse.ArgumentParser(description="The stability map of pneu-plant tune as a figure.")
    p.add_argument("--map", help="MAP.csv from pneu-plant tune --csv (default: run pneu-plant tune)")
    p.add_argument("--config", help="configuration for pneu-plant tune (default: its embedded sim.yaml)")
    p.add_argument("--set", action="append", default=[], help="KEY=VALUE for pneu-plant tune (repeatable)")
    p.add_argument("--step-mm", type=float, default=5.0, help="positions every N mm (default 5)")
    p.add_argument("--pneu-plant", help="the pneu-plant executable (default: from PATH)")
    p.add_argument("--out", default="stability_map", help="output stem: OUT.png and OUT.svg")
    p.add_argument("--dpi", type=int, default=110)
    args = p.parse_args(argv)
    try:
        path = args.map or run_tune(args.pneu_plant, args.config, args.step_mm, args.set)
        laws = read_map(path)
        figure(laws, map_source(args), args.out, args.dpi)
    except InputError as e:
        print(f"stability_map: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print(f"stability_map: {args.out}.png, {args.out}.svg")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
