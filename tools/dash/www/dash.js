// pneu-dash's page: subscribes to every channel of the server's /ws (Foxglove WebSocket protocol,
// JSON messages whose fields are the records' own, as their advertised JSON Schemas say) and draws
// the traces, the pressure-force plane, the events, the health and the identified parameters.
// What the page draws of the plane (the areas, the null-flow curve, a forecast's path) comes
// computed from the model library over the channels PLANE and PLANE_FORECAST: no equation of the
// model is written here. window.pneuDash is the page's state for people and for the browser test.
import { FoxgloveClient } from "./foxglove.js";

const TRACE_WINDOW_S = 10.0;    // the traces' time window
const TRAIL_S = 4.0;            // the plane's trail
const REDRAW_MS = 150;          // charts redrawn at most this often, and less often when drawing is
                                // slow: the messages keep at least two thirds of the page's time
const MAX_EVENT_ROWS = 400;
// The rate of the tick records (PNEU_STATE, 1 kHz) this page asks (/?max_rate_hz=60): the server
// then sends the newest tick at most that often and tells how many it skipped; the traces show the
// ticks received, so a spike between two of them is not drawn. Without it, every tick (the default:
// every extreme drawn).
const MAX_RATE_HZ = new URLSearchParams(location.search).has("max_rate_hz")
  ? Number(new URLSearchParams(location.search).get("max_rate_hz")) : 0;
const Chart = window.Chart;

// The loop's modes by their number on the wire (state_t / health_t MODE_*): serverInfo's metadata
// "modes" ("0:DISARMED,1:ARMED,..."), from the controller's own table.
const MODE_NAMES = [];

const state = {
  connected: false,
  serverInfo: null,
  channels: {},            // topic -> {id, schemaName, sequenceField, received}
  messages: 0,
  // missing: messages lost (by the sequence numbers, less those the server skipped at this page's
  // request); serverDropped: messages of channels without sequence numbers the server dropped for
  // this page; skipped: skipped at this page's request (maxRateHz), not counted in total
  gaps: { missing: 0, serverDropped: 0, total: 0, byTopic: {}, skipped: 0, skippedByTopic: {} },
  maxRateHz: MAX_RATE_HZ,
  gapIntervals: [],        // [t0, t1] of the loop's time where ticks are missing
  tick: null,              // the last tick
  ticks: 0,
  tickTimes: [],           // loop times of the ticks drawn (for the test: do the traces advance?)
  plane: null,             // the PLANE message
  planePoint: null,        // {x, y} of the last tick
  stuck: false,
  stop: null,              // the sticking phase: {index, t, point, forecasts: {method: prediction}, paths: {method: path msg}, restart}
  lastPhase: null,         // the last phase that ended in a (re)start, with its restart marked
  restarts: [],            // the last (re)starts after a stop: {stop, t, kind, forecast: {method: t_restart}}
  events: 0,
  health: null,
  identification: null,
  status: [],
  commandsEnabled: false,
};

// ---------------------------------------------------------------- the traces
const series = {
  y_d: [], y: [], p_p: [], p_n: [], u: [], force: [],
};

function lineDataset(label, data, color, extra = {}) {
  return {
    label, data, borderColor: color, backgroundColor: color, borderWidth: 1.3, pointRadius: 0,
    parsing: false, normalized: true, spanGaps: false, indexAxis: "x", _seriesRef: data,
    segment: { borderColor: (ctx) => (crossesGap(ctx) ? "#d62728" : undefined),
               borderDash: (ctx) => (crossesGap(ctx) ? [4, 3] : undefined) },
    ...extra,
  };
}

// A segment between two drawn points is dashed red when ticks are missing between them.
function crossesGap(ctx) {
  const a = ctx.p0.parsed.x, b = ctx.p1.parsed.x;
  for (const [g0, g1] of state.gapIntervals) if (g1 > a && g0 < b) return true;
  return false;
}

function traceChart(id, title, unit, datasets) {
  return new Chart(document.getElementById(id), {
    type: "line",
    data: { datasets },
    options: {
      animation: false, responsive: true, maintainAspectRatio: false, parsing: false, normalized: true,
      interaction: { mode: "nearest", axis: "x", intersect: false },
      plugins: {
        decimation: { enabled: true, algorithm: "min-max" },
        legend: { labels: { boxWidth: 12, font: { size: 11 } } },
        title: { display: true, text: title, font: { size: 12 } },
        tooltip: { enabled: true },
      },
      scales: {
        x: { type: "linear", title: { display: false }, ticks: { maxRotation: 0 } },
        y: { title: { display: true, text: unit } },
      },
    },
  });
}

const charts = {};

function makeTraceCharts() {
  charts.position = traceChart("chart-position", "set point and position", "mm", [
    lineDataset("set point y_d", series.y_d, "#7f7f7f", { borderDash: [6, 3] }),
    lineDataset("position y", series.y, "#1f77b4"),
  ]);
  charts.pressure = traceChart("chart-pressure", "chamber pressures (absolute)", "bar", [
    lineDataset("p_P", series.p_p, "#d62728"),
    lineDataset("p_N", series.p_n, "#2ca02c"),
  ]);
  charts.u = traceChart("chart-u", "control u (u_P = u, u_N = -u)", "V", [lineDataset("u", series.u, "#9467bd")]);
  charts.force = traceChart("chart-force", "pressure force F (Eq. 14) and the stiction bounds", "N", [
    lineDataset("F", series.force, "#ff7f0e"),
    lineDataset("F_S+", [], "#444", { borderDash: [2, 2], segment: {} }),
    lineDataset("F_S-", [], "#444", { borderDash: [2, 2], segment: {} }),
  ]);
}

