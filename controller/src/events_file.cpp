#include "pneu/controller/events_file.hpp"

#include "pneu/controller/records.hpp"
#include "pneu/records/json.hpp"

namespace pneu::controller {

// Each line is a view of a described record (pneu/controller/records.hpp): its members, their
// spelling and their digits are said there.

void EventsFile::on_event(const LoopEvent& e) {
  const EventLineOf l = event_line(e);
  records::write_json_line(out_, *l.view, l.line);
}

void EventsFile::on_forecast(const ForecastRecord& f) {
  records::write_json_line(out_, f.update == 0 ? kPredictionLine : kReforecastLine, f);
}

void EventsFile::on_command(const CommandRecord& c) { records::write_json_line(out_, kCommandLine, c); }

void EventsFile::on_end(double t_end_s) {
  EventLine l;
  l.t_s = t_end_s;
  records::write_json_line(out_, event_lines::kEnd, l);
}

}  // namespace pneu::controller
