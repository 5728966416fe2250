// The open-loop input file of `pneu-plant simulate`: header with columns t and u (others ignored),
// one row per sample, time strictly increasing at a fixed sample rate.
#pragma once

#include <filesystem>
#include <istream>
#include <string>
#include <vector>

namespace pneu::plant_app {

struct InputSignal {
  std::vector<double> t_s;
  std::vector<double> u_v;
  double period_s = 0.0;
};

/// Throws cli::UsageError naming `origin:line` and the reason.
[[nodiscard]] InputSignal read_input_csv(std::istream& in, const std::string& origin);
[[nodiscard]] InputSignal read_input_csv(const std::filesystem::path& path);

}  // namespace pneu::plant_app