// The events on the traces' time axis, one lane each: what happened, and when the forecasts said
// the carriage would restart.
const LANES = ["fault", "command", "hold", "forecast restart", "restart / start", "stop"];
const LANE_STYLE = {
  "stop": ["#d62728", "rect"], "restart / start": ["#1a9641", "triangle"], "forecast restart": ["#e66100", "rectRot"],
  "hold": ["#2471a3", "circle"], "command": ["#6a3d9a", "star"], "fault": ["#c62828", "crossRot"],
};
const timeline = Object.fromEntries(LANES.map((l) => [l, []]));

function makeTimeline() {
  charts.timeline = new Chart(document.getElementById("chart-timeline"), {
    type: "scatter",
    data: {
      datasets: LANES.map((lane) => ({
        // parsed: the forecast restarts are not in the order of their times
        label: lane, data: timeline[lane], borderColor: LANE_STYLE[lane][0],
        backgroundColor: LANE_STYLE[lane][0], pointStyle: LANE_STYLE[lane][1], pointRadius: 5, borderWidth: 1.5,
        _seriesRef: timeline[lane],
      })),
    },
    options: {
      animation: false, responsive: true, maintainAspectRatio: false,
      plugins: {
        legend: { display: false },
        title: { display: true, text: "events (forecast restarts: when each forecast said; stops and restarts: when they were)", font: { size: 12 } },
        tooltip: { callbacks: { label: (ctx) => `${LANES[ctx.raw.y]} t = ${ctx.raw.x.toFixed(3)} s ${ctx.raw.text ?? ""}` } },
      },
      scales: {
        x: { type: "linear", ticks: { maxRotation: 0 } },
        y: { type: "linear", min: -0.5, max: LANES.length - 0.5,
             afterBuildTicks: (axis) => { axis.ticks = LANES.map((_, i) => ({ value: i })); },
             ticks: { autoSkip: false, callback: (v) => LANES[v] ?? "", font: { size: 10 } } },
      },
    },
  });
}

function markTimeline(lane, t, text) {
  if (!Number.isFinite(t)) return;
  timeline[lane].push({ x: t, y: LANES.indexOf(lane), text });
}

function trim(arr, t0) {
  let k = 0;
  while (k < arr.length && arr[k].x < t0) ++k;
  if (k > 0) arr.splice(0, k);
}

function redrawTraces() {
  if (!state.tick) return;
  const t1 = state.tick.t, t0 = Math.max(t1 - TRACE_WINDOW_S, Math.min(0, t1));
  for (const arr of Object.values(series)) trim(arr, t0 - 0.5);
  while (state.gapIntervals.length && state.gapIntervals[0][1] < t0 - TRAIL_S) state.gapIntervals.shift();
  if (state.plane) {
    const fs = charts.force.data.datasets;
    fs[1]._seriesRef = [{ x: t0, y: state.plane.static_positive }, { x: t1, y: state.plane.static_positive }];
    fs[2]._seriesRef = [{ x: t0, y: state.plane.static_negative }, { x: t1, y: state.plane.static_negative }];
  }
  for (const arr of Object.values(timeline)) trim(arr, t0 - 0.5);
  for (const c of [charts.position, charts.pressure, charts.u, charts.force, charts.timeline]) {
    c.options.scales.x.min = t0;
    c.options.scales.x.max = t1;
    // The decimation plugin shows its own copy as `data` once it has run: hand it the whole
    // series again (our arrays) on every redraw.
    for (const ds of c.data.datasets) ds.data = ds._seriesRef;
    c.update("none");
  }
}

// ---------------------------------------------------------------- the plane
const trail = [];  // {x, y, t, stuck}

function planeXY(p_p, p_n) {
  const g = state.plane;
  return { x: g.x_per_pa * p_p + g.x_offset, y: g.y_per_pa * p_n + g.y_offset };
}

function closed(points) {
  const out = points.map((p) => ({ x: p.x, y: p.y }));
  if (out.length) out.push({ ...out[0] });
  return out;
}

