// A sink of the runtime: the trajectory file (pneud --trajectory), one CSV row per tick drained:
// the tick's fields (records.hpp: seq,t,y_d,y,v_hat,a_hat,p_p,p_n,force,u,stuck,mode,validity),
// then the pressures and force each forecast made at the open stop expects at that tick
// (p_p_linearized,...,force_nonlinear; empty when not followed).
#pragma once

#include <ostream>
#include <string>

#include "pneu/controller/run_listener.hpp"

namespace pneu::controller {

class TrajectoryFile final : public RunListener {
 public:
  /// Writes the header line to `out` at once; `out` must outlive the sink.
  explicit TrajectoryFile(std::ostream& out);

  /// The header line (without its newline).
  [[nodiscard]] static std::string header();

  void on_tick(const TickRecord& tick, const ExpectedAtTick& expected) override;

 private:
  std::ostream& out_;
};

}  // namespace pneu::controller
