// The `sim` backend: the sim_plant model in the same process, integrated between ticks with the
// last command held (zero-order hold), sensors read through the sensor models.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "pneu/hal/backend.hpp"
#include "pneu/sim_plant/plant.hpp"
#include "pneu/sim_plant/sensors.hpp"

namespace pneu::hal {

class SimBackend final : public Backend {
 public:
  /// The plant starts at rest at `initial_position_m` at complete equilibrium for `initial_u_v`.
  /// `pushes` (hal.sim.pushes): external forces on the carriage, on the loop's time.
  SimBackend(const model::PlantParams& plant, const model::SensorParams& sensors,
             double initial_position_m, double initial_u_v, std::span<const model::Push> pushes = {});

  void open(double t0_s) override;
  void close() noexcept override {}
  /// Integrates the plant from its current time to `t_s` with the held command (and each push from
  /// its own start to its own end), then samples the sensors. Real-time safe.
  [[nodiscard]] Status read(double t_s, SensorFrame& frame) noexcept override;
  [[nodiscard]] Status write(const ActuatorCommand& command) noexcept override;

  /// The simulated truth, for tests and what-if runs.
  [[nodiscard]] const plant::Plant& plant() const noexcept { return plant_; }
  [[nodiscard]] const ActuatorCommand& held_command() const noexcept { return command_; }
  /// The plant's changes between rest and motion since open(), in order: breakaways (the true
  /// restarts, however small the motion that follows: the stop detector sees a start only beyond
  /// its motion band), sticks and end stops. The plant starts at rest. Up to kMaxMotionEvents are
  /// kept (room reserved up front: recording never allocates); more are counted.
  [[nodiscard]] std::span<const plant::PlantEvent> motion_events() const noexcept { return motion_events_; }
  [[nodiscard]] std::uint64_t motion_events_dropped() const noexcept { return motion_events_dropped_; }
  static constexpr std::size_t kMaxMotionEvents = 8192;

 private:
  plant::Plant plant_;
  plant::SensorSuite sensors_;
  double initial_position_m_;
  double initial_u_v_;
  ActuatorCommand command_;
  std::vector<model::Push> pushes_;
  std::vector<plant::PlantEvent> motion_events_;
  std::uint64_t motion_events_dropped_ = 0;
};

}  // namespace pneu::hal