function makePlaneChart() {
  // Chart.js draws the dataset of the lowest order last, on top: the areas at the bottom, the
  // state point on top, in the reverse of the order listed here. The data are parsed (not
  // `parsing: false`, which tells Chart.js the points are sorted by x and lets it draw only those
  // its binary search finds in view): a trail, a path or an area goes back and forth in x.
  let order = 100;
  const ds = (label, color, extra) => ({
    label, data: [], borderColor: color, backgroundColor: color, showLine: true, pointRadius: 0,
    borderWidth: 1.2, order: order--, ...extra,
  });
  charts.plane = new Chart(document.getElementById("chart-plane"), {
    type: "scatter",
    data: {
      datasets: [
        ds("no-restarting area (Eq. 13): F_S- <= F <= F_S+", "#b7950b",
           { backgroundColor: "rgba(252, 243, 207, 0.9)", fill: "shape", borderWidth: 0.8 }),
        ds("stop area (Eq. 12): F_C- <= F <= F_C+", "#5dade2",
           { backgroundColor: "rgba(214, 234, 248, 0.95)", fill: "shape", borderWidth: 0.8 }),
        ds("null-flow curve (complete equilibrium)", "#000000", { borderWidth: 1.6 }),
        // one line, red where stuck, blue where moving, not drawn over missing ticks
        ds("trail: stuck (red), moving (blue)", "#d62728", {
          borderWidth: 1.6,
          segment: {
            borderColor: (ctx) => {
              const a = trailShown[ctx.p0DataIndex], b = trailShown[ctx.p1DataIndex];
              if (!a || !b) return undefined;
              if (state.gapIntervals.some(([g0, g1]) => g1 > a.t && g0 < b.t)) return "rgba(0, 0, 0, 0)";
              return a.stuck && b.stuck ? "#d62728" : "#1f77b4";
            },
          },
        }),
        ds("forecast path (from the model)", "#e66100", { borderDash: [6, 3], borderWidth: 2.0 }),
        ds("equilibrium under u*", "#1a9641", { showLine: false, pointRadius: 6, pointStyle: "crossRot", borderWidth: 2 }),
        ds("forecast restart", "#e66100", { showLine: false, pointRadius: 8, pointStyle: "triangle", borderWidth: 2,
                                            backgroundColor: "rgba(230, 97, 0, 0.3)" }),
        ds("stop", "#d62728", { showLine: false, pointRadius: 6, pointStyle: "rect", borderWidth: 2,
                                backgroundColor: "#ffffff" }),
        ds("actual restart", "#6a3d9a", { showLine: false, pointRadius: 10, pointStyle: "star", borderWidth: 2.5 }),
        ds("state point", "#111111", { showLine: false, pointRadius: 6, borderWidth: 2, backgroundColor: "#ffeb3b" }),
      ],
    },
    options: {
      animation: false, responsive: true, maintainAspectRatio: true, aspectRatio: 1,
      plugins: {
        decimation: { enabled: false },
        legend: { position: "bottom", labels: { boxWidth: 12, font: { size: 10 } } },
        tooltip: { enabled: true },
      },
      scales: {
        x: { type: "linear", title: { display: true, text: "x = S_P p_P [N]" } },
        y: { type: "linear", title: { display: true, text: "y = S_N p_N + S_r p_E [N]" } },
      },
    },
  });
}

const PLANE = { noRestart: 0, stopArea: 1, nullFlow: 2, trail: 3, path: 4, equilibrium: 5,
                forecastRestart: 6, stop: 7, restart: 8, point: 9 };
let trailShown = [];  // the trail as drawn last

function onPlane(msg) {
  state.plane = msg;
  const d = charts.plane.data.datasets;
  d[PLANE.noRestart].data = closed(msg.no_restart_area);
  d[PLANE.stopArea].data = closed(msg.stop_area);
  d[PLANE.nullFlow].data = msg.null_flow.map((p) => ({ x: p.x, y: p.y }));
  charts.plane.update("none");
}

function nearestTrailPoint(t) {
  let best = null;
  for (const p of trail) if (!best || Math.abs(p.t - t) < Math.abs(best.t - t)) best = p;
  return best && Math.abs(best.t - t) < 0.05 ? best : state.planePoint;
}

// The view: the whole plane, or around `points` (no side shorter than `minSpan` [N]), square.
function planeView(points, minSpan) {
  const g = state.plane;
  const whole = document.querySelector('input[name="plane-view"]:checked')?.value === "whole";
  if (whole || !points.length) {
    const span = Math.max(g.x_max - g.x_min, g.y_max - g.y_min);
    return { x0: g.x_min, x1: g.x_min + span, y0: g.y_min, y1: g.y_min + span };
  }
  let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
  for (const p of points) {
    if (!Number.isFinite(p.x) || !Number.isFinite(p.y)) continue;
    x0 = Math.min(x0, p.x); x1 = Math.max(x1, p.x); y0 = Math.min(y0, p.y); y1 = Math.max(y1, p.y);
  }
  const span = Math.max(x1 - x0, y1 - y0, minSpan) * 1.25;
  const xc = (x0 + x1) / 2, yc = (y0 + y1) / 2;
  return { x0: xc - span / 2, x1: xc + span / 2, y0: yc - span / 2, y1: yc + span / 2 };
}

