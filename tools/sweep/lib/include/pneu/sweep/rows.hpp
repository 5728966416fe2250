// The rows of the sweep's files, described once (pneu/records/record.hpp): the stops file's row
// (pneu-sweep --out, one per judged-window stop) and the scenarios file's (--scenarios-out, one
// per scenario). Their CSV columns and cells, their JSON and JSON Schemas follow from these
// descriptions: a new column is one line here (and one where report.cpp fills the row: stop_row,
// scenario_row in report.hpp). Only the records' vocabulary is included: pneu-records writes the
// schemas from here.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <tuple>

#include "pneu/records/record.hpp"

namespace pneu::sweep {

/// The stops file: what one method's forecast made at the stop said, and its verdict.
struct ForecastCells {
  bool will_restart = false;
  double t_restart_s = 0.0;
  int direction = 0;
  const char* verdict = nullptr;
  std::optional<double> error_ms;       ///< a true restart's only
  std::optional<double> error_percent;  ///< a true restart's only
  bool within_criteria = false;
};

/// The stops file's row.
struct StopRow {
  int scenario = 0;
  double y0_m = 0.0, y_d_m = 0.0, friction_scale = 0.0, gain_scale = 0.0;
  std::uint64_t stop = 0;
  double t_stop_s = 0.0, y_stop_m = 0.0, force_n = 0.0, u_star_v = 0.0, equilibrium_force_n = 0.0;
  const char* outcome = nullptr;
  double t_end_s = 0.0, sticking_s = 0.0;
  int direction = 0;
  std::optional<ForecastCells> lin, nl;  ///< none when the method made no forecast
  std::optional<double> lin_halfway_error_percent, nl_halfway_error_percent, rx_halfway_error_percent;
  std::optional<bool> forecast_on_unidentified_bound, side_broken_away_slowly;  ///< --online only
};

/// The scenarios file: the simulated bench a scenario ran.
struct BenchCells {
  double static_positive_n = 0.0, coulomb_positive_n = 0.0, static_negative_n = 0.0, coulomb_negative_n = 0.0;
  double viscous_n_s_per_m = 0.0, max_conductance_m3_per_s_pa = 0.0, leak_conductance_in_m3_per_s_pa = 0.0;
  double leak_conductance_out_m3_per_s_pa = 0.0, dead_volume_p_m3 = 0.0, dead_volume_n_m3 = 0.0;
  double null_offset_v = 0.0;
  std::optional<double> heat_transfer_w_per_m2_k, thermal_time_constant_s;  ///< none: adiabatic
  double spool_time_constant_s = 0.0;
};

/// The scenarios file, --identify: the model identified, against the bench.
struct IdentifiedCells {
  double static_positive_n = 0.0, static_negative_n = 0.0, null_offset_v = 0.0;
  double null_pressure_error_pa = 0.0, pressure_residual_pa = 0.0, pressure_explained_pa = 0.0;
  bool model_fits = false;
  std::optional<double> heat_transfer_w_per_m2_k;  ///< none: adiabatic
  double spool_time_constant_s = 0.0;
  int published = 0, within_3_sigma = 0;
};

/// The scenarios file's row. A scenario whose identification failed did not run: its outcome
/// says so, and the run's figures have no value.
struct ScenarioRow {
  int scenario = 0;
  double y0_m = 0.0, y_d_m = 0.0, friction_scale = 0.0, gain_scale = 0.0;
  const char* outcome = nullptr;
  double settle_time_s = 0.0, final_error_m = 0.0;
  const char* fault_cause = nullptr;
  double fault_after_s = 0.0;
  std::optional<std::uint64_t> stops, restarts;
  std::optional<bool> at_rest_at_end;
  double last_second_swing_m = 0.0, oscillation_rule_after_s = 0.0;
  BenchCells bench;
  std::optional<IdentifiedCells> identified;
  std::optional<std::string> identification_failed;
  double in_window_after_s = 0.0, hold_after_s = 0.0;
  std::optional<std::uint64_t> restarts_after_hold;
};

}  // namespace pneu::sweep

