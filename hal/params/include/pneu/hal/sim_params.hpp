// The parameters of the simulated bench: what it is (hal.sim: its plant when it is not the
// controller's model, the pushes on its carriage), used by the sim backend in process (hal/sim)
// and by pneu-plant serve and simulate; and where it starts (simulation).
#pragma once

#include <cmath>
#include <vector>

#include "pneu/config/describe.hpp"
#include "pneu/model/params.hpp"

namespace pneu::hal {

/// hal.sim: the simulated bench (in process, and pneu-plant serve and simulate).
struct SimBenchConfig {
  /// hal.sim.plant present: the simulated bench is not the controller's model. Any subset of
  /// plant:'s keys, each over plant:'s value.
  bool has_plant = false;
  model::PlantParams plant;  ///< the bench: plant: with hal.sim.plant's keys over it
  /// hal.sim.pushes: external forces on the carriage (the simulated bench's disturbance input), on
  /// the loop's time in process, on pneu-plant serve's own (from its start) over Modbus.
  std::vector<model::Push> pushes;
};

/// simulation: where the simulated bench starts (in process, pneu-plant serve and simulate).
struct SimulationConfig {
  double initial_position_m = 0.2195;  ///< simulation.initial_position_m: rest position at t = 0 [m], inside the stroke
};

}  // namespace pneu::hal

// Their keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp
// reads the whole configuration with it; plant:'s keys, which hal.sim.plant takes, are described
// there).
namespace pneu::config::schema {

using hal::SimBenchConfig;
using hal::SimulationConfig;

/// One of hal.sim.pushes.
void describe(auto& a, Like<model::Push> auto& p) {
  a.field(PNEU_NVP(p, t_s), Range::non_negative(), "it starts [s]");
  a.field(PNEU_NVP(p, force_n), Range::any(), "towards +y while it lasts [N]");
  a.field(PNEU_NVP(p, duration_s), Range::positive(), "it lasts [s]");
}

// hal.sim.plant: any subset of plant:'s keys (the loader lays them over plant:'s before reading);
// written whole.
void describe(auto& a, Like<SimBenchConfig> auto& s) {
  a.optional_section(optional(PNEU_NVP(s, plant)), s.has_plant);
  a.list(optional(PNEU_NVP(s, pushes)));
}

void describe(auto& a, Like<SimulationConfig> auto& s, const model::Geometry& geometry) {
  const double half = geometry.half_stroke_m();
  a.field(PNEU_NVP(s, initial_position_m), Range::any(), "rest position at t = 0 [m], inside the stroke");
  a.check("initial_position_m", std::abs(s.initial_position_m) <= half,
          [&] { return outside_the_stroke(half, s.initial_position_m); });
}

}  // namespace pneu::config::schema
