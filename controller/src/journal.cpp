#include "pneu/controller/journal.hpp"


#if __has_include(<systemd/sd-daemon.h>)
#include <systemd/sd-daemon.h>  // the macros only: nothing of libsystemd is linked here
#else
#define SD_ERR "<3>"
#define SD_WARNING "<4>"
#define SD_NOTICE "<5>"
#define SD_INFO "<6>"
#endif

#include "pneu/controller/supervisor.hpp"
#include "pneu/config/text.hpp"
#include "pneu/hal/types.hpp"

namespace pneu::controller {

namespace {

const char* prefix(Priority p) noexcept {
  switch (p) {
    case Priority::kErr: return SD_ERR;
    case Priority::kWarning: return SD_WARNING;
    case Priority::kNotice: return SD_NOTICE;
    case Priority::kInfo: return SD_INFO;
  }
  return SD_INFO;
}

}  // namespace

void journal_line(std::FILE* out, Priority priority, std::string_view text) {
  std::fprintf(out, "%spneud: %.*s\n", prefix(priority), static_cast<int>(text.size()), text.data());
  std::fflush(out);
}

void JournalLines::line(Priority priority, const char* format, ...) {
  va_list args;
  va_start(args, format);
  const std::string text = text::vformat(format, args);
  va_end(args);
  journal_line(out_, priority, text);
  ++lines_;
}

void JournalLines::on_tick(const TickRecord& r, const ExpectedAtTick& /*expected*/) {
  const bool link_down = (r.sensor_validity & hal::kCommsError) != 0;
  if (link_down && !link_down_) {
    link_down_since_s_ = r.t_s;
    line(Priority::kWarning,
         "link to the device lost at %.3f s: the backend cannot reach it (a comms fault latches once the samples "
         "have been bad for controller.comms_fault_after_s)",
         r.t_s);
  } else if (!link_down && link_down_) {
    line(Priority::kNotice, "link to the device back at %.3f s, after %.3f s", r.t_s, r.t_s - link_down_since_s_);
  }
  link_down_ = link_down;
  // Arming and disarming. A fault and its reset have events of their own (on_event), so has the
  // movement test's end.
  if (seen_tick_) {
    if (mode_ == Mode::kDisarmed && drives(r.mode))
      line(Priority::kNotice, "armed at %.3f s: the law drives the valves, holding %.3f mm", r.t_s, r.y_d_m * 1e3);
    else if (mode_ == Mode::kDisarmed && r.mode == Mode::kMovementTest)
      line(Priority::kNotice,
           "armed at %.3f s: the movement test first (controller.movement_test): open-loop pulses around u_0 check "
           "the wiring before the law drives the valves; set points are refused until it passed",
           r.t_s);
    else if (powered(mode_) && r.mode == Mode::kDisarmed)
      line(Priority::kNotice,
           "disarmed at %.3f s (y = %.3f mm): valve power off, the outputs at the neutral voltage u_0; send ARM to drive",
           r.t_s, r.y_m * 1e3);
  }
  seen_tick_ = true;
  mode_ = r.mode;
}

void JournalLines::on_event(const LoopEvent& e) {
  switch (e.kind) {
    case LoopEvent::Kind::kFault:
      if (e.fault_cause == FaultCause::kMovementTest) {  // the finding, its sentence and the figures
        line(Priority::kErr, "FAULT at %.3f s (y = %.3f mm): %s: %s: %s [%s]; %s", e.t_s, e.y_m * 1e3,
             fault_name(e.fault_cause), movement_finding_name(e.movement_test.finding),
             movement_finding_text(e.movement_test.finding), describe(e.movement_test).c_str(),
             fault_text(e.fault_cause));
        return;
      }
      line(Priority::kErr, "FAULT at %.3f s (y = %.3f mm): %s: %s%s%s", e.t_s, e.y_m * 1e3, fault_name(e.fault_cause),
           fault_text(e.fault_cause), e.fault_key != nullptr ? "; decided by " : "",
           e.fault_key != nullptr ? e.fault_key : "");
      return;
    case LoopEvent::Kind::kMovementTest:
      switch (e.movement_end) {
        case MovementTestEnd::kPassed:
          line(Priority::kNotice, "movement test passed at %.3f s: %s; the law drives the valves, holding %.3f mm",
               e.t_s, describe(e.movement_test).c_str(), e.y_d_m * 1e3);
          return;
        case MovementTestEnd::kFinding: return;  // the fault's line names it
        case MovementTestEnd::kDisarmed:
        case MovementTestEnd::kFault:
        case MovementTestEnd::kStopped:
        case MovementTestEnd::kNone:
          line(Priority::kNotice, "movement test aborted at %.3f s (y = %.3f mm) by %s%s: the next ARM runs it again",
               e.t_s, e.y_m * 1e3,
               e.movement_end == MovementTestEnd::kDisarmed ? "a disarm"
               : e.movement_end == MovementTestEnd::kFault  ? "a fault: "
                                                            : "the run's stop",
               e.movement_end == MovementTestEnd::kFault ? fault_name(e.fault_cause) : "");
          return;
      }
      return;
    case LoopEvent::Kind::kFaultReset:
      line(Priority::kNotice, "fault (%s) reset at %.3f s: disarmed, send ARM to drive", fault_name(e.fault_cause),
           e.t_s);
      return;
    case LoopEvent::Kind::kResetRefused:
      line(Priority::kWarning, "fault reset refused at %.3f s: the cause is still present (%s): %s", e.t_s,
           fault_name(e.fault_cause), fault_text(e.fault_cause));
      return;
    case LoopEvent::Kind::kHoldStart:
      if (e.direction == 0)
        line(Priority::kInfo, "hold from %.3f s: at rest at %.3f mm, within the window of the set point %.3f mm",
             e.t_s, e.y_m * 1e3, e.y_d_m * 1e3);
      else
        line(Priority::kInfo, "hold from %.3f s: at rest at %.3f mm, reaching %s for the window of the set point %.3f mm",
             e.t_s, e.y_m * 1e3, e.direction > 0 ? "up" : "down", e.y_d_m * 1e3);
      return;
    case LoopEvent::Kind::kHoldEnd:
      line(Priority::kInfo, "hold ended at %.3f s (y = %.3f mm): %s", e.t_s, e.y_m * 1e3, hold_end_name(e.hold_end));
      return;
    case LoopEvent::Kind::kStop:
    case LoopEvent::Kind::kStart:
      return;
  }
}

}  // namespace pneu::controller
