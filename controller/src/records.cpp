// A loop event as the outside world sees it: the events file's line (its view and members) and
// the event_t message (its kind and its text for people).
#include "pneu/controller/records.hpp"

#include "pneu/controller/movement_test.hpp"
#include "pneu/controller/supervisor.hpp"

namespace pneu::controller {

EventLineOf event_line(const LoopEvent& e) {
  EventLineOf o{&event_lines::kStop, {}};
  EventLine& l = o.line;
  l.t_s = e.t_s;
  l.stop = e.stop_index;
  l.y_m = e.y_m;
  l.force_n = e.force_n;
  l.y_d_m = e.y_d_m;
  switch (e.kind) {
    case LoopEvent::Kind::kStop:
      o.view = &event_lines::kStop;
      break;
    case LoopEvent::Kind::kStart:
      o.view = &event_lines::kStart;
      l.restart = e.restart;
      l.direction = e.direction;
      break;
    case LoopEvent::Kind::kFault:
      o.view = &event_lines::kFault;
      l.cause = fault_name(e.fault_cause);
      l.text = fault_text(e.fault_cause);
      l.key = e.fault_key;
      if (e.fault_cause == FaultCause::kMovementTest) l.finding = movement_finding_name(e.movement_test.finding);
      break;
    case LoopEvent::Kind::kMovementTest:
      o.view = &event_lines::kMovementTest;
      l.end = movement_test_end_name(e.movement_end);
      l.finding = movement_finding_name(e.movement_test.finding);
      l.pulses = e.movement_test.pulses;
      l.duration_s = e.movement_test.duration_s;
      l.y_start_m = e.movement_test.y_start_m;
      l.y_end_m = e.movement_test.y_end_m;
      if (e.movement_end == MovementTestEnd::kFault) l.cause = fault_name(e.fault_cause);
      l.text = describe(e.movement_test);
      break;
    case LoopEvent::Kind::kFaultReset:
    case LoopEvent::Kind::kResetRefused:
      o.view = e.kind == LoopEvent::Kind::kFaultReset ? &event_lines::kFaultReset : &event_lines::kFaultResetRefused;
      l.cause = fault_name(e.fault_cause);
      break;
    case LoopEvent::Kind::kHoldStart:
      o.view = &event_lines::kHoldStart;
      l.reach = e.direction;
      break;
    case LoopEvent::Kind::kHoldEnd:
      o.view = &event_lines::kHoldEnd;
      l.why = hold_end_name(e.hold_end);
      break;
  }
  return o;
}

EventMessage event_message(const LoopEvent& e) {
  EventMessage m;
  m.t_s = e.t_s;
  m.stop = static_cast<std::int64_t>(e.stop_index);
  m.y_m = e.y_m;
  m.force_n = e.force_n;
  m.y_d_m = e.y_d_m;
  m.direction = static_cast<std::int8_t>(e.direction);
  m.seq = 0;
  switch (e.kind) {
    case LoopEvent::Kind::kStop:
      m.kind = event_kind::kStop;
      m.text = "stop";
      break;
    case LoopEvent::Kind::kFaultReset:
      m.kind = event_kind::kFaultReset;
      m.text = std::string("fault (") + fault_name(e.fault_cause) + ") reset: disarmed, send ARM to drive";
      break;
    case LoopEvent::Kind::kResetRefused:
      m.kind = event_kind::kFaultResetRefused;
      m.text = std::string("fault reset refused: the cause is still present (") + fault_name(e.fault_cause) +
               "): " + fault_text(e.fault_cause);
      break;
    case LoopEvent::Kind::kHoldStart:
      m.kind = event_kind::kHoldStart;
      m.text = "hold: at rest within the window, the pressure force driven into the stiction band";
      break;
    case LoopEvent::Kind::kHoldEnd:
      m.kind = event_kind::kHoldEnd;
      m.text = std::string("hold ended: ") + hold_end_name(e.hold_end);
      break;
    case LoopEvent::Kind::kFault:
      m.kind = event_kind::kFault;
      m.text = std::string("fault (") + fault_name(e.fault_cause) + "): " + fault_text(e.fault_cause);
      if (e.fault_cause == FaultCause::kMovementTest)
        m.text += std::string("; finding: ") + movement_finding_name(e.movement_test.finding) + ": " +
                  movement_finding_text(e.movement_test.finding);
      break;
    case LoopEvent::Kind::kMovementTest:
      m.kind = event_kind::kMovementTest;
      m.text = std::string("movement test at ARM ") + movement_test_end_name(e.movement_end) + ": " +
               describe(e.movement_test);
      break;
    case LoopEvent::Kind::kStart:
      m.kind = e.restart ? event_kind::kRestart : event_kind::kStart;
      m.text = e.restart ? "restart after a stop, set point unchanged" : "start";
      break;
  }
  return m;
}

}  // namespace pneu::controller
