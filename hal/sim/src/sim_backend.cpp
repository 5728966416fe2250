#include "pneu/hal/sim_backend.hpp"

namespace pneu::hal {

SimBackend::SimBackend(const model::PlantParams& plant, const model::SensorParams& sensors,
                       double initial_position_m, double initial_u_v, std::span<const model::Push> pushes)
    : plant_(plant),
      sensors_(sensors),
      initial_position_m_(initial_position_m),
      initial_u_v_(initial_u_v),
      command_(ActuatorCommand::from_control(initial_u_v, true)),
      pushes_(pushes.begin(), pushes.end()) {
  plant_.reset_at_rest(initial_position_m_, initial_u_v_);
  motion_events_.reserve(kMaxMotionEvents);
}

void SimBackend::open(double t0_s) {
  plant_.set_external_force_n(plant::push_force_n(pushes_, t0_s));
  plant_.reset_at_rest(initial_position_m_, initial_u_v_, t0_s);
  command_ = ActuatorCommand::from_control(initial_u_v_, true);
  motion_events_.clear();
  motion_events_dropped_ = 0;
}

Status SimBackend::read(double t_s, SensorFrame& frame) noexcept {
  // The simulated bench has no valve power relay (that is the GPIO decorator's line): the valves
  // see the commanded voltages, the safe ones included.
  plant::step_with_pushes(plant_, t_s, command_.u_p_v, command_.u_n_v, pushes_, [this](auto events) {
    for (const auto& e : events) {
      if (e.kind == plant::PlantEvent::Kind::kReversal) continue;  // sliding on: no change
      if (motion_events_.size() < kMaxMotionEvents) motion_events_.push_back(e);  // within the reserved room
      else ++motion_events_dropped_;
    }
  });
  const auto& s = plant_.state();
  const auto m = sensors_.measure(s.y_m, s.p_p_pa, s.p_n_pa);
  frame = SensorFrame{t_s, m.y_m, m.p_p_pa, m.p_n_pa, 0.0, false, true, kSensorsValid, 0.0};
  return Status::kOk;
}

Status SimBackend::write(const ActuatorCommand& command) noexcept {
  command_ = command;
  return Status::kOk;
}

}  // namespace pneu::hal