function redrawPlane() {
  if (!state.plane || !state.planePoint) return;
  const d = charts.plane.data.datasets;
  trailShown = trail.slice();
  d[PLANE.trail].data = trailShown;
  d[PLANE.point].data = [state.planePoint];
  d[PLANE.point].backgroundColor = state.stuck ? "#d62728" : "#ffeb3b";
  const phase = state.stop ?? state.lastPhase;
  // Stuck (or just restarted): a close-up on the phase (Fig. 10), else the last seconds' trail.
  const band = state.plane.static_positive - state.plane.static_negative;
  const closeUp = Boolean(phase && (state.stop || trail.length && trail[trail.length - 1].t - phase.restart.t < 0.5));
  const shown = closeUp ? trail.filter((p) => p.t >= phase.t) : [...trail];
  const path = phase ? preferred(phase.paths) : null;
  const forecast = phase ? preferred(phase.forecasts) : null;
  d[PLANE.path].data = path ? path.path.map((p) => ({ x: p.x, y: p.y })) : [];
  d[PLANE.forecastRestart].data = path && path.will_restart ? [path.path[path.path.length - 1]] : [];
  d[PLANE.equilibrium].data = forecast && Number.isFinite(forecast.p_p_equilibrium)
    ? [planeXY(forecast.p_p_equilibrium, forecast.p_n_equilibrium)] : [];
  d[PLANE.stop].data = phase?.point ? [phase.point] : [];
  d[PLANE.restart].data = phase?.restart?.point ? [phase.restart.point] : [];
  if (phase?.point) shown.push(phase.point);
  shown.push(...d[PLANE.path].data, ...d[PLANE.equilibrium].data);
  const v = planeView(shown, closeUp ? 0.35 * band : 1.5 * band);
  const s = charts.plane.options.scales;
  s.x.min = v.x0; s.x.max = v.x1; s.y.min = v.y0; s.y.max = v.y1;
  charts.plane.update("none");
  const box = document.getElementById("plane-box");
  box.dataset.stuck = String(state.stuck);
  box.dataset.forecastPoints = String(d[PLANE.path].data.length);
}

// The forecast shown first: the linearized (the paper's), else the first there is.
function preferred(byMethod) {
  if (!byMethod) return null;
  return byMethod.linearized ?? Object.values(byMethod)[0] ?? null;
}

function fmtS(t) { return Number.isFinite(t) ? t.toFixed(3) : "?"; }
function fmtMs(dt) { return `${dt >= 0 ? "+" : ""}${(dt * 1e3).toFixed(0)} ms`; }

function redrawForecast() {
  const el = document.getElementById("forecast");
  const line = document.getElementById("forecast-line");
  const countdown = document.getElementById("countdown");
  const restartLine = document.getElementById("restart-line");
  const now = state.tick?.t;
  const phase = state.stop;
  if (phase) {
    const forecasts = Object.values(phase.forecasts);
    const made = forecasts.map((f) => `${f.method}${f.update ? ` (again, ${f.update})` : ""}: ` +
      (f.will_restart ? `restart ${f.direction > 0 ? "+" : "-"} at t = ${fmtS(f.t_restart)} s`
                      : "no restart") + (f.model_fits === false ? " (uncertain: the model did not fit)" : ""));
    line.textContent = `stuck since t = ${fmtS(phase.t)} s (stop ${phase.index}); ` +
      (made.length ? `forecast ${made.join("; ")}` : "no forecast yet");
    const f = preferred(phase.forecasts);
    el.dataset.stop = String(phase.index);  // what is drawn is this stop's (the page draws every 150 ms or so)
    if (f && f.will_restart && Number.isFinite(f.t_restart) && Number.isFinite(now)) {
      const left = f.t_restart - now;
      countdown.textContent = left >= 0 ? `restart in ${left.toFixed(2)} s (${f.method})`
                                        : `restart overdue by ${(-left).toFixed(2)} s (${f.method})`;
      el.dataset.state = "counting";
      el.dataset.countdownS = left.toFixed(3);
    } else {
      countdown.textContent = f ? "no restart forecast: the force stays in the band" : "";
      el.dataset.state = f ? "no-restart" : "stuck";
      delete el.dataset.countdownS;
    }
    restartLine.textContent = "";
  } else if (state.lastPhase?.restart) {
    const p = state.lastPhase, r = p.restart;
    const errs = Object.values(p.forecasts).filter((f) => f.will_restart && Number.isFinite(f.t_restart))
      .map((f) => `${f.method} said ${fmtS(f.t_restart)} s (${fmtMs(r.t - f.t_restart)})`);
    line.textContent = `moving (stop ${p.index} lasted ${(r.t - p.t).toFixed(3)} s)`;
    countdown.textContent = "";
    restartLine.textContent = `${r.kind} at t = ${fmtS(r.t)} s` + (errs.length ? `: ${errs.join("; ")}` : "");
    el.dataset.state = "restarted";
    delete el.dataset.countdownS;
    delete el.dataset.stop;
  } else {
    line.textContent = "no forecast: the carriage is not stuck";
    countdown.textContent = "";
    restartLine.textContent = "";
    el.dataset.state = "none";
    delete el.dataset.stop;
  }
}

