// A measured valve characteristic q(w, p) on a rectangular grid, as a flow bench gives it (Fig. 12
// of the paper), and its file format.
//
// File format "pneu valve table v1": CSV text, lines starting with '#' are comments, then the
// header `voltage_v,pressure_pa,mass_flow_kg_per_s`, then one row per grid point: valve voltage w
// [V], absolute chamber pressure p [Pa], mass flow into the chamber q [kg/s] (q > 0 fills it).
// The rows cover every pair of a strictly increasing voltage axis and a strictly increasing
// pressure axis (at least 2 points each), sorted by voltage, then by pressure.
//
// Interpolation: piecewise linear in w (the model's q is piecewise linear in w, with kinks at
// w = 0 and +-u_max, so a grid holding those voltages reproduces it exactly in w) and monotone
// cubic Hermite (Fritsch-Carlson) in p, so dq/dp is continuous in p. Outside the grid the
// nearest edge is used.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <stdexcept>
#include <vector>

#include "pneu/model/valve.hpp"

namespace pneu::model {

/// A malformed valve table; the message names the file and line where it applies.
class ValveTableError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ValveTable final : public ValveCharacteristic {
 public:
  /// `flows_kg_per_s[i * pressures.size() + j]` is q(voltages[i], pressures[j]).
  /// Throws ValveTableError on a grid that is not strictly increasing, too small, or not finite.
  ValveTable(std::vector<double> voltages_v, std::vector<double> pressures_pa,
             std::vector<double> flows_kg_per_s);

  /// Samples a characteristic on the given axes (what characterize-valve measures).
  [[nodiscard]] static ValveTable sample(const ValveCharacteristic& valve,
                                         std::vector<double> voltages_v,
                                         std::vector<double> pressures_pa);
  /// Reads the file format above. Throws ValveTableError naming the line.
  [[nodiscard]] static ValveTable load(const std::filesystem::path& path);
  [[nodiscard]] static ValveTable read(std::istream& in, const std::string& origin);
  /// Writes the file format above, with a comment block documenting it.
  void write(std::ostream& out) const;

  [[nodiscard]] double mass_flow_kg_per_s(double w_v, double p_pa) const noexcept override;
  [[nodiscard]] double dq_dp(double w_v, double p_pa) const noexcept override;
  [[nodiscard]] double min_pressure_pa() const noexcept override { return pressures_.front(); }
  [[nodiscard]] double max_pressure_pa() const noexcept override { return pressures_.back(); }
  [[nodiscard]] double min_voltage_v() const noexcept override { return voltages_.front(); }
  [[nodiscard]] double max_voltage_v() const noexcept override { return voltages_.back(); }

  [[nodiscard]] const std::vector<double>& voltages_v() const noexcept { return voltages_; }
  [[nodiscard]] const std::vector<double>& pressures_pa() const noexcept { return pressures_; }

 private:
  struct Cell {
    std::size_t i;   // voltage cell
    double alpha;    // weight of voltage row i + 1
  };
  [[nodiscard]] Cell voltage_cell(double w) const noexcept;
  // Hermite value (derivative = false) or slope (true) of row i at pressure p.
  [[nodiscard]] double row_eval(std::size_t i, double p, bool derivative) const noexcept;

  std::vector<double> voltages_;
  std::vector<double> pressures_;
  std::vector<double> flows_;
  std::vector<double> slopes_;  // Fritsch-Carlson dq/dp at each grid point
};

}  // namespace pneu::model
