// Online refinement: while pneud runs, the bench identified again from its own recent signals at
// every stop that follows a breakaway, and the restart forecasts made on what was identified.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <stop_token>
#include <string>
#include <thread>
#include <vector>

#include "pneu/controller/run_listener.hpp"
#include "pneu/controller/runtime.hpp"
#include "pneu/identify/identify.hpp"
#include "pneu/model/valve.hpp"

namespace pneu::config {
struct Config;  // pneu/config/config.hpp: the root configuration, taken whole by reference here
}

namespace pneu::identify {

/// A sink of the run that keeps the last `window_s` of samples and, at each stop that follows a
/// breakaway (the stop event comes before the stop's forecasts), identifies the bench from them
/// with identify(), starting from `config`'s plant: as the prior. Each parameter identified
/// replaces the running estimate; one the window cannot tell (no breakaway that way, the valve fit
/// not separable) keeps it. The runtime's forecasts then use the running estimate: the stiction
/// bounds and the valves' model with the identified conductances, null offset and dead volumes
/// (not with controller.predictor.valve_table: a measured table is not refined). Never on the
/// loop's thread.
///
/// Where the fit runs (Fitting): on the thread that drains, within the stop's event (the
/// simulated clock, tests, the sweep), or on a thread of the learner's own (pneud on the real
/// clock: the fit takes from a tenth of a second to seconds, and the service thread that drains
/// also pets systemd's watchdog, publishes health and handles commands). On its own thread, the
/// stop's event takes the window's snapshot (on the draining thread) and hands the fit to the
/// learner's thread, one fit at a time; the runtime waits for the update without blocking
/// (Runtime::drain returns and resumes where it stopped), so the stop is still forecast on the
/// model learnt at its event. Should the fit outlast the runtime's bound (half its ticks queue,
/// 4.1 s at 1 kHz), the stop is forecast on the model in force, the update counted late
/// (updates_late()) and taken once made, from the next forecasts on; a stop after a breakaway
/// that comes while that late fit still runs starts none (the next stop's does: stops_while_busy()).
///
/// It never changes the runtime while the runtime hands it a record: it is the runtime's model
/// source (Runtime::set_model_source), and an update made at a stop's event waits in it until the
/// runtime, once every sink has had that event, takes it (take_model_update) and makes the stop's
/// forecasts on it; the update's record then goes to the runtime's sinks (LCM's
/// <prefix>IDENTIFICATION).
///
/// Its memory does not grow with the run: the window's samples in a buffer of fixed size (and its
/// snapshot for the fit in another); the valves' model of each update owned by the update
/// (shared), so that it lives while the runtime uses it (the model in force, the forecasts it
/// follows) and no longer; the stops forecast on a configured bound remembered for the stops the
/// runtime keeps.
class OnlineIdentifier final : public controller::RunListener, public controller::ModelSource {
 public:
  /// Where the fit runs (above, at the class).
  enum class Fitting { kOnTheDrainingThread, kOnItsOwnThread };
  /// Attaches itself to `runtime`, as a sink and as its model source: it must outlive the
  /// runtime's last drain() or finish().
  OnlineIdentifier(const config::Config& config, controller::Runtime& runtime, double window_s = kDefaultWindow_s,
                   Fitting fitting = Fitting::kOnTheDrainingThread);
  static constexpr double kDefaultWindow_s = 60.0;
  OnlineIdentifier(const OnlineIdentifier&) = delete;
  OnlineIdentifier& operator=(const OnlineIdentifier&) = delete;
  /// A fit still running on its thread is finished first (the thread joined), its result let go.
  ~OnlineIdentifier() override;

  void on_tick(const controller::TickRecord& tick, const controller::ExpectedAtTick&) override;
  void on_event(const controller::LoopEvent& event) override;
  void on_forecast(const controller::ForecastRecord& forecast) override;
  [[nodiscard]] std::optional<controller::ModelUpdate> take_model_update() override;
  [[nodiscard]] bool update_coming() const override { return awaited_; }
  void update_late() override;

