// pneu-records: the files that follow from the records' descriptions (pneu/records/record.hpp,
// pneu/controller/records.hpp): the LCM messages' definitions for lcm-gen with the conversion's
// member lists (the build runs it before lcm-gen), and the JSON Schemas of the records as JSON.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>

#include "pneu/config/cli.hpp"
#include "pneu/controller/records.hpp"
#include "pneu/records/lcm.hpp"
#include "pneu/records/schema.hpp"

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
    if (cpp)
      write_if_changed(fs::path(*cpp) / "pneu_lcm" / "state_t_members.hpp",
                       records::lcm_members_header<controller::TickRecord>("pneu_lcm", "state_t"));
  }
  if (schemas) {
    write_if_changed(fs::path(*schemas) / "tick.schema.json",
                     records::json_schema<controller::TickRecord>("https://pneu.invalid/schemas/tick.schema.json"));
    write_if_changed(fs::path(*schemas) / "expected.schema.json",
                     records::json_schema<controller::ForecastPoint>("https://pneu.invalid/schemas/expected.schema.json"));
  }
  return cli::kExitOk;
}

}  // namespace

int main(int argc, char** argv) { return pneu::cli::run_main("pneu-records", run, argc, argv); }
