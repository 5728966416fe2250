#include "pneu/identify/online.hpp"
#include "pneu/config/config.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>

#include "pneu/identify/identification_run.hpp"

namespace pneu::identify {

OnlineIdentifier::OnlineIdentifier(const config::Config& config, controller::Runtime& runtime, double window_s,
                                   Fitting fitting)
    : runtime_(runtime), prior_(config.plant), forecast_valves_(config.plant), options_(options_for(config)),
      window_s_(window_s), fitting_(fitting), model_(runtime.model()) {
  // The short stuck phases of ordinary stick-slip carry the valves too: fit every one.
  options_.min_fit_phase_s = options_.min_stuck_s;
  const auto ticks = static_cast<std::size_t>(std::ceil(window_s_ * config.controller.rate_hz)) + 2;
  samples_.reserve(ticks + ticks / 4);
  fit_.window.reserve(samples_.capacity());

  estimate_.plant = prior_;
  if (fitting_ == Fitting::kOnItsOwnThread) thread_ = std::jthread([this](std::stop_token stop) { fit_on_own_thread(stop); });
  runtime.add_sink(*this);
  runtime.set_model_source(*this);
}

OnlineIdentifier::~OnlineIdentifier() {
  if (thread_.joinable()) {
    thread_.request_stop();  // (wakes it from posted_; a fit running is finished first)
    thread_.join();
  }
}

void OnlineIdentifier::fit_on_own_thread(std::stop_token stop) {
  for (;;) {
    {
      std::unique_lock lock(mutex_);
      if (!posted_.wait(lock, stop, [this] { return fit_posted_; })) return;  // asked to stop
      fit_posted_ = false;
    }
    run_fit(fit_, prior_, outcome_);
    fit_done_.store(true, std::memory_order_release);
  }
}

void OnlineIdentifier::on_tick(const controller::TickRecord& tick, const controller::ExpectedAtTick&) {
  if (samples_.size() == samples_.capacity() && first_ > 0) {  // full: the window moves to the front
    samples_.erase(samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(first_));
    first_ = 0;
  }
  samples_.push_back(sample_of(tick));
  while (first_ < samples_.size() && samples_[first_].t_s < tick.t_s - window_s_) {
    ++first_;
    window_from_start_ = false;
  }
}

std::optional<controller::ModelUpdate> OnlineIdentifier::take_model_update() {
  if (!fitting_now_ || !fit_done_.load(std::memory_order_acquire)) return std::nullopt;
  fit_done_.store(false, std::memory_order_relaxed);
  fitting_now_ = false;
  awaited_ = false;
  return finish_update();
}

void OnlineIdentifier::update_late() {
  awaited_ = false;
  ++updates_late_;
}

void OnlineIdentifier::on_event(const controller::LoopEvent& e) {
  using Kind = controller::LoopEvent::Kind;
  if (e.kind == Kind::kStart) {
    ++starts_since_update_;
    if (e.restart) ++restarts_;
    if (stuck_since_s_ >= 0.0 && e.t_s - stuck_since_s_ >= options_.min_fit_phase_s) ++long_phases_ended_;
    stuck_since_s_ = -1.0;
  } else if (e.kind == Kind::kStop) {
    if (starts_since_update_ > 0 && first_ < samples_.size()) {
      if (fitting_now_) ++stops_while_busy_;  // a late fit still running: the next stop's update
      else start_update(samples_.back().t_s);
    }
    stuck_since_s_ = e.t_s;
  }
}

void OnlineIdentifier::on_forecast(const controller::ForecastRecord& f) {
  if (f.update != 0 || f.stop == last_stop_forecast_) return;  // a stop's first forecast made at it
  last_stop_forecast_ = f.stop;
  ++stops_forecast_;
  const char* key = controller::side_turned_on(f.prediction, f.force_n) > 0 ? "plant.friction.static_positive_n" : "plant.friction.static_negative_n";
  const bool identified = !estimate_.estimates.empty() && estimate_.at(key).identified;
  if (identified) return;
  ++stops_on_configured_bound_count_;
  stops_on_configured_bound_.push_back(f.stop);
  // Only the stops the runtime keeps are asked about.
  const auto& kept = runtime_.stops();
  while (!kept.empty() && !stops_on_configured_bound_.empty() && stops_on_configured_bound_.front() < kept.front().index)
    stops_on_configured_bound_.pop_front();
}

bool OnlineIdentifier::forecast_on_a_configured_bound(std::uint64_t stop) const noexcept {
  return std::binary_search(stops_on_configured_bound_.begin(), stops_on_configured_bound_.end(), stop);
}

bool OnlineIdentifier::valve_fit_due(double t_s) const noexcept {
  if (long_phases_ended_ == long_phases_fitted_) return false;
  if (valve_fits_ == 0) return true;
  const double since_first_s = t_s - first_valve_fit_s_;
  return t_s - last_valve_fit_s_ >= kValveRefitShare * std::min(since_first_s, window_s_);
}

void OnlineIdentifier::start_update(double t_s) {
  starts_since_update_ = 0;
  Fit& f = fit_;  // (no fit is running: fitting_now_ is false)
  f.options = options_;
  f.options.fit_valves = valve_fit_due(t_s);
  f.options.at_rest_at_start = window_from_start_;  // the run's start is at rest; a later window's is not
  f.options.valve_fit_starts.clear();
  if (updates_ > 0) f.options.valve_fit_starts = {forecast_valves_};
  f.t_s = t_s;
  f.long_phases = long_phases_ended_;
  const std::span<const Sample> w = window();
  f.window.assign(w.begin(), w.end());  // within the capacity taken at the start
  fitting_now_ = true;
  awaited_ = true;
  if (fitting_ == Fitting::kOnTheDrainingThread) {
    run_fit(f, prior_, outcome_);
    fit_done_.store(true, std::memory_order_relaxed);
    return;
  }
  {
    const std::lock_guard lock(mutex_);
    fit_posted_ = true;
  }
  posted_.notify_one();
}

void OnlineIdentifier::run_fit(const Fit& fit, const model::PlantParams& prior, FitOutcome& outcome) {
  const auto wall0 = std::chrono::steady_clock::now();
  outcome.refused = false;
  outcome.refusal.clear();
  try {
    outcome.id = identify(fit.window, prior, fit.options);
  } catch (const std::exception& e) {  // too little in the window (InsufficientData), or worse:
    outcome.refused = true;             // the run goes on, forecasting on the last estimate
    outcome.refusal = e.what();
  } catch (...) {
    outcome.refused = true;
    outcome.refusal = "the fit failed";
  }
  outcome.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
}

std::optional<controller::ModelUpdate> OnlineIdentifier::finish_update() {
  longest_update_s_ = std::max(longest_update_s_, outcome_.wall_s);
  if (outcome_.refused) {
    ++refused_;
    last_refusal_ = outcome_.refusal;
    return std::nullopt;
  }
  const double t_s = fit_.t_s;
  const Options& o = fit_.options;
  const Identification& id = outcome_.id;
  if (o.fit_valves) {
    long_phases_fitted_ = fit_.long_phases;
    if (valve_fits_++ == 0) first_valve_fit_s_ = t_s;
    last_valve_fit_s_ = t_s;
    // The link's delay, found by the first fit, is kept: the next fits need not search it.
    if (options_.command_delay_samples < 0 && id.evidence.fitted_phases > 0)
      options_.command_delay_samples = id.evidence.command_delay_samples;
  }
  // Each parameter identified in this window replaces the running estimate; the others keep it.
  if (estimate_.estimates.empty()) {
    estimate_ = id;
    for (Estimate& x : estimate_.estimates)
      if (!x.identified) x.value = x.prior;
  } else {
    for (std::size_t i = 0; i < id.estimates.size(); ++i) {
      Estimate& running = estimate_.estimates[i];
      const Estimate& latest = id.estimates[i];
      // One still not identified says why in this window's words, where this window tried it.
      const bool tried = o.fit_valves || !from_the_valve_fit(latest.key);
      if (latest.identified) {
        running = latest;
      } else if (!running.identified && tried) {
        running = latest;
        running.value = running.prior;
      }
    }
    // The valve fit's own figures stay the last fit's where this window did not refit.
    const Evidence last_fit = estimate_.evidence;
    estimate_.evidence = id.evidence;
    if (!o.fit_valves) {
      estimate_.evidence.fitted_phases = last_fit.fitted_phases;
      estimate_.evidence.pressure_rms_residual_pa = last_fit.pressure_rms_residual_pa;
      estimate_.evidence.command_delay_samples = last_fit.command_delay_samples;
    }
  }
  // The running plant: the prior with every estimate's value.
  model::PlantParams p = prior_;
  const auto value = [&](const char* key) { return estimate_.at(key).value; };
  p.friction.static_positive_n = value("plant.friction.static_positive_n");
  p.friction.static_negative_n = value("plant.friction.static_negative_n");
  p.friction.coulomb_positive_n = std::min(value("plant.friction.coulomb_positive_n"), p.friction.static_positive_n);
  p.friction.coulomb_negative_n = std::max(value("plant.friction.coulomb_negative_n"), p.friction.static_negative_n);
  p.friction.viscous_n_s_per_m = value("plant.friction.viscous_n_s_per_m");
  p.valve.max_conductance_m3_per_s_pa = value("plant.valve.max_conductance_m3_per_s_pa");
  p.valve.leak_conductance_in_m3_per_s_pa = value("plant.valve.leak_conductance_in_m3_per_s_pa");
  p.valve.leak_conductance_out_m3_per_s_pa = value("plant.valve.leak_conductance_out_m3_per_s_pa");
  p.valve.null_offset_v = value("plant.valve.null_offset_v");
  p.geometry.dead_volume_p_m3 = value("plant.geometry.dead_volume_p_m3");
  p.geometry.dead_volume_n_m3 = value("plant.geometry.dead_volume_n_m3");
  p.thermal.heat_transfer_w_per_m2_k = value("plant.thermal.heat_transfer_w_per_m2_k");
  p.valve.spool_time_constant_s = value("plant.valve.spool_time_constant_s");
  estimate_.plant = p;
  ++updates_;
  // The forecasts from now on: the running estimate's stiction, and the last valve fit's valves
  // and volumes with every parameter free (what predicts the pressures best; the estimate keeps
  // the configured value of one it cannot tell apart, and fits the others around that).
  if (id.jointly_fitted) forecast_valves_ = *id.jointly_fitted;
  controller::PredictorModel& m = model_;
  m.geometry = forecast_valves_.geometry;
  m.friction = p.friction;
  m.thermal = forecast_valves_.thermal;
  m.spool_time_constant_s = forecast_valves_.valve.spool_time_constant_s;
  // The forecasts say they are uncertain while the last valve fit does not fit.
  if (o.fit_valves && id.evidence.fitted_phases > 0) m.fits = id.evidence.model_fits;
  auto valve = std::make_shared<const model::ValveModel>(forecast_valves_.valve, p.gas);
  m.valve = valve.get();
  controller::IdentificationRecord record;
  record.t_s = t_s;
  record.updates = static_cast<std::uint32_t>(updates_);
  for (std::size_t i = 0; i < controller::kIdentifiedParameterKeys.size(); ++i) {
    const Estimate& e = estimate_.at(controller::kIdentifiedParameterKeys[i]);
    record.value[i] = e.value;
    record.sigma[i] = e.identified ? e.std : 0.0;
    record.identified[i] = e.identified;
  }
  return controller::ModelUpdate{m, std::move(valve), record};
}

}  // namespace pneu::identify
