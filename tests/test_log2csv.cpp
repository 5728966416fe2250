// pneu-log2csv as a user runs it: a log written the way lcm-logger writes it, converted, and every
// cell read back; bad and damaged logs refused or salvaged with a message.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "pneu/controller/records.hpp"
#include "pneu/records/csv.hpp"
#include "pneu_lcm/command_t.hpp"
#include "pneu_lcm/event_t.hpp"
#include "pneu_lcm/health_t.hpp"
#include "pneu_lcm/identification_t.hpp"
#include "pneu_lcm/prediction_t.hpp"
#include "pneu_lcm/state_t.hpp"

#include "support/child_process.hpp"

namespace fs = std::filesystem;
using ::testing::ContainsRegex;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::Not;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr std::int64_t kLogStart = 1'700'000'000'000'000;  // log timestamps [us]

struct Outcome {
  int exit_code;
  std::string out;
  std::string err;
};

struct Entry {
  std::string channel;
  std::int64_t timestamp;
  std::vector<std::uint8_t> data;
};

template <class T>
std::vector<std::uint8_t> encode(const T& msg) {
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(msg.getEncodedSize()));
  const int n = msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
  EXPECT_EQ(n, static_cast<int>(buf.size()));
  return buf;
}

using pneu::test::slurp;

// A CSV file read by RFC 4180: quoted cells may hold commas, doubled quotes and newlines.
struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;

  [[nodiscard]] const std::string& at(std::size_t row, const std::string& column) const {
    for (std::size_t c = 0; c < header.size(); ++c)
      if (header[c] == column) return rows.at(row).at(c);
    throw std::out_of_range("no column " + column);
  }
};

Csv parse_csv(const std::string& text) {
  std::vector<std::vector<std::string>> records;
  std::vector<std::string> record;
  std::string cell;
  bool in_quotes = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_quotes) {
      if (c != '"')
        cell += c;
      else if (i + 1 < text.size() && text[i + 1] == '"')
        cell += text[++i];
      else
        in_quotes = false;
    } else if (c == '"') {
      in_quotes = true;
    } else if (c == ',') {
      record.push_back(std::move(cell));
      cell.clear();
    } else if (c == '\n') {
      record.push_back(std::move(cell));
      cell.clear();
      records.push_back(std::move(record));
      record.clear();
    } else {
      cell += c;
    }
  }
  EXPECT_FALSE(in_quotes) << "unterminated quote";
  EXPECT_TRUE(cell.empty() && record.empty()) << "last line without a newline";
  Csv csv;
  if (records.empty()) return csv;
  csv.header = records.front();
  csv.rows.assign(records.begin() + 1, records.end());
  for (const auto& r : csv.rows)
    EXPECT_EQ(r.size(), csv.header.size()) << "a row of the wrong width";
  return csv;
}

std::vector<std::string> split_header(const std::string& h) {
  std::vector<std::string> out;
  std::stringstream ss(h);
  for (std::string c; std::getline(ss, c, ',');) out.push_back(c);
  return out;
}

// Bit for bit: the cell read back is the very double written; NaN is the empty cell.
void expect_double(const std::string& cell, double expected, const std::string& what) {
  if (std::isnan(expected)) {
    EXPECT_EQ(cell, "") << what;
    return;
  }
  char* end = nullptr;
  const double got = std::strtod(cell.c_str(), &end);
  EXPECT_TRUE(!cell.empty() && *end == '\0') << what << ": '" << cell << "' is not a number";
  EXPECT_EQ(std::bit_cast<std::uint64_t>(got), std::bit_cast<std::uint64_t>(expected))
      << what << ": '" << cell << "' does not read back as " << expected;
}

void expect_int(const std::string& cell, std::int64_t expected, const std::string& what) {
  std::size_t used = 0;
  std::int64_t got = 0;
  try {
    got = std::stoll(cell, &used);
  } catch (const std::exception&) {
    ADD_FAILURE() << what << ": '" << cell << "' is not an integer";
    return;
  }
  EXPECT_EQ(used, cell.size()) << what << ": '" << cell << "'";
  EXPECT_EQ(got, expected) << what;
}

// Any double, from its bits: subnormals, -0, huge and tiny exponents, the odd NaN and infinity.
double any_double(std::mt19937_64& rng) { return std::bit_cast<double>(rng()); }

class Log2Csv : public ::testing::Test {
 protected:
  void SetUp() override {
    out_dir_ = dir_ / "out";
  }

  Outcome run(const std::string& args) const {
    const fs::path out = dir_ / "stdout.txt", err = dir_ / "stderr.txt";
    const std::string cmd = std::string(PNEU_BINARY_DIR) + "/bin/pneu-log2csv " + args + " >" +
                            out.string() + " 2>" + err.string();
    const int status = std::system(cmd.c_str());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(out), slurp(err)};
  }
  Outcome convert(const fs::path& log, const std::string& extra = "") const {
    return run(log.string() + " " + out_dir_.string() + (extra.empty() ? "" : " " + extra));
  }

  fs::path write_log(const std::vector<Entry>& entries,
                     const std::string& name = "in.lcmlog") const {
    const fs::path p = dir_ / name;
    lcm::LogFile log(p.string(), "w");
    EXPECT_TRUE(log.good());
    for (const auto& e : entries) {
      lcm::LogEvent ev{};
      ev.timestamp = e.timestamp;
      ev.channel = e.channel;
      ev.datalen = static_cast<std::int32_t>(e.data.size());
      ev.data = const_cast<std::uint8_t*>(e.data.data());
      EXPECT_EQ(log.writeEvent(&ev), 0);
    }
    return p;
  }

  Csv read_csv(const std::string& name) const {
    const fs::path p = out_dir_ / name;
    EXPECT_TRUE(fs::exists(p)) << p << " was not written";
    return parse_csv(slurp(p));
  }
  std::vector<std::string> outputs() const {
    std::vector<std::string> names;
    if (!fs::exists(out_dir_)) return names;
    for (const auto& e : fs::directory_iterator(out_dir_))
      names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

  pneu::test::TestDir dir_{"pneu_log2csv_"};
  fs::path out_dir_;
};

