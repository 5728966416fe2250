#include "pneu/assembly/assembled_run.hpp"
#include "pneu/config/config.hpp"

#include <utility>

#include "pneu/backends/factory.hpp"
#include "pneu/controller/loop_params.hpp"

namespace pneu::assembly {

std::unique_ptr<hal::SimBackend> simulated_bench(const RunSpec& spec, const model::PlantParams& bench) {
  return backends::make_sim_backend(spec.config(), spec.first_output_v(), bench);
}

std::unique_ptr<hal::SimBackend> simulated_bench(const RunSpec& spec) {
  return simulated_bench(spec, config::simulated_bench(spec.config()));
}

AssembledRun AssembledRun::on_configured_backend(RunSpec spec, const RunOptions& options) {
  std::unique_ptr<hal::Backend> backend = backends::make_backend(spec.config(), spec.first_output_v());
  return AssembledRun(std::move(spec), std::move(backend), options);
}

AssembledRun AssembledRun::on_simulated_bench(RunSpec spec, const model::PlantParams& bench,
                                              const RunOptions& options) {
  std::unique_ptr<hal::Backend> backend = assembly::simulated_bench(spec, bench);
  return AssembledRun(std::move(spec), std::move(backend), options);
}

AssembledRun AssembledRun::on_simulated_bench(RunSpec spec, const RunOptions& options) {
  std::unique_ptr<hal::Backend> backend = assembly::simulated_bench(spec);
  return AssembledRun(std::move(spec), std::move(backend), options);
}

AssembledRun::AssembledRun(RunSpec spec, std::unique_ptr<hal::Backend> backend, const RunOptions& options)
    : spec_(std::move(spec)) {
  const config::Config& config = spec_.config();
  sim_ = dynamic_cast<const hal::SimBackend*>(backend.get());
  run_.backend = std::move(backend);
  run_.outputs = std::make_unique<controller::LoopOutputs>();
  run_.loop = std::make_unique<controller::ControlLoop>(controller::LoopParams::from(config, spec_.law()),
                                                        *run_.backend, *run_.outputs);
  const auto& p = config.controller.predictor;
  if (!options.forecasts) {
    run_.runtime = std::make_unique<controller::Runtime>(spec_.predictor_model(), spec_.shared_valve(), false, false);
    run_.runtime->set_follow_forecasts(false);
  } else {
    run_.runtime = std::make_unique<controller::Runtime>(spec_.predictor_model(), spec_.shared_valve(), p.linearized,
                                                         p.nonlinear, p.update_period_s);
    run_.runtime->set_relaxation_forecasts(p.relaxation);
    if (config.controller.hold.enabled)
      run_.runtime->set_hold_law(controller::HoldLaw(config.controller.hold, config.controller.law.max_voltage_v,
                                                     config.controller.period_s()));
  }
}

AssembledRun::~AssembledRun() = default;

void AssembledRun::execute(controller::Clock& clock, const std::atomic<bool>& stop_requested,
                           const std::function<void(int timeout_ms)>& wait_for_input,
                           const std::function<void()>& on_loop_thread,
                           const std::function<void(const controller::MovementTestResult&)>& on_movement_test) {
  controller::execute(run_, spec_.config(), clock, stop_requested, wait_for_input, on_loop_thread, on_movement_test);
}

}  // namespace pneu::assembly
