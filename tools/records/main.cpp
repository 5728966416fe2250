// pneu-records: the files that follow from the records' descriptions (pneu/records/record.hpp,
// pneu/controller/records.hpp): the LCM messages' definitions for lcm-gen with the conversion's
// member lists (the build runs it before lcm-gen), and the JSON Schemas of the records as JSON.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "pneu/config/cli.hpp"
#include "pneu/controller/records.hpp"
#include "pneu/controller/summary_record.hpp"
#include "pneu/records/lcm.hpp"
#include "pneu/records/schema.hpp"
#include "pneu/sweep/rows.hpp"
#include "pneu/sweep/summary_record.hpp"

namespace {

using namespace pneu;
namespace fs = std::filesystem;

constexpr const char* kHelp = R"(pneu-records: the files that follow from the records' descriptions

Usage:
  pneu-records --lcm DIR [--cpp DIR]   the LCM messages described by records, DIR/<message>.lcm
                                       (for lcm-gen); with --cpp, the members each record field
                                       is carried by, DIR/pneu_lcm/<message>_members.hpp
  pneu-records --schemas DIR           the JSON Schema of each record's JSON object,
                                       DIR/<record>.schema.json
  pneu-records --help | --version

A file whose content is unchanged is not written again (the build does not redo what follows).
Exit codes: 0 written, 1 I/O failure, 2 bad command line.
)";

