// A record that exists only for tests/test_records.cpp: one field of each kind a record may have,
// and one more added by one line (`added`), which the test finds in the CSV, the JSON, the JSON
// Schema and the LCM message without anything else written for it.
#pragma once

#include <cstdint>
#include <string>
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

namespace pneu::test {

/// What a line record may hold beyond numbers: a string, an enumeration written as text, a
/// member's member, a member written only sometimes, one that may be null.
struct ProbeInner {
  double level_m = 0.0;
};
struct ProbeLine {
  std::string note;
  Light light = Light::kOff;
  ProbeInner inner;
  const char* tag = nullptr;  ///< written only when there is one
  bool known = true;
  std::int64_t count = 0;     ///< null when not known
};

inline constexpr pneu::records::Named<Light> kLightNames[] = {
    {Light::kOff, 0, "off"}, {Light::kOn, 1, "on"}, {Light::kBlinking, 7, "blinking"}};
inline constexpr const char* kProbeLineFields[] = {"light", "note", "level", "tag", "count"};
inline constexpr pneu::records::View kProbeLineView{"probe", "a line of a probe", kProbeLineFields};

}  // namespace pneu::test

template <>
struct pneu::records::Description<pneu::test::ProbeLine> {
  using R = pneu::test::ProbeLine;
  static constexpr const char* kName = "probe_line";
  static constexpr const char* kDoc = "a record for the tests of strings, names, members' members, optional and nullable members";
  static constexpr auto kFields = std::tuple{
      field("note", &R::note, "", "free text"),
      field("light", &R::light, "", "an enumeration as text").named(pneu::test::kLightNames),
      field("level", &R::inner, &pneu::test::ProbeInner::level_m, "m", "a member's member"),
      field("tag", &R::tag, "", "written when there is one").when(+[](const R& r) { return r.tag != nullptr; }),
      field("count", &R::count, "", "null when not known").null_when(+[](const R& r) { return !r.known; }),
  };
};
