#include "pneu/model/valve_table.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <istream>
#include <ostream>
#include <sstream>
#include <string>

namespace pneu::model {

namespace {

void check_axis(const std::vector<double>& axis, const char* name) {
  if (axis.size() < 2)
    throw ValveTableError(std::string("valve table: the ") + name + " axis needs at least 2 values");
  for (std::size_t i = 0; i < axis.size(); ++i) {
    if (!std::isfinite(axis[i]))
      throw ValveTableError(std::string("valve table: non-finite ") + name + " value");
    if (i > 0 && !(axis[i] > axis[i - 1]))
      throw ValveTableError(std::string("valve table: the ") + name +
                            " axis is not strictly increasing");
  }
}

std::size_t cell_index(const std::vector<double>& axis, double x) noexcept {
  const auto it = std::upper_bound(axis.begin(), axis.end(), x);
  const auto i = static_cast<std::size_t>(std::max<std::ptrdiff_t>(it - axis.begin() - 1, 0));
  return std::min(i, axis.size() - 2);
}

}  // namespace

ValveTable::ValveTable(std::vector<double> voltages, std::vector<double> pressures,
                       std::vector<double> flows)
    : voltages_(std::move(voltages)), pressures_(std::move(pressures)), flows_(std::move(flows)) {
  check_axis(voltages_, "voltage");
  check_axis(pressures_, "pressure");
  const std::size_t np = pressures_.size();
  if (flows_.size() != voltages_.size() * np)
    throw ValveTableError("valve table: " + std::to_string(flows_.size()) + " flows for a " +
                          std::to_string(voltages_.size()) + " x " + std::to_string(np) + " grid");
  for (double q : flows_)
    if (!std::isfinite(q)) throw ValveTableError("valve table: non-finite mass flow");

  // Fritsch-Carlson monotone slopes along p, row by row.
  slopes_.assign(flows_.size(), 0.0);
  std::vector<double> secant(np - 1);
  for (std::size_t i = 0; i < voltages_.size(); ++i) {
    const double* q = &flows_[i * np];
    double* m = &slopes_[i * np];
    for (std::size_t j = 0; j + 1 < np; ++j)
      secant[j] = (q[j + 1] - q[j]) / (pressures_[j + 1] - pressures_[j]);
    m[0] = secant[0];
    m[np - 1] = secant[np - 2];
    for (std::size_t j = 1; j + 1 < np; ++j)
      m[j] = (secant[j - 1] * secant[j] <= 0.0) ? 0.0 : 0.5 * (secant[j - 1] + secant[j]);
    for (std::size_t j = 0; j + 1 < np; ++j) {
      if (secant[j] == 0.0) {
        m[j] = m[j + 1] = 0.0;
        continue;
      }
      const double a = m[j] / secant[j], b = m[j + 1] / secant[j];
      const double r = a * a + b * b;
      if (r > 9.0) {
        const double t = 3.0 / std::sqrt(r);
        m[j] = t * a * secant[j];
        m[j + 1] = t * b * secant[j];
      }
    }
  }
}

ValveTable ValveTable::sample(const ValveCharacteristic& valve, std::vector<double> voltages,
                              std::vector<double> pressures) {
  std::vector<double> flows;
  flows.reserve(voltages.size() * pressures.size());
  for (double w : voltages)
    for (double p : pressures) flows.push_back(valve.mass_flow_kg_per_s(w, p));
  return ValveTable(std::move(voltages), std::move(pressures), std::move(flows));
}

ValveTable::Cell ValveTable::voltage_cell(double w) const noexcept {
  w = std::clamp(w, voltages_.front(), voltages_.back());
  const std::size_t i = cell_index(voltages_, w);
  return {i, (w - voltages_[i]) / (voltages_[i + 1] - voltages_[i])};
}

double ValveTable::row_eval(std::size_t i, double p, bool derivative) const noexcept {
  const std::size_t np = pressures_.size();
  p = std::clamp(p, pressures_.front(), pressures_.back());
  const std::size_t j = cell_index(pressures_, p);
  const double h = pressures_[j + 1] - pressures_[j];
  const double t = (p - pressures_[j]) / h;
  const double q0 = flows_[i * np + j], q1 = flows_[i * np + j + 1];
  const double m0 = slopes_[i * np + j] * h, m1 = slopes_[i * np + j + 1] * h;
  const double t2 = t * t, t3 = t2 * t;
  if (!derivative) {
    return (2 * t3 - 3 * t2 + 1) * q0 + (t3 - 2 * t2 + t) * m0 + (-2 * t3 + 3 * t2) * q1 +
           (t3 - t2) * m1;
  }
  return ((6 * t2 - 6 * t) * q0 + (3 * t2 - 4 * t + 1) * m0 + (-6 * t2 + 6 * t) * q1 +
          (3 * t2 - 2 * t) * m1) /
         h;
}

double ValveTable::mass_flow_kg_per_s(double w, double p) const noexcept {
  const Cell c = voltage_cell(w);
  return (1.0 - c.alpha) * row_eval(c.i, p, false) + c.alpha * row_eval(c.i + 1, p, false);
}

double ValveTable::dq_dp(double w, double p) const noexcept {
  const Cell c = voltage_cell(w);
  return (1.0 - c.alpha) * row_eval(c.i, p, true) + c.alpha * row_eval(c.i + 1, p, true);
}

void ValveTable::write(std::ostream& out) const {
  out << "# pneu valve table v1\n"
         "# Mass flow rate q into a chamber held at absolute pressure p while its 3-way\n"
         "# servo-distributor is driven with voltage w (Fig. 12 of Brun et al. 2005).\n"
         "# Columns: voltage_v [V], pressure_pa [Pa abs], mass_flow_kg_per_s [kg/s, > 0 fills].\n"
         "# Rows: every (voltage, pressure) pair of two strictly increasing axes, sorted by\n"
         "# voltage then pressure. Readers interpolate linearly in w, monotone cubic in p.\n"
         "voltage_v,pressure_pa,mass_flow_kg_per_s\n";
  out << std::setprecision(17);
  const std::size_t np = pressures_.size();
  for (std::size_t i = 0; i < voltages_.size(); ++i)
    for (std::size_t j = 0; j < np; ++j)
      out << voltages_[i] << ',' << pressures_[j] << ',' << flows_[i * np + j] << '\n';
}

ValveTable ValveTable::load(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw ValveTableError(path.string() + ": cannot open the valve table");
  return read(in, path.string());
}

ValveTable ValveTable::read(std::istream& in, const std::string& origin) {
  std::vector<double> voltages, pressures, flows;
  std::string line;
  std::size_t line_no = 0;
  bool header_seen = false;
  const auto fail = [&](const std::string& why) {
    throw ValveTableError(origin + ":" + std::to_string(line_no) + ": " + why);
  };
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (!header_seen) {
      if (line != "voltage_v,pressure_pa,mass_flow_kg_per_s")
        fail("expected the header 'voltage_v,pressure_pa,mass_flow_kg_per_s', got '" + line + "'");
      header_seen = true;
      continue;
    }
    double cells[3];
    std::stringstream ss(line);
    std::string cell;
    int n = 0;
    while (std::getline(ss, cell, ',')) {
      if (n == 3) fail("more than 3 columns");
      std::size_t used = 0;
      try {
        cells[n] = std::stod(cell, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != cell.size() || !std::isfinite(cells[n]))
        fail("column " + std::to_string(n + 1) + " is not a finite number: '" + cell + "'");
      ++n;
    }
    if (n != 3) fail("expected 3 columns, got " + std::to_string(n));
    const double w = cells[0], p = cells[1];
    if (voltages.empty() || w != voltages.back()) {
      if (!voltages.empty() && !(w > voltages.back())) fail("voltages must increase row block by row block");
      if (!voltages.empty() && flows.size() != voltages.size() * pressures.size())
        fail("voltage " + std::to_string(voltages.back()) + " has " +
             std::to_string(flows.size() - (voltages.size() - 1) * pressures.size()) +
             " pressures, expected " + std::to_string(pressures.size()));
      voltages.push_back(w);
    }
    const std::size_t j = flows.size() - (voltages.size() - 1) * pressures.size();
    if (voltages.size() == 1) {
      if (!pressures.empty() && !(p > pressures.back())) fail("pressures must increase within a voltage");
      pressures.push_back(p);
    } else if (j >= pressures.size() || p != pressures[j]) {
      fail("pressure " + std::to_string(p) + " does not match the grid of the first voltage");
    }
    flows.push_back(cells[2]);
  }
  if (!header_seen) throw ValveTableError(origin + ": no header line (empty file?)");
  if (flows.size() != voltages.size() * pressures.size())
    throw ValveTableError(origin + ": the last voltage does not cover every pressure of the grid");
  try {
    return ValveTable(std::move(voltages), std::move(pressures), std::move(flows));
  } catch (const ValveTableError& e) {
    throw ValveTableError(origin + ": " + e.what());
  }
}

}  // namespace pneu::model
