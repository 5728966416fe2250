// The one place that composes the HAL's backends from the configuration: hal.backend picks the
// in-process plant (sim) or the analog I/O module (modbus), and hal.gpio puts the e-stop and
// valve-power lines around it. pneud, the sweep, the end-to-end tests and the benchmarks build
// their runs' backends here, through the assembly (pneu/assembly/assembled_run.hpp).
#pragma once

#include <memory>

#include "pneu/config/describe.hpp"
#include "pneu/hal/backend.hpp"
#include "pneu/hal/sim_backend.hpp"

namespace pneu::config {
struct Config;  // pneu/config/config.hpp: the root configuration, taken whole by reference here
}

namespace pneu::backends {

/// The in-process simulated bench of `config` (hal.sim.plant over plant:, config::simulated_bench):
/// the plant at rest at simulation.initial_position_m, at complete equilibrium under
/// `first_output_v`, the loop's first output (the law's u* of Eq. 11 at the initial set point:
/// assembly::RunSpec::first_output_v()).
[[nodiscard]] std::unique_ptr<hal::SimBackend> make_sim_backend(const config::Config& config, double first_output_v);
/// The same with a simulated bench of its own, `bench`, in place of the configured one (plant:
/// stays the controller's model): a bench that is not its datasheet (pneu-sweep --bench-spread).
[[nodiscard]] std::unique_ptr<hal::SimBackend> make_sim_backend(const config::Config& config, double first_output_v,
                                                                const model::PlantParams& bench);

/// Refuses what `config` asks of this build and it left out, before anything is driven or
/// written: the modbus backend (PNEU_WITH_MODBUS), the GPIO lines (PNEU_WITH_GPIOD). Throws
/// config::ConfigError naming the key.
void require_built(const config::Config& config);

/// The backend `config` describes: the sim or the modbus backend, inside the GPIO decorator with
/// the lines of hal.gpio when enabled; opened when the run starts. Calls require_built() first.
/// Throws std::runtime_error when the register map or the GPIO lines cannot be had.
/// The sim backend starts at equilibrium under `first_output_v` (make_sim_backend()).
[[nodiscard]] std::unique_ptr<hal::Backend> make_backend(const config::Config& config, double first_output_v);

}  // namespace pneu::backends
