#include "pneu/controller/run_summary.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "pneu/records/json.hpp"
#include "pneu/config/cli.hpp"
#include "pneu/controller/supervisor.hpp"
#include "pneu/controller/verdict.hpp"

namespace pneu::controller {

namespace {

using ull = unsigned long long;

// One forecast against what happened: the restart time and its error.
std::string forecast_cell(const StopOutcome& s, const Prediction& p, double t_end_s) {
  const Verdict v = judge(s, p, t_end_s);
  char buf[64];
  if (!p.will_restart)
    std::snprintf(buf, sizeof buf, "none%s", v.kind == Verdict::Kind::kFalseNegative ? " (MISSED)" : "");
  else if (v.kind == Verdict::Kind::kTruePositive && s.sticking_s() >= 0.5)
    std::snprintf(buf, sizeof buf, "%c %.4f s (%.2f %%)%s", p.direction > 0 ? '+' : '-', p.t_restart_s,
                  v.error_percent, v.direction_ok ? "" : " WRONG DIR");
  else if (v.kind == Verdict::Kind::kTruePositive)
    std::snprintf(buf, sizeof buf, "%c %.4f s (%+.1f ms)%s", p.direction > 0 ? '+' : '-', p.t_restart_s,
                  v.error_s * 1e3, v.direction_ok ? "" : " WRONG DIR");
  else
    std::snprintf(buf, sizeof buf, "%c %.4f s%s", p.direction > 0 ? '+' : '-', p.t_restart_s,
                  v.kind == Verdict::Kind::kFalsePositive ? " (FALSE)" : "");
  return buf;
}

// Each stop, what each method forecast at it and what happened.
void print_stops(std::FILE* out, const Runtime& runtime) {
  const PredictorModel& model = runtime.model();
  std::fprintf(out, "stops (sticking phases) and their restart forecasts; forecast error in %% of the sticking\n"
                    "time when it lasted 0.5 s or more, in ms (forecast - actual) otherwise:\n");
  if (runtime.forecasts(PredictionMethod::kLinearized) && model.linearized_slope != LinearizedSlope::kStopTangent)
    std::fprintf(out, "(linearized: Eq. 23's flow slope is the %s (controller.predictor.linearized_slope: %s),\n"
                      " not the paper's tangent at the stop pressure)\n",
                 model.linearized_slope == LinearizedSlope::kChord ? "chord from the stop pressure to p_null(u*)"
                                                                    : "tangent at p_null(u*)",
                 to_string(model.linearized_slope));
  if (!model.fits)
    std::fprintf(out, "(UNCERTAIN: the model these forecasts are made on did not fit the bench when it was identified:\n"
                      " its pressure residual was beyond twice what the sensors' noise explains (controller.predictor.\n"
                      " model_fit, or online learning's last valve fit); a physics the model lacks? plant.thermal,\n"
                      " plant.valve.spool_time_constant_s)\n");
  std::fprintf(out, "  %3s %9s %9s %8s %8s %8s  %-34s %-24s %-24s\n", "#", "t_stop[s]", "y*[mm]", "F[N]",
               "u*[V]", "F_e[N]", "what happened", "linearized", "nonlinear");
  bool unforecast = false;
  for (const auto& s : runtime.stops()) {
    char happened[64];
    if (!s.ended && s.held_first)
      std::snprintf(happened, sizeof happened, "held from %.4f s to the end", s.held_first->t_s);
    else if (!s.ended && !std::isnan(s.forecast_void_at_s))
      std::snprintf(happened, sizeof happened, "stuck; u* changed at %.4f s", s.forecast_void_at_s);
    else if (!s.ended)
      std::snprintf(happened, sizeof happened, "stuck to the end (%.3f s)", s.sticking_s());
    else if (s.restarted)
      std::snprintf(happened, sizeof happened, "restart %c at %.4f s (%.3f s)", s.direction > 0 ? '+' : '-',
                    s.t_end_s, s.sticking_s());
    else
      std::snprintf(happened, sizeof happened, "set point moved at %.4f s", s.t_end_s);
    std::string cells[2];
    const std::optional<Prediction>* ps[2] = {&s.linearized, &s.nonlinear};
    for (int i = 0; i < 2; ++i) cells[i] = *ps[i] ? forecast_cell(s, **ps[i], runtime.end_time_s()) : "-";
    // F_e is a forecast's: a stop without one (not controlled then, or a reading not finite) has none.
    const Prediction* any = s.nonlinear ? &*s.nonlinear : (s.linearized ? &*s.linearized : nullptr);
    char f_e[16] = "n/a";
    if (any && std::isfinite(any->equilibrium_force_n)) std::snprintf(f_e, sizeof f_e, "%.2f", any->equilibrium_force_n);
    else unforecast = true;
    std::fprintf(out, "  %3llu %9.4f %9.3f %8.2f %8.4f %8s  %-34s %-24s %-24s\n", static_cast<ull>(s.index),
                 s.t_stop_s, s.y_stop_m * 1e3, s.force_n, s.snapshot.u_v, f_e, happened, cells[0].c_str(),
                 cells[1].c_str());
  }
  if (runtime.stops().empty()) std::fprintf(out, "  (none)\n");
  if (unforecast)
    std::fprintf(out, "  (F_e n/a: no forecast at that stop: the law did not drive the valves then (a fault's safe output,\n"
                      "   disarmed or held; u* is the law's resting output, not what the valves got), or a reading was\n"
                      "   not finite)\n");
  if (runtime.stops_forgotten() > 0)
    std::fprintf(out, "  (and %llu earlier stops, not kept)\n", static_cast<ull>(runtime.stops_forgotten()));
}

// The live predictor: each forecast made at the stop against the measured force, and the
// forecasts made again half-way.
void print_live(std::FILE* out, const Runtime& runtime) {
  const auto& stops = runtime.stops();
  const auto followed = [](const StopOutcome& s) {
    return !std::isnan(s.largest_gap_linearized_n) || !std::isnan(s.largest_gap_nonlinear_n) || s.updates > 0;
  };
  if (std::none_of(stops.begin(), stops.end(), followed)) return;
  std::fprintf(out, "while stuck: the largest gap between the measured force and each forecast made at the stop (until\n"
                    "the start is seen), and the forecast made again from the pressures half-way through the phase%s:\n",
               runtime.update_period_s() > 0.0 ? "" : " (off: controller.predictor.update_period_s = 0)");
  // The relaxation method's column only when it runs (it has no forecast at the stop to follow).
  const bool relaxation = runtime.forecasts(PredictionMethod::kRelaxation);
  std::fprintf(out, "  %3s %11s %12s %12s %7s  %-24s %-24s%s\n", "#", "stuck[s]", "gap lin[N]", "gap nl[N]",
               "updates", "half-way linearized", "half-way nonlinear", relaxation ? " half-way relaxation" : "");
  for (const auto& s : stops) {
    if (!followed(s)) continue;
    std::string cells[3] = {"-", "-", "-"};
    const std::optional<Reforecast>* halfway[3] = {&s.halfway_linearized, &s.halfway_nonlinear, &s.halfway_relaxation};
    for (int i = 0; i < 3; ++i)
      if (*halfway[i]) cells[i] = forecast_cell(s, (*halfway[i])->prediction, runtime.end_time_s());
    std::fprintf(out, "  %3llu %11.3f %12.3f %12.3f %7u  %-24s %-24s%s%s\n", static_cast<ull>(s.index),
                 s.sticking_s(), s.largest_gap_linearized_n, s.largest_gap_nonlinear_n, s.updates, cells[0].c_str(),
                 cells[1].c_str(), relaxation ? " " : "", relaxation ? cells[2].c_str() : "");
  }
}

// Under the in-position hold: the forecast under its commands made as each hold began, against what
// happened, and how many of those made while it held said restart.
void print_held(std::FILE* out, const Runtime& runtime) {
  const auto& stops = runtime.stops();
  const auto held = [](const StopOutcome& s) { return s.held_first.has_value(); };
  if (std::none_of(stops.begin(), stops.end(), held)) return;
  std::fprintf(out, "under the in-position hold: the forecast under its commands (method held) as the hold began,\n"
                    "and of those made while it held (every update period), how many said restart:\n");
  std::fprintf(out, "  %3s %11s  %-40s %9s %8s\n", "#", "hold[s]", "as it began", "forecasts", "restart");
  for (const auto& s : stops) {
    if (!held(s)) continue;
    const Prediction& p = s.held_first->prediction;
    const bool broke_away = s.ended && s.restarted;
    char cell[96];
    if (p.will_restart && broke_away)
      std::snprintf(cell, sizeof cell, "%c %.4f s (%+.1f ms)", p.direction > 0 ? '+' : '-', p.t_restart_s,
                    (p.t_restart_s - s.t_end_s) * 1e3);
    else if (p.will_restart)
      std::snprintf(cell, sizeof cell, "%c %.4f s (none came)", p.direction > 0 ? '+' : '-', p.t_restart_s);
    else
      std::snprintf(cell, sizeof cell, "none%s: F -> %.2f N, margin %.2f N%s", broke_away ? " (MISSED)" : "",
                    p.equilibrium_force_n, p.min_margin_n, p.horizon_reached ? " (horizon)" : "");
    std::fprintf(out, "  %3llu %11.4f  %-40s %9u %8u\n", static_cast<ull>(s.index), s.held_first->t_s, cell,
                 s.held_forecasts, s.held_restart_forecasts);
  }
}

void print_loop(std::FILE* out, const LoopTiming& timing) {
  const auto us = [](double s) { return s * 1e6; };
  std::fprintf(out, "loop: %llu ticks at %.0f Hz, %llu overruns (%llu deadlines skipped)\n",
               static_cast<ull>(timing.ticks), 1.0 / timing.period_s, static_cast<ull>(timing.overruns),
               static_cast<ull>(timing.deadlines_skipped));
  std::fprintf(out, "  wake-up latency [us]  min %8.2f  median %8.2f  p99 %8.2f  max %8.2f\n",
               us(timing.wake_latency.min_s()), us(timing.wake_latency.quantile_s(0.5)),
               us(timing.wake_latency.quantile_s(0.99)), us(timing.wake_latency.max_s()));
  std::fprintf(out, "  compute per tick [us] min %8.2f  median %8.2f  p99 %8.2f  max %8.2f\n",
               us(timing.compute.min_s()), us(timing.compute.quantile_s(0.5)), us(timing.compute.quantile_s(0.99)),
               us(timing.compute.max_s()));
}

void print_telemetry(std::FILE* out, const TelemetryFigures& t) {
  const CommandCounters& c = t.commands;
  std::fprintf(out,
               "telemetry: LCM %s, channels %s*; %llu publish errors; commands: %llu received, %llu accepted, %llu rejected "
               "(malformed %llu, oversized %llu, foreign %llu, stale %llu, sequence %llu, invalid %llu, rate %llu, mode %llu)\n",
               t.lcm_url.c_str(), t.channel_prefix.c_str(), static_cast<ull>(t.publish_errors), static_cast<ull>(c.received),
               static_cast<ull>(c.accepted), static_cast<ull>(c.rejected), static_cast<ull>(c.malformed),
               static_cast<ull>(c.oversized), static_cast<ull>(c.foreign), static_cast<ull>(c.stale),
               static_cast<ull>(c.sequence), static_cast<ull>(c.invalid), static_cast<ull>(c.rate),
               static_cast<ull>(c.mode));
}

// The link's exchanges per second of the run: those made before its time started (the movement
// test's) are not the loop's.
double transactions_per_s(const RunFigures& f, double t_end_s) {
  const std::uint64_t before = std::min(f.link_transactions_before_time, f.modbus->transactions);
  return static_cast<double>(f.modbus->transactions - before) / std::max(t_end_s, 1e-9);
}

void print_modbus(std::FILE* out, const RunFigures& f, double t_end_s) {
  const hal::LinkReport& m = *f.modbus;
  std::fprintf(out,
               "modbus: %llu transactions (%.0f per second), %llu errors, %llu reconnects, %llu samples out of range, "
               "%llu stale reads, oldest sample %.2f ms%s%s\n",
               static_cast<ull>(m.transactions), transactions_per_s(f, t_end_s),
               static_cast<ull>(m.errors), static_cast<ull>(m.reconnects), static_cast<ull>(m.out_of_range),
               static_cast<ull>(m.stale_reads), m.oldest_sample_s * 1e3, m.errors ? "; last error: " : "",
               m.errors ? m.last_error.c_str() : "");
  const bool read_back = !std::isnan(m.safe_output_read_back_u_p_v);
  if (m.safe_output_delivered)
    std::fprintf(out,
                 "  safe output on closing: delivered to the module on attempt %d of %d: its valve registers read back "
                 "u_P = %+.4f V, u_N = %+.4f V\n",
                 m.safe_output_attempts, m.safe_output_max_attempts, m.safe_output_read_back_u_p_v,
                 m.safe_output_read_back_u_n_v);
  else if (read_back)
    std::fprintf(out,
                 "  safe output on closing: NOT confirmed by the module after %d attempts: its valve registers last "
                 "read back u_P = %+.4f V, u_N = %+.4f V\n",
                 m.safe_output_attempts, m.safe_output_read_back_u_p_v, m.safe_output_read_back_u_n_v);
  else
    std::fprintf(out, "  safe output on closing: NOT confirmed by the module after %d attempts\n",
                 m.safe_output_attempts);
}

// The time of the fault latched at the end: the last fault event's, when it names that cause.
double latched_since_s(const RunFigures& f, const Runtime& runtime) {
  const auto& faults = runtime.faults();
  return !faults.empty() && faults.back().fault_cause == f.fault_at_end ? faults.back().t_s : NAN;
}

}  // namespace

RunEnding run_ending(const RunFigures& f) noexcept {
  if (f.modbus && !f.modbus->safe_output_delivered) return RunEnding::kSafeOutputUnconfirmed;
  if (f.fault_at_end != FaultCause::kNone) return RunEnding::kFaultLatched;
  return RunEnding::kOk;
}

const char* to_string(RunEnding ending) noexcept {
  switch (ending) {
    case RunEnding::kOk: return "ok";
    case RunEnding::kFaultLatched: return "fault_latched";
    case RunEnding::kSafeOutputUnconfirmed: return "safe_output_unconfirmed";
  }
  return "?";
}

int exit_code(RunEnding ending) noexcept {
  switch (ending) {
    case RunEnding::kOk: return cli::kExitOk;
    case RunEnding::kFaultLatched: return cli::kExitFaulted;
    case RunEnding::kSafeOutputUnconfirmed: return cli::kExitSafeOutputUnconfirmed;
  }
  return cli::kExitFailure;
}

std::string ending_text(const RunFigures& f, const Runtime& runtime) {
  const RunEnding ending = run_ending(f);
  if (ending == RunEnding::kOk) return "";
  char fault[160] = "";
  if (f.fault_at_end != FaultCause::kNone) {
    const double since_s = latched_since_s(f, runtime);
    if (std::isnan(since_s))
      std::snprintf(fault, sizeof fault, "a fault latched (%s)", fault_name(f.fault_at_end));
    else
      std::snprintf(fault, sizeof fault, "a fault latched (%s, since %.3f s)", fault_name(f.fault_at_end), since_s);
  }
  char text[512];
  if (ending == RunEnding::kSafeOutputUnconfirmed)
    std::snprintf(text, sizeof text,
                  "SAFE OUTPUT NOT CONFIRMED: the module did not confirm the safe output on closing (%d attempts): it "
                  "may still hold the last command%s%s; exit code %d",
                  f.modbus->safe_output_attempts, fault[0] ? ", and the run ended with " : "", fault, exit_code(ending));
  else
    std::snprintf(text, sizeof text, "FAULTED: the run ended with %s, the outputs in the safe state; exit code %d", fault,
                  exit_code(ending));
  return text;
}

void print_summary(std::FILE* out, const RunFigures& f, const Runtime& runtime) {
  const double t_end_s = runtime.end_time_s();
  if (const std::string ending = ending_text(f, runtime); !ending.empty()) std::fprintf(out, "%s\n", ending.c_str());
  std::fprintf(out, "pneud %s: %.3f s on the %s backend, %s clock (%s), u_0 = %+.4f V, wall time %.3f s (%.0fx real time)\n",
               f.version.c_str(), t_end_s, f.backend.c_str(), f.clock.c_str(), f.config.c_str(), f.u_0_v, f.wall_s,
               t_end_s / f.wall_s);
  print_stops(out, runtime);
  print_live(out, runtime);
  print_held(out, runtime);
  for (const auto& fault : runtime.faults())
    std::fprintf(out, "fault at %.4f s (y = %.3f mm): %s: %s%s%s\n", fault.t_s, fault.y_m * 1e3,
                 fault_name(fault.fault_cause), fault_text(fault.fault_cause),
                 fault.fault_key != nullptr ? "; decided by " : "", fault.fault_key != nullptr ? fault.fault_key : "");
  print_loop(out, f.timing);
  if (f.telemetry) print_telemetry(out, *f.telemetry);
  if (f.modbus) print_modbus(out, f, t_end_s);
  if (f.ticks_dropped || f.events_dropped)
    std::fprintf(out, "  telemetry dropped: %llu tick records, %llu events\n", static_cast<ull>(f.ticks_dropped),
                 static_cast<ull>(f.events_dropped));
}

namespace {

DurationsSummary durations_us(const TimingStats& stats) {
  return {stats.min_s() * 1e6, stats.quantile_s(0.5) * 1e6, stats.quantile_s(0.99) * 1e6, stats.max_s() * 1e6};
}

}  // namespace

RunSummaryRecord run_summary_record(const RunFigures& f, const Runtime& runtime) {
  RunSummaryRecord s;
  s.pneud = f.version;
  const RunEnding ending = run_ending(f);
  s.exit_reason = to_string(ending);
  s.exit_code = static_cast<std::uint64_t>(exit_code(ending));
  if (f.fault_at_end != FaultCause::kNone) s.fault_at_end = fault_name(f.fault_at_end);
  s.backend = f.backend;
  s.clock = f.clock;
  s.config = f.config;
  s.u_0_v = f.u_0_v;
  s.t_end_s = runtime.end_time_s();
  s.wall_s = f.wall_s;
  LoopSummary& l = s.loop;
  l.ticks = f.timing.ticks;
  l.rate_hz = 1.0 / f.timing.period_s;
  l.overruns = f.timing.overruns;
  l.deadlines_skipped = f.timing.deadlines_skipped;
  l.wake_latency_us = durations_us(f.timing.wake_latency);
  l.compute_us = durations_us(f.timing.compute);
  l.tick_records_dropped = f.ticks_dropped;
  l.events_dropped = f.events_dropped;
  l.epoch_monotonic_s = f.timing.epoch_monotonic_s;
  s.runtime = {runtime.ticks_seen(), runtime.sequence_gaps(), runtime.stops_forgotten() + runtime.stops().size(),
               runtime.stops_forgotten(), runtime.model_updates_late()};
  for (const auto& fault : runtime.faults())
    s.faults.push_back({fault.t_s, fault.y_m, fault_name(fault.fault_cause), fault.fault_key});
  if (const auto& t = f.telemetry) {
    const CommandCounters& c = t->commands;
    s.telemetry = TelemetrySummary{t->lcm_url, t->channel_prefix, t->publish_errors,
                                   CommandsSummary{c.received, c.accepted, c.rejected, c.malformed, c.oversized,
                                                   c.foreign, c.stale, c.sequence, c.invalid, c.rate, c.mode,
                                                   t->commands_dropped}};
  }
  if (const auto& m = f.modbus) {
    ModbusSummary b;
    b.transactions = m->transactions;
    b.transactions_per_s = transactions_per_s(f, runtime.end_time_s());
    b.errors = m->errors;
    b.reconnects = m->reconnects;
    b.samples_out_of_range = m->out_of_range;
    b.stale_reads = m->stale_reads;
    b.oldest_sample_ms = m->oldest_sample_s * 1e3;
    b.last_error = m->last_error;
    b.safe_output_on_closing = {m->safe_output_delivered, static_cast<std::uint64_t>(m->safe_output_attempts),
                                static_cast<std::uint64_t>(m->safe_output_max_attempts),
                                m->safe_output_read_back_u_p_v, m->safe_output_read_back_u_n_v};
    s.modbus = b;
  }
  return s;
}

void write_summary_json(std::ostream& out, const RunFigures& f, const Runtime& runtime) {
  records::write_json_document(out, run_summary_record(f, runtime));
}

}  // namespace pneu::controller
