#!/usr/bin/python3
"""docs/dashboard.md's Prometheus examples are ones Prometheus takes: its first yaml block (the scrape
configuration for many benches) passes `promtool check config`, and every PromQL query it shows (the
promql blocks and the queries table) parses, checked as recording rules by `promtool check rules`.

Usage: test_dashboard_doc_prometheus.py SOURCE_DIR
Exits 77 (ctest: skipped) with the reason when promtool is not installed."""
import os
import re
import shutil
import subprocess
import sys
import tempfile


def main():
    promtool = shutil.which("promtool")
    if promtool is None:
        print("SKIPPED: promtool (Debian's prometheus, in scripts/deps) is not installed", file=sys.stderr)
        return 77
    doc = open(os.path.join(sys.argv[1], "docs", "dashboard.md")).read()
    blocks = re.findall(r"```(\w+)\n(.*?)```", doc, re.S)
    configs = [b for kind, b in blocks if kind == "yaml" and "scrape_configs:" in b]
    queries = [b.strip() for kind, b in blocks if kind == "promql"]
    table = doc[doc.index("### Queries"):]
    queries += [q.replace("\\|", "|") for q in re.findall(r"^\| [^|`]*\| `(.*)` \|$", table, re.M)]
    if len(configs) != 1 or len(queries) < 5:
        print(f"docs/dashboard.md: expected one scrape configuration and its queries, found {len(configs)} "
              f"and {len(queries)}", file=sys.stderr)
        return 1
    failures = 0
    with tempfile.TemporaryDirectory(prefix="dashboard_doc_") as tmp:
        config = os.path.join(tmp, "prometheus.yml")
        with open(config, "w") as f:
            f.write(configs[0])
        rules = os.path.join(tmp, "rules.yml")
        with open(rules, "w") as f:
            f.write("groups:\n  - name: dashboard_md\n    rules:\n")
            for i, q in enumerate(queries):
                f.write(f"      - record: dashboard_md:query_{i}\n        expr: '{q.replace(chr(39), chr(39) * 2)}'\n")
        for args, what in (([promtool, "check", "config", "--syntax-only", config], "the scrape configuration"),
                           ([promtool, "check", "rules", rules], f"the {len(queries)} queries")):
            r = subprocess.run(args, capture_output=True, text=True)
            print(f"{what}: promtool exit {r.returncode}")
            if r.returncode != 0:
                print(f"{r.stdout}{r.stderr}\n{open(args[-1]).read()}", file=sys.stderr)
                failures += 1
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
