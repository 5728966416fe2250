#!/usr/bin/python3
"""The dashboard in a real browser (issue 31): headless Chromium (Debian's chromium and
chromium-driver, driven by python3-selenium) opens pneu-dash's page while pneud runs the paper's
scenario on the real clock (the step to 170 mm at t = 1 s; its second stop sticks about 2.5 s).
It must hold that the traces advance; that the pressure-force plane gets its geometry (the areas
and the null-flow curve) and, during the sticking phase, shows the stuck state point, the forecast
path and the forecast restart time counting down; that the actual restart is then marked at the
time pneud's events file gives. A screenshot of the page during the sticking phase is written to
OUT_DIR/dashboard.png (docs/img/dashboard.png is one of them).

The page asks for the ticks at most at 60 Hz (/?max_rate_hz=60), as on a 60 Hz display: pneu-dash
sends it the newest tick at most every 1/60 s and reports what it skipped. Every tick of the run
must be received, reported skipped or counted lost by the page, and the skipped ones must be those
pneu-dash counted (its /metrics): decimation is never shown as loss, and a loss never hidden as
decimation.

The sim backend on the real clock integrates the plant over the time that really passed: on a loaded
machine, deadlines skipped change the run itself, and its long sticking phase may not come (seen:
a run with 236 deadlines skipped stopped eleven times for 0.2 s at most). pneud's loop asks for
SCHED_FIFO (a warning where refused); a run that had no sticking phase of 0.5 s is run again (a new
pneu-dash, the page loaded again), up to ATTEMPTS runs, each attempt's figures printed. A run
without deadlines skipped must have it; when every run skipped deadlines and none had it, the test
skips saying so (the page was not shown what it is tested on).

Run inside tests/in_private_netns.sh (LCM multicast stays in a namespace of the test's own):
  test_dash_browser.py BIN_DIR SOURCE_DIR OUT_DIR
Exit codes: 0 passed, 1 failed (FAIL: what), 77 skipped (SKIPPED: why: no browser, no selenium).
"""
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
RUN_S = 7.0                  # pneud's run: the step at 1 s, the long sticking phase ends near 3.9 s
ATTEMPTS = 3                 # runs of pneud, while none had a sticking phase of LONG_PHASE_S
LONG_PHASE_S = 0.5
MAX_RATE_HZ = 60             # the page's request for the ticks


def skip(why):
    print(f"SKIPPED: {why}")
    sys.exit(77)


def fail(why, logs=()):
    print(f"FAIL: {why}")
    for path in logs:
        try:
            with open(path, encoding="utf-8", errors="replace") as f:
                print(f"--- {path}\n{f.read()[-4000:]}")
        except OSError:
            pass
    sys.exit(1)


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_http(url, seconds, what, logs):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(url, timeout=1) as r:
                if r.status == 200:
                    return r.read()
        except OSError:
            time.sleep(0.1)
    fail(f"{what} did not answer at {url} within {seconds} s", logs)


def longest_phase(events):
    """(stop, seconds) of the longest sticking phase in pneud's events file (one not ended by a
    restart lasts until the run's end event)."""
    end = next((e["t"] for e in events if e["event"] == "end"), RUN_S)
    stops = {e["stop"]: e["t"] for e in events if e["event"] == "stop"}
    restarts = {e["stop"]: e["t"] for e in events if e["event"] == "start" and e.get("restart")}
    phases = [(i, restarts.get(i, end) - t) for i, t in stops.items()]
    return max(phases, key=lambda p: p[1], default=(None, 0.0))


