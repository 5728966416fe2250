// One tick of the controller: read the sensors, differentiate, control (Eq. 4), detect stops and
// starts, write the valves, hand the tick's record and events to the non-real-time side.
#pragma once

#include <cstdint>
#include <span>

#include "pneu/config/config.hpp"
#include "pneu/controller/control_law.hpp"
#include "pneu/controller/differentiator.hpp"
#include "pneu/controller/predictor.hpp"
#include "pneu/controller/spsc_queue.hpp"
#include "pneu/controller/stop_detector.hpp"
#include "pneu/hal/backend.hpp"

namespace pneu::controller {

/// Everything one tick computed: the per-tick telemetry record.
struct TickRecord {
  std::uint64_t seq = 0;       ///< tick sequence number, from 0, no gaps
  double t_s = 0.0;            ///< loop time of the sample [s]
  double y_d_m = 0.0;          ///< set point [m]
  double y_m = 0.0;            ///< measured position [m]
  double v_hat_m_per_s = 0.0;  ///< estimated velocity [m/s]
  double a_hat_m_per_s2 = 0.0; ///< estimated acceleration [m/s^2]
  double p_p_pa = 0.0;         ///< measured chamber P pressure [Pa]
  double p_n_pa = 0.0;         ///< measured chamber N pressure [Pa]
  double force_n = 0.0;        ///< pressure force of Eq. 14 from the measured pressures [N]
  double u_v = 0.0;            ///< control sent: u_P = u, u_N = -u [V]
  bool stuck = false;          ///< the stop detector holds the carriage at rest
  std::uint32_t sensor_validity = 0;  ///< hal::SensorValidity flags of the sample
};

/// A start or stop of the carriage, with the snapshot the predictor needs at a stop.
struct LoopEvent {
  enum class Kind : std::uint8_t { kStop, kStart };
  Kind kind = Kind::kStop;
  std::uint64_t stop_index = 0;  ///< stops are numbered from 1; a start refers to the last stop (0: none)
  double t_s = 0.0;              ///< backdated to the signals (see StopDetector) [s]
  double y_m = 0.0;              ///< stop: the rest position; start: the position it left [m]
  double force_n = 0.0;          ///< stop: F when the stop was confirmed [N]
  double y_d_m = 0.0;            ///< the set point at the event [m]
  bool restart = false;          ///< start: the set point did not change since the stop
  int direction = 0;             ///< start: +1 / -1
  StopSnapshot snapshot;         ///< stop: state at confirmation, u* of Eq. 11
};

/// Where the loop's records go; both queues are drained by the non-real-time side. A full queue
/// drops the record and counts it; the loop never waits.
struct LoopOutputs {
  SpscQueue<TickRecord, 8192> ticks;
  SpscQueue<LoopEvent, 256> events;
  std::uint64_t ticks_dropped = 0;   ///< written by the loop thread only
  std::uint64_t events_dropped = 0;  ///< written by the loop thread only
};

/// The controller's tick. Construct and start() outside the loop; tick() is real-time safe.
class ControlLoop {
 public:
  /// `config.controller.law.offset_v` must already hold u_0 (see resolve_offset()).
  ControlLoop(const config::Config& config, hal::Backend& backend, LoopOutputs& outputs);

  /// Opens the backend at loop time `t0_s` and arms the detector at rest at the first reading.
  void start(double t0_s);
  /// One tick at loop time `t_s`. Real-time safe.
  void tick(double t_s) noexcept;
  /// Drives the configured output for the end of the run (valves held at u_0, power kept).
  void stop() noexcept;

  [[nodiscard]] std::uint64_t ticks() const noexcept { return seq_; }
  [[nodiscard]] double setpoint_at(double t_s) const noexcept;
  [[nodiscard]] const ControlLaw& law() const noexcept { return law_; }

 private:
  void push(const LoopEvent& e) noexcept;

  const config::Config& config_;
  hal::Backend& backend_;
  LoopOutputs& out_;
  std::span<const config::SetpointStep> schedule_;
  ControlLaw law_;
  Differentiator differentiator_;
  StopDetector detector_;
  double half_stroke_m_;
  double area_p_m2_, area_n_m2_, area_rod_m2_, p_e_pa_;
  std::uint64_t seq_ = 0;
  std::size_t next_step_ = 0;
  double y_d_m_ = 0.0;
  std::uint64_t stops_ = 0;
  double y_d_at_stop_m_ = 0.0;
};

}  // namespace pneu::controller
