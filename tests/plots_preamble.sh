# Sourced by the plotting tools' tests (test_plots.sh, test_plots_runs.sh) after they set `bin` (the
# build's bin/) and `src` (the source tree): the tool and its checker, a skip (exit 77) saying which
# Debian packages are missing, fail(), this build's programs first on PATH, and a scratch
# directory `tmp` (each test sets its own trap to remove it).
py=/usr/bin/python3
tool="$src/tools/plots/pneu_plots.py"
check="$src/tests/check_plot_figures.py"
if ! "$py" -c "import matplotlib, numpy, yaml" 2>/dev/null; then
  echo "SKIPPED: $py lacks matplotlib, numpy or yaml (Debian packages python3-matplotlib," \
       "python3-numpy, python3-yaml)" >&2
  exit 77
fi
fail() { echo "FAIL: $*" >&2; exit 1; }
export PATH="$bin:$PATH"  # where the tool looks for pneu-plant when not told
tmp=$(mktemp -d)