std::vector<pneu_lcm::state_t> random_states(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<pneu_lcm::state_t> states;
  for (int i = 0; i < n; ++i) {
    pneu_lcm::state_t s{};
    s.utime = kLogStart - 250 + i * 1000;
    s.seq = i;
    s.t = i * 1e-3;
    s.y_d = any_double(rng);
    s.y = any_double(rng);
    s.v_hat = any_double(rng);
    s.a_hat = any_double(rng);
    s.p_p = any_double(rng);
    s.p_n = any_double(rng);
    s.force = any_double(rng);
    s.u = any_double(rng);
    s.stuck = static_cast<std::int8_t>(i % 3 == 0);
    s.mode = static_cast<std::int8_t>(i % 3);
    s.validity = static_cast<std::int32_t>(rng());
    states.push_back(s);
  }
  if (n < 8) return states;
  // Values the random bits are unlikely to hit.
  states[1].y = kNaN;
  states[2].y = -0.0;
  states[3].force = std::numeric_limits<double>::infinity();
  states[4].force = -std::numeric_limits<double>::infinity();
  states[5].p_p = std::numeric_limits<double>::denorm_min();
  states[6].p_p = std::numeric_limits<double>::max();
  states[7].u = 0.1;  // not exact in binary: needs all 17 digits
  return states;
}

TEST_F(Log2Csv, HelpAndVersionExitZero) {
  const auto help = run("--help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_THAT(help.out, HasSubstr("pneu-log2csv LOGFILE OUTDIR [--channels REGEX]"));
  const auto version = run("--version");
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_THAT(version.out, ContainsRegex("^pneu-log2csv [0-9]+\\.[0-9]+\\.[0-9]+"));
}

TEST_F(Log2Csv, EveryStateFieldReadsBackBitForBitAndSeqHasNoGaps) {
  const auto states = random_states(1000, 20240601);
  std::vector<Entry> log;
  for (std::size_t i = 0; i < states.size(); ++i)
    log.push_back(
        {"PNEU_STATE", kLogStart + static_cast<std::int64_t>(i) * 1000 + 17, encode(states[i])});

  const auto r = convert(write_log(log));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, IsEmpty());
  EXPECT_THAT(
      r.out,
      ContainsRegex("PNEU_STATE +state_t +1000 +PNEU_STATE\\.csv +\\(seq 0\\.\\.999, no gaps\\)"));
  EXPECT_THAT(outputs(), ::testing::ElementsAre("PNEU_STATE.csv"));

  const Csv csv = read_csv("PNEU_STATE.csv");
  EXPECT_EQ(
      csv.header,
      split_header("log_utime,utime,seq,t,y_d,y,v_hat,a_hat,p_p,p_n,force,u,stuck,mode,validity"));
  ASSERT_EQ(csv.rows.size(), states.size());
  int nan_cells = 0;
  for (std::size_t i = 0; i < states.size(); ++i) {
    const auto& s = states[i];
    const std::string row = "row " + std::to_string(i) + " ";
    expect_int(csv.at(i, "log_utime"), log[i].timestamp, row + "log_utime");
    expect_int(csv.at(i, "utime"), s.utime, row + "utime");
    expect_int(csv.at(i, "seq"), static_cast<std::int64_t>(i), row + "seq");  // no gaps, in order
    expect_double(csv.at(i, "t"), s.t, row + "t");
    expect_double(csv.at(i, "y_d"), s.y_d, row + "y_d");
    expect_double(csv.at(i, "y"), s.y, row + "y");
    expect_double(csv.at(i, "v_hat"), s.v_hat, row + "v_hat");
    expect_double(csv.at(i, "a_hat"), s.a_hat, row + "a_hat");
    expect_double(csv.at(i, "p_p"), s.p_p, row + "p_p");
    expect_double(csv.at(i, "p_n"), s.p_n, row + "p_n");
    expect_double(csv.at(i, "force"), s.force, row + "force");
    expect_double(csv.at(i, "u"), s.u, row + "u");
    expect_int(csv.at(i, "stuck"), s.stuck, row + "stuck");
    expect_int(csv.at(i, "mode"), s.mode, row + "mode");
    expect_int(csv.at(i, "validity"), s.validity, row + "validity");
    for (const auto& cell : csv.rows[i]) nan_cells += cell.empty() ? 1 : 0;
  }
  EXPECT_GE(nan_cells, 1);  // states[1].y at least: the NaN path was exercised
  EXPECT_EQ(csv.at(2, "y"), "-0");
  EXPECT_EQ(csv.at(7, "u"), "0.10000000000000001");
}

