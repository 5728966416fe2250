// The sweep's results aggregated into its statistics.
#include "pneu/sweep/statistics.hpp"

#include <algorithm>
#include <limits>

#include "pneu/config/config.hpp"
#include "pneu/controller/supervisor.hpp"

namespace pneu::sweep {

using controller::Verdict;

Setting setting_of(const config::Config& config, const Options& options) {
  Setting s;
  s.options = options;
  s.targets = target_range(options, config.plant.geometry.half_stroke_m());
  s.hold_window_m = config.controller.hold.window_m;
  s.hold_enabled = config.controller.hold.enabled;
  const config::SupervisorConfig& v = config.controller.supervisor;
  s.settling_rules = {v.oscillation_sign_changes, v.oscillation_amplitude_m, v.oscillation_window_s, v.settle_time_s};
  const config::PredictorConfig& p = config.controller.predictor;
  s.halfway_enabled = {p.update_period_s > 0.0 && p.linearized, p.update_period_s > 0.0 && p.nonlinear,
                       p.update_period_s > 0.0 && p.relaxation};
  if (p.linearized_slope != config::LinearizedSlope::kStopTangent)
    s.linearized_name = std::string("linearized (slope: ") + config::to_string(p.linearized_slope) + ")";
  return s;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto i = static_cast<std::size_t>(pos);
  const double f = pos - static_cast<double>(i);
  if (i + 1 < v.size() && f > 0.0) return std::isinf(v[i + 1]) ? v[i + 1] : v[i] * (1 - f) + v[i + 1] * f;
  return v[i];
}

Percentiles percentiles_of(const std::vector<double>& values) {
  return {values.size(), percentile(values, 0.5), percentile(values, 0.9), percentile(values, 0.99),
          percentile(values, 1.0)};
}

Within2510 within_2_5_10(const std::vector<double>& errors_pct) {
  Within2510 within{};
  for (const double e : errors_pct)
    for (std::size_t b = 0; b < within.size(); ++b) within[b] += e <= (b == 0 ? 2.0 : b == 1 ? 5.0 : 10.0) ? 1 : 0;
  return within;
}

namespace {

// A subset of the judged stops, while they are counted.
struct SplitTally {
  Split split;
  std::vector<double> long_error_pct;
  void add(const controller::StopOutcome& s, const Verdict& v) {
    if (v.kind == Verdict::Kind::kNotJudged) return;
    ++split.stops;
    if (v.kind == Verdict::Kind::kFalseNegative || v.kind == Verdict::Kind::kFalsePositive) ++split.wrong;
    if (v.kind == Verdict::Kind::kTruePositive && s.sticking_s() >= kLongSticking_s)
      long_error_pct.push_back(v.error_percent);
  }
  [[nodiscard]] Split done() const {
    Split out = split;
    out.long_restarts = long_error_pct.size();
    out.long_within = within_2_5_10(long_error_pct);
    return out;
  }
};

// One method's figures, while they are counted.
struct MethodTally {
  MethodStatistics st;
  std::vector<double> long_error_pct, short_error_ms, halfway_error_pct;
  SplitTally unidentified_bound, slow_side;
  [[nodiscard]] MethodStatistics done() const {
    MethodStatistics out = st;
    out.long_error_percent = percentiles_of(long_error_pct);
    out.long_within = within_2_5_10(long_error_pct);
    out.short_error_ms = percentiles_of(short_error_ms);
    out.halfway_error_percent = percentiles_of(halfway_error_pct);
    out.halfway_within = within_2_5_10(halfway_error_pct);
    out.unidentified_bound = unidentified_bound.done();
    out.slow_side = slow_side.done();
    return out;
  }
};

}  // namespace

Statistics aggregate(const Setting& setting, std::span<const ScenarioResult> results) {
  Statistics out;
  out.setting = setting;
  out.scenarios = static_cast<int>(results.size());
  out.faults_by_cause.assign(controller::kFaultCauseCount, 0);
  std::array<MethodTally, kMethodCount> tally;
  std::vector<double> start_dating_ms;  // detector's start - plant's breakaway, over the starts it saw
  std::vector<double> settle_times_s, final_errors_m, in_window_after_s, reach_forecast_error_ms;
  std::array<std::vector<double>, std::size(kOutcomes)> rule_after_s;  // when the settling rules would latch
  IdentificationStatistics& id = out.identification;
  std::array<std::vector<double>, 2> id_stiction_error_pct;
  std::vector<double> id_null_error_pa, id_residual_ratio, id_heat_error_pct, id_spool_error_ms;
  for (const ScenarioResult& r : results) {
    // The stops of the judged window.
    for (const JudgedStop& j : r.stops) {
      const controller::StopOutcome& s = j.stop;
      ++out.stops;
      if (j.truth.unseen) ++out.restarts_below_motion_band;
      if (!std::isnan(j.truth.start_dating_s)) start_dating_ms.push_back(1e3 * j.truth.start_dating_s);
      if (j.fate == StopFate::kBeforeLearning) ++out.before_learning;
      if (j.truth.not_at_rest) ++out.not_at_rest;
      if (j.judged() && s.restarted) {
        ++out.restarts;
        if (s.sticking_s() >= kLongSticking_s) ++out.long_restarts;
        if (s.sticking_s() >= 1.0) ++out.restarts_after_1_s;
      }
      for (std::size_t m = 0; m < j.at_stop.size(); ++m) {
        if (!j.at_stop[m]) continue;
        const Verdict& v = j.at_stop[m]->verdict;
        MethodTally& t = tally[m];
        switch (v.kind) {
          case Verdict::Kind::kTruePositive:
            ++t.st.true_restart;
            if (!v.direction_ok) ++t.st.wrong_direction;
            if (s.sticking_s() >= kLongSticking_s) t.long_error_pct.push_back(v.error_percent);
            else t.short_error_ms.push_back(std::abs(v.error_s) * 1e3);
            break;
          case Verdict::Kind::kTrueNegative: ++t.st.true_no_restart; break;
          case Verdict::Kind::kFalsePositive: ++t.st.false_restart; break;
          case Verdict::Kind::kFalseNegative: ++t.st.missed_restart; break;
          case Verdict::Kind::kNotJudged: ++t.st.not_judged; break;
        }
        if (!j.at_stop[m]->within_criteria) ++t.st.outside_criteria;
        if (j.truth.on_configured_bound) t.unidentified_bound.add(s, v);
        if (j.on_slow_side) t.slow_side.add(s, v);
      }
      for (std::size_t m = 0; m < kMethodCount; ++m) {
        MethodTally& t = tally[m];
        const std::optional<Verdict>& v = j.halfway[m];
        if (j.long_restart && setting.halfway_enabled[m]) {
          if (!v) ++t.st.halfway_missing;
          else if (v->kind == Verdict::Kind::kFalseNegative) ++t.st.halfway_none;
          else if (v->kind == Verdict::Kind::kNotJudged) ++t.st.halfway_after_run;
          else if (v->kind == Verdict::Kind::kTruePositive && !v->direction_ok) ++t.st.halfway_wrong_direction;
        }
        if (v && v->kind == Verdict::Kind::kTruePositive) t.halfway_error_pct.push_back(v->error_percent);
      }
    }
    // --identify: what was identified against the bench.
    if (r.identified) {
      const IdentifiedCheck& c = r.check;
      id_residual_ratio.push_back(c.residual_pa / c.explained_pa);
      id.fits += c.fits ? 1 : 0;
      id.published += c.published;
      id.within_3_sigma += c.within_3_sigma;
      if (!c.outside.empty()) id.outside.push_back("scenario " + std::to_string(r.scenario.index) + ": " + c.outside);
      for (const IdentifiedCheck::KeyTally& k : c.by_key) {
        auto it = std::find_if(id.by_key.begin(), id.by_key.end(), [&](const auto& e) { return e.key == k.key; });
        if (it == id.by_key.end()) it = id.by_key.insert(id.by_key.end(), {k.key, 0, 0});
        it->published += k.published;
        it->within_3_sigma += k.within_3_sigma;
      }
      if (r.bench.has_thermal && r.identified->has_thermal)
        id_heat_error_pct.push_back(
            100 * std::abs(r.identified->thermal.heat_transfer_w_per_m2_k / r.bench.thermal.heat_transfer_w_per_m2_k - 1));
      if (r.identified->valve.spool_time_constant_s > 0.0)
        id_spool_error_ms.push_back(
            1e3 * std::abs(r.identified->valve.spool_time_constant_s - r.bench.valve.spool_time_constant_s));
    }
    // A scenario whose identification failed, or whose identified model could not be designed
    // for, did not run: it has no outcome.
    if (!r.ran()) {
      id.failures.push_back("scenario " + std::to_string(r.scenario.index) + ": " + r.identification_failed);
      continue;
    }
    ++out.scenarios_run;
    if (r.identified) {
      id_stiction_error_pct[0].push_back(100 * std::abs(r.identified->friction.static_positive_n / r.bench.friction.static_positive_n - 1));
      id_stiction_error_pct[1].push_back(100 * std::abs(r.identified->friction.static_negative_n / r.bench.friction.static_negative_n - 1));
      id_null_error_pa.push_back(r.check.null_pressure_error_pa);
    }
    const Settling& g = r.settling;
    const auto k = static_cast<std::size_t>(g.outcome);
    OutcomeStatistics& o = out.outcomes[k];
    if (o.count++ == 0) {
      o.y0_min_m = o.y0_max_m = r.scenario.y0_m;
      o.y_d_min_m = o.y_d_max_m = r.scenario.y_d_m;
    }
    o.y0_min_m = std::min(o.y0_min_m, r.scenario.y0_m);
    o.y0_max_m = std::max(o.y0_max_m, r.scenario.y0_m);
    o.y_d_min_m = std::min(o.y_d_min_m, r.scenario.y_d_m);
    o.y_d_max_m = std::max(o.y_d_max_m, r.scenario.y_d_m);
    if (g.outcome == Outcome::kSettled) {
      settle_times_s.push_back(g.settle_time_s);
      final_errors_m.push_back(g.final_error_m);
    }
    if (!std::isnan(g.in_window_after_s)) in_window_after_s.push_back(g.in_window_after_s);
    else ++out.never_in_window;
    out.held_forecasts += g.held_forecasts;
    out.held_restart_forecasts += g.held_restart_forecasts;
    out.reaches_forecast_none += g.reaches_forecast_none;
    for (const double e : g.reach_forecast_error_ms) reach_forecast_error_ms.push_back(std::abs(e));
    if (!std::isnan(g.hold_after_s)) {
      ++out.held;
      out.restarts_after_hold += g.restarts_after_hold;
      if (g.restarts_after_hold > 0) ++out.restarted_after_hold;
    }
    if (g.fault != controller::FaultCause::kNone) ++out.faults_by_cause[controller::fault_number(g.fault)];
    if (!std::isnan(g.oscillation_rule_after_s)) rule_after_s[k].push_back(g.oscillation_rule_after_s);
  }

  std::vector<double> early_ms, late_ms, gap_ms;
  for (const double d : start_dating_ms) {
    (d < 0.0 ? early_ms : late_ms).push_back(std::abs(d));
    gap_ms.push_back(std::abs(d));
  }
  out.start_early_ms = percentiles_of(early_ms);
  out.start_late_ms = percentiles_of(late_ms);
  out.start_gap_ms = percentiles_of(gap_ms);
  out.settle_time_s = percentiles_of(settle_times_s);
  out.final_error_m = percentiles_of(final_errors_m);
  out.in_window_after_s = percentiles_of(in_window_after_s);
  {
    // Over every scenario run, those never at rest within the window counted as never.
    std::vector<double> all(in_window_after_s);
    all.insert(all.end(), out.never_in_window, std::numeric_limits<double>::infinity());
    out.in_window_all_p50_s = percentile(all, 0.5);
    out.in_window_all_p90_s = percentile(all, 0.9);
  }
  out.reach_forecast_error_ms = percentiles_of(reach_forecast_error_ms);
  for (std::size_t b = 0; b < 3; ++b) {
    const double ms = b == 0 ? 1.0 : b == 1 ? 2.0 : 5.0;
    out.reach_forecasts_within_1_2_5_ms[b] = static_cast<std::size_t>(
        std::count_if(reach_forecast_error_ms.begin(), reach_forecast_error_ms.end(), [ms](double e) { return e <= ms; }));
  }
  const SettlingRules& rules = setting.settling_rules;
  out.settling_rules_checked = !setting.options.supervised && (rules.sign_changes > 0 || rules.settle_time_s > 0.0);
  std::vector<double> all_after_s;
  for (std::size_t k = 0; k < rule_after_s.size(); ++k) {
    out.outcomes[k].settling_rules_latched = rule_after_s[k].size();
    all_after_s.insert(all_after_s.end(), rule_after_s[k].begin(), rule_after_s[k].end());
  }
  out.settling_rules_latched_after_s = percentiles_of(all_after_s);
  id.identified_and_run = id_null_error_pa.size();
  for (std::size_t side = 0; side < 2; ++side) id.stiction_error_percent[side] = percentiles_of(id_stiction_error_pct[side]);
  id.null_pressure_error_pa = percentiles_of(id_null_error_pa);
  id.residual_ratio = percentiles_of(id_residual_ratio);
  id.heat_transfer_error_percent = percentiles_of(id_heat_error_pct);
  id.spool_lag_error_ms = percentiles_of(id_spool_error_ms);
  for (std::size_t m = 0; m < kMethodCount; ++m) out.methods[m] = tally[m].done();
  return out;
}

Statistics aggregate(const Setting& setting, const SweepRun& run) {
  Statistics out = aggregate(setting, std::span<const ScenarioResult>(run.results));
  out.wall_s = run.wall_s;
  out.jobs = run.jobs;
  return out;
}

}  // namespace pneu::sweep
