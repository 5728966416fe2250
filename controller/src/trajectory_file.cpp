#include "pneu/controller/trajectory_file.hpp"

#include <cmath>

#include "pneu/controller/records.hpp"
#include "pneu/records/csv.hpp"

namespace pneu::controller {

std::string TrajectoryFile::header() {
  return records::csv_header<TickRecord>() + ',' + records::csv_header<ForecastPoint>("_linearized") + ',' +
         records::csv_header<ForecastPoint>("_nonlinear");
}

TrajectoryFile::TrajectoryFile(std::ostream& out) : out_(out) { out_ << header() << '\n'; }

void TrajectoryFile::on_tick(const TickRecord& r, const ExpectedAtTick& expected) {
  records::write_csv_cells(out_, r);
  for (const ForecastPoint& x : {expected.linearized, expected.nonlinear}) {
    if (std::isnan(x.force_n)) records::write_csv_empty_cells<ForecastPoint>(out_, true);
    else records::write_csv_cells(out_, x, true);
  }
  out_ << '\n';
}

}  // namespace pneu::controller
