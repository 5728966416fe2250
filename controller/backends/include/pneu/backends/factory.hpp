// The one place that composes the HAL's backends from the configuration: hal.backend picks the
// in-process plant (sim) or the analog I/O module (modbus), and hal.gpio puts the e-stop and
// valve-power lines around it. pneud, the sweep, the end-to-end tests and the benchmarks build
// their runs' backends here (controller::make_run takes them).
#pragma once

#include <memory>

#include "pneu/config/describe.hpp"
#include "pneu/controller/control_law.hpp"
#include "pneu/hal/backend.hpp"
#include "pneu/hal/sim_backend.hpp"

namespace pneu::config {
struct Config;  // pneu/config/config.hpp: the root configuration, taken whole by reference here
}

namespace pneu::backends {

/// The in-process simulated bench of `config` (hal.sim.plant over plant:, config::simulated_bench):
/// the plant at rest at simulation.initial_position_m,
/// at complete equilibrium for the loop's first output under `law` (the run's, fixed or scheduled:
/// u* of Eq. 11 at the initial set point; controller.law.offset_v already resolved).
[[nodiscard]] std::unique_ptr<hal::SimBackend> make_sim_backend(const config::Config& config,
                                                                const controller::ControlLaw& law);
/// The same with a simulated bench of its own, `bench`, in place of the configured one (plant:
/// stays the controller's model): a bench that is not its datasheet (pneu-sweep --bench-spread). It starts at
/// its own equilibrium for the loop's first output.
[[nodiscard]] std::unique_ptr<hal::SimBackend> make_sim_backend(const config::Config& config,
                                                                const controller::ControlLaw& law,
                                                                const model::PlantParams& bench);
/// The same with the law controller::make_control_law designs from `config` (its valve table, if
/// any, relative to the working directory): for tests and benchmarks.
[[nodiscard]] std::unique_ptr<hal::SimBackend> make_sim_backend(const config::Config& config);

/// Refuses what `config` asks of this build and it left out, before anything is driven or
/// written: the modbus backend (PNEU_WITH_MODBUS), the GPIO lines (PNEU_WITH_GPIOD). Throws
/// config::ConfigError naming the key.
void require_built(const config::Config& config);

/// The backend `config` describes: the sim or the modbus backend, inside the GPIO decorator with
/// the lines of hal.gpio when enabled; opened when the run starts. Calls require_built() first.
/// Throws std::runtime_error when the register map or the GPIO lines cannot be had.
/// `law` is the run's: the sim backend starts at equilibrium for its first output.
[[nodiscard]] std::unique_ptr<hal::Backend> make_backend(const config::Config& config,
                                                         const controller::ControlLaw& law);

}  // namespace pneu::backends
