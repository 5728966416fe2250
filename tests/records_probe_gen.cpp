// Writes the test-only record's LCM message, as pneu-records does for the product's records:
//   records_probe_gen LCM_DIR CPP_DIR  ->  LCM_DIR/probe_t.lcm, CPP_DIR/pneu_test_lcm/probe_t_members.hpp
// A file it cannot write fails the build here, naming the file (exit 1), not later at compiling it.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "pneu/records/lcm.hpp"
#include "records_probe.hpp"

namespace {
bool write(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  out.close();
  if (out) return true;
  std::fprintf(stderr, "records_probe_gen: cannot write %s\n", path.c_str());
  return false;
}
}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: records_probe_gen LCM_DIR CPP_DIR\n");
    return 2;
  }
  namespace fs = std::filesystem;
  using pneu::test::ProbeRecord;
  std::error_code ec;
  fs::create_directories(fs::path(argv[2]) / "pneu_test_lcm", ec);
  const bool ok =
      write(fs::path(argv[1]) / "probe_t.lcm",
            pneu::records::lcm_message_text<ProbeRecord>("pneu_test_lcm", "probe_t", "A probe.", "tests/records_probe.hpp",
                                                         "  int64_t utime;      // microseconds since the Unix epoch\n",
                                                         "  const int8_t LIGHT_BLINKING = 2;\n")) &&
      write(fs::path(argv[2]) / "pneu_test_lcm" / "probe_t_members.hpp",
            pneu::records::lcm_members_header<ProbeRecord>("pneu_test_lcm", "probe_t"));
  return ok ? 0 : 1;
}
