// Writes the test-only record's LCM message, as pneu-records does for the product's records:
//   records_probe_gen LCM_DIR CPP_DIR  ->  LCM_DIR/probe_t.lcm, CPP_DIR/pneu_test_lcm/probe_t_members.hpp
#include <filesystem>
#include <fstream>

#include "pneu/records/lcm.hpp"
#include "records_probe.hpp"

int main(int argc, char** argv) {
  if (argc != 3) return 2;
  namespace fs = std::filesystem;
  using pneu::test::ProbeRecord;
  fs::create_directories(fs::path(argv[2]) / "pneu_test_lcm");
  std::ofstream(fs::path(argv[1]) / "probe_t.lcm")
      << pneu::records::lcm_message_text<ProbeRecord>("pneu_test_lcm", "probe_t", "A probe.", "tests/records_probe.hpp",
                                                      "  int64_t utime;      // microseconds since the Unix epoch\n",
                                                      "  const int8_t LIGHT_BLINKING = 2;\n");
  std::ofstream(fs::path(argv[2]) / "pneu_test_lcm" / "probe_t_members.hpp")
      << pneu::records::lcm_members_header<ProbeRecord>("pneu_test_lcm", "probe_t");
  return 0;
}
