#include "input_csv.hpp"

#include <charconv>
#include <cmath>
#include <fstream>

#include "pneu/config/cli.hpp"

namespace pneu::plant_app {

namespace {

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> cells;
  std::size_t start = 0;
  for (;;) {
    const auto comma = line.find(',', start);
    std::string cell = line.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    // Trim spaces around a cell.
    const auto b = cell.find_first_not_of(" \t");
    const auto e = cell.find_last_not_of(" \t");
    cells.push_back(b == std::string::npos ? "" : cell.substr(b, e - b + 1));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return cells;
}

}  // namespace

InputSignal read_input_csv(std::istream& in, const std::string& origin) {
  InputSignal s;
  std::string line;
  std::size_t line_no = 0;
  const auto fail = [&](const std::string& why) {
    throw cli::UsageError(origin + ":" + std::to_string(line_no) + ": " + why);
  };
  int col_t = -1, col_u = -1;
  std::size_t columns = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    const auto cells = split(line);
    if (columns == 0) {
      for (std::size_t i = 0; i < cells.size(); ++i) {
        if (cells[i] == "t") col_t = static_cast<int>(i);
        if (cells[i] == "u") col_u = static_cast<int>(i);
      }
      if (col_t < 0 || col_u < 0)
        fail(std::string("the header must name the columns 't' (s) and 'u' (V); missing '") +
             (col_t < 0 ? "t" : "u") + "' in '" + line + "'");
      columns = cells.size();
      continue;
    }
    if (cells.size() != columns)
      fail("expected " + std::to_string(columns) + " columns, got " + std::to_string(cells.size()));
    double values[2];
    const int cols[2] = {col_t, col_u};
    for (int k = 0; k < 2; ++k) {
      const std::string& cell = cells[static_cast<std::size_t>(cols[k])];
      const char* first = cell.data();
      const char* last = first + cell.size();
      if (!cell.empty() && *first == '+') ++first;
      const auto [ptr, ec] = std::from_chars(first, last, values[k]);
      if (cell.empty() || ec != std::errc() || ptr != last || !std::isfinite(values[k]))
        fail(std::string("column '") + (k == 0 ? "t" : "u") + "' is not a finite number: '" + cell + "'");
    }
    if (!s.t_s.empty()) {
      const double dt = values[0] - s.t_s.back();
      if (!(dt > 0.0))
        fail("time does not increase (" + std::to_string(values[0]) + " s after " +
             std::to_string(s.t_s.back()) + " s)");
      if (s.t_s.size() == 1) {
        s.period_s = dt;
      } else if (std::abs(dt - s.period_s) > 1e-3 * s.period_s) {
        fail("sample period " + std::to_string(dt) + " s differs from the first one (" +
             std::to_string(s.period_s) + " s): the input must have a fixed sample rate");
      }
    }
    s.t_s.push_back(values[0]);
    s.u_v.push_back(values[1]);
  }
  if (columns == 0) throw cli::UsageError(origin + ": empty file: expected a header 't,u'");
  if (s.t_s.size() < 2) throw cli::UsageError(origin + ": needs at least two samples to define the sample period");
  return s;
}

InputSignal read_input_csv(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw cli::UsageError(path.string() + ": cannot open the input file");
  return read_input_csv(in, path.string());
}

}  // namespace pneu::plant_app
