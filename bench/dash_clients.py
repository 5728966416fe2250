#!/usr/bin/python3
"""The figures of bench/dash_clients.sh, from its run directory: DIR/REP/{A,B,D,C}/ each with pneud's
--summary-json, cyclictest's histogram, pneu-dash's CPU ticks and RSS samples, /metrics after the
phase, and each client's file (bench/dash_client.cpp).

Latency from the tick to a client's receipt, exactly: the state record's t is the loop's time of the
tick's wake-up (the sample), since the loop's epoch; pneud's --summary-json gives that epoch on
CLOCK_MONOTONIC (loop.epoch_monotonic_s). The client reads CLOCK_MONOTONIC once it has the whole
frame and has decoded its JSON. latency = receipt - (epoch_monotonic_s + t): the tick's computation,
the loop's queue to the telemetry thread, LCM encode and UDP multicast on loopback, pneu-dash's LCM
decode, JSON writing and queueing, the WebSocket frame on TCP loopback, the client's JSON decode.
Split at pneu-dash's LCM receipt: the frame's timestamp is LCM's recv_utime (CLOCK_REALTIME, us),
mapped to CLOCK_MONOTONIC with the client's measured REALTIME - MONOTONIC offset. At 60 Hz (D) a
state may wait in pneu-dash up to 1/60 s for its turn (the newest then goes): that wait is in it.

usage: dash_clients.py DIR REPEATS CLIENTS
"""
import glob
import json
import os
import re
import statistics
import sys


def pct(values, q):
    if not values:
        return float("nan")
    v = sorted(values)
    return v[min(len(v) - 1, int(q * len(v)))]


def cyclic(path):
    hist, total = {}, 0
    with open(path) as f:
        for line in f:
            m = re.match(r"^(\d+)\s+(\d+)", line)
            if m and int(m.group(2)) > 0:
                hist[int(m.group(1))] = int(m.group(2))
                total += int(m.group(2))
    out = []
    for q in (0.5, 0.99):
        s = 0
        for k in sorted(hist):
            s += hist[k]
            if s >= q * total:
                out.append(k)
                break
    return out if len(out) == 2 else [float("nan")] * 2


def client(path, epoch_s):
    """The state rows of one client: (latencies us, tick->dash us, dash->client us, seqs, header);
    header["t"]: each row's loop time [s]."""
    lat, to_dash, to_client, seqs, head = [], [], [], set(), {"status": [], "count": {}, "t": []}
    offset = 0
    with open(path) as f:
        for line in f:
            if line.startswith("# "):
                parts = line[2:].rstrip("\n").split(" ", 2)
                if parts[0] == "realtime_minus_monotonic_ns":
                    offset = int(parts[1])
                elif parts[0] == "count":
                    head["count"][parts[1]] = int(parts[2])
                elif parts[0] == "status":
                    head["status"].append(" ".join(parts[1:]))
                elif parts[0] in ("skipped", "max_rate_hz"):
                    head[parts[0]] = float(parts[1])
                continue
            seq, t, frame_ns, recv_ns = line.split()
            tick_ns = epoch_s * 1e9 + float(t) * 1e9
            recv = int(recv_ns)
            dash_ns = int(frame_ns) - offset
            lat.append((recv - tick_ns) / 1e3)
            to_dash.append((dash_ns - tick_ns) / 1e3)
            to_client.append((recv - dash_ns) / 1e3)
            seqs.add(int(seq))
            head["t"].append(float(t))
    return lat, to_dash, to_client, seqs, head


def counter(path, name):
    """A pneu_dash counter by channel, from /metrics' text."""
    out = {}
    with open(path) as f:
        for line in f:
            m = re.match(r'^' + name + r'\{[^}]*channel="([^"]+)"[^}]*\} (\d+)', line)
            if m:
                out[m.group(1)] = int(m.group(2))
    return out


