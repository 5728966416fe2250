// One way to assemble a run: from a RunSpec (run_spec.hpp), the backend, the loop and its outputs,
// the runtime and its sinks, owned together, in the order the run needs them (the plant started at
// equilibrium for the law's first output, the runtime's forecasts on the spec's valve, the sinks
// in the order added), then executed on a clock.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "pneu/assembly/run_spec.hpp"
#include "pneu/controller/clock.hpp"
#include "pneu/controller/run_listener.hpp"
#include "pneu/controller/session.hpp"
#include "pneu/hal/backend.hpp"
#include "pneu/hal/sim_backend.hpp"
#include "pneu/model/params.hpp"

namespace pneu::assembly {

/// What the run's runtime does beyond what the configuration says.
struct RunOptions {
  /// false: the runtime makes no forecast, and follows none (a run only recorded: the
  /// identification run). The loop, and so its records, are the same.
  bool forecasts = true;
};

/// The in-process simulated bench `bench` for `spec` (hal.sim.pushes, sensors: as configured): at
/// rest at simulation.initial_position_m, at complete equilibrium for the loop's first output
/// (RunSpec::first_output_v()).
[[nodiscard]] std::unique_ptr<hal::SimBackend> simulated_bench(const RunSpec& spec, const model::PlantParams& bench);
/// ... the configured one (hal.sim.plant, else plant:; config::simulated_bench).
[[nodiscard]] std::unique_ptr<hal::SimBackend> simulated_bench(const RunSpec& spec);

/// A run, assembled: owns its specification (the valve, the law), the backend, the loop and its
/// outputs, the runtime and the sinks emplaced in it. Movable; what the loop and the runtime
/// refer to is held by pointer, so moving keeps it in place.
class AssembledRun {
 public:
  /// On the backend the configuration describes (hal.backend, inside hal.gpio's lines when
  /// enabled: pneu/backends/factory.hpp; refused when this build left it out), opened when the run
  /// starts.
  [[nodiscard]] static AssembledRun on_configured_backend(RunSpec spec, const RunOptions& options = {});
  /// On the in-process simulated bench `bench` (a bench other than the controller's model:
  /// pneu-sweep --bench-spread, a test's mis-modelled bench); simulated_bench() is it.
  [[nodiscard]] static AssembledRun on_simulated_bench(RunSpec spec, const model::PlantParams& bench,
                                                       const RunOptions& options = {});
  /// ... the configured simulated bench (config::simulated_bench).
  [[nodiscard]] static AssembledRun on_simulated_bench(RunSpec spec, const RunOptions& options = {});
  /// On `backend`, made elsewhere (a test's own; a recording wrapper).
  AssembledRun(RunSpec spec, std::unique_ptr<hal::Backend> backend, const RunOptions& options = {});

  AssembledRun(AssembledRun&&) noexcept = default;
  AssembledRun& operator=(AssembledRun&&) noexcept = default;
  ~AssembledRun();

  [[nodiscard]] const RunSpec& spec() const noexcept { return spec_; }
  [[nodiscard]] const config::Config& config() const noexcept { return spec_.config(); }
  /// The parts (the backend, the loop and its outputs, the runtime, the timing, the movement
  /// test's result), owned here.
  [[nodiscard]] controller::Run& run() noexcept { return run_; }
  [[nodiscard]] const controller::Run& run() const noexcept { return run_; }
  [[nodiscard]] controller::Runtime& runtime() noexcept { return *run_.runtime; }
  [[nodiscard]] const controller::Runtime& runtime() const noexcept { return *run_.runtime; }
  [[nodiscard]] controller::ControlLoop& loop() noexcept { return *run_.loop; }
  [[nodiscard]] controller::LoopOutputs& outputs() noexcept { return *run_.outputs; }
  [[nodiscard]] hal::Backend& backend() noexcept { return *run_.backend; }
  /// The in-process simulated bench the run drives (the simulated truth), or null when the
  /// backend is another.
  [[nodiscard]] const hal::SimBackend* simulated_bench() const noexcept { return sim_; }

  /// A sink made in place and owned by the run, handed every record after the sinks added before
  /// it.
  template <class Sink, class... Args>
  Sink& emplace_sink(Args&&... args) {
    auto sink = std::make_unique<Sink>(std::forward<Args>(args)...);
    Sink& ref = *sink;
    owned_sinks_.push_back(std::move(sink));
    run_.runtime->add_sink(ref);
    return ref;
  }
  /// A sink owned by the caller (a file, LCM's bridge, a test's recorder), in order likewise: it
  /// must stay until execute() has returned.
  void add_sink(controller::RunListener& sink) { run_.runtime->add_sink(sink); }

  /// Runs it for controller.duration_s on `clock`, then drains what is left and finishes the
  /// runtime: controller::execute() (pneu/controller/session.hpp) with this run's configuration.
  void execute(controller::Clock& clock, const std::atomic<bool>& stop_requested,
               const std::function<void(int timeout_ms)>& wait_for_input = {},
               const std::function<void()>& on_loop_thread = {},
               const std::function<void(const controller::MovementTestResult&)>& on_movement_test = {});

 private:
  RunSpec spec_;
  // Declared before the run: the runtime holds them, so they go after it.
  std::vector<std::unique_ptr<controller::RunListener>> owned_sinks_;
  controller::Run run_;
  const hal::SimBackend* sim_ = nullptr;
};

}  // namespace pneu::assembly