def watch_one_run(driver, bin_dir, work, logs, procs, shot):
    """A new pneu-dash, the page loaded from it, pneud's run watched on the page to its end."""
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    dash = subprocess.Popen([os.path.join(bin_dir, "pneu-dash"), "--listen", f"127.0.0.1:{port}"],
                            stdout=open(logs[0], "w"), stderr=subprocess.STDOUT)
    procs.append(dash)
    page = wait_http(base + "/", 20, "pneu-dash", logs).decode()
    if "chart-plane" not in page:
        fail("/ is not the dashboard page", logs)
    wait_http(base + "/js/chart.js/chart.min.js", 5, "pneu-dash's Chart.js", logs)
    driver.get(base + f"/?max_rate_hz={MAX_RATE_HZ}")

    def snap():
        return driver.execute_script("return window.pneuDash && window.pneuDash.snapshot();")

    deadline = time.monotonic() + 15
    s = snap()
    while not (s and s["connected"] and s["planeLoaded"]):
        if time.monotonic() > deadline:
            fail(f"the page did not connect and get the plane within 15 s: {json.dumps(s)}", logs)
        time.sleep(0.1)
        s = snap()
    print(f"connected; channels {s['topics']}; null-flow curve of {s['nullFlowPoints']} points")
    if s["nullFlowPoints"] < 50:
        fail(f"the plane's null-flow curve has {s['nullFlowPoints']} points")

    # pneud on the real clock, the paper's scenario; its supervision of the loop's timing off: a
    # stall of the shared machine would latch a fault (timing is not this test's subject); its loop
    # on SCHED_FIFO where permitted (a warning otherwise), Chromium's drawing does not delay it.
    events_path = os.path.join(work, "events.jsonl")
    summary_path = os.path.join(work, "summary.json")
    pneud = subprocess.Popen(
        [os.path.join(bin_dir, "pneud"), "--clock", "real", "--duration", str(RUN_S),
         "--require-telemetry", "--events", events_path, "--summary-json", summary_path,
         "--set", "controller.realtime.priority=40",
         "--set", "controller.supervisor.overruns_in_a_row=0",
         "--set", "controller.supervisor.max_tick_interval_s=0"],
        stdout=open(logs[1], "w"), stderr=open(logs[2], "w"))
    procs.append(pneud)

    advancing = []           # (wall time, loop time, trace points)
    stuck_seen = None        # the snapshot the screenshot was taken at
    countdowns = []          # (stop, loop time, countdown) while stuck with a restart forecast
    restart_seen = None
    last_stuck = None        # the last look at a stuck carriage, for the failure's message
    deadline = time.monotonic() + RUN_S + 20
    while time.monotonic() < deadline:
        s = snap()
        if s["t"] is not None:
            advancing.append((time.monotonic(), s["t"], s["tracePoints"]))
        # stuck, the forecast and its path shown; counting down when it forecasts a restart
        stuck_now = (s["stuck"] and s["stop"] and s["forecast"] and s["forecastPathPoints"] > 1
                     and s["forecastState"] == ("counting" if s["forecast"]["will_restart"] else "no-restart")
                     and s["forecastStop"] == s["stop"]["index"])  # drawn for this stop, not the last one
        if s["stuck"]:
            last_stuck = s
        if stuck_now and (stuck_seen is None or stuck_seen["stop"] == s["stop"]):
            if s["forecast"]["will_restart"]:
                countdowns.append((s["stop"]["index"], s["t"], s["countdownS"]))
            # well into a phase (the paper's second stop: about 2.5 s on an idle machine; on a
            # loaded one the real clock's phase may end otherwise)
            if stuck_seen is None and s["t"] - s["stop"]["t"] > 0.3:
                driver.save_screenshot(shot)
                after = snap()
                if after["stuck"] and after["stop"] == s["stop"]:
                    stuck_seen = s
                    print(f"screenshot at t = {s['t']:.3f} s: stop {s['stop']['index']} since "
                          f"{s['stop']['t']:.3f} s, state point {s['planePoint']} (trail: {s['trailPoints']} points, "
                          f"{s['trailSegments']} segments), forecast "
                          f"{s['forecast']}, countdown '{s['countdownText']}'")
        if stuck_seen:
            marked = [r for r in s["restarts"] if r["stop"] == stuck_seen["stop"]["index"]]
            if marked:
                restart_seen = marked[0]
                break
        if pneud.poll() is not None and s["t"] is not None and s["t"] >= RUN_S - 0.01:
            break  # the page has seen the whole run
        time.sleep(0.1)
    pneud.wait(timeout=RUN_S + 20)
    if pneud.returncode != 0:
        fail(f"pneud exited with {pneud.returncode}", logs)
    with open(events_path, encoding="utf-8") as f:
        events = [json.loads(line) for line in f if line.strip()]
    with open(summary_path, encoding="utf-8") as f:
        summary = json.load(f)
    stops = {e["stop"]: e for e in events if e["event"] == "stop"}
    return dict(dash=dash, base=base, stops=stops, stuck_seen=stuck_seen, countdowns=countdowns, restart_seen=restart_seen,
                events=events, advancing=advancing, last_stuck=last_stuck, summary=summary, snap=snap)


