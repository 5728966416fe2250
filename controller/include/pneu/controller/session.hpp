// The parts of a run derived from the configuration (u_e, the law's design, the predictors' model,
// the loop's parameters: session.cpp) and the run executed. pneu/assembly/ assembles runs of them:
// pneud, the sweep, the identification run, the benchmarks and the tests build theirs there.
#pragma once

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "pneu/config/describe.hpp"
#include "pneu/controller/clock.hpp"
#include "pneu/controller/movement_test.hpp"
#include "pneu/controller/runtime.hpp"
#include "pneu/hal/backend.hpp"
#include "pneu/model/tangent_linear.hpp"
#include "pneu/model/valve_table.hpp"

namespace pneu::config {
struct Config;  // pneu/config/config.hpp: the root configuration, taken whole by reference here
}

namespace pneu::controller {

/// u_e of Eq. 7 for `config`'s model: the voltage at which its chambers at rest at mid-stroke, each
/// where it settles, balance the force [V].
[[nodiscard]] double equilibrium_voltage_v(const config::Config& config, const model::ValveCharacteristic& valve);

/// The sampled loop pneud runs for `config`: the loop's period and differentiator, and the I/O
/// delay of its backend (a module on a bus: the command written at a tick acts after the next
/// read, one sample; in process, none).
[[nodiscard]] model::SampledLoop sampled_loop(const config::Config& config);

/// How make_control_law() designs: whether it checks the sampled loop (and with which delay), and
/// where it reports the nodes it fell back at.
struct LawDesign {
  bool check_sampled = true;
  /// The sampled loop's delay beyond the hold [samples]; unset: the backend's (sampled_loop()).
  std::optional<int> delay_samples;
  std::vector<model::DesignFallback>* fallbacks = nullptr;  ///< filled when given
};

/// The law of Eq. 4 for `config` (controller.law.offset_v holding u_0: assembly::RunSpec designs it
/// so): the fixed gains of controller.law, or
/// with controller.law.gains scheduled, the table designed by pole placement at nodes over the
/// stroke (controller.law.design) on the tangent-linear model of plant: with `valve`, around u_e of
/// Eq. 7. Where the requested dynamics cannot be had (a gain negative or beyond its limit, the
/// sampled loop at controller.rate_hz with the backend's delay unstable), node by node the nearest
/// feasible ones the sampled loop is stable with (model::design_schedule_falling_back), each one
/// reported; with controller.law.design.infeasible refuse, or when nothing is stable there, a
/// design refused: config::ConfigError at controller.law.design, with the position, the gain and
/// the reason. Without the sampled loop's check (pneu-plant tune maps it), only a placement's own
/// refusals fall back or refuse.
[[nodiscard]] ControlLaw make_control_law(const config::Config& config, const model::ValveCharacteristic& valve,
                                          const LawDesign& how = {});

/// The predictors' view of the bench; its valve is `valve`, which the caller keeps (the runtime
/// can own it: Runtime's constructor, set_model()).
[[nodiscard]] PredictorModel predictor_model(const config::Config& config,
                                             const model::ValveCharacteristic& valve);

/// A complete run, on whatever backend: the backend the loop drives, the loop and its outputs, the
/// runtime. assembly::AssembledRun (pneu/assembly/assembled_run.hpp) builds it and owns it with
/// what it refers to. Movable: the parts the loop refers to are held by pointer.
struct Run {
  std::unique_ptr<hal::Backend> backend;
  std::unique_ptr<LoopOutputs> outputs;
  std::unique_ptr<ControlLoop> loop;
  std::unique_ptr<Runtime> runtime;
  LoopTiming timing;
  std::optional<MovementTestResult> movement_test;  ///< the movement test's, when it ran
  /// The link's exchanges before the loop's time started (the movement test's; hal::LinkReport).
  std::uint64_t link_transactions_before_time = 0;
};

/// Runs it for controller.duration_s on `clock` (the simulated clock drains the runtime between
/// ticks, waiting there for a model update the drain stops for; the real clock drains it from a
/// service thread, which does not wait: it calls `wait_for_input` and drains again), then drains
/// what is left (a model update still being made waited for) and finishes the runtime.
/// `wait_for_input(timeout_ms)`, when set, is how the service thread waits between drains (LCM's
/// handle); else it sleeps 2 ms.
/// `on_loop_thread`, when set, runs on the loop thread before the backend opens and time starts
/// (real clock: its real-time set-up, which the backend's own I/O thread, started after it,
/// inherits; what it throws ends the run, the backend closed).
/// On hal.backend modbus with controller.movement_test.enabled, the movement test then runs on the
/// loop thread before time starts (movement_test_runs()); its result goes to `on_movement_test`
/// (when set, on the loop thread, before any tick) and into `run.movement_test`. A finding other
/// than a pass or an interruption ends the run before closed loop: std::runtime_error naming it,
/// the safe output written and the backend closed.
void execute(Run& run, const config::Config& config, Clock& clock,
             const std::atomic<bool>& stop_requested,
             const std::function<void(int timeout_ms)>& wait_for_input = {},
             const std::function<void()>& on_loop_thread = {},
             const std::function<void(const MovementTestResult&)>& on_movement_test = {});

/// Whether execute() runs the movement test for `config` before the loop's time starts: on
/// hal.backend modbus (a bench, or pneu-plant serve) with controller.movement_test.enabled, when
/// the run starts armed (controller.start_armed, or an identification run); never on the
/// in-process plant, which cannot be miswired. A run that starts disarmed runs it in the loop at
/// its first ARM instead (movement_test_at_first_arm(), loop_params.hpp; Mode::kMovementTest).
[[nodiscard]] bool movement_test_runs(const config::Config& config) noexcept;

}  // namespace pneu::controller
