// The non-real-time runtime of a run: drains the loop's queues, runs the restart predictors at
// each stop, follows their forecasts against the measurements while the carriage stays stuck and
// makes them again from the pressures of the moment (the live predictor), keeps its account of
// each sticking phase (StopOutcome, judged by verdict.hpp), and emits all of it as typed records
// to its sinks (RunListener). It writes nothing itself.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "pneu/controller/control_law.hpp"
#include "pneu/controller/hold_law.hpp"
#include "pneu/controller/loop.hpp"
#include "pneu/controller/predictor.hpp"
#include "pneu/controller/run_listener.hpp"
#include "pneu/controller/stop_outcome.hpp"

namespace pneu::controller {

class Runtime {
 public:
  /// Forecasts on `model` with the methods enabled; while stuck, made again every
  /// `update_period_s` (0: only at the stop). It owns `valve`, the model's (model.valve ==
  /// valve.get(); null: a model without one), as set_model() does.
  Runtime(const PredictorModel& model, std::shared_ptr<const model::ValveCharacteristic> valve, bool linearized,
          bool nonlinear, double update_period_s = 0.0);

  /// Whether each forecast made at a stop is followed tick by tick against the measured force
  /// (ExpectedAtTick, the gaps of StopOutcome; on by default). The forecasts made again every
  /// update period do not depend on it.
  void set_follow_forecasts(bool on) noexcept { follow_ = on; }
  /// Whether each stop keeps its forecasts made again after it ended (tests, the sweep); else
  /// only its half-way ones, so that a daemon's memory does not grow with the time spent at rest.
  void set_keep_reforecasts(bool on) noexcept { keep_reforecasts_ = on; }
  /// Whether the forecasts made again while stuck include the relaxation method's, fitted to the
  /// phase's own pressures (predict_relaxation; off by default). It needs update_period_s > 0.
  void set_relaxation_forecasts(bool on) noexcept { relaxation_ = on; }
  /// The in-position hold's law (controller.hold): while the loop holds a stop, forecasts under
  /// its commands (predict_held) at the hold's start and then every update period. Off unless set.
  void set_hold_law(const HoldLaw& law) noexcept { hold_law_ = law; }
  /// Adds a sink: every record goes to each sink, in the order they were added. Not owned; it
  /// must outlive the runtime's last drain(), finish() or record_command().
  void add_sink(RunListener& sink) { sinks_.push_back(&sink); }
  /// What learns the bench while the run goes on (online identification), often also a sink. Once
  /// every sink has had a record, the runtime asks it for an update; one it gives is taken over
  /// (set_model) and told to the sinks (RunListener::on_identification) before the runtime acts
  /// on that record: a stop's forecasts are made on the model learnt at the stop's event. So no
  /// sink changes the runtime while the runtime is handing it a record. An update still being made
  /// on a thread of the source's own (ModelSource::update_coming) is waited for: see drain(). Not
  /// owned; it must outlive the runtime's last drain() or finish().
  void set_model_source(ModelSource& source) noexcept { model_source_ = &source; }

  /// Pops everything the loop queued, each event before the record of the tick that raised it,
  /// so that the result does not depend on how often it is called. Not real-time: call from the
  /// service thread or between simulated ticks. True when it drained everything; false when it
  /// stopped to wait for a model update: the model source said one was coming for the event just
  /// handed (ModelSource::update_coming). The records after it then stay in the loop's queues
  /// (the health records excepted: they are handed on while it waits) and the next drain()
  /// resumes exactly there, first asking the source for the update. It waits while fewer than
  /// kMaxTicksQueuedWaiting ticks are queued; then it goes on with the model in force (the stop
  /// forecast on it), counts the update late (model_updates_late(), ModelSource::update_late) and
  /// takes the update, once given, from the next record on.
  bool drain(LoopOutputs& outputs);
  /// The most ticks queued that drain() waits for a model update with: half the ticks queue,
  /// 4.1 s of a 1 kHz loop, so that the queue does not overflow while it waits.
  static constexpr std::size_t kMaxTicksQueuedWaiting = decltype(LoopOutputs::ticks)::capacity() / 2;
  /// Whether the last drain() stopped to wait for a model update.
  [[nodiscard]] bool waiting_for_model_update() const noexcept { return waiting_.has_value(); }
  /// The model updates drain() stopped waiting for before they came (their stops forecast on the
  /// model in force).
  [[nodiscard]] std::uint64_t model_updates_late() const noexcept { return model_updates_late_; }
  /// Closes the run at `t_end_s` (or the last tick drained, if later). Waiting for a model update
  /// (drain() returned false), it goes on without it first (the update late) and drains the rest.
  void finish(double t_end_s);
  /// Hands a command's verdict to the sinks, dated by the last tick drained. Not real-time, not
  /// thread-safe: call from the thread that drains (the service thread).
  void record_command(CommandRecord command);

  /// The stops of the run, the last max_stops_kept of them (kMaxStopsKept unless set; at least 4).
  /// The memory they take is taken whole when the runtime is made (and when the number is set),
  /// so that a daemon's does not grow as the stops come.
  [[nodiscard]] const std::vector<StopOutcome>& stops() const noexcept { return stops_; }
  [[nodiscard]] std::uint64_t stops_forgotten() const noexcept { return stops_forgotten_; }
  static constexpr std::size_t kMaxStopsKept = 4096;
  /// Before the first drain().
  void set_max_stops_kept(std::size_t n);
  [[nodiscard]] double end_time_s() const noexcept { return t_end_s_; }
  /// The faults latched during the run (kind kFault events), in order.
  [[nodiscard]] const std::vector<LoopEvent>& faults() const noexcept { return faults_; }
  [[nodiscard]] std::uint64_t ticks_seen() const noexcept { return ticks_seen_; }
  [[nodiscard]] std::uint64_t sequence_gaps() const noexcept { return sequence_gaps_; }

