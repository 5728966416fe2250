#include "pneu/controller/trajectory_file.hpp"

#include <cmath>

#include "pneu/controller/json_text.hpp"

namespace pneu::controller {

using json::num;

TrajectoryFile::TrajectoryFile(std::ostream& out) : out_(out) {
  out_ << "seq,t,y_d,y,v_hat,a_hat,p_P,p_N,F,u,stuck,mode,validity,"
          "p_P_linearized,p_N_linearized,F_linearized,p_P_nonlinear,p_N_nonlinear,F_nonlinear\n";
}

void TrajectoryFile::on_tick(const TickRecord& r, const ExpectedAtTick& expected) {
  out_ << r.seq << ',' << num(r.t_s, 12) << ',' << num(r.y_d_m) << ',' << num(r.y_m, 12) << ','
       << num(r.v_hat_m_per_s) << ',' << num(r.a_hat_m_per_s2) << ',' << num(r.p_p_pa) << ',' << num(r.p_n_pa)
       << ',' << num(r.force_n) << ',' << num(r.u_v) << ',' << (r.stuck ? 1 : 0) << ','
       << static_cast<int>(r.mode) << ',' << r.sensor_validity;
  for (const ForecastPoint& x : {expected.linearized, expected.nonlinear}) {
    if (std::isnan(x.force_n)) out_ << ",,,";
    else out_ << ',' << num(x.p_p_pa) << ',' << num(x.p_n_pa) << ',' << num(x.force_n);
  }
  out_ << '\n';
}

}  // namespace pneu::controller
