#include "pneu/controller/session.hpp"
#include "pneu/config/config.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <thread>

namespace pneu::controller {

double equilibrium_voltage_v(const config::Config& config, const model::ValveCharacteristic& valve) {
  return model::equilibrium_voltage_v(valve, model::ChamberProcess(config.plant), 0.0);
}

model::SampledLoop sampled_loop(const config::Config& config) {
  return {config.controller.period_s(), config.controller.differentiator.smoothing,
          config.hal.backend == config::BackendKind::kModbus ? 1 : 0};
}

ControlLaw make_control_law(const config::Config& config, const model::ValveCharacteristic& valve, const LawDesign& how) {
  const ControlLawParams& law = config.controller.law;
  if (law.gains == GainsKind::kFixed) return ControlLaw(law);
  const GainDesignParams& d = law.design;
  const double u_e = equilibrium_voltage_v(config, valve);
  const model::RequestedDynamics poles{d.real_pole_1_per_s, d.natural_frequency_rad_per_s, d.damping};
  const model::GainLimits limits{d.max_position_gain_v_per_m, d.max_velocity_gain_v_s_per_m,
                                 d.max_acceleration_gain_v_s2_per_m};
  model::SampledLoop loop = sampled_loop(config);
  if (how.delay_samples) loop.delay_samples = *how.delay_samples;
  try {
    if (d.infeasible == InfeasibleDesign::kFallBack) {
      model::ScheduleDesign design = model::design_schedule_falling_back(config.plant, valve, u_e, poles, limits,
                                                                         d.node_spacing_m, how.check_sampled ? &loop : nullptr);
      if (how.fallbacks != nullptr) *how.fallbacks = std::move(design.fallbacks);
      return ControlLaw(law, design.schedule);
    }
    const model::GainSchedule schedule =
        model::design_schedule(config.plant, valve, u_e, poles, limits, d.node_spacing_m);
    // Placed on the continuous model: the loop as it samples must follow.
    if (how.check_sampled) model::require_sampled_stable(config.plant, valve, u_e, schedule, loop);
    return ControlLaw(law, schedule);
  } catch (const model::GainDesignError& e) {
    throw config::ConfigError("controller.law.design", std::string("the scheduled gains cannot be designed: ") + e.what());
  }
}

PredictorModel predictor_model(const config::Config& config, const model::ValveCharacteristic& valve) {
  PredictorModel m;
  m.geometry = config.plant.geometry;
  m.gas = config.plant.gas;
  m.friction = config.plant.friction;
  m.valve = &valve;
  m.horizon_s = config.controller.predictor.horizon_s;
  m.linearized_slope = config.controller.predictor.linearized_slope;
  m.has_thermal = config.plant.has_thermal;
  m.thermal = config.plant.thermal;
  m.spool_time_constant_s = config.plant.valve.spool_time_constant_s;
  m.command_delay_samples = sampled_loop(config).delay_samples;
  const auto& predictor = config.controller.predictor;
  m.fits = !predictor.has_model_fit || predictor.model_fit.fits();
  return m;
}

bool movement_test_at_first_arm(const config::Config& config) noexcept {
  return config.hal.backend == config::BackendKind::kModbus && config.controller.movement_test.enabled &&
         !config.controller.start_armed;
}

LoopParams LoopParams::from(const config::Config& config, const ControlLaw& law) {
  const config::ControllerConfig& c = config.controller;
  LoopSettings s;
  s.rate_hz = c.rate_hz;
  s.law = c.law;
  s.differentiator = c.differentiator;
  s.stop_detector = c.stop_detector;
  s.hold = c.hold;
  s.movement_test = c.movement_test;
  s.initial_setpoint_m = c.initial_setpoint_m;
  if (c.schedule.size() > s.schedule_steps.size())  // the schema refuses it first
    throw config::ConfigError("controller.setpoints.schedule", "more steps than the loop holds");
  std::copy(c.schedule.begin(), c.schedule.end(), s.schedule_steps.begin());
  s.schedule_size = c.schedule.size();
  s.soft_limit_min_m = c.soft_limit_min_m;
  s.soft_limit_max_m = c.soft_limit_max_m;
  s.start_armed = c.start_armed;
  s.comms_fault_after_s = c.comms_fault_after_s;
  s.supervisor = c.supervisor;
  return {s, config.commands.setpoint_stream_timeout_s, config.plant.geometry, config.plant.gas.exhaust_pressure_pa,
          config.plant.friction, law, movement_test_at_first_arm(config)};
}

LoopParams LoopParams::from(const config::Config& config) {
  if (config.controller.law.gains != GainsKind::kFixed)
    throw std::invalid_argument("LoopParams::from: a scheduled law needs its designed table (make_control_law)");
  return from(config, ControlLaw(config.controller.law));
}

bool movement_test_runs(const config::Config& config) noexcept {
  return config.hal.backend == config::BackendKind::kModbus && config.controller.movement_test.enabled &&
         config.controller.start_armed;
}

namespace {

// Drains everything queued, waiting for a model update the drain stops for (no tick is queued
// meanwhile: between simulated ticks, or once the loop has stopped), so that the run's records do
// not depend on how long the update takes.
void drain_all(Runtime& runtime, LoopOutputs& outputs) {
  while (!runtime.drain(outputs)) std::this_thread::sleep_for(std::chrono::microseconds(200));
}

}  // namespace

void execute(Run& run, const config::Config& config, Clock& clock,
             const std::atomic<bool>& stop_requested,
             const std::function<void(int timeout_ms)>& wait_for_input,
             const std::function<void()>& on_loop_thread,
             const std::function<void(const MovementTestResult&)>& on_movement_test) {
  const double period = config.controller.period_s();
  // The movement test: on the loop thread, its backend open, before time starts.
  std::function<void()> before_time;
  if (movement_test_runs(config)) {
    before_time = [&] {
      MovementTest test(config.controller.movement_test, MovementTestBench::of(config));
      const MovementTestResult& r = run.movement_test.emplace(
          run_movement_test(*run.backend, clock, period, test, stop_requested));
      if (const auto link = run.backend->link_report()) run.link_transactions_before_time = link->transactions;
      if (on_movement_test) on_movement_test(r);
      if (!r.passed() && r.finding != MovementFinding::kInterrupted)
        throw std::runtime_error(
            std::string("movement test before closed loop: ") + movement_finding_text(r.finding) + " [" +
            describe(r) + "]; outputs at u_0, valve power off; closed loop not started "
            "(controller.movement_test, docs/configuration.md)");
    };
  }
  const auto ticks = static_cast<std::uint64_t>(std::llround(config.controller.duration_s / period)) +
                     (config.controller.duration_s > 0.0 ? 1 : 0);  // both ends: t = 0 and t = duration
  const double health_s = config.telemetry.health_period_s;
  if (clock.simulated()) {
    run_loop(*run.loop, clock, period, ticks, stop_requested, run.timing,
             [&] { drain_all(*run.runtime, *run.outputs); }, health_s, run.outputs.get(), {}, before_time);
  } else {
    std::atomic<bool> done{false};
    std::thread service([&] {
      while (!done.load(std::memory_order_acquire)) {
        run.runtime->drain(*run.outputs);
        if (wait_for_input) wait_for_input(2);
        else std::this_thread::sleep_for(std::chrono::milliseconds(2));
      }
    });
    try {
      run_loop(*run.loop, clock, period, ticks, stop_requested, run.timing, {}, health_s, run.outputs.get(),
               on_loop_thread, before_time);
    } catch (...) {  // the backend failed to open, or the real-time set-up was refused: the safe
                     // output, the backend closed, the service thread stopped, then report
      run.loop->stop();
      run.backend->close();
      done.store(true, std::memory_order_release);
      service.join();
      throw;
    }
    run.loop->stop();  // the safe state first, before waiting for the service thread
    done.store(true, std::memory_order_release);
    service.join();
  }
  run.loop->stop();
  run.backend->close();
  drain_all(*run.runtime, *run.outputs);  // a model update still being made: waited for
  run.runtime->finish(run.runtime->end_time_s());
}

}  // namespace pneu::controller