// Writes `text` to `path` unless it already holds exactly that.
void write_if_changed(const fs::path& path, const std::string& text) {
  {
    std::ifstream in(path, std::ios::binary);
    if (in) {
      const std::string old((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (old == text) return;
    }
  }
  fs::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  out.close();
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

// state_t: the tick, on <prefix>STATE.
std::string state_t_lcm() {
  std::string constants = "  const int8_t ";
  bool first = true;
  for (const auto& [mode, name] : controller::kModeNames) {
    if (!first) constants += ", ";
    first = false;
    constants += std::string("MODE_") + name + " = " + std::to_string(static_cast<int>(mode));
  }
  constants += ";\n";
  return records::lcm_message_text<controller::TickRecord>(
      "pneu_lcm", "state_t", "Per-tick state of one axis, published at the loop rate on <prefix>STATE.",
      "controller/include/pneu/controller/records.hpp",
      "  int64_t utime;      // time of the sample, microseconds since the Unix epoch\n", constants);
}

// event_t: an event, on <prefix>EVENT.
std::string event_t_lcm() {
  return records::lcm_message_text<controller::EventMessage>(
      "pneu_lcm", "event_t", "Something that happened, on <prefix>EVENT.", "controller/include/pneu/controller/records.hpp",
      "  int64_t utime;      // microseconds since the Unix epoch\n", "");
}

// prediction_t: a forecast, on <prefix>PREDICTION.
std::string prediction_t_lcm() {
  return records::lcm_message_text<controller::ForecastRecord>(
      "pneu_lcm", "prediction_t",
      "A restart forecast (docs/model.md section 6), on <prefix>PREDICTION: made at a stop (update 0), then,\n"
      "// while the carriage stays stuck under the same u*, made again from the pressures of the moment\n"
      "// every controller.predictor.update_period_s (update 1, 2, ...).\n"
      "// METHOD_RELAXATION: each chamber's relaxation fitted to the pressures since the stop (no valve\n"
      "// model); made again only (update >= 1), its tau_* and *_equilibrium the fitted ones, and\n"
      "// stop_forecast_force NaN.\n"
      "// METHOD_HELD: while the in-position hold holds the stop, the pressure equations integrated\n"
      "// under the hold's own commands (its PI law closed on the model's force); made again only\n"
      "// (update >= 1), u_star the hold's command then, equilibrium_force the force it settles on\n"
      "// (reaching: the force at the breakaway it forecasts), stop_forecast_force NaN.",
      "controller/include/pneu/controller/records.hpp",
      "  int64_t utime;      // microseconds since the Unix epoch\n", "");
}

// health_t: the daemon's health, on <prefix>HEALTH.
std::string health_t_lcm() {
  return records::lcm_message_text<controller::HealthMessage>(
      "pneu_lcm", "health_t", records::Description<controller::HealthMessage>::kDoc,
      "controller/include/pneu/controller/records.hpp",
      "  int64_t utime;      // microseconds since the Unix epoch\n", "");
}

// identification_t: the running estimate of online identification, on <prefix>IDENTIFICATION.
std::string identification_t_lcm() {
  return records::lcm_message_text<controller::IdentificationRecord>(
      "pneu_lcm", "identification_t", records::Description<controller::IdentificationRecord>::kDoc,
      "controller/include/pneu/controller/records.hpp",
      "  int64_t utime;      // microseconds since the Unix epoch\n", "");
}

// The JSON Schema of a line of the events file: one of its views.
std::string events_schema() {
  std::vector<std::string> lines;
  for (const records::View& v : controller::kEventLineViews)
    lines.push_back(records::json_line_schema<controller::EventLine>(v));
  lines.push_back(records::json_line_schema<controller::ForecastRecord>(controller::kPredictionLine));
  lines.push_back(records::json_line_schema<controller::ForecastRecord>(controller::kReforecastLine));
  lines.push_back(records::json_line_schema<controller::CommandRecord>(controller::kCommandLine));
  return records::json_lines_schema("https://pneu.invalid/schemas/events.schema.json", "events",
                                    "a line of the events file (pneud --events): one JSON object a line, its "
                                    "\"event\" member naming which",
                                    lines);
}

int run(int argc, char** argv) {
  const cli::Args args(argc, argv, 1, {"lcm", "cpp", "schemas"}, {"help", "version"}, {});
  if (args.flag("help")) {
    std::cout << kHelp;
    return cli::kExitOk;
  }
  if (args.flag("version")) {
    std::printf("pneu-records %s\n", PNEU_VERSION);
    return cli::kExitOk;
  }
  const auto lcm = args.value("lcm");
  const auto cpp = args.value("cpp");
  const auto schemas = args.value("schemas");
  if (!lcm && !schemas) throw cli::UsageError("give --lcm DIR or --schemas DIR");
  if (cpp && !lcm) throw cli::UsageError("--cpp goes with --lcm");
  if (lcm) {
    write_if_changed(fs::path(*lcm) / "state_t.lcm", state_t_lcm());
    write_if_changed(fs::path(*lcm) / "event_t.lcm", event_t_lcm());
    write_if_changed(fs::path(*lcm) / "prediction_t.lcm", prediction_t_lcm());
    write_if_changed(fs::path(*lcm) / "health_t.lcm", health_t_lcm());
    write_if_changed(fs::path(*lcm) / "identification_t.lcm", identification_t_lcm());
    if (cpp) {
      const fs::path dir = fs::path(*cpp) / "pneu_lcm";
      write_if_changed(dir / "state_t_members.hpp", records::lcm_members_header<controller::TickRecord>("pneu_lcm", "state_t"));
      write_if_changed(dir / "event_t_members.hpp",
                       records::lcm_members_header<controller::EventMessage>("pneu_lcm", "event_t"));
      write_if_changed(dir / "prediction_t_members.hpp",
                       records::lcm_members_header<controller::ForecastRecord>("pneu_lcm", "prediction_t"));
      write_if_changed(dir / "health_t_members.hpp",
                       records::lcm_members_header<controller::HealthMessage>("pneu_lcm", "health_t"));
      write_if_changed(dir / "identification_t_members.hpp",
                       records::lcm_members_header<controller::IdentificationRecord>("pneu_lcm", "identification_t"));
    }
  }
  if (schemas) {
    write_if_changed(fs::path(*schemas) / "tick.schema.json",
                     records::json_schema<controller::TickRecord>("https://pneu.invalid/schemas/tick.schema.json"));
    write_if_changed(fs::path(*schemas) / "expected.schema.json",
                     records::json_schema<controller::ForecastPoint>("https://pneu.invalid/schemas/expected.schema.json"));
    write_if_changed(fs::path(*schemas) / "forecast.schema.json",
                     records::json_schema<controller::ForecastRecord>("https://pneu.invalid/schemas/forecast.schema.json"));
    write_if_changed(fs::path(*schemas) / "event_message.schema.json",
                     records::json_schema<controller::EventMessage>(
                         "https://pneu.invalid/schemas/event_message.schema.json"));
    write_if_changed(fs::path(*schemas) / "events.schema.json", events_schema());
    write_if_changed(fs::path(*schemas) / "health.schema.json",
                     records::json_schema<controller::HealthMessage>("https://pneu.invalid/schemas/health.schema.json"));
    write_if_changed(fs::path(*schemas) / "identification.schema.json",
                     records::json_schema<controller::IdentificationRecord>(
                         "https://pneu.invalid/schemas/identification.schema.json"));
    write_if_changed(fs::path(*schemas) / "summary.schema.json",
                     records::json_schema<controller::RunSummaryRecord>("https://pneu.invalid/schemas/summary.schema.json"));
    write_if_changed(fs::path(*schemas) / "sweep_stop.schema.json",
                     records::json_schema<sweep::StopRow>("https://pneu.invalid/schemas/sweep_stop.schema.json"));
    write_if_changed(fs::path(*schemas) / "sweep_summary.schema.json",
                     records::json_schema<sweep::SweepSummary>("https://pneu.invalid/schemas/sweep_summary.schema.json"));
    write_if_changed(fs::path(*schemas) / "sweep_scenario.schema.json",
                     records::json_schema<sweep::ScenarioRow>("https://pneu.invalid/schemas/sweep_scenario.schema.json"));
  }
  return cli::kExitOk;
}

}  // namespace

int main(int argc, char** argv) { return pneu::cli::run_main("pneu-records", run, argc, argv); }
