// The supervisor: the checks that latch a fault (docs/architecture.md, "Faults and the safe state").
// One call per tick with what the tick read and did; it answers with the first fault cause found,
// or none. Pure logic and real-time safe (no allocation, no throw), tested on synthetic frames.
#pragma once

#include <cstdint>

#include "pneu/config/config.hpp"
#include "pneu/hal/types.hpp"

namespace pneu::controller {

/// Why the loop latched a fault. Stable numbers: they travel in event_t and health_t.
enum FaultCause : std::uint8_t {
  kFaultNone = 0,
  kFaultEStop = 1,            ///< the e-stop input is pressed (or could not be read)
  kFaultComms = 2,            ///< samples stale, lost or unreadable for comms_fault_after_s
  kFaultSensorRange = 3,      ///< a reading outside its plausible range or its converter's range
  kFaultSensorNonFinite = 4,  ///< a reading is NaN or infinite
  kFaultSensorFrozen = 5,     ///< a pressure reading unchanged bit for bit for frozen_after_s
  kFaultSensorJump = 6,       ///< the position moved faster than max_speed_m_per_s allows
  kFaultSoftLimit = 7,        ///< armed, the position left the soft limits
  kFaultFollowingError = 8,   ///< armed, |y_d - y| above the window for longer than its limit
  kFaultOverrun = 9,          ///< overruns in a row, or one tick interval beyond its limit
  kFaultCommandTimeout = 10,  ///< armed, the set-point stream fell silent
};
inline constexpr std::uint8_t kFaultCauseCount = 11;

/// A short name and a sentence for people (static strings).
[[nodiscard]] const char* fault_name(std::uint8_t cause) noexcept;
[[nodiscard]] const char* fault_text(std::uint8_t cause) noexcept;

/// What one tick hands the supervisor.
struct SupervisedTick {
  double t_s = 0.0;                  ///< the tick's loop time [s]
  hal::Status status = hal::Status::kOk;  ///< the backend read's status
  const hal::SensorFrame* frame = nullptr;
  bool armed = false;
  double y_d_m = 0.0;                ///< the set point in force
  double last_setpoint_t_s = 0.0;    ///< loop time of the last set point received (or of arming)
};

class Supervisor {
 public:
  explicit Supervisor(const config::Config& config);

  /// Forgets the history (at start-up), at loop time `t_s`.
  void reset(double t_s) noexcept;
  /// Re-arming: the following-error timer starts afresh.
  void on_arm() noexcept { following_since_s_ = -1.0; }
  /// Tells the supervisor whether the tick just finished overran its deadline (real clock).
  void note_overrun(bool overran) noexcept;

  /// Checks one tick; returns the first cause found (kFaultNone: all well). The same as
  /// check_sample() then check_motion() on the same tick.
  [[nodiscard]] FaultCause check(const SupervisedTick& tick) noexcept;
  /// What the sample says: the e-stop, the readings (finite, in range, no jump, not frozen), comms.
  [[nodiscard]] FaultCause check_sample(const SupervisedTick& tick) noexcept;
  /// What the loop does with it, once this tick's commands and set point are in force: soft
  /// limits, following error, timing, the set-point stream.
  [[nodiscard]] FaultCause check_motion(const SupervisedTick& tick) noexcept;

  /// Whether this tick's sample was good (read ok, every reading valid, finite and plausible):
  /// only good samples may reach the differentiator and the stop detector.
  [[nodiscard]] bool sample_good() const noexcept { return sample_good_; }
  /// Whether a cause that a reset cannot clear is present now: the e-stop pressed, a bad sample,
  /// a frozen pressure. (A jump, a following error, an overrun are events: once latched, a reset
  /// clears them, and they latch again if they happen again.)
  [[nodiscard]] bool cause_present() const noexcept { return estop_ || !sample_good_ || frozen_; }
  /// The cause a reset would meet now (kFaultNone: none).
  [[nodiscard]] FaultCause present_cause() const noexcept {
    return estop_ ? kFaultEStop : !sample_good_ ? sample_cause_ : frozen_ ? kFaultSensorFrozen : kFaultNone;
  }

 private:
  [[nodiscard]] FaultCause check_reading(const hal::SensorFrame& f) noexcept;

  const config::SupervisorConfig cfg_;
  const double period_s_;
  const double comms_fault_after_s_;
  const double soft_min_m_, soft_max_m_;
  const double stream_timeout_s_;
  bool estop_ = false;
  bool frozen_ = false;                   // a pressure reading is frozen now
  bool sample_good_ = true;
  FaultCause sample_cause_ = kFaultNone;  // why the last sample was not good
  double bad_since_s_ = -1.0;           // first tick of the current run of bad reads
  bool have_last_y_ = false;
  double last_y_m_ = 0.0, last_y_t_s_ = 0.0;
  double last_p_p_pa_ = 0.0, last_p_n_pa_ = 0.0;
  double p_p_changed_s_ = 0.0, p_n_changed_s_ = 0.0;
  double following_since_s_ = -1.0;
  double last_tick_t_s_ = -1.0;
  std::uint32_t overruns_in_a_row_ = 0;
  bool overrun_fault_ = false;
};

}  // namespace pneu::controller
