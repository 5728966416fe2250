// The supervisor: the checks that latch a fault (docs/architecture.md, "Faults and the safe state").
// One call per tick with what the tick read and did; it answers with the first fault cause found,
// or none. Pure logic and real-time safe (no allocation, no throw), tested on synthetic frames.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "pneu/controller/supervisor_params.hpp"
#include "pneu/controller/loop_params.hpp"
#include "pneu/hal/types.hpp"

namespace pneu::controller {

/// Why the loop latched a fault. Stable numbers: they travel in event_t and health_t.
enum class FaultCause : std::uint8_t {
  kNone = 0,
  kEStop = 1,            ///< the e-stop input is pressed (or could not be read)
  kComms = 2,            ///< samples stale, lost or unreadable for comms_fault_after_s
  kSensorRange = 3,      ///< a reading outside its plausible range or its converter's range
  kSensorNonFinite = 4,  ///< a reading is NaN or infinite
  kSensorFrozen = 5,     ///< a pressure reading unchanged bit for bit for frozen_after_s
  kSensorJump = 6,       ///< the position moved faster than max_speed_m_per_s allows
  kSoftLimit = 7,        ///< armed, the position left the soft limits
  kFollowingError = 8,   ///< armed, |y_d - y| above the window for longer than its limit
  kOverrun = 9,          ///< overruns in a row, or one tick interval beyond its limit
  kCommandTimeout = 10,  ///< armed, the set-point stream fell silent
  kOscillation = 11,     ///< armed, the loop does not settle: the error swings from side to side
  kNotSettled = 12,      ///< armed, no rest within settle_time_s of a set-point change
  /// another controller's health heard on this one's channels (LoopOutputs::external_fault, set by
  /// the service thread while it hears it)
  kAnotherController = 13,
  /// the movement test at the first ARM of a run started disarmed found the wiring wrong
  /// (controller.movement_test; LoopEvent::movement_test names the finding)
  kMovementTest = 14,
};
/// How many causes there are, kNone included.
inline constexpr std::size_t kFaultCauseCount = 15;

/// The cause's stable number, as it travels in event_t and health_t.
[[nodiscard]] constexpr std::uint8_t fault_number(FaultCause cause) noexcept {
  return static_cast<std::uint8_t>(cause);
}

/// A short name and a sentence for people (static strings; "unknown" and "fault" for a number
/// that is no cause).
[[nodiscard]] const char* fault_name(FaultCause cause) noexcept;
[[nodiscard]] const char* fault_text(FaultCause cause) noexcept;
/// What raising (or turning off) the supervisor key `key` would cost, for a message that names the
/// key that latched a fault (static strings; a generic sentence for a key it does not know).
[[nodiscard]] const char* relaxing_costs(const char* key) noexcept;

/// What one tick hands the supervisor.
struct SupervisedTick {
  double t_s = 0.0;                  ///< the tick's loop time [s]
  hal::Status status = hal::Status::kOk;  ///< the backend read's status
  const hal::SensorFrame* frame = nullptr;
  bool armed = false;
  double y_d_m = 0.0;                ///< the set point in force
  double last_setpoint_t_s = 0.0;    ///< loop time of the last set point received (or of arming)
  /// The stop detector holds the carriage at rest (as of the last good sample before this tick).
  bool at_rest = true;
};

class Supervisor {
 public:
  explicit Supervisor(const LoopParams& params);

  /// Forgets the history (at start-up), at loop time `t_s`.
  void reset(double t_s) noexcept;
  /// Re-arming: the following-error timer, the oscillation count and the settle timer start
  /// afresh (arming sets the set point: the carriage must settle from then on).
  void on_arm() noexcept;
  /// Tells the supervisor whether the tick just finished overran its deadline (real clock).
  void note_overrun(bool overran) noexcept;

