#include "pneu/controller/events_file.hpp"

#include "pneu/controller/json_text.hpp"
#include "pneu/controller/supervisor.hpp"

namespace pneu::controller {

using json::num;
using json::Str;

void EventsFile::on_event(const LoopEvent& e) {
  switch (e.kind) {
    case LoopEvent::Kind::kStop:
      out_ << "{\"event\":\"stop\",\"t\":" << num(e.t_s, 12) << ",\"stop\":" << e.stop_index
           << ",\"y\":" << num(e.y_m, 12) << ",\"force\":" << num(e.force_n) << ",\"y_d\":" << num(e.y_d_m)
           << "}\n";
      return;
    case LoopEvent::Kind::kStart:
      out_ << "{\"event\":\"start\",\"t\":" << num(e.t_s, 12) << ",\"stop\":" << e.stop_index
           << ",\"restart\":" << (e.restart ? "true" : "false") << ",\"direction\":" << e.direction
           << ",\"y\":" << num(e.y_m, 12) << ",\"y_d\":" << num(e.y_d_m) << "}\n";
      return;
    case LoopEvent::Kind::kFault:
      out_ << "{\"event\":\"fault\",\"t\":" << num(e.t_s, 12) << ",\"y\":" << num(e.y_m, 12) << ",\"cause\":\""
           << fault_name(e.fault_cause) << "\",\"text\":\"" << fault_text(e.fault_cause) << '"';
      if (e.fault_key != nullptr) out_ << ",\"key\":\"" << e.fault_key << '"';
      if (e.fault_cause == FaultCause::kMovementTest)
        out_ << ",\"finding\":\"" << movement_finding_name(e.movement_test.finding) << '"';
      out_ << "}\n";
      return;
    case LoopEvent::Kind::kMovementTest:
      out_ << "{\"event\":\"movement_test\",\"t\":" << num(e.t_s, 12) << ",\"end\":\""
           << movement_test_end_name(e.movement_end) << "\",\"finding\":\""
           << movement_finding_name(e.movement_test.finding) << "\",\"pulses\":" << e.movement_test.pulses
           << ",\"duration\":" << num(e.movement_test.duration_s) << ",\"y_start\":" << num(e.movement_test.y_start_m, 12)
           << ",\"y_end\":" << num(e.movement_test.y_end_m, 12);
      if (e.movement_end == MovementTestEnd::kFault) out_ << ",\"cause\":\"" << fault_name(e.fault_cause) << '"';
      out_ << ",\"text\":" << Str{describe(e.movement_test)} << "}\n";
      return;
    case LoopEvent::Kind::kFaultReset:
    case LoopEvent::Kind::kResetRefused:
      out_ << "{\"event\":\"" << (e.kind == LoopEvent::Kind::kFaultReset ? "fault_reset" : "fault_reset_refused")
           << "\",\"t\":" << num(e.t_s, 12) << ",\"cause\":\"" << fault_name(e.fault_cause) << "\"}\n";
      return;
    case LoopEvent::Kind::kHoldStart:
      out_ << "{\"event\":\"hold_start\",\"t\":" << num(e.t_s, 12) << ",\"stop\":" << e.stop_index
           << ",\"y\":" << num(e.y_m, 12) << ",\"force\":" << num(e.force_n) << ",\"y_d\":" << num(e.y_d_m)
           << ",\"reach\":" << e.direction << "}\n";
      return;
    case LoopEvent::Kind::kHoldEnd:
      out_ << "{\"event\":\"hold_end\",\"t\":" << num(e.t_s, 12) << ",\"stop\":" << e.stop_index
           << ",\"why\":\"" << hold_end_name(e.hold_end) << "\",\"y\":" << num(e.y_m, 12)
           << ",\"y_d\":" << num(e.y_d_m) << "}\n";
      return;
  }
}

void EventsFile::on_forecast(const ForecastRecord& f) {
  const Prediction& p = f.prediction;
  if (f.update == 0) {
    out_ << "{\"event\":\"prediction\",\"t\":" << num(f.t_s, 12) << ",\"stop\":" << f.stop
         << ",\"t_stop\":" << num(f.t_stop_s, 12) << ",\"method\":\"" << to_string(p.method)
         << "\",\"will_restart\":" << (p.will_restart ? "true" : "false") << ",\"direction\":" << p.direction
         << ",\"t_restart\":" << num(p.t_restart_s, 12) << ",\"u_star\":" << num(f.u_star_v)
         << ",\"equilibrium_force\":" << num(p.equilibrium_force_n) << ",\"tau_p\":" << num(p.tau_p_s)
         << ",\"tau_n\":" << num(p.tau_n_s) << ",\"min_margin\":" << num(p.min_margin_n)
         << ",\"horizon_reached\":" << (p.horizon_reached ? "true" : "false")
         << (p.model_fits ? "" : ",\"model_fits\":false") << "}\n";
    return;
  }
  out_ << "{\"event\":\"reforecast\",\"t\":" << num(f.t_s, 12) << ",\"stop\":" << f.stop
       << ",\"t_stop\":" << num(f.t_stop_s, 12) << ",\"update\":" << f.update << ",\"method\":\""
       << to_string(p.method) << "\",\"will_restart\":" << (p.will_restart ? "true" : "false")
       << ",\"direction\":" << p.direction << ",\"t_restart\":" << num(p.t_restart_s, 12)
       << ",\"u_star\":" << num(f.u_star_v) << ",\"force\":" << num(f.force_n)
       << ",\"stop_forecast_force\":" << num(f.stop_forecast_force_n) << ",\"min_margin\":" << num(p.min_margin_n)
       << ",\"horizon_reached\":" << (p.horizon_reached ? "true" : "false")
       << (p.model_fits ? "" : ",\"model_fits\":false") << "}\n";
}

void EventsFile::on_command(const CommandRecord& c) {
  out_ << "{\"event\":\"command\",\"t\":" << num(c.t_s, 12) << ",\"verdict\":\""
       << (c.accepted ? "accepted" : "rejected") << "\",\"reason\":";
  if (c.accepted) out_ << "null";
  else out_ << Str{c.reason};
  out_ << ",\"kind\":";
  if (c.decoded) out_ << Str{c.kind} << ",\"seq\":" << c.seq << ",\"value\":" << num(c.value);
  else out_ << "null,\"seq\":null,\"value\":null";
  out_ << ",\"text\":" << Str{c.text} << "}\n";
}

void EventsFile::on_end(double t_end_s) { out_ << "{\"event\":\"end\",\"t\":" << num(t_end_s, 12) << "}\n"; }

}  // namespace pneu::controller
