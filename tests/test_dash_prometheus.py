#!/usr/bin/python3
"""A real Prometheus (Debian's prometheus) scrapes pneu-dash's /metrics and answers a query on the
restart counter. Run inside a private network namespace (tests/in_private_netns.sh): pneud on the
real clock runs the paper's set-point step (the default bench: the carriage sticks and restarts),
pneu-dash listens to its LCM channels and serves /metrics on 127.0.0.1, Prometheus scrapes it every
second into a temporary directory; the answer to pneu_restarts_total{bench="..."} must be the number
of restarts in pneud's own events file. Both servers are stopped by their process ids.

Usage: test_dash_prometheus.py BIN_DIR   (the build's bin/: pneud, pneu-dash)
Exits 77 (ctest: skipped) with the reason when prometheus is not installed."""
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request

BENCH = "bench-under-test"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def get(url, timeout=2.0):
    with urllib.request.urlopen(url, timeout=timeout) as r:
        return r.status, r.read().decode()


def eventually(check, limit_s, every_s=0.2):
    """check()'s first true value within limit_s, else its last value."""
    until = time.monotonic() + limit_s
    while True:
        value = check()
        if value or time.monotonic() >= until:
            return value
        time.sleep(every_s)


def stop(proc, name):
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
            print(f"{name} (pid {proc.pid}) did not stop on SIGTERM within 10 s: killed", file=sys.stderr)


def main():
    bin_dir = sys.argv[1]
    prometheus = shutil.which("prometheus")
    if prometheus is None or shutil.which("promtool") is None:
        print("SKIPPED: prometheus and promtool (Debian's prometheus, in scripts/deps) are not installed",
              file=sys.stderr)
        return 77
    tmp = tempfile.mkdtemp(prefix="dash_prometheus_")
    dash_port, prom_port = free_port(), free_port()
    procs = []
    failed = True
    try:
        def spawn(name, args):
            p = subprocess.Popen(args, stdout=open(os.path.join(tmp, name + ".out"), "w"),
                                 stderr=open(os.path.join(tmp, name + ".err"), "w"))
            procs.append((p, name))
            return p

        def log(name):
            return open(os.path.join(tmp, name + ".err")).read()[-3000:]

        dash = spawn("pneu-dash", [os.path.join(bin_dir, "pneu-dash"), "--listen", f"127.0.0.1:{dash_port}",
                                   "--bench", BENCH])
        metrics_url = f"http://127.0.0.1:{dash_port}/metrics"

        def dash_serves():
            try:
                status, text = get(metrics_url)
                return status == 200 and f'pneu_restarts_total{{bench="{BENCH}"}} 0' in text
            except OSError:
                return False
        if not eventually(dash_serves, 15):
            print(f"pneu-dash does not serve {metrics_url} within 15 s:\n{log('pneu-dash')}", file=sys.stderr)
            return 1

        config = os.path.join(tmp, "prometheus.yml")
        with open(config, "w") as f:
            f.write("global: {scrape_interval: 1s, evaluation_interval: 1s}\n"
                    "scrape_configs:\n"
                    "  - job_name: pneu\n"
                    f"    static_configs: [{{targets: ['127.0.0.1:{dash_port}']}}]\n")
        prom = spawn("prometheus", [prometheus, f"--config.file={config}",
                                    f"--storage.tsdb.path={os.path.join(tmp, 'tsdb')}",
                                    f"--web.listen-address=127.0.0.1:{prom_port}"])

        def query(q):
            try:
                _, body = get(f"http://127.0.0.1:{prom_port}/api/v1/query?" + urllib.parse.urlencode({"query": q}))
                answer = json.loads(body)
                return answer["data"]["result"] if answer.get("status") == "success" else None
            except (OSError, ValueError, KeyError):
                return None
        if not eventually(lambda: query(f'up{{job="pneu"}} == 1'), 30):
            print(f"prometheus has not scraped pneu-dash within 30 s:\n{log('prometheus')}", file=sys.stderr)
            return 1

        # The paper's step on the default bench, on the real clock, its loop-timing faults off (a shared
        # machine stalls now and then; timing is not this test's business), its loop on SCHED_FIFO
        # where permitted (a warning otherwise): its restart within 5 s needs the loop on time.
        events = os.path.join(tmp, "events.jsonl")
        pneud = subprocess.run([os.path.join(bin_dir, "pneud"), "--clock", "real", "--duration", "5",
                                "--require-telemetry", "--quiet", "--events", events,
                                "--set", "controller.realtime.priority=40",
                                "--set", "controller.supervisor.overruns_in_a_row=0",
                                "--set", "controller.supervisor.max_tick_interval_s=0"],
                               capture_output=True, text=True, timeout=60)
        if pneud.returncode != 0:
            print(f"pneud failed ({pneud.returncode}):\n{pneud.stderr}", file=sys.stderr)
            return 1
        with open(events) as f:
            lines = [json.loads(line) for line in f]
        restarts = sum(1 for e in lines if e.get("event") == "start" and e.get("restart") is True)
        stops = sum(1 for e in lines if e.get("event") == "stop")
        print(f"pneud's events: {stops} stops, {restarts} restarts")
        if restarts < 1:
            print(f"the paper's step on the default bench restarts after a stop: none in\n{open(events).read()}",
                  file=sys.stderr)
            return 1

        q = f'pneu_restarts_total{{bench="{BENCH}"}}'
        last = None

        def answers():
            nonlocal last
            last = query(q)
            return bool(last) and float(last[0]["value"][1]) == restarts
        if not eventually(answers, 20):
            print(f"prometheus answers {q} with {json.dumps(last)}, not {restarts} within 20 s\n"
                  f"pneu-dash's /metrics:\n{get(metrics_url)[1]}", file=sys.stderr)
            return 1
        print(f"prometheus answers {q}: {json.dumps(last)}")
        stops_answer = query(f'pneu_stops_total{{bench="{BENCH}"}}')
        if not stops_answer or float(stops_answer[0]["value"][1]) != stops:
            print(f"pneu_stops_total: {json.dumps(stops_answer)}, pneud's events: {stops}", file=sys.stderr)
            return 1
        # The whole of /metrics (the server's own counters too): promtool parses and lints it clean,
        # and every series is the bench's.
        text = get(metrics_url)[1]
        promtool = subprocess.run([shutil.which("promtool"), "check", "metrics"], input=text,
                                  capture_output=True, text=True)
        if promtool.returncode != 0:
            print(f"promtool check metrics on pneu-dash's /metrics: {promtool.stdout}{promtool.stderr}\n{text}",
                  file=sys.stderr)
            return 1
        unlabelled = [line for line in text.splitlines()
                      if line and not line.startswith("#") and f'{{bench="{BENCH}"' not in line]
        if unlabelled:
            print("series without the bench label first:\n" + "\n".join(unlabelled), file=sys.stderr)
            return 1
        failed = False
        return 0
    finally:
        for p, name in reversed(procs):
            stop(p, name)
        if failed:
            print(f"kept for a look: {tmp}", file=sys.stderr)
        else:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
