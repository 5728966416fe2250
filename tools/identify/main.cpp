// pneu-identify: the bench identified offline, from the record of an ordinary run: pneud's
// --trajectory file, pneu-log2csv's state CSV, or an LCM log of the daemon's <prefix>STATE.
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "pneu/config/cli.hpp"
#include "pneu/config/config.hpp"
#include "pneu/config/yaml_text.hpp"
#include "pneu/identify/identification_run.hpp"
#include "pneu/identify/identify.hpp"
#if PNEU_WITH_LCM
#include <lcm/lcm-cpp.hpp>

#include "pneu_lcm/state_t.hpp"
#endif

namespace {

using namespace pneu;

constexpr const char* kHelp = R"(pneu-identify: the bench identified from the record of a run

Usage:
  pneu-identify (--trajectory FILE.csv | --lcm-log FILE [--channel NAME]) [--config FILE]
                [--out OUT.yaml] [--quiet]
  pneu-identify --help | --version

  --trajectory FILE  a CSV with a header naming t, y, p_p, p_n (p_P, p_N: an older pneud's) and u, and
                     optionally mode (1 = armed: the valves driven with +-u; other rows are left out
                     of the valve fit): pneud's --trajectory file, or pneu-log2csv's state CSV
  --lcm-log FILE     an LCM log (lcm-logger) of the daemon's state messages ...
  --channel NAME     ... on this channel (default: the config's telemetry.channel_prefix + STATE)
  --config FILE      the configuration of the run (default: the effective configuration pneud
                     wrote beside --trajectory, FILE.csv.config.yaml, else the embedded
                     config/sim.yaml): plant:
                     is the prior (what is not identified is kept), the stop detector's rest band
                     says how still a stuck carriage reads
  --out OUT.yaml     write the configuration with plant: identified: the text of --config (its
                     comments kept), each identified value replaced in place with its uncertainty
                     beside it, under a header saying when, from which record, with which residual
  --quiet            no report on stdout

What it estimates and how is pneud --identify's (see docs/identification.md); from an
ordinary run it can only see what the run showed: a parameter the record cannot tell apart from
the others is reported as such and kept. A record with no sticking phase, no breakaway, or no
stuck phase long enough to fit the valves is refused, naming what is missing (exit 2).

Exit codes: 0 identified, 1 I/O failure, 2 bad command line, configuration or record.
)";

// The columns of a CSV header line.
std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) cells.push_back(cell);
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

std::vector<identify::Sample> read_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw cli::UsageError("cannot open " + path);
  std::string line;
  if (!std::getline(in, line)) throw cli::UsageError(path + ": empty");
  const std::vector<std::string> header = split(line);
  std::map<std::string, std::size_t> at;
  for (std::size_t i = 0; i < header.size(); ++i) at.emplace(header[i], i);
  const auto column = [&](std::initializer_list<const char*> names) -> std::size_t {
    for (const char* n : names)
      if (const auto it = at.find(n); it != at.end()) return it->second;
    throw cli::UsageError(path + ": no column " + *names.begin());
  };
  const std::size_t t = column({"t"}), y = column({"y"}), pp = column({"p_p", "p_P"}), pn = column({"p_n", "p_N"}),
                    u = column({"u"});
  const auto mode_it = at.find("mode");
  std::vector<identify::Sample> samples;
  std::size_t row = 1;
  while (std::getline(in, line)) {
    ++row;
    if (line.empty()) continue;
    const std::vector<std::string> cells = split(line);
    const auto number = [&](std::size_t c) {
      if (c >= cells.size() || cells[c].empty())
        throw cli::UsageError(path + ":" + std::to_string(row) + ": column " + header[c] + " is empty");
      std::size_t used = 0;
      double v = 0;
      try {
        v = std::stod(cells[c], &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != cells[c].size() || !std::isfinite(v))
        throw cli::UsageError(path + ":" + std::to_string(row) + ": " + header[c] + " is not a number: " + cells[c]);
      return v;
    };
    identify::Sample s{number(t), number(y), number(pp), number(pn), number(u), true};
    if (mode_it != at.end()) s.driven = number(mode_it->second) == 1.0;
    if (!samples.empty() && !(s.t_s > samples.back().t_s))
      throw cli::UsageError(path + ":" + std::to_string(row) + ": t does not increase");
    samples.push_back(s);
  }
  return samples;
}

#if PNEU_WITH_LCM
std::vector<identify::Sample> read_lcm_log(const std::string& path, const std::string& channel) {
  lcm::LogFile log(path, "r");
  if (!log.good()) throw cli::UsageError("cannot open the LCM log " + path);
  std::vector<identify::Sample> samples;
  long undecodable = 0;
  while (const lcm::LogEvent* e = log.readNextEvent()) {
    if (e->channel != channel) continue;
    pneu_lcm::state_t m{};
    if (m.decode(e->data, 0, e->datalen) != e->datalen) {
      ++undecodable;
      continue;
    }
    if (!samples.empty() && !(m.t > samples.back().t_s)) continue;  // a repeat, or a restart of the daemon
    samples.push_back({m.t, m.y, m.p_p, m.p_n, m.u, m.mode == pneu_lcm::state_t::MODE_ARMED || m.mode == pneu_lcm::state_t::MODE_HOLD});
  }
  if (undecodable > 0)
    std::fprintf(stderr, "pneu-identify: %ld messages on %s are not state_t: left out\n", undecodable, channel.c_str());
  if (samples.empty()) throw cli::UsageError(path + ": no state_t message on " + channel);
  return samples;
}
#endif

int run(int argc, char** argv) {
  const cli::Args args(argc, argv, 1, {"trajectory", "lcm-log", "channel", "config", "out"},
                       {"quiet", "help", "version"});
  if (args.flag("help")) {
    std::cout << kHelp;
    return cli::kExitOk;
  }
  if (args.flag("version")) {
    std::printf("pneu-identify %s\n", PNEU_VERSION);
    return cli::kExitOk;
  }
  const auto trajectory = args.value("trajectory");
  const auto lcm_log = args.value("lcm-log");
  // The run's own configuration, when pneud wrote it beside the trajectory.
  std::string config_path = args.value("config").value_or("");
  if (config_path.empty() && trajectory && std::filesystem::is_regular_file(*trajectory + ".config.yaml"))
    config_path = *trajectory + ".config.yaml";
  // Its text too: its comments are kept in the configuration written.
  const std::string config_text = config::text_of(config_path);
  const config::Config cfg = config::load_string(config_text, {}, config_path.empty() ? "<embedded sim.yaml>" : config_path);
  if (trajectory.has_value() == lcm_log.has_value()) throw cli::UsageError("give one of --trajectory and --lcm-log");
  std::optional<cli::OutputFile> out;
  if (const auto p = args.value("out")) out.emplace(*p, "--out");  // an unwritable path fails first
  std::vector<identify::Sample> samples;
  std::string source;
  if (trajectory) {
    samples = read_csv(*trajectory);
    source = "the trajectory " + *trajectory;
  } else {
#if PNEU_WITH_LCM
    const std::string channel = args.value("channel").value_or(cfg.telemetry.channel_prefix + "STATE");
    samples = read_lcm_log(*lcm_log, channel);
    source = "the LCM log " + *lcm_log + " (" + channel + ")";
#else
    throw cli::UsageError("--lcm-log: this build has no LCM (PNEU_WITH_LCM=OFF); convert the log elsewhere with pneu-log2csv");
#endif
  }
  identify::Identification id;
  try {
    id = identify::identify(samples, cfg.plant, identify::options_for(cfg));
  } catch (const identify::InsufficientData& e) {
    throw cli::UsageError(std::string("the record cannot identify the bench: ") + e.what());
  }
  if (!args.flag("quiet")) {
    std::printf("identified from %zu samples over %.3f s:\n", samples.size(), samples.back().t_s - samples.front().t_s);
    identify::print_report(stdout, id);
  }
  if (out) {
    char record[64];
    std::snprintf(record, sizeof record, ": %zu samples over %.2f s", samples.size(),
                  samples.back().t_s - samples.front().t_s);
    const identify::IdentifiedYaml yaml = identify::identified_config_yaml(
        config_text, cfg, id,
        {"pneu-identify " PNEU_VERSION, args.command_line(), source + record, config_path, std::time(nullptr)});
    out->stream() << yaml.text;
    out->commit();
    if (!args.flag("quiet")) std::printf("written: %s\n", out->path().c_str());
    if (!yaml.text_not_kept.empty())
      std::fprintf(stderr, "pneu-identify: warning: %s: the whole configuration, without the comments of %s: %s\n",
                   out->path().c_str(), config_path.empty() ? "the embedded sim.yaml" : config_path.c_str(),
                   yaml.text_not_kept.c_str());
  }
  return cli::kExitOk;
}

}  // namespace

int main(int argc, char** argv) { return pneu::cli::run_main("pneu-identify", run, argc, argv); }
