// The movement test before closed loop (controller.movement_test), as an axis controller runs one
// before it enables its position loop: two small open-loop pulses around u_0, each ended once the
// carriage moved controller.movement_test.travel_m (or after pulse_s), then the pulse reversed
// until the carriage goes no further (the pressures that broke it away would carry it on), then
// u_0 for rest_s. A first pulse that did not move the carriage the right way is the last. From what the sensors did it judges the wiring: +u (valve P opening to
// the supply, valve N to the exhaust, docs/model.md) must move the carriage towards +y, raise p_P
// and lower p_N, and each reading must change by more than its noise. The state machine is pure
// logic and real-time safe (no allocation, no throw): run_movement_test() paces it on a backend
// before the loop's time starts (pneud starting armed), and the loop steps it tick by tick at the
// first ARM of a run that started disarmed (ControlLoop, Mode::kMovementTest).
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

#include "pneu/controller/movement_test_params.hpp"
#include "pneu/hal/backend.hpp"

namespace pneu::config {
struct Config;
}

namespace pneu::controller {

struct LoopSettings;  // loop_params.hpp
class Clock;  // clock.hpp (which includes loop.hpp, which holds a MovementTest)

/// What the movement test found.
enum class MovementFinding : std::uint8_t {
  kPassed = 0,
  kTubesSwapped,            ///< +u moved the carriage towards -y, lowered p_P and raised p_N
  kPressureSensorsSwapped,  ///< +u moved it towards +y, but p_P fell and p_N rose
  kPositionReversed,        ///< the pressures answered +u rightly, the position reading went -y
  kPositionNotResponding,   ///< the pressures changed, the position reading did not
  kPressurePDead,           ///< the p_P reading did not change
  kPressureNDead,           ///< the p_N reading did not change
  kNoResponse,              ///< no reading changed: valve power, the supply or the outputs
  kInconsistent,            ///< the readings answered, but in no pattern of a wiring fault
  kInvalidReading,          ///< a reading was invalid (out of range, non-finite) during the test
  kEStop,                   ///< the e-stop was pressed
  kComms,                   ///< no good sample for longer than controller.comms_fault_after_s
  kInterrupted,             ///< a stop was requested (SIGTERM, SIGINT) during the test
};
/// A short name ("tubes-swapped") and a sentence for people (static strings).
[[nodiscard]] const char* movement_finding_name(MovementFinding f) noexcept;
[[nodiscard]] const char* movement_finding_text(MovementFinding f) noexcept;

/// How one pulse went: its voltage relative to u_0, how long it drove, the position change at its
/// end, and the largest rise and fall of each pressure reading from the pulse's start.
struct MovementPulse {
  double du_v = 0.0;
  double duration_s = 0.0;
  double moved_m = 0.0;
  double p_p_rise_pa = 0.0, p_p_fall_pa = 0.0;
  double p_n_rise_pa = 0.0, p_n_fall_pa = 0.0;
};

struct MovementTestResult {
  MovementFinding finding = MovementFinding::kPassed;
  int pulses = 0;               ///< pulses completed (0 to 2)
  MovementPulse pulse[2];
  double duration_s = 0.0;      ///< the test's length [s]
  double y_start_m = 0.0;       ///< the position read when it started [m]
  double y_end_m = 0.0;         ///< ... when it ended [m]
  [[nodiscard]] bool passed() const noexcept { return finding == MovementFinding::kPassed; }
};

/// One line for people: the finding, its sentence and the pulses' figures. Not real-time.
[[nodiscard]] std::string describe(const MovementTestResult& r);

/// What the test needs to know of the bench besides controller.movement_test.
struct MovementTestBench {
  double u_0_v = 0.0;                 ///< the neutral voltage (controller.law.offset_v, resolved) [V]
  double comms_fault_after_s = 0.05;  ///< this long without a good sample ends the test [s]
  double soft_min_m = -0.24, soft_max_m = 0.24;  ///< a pulse ends beyond them [m]
  /// `config`'s (its offset resolved), with the loop's period as the least comms limit.
  [[nodiscard]] static MovementTestBench of(const config::Config& config) noexcept;
  /// ... from what the loop holds of controller.* (LoopParams).
  [[nodiscard]] static MovementTestBench of(const LoopSettings& controller) noexcept;
};

/// The test's state machine: one step() per tick with the tick's sample; it answers with the
/// command to write (valve power on while it runs; off, at u_0, once done).
class MovementTest {
 public:
  MovementTest(const MovementTestConfig& cfg, const MovementTestBench& bench) noexcept;

  [[nodiscard]] hal::ActuatorCommand step(double t_s, hal::Status status, const hal::SensorFrame& frame) noexcept;
  /// Ends the test (a stop was requested).
  void interrupt() noexcept { finish(MovementFinding::kInterrupted); }
  [[nodiscard]] bool done() const noexcept { return phase_ == Phase::kDone; }
  [[nodiscard]] const MovementTestResult& result() const noexcept { return result_; }

 private:
  enum class Phase : std::uint8_t { kStart, kPulse, kBrake, kRest, kDone };
  static constexpr double kBrakeStill_s = 0.01;  // braking ends once the carriage went no further this long
  void finish(MovementFinding f) noexcept;
  void start_pulse(double t_s, const hal::SensorFrame& f) noexcept;
  [[nodiscard]] MovementFinding judge() const noexcept;

  MovementTestConfig cfg_;
  MovementTestBench bench_;
  Phase phase_ = Phase::kStart;
  MovementTestResult result_;
  double t_start_s_ = 0.0, t_phase_s_ = 0.0, last_good_s_ = 0.0;
  bool started_ = false, have_good_ = false;
  int sign_ = +1;  // the pulse in force: u = u_0 + sign * pulse_v
  double y0_m_ = 0.0, p_p0_pa_ = 0.0, p_n0_pa_ = 0.0, y_m_ = 0.0;
  bool moved_right_ = false;                 // the last pulse moved the carriage the way +u -> +y says
  int brake_sign_ = +1;                      // the way the carriage went in the pulse
  double best_m_ = 0.0, t_best_s_ = 0.0;     // braking: the furthest it went that way, and when
};

/// Runs `test` on `backend` (already open) at `period_s` on `clock`, from now until it is done or
/// `stop_requested`, skipping deadlines passed after an overrun; the last command written is u_0
/// with valve power off. Real-time safe.
MovementTestResult run_movement_test(hal::Backend& backend, Clock& clock, double period_s, MovementTest& test,
                                     const std::atomic<bool>& stop_requested) noexcept;

}  // namespace pneu::controller