TEST_F(Log2Csv, SeqGapsAreCountedInTheSummary) {
  const auto states = random_states(20, 7);
  std::vector<Entry> log;
  for (std::size_t i = 0; i < states.size(); ++i) {
    if (i == 5 || i == 6 || i == 12) continue;  // two gaps, three ticks missing
    log.push_back({"PNEU_STATE", kLogStart + static_cast<std::int64_t>(i), encode(states[i])});
  }
  const auto r = convert(write_log(log));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("(seq 0..19, 2 gaps, 3 missing)"));
  EXPECT_EQ(read_csv("PNEU_STATE.csv").rows.size(), 17u);
}

TEST_F(Log2Csv, EventTextIsQuotedWithQuotesDoubledAndKindsNamed) {
  const std::vector<std::pair<std::int8_t, std::string>> kinds = {
      {1, "start"}, {2, "restart"},          {3, "stop"},
      {4, "fault"}, {5, "command_accepted"}, {6, "command_rejected"},
      {7, "end"},   {42, "unknown"}};
  const std::vector<std::string> texts = {
      "",   "valve \"P\" stuck, at 3.2 bar", "\"", ",", "two\nlines", "plain", "a \"\"b\"\" c",
      "end"};
  std::vector<pneu_lcm::event_t> events;
  std::vector<Entry> log;
  for (std::size_t i = 0; i < kinds.size(); ++i) {
    pneu_lcm::event_t e{};
    e.utime = kLogStart + static_cast<std::int64_t>(i);
    e.kind = kinds[i].first;
    e.t = 1.0 / 3.0 + static_cast<double>(i);
    e.stop = static_cast<std::int64_t>(i) * 7;
    e.y = -0.012345678901234567;
    e.force = 12.5e-300;
    e.y_d = i == 3 ? kNaN : 0.02;
    e.direction = i % 2 == 0 ? 1 : -1;
    e.seq = i == 4 || i == 5 ? 1'718'000'000'000'000 + static_cast<std::int64_t>(i) : 0;  // command events
    e.origin = i == 4 ? "pneu-dash \"lab, 2\"" : "";  // a command verdict's sender: free text, quoted
    e.session = i == 4 ? 123456789 : 0;
    e.text = texts[i];
    events.push_back(e);
    log.push_back({"PNEU_EVENT", kLogStart + 100 + static_cast<std::int64_t>(i), encode(e)});
  }
  const auto r = convert(write_log(log));
  ASSERT_EQ(r.exit_code, 0) << r.err;

  const std::string raw = slurp(out_dir_ / "PNEU_EVENT.csv");
  EXPECT_THAT(raw, HasSubstr(",\"valve \"\"P\"\" stuck, at 3.2 bar\"\n"));
  EXPECT_THAT(raw, HasSubstr(",\"\"\n"));  // empty text: still quoted
  const Csv csv = parse_csv(raw);
  EXPECT_EQ(csv.header,
            split_header("log_utime,utime,kind,kind_name,t,stop,y,force,y_d,direction,seq,origin,session,text"));
  EXPECT_EQ(csv.header, split_header("log_utime,utime," + pneu::records::csv_header<pneu::controller::EventMessage>()))
      << "the event message's description";
  ASSERT_EQ(csv.rows.size(), events.size());
  for (std::size_t i = 0; i < events.size(); ++i) {
    const auto& e = events[i];
    const std::string row = "event " + std::to_string(i) + " ";
    expect_int(csv.at(i, "log_utime"), log[i].timestamp, row + "log_utime");
    expect_int(csv.at(i, "utime"), e.utime, row + "utime");
    expect_int(csv.at(i, "kind"), e.kind, row + "kind");
    EXPECT_EQ(csv.at(i, "kind_name"), kinds[i].second) << row;
    expect_double(csv.at(i, "t"), e.t, row + "t");
    expect_int(csv.at(i, "stop"), e.stop, row + "stop");
    expect_double(csv.at(i, "y"), e.y, row + "y");
    expect_double(csv.at(i, "force"), e.force, row + "force");
    expect_double(csv.at(i, "y_d"), e.y_d, row + "y_d");
    expect_int(csv.at(i, "direction"), e.direction, row + "direction");
    expect_int(csv.at(i, "seq"), e.seq, row + "seq");
    EXPECT_EQ(csv.at(i, "origin"), e.origin) << row;
    expect_int(csv.at(i, "session"), e.session, row + "session");
    EXPECT_EQ(csv.at(i, "text"), e.text) << row;
  }
}

