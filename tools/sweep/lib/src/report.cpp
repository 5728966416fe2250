// What a sweep writes: its summary and its JSON from the statistics, its stops and scenarios files
// from the results.
#include "pneu/sweep/report.hpp"

#include <algorithm>
#include <string>

#include "pneu/records/csv.hpp"
#include "pneu/records/json.hpp"
#include "pneu/sweep/rows.hpp"
#include "pneu/controller/supervisor.hpp"
#include "pneu/model/chamber.hpp"

namespace pneu::sweep {

using controller::Verdict;

namespace {

const char* verdict_name(Verdict::Kind k) {
  switch (k) {
    case Verdict::Kind::kTruePositive: return "true_restart";
    case Verdict::Kind::kTrueNegative: return "true_no_restart";
    case Verdict::Kind::kFalsePositive: return "false_restart";
    case Verdict::Kind::kFalseNegative: return "missed_restart";
    case Verdict::Kind::kNotJudged: return "not_judged";
  }
  return "?";
}

unsigned long long ull(std::uint64_t v) { return static_cast<unsigned long long>(v); }

// The live predictor's half-way forecasts of the restarts after >= 0.5 s.
void print_halfway(std::FILE* out, const MethodStatistics& st) {
  const Percentiles& h = st.halfway_error_percent;
  std::fprintf(out,
               "    made again half-way, sticking >= 0.5 s (%zu): p50 %.3f %%  p90 %.3f %%  p99 %.3f %%  max %.3f %% "
               "(the live predictor, from the pressures of the moment; not judged)\n",
               h.count, h.p50, h.p90, h.p99, h.max);
  const Within2510& within = st.halfway_within;
  std::fprintf(out,
               "      of %llu such restarts: within 2 %%: %zu, 5 %%: %zu, 10 %%: %zu (wrong direction: %llu); forecast "
               "none: %llu; restart after the run: %llu; no forecast by half-way: %llu\n",
               ull(st.halfway_restarts()), within[0], within[1], within[2], ull(st.halfway_wrong_direction),
               ull(st.halfway_none), ull(st.halfway_after_run), ull(st.halfway_missing));
}

}  // namespace

void print_summary(std::FILE* out, const Statistics& st) {
  const Setting& set = st.setting;
  const Options& o = set.options;
  const int n = st.scenarios;
  char bench_text[160] = "";
  if (o.design != Design::kMonteCarlo)
    std::snprintf(bench_text, sizeof bench_text,
                  ", an atlas (%s) of set point x bench friction and dead volumes +-%.0f %%, null offset within +-%.3g V%s%s",
                  design_name(o.design), o.bench_spread * 100, 0.5 * o.bench_spread,
                  o.bench_thermal_s.given() ? ", thermal time constant" : "",
                  o.bench_spool_lag_s.given() ? ", spool lag" : "");
  else if (o.bench_spread > 0.0)
    std::snprintf(bench_text, sizeof bench_text, ", bench +-%.0f %% of the model and a valve null offset within +-%.3g V",
                  o.bench_spread * 100, 0.5 * o.bench_spread);
  std::fprintf(out,
               "pneu-sweep: %d scenarios (%d set-point steps over [%.3f, %.3f] m, seed %llu, friction +-%.0f %%, gains "
               "+-%.0f %%%s), stops of the first %.0f s judged (+ %.1f s tail)\n",
               n, n, set.targets.lo_m, set.targets.hi_m, ull(o.seed), o.friction_spread * 100, o.gain_spread * 100,
               bench_text, o.duration_s, o.tail_s);
  std::fprintf(out,
               "  %llu stops, %llu restarts (%llu after >= 0.5 s of sticking, %llu after >= 1 s), timed by the plant's "
               "breakaways; %llu of them moved the carriage less than the stop detector's motion band\n",
               ull(st.stops), ull(st.restarts), ull(st.long_restarts), ull(st.restarts_after_1_s),
               ull(st.restarts_below_motion_band));
  if (st.start_gap_ms.count > 0) {
    const Percentiles &early = st.start_early_ms, &late = st.start_late_ms, &gap = st.start_gap_ms;
    std::fprintf(out,
                 "  the detector dated the %zu starts it saw %zu before the plant's breakaway (max %.1f ms), %zu at or "
                 "after it (max %.1f ms); |gap| p50 %.2f ms p90 %.2f ms p99 %.1f ms\n",
                 gap.count, early.count, early.count == 0 ? 0.0 : early.max, late.count,
                 late.count == 0 ? 0.0 : late.max, gap.p50, gap.p90, gap.p99);
  }
  if (st.not_at_rest > 0)
    std::fprintf(out,
                 "  %llu stops were confirmed while the plant was still sliding within the detector's rest band: "
                 "their forecasts are not judged\n",
                 ull(st.not_at_rest));
  std::fprintf(out,
               "  outcomes (the first rest after the step): %llu settled, %llu never settled, %llu at rest against an end "
               "stop, %llu faults\n",
               ull(st.count(Outcome::kSettled)), ull(st.count(Outcome::kNeverSettled)), ull(st.count(Outcome::kEndStop)),
               ull(st.count(Outcome::kFault)));
  if (st.count(Outcome::kFault) > 0) {
    std::fprintf(out, "    faults by cause:");
    for (std::size_t c = 1; c < st.faults_by_cause.size(); ++c)
      if (st.faults_by_cause[c] > 0)
        std::fprintf(out, " %s %llu", controller::fault_name(static_cast<controller::FaultCause>(c)),
                     ull(st.faults_by_cause[c]));
    std::fprintf(out, "\n");
  }
  for (const Outcome oc : {Outcome::kNeverSettled, Outcome::kEndStop, Outcome::kFault}) {
    const OutcomeStatistics& k = st.outcomes[static_cast<std::size_t>(oc)];
    if (k.count == 0) continue;
    std::fprintf(out, "    %s: y0 in [%.3f, %.3f] m, y_d in [%.3f, %.3f] m\n", outcome_name(oc), k.y0_min_m, k.y0_max_m,
                 k.y_d_min_m, k.y_d_max_m);
  }
  const Percentiles &settle = st.settle_time_s, &fin = st.final_error_m, &win = st.in_window_after_s;
  std::fprintf(out, "    settle time from the step (%zu settled): p50 %.3f s  p90 %.3f s  p99 %.3f s  max %.3f s\n",
               settle.count, settle.p50, settle.p90, settle.p99, settle.max);
  std::fprintf(out, "    final |y_d - y| (%zu settled): p50 %.3f mm  p90 %.3f mm  p99 %.3f mm  max %.3f mm\n", fin.count,
               fin.p50 * 1e3, fin.p90 * 1e3, fin.p99 * 1e3, fin.max * 1e3);
  std::fprintf(out,
               "    at rest within +-%.3f mm of the set point (controller.hold.window_m), from the step (%zu of %zu run): "
               "p50 %.3f s  p90 %.3f s  max %.3f s\n",
               set.hold_window_m * 1e3, win.count, st.scenarios_run, win.p50, win.p90, win.max);
  {
    // Over every scenario run, those never at rest within the window counted as never: beside the
    // percentiles above, which count only those that came to rest there.
    char p50[32], p90[32];
    for (auto [text, v] : {std::pair{p50, st.in_window_all_p50_s}, std::pair{p90, st.in_window_all_p90_s}}) {
      if (std::isinf(v)) std::snprintf(text, sizeof p50, "never");
      else std::snprintf(text, sizeof p50, "%.3f s", v);
    }
    std::fprintf(out, "    ... over all %zu run, the %zu never at rest within it counted as never: p50 %s  p90 %s\n",
                 win.count + st.never_in_window, st.never_in_window, p50, p90);
  }
  std::fprintf(out,
               "    the in-position hold (%s): began in %llu scenarios; restarts after it began (breakaways of the plant "
               "beyond the motion band): %llu, in %llu scenarios\n",
               set.hold_enabled ? "on" : "off", ull(st.held), ull(st.restarts_after_hold), ull(st.restarted_after_hold));
  if (set.hold_enabled) {
    const Percentiles& reach = st.reach_forecast_error_ms;
    const auto& within = st.reach_forecasts_within_1_2_5_ms;
    std::fprintf(out,
                 "    forecasts under the hold's commands (method held): %llu made while held within the window, %llu of "
                 "them a restart; reaches that broke away: %zu, forecast as each began within 1 / 2 / 5 ms of the start "
                 "seen: %zu / %zu / %zu (|error| p50 %.2f ms, max %.2f ms), %llu forecast none\n",
                 ull(st.held_forecasts), ull(st.held_restart_forecasts), reach.count, within[0], within[1], within[2],
                 reach.p50, reach.max, ull(st.reaches_forecast_none));
  }
  if (st.settling_rules_checked) {
    const SettlingRules& rules = set.settling_rules;
    std::fprintf(out,
                 "    the settling rules (%u sign changes beyond +-%.1f mm within %.2f s; settle time %.2f s), checked "
                 "alongside, would latch the oscillation or not-settled fault in:",
                 rules.sign_changes, rules.amplitude_m * 1e3, rules.window_s, rules.settle_time_s);
    const char* separator = " ";
    for (const Outcome oc : kOutcomes) {
      const OutcomeStatistics& k = st.outcomes[static_cast<std::size_t>(oc)];
      if (k.count == 0) continue;
      std::fprintf(out, "%s%zu of %llu %s", separator, k.settling_rules_latched, ull(k.count), outcome_name(oc));
      separator = ", ";
    }
    if (st.settling_rules_latched_after_s.count > 0)
      std::fprintf(out, "; after the step: p50 %.3f s  max %.3f s", st.settling_rules_latched_after_s.p50,
                   st.settling_rules_latched_after_s.max);
    std::fprintf(out, "\n");
  }
  if (o.online)
    std::fprintf(out, "  online identification: %llu stops before their bench had restarted %d times (while it learns) not judged\n",
                 ull(st.before_learning), kOnlineLearningRestarts);
  if (o.identify) {
    const IdentificationStatistics& id = st.identification;
    std::fprintf(out, "  identified first (pneud's identification run on each bench): %zu of %d, %zu failed\n",
                 id.identified_and_run, n, id.failures.size());
    for (const auto& f : id.failures) std::fprintf(out, "    failed: %s\n", f.c_str());
    if (id.null_pressure_error_pa.count > 0) {
      for (int side = 0; side < 2; ++side) {
        const Percentiles& e = id.stiction_error_percent[static_cast<std::size_t>(side)];
        std::fprintf(out, "    %s error against the bench: p50 %.3f %%  p90 %.3f %%  max %.3f %%\n",
                     side == 0 ? "F_S+" : "F_S-", e.p50, e.p90, e.max);
      }
      const Percentiles& e = id.null_pressure_error_pa;
      std::fprintf(out, "    p_null(u) over |u| < 1 V, largest error against the bench: p50 %.0f Pa  p90 %.0f Pa  max %.0f Pa\n",
                   e.p50, e.p90, e.max);
    }
    if (id.residual_ratio.count > 0) {
      const Percentiles& r = id.residual_ratio;
      std::fprintf(out,
                   "    the model fits (pressure residual within twice what the sensors' noise explains) on %zu of %zu; "
                   "residual in what the noise explains: p50 %.2f  p90 %.2f  max %.2f\n",
                   id.fits, r.count, r.p50, r.p90, r.max);
      std::fprintf(out,
                   "    parameters published that the bench has too, within 3 of their stated sigmas of it: %d of %d "
                   "(%.1f %%)\n",
                   id.within_3_sigma, id.published, id.published > 0 ? 100.0 * id.within_3_sigma / id.published : 0.0);
      std::fprintf(out, "     ");
      for (const auto& k : id.by_key)
        std::fprintf(out, " %s %d of %d;", k.key.substr(k.key.rfind('.') + 1).c_str(), k.within_3_sigma, k.published);
      std::fprintf(out, "\n");
      for (std::size_t i = 0; i < id.outside.size() && i < 10; ++i) std::fprintf(out, "      outside: %s\n", id.outside[i].c_str());
      if (id.outside.size() > 10) std::fprintf(out, "      ... %zu scenarios with one outside in all\n", id.outside.size());
      if (id.heat_transfer_error_percent.count > 0) {
        const Percentiles& e = id.heat_transfer_error_percent;
        std::fprintf(out, "    heat transfer error against the bench: p50 %.3f %%  p90 %.3f %%  max %.3f %%\n", e.p50, e.p90,
                     e.max);
      }
      if (id.spool_lag_error_ms.count > 0) {
        const Percentiles& e = id.spool_lag_error_ms;
        std::fprintf(out, "    spool lag error against the bench: p50 %.4f ms  p90 %.4f ms  max %.4f ms\n", e.p50, e.p90,
                     e.max);
      }
    }
  }
  if (st.shards > 0)  // merged: the shards' wall times summed (they may have run at once, or not)
    std::fprintf(out, "  %.2f s wall summed over %d shards (each on up to %d threads): %.1f scenarios per shard-second\n",
                 st.wall_s, st.shards, st.jobs, n / st.wall_s);
  else
    std::fprintf(out, "  %.2f s wall on %d threads: %.1f scenarios/s\n", st.wall_s, st.jobs, n / st.wall_s);
  const std::string names[2] = {set.linearized_name, "nonlinear"};
  for (std::size_t m = 0; m < 2; ++m) {
    const MethodStatistics& ms = st.methods[m];
    if (ms.judged() == 0) continue;
    std::fprintf(out, "  %s:\n", names[m].c_str());
    std::fprintf(out, "    confusion            actual restart  actual none\n");
    std::fprintf(out, "      forecast restart   %14llu  %11llu\n", ull(ms.true_restart), ull(ms.false_restart));
    std::fprintf(out, "      forecast none      %14llu  %11llu\n", ull(ms.missed_restart), ull(ms.true_no_restart));
    std::fprintf(out,
                 "    not judged: %llu (the set point moved, the plant was not at rest, or the forecast restart falls after "
                 "the run)\n",
                 ull(ms.not_judged));
    std::fprintf(out, "    wrong direction: %llu\n", ull(ms.wrong_direction));
    const Percentiles &lg = ms.long_error_percent, &sh = ms.short_error_ms;
    std::fprintf(out,
                 "    error, sticking >= 0.5 s (%zu): p50 %.3f %%  p90 %.3f %%  p99 %.3f %%  max %.3f %% of the sticking "
                 "time\n",
                 lg.count, lg.p50, lg.p90, lg.p99, lg.max);
    std::fprintf(out, "    error, sticking <  0.5 s (%zu): p50 %.3f ms p90 %.3f ms p99 %.3f ms max %.3f ms\n", sh.count,
                 sh.p50, sh.p90, sh.p99, sh.max);
    std::fprintf(out,
                 "    sticking >= 0.5 s, within 2 %%: %zu, 5 %%: %zu, 10 %%: %zu of %zu; verdict wrong (restart or "
                 "none): %llu of %llu judged stops (%.2f %%)\n",
                 ms.long_within[0], ms.long_within[1], ms.long_within[2], lg.count, ull(ms.wrong()), ull(ms.judged()),
                 ms.judged() ? 100.0 * static_cast<double>(ms.wrong()) / static_cast<double>(ms.judged()) : 0.0);
    std::fprintf(out, "    outside the acceptance criteria (%s %%, 10 ms): %llu\n", m == 0 ? "5" : "1",
                 ull(ms.outside_criteria));
    if (o.online) {
      const Split& un = ms.unidentified_bound;
      std::fprintf(out,
                   "    --online, judged stops forecast on a stiction bound not identified yet (the configured one: no "
                   "breakaway that way yet): %llu, verdict wrong on %llu; sticking >= 0.5 s within 2 %%: %zu, "
                   "5 %%: %zu, 10 %%: %zu of %zu\n",
                   ull(un.stops), ull(un.wrong), un.long_within[0], un.long_within[1], un.long_within[2], un.long_restarts);
      // The others, on bounds it had identified.
      std::fprintf(out,
                   "    --online, the others, on identified bounds: %llu, verdict wrong on %llu; sticking >= 0.5 s within "
                   "2 %%: %zu, 5 %%: %zu, 10 %%: %zu of %zu\n",
                   ull(ms.judged() - un.stops), ull(ms.wrong() - un.wrong), ms.long_within[0] - un.long_within[0],
                   ms.long_within[1] - un.long_within[1], ms.long_within[2] - un.long_within[2],
                   lg.count - un.long_restarts);
      // Across both: the stops on a side the bench had broken away to slowly.
      const Split& slow = ms.slow_side;
      std::fprintf(out,
                   "    --online, judged stops on a side the bench had already broken away to after >= %.1f s stuck (a "
                   "slow breakaway): %llu, verdict wrong on %llu; sticking >= 0.5 s within 2 %%: %zu, 5 %%: %zu, 10 %%: "
                   "%zu of %zu\n",
                   kLongSticking_s, ull(slow.stops), ull(slow.wrong), slow.long_within[0], slow.long_within[1],
                   slow.long_within[2], slow.long_restarts);
    }
    print_halfway(out, ms);
  }
  if (set.halfway_enabled[2]) {
    std::fprintf(out, "  relaxation (made again only, fitted to the phase's own pressures; no valve model):\n");
    print_halfway(out, st.methods[2]);
  }
}

namespace {

SummaryPercentiles percentiles(const Percentiles& p) { return {p.count, p.p50, p.p90, p.p99, p.max}; }

SummaryWithin within(const Within2510& w) { return {w[0], w[1], w[2]}; }

SummarySplit split(const Split& s) { return {s.stops, s.wrong, s.long_restarts, within(s.long_within)}; }

SummaryMethod method(const MethodStatistics& m) {
  SummaryMethod r;
  r.judged = m.judged();
  r.true_restart = m.true_restart;
  r.true_no_restart = m.true_no_restart;
  r.false_restart = m.false_restart;
  r.missed_restart = m.missed_restart;
  r.not_judged = m.not_judged;
  r.wrong_direction = m.wrong_direction;
  r.outside_criteria = m.outside_criteria;
  r.long_error_percent = percentiles(m.long_error_percent);
  r.long_within = within(m.long_within);
  r.short_error_ms = percentiles(m.short_error_ms);
  r.halfway = {m.halfway_restarts(), percentiles(m.halfway_error_percent), within(m.halfway_within),
               m.halfway_wrong_direction, m.halfway_none, m.halfway_after_run, m.halfway_missing};
  r.online_unidentified_bound = split(m.unidentified_bound);
  r.online_slow_side = split(m.slow_side);
  return r;
}

}  // namespace

SweepSummary summary_record(const Statistics& st) {
  const Setting& set = st.setting;
  const Options& o = set.options;
  SweepSummary r;
  r.scenarios = static_cast<std::uint64_t>(st.scenarios);
  r.scenarios_run = st.scenarios_run;
  r.setting = {o.seed,          set.targets.lo_m,     set.targets.hi_m, o.duration_s,      o.step_time_s,
               o.tail_s,        o.friction_spread,    o.gain_spread,    o.bench_spread,    0.5 * o.bench_spread,
               o.supervised,    o.identify,           o.online,         set.hold_enabled,  set.hold_window_m};
  r.stops = {st.stops,
             st.restarts,
             st.long_restarts,
             st.restarts_after_1_s,
             st.restarts_below_motion_band,
             st.not_at_rest,
             st.before_learning,
             percentiles(st.start_early_ms),
             percentiles(st.start_late_ms),
             percentiles(st.start_gap_ms)};
  for (const Outcome oc : kOutcomes) {
    const OutcomeStatistics& k = st.outcomes[static_cast<std::size_t>(oc)];
    std::string key = outcome_name(oc);
    std::replace(key.begin(), key.end(), '-', '_');
    r.outcomes.emplace_back(key, SummaryOutcome{k.count, k.y0_min_m, k.y0_max_m, k.y_d_min_m, k.y_d_max_m,
                                                k.settling_rules_latched});
  }
  for (std::size_t c = 1; c < st.faults_by_cause.size(); ++c)
    if (st.faults_by_cause[c] > 0)
      r.faults_by_cause.emplace_back(controller::fault_name(static_cast<controller::FaultCause>(c)), st.faults_by_cause[c]);
  r.settle_time_s = percentiles(st.settle_time_s);
  r.final_error_m = percentiles(st.final_error_m);
  r.in_window = {set.hold_window_m, percentiles(st.in_window_after_s), st.never_in_window, st.in_window_all_p50_s,
                 st.in_window_all_p90_s};
  r.hold = {set.hold_enabled,
            st.held,
            st.restarts_after_hold,
            st.restarted_after_hold,
            st.held_forecasts,
            st.held_restart_forecasts,
            percentiles(st.reach_forecast_error_ms),
            st.reach_forecasts_within_1_2_5_ms[0],
            st.reach_forecasts_within_1_2_5_ms[1],
            st.reach_forecasts_within_1_2_5_ms[2],
            st.reaches_forecast_none};
  r.settling_rules = {st.settling_rules_checked, set.settling_rules.sign_changes, set.settling_rules.amplitude_m,
                      set.settling_rules.window_s, set.settling_rules.settle_time_s,
                      percentiles(st.settling_rules_latched_after_s)};
  r.identified = o.identify;
  if (o.identify) {
    const IdentificationStatistics& id = st.identification;
    SummaryIdentification& s = r.identification;
    s.identified_and_run = id.identified_and_run;
    s.failed = id.failures;
    s.static_positive_error_percent = percentiles(id.stiction_error_percent[0]);
    s.static_negative_error_percent = percentiles(id.stiction_error_percent[1]);
    s.null_pressure_error_pa = percentiles(id.null_pressure_error_pa);
    s.residual_in_noise = percentiles(id.residual_ratio);
    s.fits = id.fits;
    s.published = static_cast<std::uint64_t>(id.published);
    s.within_3_sigma = static_cast<std::uint64_t>(id.within_3_sigma);
    for (const auto& k : id.by_key)
      s.by_key.emplace_back(k.key, SummaryKeyTally{static_cast<std::uint64_t>(k.published),
                                                   static_cast<std::uint64_t>(k.within_3_sigma)});
    s.outside = id.outside;
    s.heat_transfer_error_percent = percentiles(id.heat_transfer_error_percent);
    s.spool_lag_error_ms = percentiles(id.spool_lag_error_ms);
  }
  r.methods = {method(st.methods[0]), method(st.methods[1]), method(st.methods[2])};
  r.wall_s = st.wall_s;
  r.jobs = static_cast<std::uint64_t>(st.jobs);
  return r;
}

void write_summary_json(std::ostream& out, const Statistics& st) { records::write_json_document(out, summary_record(st)); }

StopRow stop_row(const ScenarioResult& r, const JudgedStop& j, bool online) {
  const controller::StopOutcome& s = j.stop;
  const controller::Prediction* any = s.nonlinear ? &*s.nonlinear : (s.linearized ? &*s.linearized : nullptr);
  StopRow row;
  row.scenario = r.scenario.index;
  row.y0_m = r.scenario.y0_m;
  row.y_d_m = r.scenario.y_d_m;
  row.friction_scale = r.scenario.friction_scale;
  row.gain_scale = r.scenario.gain_scale;
  row.stop = s.index;
  row.t_stop_s = s.t_stop_s;
  row.y_stop_m = s.y_stop_m;
  row.force_n = s.force_n;
  row.u_star_v = s.snapshot.u_v;
  row.equilibrium_force_n = any ? any->equilibrium_force_n : NAN;
  row.outcome = fate_name(j.fate);
  row.t_end_s = s.t_end_s;
  row.sticking_s = s.sticking_s();
  row.direction = s.direction;
  std::optional<ForecastCells>* cells[] = {&row.lin, &row.nl};
  for (std::size_t m = 0; m < j.at_stop.size(); ++m) {
    const std::optional<JudgedForecast>& f = j.at_stop[m];
    if (!f) continue;
    const bool tp = f->verdict.kind == Verdict::Kind::kTruePositive;
    ForecastCells c;
    c.will_restart = f->prediction.will_restart;
    c.t_restart_s = f->prediction.t_restart_s;
    c.direction = f->prediction.direction;
    c.verdict = verdict_name(f->verdict.kind);
    if (tp) c.error_ms = f->verdict.error_s * 1e3;
    if (tp) c.error_percent = f->verdict.error_percent;
    c.within_criteria = f->within_criteria;
    *cells[m] = c;
  }
  std::optional<double>* halfway[] = {&row.lin_halfway_error_percent, &row.nl_halfway_error_percent,
                                      &row.rx_halfway_error_percent};
  for (std::size_t m = 0; m < j.halfway.size(); ++m)
    if (j.halfway[m] && j.halfway[m]->kind == Verdict::Kind::kTruePositive) *halfway[m] = j.halfway[m]->error_percent;
  // --online: whether the stop was forecast on a stiction bound online learning had not identified
  // yet (pneud's summary counts these); no value without --online.
  if (online) {
    row.forecast_on_unidentified_bound = j.truth.on_configured_bound;
    row.side_broken_away_slowly = j.on_slow_side;
  }
  return row;
}

std::string stops_csv_header() { return records::csv_header<StopRow>() + '\n'; }

std::string stops_csv_rows(const ScenarioResult& r, bool online) {
  std::string lines;
  for (const JudgedStop& j : r.stops) {
    records::write_csv_cells(lines, stop_row(r, j, online));
    lines += '\n';
  }
  return lines;
}

void write_stops_csv(std::ostream& os, std::span<const ScenarioResult> results, bool online) {
  os << stops_csv_header();
  for (const ScenarioResult& r : results) os << stops_csv_rows(r, online);
}

ScenarioRow scenario_row(const ScenarioResult& r) {
  ScenarioRow row;
  row.scenario = r.scenario.index;
  row.y0_m = r.scenario.y0_m;
  row.y_d_m = r.scenario.y_d_m;
  row.friction_scale = r.scenario.friction_scale;
  row.gain_scale = r.scenario.gain_scale;
  const Settling& g = r.settling;
  if (r.ran()) {
    row.outcome = outcome_name(g.outcome);
    row.settle_time_s = g.settle_time_s;
    row.final_error_m = g.final_error_m;
    row.fault_cause = g.fault == controller::FaultCause::kNone ? nullptr : controller::fault_name(g.fault);
    row.fault_after_s = g.fault_after_s;
    row.stops = g.stops;
    row.restarts = g.restarts;
    row.at_rest_at_end = g.at_rest_at_end;
    row.last_second_swing_m = g.last_second_swing_m;
    row.oscillation_rule_after_s = g.oscillation_rule_after_s;
    row.in_window_after_s = g.in_window_after_s;
    row.hold_after_s = g.hold_after_s;
    row.restarts_after_hold = g.restarts_after_hold;
  } else {  // it did not run: the run's figures have no value
    row.outcome = "identification_failed";
    row.settle_time_s = row.final_error_m = row.fault_after_s = row.last_second_swing_m = NAN;
    row.oscillation_rule_after_s = row.in_window_after_s = row.hold_after_s = NAN;
  }
  const model::PlantParams& b = r.bench;
  BenchCells& c = row.bench;
  c.static_positive_n = b.friction.static_positive_n;
  c.coulomb_positive_n = b.friction.coulomb_positive_n;
  c.static_negative_n = b.friction.static_negative_n;
  c.coulomb_negative_n = b.friction.coulomb_negative_n;
  c.viscous_n_s_per_m = b.friction.viscous_n_s_per_m;
  c.max_conductance_m3_per_s_pa = b.valve.max_conductance_m3_per_s_pa;
  c.leak_conductance_in_m3_per_s_pa = b.valve.leak_conductance_in_m3_per_s_pa;
  c.leak_conductance_out_m3_per_s_pa = b.valve.leak_conductance_out_m3_per_s_pa;
  c.dead_volume_p_m3 = b.geometry.dead_volume_p_m3;
  c.dead_volume_n_m3 = b.geometry.dead_volume_n_m3;
  c.null_offset_v = b.valve.null_offset_v;
  if (b.has_thermal) {
    c.heat_transfer_w_per_m2_k = b.thermal.heat_transfer_w_per_m2_k;
    c.thermal_time_constant_s = model::thermal_time_constant_s(b);
  }
  c.spool_time_constant_s = b.valve.spool_time_constant_s;
  if (r.identified) {
    IdentifiedCells i;
    i.static_positive_n = r.identified->friction.static_positive_n;
    i.static_negative_n = r.identified->friction.static_negative_n;
    i.null_offset_v = r.identified->valve.null_offset_v;
    i.null_pressure_error_pa = r.check.null_pressure_error_pa;
    i.pressure_residual_pa = r.check.residual_pa;
    i.pressure_explained_pa = r.check.explained_pa;
    i.model_fits = r.check.fits;
    if (r.identified->has_thermal) i.heat_transfer_w_per_m2_k = r.identified->thermal.heat_transfer_w_per_m2_k;
    i.spool_time_constant_s = r.identified->valve.spool_time_constant_s;
    i.published = r.check.published;
    i.within_3_sigma = r.check.within_3_sigma;
    row.identified = i;
  }
  if (!r.identification_failed.empty()) {
    std::string reason = r.identification_failed;  // one quoted cell, with no quote in it
    std::replace(reason.begin(), reason.end(), '"', '\'');
    row.identification_failed = reason;
  }
  return row;
}

std::string scenarios_csv_header(bool identify) {
  return records::csv_header<ScenarioRow>(identify ? kIdentifiedScenarioColumns : kScenarioColumns) + '\n';
}

std::string scenarios_csv_row(const ScenarioResult& r, bool identify) {
  std::string line;
  records::write_csv_row(line, identify ? kIdentifiedScenarioColumns : kScenarioColumns, scenario_row(r));
  return line;
}

void write_scenarios_csv(std::ostream& os, std::span<const ScenarioResult> results, bool identify) {
  os << scenarios_csv_header(identify);
  for (const ScenarioResult& r : results) os << scenarios_csv_row(r, identify);
}

}  // namespace pneu::sweep