  /// The running estimate: the configuration's plant: until the first update. Its evidence is the
  /// last window's, but for the valve fit's figures (phases fitted, residual, command delay): the
  /// last window's that refitted the valves.
  [[nodiscard]] const Identification& estimate() const noexcept { return estimate_; }
  [[nodiscard]] int updates() const noexcept { return updates_; }
  /// Updates the window could not make (no breakaway, too little to fit), and the last reason.
  [[nodiscard]] int refused() const noexcept { return refused_; }
  [[nodiscard]] const std::string& last_refusal() const noexcept { return last_refusal_; }
  /// The longest an update's fit took, wall time [s] (on the learner's thread, or the draining one).
  [[nodiscard]] double longest_update_s() const noexcept { return longest_update_s_; }
  /// The updates the runtime stopped waiting for (its bound passed): their stops were forecast on
  /// the model before, the update taken from the next forecasts on.
  [[nodiscard]] int updates_late() const noexcept { return updates_late_; }
  /// The stops after a breakaway that found a late fit still running: no update of their own.
  [[nodiscard]] int stops_while_busy() const noexcept { return stops_while_busy_; }
  /// The restarts seen (starts with the set point unchanged since the stop).
  [[nodiscard]] int restarts() const noexcept { return restarts_; }
  /// The stops forecast (at the stop) while learning, and those among them whose forecast turned
  /// on a stiction bound the running estimate had not identified: the side it forecast a restart
  /// towards, or for "no restart" the side the force relaxes towards. No record of a bench that
  /// has only broken away one way tells the other bound: those forecasts are the configured
  /// value's, however well the rest is known.
  [[nodiscard]] int stops_forecast() const noexcept { return stops_forecast_; }
  [[nodiscard]] int stops_on_a_configured_bound() const noexcept { return stops_on_configured_bound_count_; }
  /// Whether the stop of this index (StopOutcome::index) was forecast on a configured bound: known
  /// for the stops the runtime keeps (Runtime::stops).
  [[nodiscard]] bool forecast_on_a_configured_bound(std::uint64_t stop) const noexcept;

 private:
  // One fit: the window's snapshot and how to fit it, handed to where it runs; its outcome.
  struct Fit {
    std::vector<Sample> window;  // its capacity the samples buffer's, taken at the start
    Options options;
    double t_s = 0.0;
    std::uint64_t long_phases = 0;  // long_phases_ended_ when it was handed
  };
  struct FitOutcome {
    Identification id;
    bool refused = false;
    std::string refusal;
    double wall_s = 0.0;
  };
  // At a stop's event: the snapshot taken and the fit handed on (or run, on the draining thread).
  void start_update(double t_s);
  static void run_fit(const Fit& fit, const model::PlantParams& prior, FitOutcome& outcome);
  // The fit's outcome made the running estimate and the runtime's update (none if refused).
  std::optional<controller::ModelUpdate> finish_update();
  void fit_on_own_thread(std::stop_token stop);
  // Whether this update refits the valves (below, at the class).
  [[nodiscard]] bool valve_fit_due(double t_s) const noexcept;
  static constexpr double kValveRefitShare = 0.25;
  // The window: samples_[first_, end), its oldest first.
  [[nodiscard]] std::span<const Sample> window() const noexcept {
    return std::span<const Sample>(samples_).subspan(first_);
  }

  const controller::Runtime& runtime_;
  const model::PlantParams prior_;  // read by the fit's thread too: never changed
  // The valves and volumes the forecasts use: the last valve fit's, every parameter free (the prior
  // until the first fit; a parameter is identified only where a fit ran).
  model::PlantParams forecast_valves_;
  Options options_;
  double window_s_;
  Fitting fitting_;
  // The window's samples from first_ on; what comes before is let go when the buffer is full (its
  // capacity, fixed at the start, holds the window at the loop's rate and a quarter more).
  std::vector<Sample> samples_;
  std::size_t first_ = 0;
  Identification estimate_;
  controller::PredictorModel model_;  // the model of the last update, or the runtime's at the start
  int updates_ = 0, refused_ = 0, restarts_ = 0;
  int updates_late_ = 0, stops_while_busy_ = 0;
  int starts_since_update_ = 0;
  int stops_forecast_ = 0;
  int stops_on_configured_bound_count_ = 0;
  std::deque<std::uint64_t> stops_on_configured_bound_;  // their indices, increasing, of the stops kept
  std::uint64_t last_stop_forecast_ = 0;  // the stop whose forecasts were counted last
  // The stuck phases long enough for the valve fit that ended, and those of them the last valve
  // fit had: a valve fit is due while a new one ended since.
  std::uint64_t long_phases_ended_ = 0, long_phases_fitted_ = 0;
  int valve_fits_ = 0;
  double first_valve_fit_s_ = 0.0, last_valve_fit_s_ = 0.0;
  bool window_from_start_ = true;  // the window still holds the run's first tick
  double stuck_since_s_ = -1.0;
  std::string last_refusal_;
  double longest_update_s_ = 0.0;

  // The fit in progress (the draining thread's side): handed on, its outcome not yet taken.
  bool fitting_now_ = false;
  bool awaited_ = false;  // and the runtime waits for it (update_coming)
  Fit fit_;               // the fit's thread's alone from handing it on until fit_done_
  FitOutcome outcome_;    // likewise
  std::atomic<bool> fit_done_{false};
  // The fit's thread (Fitting::kOnItsOwnThread): woken by fit_posted_; declared last, so that it
  // is joined before the rest goes.
  std::mutex mutex_;
  std::condition_variable_any posted_;
  bool fit_posted_ = false;  // under mutex_
  std::jthread thread_;
};

}  // namespace pneu::identify
