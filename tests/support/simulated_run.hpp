// A run as pneud assembles it (pneu/assembly/), on the in-process simulated bench, executed on the
// simulated clock: what the end-to-end tests repeat.
#pragma once

#include <atomic>

#include "pneu/assembly/assembled_run.hpp"
#include "pneu/controller/clock.hpp"

namespace pneu::test {

/// The run of `config` (u_0 resolved and the law designed by assembly::RunSpec) on its configured
/// simulated bench.
[[nodiscard]] inline assembly::AssembledRun simulated_run(const config::Config& config) {
  return assembly::AssembledRun::on_simulated_bench(assembly::RunSpec::of(config));
}

/// Executes `run` on the simulated clock to its end, nothing asking it to stop.
inline void execute_simulated(assembly::AssembledRun& run) {
  controller::SimulatedClock clock;
  const std::atomic<bool> never{false};
  run.execute(clock, never);
}

}  // namespace pneu::test