// ---------------------------------------------------------------- the messages
// The messages missing from a channel's sequence numbers. On a channel the server decimates at this
// page's request, a gap is messages skipped or lost: the server's reports of its skips (status
// "pneu-dash.skipped", sent after the messages they cover) tell them apart, and what is lost is
// counted at each report, drawn over the ticks between the reports.
function countSequence(topic, channel, msg) {
  const field = channel.sequenceField;
  if (!field || typeof msg[field] !== "number") return;
  const seq = msg[field];
  const last = channel.lastSeq;
  channel.lastSeq = seq;
  channel.lastT = msg.t;
  if (last === undefined || seq <= last) {  // the first, or a restarted sender
    channel.firstSeq = seq;
    channel.firstT = msg.t;
    channel.receivedSinceFirst = 1;
    return;
  }
  channel.receivedSinceFirst += 1;
  const missing = seq - last - 1;
  if (missing <= 0) return;
  if (channel.decimated) {
    channel.gapsInSequence += missing;  // judged at the server's next report
    return;
  }
  countLost(topic, missing, state.tick?.t, msg.t);
}

function countLost(topic, lost, t0, t1) {
  state.gaps.missing += lost;
  state.gaps.byTopic[topic] = (state.gaps.byTopic[topic] ?? 0) + lost;
  if (topic.endsWith("STATE") && t0 !== undefined && t1 !== undefined) state.gapIntervals.push([t0, t1]);
  updateGapBadge();
}

// The server's report of the messages it skipped for a subscription since it subscribed, among
// those older than the last it sent before the report: of the gaps in the sequence up to there,
// the rest is lost.
function onSkippedReport(report) {
  const channel = client.channels.get(client.subscriptions.get(report.subscriptionId));
  const c = channel && state.channels[channel.topic];
  if (!c || !c.decimated || typeof report.skipped !== "number") return;
  const lost = c.gapsInSequence - report.skipped;
  state.gaps.skipped += report.skipped - c.skipped;
  state.gaps.skippedByTopic[channel.topic] = report.skipped;
  c.skipped = report.skipped;
  if (lost > c.lost) countLost(channel.topic, lost - c.lost, c.reportedT ?? c.firstT, c.lastT);
  c.lost = Math.max(c.lost, lost);
  c.reportedSeq = c.lastSeq;
  c.reportedT = c.lastT;
}

function updateGapBadge() {
  state.gaps.total = state.gaps.missing + state.gaps.serverDropped;
  const el = document.getElementById("gaps");
  el.textContent = `gaps: ${state.gaps.total}`;
  el.dataset.gaps = String(state.gaps.total);
  el.title = `missing from the sequence numbers: ${state.gaps.missing} ` +
    `(${Object.entries(state.gaps.byTopic).map(([k, v]) => `${k} ${v}`).join(", ") || "none"}); ` +
    `dropped by the server for this page on channels without sequence numbers: ${state.gaps.serverDropped}` +
    (state.maxRateHz > 0 ? `; not counted: ${state.gaps.skipped} ticks skipped by the server as this page asked ` +
                           `for at most ${state.maxRateHz} Hz` : "");
}

function onTick(m) {
  if (state.tick && m.t < state.tick.t) {  // pneud restarted: a new run, a new time axis
    for (const arr of Object.values(series)) arr.length = 0;
    for (const arr of Object.values(timeline)) arr.length = 0;
    trail.length = 0;
    state.gapIntervals.length = 0;
    state.stop = null;
    state.lastPhase = null;
    state.restarts.length = 0;
  }
  state.tick = m;
  state.ticks += 1;
  series.y_d.push({ x: m.t, y: m.y_d * 1e3 });
  series.y.push({ x: m.t, y: m.y * 1e3 });
  series.p_p.push({ x: m.t, y: m.p_p * 1e-5 });
  series.p_n.push({ x: m.t, y: m.p_n * 1e-5 });
  series.u.push({ x: m.t, y: m.u });
  series.force.push({ x: m.t, y: m.force });
  state.stuck = Boolean(m.stuck);
  if (state.plane && Number.isFinite(m.p_p) && Number.isFinite(m.p_n)) {
    const p = planeXY(m.p_p, m.p_n);
    state.planePoint = p;
    const last = trail[trail.length - 1];
    if (!last || m.t - last.t >= 0.004 || last.stuck !== state.stuck) trail.push({ ...p, t: m.t, stuck: state.stuck });
    while (trail.length && trail[0].t < m.t - TRAIL_S) trail.shift();
  }
  if (!state.tickTimes.length || m.t - state.tickTimes[state.tickTimes.length - 1] >= 0.1) {
    state.tickTimes.push(m.t);
    if (state.tickTimes.length > 200) state.tickTimes.shift();
  }
  document.getElementById("loop-time").textContent = `t = ${m.t.toFixed(3)} s`;
  setMode(m.mode);
}

function setMode(mode) {
  const el = document.getElementById("mode");
  const name = MODE_NAMES[mode] ?? `mode ${mode}`;
  if (el.dataset.mode !== name) {
    el.dataset.mode = name;
    el.textContent = name;
  }
}

const EVENT_CLASS = {
  stop: "stop", restart: "restart", start: "start", fault: "fault", fault_reset: "fault",
  fault_reset_refused: "fault", command_accepted: "command", command_rejected: "refused",
  hold_start: "hold", hold_end: "hold", movement_test: "test", end: "end",
};