template <>
struct pneu::records::Description<pneu::sweep::ForecastCells> {
  using R = pneu::sweep::ForecastCells;
  static constexpr const char* kName = "sweep_forecast";
  static constexpr const char* kDoc = "a method's forecast made at the stop, judged against the plant";
  static constexpr auto kFields = std::tuple{
      field("will_restart", &R::will_restart, "", "it forecast a restart"),
      field("t_restart_s", &R::t_restart_s, "s", "the restart time it forecast (nan: none)").fixed(6).nan_as_text(),
      field("direction", &R::direction, "", "+1 / -1, 0 when no restart"),
      field("verdict", &R::verdict, "", "true_restart, true_no_restart, false_restart, missed_restart, not_judged"),
      field("error_ms", &R::error_ms, "ms", "a true restart: forecast minus seen").fixed(6).nan_as_text(),
      field("error_percent", &R::error_percent, "%", "a true restart: the error in percent of the time stuck").fixed(6).nan_as_text(),
      field("within_criteria", &R::within_criteria, "", "within the acceptance criteria: 1 % (nonlinear) / 5 % or 10 ms"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::StopRow> {
  using R = pneu::sweep::StopRow;
  static constexpr const char* kName = "sweep_stop";
  static constexpr const char* kDoc = "a stop of a sweep's scenario in its judged window, its forecasts judged (pneu-sweep --out)";
  static constexpr auto kFields = std::tuple{
      field("scenario", &R::scenario, "", "the scenario's index"),
      field("y0_m", &R::y0_m, "m", "where the scenario started").fixed(6).nan_as_text(),
      field("y_d_m", &R::y_d_m, "m", "the set point it stepped to").fixed(6).nan_as_text(),
      field("friction_scale", &R::friction_scale, "", "the scenario's friction factor").fixed(4).nan_as_text(),
      field("gain_scale", &R::gain_scale, "", "the scenario's gain factor").fixed(4).nan_as_text(),
      field("stop", &R::stop, "", "the stop's index"),
      field("t_stop_s", &R::t_stop_s, "s", "when the stop was confirmed").fixed(6).nan_as_text(),
      field("y_stop_m", &R::y_stop_m, "m", "the rest position").fixed(9).nan_as_text(),
      field("force_n", &R::force_n, "N", "the pressure force at the stop").fixed(4).nan_as_text(),
      field("u_star_v", &R::u_star_v, "V", "the control held while stuck (Eq. 11)").fixed(6).nan_as_text(),
      field("equilibrium_force_n", &R::equilibrium_force_n, "N", "F at complete equilibrium under u* (nan: no forecast)")
          .fixed(4)
          .nan_as_text(),
      field("outcome", &R::outcome, "", "what the plant did: the stop's fate"),
      field("t_end_s", &R::t_end_s, "s", "when the stop ended").fixed(6).nan_as_text(),
      field("sticking_s", &R::sticking_s, "s", "how long it stuck").fixed(6).nan_as_text(),
      field("direction", &R::direction, "", "the way it broke away, 0 when it did not"),
      group("lin", &R::lin, "lin_", "the linearized method's forecast at the stop"),
      group("nl", &R::nl, "nl_", "the nonlinear method's forecast at the stop"),
      field("lin_halfway_error_percent", &R::lin_halfway_error_percent, "%",
            "a long restart: the linearized forecast made again half-way, its error").fixed(6).nan_as_text(),
      field("nl_halfway_error_percent", &R::nl_halfway_error_percent, "%", "... the nonlinear's").fixed(6).nan_as_text(),
      field("rx_halfway_error_percent", &R::rx_halfway_error_percent, "%", "... the relaxation's").fixed(6).nan_as_text(),
      field("forecast_on_unidentified_bound", &R::forecast_on_unidentified_bound, "",
            "--online: forecast on a stiction bound online learning had not identified yet"),
      field("side_broken_away_slowly", &R::side_broken_away_slowly, "",
            "--online: its forecast turns on a side the bench broke away to slowly earlier"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::BenchCells> {
  using R = pneu::sweep::BenchCells;
  static constexpr const char* kName = "sweep_bench";
  static constexpr const char* kDoc = "the simulated bench a scenario ran (its figures read back as the same doubles)";
  static constexpr auto kFields = std::tuple{
      field("static_positive_n", &R::static_positive_n, "N", "F_S+", 17).nan_as_text(),
      field("coulomb_positive_n", &R::coulomb_positive_n, "N", "F_C+", 17).nan_as_text(),
      field("static_negative_n", &R::static_negative_n, "N", "F_S-", 17).nan_as_text(),
      field("coulomb_negative_n", &R::coulomb_negative_n, "N", "F_C-", 17).nan_as_text(),
      field("viscous_n_s_per_m", &R::viscous_n_s_per_m, "N s/m", "sigma", 17).nan_as_text(),
      field("max_conductance_m3_per_s_pa", &R::max_conductance_m3_per_s_pa, "m^3/(s Pa)", "C_max", 17).nan_as_text(),
      field("leak_conductance_in_m3_per_s_pa", &R::leak_conductance_in_m3_per_s_pa, "m^3/(s Pa)", "the inward leak", 17).nan_as_text(),
      field("leak_conductance_out_m3_per_s_pa", &R::leak_conductance_out_m3_per_s_pa, "m^3/(s Pa)", "the outward leak", 17).nan_as_text(),
      field("dead_volume_p_m3", &R::dead_volume_p_m3, "m^3", "chamber P's dead volume", 17).nan_as_text(),
      field("dead_volume_n_m3", &R::dead_volume_n_m3, "m^3", "chamber N's dead volume", 17).nan_as_text(),
      field("null_offset_v", &R::null_offset_v, "V", "the valves' null offset", 17).nan_as_text(),
      field("heat_transfer_w_per_m2_k", &R::heat_transfer_w_per_m2_k, "W/(m^2 K)", "the walls' heat transfer (none: adiabatic)", 17).nan_as_text(),
      field("thermal_time_constant_s", &R::thermal_time_constant_s, "s", "the chambers' thermal time constant", 17).nan_as_text(),
      field("spool_time_constant_s", &R::spool_time_constant_s, "s", "the valve spool's lag", 17).nan_as_text(),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::IdentifiedCells> {
  using R = pneu::sweep::IdentifiedCells;
  static constexpr const char* kName = "sweep_identified";
  static constexpr const char* kDoc = "--identify: the model identified on the scenario's bench";
  static constexpr auto kFields = std::tuple{
      field("static_positive_n", &R::static_positive_n, "N", "F_S+ identified", 6).nan_as_text(),
      field("static_negative_n", &R::static_negative_n, "N", "F_S- identified", 6).nan_as_text(),
      field("null_offset_v", &R::null_offset_v, "V", "the null offset identified", 6).nan_as_text(),
      field("null_pressure_error_pa", &R::null_pressure_error_pa, "Pa", "the null-flow pressure's error").fixed(1).nan_as_text(),
      field("pressure_residual_pa", &R::pressure_residual_pa, "Pa", "the valve fit's residual").fixed(3).nan_as_text(),
      field("pressure_explained_pa", &R::pressure_explained_pa, "Pa", "what the noise explains of it").fixed(3).nan_as_text(),
      field("model_fits", &R::model_fits, "", "the model fits the bench"),
      field("heat_transfer_w_per_m2_k", &R::heat_transfer_w_per_m2_k, "W/(m^2 K)", "identified (none: adiabatic)").fixed(4),
      field("spool_time_constant_s", &R::spool_time_constant_s, "s", "identified", 6).nan_as_text(),
      field("published", &R::published, "", "the parameters it published that the bench has too"),
      field("within_3_sigma", &R::within_3_sigma, "", "those within 3 of their stated sigmas of the bench's value"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::ScenarioRow> {
  using R = pneu::sweep::ScenarioRow;
  static constexpr const char* kName = "sweep_scenario";
  static constexpr const char* kDoc = "a sweep's scenario: how it settled, its bench (pneu-sweep --scenarios-out)";
  static constexpr auto kFields = std::tuple{
      field("scenario", &R::scenario, "", "the scenario's index"),
      field("y0_m", &R::y0_m, "m", "where it started (reads back as the same double)", 17),
      field("y_d_m", &R::y_d_m, "m", "the set point it stepped to (reads back as the same double)", 17),
      field("friction_scale", &R::friction_scale, "", "its friction factor").fixed(4),
      field("gain_scale", &R::gain_scale, "", "its gain factor").fixed(4),
      field("outcome", &R::outcome, "", "settled, ..., or identification_failed (it did not run)"),
      field("settle_time_s", &R::settle_time_s, "s", "the first rest after the step, before any fault").fixed(6),
      field("final_error_m", &R::final_error_m, "m", "|y_d - y| at the end of the run").fixed(9),
      field("fault_cause", &R::fault_cause, "", "the first fault latched (empty: none)"),
      field("fault_after_s", &R::fault_after_s, "s", "when").fixed(6),
      field("stops", &R::stops, "", "stops over the whole run"),
      field("restarts", &R::restarts, "", "restarts over the whole run"),
      field("at_rest_at_end", &R::at_rest_at_end, "", "at rest at the end"),
      field("last_second_swing_m", &R::last_second_swing_m, "m", "peak-to-peak position over the last second").fixed(9),
      field("oscillation_rule_after_s", &R::oscillation_rule_after_s, "s",
            "when the settling rules checked alongside would latch").fixed(6),
      group("bench", &R::bench, "bench_", "the simulated bench it ran"),
      group("identified", &R::identified, "identified_", "--identify: the model identified"),
      field("identification_failed", &R::identification_failed, "", "--identify: why it failed (no value: it did not)"),
      field("in_window_after_s", &R::in_window_after_s, "s", "the first rest within controller.hold.window_m").fixed(6),
      field("hold_after_s", &R::hold_after_s, "s", "the in-position hold's first start within the window").fixed(6),
      field("restarts_after_hold", &R::restarts_after_hold, "", "breakaways beyond the motion band after it"),
  };
};

namespace pneu::sweep {
namespace detail {
inline constexpr const char* kScenarioColumns[] = {
    "scenario", "y0_m", "y_d_m", "friction_scale", "gain_scale", "outcome", "settle_time_s", "final_error_m",
    "fault_cause", "fault_after_s", "stops", "restarts", "at_rest_at_end", "last_second_swing_m",
    "oscillation_rule_after_s", "bench", "in_window_after_s", "hold_after_s", "restarts_after_hold"};
inline constexpr const char* kIdentifiedScenarioColumns[] = {
    "scenario", "y0_m", "y_d_m", "friction_scale", "gain_scale", "outcome", "settle_time_s", "final_error_m",
    "fault_cause", "fault_after_s", "stops", "restarts", "at_rest_at_end", "last_second_swing_m",
    "oscillation_rule_after_s", "bench", "identified", "identification_failed", "in_window_after_s", "hold_after_s",
    "restarts_after_hold"};
}  // namespace detail
/// The scenarios file's columns: without --identify, and with it.
inline constexpr records::View kScenarioColumns{"scenario", "a scenario", detail::kScenarioColumns};
inline constexpr records::View kIdentifiedScenarioColumns{"scenario", "a scenario, identified first",
                                                          detail::kIdentifiedScenarioColumns};
static_assert(records::names_fields_of<ScenarioRow>(kScenarioColumns) &&
              records::names_fields_of<ScenarioRow>(kIdentifiedScenarioColumns));
}  // namespace pneu::sweep