  [[nodiscard]] const PredictorModel& model() const noexcept { return model_; }
  /// The model the forecasts use from now on: the forecasts made again while stuck from the next
  /// one, each stop's from its own. A forecast already followed keeps the model it was made with.
  /// `valve`, if given, owns model.valve, and the runtime keeps it while it is in use (by the
  /// model, or by a forecast followed) and no longer; without it, model.valve must outlive the
  /// runtime's use of it. The estimate of the chambers' temperatures and spools goes on from where
  /// it stands, on the new model. Not from a sink while it is handed a record: a ModelSource does
  /// that (set_model_source).
  void set_model(const PredictorModel& model, std::shared_ptr<const model::ValveCharacteristic> valve = nullptr) noexcept;
  /// The chambers' temperatures and spools as estimated at the last tick drained, for a model that
  /// has them (PredictorModel::has_hidden_state), else nothing.
  [[nodiscard]] const std::optional<model::ChamberObserver>& chamber_estimate() const noexcept { return observer_; }
  [[nodiscard]] bool forecasts(PredictionMethod method) const noexcept {
    switch (method) {
      case PredictionMethod::kLinearized: return linearized_;
      case PredictionMethod::kNonlinear: return nonlinear_;
      case PredictionMethod::kRelaxation: return relaxation_ && update_period_s_ > 0.0;
      case PredictionMethod::kHeld: return hold_law_.has_value();
    }
    return false;
  }
  [[nodiscard]] double update_period_s() const noexcept { return update_period_s_; }

 private:
  void on_tick(const TickRecord& r);
  // Hands the event to the sinks, then acts on it once the model source's update for it is
  // taken (or late); false: waiting for it (waiting_).
  bool on_event(const LoopEvent& e, const LoopOutputs& out);
  // The wait for the update of waiting_: true once it is over (the update taken, or given up on
  // with `out`'s ticks queue half full or `give_up`), waiting_ acted on.
  bool resume(const LoopOutputs& out, bool give_up = false);
  void act_on(const LoopEvent& e);
  void drain_health(LoopOutputs& out);
  void emit_forecast(const StopOutcome& s, const Prediction& p);
  void reforecast(StopOutcome& s, const TickRecord& r, const ExpectedAtTick& expected);
  void settle(StopOutcome& s) const;
  void held_forecast(StopOutcome& s, const TickRecord& r);
  // Hands a record to every sink (`call(sink)`), then takes over the model source's update, if any.
  template <class Call>
  void dispatch(const Call& call);
  // Whether it took one.
  bool take_model_update();

  // The forecasts of the open stop, followed while they hold.
  struct Following {
    std::optional<ForecastTrack> tracks[2];  // linearized, nonlinear
    double next_update_s = 0.0;
    std::uint32_t stride = 1;  // updates kept: every stride-th (thinned beyond kMaxReforecastsKept)
    PhaseHistory history;      // the pressures since the snapshot, for the relaxation method
    std::shared_ptr<const model::ValveCharacteristic> valve;  // owns the tracks' valve, if it was handed over
  };

  // With each snapshot, what no sensor gives (StopSnapshot::t_p_k ...), as estimated now.
  StopSnapshot with_hidden_state(StopSnapshot s) const noexcept;

  PredictorModel model_;
  std::shared_ptr<const model::ValveCharacteristic> valve_;  // owns model_.valve, if it was handed over
  ModelSource* model_source_ = nullptr;
  // Where a drain() waiting for a model update stopped: the event handed (not acted on yet), the
  // tick popped whose events were being handed (its record not handed yet), the queues.
  std::optional<LoopEvent> waiting_;
  std::optional<TickRecord> in_hand_;
  LoopOutputs* waiting_on_ = nullptr;
  std::uint64_t model_updates_late_ = 0;
  std::optional<model::ChamberObserver> observer_;  // with a model that has hidden state
  bool observer_started_ = false;
  // The last commands (u_P, u_N), newest first: the valves act on the one model_.command_delay_samples back.
  std::array<std::array<double, 2>, 4> recent_commands_{};
  bool linearized_, nonlinear_;
  bool relaxation_ = false;
  double update_period_s_;
  bool follow_ = true;
  bool keep_reforecasts_ = false;
  std::uint64_t stops_forgotten_ = 0;
  std::size_t max_stops_kept_ = kMaxStopsKept;
  std::vector<RunListener*> sinks_;
  std::vector<StopOutcome> stops_;
  std::optional<Following> following_;
  std::optional<HoldLaw> hold_law_;
  std::optional<HoldState> hold_;   // the hold in force, as it started
  double next_held_s_ = 0.0;        // the next forecast under it is due
  std::vector<LoopEvent> faults_;  // the faults latched, for the summary
  double t_end_s_ = 0.0;
  std::uint64_t ticks_seen_ = 0;
  std::uint64_t next_seq_ = 0;
  std::uint64_t sequence_gaps_ = 0;
};

}  // namespace pneu::controller
