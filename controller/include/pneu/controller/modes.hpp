// The loop's modes as one state machine (docs/architecture.md, "The loop's modes"): the modes, the
// events that change them, and the table of every change. ControlLoop::transition() (loop.cpp) is
// the one place that follows the table and does what each change does on the way (the safe output,
// the hold's start and end, the movement test's start and end, arming, the fault latched and reset).
// Pure and real-time safe: value types and constexpr look-ups.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>

namespace pneu::controller {

/// The loop's operating mode.
enum class Mode : std::uint8_t {
  kDisarmed = 0,  ///< valve power off, outputs at the neutral voltage u_0 (F_e(u_0) = 0)
  kArmed = 1,     ///< valve power on, the control law drives the valves
  kFault = 2,     ///< latched by the supervisor: valve power off, the configured safe output,
                  ///< until a reset received once the cause is gone (then disarmed)
  kHold = 3,      ///< armed, the carriage at rest within controller.hold.window_m of its set point:
                  ///< the loop drives the pressure force into the stiction band instead of Eq. 4
  kMovementTest = 4,  ///< armed, the movement test first (the first ARM of a run started disarmed
                      ///< on a real backend, LoopParams::movement_test_at_arm): valve power on, the
                      ///< test's open-loop pulses drive the valves; set points are refused. A pass
                      ///< arms (kArmed, holding where the carriage is), a finding latches a fault.
};
/// How many modes there are.
inline constexpr std::size_t kModeCount = 5;

/// Valve power on and the loop driving the valves: armed, or holding.
[[nodiscard]] constexpr bool drives(Mode m) noexcept { return m == Mode::kArmed || m == Mode::kHold; }
/// Valve power on: the loop drives the valves, or the movement test pulses them. DISARM ends either.
[[nodiscard]] constexpr bool powered(Mode m) noexcept { return drives(m) || m == Mode::kMovementTest; }
/// Whether a set point (or a step of it) takes effect: not in a fault (one queued before it is
/// stale), not during the movement test (its pass holds where the carriage is).
[[nodiscard]] constexpr bool takes_set_points(Mode m) noexcept {
  return m != Mode::kFault && m != Mode::kMovementTest;
}

/// What changes the loop's mode: the events its state machine takes, each raised by the tick where
/// it sees it (ControlLoop::tick; the run's stop by ControlLoop::stop).
enum class ModeEvent : std::uint8_t {
  kArm = 0,           ///< an ARM command, the movement test not due
  kArmTestDue,        ///< an ARM command with the movement test at ARM due (not passed in this run)
  kDisarm,            ///< a DISARM command
  kFault,             ///< a fault cause: the supervisor's, the service side's, the movement test's finding
  kReset,             ///< a FAULT_RESET command, the cause gone
  kResetRefused,      ///< a FAULT_RESET command while the cause is still present
  kTestPassed,        ///< the movement test passed
  kHoldStart,         ///< at rest within controller.hold.window_m (or reach_m) of the set point, away
                      ///< from the end stops, controller.hold.enabled
  kHoldEnd,           ///< holding: the set point changed, the reading left the window, the carriage moved
  kRunStops,          ///< the run stops (SIGTERM, SIGINT, the end of its duration)
};
/// How many events there are.
inline constexpr std::size_t kModeEventCount = 10;

/// One change of mode: in mode `from`, `event` leads to mode `to`.
struct ModeTransition {
  Mode from;
  ModeEvent event;
  Mode to;
};

/// Every change of the loop's mode. An event in a mode not listed with it changes nothing and does
/// nothing (an ARM while armed, a DISARM or a fault in a fault, a reset when there is no fault).
/// ControlLoop::transition() says what each does on the way.
inline constexpr std::array<ModeTransition, 15> kModeTransitions{{
    // from                event                       to
    {Mode::kDisarmed,      ModeEvent::kArm,            Mode::kArmed},         // holding where the carriage is
    {Mode::kDisarmed,      ModeEvent::kArmTestDue,     Mode::kMovementTest},  // the test's pulses, valve power on
    {Mode::kMovementTest,  ModeEvent::kTestPassed,     Mode::kArmed},         // as an ARM arms; not due again
    {Mode::kArmed,         ModeEvent::kHoldStart,      Mode::kHold},          // hold_start (reaching or within)
    {Mode::kHold,          ModeEvent::kHoldEnd,        Mode::kArmed},         // hold_end: why
    {Mode::kArmed,         ModeEvent::kDisarm,         Mode::kDisarmed},
    {Mode::kHold,          ModeEvent::kDisarm,         Mode::kDisarmed},      // hold_end: disarmed
    {Mode::kMovementTest,  ModeEvent::kDisarm,         Mode::kDisarmed},      // the test aborted: disarmed
    {Mode::kMovementTest,  ModeEvent::kRunStops,       Mode::kDisarmed},      // the test aborted: stopped
    {Mode::kDisarmed,      ModeEvent::kFault,          Mode::kFault},         // the safe output, latched
    {Mode::kArmed,         ModeEvent::kFault,          Mode::kFault},
    {Mode::kHold,          ModeEvent::kFault,          Mode::kFault},         // hold_end: fault, first
    {Mode::kMovementTest,  ModeEvent::kFault,          Mode::kFault},         // the test's end (finding, or aborted), first
    {Mode::kFault,         ModeEvent::kReset,          Mode::kDisarmed},      // fault_reset
    {Mode::kFault,         ModeEvent::kResetRefused,   Mode::kFault},         // fault_reset_refused: the cause
}};

/// The mode after `event` in mode `from` (kModeTransitions), or none: the event means nothing there.
[[nodiscard]] constexpr std::optional<Mode> next_mode(Mode from, ModeEvent event) noexcept {
  for (const ModeTransition& t : kModeTransitions)
    if (t.from == from && t.event == event) return t.to;
  return std::nullopt;
}

}  // namespace pneu::controller