def phase(d):
    with open(os.path.join(d, "summary.json")) as f:
        s = json.load(f)
    loop = s["loop"]
    r = {"overruns": loop["overruns"], "wake_med": loop["wake_latency_us"]["median"],
         "wake_p99": loop["wake_latency_us"]["p99"], "ticks": loop["ticks"]}
    r["cyc_med"], r["cyc_p99"] = cyclic(os.path.join(d, "cyclic.txt"))
    c0, c1, hz = open(os.path.join(d, "cpu.txt")).read().split()
    start = float(open(os.path.join(d, "start.txt")).read())
    end = float(open(os.path.join(d, "end.txt")).read())
    r["wall_s"] = end - start
    r["dash_cpu_ms_per_s"] = 1000.0 * (float(c1) - float(c0)) / float(hz) / r["wall_s"]
    rss = []
    with open(os.path.join(d, "rss.txt")) as f:
        for line in f:
            p = line.split()
            if len(p) == 2:
                rss.append((float(p[0]), int(p[1])))
    r["rss"] = rss
    r["dropped"] = counter(os.path.join(d, "metrics.txt"), "pneu_dash_messages_dropped_total")
    r["published_states"] = sum(v for k, v in counter(os.path.join(d, "metrics.txt"),
                                                      "pneu_dash_messages_published_total").items() if k.endswith("STATE"))
    lat, to_dash, to_client, rates, ts, per_s, lost = [], [], [], [], [], [], []
    epoch = loop["epoch_monotonic_s"]
    for path in sorted(glob.glob(os.path.join(d, "client*.txt"))):
        l, a, b, seqs, head = client(path, epoch)
        lat += l
        to_dash += a
        to_client += b
        ts += head["t"]
        rates.append(len(seqs) / loop["ticks"])
        per_s.append(len(seqs) / (loop["ticks"] / loop["rate_hz"]))
        # of the states from the first to the last received: received, skipped at its request
        # (pneu-dash's last report), lost (the rest)
        if seqs:
            lost.append(max(seqs) - min(seqs) + 1 - len(seqs) - int(head.get("skipped", 0)))
    r["received_per_s_max"] = max(per_s, default=float("nan"))
    r["lost_max"] = max(lost, default=0)
    r["clients"] = len(rates)
    if rates:
        r["lat_p50"], r["lat_p99"], r["lat_max"] = pct(lat, 0.5), pct(lat, 0.99), max(lat)
        r["to_dash_p50"], r["to_dash_p99"] = pct(to_dash, 0.5), pct(to_dash, 0.99)
        r["to_client_p50"], r["to_client_p99"] = pct(to_client, 0.5), pct(to_client, 0.99)
        r["received_min"] = min(rates)
    stalled = os.path.join(d, "stalled.txt")
    if os.path.exists(stalled):
        _, _, _, seqs, head = client(stalled, epoch)
        r["stalled_states"] = len(seqs)
        ordered = sorted(seqs)
        # the states it got before the first it never got (its socket's buffers), and the newest
        gap = next((a for a, b in zip(ordered, ordered[1:]) if b != a + 1), ordered[-1] if ordered else 0)
        r["stalled_first_gap_t"] = gap / loop["rate_hz"]
        r["stalled_newest_t"] = ordered[-1] / loop["rate_hz"] if ordered else 0.0
        r["stalled_status"] = head["status"]
        # When pneu-dash started dropping for it: the first second its dropped counter rose after
        # pneud started (on the loop's time: pneud's start is the loop's 0, to within its start-up).
        r["stalled_full_t"] = float("nan")
        with open(os.path.join(d, "dropped.txt")) as f:
            samples = [(float(a), int(b)) for a, b in (line.split() for line in f if len(line.split()) == 2)]
        before = [n for t, n in samples if t <= start]
        rose = [t for t, n in samples if t > start and n > (before[-1] if before else 0)]
        if rose:
            r["stalled_full_t"] = rose[0] - start
        # The others' latency while its queue filled, and once it was full (pneu-dash dropping
        # for it), each side 0.5 s away from the moment.
        full = r["stalled_full_t"] if r["stalled_full_t"] == r["stalled_full_t"] else float("inf")
        filling = [x for x, t in zip(lat, ts) if t < full - 0.5]
        dropping = [x for x, t in zip(lat, ts) if t > full + 0.5]
        r["filling_p50"], r["filling_p99"] = pct(filling, 0.5), pct(filling, 0.99)
        r["dropping_p50"], r["dropping_p99"] = pct(dropping, 0.5), pct(dropping, 0.99)
        # Every 5 s of the loop: the others' tick -> receipt p99, and its pneu-dash -> client part
        # (the machine's stalls show in the tick -> pneu-dash part too; the server's queueing not).
        r["windows"] = []
        for w in range(0, int(max(ts)) + 1, 5):
            idx = [i for i, t in enumerate(ts) if w <= t < w + 5]
            if idx:
                r["windows"].append((w, pct([lat[i] for i in idx], 0.99), pct([to_client[i] for i in idx], 0.5),
                                     pct([to_client[i] for i in idx], 0.99)))
    return r


