#!/usr/bin/python3
"""The longest stall of pneud's service thread on the real clock, seen from systemd's side.

Runs PNEUD (the simulated bench, the real clock) under a fake NOTIFY_SOCKET with a watchdog of
WATCHDOG_USEC = 40 ms, so that pneud pets it every 10 ms while its service thread runs and the
loop ticks (controller/app/systemd_notifier.cpp). The service thread pets between drains: the
longest gap between two WATCHDOG=1 messages is the longest the service thread was away (draining,
learning, handling LCM). Set points every STEP_S seconds, `0.2 m sin(2.4 i)` (a different step
each time, as in bench/soak_online_learning.sh), so that the carriage stops after breakaways.

    bench/service_thread_stall.py PNEUD [SECONDS] [STEP_S] [--set KEY=VALUE ...]

Prints the gaps' count, median, 99th percentile and maximum, and pneud's summary lines about
online identification; exit 1 when pneud fails.
"""
import math
import os
import socket
import subprocess
import sys
import tempfile
import time

pneud = sys.argv[1]
seconds = float(sys.argv[2]) if len(sys.argv) > 2 and not sys.argv[2].startswith("--") else 20.0
step_s = float(sys.argv[3]) if len(sys.argv) > 3 and not sys.argv[3].startswith("--") else 2.0
extra = [a for a in sys.argv[2:] if a.startswith("--set") or "=" in a]

with tempfile.TemporaryDirectory(prefix="pneu_stall_") as d:
    path = os.path.join(d, "notify")
    s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    s.bind(path)
    s.settimeout(0.1)
    points = ", ".join("{t_s: %.1f, position_m: %.6f}" % (step_s * i, 0.2 * math.sin(2.4 * i))
                       for i in range(1, int(seconds / step_s) + 1))
    env = dict(os.environ, NOTIFY_SOCKET=path, WATCHDOG_USEC="40000")
    args = [pneud, "--clock", "real", "--duration", str(seconds),
            "--set", "controller.setpoints.schedule=[%s]" % points,
            "--set", "controller.supervisor.overruns_in_a_row=0",
            "--set", "controller.supervisor.max_tick_interval_s=0",
            "--set", "telemetry.enabled=false"] + extra
    p = subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    pets = []
    while p.poll() is None:
        try:
            m = s.recv(4096).decode()
        except socket.timeout:
            continue
        if "WATCHDOG=1" in m:
            pets.append(time.monotonic())
    out, err = p.communicate()
    gaps = sorted(b - a for a, b in zip(pets, pets[1:]))
    if p.returncode != 0 or not gaps:
        print(f"pneud exited {p.returncode}, {len(pets)} pets\n{err}")
        sys.exit(1)
    q = lambda f: gaps[min(len(gaps) - 1, int(f * len(gaps)))]
    print(f"{len(pets)} WATCHDOG=1 in {seconds:g} s: gap median {q(0.5) * 1e3:.1f} ms, "
          f"p99 {q(0.99) * 1e3:.1f} ms, max {gaps[-1] * 1e3:.1f} ms")
    for line in out.splitlines():
        if "online identification" in line or "updates" in line or "loop:" in line:
            print("  " + line.strip())