function addEventRow(t, what, stop, detail, cls) {
  const body = document.querySelector("#events tbody");
  const row = document.createElement("tr");
  row.className = cls ?? "";
  row.dataset.kind = what;
  for (const text of [fmtS(t), what, stop ? String(stop) : "", detail]) {
    const td = document.createElement("td");
    td.textContent = text;
    row.appendChild(td);
  }
  body.insertBefore(row, body.firstChild);
  while (body.rows.length > MAX_EVENT_ROWS) body.deleteRow(body.rows.length - 1);
  state.events += 1;
}

function onEvent(m) {
  const kind = m.kind;
  const detail = [m.text, Number.isFinite(m.force) ? `F = ${m.force.toFixed(2)} N` : "",
                  Number.isFinite(m.y) ? `y = ${(m.y * 1e3).toFixed(2)} mm` : "",
                  m.direction ? `direction ${m.direction > 0 ? "+" : "-"}` : "",
                  m.seq ? `command seq ${m.seq}` : ""].filter(Boolean).join("; ");
  addEventRow(m.t, kind, m.stop, detail, EVENT_CLASS[kind]);
  const lane = { stop: "stop", restart: "restart / start", start: "restart / start", fault: "fault",
                 fault_reset: "fault", fault_reset_refused: "fault", command_accepted: "command",
                 command_rejected: "command", hold_start: "hold", hold_end: "hold" }[kind];
  if (lane) markTimeline(lane, m.t, kind);
  if (kind === "stop") {
    state.stop = { index: m.stop, t: m.t, point: nearestTrailPoint(m.t), forecasts: {}, paths: {}, restart: null };
    state.lastPhase = null;
  } else if ((kind === "restart" || kind === "start") && state.stop) {
    state.stop.restart = { t: m.t, kind, direction: m.direction, point: nearestTrailPoint(m.t) };
    state.lastPhase = state.stop;
    // the restarts marked, with what the forecasts had said (the last few)
    state.restarts.push({ stop: m.stop, t: m.t, kind,
                          forecast: Object.fromEntries(Object.values(state.stop.forecasts).map((f) => [f.method, f.t_restart])) });
    if (state.restarts.length > 20) state.restarts.shift();
    state.stop = null;
  } else if ((kind === "fault" || kind === "end") && state.stop) {
    state.lastPhase = null;
    state.stop = null;
  }
}

function onPrediction(m) {
  if (m.update === 0) {
    addEventRow(m.t, `forecast (${m.method})`, m.stop,
      m.will_restart ? `restart ${m.direction > 0 ? "+" : "-"} at t = ${fmtS(m.t_restart)} s` : "no restart",
      "forecast");
  }
  const phase = state.stop?.index === m.stop ? state.stop : null;
  if (phase) phase.forecasts[m.method] = m;
  if (m.update === 0 && m.will_restart) markTimeline("forecast restart", m.t_restart, `${m.method}, stop ${m.stop}`);
}

function onPlaneForecast(m) {
  const phase = state.stop?.index === m.stop ? state.stop : null;
  if (phase) phase.paths[m.method] = m;
}

function flatten(obj, prefix = "", out = []) {
  for (const [k, v] of Object.entries(obj)) {
    if (v !== null && typeof v === "object" && !Array.isArray(v)) flatten(v, `${prefix}${k}.`, out);
    else out.push([`${prefix}${k}`, v]);
  }
  return out;
}

function onHealth(m, channel) {
  state.health = m;
  setMode(m.mode);
  if (m.host) document.getElementById("bench").textContent = `bench: ${m.host} (pid ${m.pid})`;
  const body = document.querySelector("#health tbody");
  body.textContent = "";
  const docs = channel.properties ?? {};
  for (const [k, v] of flatten(m)) {
    const row = body.insertRow();
    row.dataset.key = k;
    const name = row.insertCell();
    name.textContent = k;
    name.title = docs[k.split(".")[0]]?.description ?? "";
    let text = v === null ? "-" : typeof v === "number" && !Number.isInteger(v) ? v.toPrecision(4) : String(v);
    if (k === "mode") text = MODE_NAMES[v] ?? text;
    const cell = row.insertCell();
    cell.textContent = text;
    if (/overruns|errors|dropped|rejected|faults|skipped/.test(k) && v > 0) cell.className = "warn";
  }
  const row = body.insertRow();
  row.insertCell().textContent = "page: messages received";
  row.insertCell().textContent = String(state.messages);
}

function onIdentification(m) {
  state.identification = m;
  document.getElementById("identification-when").textContent = `(update ${m.updates}, t = ${fmtS(m.t)} s)`;
  const body = document.querySelector("#identification tbody");
  body.textContent = "";
  for (const [name, value] of Object.entries(m.value ?? {})) {
    const row = body.insertRow();
    const identified = m.identified?.[name];
    row.className = identified ? "identified" : "not-identified";
    row.insertCell().textContent = name;
    row.insertCell().textContent = Number.isFinite(value) ? value.toPrecision(4) : "-";
    const sigma = m.sigma?.[name];
    row.insertCell().textContent = Number.isFinite(sigma) && sigma > 0 ? sigma.toPrecision(2) : "-";
    row.insertCell().textContent = identified ? "identified" : "not identified";
  }
}