def rss_line(rss, t0, t1):
    """RSS at the start of pneud's run, then every quarter of it, and the largest [MiB]."""
    inside = [(t, v) for t, v in rss if t0 <= t <= t1] or rss
    marks = []
    for q in (0.0, 0.25, 0.5, 0.75, 1.0):
        target = t0 + q * (t1 - t0)
        marks.append(min(inside, key=lambda tv: abs(tv[0] - target))[1] / 1024)
    return marks, max(v for _, v in inside) / 1024


def main(argv):
    root, reps, n = argv[0], int(argv[1]), int(argv[2])
    rows = {"A": [], "B": [], "C": [], "D": []}
    for rep in range(1, reps + 1):
        print("repetition %d:" % rep)
        prev_drop, prev_published = {}, 0
        for name in "ABDC":  # in the order they ran
            d = os.path.join(root, str(rep), name)
            r = phase(d)
            start = float(open(os.path.join(d, "start.txt")).read())
            end = float(open(os.path.join(d, "end.txt")).read())
            r["rss_marks"], r["rss_max"] = rss_line(r["rss"], start, end)
            r["drops_phase"] = sum(r["dropped"].values()) - sum(prev_drop.values())
            r["lost_before_dash"] = r["ticks"] - (r["published_states"] - prev_published)
            prev_drop, prev_published = r["dropped"], r["published_states"]
            rows[name].append(r)
            label = {"A": "0 clients", "B": "%d clients" % n, "C": "%d clients + 1 stopped reading" % n,
                     "D": "%d clients at 60 Hz" % n}[name]
            print("  %s %-30s pneud %6d ticks, overruns %3d, wake-up median %5.1f us p99 %6.1f us | cyclictest median %3d p99 %4d us"
                  % (name, label, r["ticks"], r["overruns"], r["wake_med"], r["wake_p99"], r["cyc_med"], r["cyc_p99"]))
            print("    pneu-dash CPU %.1f ms/s of running, RSS %s MiB (start, quarters, end of pneud's run; max %.1f)"
                  % (r["dash_cpu_ms_per_s"], " ".join("%.1f" % m for m in r["rss_marks"]), r["rss_max"]))
            if r["clients"]:
                print("    tick -> client receipt: p50 %.0f us, p99 %.0f us, max %.0f us (of which tick -> pneu-dash's LCM receipt p50 %.0f p99 %.0f, "
                      "pneu-dash -> client p50 %.0f p99 %.0f); states received per tick, the fewest of %d clients: %.4f"
                      % (r["lat_p50"], r["lat_p99"], r["lat_max"], r["to_dash_p50"], r["to_dash_p99"], r["to_client_p50"],
                         r["to_client_p99"], r["clients"], r["received_min"]))
                print("    states received per second of the loop, the most of %d clients: %.1f; states lost (neither received "
                      "nor reported skipped, from the first to the last received), the most of a client: %d"
                      % (r["clients"], r["received_per_s_max"], r["lost_max"]))
            print("    frames dropped by pneu-dash in this phase (/metrics): %d; states pneud published that pneu-dash's LCM "
                  "subscription never received (ticks - pneu_dash_messages_published_total): %d" % (r["drops_phase"], r["lost_before_dash"]))
            if "stalled_states" in r:
                print("    the client that stopped reading: %d states taken in all, those up to t = %.1f s of the loop (its socket's "
                      "buffers) and the newest, up to t = %.1f s; pneu-dash dropped for it from t = %.0f s (its queue full: the "
                      "oldest states queued, then what did not fit); pneu-dash told it: %s"
                      % (r["stalled_states"], r["stalled_first_gap_t"], r["stalled_newest_t"], r["stalled_full_t"],
                         "; ".join(r["stalled_status"]) or "(nothing)"))
                print("    the 8 others, tick -> receipt while its queue filled: p50 %.0f p99 %.0f us; once pneu-dash dropped for it: p50 %.0f p99 %.0f us"
                      % (r["filling_p50"], r["filling_p99"], r["dropping_p50"], r["dropping_p99"]))
                print("    every 5 s of the loop (t from; tick -> receipt p99; pneu-dash -> client p50/p99) [us]: " +
                      ", ".join("%d%s: %.0f; %.0f/%.0f" % (w, "*" if w + 5 > r["stalled_full_t"] else "", a, b, c)
                                for w, a, b, c in r["windows"]) + "   (*: dropping for the stopped client)")
    med = lambda name, key: statistics.median(r[key] for r in rows[name])
    print("medians over %d repetitions:" % reps)
    print("  %-34s %9s %12s %10s %10s %10s %9s %9s %9s %9s %11s" % ("", "overruns", "wake med us", "p99 us", "cyc med", "cyc p99",
                                                                   "dash ms/s", "RSS MiB", "lat p50", "lat p99", "recv/tick"))
    for name, label in (("A", "0 clients"), ("B", "%d clients" % n), ("D", "%d clients at 60 Hz" % n),
                        ("C", "%d clients + 1 stopped reading" % n)):
        lat = ("%9.0f %9.0f %11.4f" % (med(name, "lat_p50"), med(name, "lat_p99"), med(name, "received_min"))
               if rows[name][0]["clients"] else "%9s %9s %11s" % ("-", "-", "-"))
        print("  %s %-32s %9.0f %12.1f %10.1f %10.0f %10.0f %9.1f %9.1f %s" % (
            name, label, med(name, "overruns"), med(name, "wake_med"), med(name, "wake_p99"), med(name, "cyc_med"),
            med(name, "cyc_p99"), med(name, "dash_cpu_ms_per_s"), med(name, "rss_max"), lat))
    per_client = [(b["dash_cpu_ms_per_s"] - a["dash_cpu_ms_per_s"]) / n for a, b in zip(rows["A"], rows["B"])]
    print("  pneu-dash CPU per client (B - A) / %d, every state forwarded (1 kHz): "
          "%.2f ms per second of running (%.2f %% of one core); each repetition: %s"
          % (n, statistics.median(per_client), statistics.median(per_client) / 10, " ".join("%.2f" % x for x in per_client)))
    per_client_60 = [(dd["dash_cpu_ms_per_s"] - a["dash_cpu_ms_per_s"]) / n for a, dd in zip(rows["A"], rows["D"])]
    print("  pneu-dash CPU per client at 60 Hz (D - A) / %d, the newest state at most every 1/60 s: "
          "%.2f ms per second of running (%.2f %% of one core); each repetition: %s"
          % (n, statistics.median(per_client_60), statistics.median(per_client_60) / 10,
             " ".join("%.2f" % x for x in per_client_60)))
    print("  C: pneu-dash's largest RSS %.1f MiB against B's %.1f MiB; frames dropped for the client that stopped reading: %s"
          % (med("C", "rss_max"), med("B", "rss_max"), " ".join(str(r["drops_phase"]) for r in rows["C"])))
    print("  C: the others' tick -> receipt while its queue filled p50 %.0f p99 %.0f us, once dropping p50 %.0f p99 %.0f us (medians)"
          % (med("C", "filling_p50"), med("C", "filling_p99"), med("C", "dropping_p50"), med("C", "dropping_p99")))
    print("  states lost before pneu-dash (LCM/UDP, not its queues), A B D C in each repetition: %s"
          % ", ".join(" ".join(str(rows[p][i]["lost_before_dash"]) for p in "ABDC") for i in range(reps)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