def main():
    if len(sys.argv) != 4:
        print(__doc__)
        sys.exit(2)
    bin_dir, source_dir, out_dir = sys.argv[1:]
    for path in (CHROMIUM, CHROMEDRIVER):
        if not os.access(path, os.X_OK):
            skip(f"{path} is missing (Debian packages chromium, chromium-driver)")
    try:
        from selenium import webdriver
        import chromium_driver
    except ImportError:
        skip("selenium is missing (Debian package python3-selenium)")

    work = tempfile.mkdtemp(prefix="pneu_dash_browser.")
    logs = [os.path.join(work, n) for n in ("dash.err", "pneud.out", "pneud.err")]
    procs = []
    driver = None
    try:
        driver, browser_procs = chromium_driver.start(
            CHROMIUM, CHROMEDRIVER, ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                                     "--window-size=1680,1180", "--hide-scrollbars", "--force-device-scale-factor=1"),
            work)
        procs.extend(browser_procs)
        driver.set_script_timeout(10)
        shot = os.path.join(out_dir, "dashboard.png")
        for number in range(1, ATTEMPTS + 1):
            run = watch_one_run(driver, bin_dir, work, logs, procs, shot)
            longest = longest_phase(run["events"])
            skipped = run["summary"]["loop"]["deadlines_skipped"] if run["summary"] else None
            print(f"run {number}: {len(run['stops'])} stops, the longest sticking phase "
                  f"{longest[1]:.3f} s (stop {longest[0]}), {skipped} deadlines skipped, "
                  f"{run['summary']['loop']['overruns'] if run['summary'] else None} overruns; "
                  f"the page {'showed' if run['stuck_seen'] else 'did not show'} a stuck carriage for 0.3 s")
            if run["stuck_seen"] is not None or longest[1] >= LONG_PHASE_S or skipped == 0:
                break  # judged below: the page saw it, or it had to
            run["dash"].terminate()
            if number < ATTEMPTS:
                print(f"run {number}: the machine's load changed the real-clock run (no sticking phase of "
                      f"{LONG_PHASE_S} s); running it again")
        else:
            skip(f"none of {ATTEMPTS} runs of pneud on the real clock had a sticking phase of {LONG_PHASE_S} s, "
                 f"each with deadlines skipped (the machine's load changed the run): the page was not shown "
                 f"the sticking phase it is tested on")
        stops, stuck_seen, countdowns, restart_seen, events, advancing, last_stuck, snap = (
            run[k] for k in ("stops", "stuck_seen", "countdowns", "restart_seen", "events", "advancing", "last_stuck",
                             "snap"))

        # The mode by its name (serverInfo's metadata, from the controller's table): pneud runs armed.
        mode = driver.execute_script("return document.getElementById('mode').dataset.mode;")
        if mode != "ARMED":
            fail(f"the page names pneud's mode {mode!r}, not 'ARMED'", logs)

        # The traces advance: over at least a second of wall time, loop time and points grew.
        first = next((a for a in advancing if a[1] > 0.2), None)
        last = advancing[-1] if advancing else None
        if not first or not last or last[0] - first[0] < 1.0 or last[1] - first[1] < 0.8 or last[2] <= first[2]:
            fail(f"the traces did not advance: first {first}, last {last}", logs)
        print(f"traces advanced: loop time {first[1]:.3f} -> {last[1]:.3f} s over "
              f"{last[0] - first[0]:.2f} s of wall time, trace points {first[2]} -> {last[2]}")

        if stuck_seen is None:
            fail(f"the page never showed a stuck carriage with its forecast and the forecast's path for "
                 f"0.3 s; pneud's stops: {list(stops.values())}; the page's last look at a stuck carriage: "
                 f"{json.dumps({k: v for k, v in (last_stuck or {}).items() if k not in ('tickTimes', 'restarts')})}",
                 logs)
        index = stuck_seen["stop"]["index"]
        if index not in stops or abs(stops[index]["t"] - stuck_seen["stop"]["t"]) > 1e-6:
            fail(f"the page's stop {stuck_seen['stop']} is not pneud's {stops.get(index)}")
        forecasts = [e for e in events if e["event"] == "prediction" and e["stop"] == index
                     and e["method"] == stuck_seen["forecast"]["method"]]
        if not forecasts:
            fail(f"pneud made no {stuck_seen['forecast']['method']} forecast at stop {index}")
        # the forecast shown is one pneud made at this stop (at the stop or again while stuck)
        made = [(e["will_restart"], e["t_restart"]) for e in events if e["event"] in ("prediction", "reforecast")
                and e["stop"] == index and e["method"] == stuck_seen["forecast"]["method"]]
        shown = (stuck_seen["forecast"]["will_restart"], stuck_seen["forecast"]["t_restart"])
        if not any(w == shown[0] and (t == shown[1] or (t is not None and shown[1] is not None
                                                        and abs(t - shown[1]) < 1e-6)) for w, t in made):
            fail(f"the page's forecast {stuck_seen['forecast']} is none of pneud's: {made}")
        # counting down: the time left falls as loop time goes on
        if stuck_seen["forecast"]["will_restart"] and len([c for c in countdowns if c[0] == index]) < 3:
            fail(f"too few looks at the countdown: {countdowns}")
        countdowns = [(t, c) for i, t, c in countdowns if i == index]
        if countdowns:
            (t0, c0), (t1, c1) = countdowns[0], countdowns[-1]
            if not (t1 - t0 > 0.3 and c1 < c0):
                fail(f"the restart countdown did not count down: {countdowns[:3]} ... {countdowns[-3:]}")
            print(f"countdown {c0:.3f} s at t = {t0:.3f} s -> {c1:.3f} s at t = {t1:.3f} s")
        else:
            print(f"stop {index}: pneud forecast no restart, the page said so (no countdown)")

        restarts = [e for e in events if e["event"] == "start" and e["stop"] == index and e["restart"]]
        if restarts:
            if restart_seen is None:
                fail(f"pneud restarted at {restarts[0]['t']} s, the page did not mark it", logs)
            if abs(restart_seen["t"] - restarts[0]["t"]) > 1e-6:
                fail(f"the page marked the restart at {restart_seen}, pneud's is {restarts[0]}")
            print(f"restart marked at t = {restart_seen['t']:.4f} s (pneud's events file: "
                  f"{restarts[0]['t']:.4f} s); forecast {stuck_seen['forecast']['t_restart']:.4f} s")
        else:
            print(f"pneud's run ended before stop {index} restarted: nothing to mark")
        # Every tick is received, skipped at the page's request or counted lost: none joined
        # silently. pneu-dash reports the skipped ones at most every 0.5 s, after the tick they
        # precede: wait for the report that covers the last tick received.
        deadline = time.monotonic() + 5
        final = snap()
        while time.monotonic() < deadline:
            seqs = final["sequences"].get("PNEU_STATE")
            if seqs and seqs["reportedSeq"] == seqs["last"]:
                break
            time.sleep(0.2)
            final = snap()
        seqs = final["sequences"].get("PNEU_STATE")
        if not seqs:
            fail(f"the page counted no sequence numbers on PNEU_STATE: {final['sequences']}")
        if not seqs["decimated"] or final["maxRateHz"] != MAX_RATE_HZ:
            fail(f"the page did not ask for the ticks at {MAX_RATE_HZ} Hz: {seqs}, maxRateHz {final['maxRateHz']}")
        if seqs["reportedSeq"] != seqs["last"]:
            fail(f"pneu-dash's report of the ticks it skipped did not come after the last tick ({seqs})", logs)
        span = seqs["last"] - seqs["first"] + 1
        lost = final["gaps"]["byTopic"].get("PNEU_STATE", 0)
        if seqs["received"] + seqs["skipped"] + lost != span:
            fail(f"ticks {seqs['first']}..{seqs['last']}: {seqs['received']} received, {seqs['skipped']} skipped "
                 f"and {lost} counted lost do not make {span}")
        # The skipped ones are what pneu-dash skipped (the page is its one client): none lost taken for
        # skipped; and they are most of them (at most 60 a second of the 1000).
        metrics = urllib.request.urlopen(run["base"] + "/metrics", timeout=5).read().decode()
        skipped = [int(line.split()[-1]) for line in metrics.splitlines()
                   if line.startswith("pneu_dash_messages_skipped_total{") and 'channel="PNEU_STATE"' in line]
        if skipped != [seqs["skipped"]]:
            fail(f"the page was told {seqs['skipped']} ticks skipped, pneu-dash's /metrics says {skipped}")
        # And what it counts lost, pneu-dash never had (pneud's ticks it did not receive) or dropped.
        counter = lambda name: sum(int(line.split()[-1]) for line in metrics.splitlines()
                                   if line.startswith(name + "{") and 'channel="PNEU_STATE"' in line)
        never_had = run["summary"]["loop"]["ticks"] - counter("pneu_dash_messages_published_total")
        if lost > max(0, never_had) + counter("pneu_dash_messages_dropped_total"):
            fail(f"the page counted {lost} ticks lost; pneu-dash never had {never_had} of pneud's "
                 f"{run['summary']['loop']['ticks']} and dropped {counter('pneu_dash_messages_dropped_total')}")
        if not 10 * seqs["received"] < span:
            fail(f"the page asked for {MAX_RATE_HZ} Hz and received {seqs['received']} of {span} ticks")
        print(f"ticks seq {seqs['first']}..{seqs['last']}: {seqs['received']} received, {seqs['skipped']} skipped "
              f"at the page's request (pneu-dash's /metrics: {skipped[0]}), {lost} counted lost (pneu-dash never had "
              f"{never_had} of pneud's ticks, dropped {counter('pneu_dash_messages_dropped_total')})")
        print(f"the page drew in {final['drawMs']} ms, {final['lagS']} s behind the server; "
              f"gaps counted by the page: {final['gaps']}; events shown: {final['events']}; "
              f"messages by channel: {final['received']}")
        if not os.path.isfile(shot) or os.path.getsize(shot) < 10000:
            fail(f"no screenshot at {shot}")
        print(f"screenshot: {shot}")
        print("PASS")
    finally:
        if driver is not None:
            driver.quit()
        for p in procs:
            if p.poll() is None:
                p.terminate()
                try:
                    p.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    p.kill()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