TEST_F(Log2Csv, PredictionWithoutRestartHasAnEmptyRestartTime) {
  pneu_lcm::prediction_t none{};
  none.utime = kLogStart + 5;
  none.t = 2.5;
  none.stop = 3;
  none.t_stop = 2.375;
  none.method = pneu_lcm::prediction_t::METHOD_LINEARIZED;
  none.will_restart = 0;
  none.direction = 0;
  none.t_restart = kNaN;
  none.u_star = 0.123456789;
  none.equilibrium_force = -41.25;
  none.p_p_equilibrium = 312345.5;
  none.p_n_equilibrium = 298765.25;
  none.tau_p = 0.0123;
  none.tau_n = 0.0456;
  none.min_margin = 3.75;
  none.horizon_reached = 0;
  none.force = -12.5;
  none.stop_forecast_force = -12.5;
  none.model_fits = 1;
  pneu_lcm::prediction_t restart = none;
  restart.update = 7;
  restart.force = -49.875;
  restart.stop_forecast_force = -48.0625;
  restart.method = pneu_lcm::prediction_t::METHOD_NONLINEAR;
  restart.will_restart = 1;
  restart.direction = -1;
  restart.t_restart = 3.1415926535897931;
  restart.horizon_reached = 1;
  restart.model_fits = 0;  // made on a model that did not fit the bench when identified
  pneu_lcm::prediction_t relaxation = restart;  // fitted to the phase's pressures: none at the stop
  relaxation.method = pneu_lcm::prediction_t::METHOD_RELAXATION;
  relaxation.horizon_reached = 0;
  relaxation.stop_forecast_force = kNaN;
  pneu_lcm::prediction_t held = relaxation;  // under the in-position hold's commands
  held.method = pneu_lcm::prediction_t::METHOD_HELD;
  held.will_restart = 0;
  held.direction = 0;
  held.t_restart = kNaN;
  held.equilibrium_force = -2.5;
  const std::vector<pneu_lcm::prediction_t> msgs = {none, restart, relaxation, held};

  const auto r = convert(write_log({{"PNEU_PREDICTION", kLogStart, encode(none)},
                                    {"PNEU_PREDICTION", kLogStart + 1, encode(restart)},
                                    {"PNEU_PREDICTION", kLogStart + 2, encode(relaxation)},
                                    {"PNEU_PREDICTION", kLogStart + 3, encode(held)}}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Csv csv = read_csv("PNEU_PREDICTION.csv");
  EXPECT_EQ(csv.header,
            split_header(
                "log_utime,utime,t,stop,t_stop,update,method,method_name,will_restart,direction,t_restart,"
                "u_star,equilibrium_force,p_p_equilibrium,p_n_equilibrium,tau_p,tau_n,min_margin,"
                "horizon_reached,force,stop_forecast_force,model_fits"));
  EXPECT_EQ(csv.header,
            split_header("log_utime,utime," + pneu::records::csv_header<pneu::controller::ForecastRecord>()))
      << "the forecast's description";
  ASSERT_EQ(csv.rows.size(), 4u);
  EXPECT_EQ(csv.at(0, "t_restart"), "");
  EXPECT_EQ(csv.at(0, "method_name"), "linearized");
  EXPECT_EQ(csv.at(1, "method_name"), "nonlinear");
  EXPECT_EQ(csv.at(2, "method_name"), "relaxation");
  EXPECT_EQ(csv.at(3, "method_name"), "held");
  for (std::size_t i = 0; i < msgs.size(); ++i) {
    const auto& m = msgs[i];
    const std::string row = "prediction " + std::to_string(i) + " ";
    expect_int(csv.at(i, "log_utime"), kLogStart + static_cast<std::int64_t>(i), row + "log_utime");
    expect_int(csv.at(i, "utime"), m.utime, row + "utime");
    expect_double(csv.at(i, "t"), m.t, row + "t");
    expect_int(csv.at(i, "stop"), m.stop, row + "stop");
    expect_double(csv.at(i, "t_stop"), m.t_stop, row + "t_stop");
    expect_int(csv.at(i, "update"), m.update, row + "update");
    expect_int(csv.at(i, "method"), m.method, row + "method");
    expect_int(csv.at(i, "will_restart"), m.will_restart, row + "will_restart");
    expect_int(csv.at(i, "direction"), m.direction, row + "direction");
    expect_double(csv.at(i, "t_restart"), m.t_restart, row + "t_restart");
    expect_double(csv.at(i, "u_star"), m.u_star, row + "u_star");
    expect_double(csv.at(i, "equilibrium_force"), m.equilibrium_force, row + "equilibrium_force");
    expect_double(csv.at(i, "p_p_equilibrium"), m.p_p_equilibrium, row + "p_p_equilibrium");
    expect_double(csv.at(i, "p_n_equilibrium"), m.p_n_equilibrium, row + "p_n_equilibrium");
    expect_double(csv.at(i, "tau_p"), m.tau_p, row + "tau_p");
    expect_double(csv.at(i, "tau_n"), m.tau_n, row + "tau_n");
    expect_double(csv.at(i, "min_margin"), m.min_margin, row + "min_margin");
    expect_int(csv.at(i, "horizon_reached"), m.horizon_reached, row + "horizon_reached");
    expect_double(csv.at(i, "force"), m.force, row + "force");
    expect_double(csv.at(i, "stop_forecast_force"), m.stop_forecast_force, row + "stop_forecast_force");
    expect_int(csv.at(i, "model_fits"), m.model_fits, row + "model_fits");
  }
}

TEST_F(Log2Csv, IdentificationColumnsNameEachParameterInTheOrderOfItsArraysAndReadBack) {
  pneu_lcm::identification_t m{};
  m.utime = kLogStart;
  m.t = 30.5;
  m.updates = 4;
  for (int i = 0; i < 13; ++i) {
    m.value[i] = 1.0 + i;
    m.sigma[i] = i == 12 ? kNaN : 0.1 * i;
    m.identified[i] = static_cast<std::int8_t>(i % 2);
  }
  const auto r = convert(write_log({{"PNEU_IDENTIFICATION", kLogStart, encode(m)}}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Csv csv = read_csv("PNEU_IDENTIFICATION.csv");
  EXPECT_EQ(csv.header,
            split_header("log_utime,utime,t,updates,"
             "static_positive_n,static_positive_n_sigma,static_positive_n_identified,"
             "static_negative_n,static_negative_n_sigma,static_negative_n_identified,"
             "coulomb_positive_n,coulomb_positive_n_sigma,coulomb_positive_n_identified,"
             "coulomb_negative_n,coulomb_negative_n_sigma,coulomb_negative_n_identified,"
             "viscous_n_s_per_m,viscous_n_s_per_m_sigma,viscous_n_s_per_m_identified,"
             "max_conductance_m3_per_s_pa,max_conductance_m3_per_s_pa_sigma,max_conductance_m3_per_s_pa_identified,"
             "leak_conductance_in_m3_per_s_pa,leak_conductance_in_m3_per_s_pa_sigma,"
             "leak_conductance_in_m3_per_s_pa_identified,"
             "leak_conductance_out_m3_per_s_pa,leak_conductance_out_m3_per_s_pa_sigma,"
             "leak_conductance_out_m3_per_s_pa_identified,"
             "null_offset_v,null_offset_v_sigma,null_offset_v_identified,"
             "dead_volume_p_m3,dead_volume_p_m3_sigma,dead_volume_p_m3_identified,"
             "dead_volume_n_m3,dead_volume_n_m3_sigma,dead_volume_n_m3_identified,"
             "heat_transfer_w_per_m2_k,heat_transfer_w_per_m2_k_sigma,heat_transfer_w_per_m2_k_identified,"
             "spool_time_constant_s,spool_time_constant_s_sigma,spool_time_constant_s_identified"))
      << "the spelling of every column, as before: the config keys' last parts (controller::kIdentifiedParameterKeys)";
  ASSERT_EQ(csv.rows.size(), 1u);
  EXPECT_EQ(csv.at(0, "max_conductance_m3_per_s_pa"), "6");
  EXPECT_EQ(csv.at(0, "max_conductance_m3_per_s_pa_identified"), "1");
  EXPECT_EQ(csv.at(0, "spool_time_constant_s_sigma"), "");
  // The message's constants name the same order as the keys.
  const auto index_of = [](std::string_view key) {
    const auto& keys = pneu::controller::kIdentifiedParameterKeys;
    return static_cast<int>(std::find(keys.begin(), keys.end(), key) - keys.begin());
  };
  using I = pneu_lcm::identification_t;
  EXPECT_EQ(index_of("plant.friction.static_positive_n"), int{I::STATIC_POSITIVE_N});
  EXPECT_EQ(index_of("plant.friction.coulomb_negative_n"), int{I::COULOMB_NEGATIVE_N});
  EXPECT_EQ(index_of("plant.valve.max_conductance_m3_per_s_pa"), int{I::MAX_CONDUCTANCE});
  EXPECT_EQ(index_of("plant.valve.leak_conductance_out_m3_per_s_pa"), int{I::LEAK_OUT});
  EXPECT_EQ(index_of("plant.valve.null_offset_v"), int{I::NULL_OFFSET_V});
  EXPECT_EQ(index_of("plant.geometry.dead_volume_n_m3"), int{I::DEAD_VOLUME_N_M3});
  EXPECT_EQ(index_of("plant.thermal.heat_transfer_w_per_m2_k"), int{I::HEAT_TRANSFER_W_PER_M2_K});
  EXPECT_EQ(index_of("plant.valve.spool_time_constant_s"), int{I::SPOOL_TIME_CONSTANT_S});
}

TEST_F(Log2Csv, HealthAndCommandFieldsReadBack) {
  pneu_lcm::health_t h{};
  h.utime = kLogStart + 1;
  h.t = 12.000000000000002;
  h.mode = 1;
  h.ticks = 12001;
  h.overruns = 3;
  const double latency[4] = {1.5, 12.25, 80.125, 210.0625};
  const double compute[4] = {4.0e-1, 9.5, 30.75, 44.875};
  for (int i = 0; i < 4; ++i) {
    h.wake_latency_us[i] = latency[i];
    h.compute_us[i] = compute[i];
  }
  h.comms_errors = 2;
  h.telemetry_dropped = 5;
  h.commands_received = 100;
  h.commands_accepted = 85;
  h.commands_rejected = 15;
  h.rejected_malformed = 1;
  h.rejected_invalid = 2;
  h.rejected_rate = 3;
  h.rejected_mode = 4;
  h.rejected_sequence = 5;
  h.rejected_stale = 6;
  h.rejected_foreign = 7;
  h.rejected_oversized = 8;
  h.deadlines_skipped = 9;
  h.fault_cause = 10;
  h.faults = 11;
  h.is_final = true;
  h.host = "bench-pc";
  h.pid = 4321;
  h.start_utime = kLogStart - 5'000'000;
  h.nonce = -1234567890123;
  h.period = 0.25;

  std::vector<pneu_lcm::command_t> commands;
  const std::vector<std::string> names = {"set_point", "set_point_step", "arm",      "disarm",
                                          "fault_reset", "hold_on",      "hold_off", "unknown"};
  for (int k = 1; k <= 8; ++k) {
    pneu_lcm::command_t c{};
    c.utime = kLogStart + 10 * k;
    c.seq = 1000 + k * k;
    c.kind = static_cast<std::int8_t>(k);
    c.value = k == 2 ? -0.0015 : 0.05 * k;
    // Who sent it: quoted in the CSV; a byte that is not printable ASCII comes out as '?'.
    const std::string origin = k == 2 ? "a \"quoted\", sender\x07" : "pneu-dash 127.0.0.1:8765";
    std::copy(origin.begin(), origin.end(), c.origin);
    c.session = 1000000 + k;
    commands.push_back(c);
  }
  std::vector<Entry> log = {{"PNEU_HEALTH", kLogStart + 2, encode(h)}};
  for (std::size_t i = 0; i < commands.size(); ++i)
    log.push_back(
        {"PNEU_COMMAND", kLogStart + 20 + static_cast<std::int64_t>(i), encode(commands[i])});

  const auto r = convert(write_log(log));
  ASSERT_EQ(r.exit_code, 0) << r.err;

  const Csv health = read_csv("PNEU_HEALTH.csv");
  const std::vector<std::string> quantiles = {"min", "median", "p99", "max"};
  std::vector<std::string> expected_header = {"log_utime", "utime", "t",
                                              "mode",      "ticks", "overruns"};
  for (const auto& q : quantiles) expected_header.push_back("wake_latency_us_" + q);
  for (const auto& q : quantiles) expected_header.push_back("compute_us_" + q);
  for (const char* c : {"comms_errors", "telemetry_dropped", "commands_received",
                        "commands_accepted", "commands_rejected", "rejected_malformed",
                        "rejected_invalid", "rejected_rate", "rejected_mode", "rejected_sequence",
                        "rejected_stale", "rejected_foreign", "rejected_oversized", "deadlines_skipped",
                        "fault_cause", "faults", "is_final", "host", "pid", "start_utime", "nonce", "period"})
    expected_header.emplace_back(c);
  EXPECT_EQ(health.header, expected_header);
  EXPECT_EQ(health.header, split_header("log_utime,utime," + pneu::records::csv_header<pneu::controller::HealthMessage>()))
      << "the health's description";
  ASSERT_EQ(health.rows.size(), 1u);
  expect_int(health.at(0, "log_utime"), kLogStart + 2, "log_utime");
  expect_int(health.at(0, "utime"), h.utime, "utime");
  expect_double(health.at(0, "t"), h.t, "t");
  expect_int(health.at(0, "mode"), h.mode, "mode");
  expect_int(health.at(0, "ticks"), h.ticks, "ticks");
  expect_int(health.at(0, "overruns"), h.overruns, "overruns");
  for (int i = 0; i < 4; ++i) {
    expect_double(health.at(0, "wake_latency_us_" + quantiles[i]), latency[i], quantiles[i]);
    expect_double(health.at(0, "compute_us_" + quantiles[i]), compute[i], quantiles[i]);
  }
  const std::int64_t counters[] = {h.comms_errors,      h.telemetry_dropped, h.commands_received,
                                   h.commands_accepted, h.commands_rejected, h.rejected_malformed,
                                   h.rejected_invalid,  h.rejected_rate,     h.rejected_mode,
                                   h.rejected_sequence, h.rejected_stale,   h.rejected_foreign,
                                   h.rejected_oversized, h.deadlines_skipped, h.fault_cause,
                                   h.faults,            h.is_final};
  for (int i = 0; i < 17; ++i)
    expect_int(health.rows[0][static_cast<std::size_t>(14 + i)], counters[i],
               expected_header[static_cast<std::size_t>(14 + i)]);
  EXPECT_EQ(health.at(0, "host"), "bench-pc");
  expect_int(health.at(0, "pid"), h.pid, "pid");
  expect_int(health.at(0, "start_utime"), h.start_utime, "start_utime");
  expect_int(health.at(0, "nonce"), h.nonce, "nonce");
  expect_double(health.at(0, "period"), h.period, "period");

  const Csv cmd = read_csv("PNEU_COMMAND.csv");
  EXPECT_EQ(cmd.header, split_header("log_utime,utime,seq,kind,kind_name,value,origin,session"));
  ASSERT_EQ(cmd.rows.size(), commands.size());
  for (std::size_t i = 0; i < commands.size(); ++i) {
    const auto& c = commands[i];
    const std::string row = "command " + std::to_string(i) + " ";
    expect_int(cmd.at(i, "log_utime"), log[i + 1].timestamp, row + "log_utime");
    expect_int(cmd.at(i, "utime"), c.utime, row + "utime");
    expect_int(cmd.at(i, "seq"), c.seq, row + "seq");
    expect_int(cmd.at(i, "kind"), c.kind, row + "kind");
    EXPECT_EQ(cmd.at(i, "kind_name"), names[i]) << row;
    expect_double(cmd.at(i, "value"), c.value, row + "value");
    EXPECT_EQ(cmd.at(i, "origin"), i == 1 ? "a \"quoted\", sender?" : "pneu-dash 127.0.0.1:8765") << row;
    expect_int(cmd.at(i, "session"), c.session, row + "session");
  }
}

TEST_F(Log2Csv, UndecodableMessagesAreWrittenRawAndCounted) {
  pneu_lcm::state_t s{};
  s.seq = 1;
  auto whole = encode(s);
  auto cut = whole;
  cut.resize(30);  // its fingerprint, but too short
  auto padded = whole;
  padded.push_back(0);  // its fingerprint, one byte too many
  const std::vector<std::uint8_t> garbage = {0xde, 0xad, 0xbe, 0xef, 0x01,
                                             0x02, 0x03, 0x04, 0x05, 0x06};
  const std::vector<std::uint8_t> tiny = {0xab, 0xcd, 0xef};
  const auto r = convert(write_log({{"JUNK", kLogStart + 1, garbage},
                                    {"JUNK", kLogStart + 2, cut},
                                    {"JUNK", kLogStart + 3, padded},
                                    {"JUNK", kLogStart + 4, tiny},
                                    {"PNEU_STATE", kLogStart + 5, whole}}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("4 messages on 1 channel undecodable"));
  EXPECT_THAT(r.out, ContainsRegex("JUNK +unknown +4 +JUNK\\.csv"));
  EXPECT_THAT(outputs(), ::testing::ElementsAre("JUNK.csv", "PNEU_STATE.csv"));

  char state_fingerprint[17];
  std::snprintf(state_fingerprint, sizeof state_fingerprint, "%016llx",
                static_cast<unsigned long long>(pneu_lcm::state_t::getHash()));
  const Csv csv = read_csv("JUNK.csv");
  EXPECT_EQ(csv.header, split_header("log_utime,bytes,fingerprint_hex"));
  ASSERT_EQ(csv.rows.size(), 4u);
  EXPECT_EQ(csv.rows[0],
            (std::vector<std::string>{std::to_string(kLogStart + 1), "10", "deadbeef01020304"}));
  EXPECT_EQ(csv.rows[1],
            (std::vector<std::string>{std::to_string(kLogStart + 2), "30", state_fingerprint}));
  EXPECT_EQ(csv.rows[2],
            (std::vector<std::string>{std::to_string(kLogStart + 3), std::to_string(padded.size()),
                                      state_fingerprint}));
  EXPECT_EQ(csv.rows[3], (std::vector<std::string>{std::to_string(kLogStart + 4), "3", "abcdef"}));
  EXPECT_EQ(read_csv("PNEU_STATE.csv").rows.size(), 1u);
}

TEST_F(Log2Csv, ChannelCarryingSeveralTypesIsSplitByType) {
  const auto states = random_states(10, 3);
  pneu_lcm::command_t c{};
  c.kind = pneu_lcm::command_t::KIND_ARM;
  std::vector<Entry> log;
  for (std::size_t i = 0; i < states.size(); ++i) {
    log.push_back({"MIX", kLogStart + static_cast<std::int64_t>(i), encode(states[i])});
    if (i % 4 == 0) log.push_back({"MIX", kLogStart + static_cast<std::int64_t>(i), encode(c)});
  }
  log.push_back({"MIX", kLogStart + 99, {1, 2, 3, 4, 5, 6, 7, 8, 9}});
  const auto r = convert(write_log(log));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(outputs(),
              ::testing::ElementsAre("MIX.command_t.csv", "MIX.state_t.csv", "MIX.unknown.csv"));
  const Csv st = read_csv("MIX.state_t.csv");
  ASSERT_EQ(st.rows.size(), 10u);
  for (std::size_t i = 0; i < st.rows.size(); ++i)
    expect_int(st.at(i, "seq"), static_cast<std::int64_t>(i), "seq");
  EXPECT_EQ(read_csv("MIX.command_t.csv").rows.size(), 3u);
  EXPECT_EQ(read_csv("MIX.unknown.csv").rows.size(), 1u);
  EXPECT_THAT(r.out, ContainsRegex("MIX +command_t +3 +MIX\\.command_t\\.csv"));
}

TEST_F(Log2Csv, ChannelNamesBecomeSafeFileNamesWithoutCollisions) {
  pneu_lcm::command_t c{};
  const auto r = convert(write_log({{"bench/arm 1:STATE", kLogStart, encode(c)},
                                    {"a b", kLogStart + 1, encode(c)},
                                    {"a:b", kLogStart + 2, encode(c)},
                                    {"ok-name_1.x", kLogStart + 3, encode(c)}}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(outputs(), ::testing::ElementsAre("a_b-2.csv", "a_b.csv", "bench_arm_1_STATE.csv",
                                                "ok-name_1.x.csv"));
  EXPECT_THAT(r.err, HasSubstr("channel 'a:b' written to a_b-2.csv"));
}

TEST_F(Log2Csv, ChannelsOptionMatchesWholeNames) {
  pneu_lcm::command_t c{};
  const auto log = write_log({{"PNEU_STATE", kLogStart, encode(c)},
                              {"PNEU_EVENT", kLogStart + 1, encode(c)},
                              {"XPNEU_STATE", kLogStart + 2, encode(c)},
                              {"PNEU", kLogStart + 3, encode(c)},
                              {"PNEU_EVENT", kLogStart + 4, encode(c)}});
  const auto r = convert(log, "--channels 'PNEU_.*'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(outputs(), ::testing::ElementsAre("PNEU_EVENT.csv", "PNEU_STATE.csv"));
  EXPECT_EQ(read_csv("PNEU_EVENT.csv").rows.size(), 2u);
  EXPECT_THAT(r.out, HasSubstr("not matching --channels): 2 events on 2 channels"));
}

TEST_F(Log2Csv, MissingLogFileIsRefusedWithExitCode2) {
  const auto r = convert(dir_ / "no_such.lcmlog");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("no_such.lcmlog': no such file"));
  EXPECT_FALSE(fs::exists(out_dir_));
}

TEST_F(Log2Csv, TextFileIsNotAnLcmLog) {
  const fs::path p = dir_ / "in.csv";
  std::ofstream(p) << "t,y\n0,0.1\n1,0.2\n";
  const auto r = convert(p);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("not an LCM log"));
  EXPECT_FALSE(fs::exists(out_dir_));
}

TEST_F(Log2Csv, DirectoryIsNotAnLcmLog) {
  const auto r = convert(dir_);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("is a directory"));
  EXPECT_FALSE(fs::exists(out_dir_));
}

TEST_F(Log2Csv, EmptyLogIsValidAndHasNoEvents) {
  const auto r = convert(write_log({}));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("is empty"));
  EXPECT_THAT(outputs(), IsEmpty());
}

TEST_F(Log2Csv, TruncatedLogKeepsEveryCompleteEvent) {
  const auto states = random_states(100, 11);
  std::vector<Entry> log;
  for (std::size_t i = 0; i < states.size(); ++i)
    log.push_back({"PNEU_STATE", kLogStart + static_cast<std::int64_t>(i), encode(states[i])});
  const fs::path whole = write_log(log, "whole.lcmlog");
  const auto size = fs::file_size(whole);
  const std::size_t last_event =
      4 + 8 + 8 + 4 + 4 + std::string("PNEU_STATE").size() + log.back().data.size();
  // Cut inside the payload, the channel name, the header, right after the marker, inside it.
  for (const std::size_t cut :
       {std::size_t{1}, last_event - 30, last_event - 6, last_event - 4, last_event - 2}) {
    SCOPED_TRACE("cut " + std::to_string(cut) + " bytes");
    fs::remove_all(out_dir_);
    const fs::path truncated = dir_ / "in_truncated.lcmlog";
    fs::copy_file(whole, truncated, fs::copy_options::overwrite_existing);
    fs::resize_file(truncated, size - cut);
    const auto r = convert(truncated);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_THAT(r.err, HasSubstr("is truncated"));
    EXPECT_THAT(r.err, HasSubstr("the 99 complete events before them were converted"));
    EXPECT_THAT(r.err, HasSubstr("last " + std::to_string(last_event - cut) + " bytes"));
    const Csv csv = read_csv("PNEU_STATE.csv");
    ASSERT_EQ(csv.rows.size(), 99u);
    for (std::size_t i = 0; i < csv.rows.size(); ++i) {
      expect_int(csv.at(i, "seq"), static_cast<std::int64_t>(i), "seq");
      expect_double(csv.at(i, "force"), states[i].force, "force");
    }
  }
}

// Damage inside a log (not its end): LCM 1.3.1's reader stops at it and drops the event before
// it, so what can be promised is the damage located and the events before it in order.
TEST_F(Log2Csv, DamageInsideTheLogIsLocatedAndTheEventsBeforeItKept) {
  const auto states = random_states(4, 5);
  std::vector<Entry> head, rest;
  for (std::size_t i = 0; i < 4; ++i)
    (i < 2 ? head : rest)
        .push_back({"PNEU_STATE", kLogStart + static_cast<std::int64_t>(i), encode(states[i])});
  const std::string before = slurp(write_log(head, "head.lcmlog"));
  const fs::path damaged = dir_ / "in_damaged.lcmlog";
  std::ofstream(damaged, std::ios::binary)
      << before << "xyzzy" << slurp(write_log(rest, "rest.lcmlog"));

  const auto r = convert(damaged);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("is damaged at byte " + std::to_string(before.size())));
  const Csv csv = read_csv("PNEU_STATE.csv");
  ASSERT_GE(csv.rows.size(), 1u);
  ASSERT_LE(csv.rows.size(), 2u);
  for (std::size_t i = 0; i < csv.rows.size(); ++i)
    expect_int(csv.at(i, "seq"), static_cast<std::int64_t>(i), "seq");
  EXPECT_THAT(r.err, HasSubstr(std::to_string(csv.rows.size()) + " complete event"));
}

TEST_F(Log2Csv, BadCommandLinesExitWith2) {
  const fs::path log = write_log({});
  for (const std::string& args :
       {std::string(""), log.string(), log.string() + " a b", log.string() + " out --channels '('",
        log.string() + " out --bogus"}) {
    SCOPED_TRACE(args);
    const auto r = run(args);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_THAT(r.err, HasSubstr("pneu-log2csv: "));
  }
  EXPECT_THAT(run(log.string() + " x --channels '('").err, HasSubstr("--channels"));
  const fs::path file = dir_ / "in_a_file";
  std::ofstream(file) << "x";
  const auto r = run(log.string() + " " + file.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("not a directory"));
}

TEST_F(Log2Csv, FailedWriteExits1AndLeavesNoPartialFile) {
  pneu_lcm::command_t c{};
  const fs::path log = write_log({{"A", kLogStart, encode(c)}, {"B", kLogStart + 1, encode(c)}});
  fs::create_directories(out_dir_ / "B.csv");  // the output cannot be moved into place
  const auto r = convert(log);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("B.csv"));
  for (const auto& name : outputs()) EXPECT_THAT(name, Not(HasSubstr("partial"))) << name;
  EXPECT_TRUE(fs::is_directory(out_dir_ / "B.csv"));
}

}  // namespace