// Which handler a channel's messages go to, by the last part of its topic (the LCM channel's
// name after its prefix, controller.telemetry.channel_prefix).
const HANDLERS = [
  [/STATE$/, onTick], [/EVENT$/, onEvent], [/PLANE_FORECAST$/, onPlaneForecast], [/PREDICTION$/, onPrediction],
  [/HEALTH$/, onHealth], [/IDENTIFICATION$/, onIdentification], [/PLANE$/, onPlane],
];

const decoder = new TextDecoder();

function onMessage(channel, stampNs, payload) {
  let m;
  try {
    m = JSON.parse(decoder.decode(payload));
  } catch (err) {
    addStatus(2, `${channel.topic}: a message that is not JSON (${err})`);
    return;
  }
  state.messages += 1;
  const c = state.channels[channel.topic];
  if (c) {
    c.received += 1;
    countSequence(channel.topic, c, m);
  }
  if (c?.isState) state.lagS = Date.now() / 1e3 - Number(stampNs) / 1e9;  // how far behind the page is
  const handler = HANDLERS.find(([re]) => re.test(channel.topic));
  if (handler) handler[1](m, c ?? {});
}

function addStatus(level, message) {
  state.status.push({ level, message });
  if (state.status.length > 50) state.status.shift();
  const ul = document.getElementById("status-messages");
  const li = document.createElement("li");
  li.className = ["info", "warn", "error"][level] ?? "info";
  li.textContent = message;
  ul.insertBefore(li, ul.firstChild);
  while (ul.children.length > 20) ul.removeChild(ul.lastChild);
}

// ---------------------------------------------------------------- the connection
let client = null;

