#include "pneu/controller/runtime.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "pneu/controller/verdict.hpp"

namespace pneu::controller {

namespace {

ForecastRecord forecast_record(const StopOutcome& s, const Reforecast& f) {
  ForecastRecord r;
  r.stop = s.index;
  r.t_stop_s = s.t_stop_s;
  r.update = f.update;
  r.t_s = f.t_s;
  r.u_star_v = f.u_star_v;
  r.force_n = f.force_n;
  r.stop_forecast_force_n = f.stop_forecast_force_n;
  r.prediction = f.prediction;
  return r;
}

// The stop's snapshot with the time and pressures of a later tick (the live predictor's start).
StopSnapshot snapshot_at(const StopOutcome& s, const TickRecord& r) {
  StopSnapshot now = s.snapshot;
  now.t_s = r.t_s;
  now.p_p_pa = r.p_p_pa;
  now.p_n_pa = r.p_n_pa;
  return now;
}

}  // namespace

Runtime::Runtime(const PredictorModel& model, std::shared_ptr<const model::ValveCharacteristic> valve, bool linearized,
                 bool nonlinear, double update_period_s)
    : model_(model), linearized_(linearized), nonlinear_(nonlinear), update_period_s_(update_period_s) {
  set_model(model, std::move(valve));
  set_max_stops_kept(kMaxStopsKept);
}

void Runtime::set_max_stops_kept(std::size_t n) {
  max_stops_kept_ = std::max<std::size_t>(n, 4);
  // Taken and touched now (made and let go: the memory stays the vector's), so that it is resident
  // from the start rather than as the stops come.
  std::vector<StopOutcome> kept(max_stops_kept_);
  kept.clear();
  for (StopOutcome& s : stops_) kept.push_back(std::move(s));
  stops_ = std::move(kept);
}

void Runtime::set_model(const PredictorModel& model, std::shared_ptr<const model::ValveCharacteristic> valve) noexcept {
  model_ = model;
  valve_ = std::move(valve);
  if (!model.has_hidden_state() || model.valve == nullptr) {
    observer_.reset();
    return;
  }
  model::ChamberObserver next(model.process(), *model.valve, model::SpoolLag{model.spool_time_constant_s});
  if (observer_) next.resume(*observer_);
  observer_.emplace(next);
}

StopSnapshot Runtime::with_hidden_state(StopSnapshot s) const noexcept {
  if (!observer_ || !observer_started_) return s;
  const model::ChamberState& x = observer_->state();
  s.t_p_k = x.t_p_k;
  s.t_n_k = x.t_n_k;
  s.w_p_v = x.w_p_v;
  s.w_n_v = x.w_n_v;
  return s;
}

template <class Call>
void Runtime::dispatch(const Call& call) {
  for (RunListener* sink : sinks_) call(*sink);
  if (!waiting_) take_model_update();  // (waiting, it is taken where the drain stopped)
}

bool Runtime::take_model_update() {
  if (model_source_ == nullptr) return false;
  std::optional<ModelUpdate> update = model_source_->take_model_update();
  if (!update) return false;
  set_model(update->model, std::move(update->valve));
  for (RunListener* sink : sinks_) sink->on_identification(update->record);
  return true;
}

bool Runtime::drain(LoopOutputs& out) {
  if (waiting_ && !resume(out)) {
    drain_health(out);
    return false;
  }
  // Ticks and events come on two queues. The loop pushes a tick's events before its record, so
  // the events raised up to a record are in their queue when the record is popped.
  for (;;) {
    if (!in_hand_) {
      TickRecord r;
      if (!out.ticks.try_pop(r)) break;
      in_hand_ = r;
    }
    for (const LoopEvent* e = out.events.front(); e && e->tick_seq <= in_hand_->seq; e = out.events.front()) {
      LoopEvent event;
      (void)out.events.try_pop(event);  // the one front() showed
      if (!on_event(event, out)) {
        waiting_on_ = &out;
        drain_health(out);
        return false;
      }
    }
    const TickRecord r = *in_hand_;
    in_hand_.reset();
    on_tick(r);
  }
  LoopEvent e;
  while (out.events.try_pop(e))
    if (!on_event(e, out)) {
      waiting_on_ = &out;
      drain_health(out);
      return false;
    }
  drain_health(out);
  return true;
}

void Runtime::drain_health(LoopOutputs& out) {
  HealthRecord h;
  while (out.health.try_pop(h)) dispatch([&](RunListener& sink) { sink.on_health(h); });
}

bool Runtime::on_event(const LoopEvent& e, const LoopOutputs& out) {
  for (RunListener* sink : sinks_) sink->on_event(e);
  if (model_source_ != nullptr && !take_model_update() && model_source_->update_coming()) {
    waiting_ = e;
    return resume(out);
  }
  act_on(e);
  return true;
}

bool Runtime::resume(const LoopOutputs& out, bool give_up) {
  if (!take_model_update() && model_source_->update_coming()) {
    if (!give_up && out.ticks.size() < kMaxTicksQueuedWaiting) return false;
    ++model_updates_late_;  // the stop forecast on the model in force; the update from the next record on
    model_source_->update_late();
  }
  const LoopEvent e = *waiting_;
  waiting_.reset();
  act_on(e);
  return true;
}

void Runtime::on_tick(const TickRecord& r) {
  if (r.seq != next_seq_) ++sequence_gaps_;
  next_seq_ = r.seq + 1;
  ++ticks_seen_;
  t_end_s_ = r.t_s;
  // The chambers' hidden state to this tick (a bad sample is skipped: the next good one takes over).
  if (observer_ && std::isfinite(r.y_m) && std::isfinite(r.p_p_pa) && std::isfinite(r.p_n_pa)) {
    if (!observer_started_) {
      observer_->reset(r.t_s, r.y_m, r.p_p_pa, r.p_n_pa, r.u_v, r.u_n_v);
      recent_commands_.fill({r.u_v, r.u_n_v});
    } else {
      observer_->advance(r.t_s, r.y_m, r.p_p_pa, r.p_n_pa);
    }
    observer_started_ = true;
    // The valves act on the command recorded the link's delay before (a module on a bus: one tick).
    std::copy_backward(recent_commands_.begin(), recent_commands_.end() - 1, recent_commands_.end());
    recent_commands_[0] = {r.u_v, r.u_n_v};
    const auto& acting =
        recent_commands_[static_cast<std::size_t>(std::clamp(model_.command_delay_samples, 0, 3))];
    observer_->command(acting[0], acting[1]);
  }

  // A forecast holds while the carriage stays stuck under the u* it assumed: armed (not holding:
  // the hold drives u), same set point.
  if (!stops_.empty() && !stops_.back().ended && std::isnan(stops_.back().forecast_void_at_s) &&
      (r.mode != Mode::kArmed || r.y_d_m != stops_.back().y_d_m))
    stops_.back().forecast_void_at_s = r.t_s;
  ExpectedAtTick expected;
  bool reforecast_due = false;
  if (following_) {
    StopOutcome& s = stops_.back();
    if (s.ended || !r.stuck || !std::isnan(s.forecast_void_at_s)) {
      following_.reset();
    } else if (r.t_s >= s.snapshot.t_s) {
      double* gaps[2] = {&s.largest_gap_linearized_n, &s.largest_gap_nonlinear_n};
      ForecastPoint* at[2] = {&expected.linearized, &expected.nonlinear};
      for (int i = 0; i < 2 && follow_; ++i) {
        if (!following_->tracks[i]) continue;
        *at[i] = following_->tracks[i]->at(r.t_s);
        const double gap = std::abs(r.force_n - at[i]->force_n);
        if (std::isfinite(gap)) *gaps[i] = std::isnan(*gaps[i]) ? gap : std::max(*gaps[i], gap);
      }
      if (relaxation_ && std::isfinite(r.p_p_pa) && std::isfinite(r.p_n_pa))
        following_->history.add(r.t_s, r.p_p_pa, r.p_n_pa);
      // (Not at the snapshot's own tick: that forecast is the stop's.)
      if (update_period_s_ > 0.0 && r.t_s > s.snapshot.t_s && r.t_s >= following_->next_update_s - 1e-9) {
        reforecast_due = true;
        // The next whole period after this tick (a period under the loop's: every tick).
        const double periods = std::floor((r.t_s - s.snapshot.t_s) / update_period_s_ + 1e-6) + 1.0;
        following_->next_update_s = s.snapshot.t_s + periods * update_period_s_;
      }
    }
  }
  dispatch([&](RunListener& sink) { sink.on_tick(r, expected); });
  if (reforecast_due) reforecast(stops_.back(), r, expected);
  if (hold_ && r.mode == Mode::kHold && r.stuck && r.t_s >= next_held_s_ - 1e-9 && !stops_.empty() &&
      !stops_.back().ended) {
    held_forecast(stops_.back(), r);
    next_held_s_ = update_period_s_ > 0.0
                       ? hold_->t0_s + (std::floor((r.t_s - hold_->t0_s) / update_period_s_ + 1e-6) + 1.0) * update_period_s_
                       : std::numeric_limits<double>::infinity();
  }
}

// A forecast under the hold's commands from this tick's pressures, the command it sent and the
// hold's integral term after it.
void Runtime::held_forecast(StopOutcome& s, const TickRecord& r) {
  StopSnapshot now = with_hidden_state(snapshot_at(s, r));
  now.u_v = r.u_v;  // the hold's command, not u*
  if (!snapshot_is_finite(now)) return;
  HoldState state = *hold_;
  state.integral_v = r.hold_integral_v;
  Reforecast f;
  f.update = ++s.updates;
  f.t_s = r.t_s;
  f.force_n = r.force_n;
  f.u_star_v = r.u_v;
  f.prediction = predict_held(model_, *hold_law_, state, now);
  ++s.held_forecasts;
  if (f.prediction.will_restart) ++s.held_restart_forecasts;
  if (!s.held_first || s.held_first->t_s < hold_->t0_s) s.held_first = f;
  const ForecastRecord record = forecast_record(s, f);
  dispatch([&](RunListener& sink) { sink.on_forecast(record); });
}

void Runtime::reforecast(StopOutcome& s, const TickRecord& r, const ExpectedAtTick& expected) {
  const StopSnapshot now = with_hidden_state(snapshot_at(s, r));
  if (!snapshot_is_finite(now)) return;
  ++s.updates;
  // Bounded history: past the cap, every other update kept is let go, evenly over the phase.
  if (s.reforecasts.size() + 3 > StopOutcome::kMaxReforecastsKept) {
    following_->stride *= 2;
    const std::uint32_t stride = following_->stride;
    std::erase_if(s.reforecasts, [stride](const Reforecast& f) { return f.update % stride != 0; });
  }
  const bool keep = s.updates % following_->stride == 0;
  const auto emit = [&](const Prediction& prediction, double stop_forecast_force_n) {
    Reforecast f;
    f.update = s.updates;
    f.t_s = r.t_s;
    f.force_n = r.force_n;
    f.u_star_v = now.u_v;
    f.stop_forecast_force_n = stop_forecast_force_n;
    f.prediction = prediction;
    if (keep) s.reforecasts.push_back(f);
    const ForecastRecord record = forecast_record(s, f);
    dispatch([&](RunListener& sink) { sink.on_forecast(record); });
  };
  if (linearized_) emit(predict_linearized(model_, now), expected.linearized.force_n);
  if (nonlinear_) emit(predict_nonlinear(model_, now), expected.nonlinear.force_n);
  // (No forecast of this method was made at the stop: nothing to follow.)
  if (relaxation_)
    if (const auto p = predict_relaxation(model_, now, following_->history))
      emit(*p, std::numeric_limits<double>::quiet_NaN());
}

void Runtime::emit_forecast(const StopOutcome& s, const Prediction& p) {
  Reforecast at_stop;  // update 0: from the stop's snapshot
  at_stop.t_s = s.snapshot.t_s;
  at_stop.force_n = s.force_n;
  at_stop.u_star_v = s.snapshot.u_v;
  at_stop.stop_forecast_force_n = s.force_n;
  at_stop.prediction = p;
  const ForecastRecord record = forecast_record(s, at_stop);
  dispatch([&](RunListener& sink) { sink.on_forecast(record); });
}

// The stop has ended (or the run has): its half-way forecasts are settled, and its history goes
// unless it is kept.
void Runtime::settle(StopOutcome& s) const {
  s.halfway_linearized.reset();
  s.halfway_nonlinear.reset();
  s.halfway_relaxation.reset();
  if (const Reforecast* f = halfway_reforecast(s, PredictionMethod::kLinearized)) s.halfway_linearized = *f;
  if (const Reforecast* f = halfway_reforecast(s, PredictionMethod::kNonlinear)) s.halfway_nonlinear = *f;
  if (const Reforecast* f = halfway_reforecast(s, PredictionMethod::kRelaxation)) s.halfway_relaxation = *f;
  if (!keep_reforecasts_) std::vector<Reforecast>().swap(s.reforecasts);
}

void Runtime::act_on(const LoopEvent& e) {
  if (e.kind == LoopEvent::Kind::kStop) {
    StopOutcome s;
    s.index = e.stop_index;
    s.t_stop_s = e.t_s;
    s.y_stop_m = e.y_m;
    s.force_n = e.force_n;
    s.y_d_m = e.y_d_m;
    s.snapshot = e.snapshot;
    // The snapshot's tick comes after its event: the chambers' hidden state taken to it.
    if (observer_ && observer_started_ && snapshot_is_finite(s.snapshot)) {
      observer_->advance(s.snapshot.t_s, s.snapshot.y_m, s.snapshot.p_p_pa, s.snapshot.p_n_pa);
      s.snapshot = with_hidden_state(s.snapshot);
    }
    // Forecasts assume the law holds u* (Eq. 11): not when disarmed or faulted.
    const bool forecastable = e.controlled && snapshot_is_finite(s.snapshot);
    if (linearized_ && forecastable) s.linearized = predict_linearized(model_, s.snapshot);
    if (nonlinear_ && forecastable) s.nonlinear = predict_nonlinear(model_, s.snapshot);
    if (s.linearized) emit_forecast(s, *s.linearized);
    if (s.nonlinear) emit_forecast(s, *s.nonlinear);
    following_.reset();
    if (stops_.size() >= max_stops_kept_) {  // a daemon's summary lists the last ones
      const std::size_t n = stops_.size() - max_stops_kept_ + max_stops_kept_ / 4;
      stops_.erase(stops_.begin(), stops_.begin() + static_cast<std::ptrdiff_t>(n));
      stops_forgotten_ += n;
    }
    stops_.push_back(s);
    if (forecastable && (linearized_ || nonlinear_ || forecasts(PredictionMethod::kRelaxation))) {
      following_.emplace();
      following_->valve = valve_;
      if (linearized_) following_->tracks[0].emplace(PredictionMethod::kLinearized, model_, s.snapshot);
      if (nonlinear_) following_->tracks[1].emplace(PredictionMethod::kNonlinear, model_, s.snapshot);
      following_->next_update_s = s.snapshot.t_s + update_period_s_;
    }
    return;
  }
  if (e.kind == LoopEvent::Kind::kHoldStart) {
    if (hold_law_) hold_ = e.hold;
    next_held_s_ = e.t_s;  // the first at the hold's own tick
    return;
  }
  if (e.kind == LoopEvent::Kind::kHoldEnd) {
    hold_.reset();
    return;
  }
  if (e.kind == LoopEvent::Kind::kFaultReset || e.kind == LoopEvent::Kind::kResetRefused) return;
  if (e.kind == LoopEvent::Kind::kFault) {
    following_.reset();  // the safe output replaces u*
    faults_.push_back(e);
    return;
  }
  if (!stops_.empty() && stops_.back().index == e.stop_index && !stops_.back().ended) {
    following_.reset();
    StopOutcome& s = stops_.back();
    s.ended = true;
    s.restarted = e.restart;
    s.t_end_s = e.t_s;
    s.direction = e.direction;
    settle(s);
  }
}

void Runtime::finish(double t_end_s) {
  while (waiting_) {  // the update given up on (late), the rest drained
    (void)resume(*waiting_on_, true);
    (void)drain(*waiting_on_);
  }
  t_end_s_ = std::max(t_end_s_, t_end_s);
  for (auto& s : stops_)
    if (!s.ended) {
      s.t_end_s = t_end_s_;
      settle(s);
    }
  dispatch([&](RunListener& sink) { sink.on_end(t_end_s_); });
}

void Runtime::record_command(CommandRecord command) {
  command.t_s = t_end_s_;
  dispatch([&](RunListener& sink) { sink.on_command(command); });
}

}  // namespace pneu::controller
