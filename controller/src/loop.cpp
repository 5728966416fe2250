#include "pneu/controller/loop.hpp"

#include <cmath>

namespace pneu::controller {

namespace {
// A carriage within this distance of an end stop is pressed against it [m].
constexpr double kEndStopTolerance_m = 1.0e-4;
}  // namespace

ControlLoop::ControlLoop(const config::Config& config, hal::Backend& backend, LoopOutputs& outputs)
    : config_(config),
      backend_(backend),
      out_(outputs),
      schedule_(config.controller.schedule),
      law_(config.controller.law),
      differentiator_(config.controller.differentiator, config.controller.period_s()),
      detector_(config.controller.stop_detector, config.controller.period_s()),
      half_stroke_m_(config.plant.geometry.half_stroke_m()),
      area_p_m2_(config.plant.geometry.area_p_m2()),
      area_n_m2_(config.plant.geometry.area_n_m2()),
      area_rod_m2_(config.plant.geometry.area_rod_m2()),
      p_e_pa_(config.plant.gas.exhaust_pressure_pa) {}

double ControlLoop::setpoint_at(double t_s) const noexcept {
  double y_d = config_.controller.initial_setpoint_m;
  for (const auto& s : schedule_) {
    if (s.t_s > t_s) break;
    y_d = s.position_m;
  }
  return y_d;
}

void ControlLoop::start(double t0_s) {
  backend_.open(t0_s);
  seq_ = 0;
  next_step_ = 0;
  stops_ = 0;
  y_d_m_ = config_.controller.initial_setpoint_m;
  hal::SensorFrame frame;
  (void)backend_.read(t0_s, frame);
  differentiator_.reset(frame.y_m);
  detector_.reset_at_rest(t0_s, frame.y_m);
  y_d_at_stop_m_ = y_d_m_;
}

void ControlLoop::push(const LoopEvent& e) noexcept {
  if (!out_.events.try_push(e)) ++out_.events_dropped;
}

void ControlLoop::tick(double t_s) noexcept {
  hal::SensorFrame frame;
  (void)backend_.read(t_s, frame);  // status and validity go to the supervisor (issue 6)

  while (next_step_ < schedule_.size() && schedule_[next_step_].t_s <= t_s + 1e-9)
    y_d_m_ = schedule_[next_step_++].position_m;

  differentiator_.update(frame.y_m);
  const double v_hat = differentiator_.velocity_m_per_s();
  const double a_hat = differentiator_.acceleration_m_per_s2();
  const double u = law_.control_v(y_d_m_, frame.y_m, v_hat, a_hat);
  (void)backend_.write(hal::ActuatorCommand::from_control(u, true));

  const double force = area_p_m2_ * frame.p_p_pa - area_n_m2_ * frame.p_n_pa - area_rod_m2_ * p_e_pa_;
  switch (detector_.update(t_s, frame.y_m)) {
    case StopDetectorEvent::kStop: {
      LoopEvent e;
      e.kind = LoopEvent::Kind::kStop;
      e.stop_index = ++stops_;
      e.t_s = detector_.event_time_s();
      e.y_m = detector_.event_position_m();
      e.force_n = force;
      e.y_d_m = y_d_m_;
      e.snapshot.t_s = t_s;
      e.snapshot.y_m = e.y_m;
      e.snapshot.p_p_pa = frame.p_p_pa;
      e.snapshot.p_n_pa = frame.p_n_pa;
      e.snapshot.u_v = law_.resting_control_v(y_d_m_, e.y_m);
      e.snapshot.blocked_direction = e.y_m >= half_stroke_m_ - kEndStopTolerance_m    ? +1
                                     : e.y_m <= -half_stroke_m_ + kEndStopTolerance_m ? -1
                                                                                      : 0;
      y_d_at_stop_m_ = y_d_m_;
      push(e);
      break;
    }
    case StopDetectorEvent::kStart: {
      LoopEvent e;
      e.kind = LoopEvent::Kind::kStart;
      e.stop_index = stops_;
      e.t_s = detector_.event_time_s();
      e.y_m = detector_.event_position_m();
      e.force_n = force;
      e.y_d_m = y_d_m_;
      e.restart = stops_ > 0 && y_d_m_ == y_d_at_stop_m_;
      e.direction = frame.y_m > e.y_m ? +1 : -1;
      push(e);
      break;
    }
    case StopDetectorEvent::kNone: break;
  }

  TickRecord r;
  r.seq = seq_++;
  r.t_s = t_s;
  r.y_d_m = y_d_m_;
  r.y_m = frame.y_m;
  r.v_hat_m_per_s = v_hat;
  r.a_hat_m_per_s2 = a_hat;
  r.p_p_pa = frame.p_p_pa;
  r.p_n_pa = frame.p_n_pa;
  r.force_n = force;
  r.u_v = u;
  r.stuck = detector_.stopped();
  r.sensor_validity = frame.validity;
  if (!out_.ticks.try_push(r)) ++out_.ticks_dropped;
}

void ControlLoop::stop() noexcept {
  (void)backend_.write(hal::ActuatorCommand::from_control(config_.controller.law.offset_v, true));
}

}  // namespace pneu::controller