  /// Checks one tick; returns the first cause found (FaultCause::kNone: all well). The same as
  /// check_sample() then check_motion() on the same tick.
  [[nodiscard]] FaultCause check(const SupervisedTick& tick) noexcept;
  /// What the sample says: the e-stop, the readings (finite, in range, no jump, not frozen), comms.
  [[nodiscard]] FaultCause check_sample(const SupervisedTick& tick) noexcept;
  /// What the loop does with it, once this tick's commands and set point are in force: soft
  /// limits, following error, settling (oscillation, settle time), timing, the set-point stream.
  [[nodiscard]] FaultCause check_motion(const SupervisedTick& tick) noexcept;

  /// The config key of the rule that found the cause the last check_sample() or check_motion()
  /// returned (a static string), or nullptr when none did or no key decides it (the e-stop, a
  /// reading that is not a number).
  [[nodiscard]] const char* decided_by() const noexcept { return decided_by_; }
  /// Whether this tick's sample was good (read ok, every reading valid, finite and plausible):
  /// only good samples may reach the differentiator and the stop detector.
  [[nodiscard]] bool sample_good() const noexcept { return sample_good_; }
  /// Whether a cause that a reset cannot clear is present now: the e-stop pressed, a bad sample,
  /// a frozen pressure. (A jump, a following error, an overrun are events: once latched, a reset
  /// clears them, and they latch again if they happen again.)
  [[nodiscard]] bool cause_present() const noexcept { return estop_ || !sample_good_ || frozen_; }
  /// The cause a reset would meet now (FaultCause::kNone: none).
  [[nodiscard]] FaultCause present_cause() const noexcept {
    return estop_ ? FaultCause::kEStop : !sample_good_ ? sample_cause_ : frozen_ ? FaultCause::kSensorFrozen : FaultCause::kNone;
  }

 private:
  [[nodiscard]] FaultCause check_reading(const hal::SensorFrame& f) noexcept;
  /// Armed, with a good sample: whether the loop fails to settle, and by which rule
  /// (FaultCause::kOscillation or kNotSettled; kNone when it does not fail).
  [[nodiscard]] FaultCause not_settling(const SupervisedTick& tick) noexcept;
  void forget_settling() noexcept;

  const SupervisorConfig cfg_;
  const double period_s_;
  const double comms_fault_after_s_;
  const double soft_min_m_, soft_max_m_;
  const double stream_timeout_s_;
  bool estop_ = false;
  bool frozen_ = false;                   // a pressure reading is frozen now
  bool sample_good_ = true;
  const char* decided_by_ = nullptr;
  const char* reading_key_ = nullptr;     // the rule check_reading() found a reading out by
  FaultCause sample_cause_ = FaultCause::kNone;  // why the last sample was not good
  double bad_since_s_ = -1.0;           // first tick of the current run of bad reads
  bool have_last_y_ = false;
  double last_y_m_ = 0.0;
  double last_y_earliest_t_s_ = 0.0;  // the earliest the last good position may have been read
  double last_p_p_pa_ = 0.0, last_p_n_pa_ = 0.0;
  double p_p_changed_s_ = 0.0, p_n_changed_s_ = 0.0;
  double following_since_s_ = -1.0;
  // Settling. The set point of the last armed tick (NaN: none yet, or re-armed).
  double last_y_d_m_ = 0.0;
  // Oscillation: the side of the error band the error was last seen beyond (+1, -1; 0: not yet),
  // and the times of the last sign changes (a ring of kMaxOscillationSignChanges).
  int error_side_ = 0;
  std::array<double, SupervisorConfig::kMaxOscillationSignChanges> sign_change_t_s_{};
  std::uint64_t sign_changes_ = 0;
  // Settle time: the last set-point change, whether a rest began since, and the last tick's rest.
  double settle_since_s_ = -1.0;  // -1: settled, or not armed
  bool was_at_rest_ = true;
  double last_tick_t_s_ = -1.0;
  std::uint32_t overruns_in_a_row_ = 0;
  bool overrun_fault_ = false;
};

}  // namespace pneu::controller
