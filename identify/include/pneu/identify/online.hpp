// Online refinement: while pneud runs, the bench identified again from its own recent signals at
// every stop that follows a breakaway, and the restart forecasts made on what was identified.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/controller/run_listener.hpp"
#include "pneu/controller/runtime.hpp"
#include "pneu/identify/identify.hpp"
#include "pneu/model/valve.hpp"

namespace pneu::identify {

/// A sink of the run that keeps the last `window_s` of samples and, at each stop that follows a
/// breakaway (the stop event comes before the stop's forecasts), identifies the bench from them
/// with identify(), starting from `config`'s plant: as the prior. Each parameter identified
/// replaces the running estimate; one the window cannot tell (no breakaway that way, the valve fit
/// not separable) keeps it. The runtime's forecasts then use the running estimate: the stiction
/// bounds and the valves' model with the identified conductances, null offset and dead volumes
/// (not with controller.predictor.valve_table: a measured table is not refined). Runs on the
/// thread that drains (not the loop's): allocation and the fit's milliseconds are fine there.
/// Each update goes to the runtime's sinks (Runtime::record_identification: LCM's
/// <prefix>IDENTIFICATION).
class OnlineIdentifier final : public controller::RunListener {
 public:
  OnlineIdentifier(const config::Config& config, controller::Runtime& runtime, double window_s = kDefaultWindow_s);
  static constexpr double kDefaultWindow_s = 60.0;

  void on_tick(const controller::TickRecord& tick, const controller::ExpectedAtTick&) override;
  void on_event(const controller::LoopEvent& event) override;
  void on_forecast(const controller::ForecastRecord& forecast) override;

  /// The running estimate: the configuration's plant: until the first update. Its evidence is the
  /// last window's, but for the valve fit's figures (phases fitted, residual, command delay): the
  /// last window's that refitted the valves.
  [[nodiscard]] const Identification& estimate() const noexcept { return estimate_; }
  [[nodiscard]] int updates() const noexcept { return updates_; }
  /// Updates the window could not make (no breakaway, too little to fit), and the last reason.
  [[nodiscard]] int refused() const noexcept { return refused_; }
  [[nodiscard]] const std::string& last_refusal() const noexcept { return last_refusal_; }
  /// The longest an update took on the thread that drains, wall time [s].
  [[nodiscard]] double longest_update_s() const noexcept { return longest_update_s_; }
  /// The restarts seen (starts with the set point unchanged since the stop).
  [[nodiscard]] int restarts() const noexcept { return restarts_; }
  /// The stops forecast (at the stop) while learning, and those among them whose forecast turned
  /// on a stiction bound the running estimate had not identified: the side it forecast a restart
  /// towards, or for "no restart" the side the force relaxes towards. No record of a bench that
  /// has only broken away one way tells the other bound: those forecasts are the configured
  /// value's, however well the rest is known.
  [[nodiscard]] int stops_forecast() const noexcept { return stops_forecast_; }
  [[nodiscard]] int stops_on_a_configured_bound() const noexcept {
    return static_cast<int>(stops_on_configured_bound_.size());
  }
  /// Whether the stop of this index (StopOutcome::index) was forecast on a configured bound.
  [[nodiscard]] bool forecast_on_a_configured_bound(std::uint64_t stop) const noexcept;

 private:
  void update(double t_s);

  controller::Runtime& runtime_;
  model::PlantParams prior_;
  // The valves and volumes the forecasts use: the last valve fit's, every parameter free (the prior
  // until the first fit; a parameter is identified only where a fit ran).
  model::PlantParams forecast_valves_;
  Options options_;
  double window_s_;
  std::deque<Sample> window_;
  Identification estimate_;
  std::vector<std::unique_ptr<model::ValveModel>> valves_;  // every model a forecast may still use
  int updates_ = 0, refused_ = 0, restarts_ = 0;
  int starts_since_update_ = 0;
  int stops_forecast_ = 0;
  std::vector<std::uint64_t> stops_on_configured_bound_;  // their indices, increasing
  std::uint64_t last_stop_forecast_ = 0;  // the stop whose forecasts were counted last
  bool new_long_phase_ = false;  // a stuck phase long enough for the valve fit ended since the last fit
  bool window_from_start_ = true;  // the window still holds the run's first tick
  double stuck_since_s_ = -1.0;
  std::string last_refusal_;
  double longest_update_s_ = 0.0;
};

}  // namespace pneu::identify
