// A record that exists only for tests/test_records.cpp: one field of each kind a record may have,
// and one more added by one line (`added`), which the test finds in the CSV, the JSON, the JSON
// Schema and the LCM message without anything else written for it.
#pragma once

#include <cstdint>
#include <tuple>

#include "pneu/records/record.hpp"

namespace pneu::test {

enum class Light : std::uint8_t { kOff = 0, kOn = 1, kBlinking = 2 };

struct ProbeRecord {
  std::uint64_t n = 0;
  double x_m = 0.0;
  bool ok = false;
  Light light = Light::kOff;
  std::uint32_t flags = 0;
  double added_v = 0.0;
  int not_described = 0;  ///< a member the outside world does not see
};

}  // namespace pneu::test

template <>
struct pneu::records::Description<pneu::test::ProbeRecord> {
  using R = pneu::test::ProbeRecord;
  static constexpr const char* kName = "probe";
  static constexpr const char* kDoc = "a record for the tests of the records' formats";
  static constexpr auto kFields = std::tuple{
      field("n", &R::n, "", "a count"),
      field("x", &R::x_m, "m", "a length", 12),
      field("ok", &R::ok, "", "a flag"),
      field("light", &R::light, "", "an enumeration"),
      field("flags", &R::flags, "", "unsigned bits"),
      field("added", &R::added_v, "V", "the field added by one line"),
  };
};
