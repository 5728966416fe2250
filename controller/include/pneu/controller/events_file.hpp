// A sink of the runtime: the events file (pneud --events), one JSON object per line, in the order
// the runtime emits them: start, stop, prediction (a forecast made at a stop), reforecast (made
// again while stuck), fault, fault_reset, fault_reset_refused, command (a command's verdict), end.
// docs/pneud.md lists each line's fields.
#pragma once

#include <ostream>

#include "pneu/controller/run_listener.hpp"

namespace pneu::controller {

class EventsFile final : public RunListener {
 public:
  /// Writes to `out`, which must outlive the sink.
  explicit EventsFile(std::ostream& out) : out_(out) {}

  void on_event(const LoopEvent& event) override;
  void on_forecast(const ForecastRecord& forecast) override;
  void on_command(const CommandRecord& command) override;
  void on_end(double t_end_s) override;

 private:
  std::ostream& out_;
};

}  // namespace pneu::controller