function connect() {
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`;
  client = new FoxgloveClient(url, {
    onOpen: () => setConnection("open"),
    onClose: () => {
      state.connected = false;
      state.channels = {};
      setConnection("closed");
      setTimeout(connect, 1000);
    },
    onServerInfo: (info) => {
      state.serverInfo = info;
      for (const entry of (info.metadata?.modes ?? "").split(",").filter(Boolean)) {
        const [number, name] = entry.split(":");
        MODE_NAMES[Number(number)] = name;
      }
      state.connected = true;
      setConnection("connected");
      document.getElementById("server-info").textContent =
        `${info.name}; capabilities: ${(info.capabilities ?? []).join(", ") || "none"}`;
      const canCommand = (info.capabilities ?? []).includes("clientPublish");
      document.getElementById("commands").dataset.serverAcceptsCommands = String(canCommand);
    },
    onStatus: (s) => {
      if (s.id === "pneu-dash.skipped") return onSkippedReport(s);  // twice a second: not listed
      addStatus(s.level, s.message);
      // The server tells how many messages it dropped for this page (a full send queue), by channel
      // ("dropped 12 messages (PNEU_STATE 10, PNEU_HEALTH 2) ..."): those of a channel with sequence
      // numbers are counted by them already.
      const dropped = /^dropped (\d+) messages \(([^)]*)\)/.exec(s.message ?? "");
      if (s.id === "pneu-dash.dropped" && dropped) {
        for (const part of dropped[2].split(", ")) {
          const [, topic, n] = /^(.*) (\d+)$/.exec(part) ?? [];
          if (topic !== undefined && !state.channels[topic]?.sequenceField) state.gaps.serverDropped += Number(n);
        }
        updateGapBadge();
      }
    },
    onAdvertise: (channels) => {
      for (const c of channels) {
        let properties = {};
        try { properties = JSON.parse(c.schema || "{}").properties ?? {}; } catch { /* no schema */ }
        state.channels[c.topic] = { id: c.id, schemaName: c.schemaName, received: 0, properties, isState: /STATE$/.test(c.topic),
                                    sequenceField: c.sequenceField ?? (properties.seq && /STATE$/.test(c.topic) ? "seq" : ""),
                                    decimated: Boolean(c.latestWins) && MAX_RATE_HZ > 0,
                                    gapsInSequence: 0, skipped: 0, lost: 0 };
      }
      // A latest-wins channel (the ticks) at the rate this page asks, 0 every message (whatever the
      // server's default); the others never decimated.
      const latest = new Set(channels.filter((c) => c.latestWins).map((c) => c.id));
      client.subscribe(channels.map((c) => c.id), (id) => (latest.has(id) ? { maxRateHz: MAX_RATE_HZ } : {}));
    },
    onMessage,
  });
  client.connect();
  window.pneuDash.client = client;
}

function setConnection(what) {
  const el = document.getElementById("connection");
  el.dataset.state = what;
  el.textContent = what;
}

// ---------------------------------------------------------------- commands (the cmd part)
// sendCommand(kind, value) -> Promise<{accepted, text}>. Unimplemented here: a commands module
// installs the implementation (installCommands) when the server takes commands.
let commandImpl = null;

function sendCommand(kind, value) {
  if (!commandImpl) return Promise.resolve({ accepted: false, text: "commands are off on this server" });
  return commandImpl(kind, value, document.getElementById("cmd-token").value);
}

function installCommands(impl) {
  commandImpl = impl;
  state.commandsEnabled = true;
  const panel = document.getElementById("commands");
  panel.dataset.enabled = "true";
  document.getElementById("commands-state").textContent = "(on: pneud validates each command)";
  for (const el of panel.querySelectorAll("button, input")) el.disabled = false;
}

// v.by: who said it, "pneud" (its verdict, in its words: "accepted: set point 170.000 mm",
// "rejected (mode): ...") or "pneu-dash" (nothing was sent: a wrong token, not connected).
function showVerdict(v) {
  const el = document.getElementById("cmd-verdict");
  el.dataset.verdict = v.accepted ? "accepted" : "rejected";
  el.dataset.by = v.by ?? "";
  el.textContent = v.by === "pneud" ? `pneud ${v.text}`
                 : v.by ? `${v.by}: ${v.text}`
                 : `${v.accepted ? "accepted" : "refused"}: ${v.text}`;
}

function wireCommandPanel() {
  const run = (kind, value) => sendCommand(kind, value).then(showVerdict,
    (err) => showVerdict({ accepted: false, text: String(err) }));
  document.getElementById("cmd-arm").onclick = () => run("arm");
  document.getElementById("cmd-disarm").onclick = () => run("disarm");
  document.getElementById("cmd-fault-reset").onclick = () => run("fault_reset");
  document.getElementById("cmd-send-set-point").onclick = () =>
    run("set_point", Number(document.getElementById("cmd-set-point").value) * 1e-3);
  document.getElementById("cmd-hold-on").onclick = () => run("hold", true);
  document.getElementById("cmd-hold-off").onclick = () => run("hold", false);
}

// ---------------------------------------------------------------- start
// The page's state, for people (the console) and for the browser test.
window.pneuDash = {
  state,
  sendCommand,
  installCommands,
  client: null,
  // A summary the test reads: what the page shows now.
  snapshot() {
    const phase = state.stop;
    const f = phase ? preferred(phase.forecasts) : null;
    const path = phase ? preferred(phase.paths) : null;
    const fc = document.getElementById("forecast").dataset;
    return {
      connected: state.connected,
      topics: Object.keys(state.channels),
      received: Object.fromEntries(Object.entries(state.channels).map(([k, c]) => [k, c.received])),
      // per channel with sequence numbers: the first and last seen, the messages received between
      sequences: Object.fromEntries(Object.entries(state.channels).filter(([, c]) => c.lastSeq !== undefined)
        .map(([k, c]) => [k, { first: c.firstSeq, last: c.lastSeq, received: c.receivedSinceFirst,
                               decimated: c.decimated, reportedSeq: c.reportedSeq ?? null, skipped: c.skipped,
                               lost: c.decimated ? c.lost : (state.gaps.byTopic[k] ?? 0) }])),
      maxRateHz: state.maxRateHz,
      ticks: state.ticks,
      t: state.tick?.t ?? null,
      tickTimes: [...state.tickTimes],
      tracePoints: charts.force ? charts.force.data.datasets[0]._data?.length ?? series.force.length : 0,
      planeLoaded: Boolean(state.plane),
      nullFlowPoints: state.plane?.null_flow.length ?? 0,
      planePoint: state.planePoint,
      trailPoints: charts.plane?.data.datasets[PLANE.trail].data.length ?? 0,
      trailSegments: charts.plane?.getDatasetMeta(PLANE.trail).dataset?.segments.length ?? 0,
      stuck: state.stuck,
      stop: phase ? { index: phase.index, t: phase.t } : null,
      forecast: f ? { method: f.method, will_restart: f.will_restart, t_restart: f.t_restart } : null,
      forecastPathPoints: path ? path.path.length : 0,
      forecastState: fc.state,
      forecastStop: fc.stop === undefined ? null : Number(fc.stop),  // the stop the forecast drawn is of
      countdownS: fc.countdownS === undefined ? null : Number(fc.countdownS),
      countdownText: document.getElementById("countdown").textContent,
      lastRestart: state.lastPhase?.restart ? { t: state.lastPhase.restart.t, stop: state.lastPhase.index } : null,
      restarts: state.restarts.map((r) => ({ ...r })),
      events: state.events,
      gaps: { ...state.gaps },
      health: Boolean(state.health),
      drawMs: state.drawMs ?? null,
      lagS: state.tick ? state.lagS : null,
      identification: Boolean(state.identification),
    };
  },
};

if (MAX_RATE_HZ > 0)
  document.getElementById("trace-rate").textContent =
    `the newest tick at most ${MAX_RATE_HZ} times a second (max_rate_hz): a spike between two is not drawn`;
makeTraceCharts();
makeTimeline();
makePlaneChart();
wireCommandPanel();
connect();

let lastDraw = 0;
let drawEvery = REDRAW_MS;
function draw() {
  const now = performance.now();
  if (now - lastDraw < drawEvery) return;
  lastDraw = now;
  redrawTraces();
  redrawPlane();
  redrawForecast();
  const took = performance.now() - now;
  state.drawMs = took;
  drawEvery = Math.max(REDRAW_MS, 3 * took);
}
function frame() {
  draw();
  requestAnimationFrame(frame);
}
requestAnimationFrame(frame);
// A hidden page gets no animation frames: draw on a timer too.
setInterval(() => { if (performance.now() - lastDraw > 4 * drawEvery) draw(); }, 4 * REDRAW_MS);
