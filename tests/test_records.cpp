// Records described once (pneu/records): from one description per record type follow its CSV
// columns and cells, its JSON object, its JSON Schema and its LCM message with the conversion to
// and from it. A test-only record (records_probe.hpp) carries a field added by one line, `added`:
// each of the four has it. The tick record (pneu/controller/records.hpp) is held to the same.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <unistd.h>

#include "pneu/controller/records.hpp"
#include "pneu/controller/trajectory_file.hpp"
#include "pneu/records/csv.hpp"
#include "pneu/records/json.hpp"
#include "pneu/records/lcm.hpp"
#include "pneu/records/schema.hpp"
#include "records_probe.hpp"
#ifdef PNEU_WITH_LCM
#include "pneu_lcm/state_t.hpp"
#include "pneu_lcm/state_t_members.hpp"
#include "pneu_test_lcm/probe_t.hpp"
#include "pneu_test_lcm/probe_t_members.hpp"
#endif

namespace {

using ::testing::HasSubstr;
using pneu::controller::Mode;
using pneu::controller::TickRecord;
using pneu::test::Light;
using pneu::test::ProbeRecord;
namespace records = pneu::records;
namespace fs = std::filesystem;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

ProbeRecord probe() {
  ProbeRecord r;
  r.n = 7;
  r.x_m = 0.1234567890123456;
  r.ok = true;
  r.light = Light::kBlinking;
  r.flags = 5;
  r.added_v = 1.5;
  r.not_described = 99;
  return r;
}

template <class R>
std::string csv_row(const R& r) {
  std::string s;
  records::write_csv_cells(s, r);
  return s;
}
template <class R>
std::string json_object(const R& r) {
  std::string s;
  records::write_json_object(s, r);
  return s;
}

TEST(Records, TheCsvHeaderNamesEachDescribedFieldOnceInOrderTheAddedOneToo) {
  EXPECT_EQ(records::csv_header<ProbeRecord>(), "n,x,ok,light,flags,added");
  EXPECT_EQ(records::csv_header<ProbeRecord>("_b"), "n_b,x_b,ok_b,light_b,flags_b,added_b");
}

TEST(Records, ACsvRowWritesEachKindAsItsFieldSaysAndNaNAsAnEmptyCell) {
  EXPECT_EQ(csv_row(probe()), "7,0.123456789012,1,2,5,1.5") << "x: 12 significant digits, as described";
  ProbeRecord r = probe();
  r.added_v = kNaN;
  r.x_m = -std::numeric_limits<double>::infinity();
  EXPECT_EQ(csv_row(r), "7,-inf,1,2,5,");
  std::string all_digits;
  records::write_csv_cells(all_digits, probe(), true, records::kDigitsToTheLastBit);
  EXPECT_EQ(all_digits, ",7,0.12345678901234559,1,2,5,1.5");
  std::string empty;
  records::write_csv_empty_cells<ProbeRecord>(empty, true);
  EXPECT_EQ(empty, ",,,,,,") << "one per field";
}

TEST(Records, AJsonObjectHasEachDescribedFieldAndNullForNoValue) {
  EXPECT_EQ(json_object(probe()), R"({"n":7,"x":0.123456789012,"ok":true,"light":2,"flags":5,"added":1.5})");
  ProbeRecord r = probe();
  r.added_v = kNaN;
  r.x_m = std::numeric_limits<double>::infinity();
  r.ok = false;
  EXPECT_EQ(json_object(r), R"({"n":7,"x":null,"ok":false,"light":2,"flags":5,"added":null})");
}

TEST(Records, TheJsonSchemaDescribesEachFieldWithItsKindUnitAndDocumentation) {
  const std::string schema = records::json_schema<ProbeRecord>("probe");
  EXPECT_THAT(schema, HasSubstr(R"("added": {"type": ["number", "null"], "description": "the field added by one line", "unit": "V"})"));
  EXPECT_THAT(schema, HasSubstr(R"("n": {"type": "integer", "description": "a count"})"));
  EXPECT_THAT(schema, HasSubstr(R"("ok": {"type": "boolean", "description": "a flag"})"));
  EXPECT_THAT(schema, HasSubstr(R"("required": ["n", "x", "ok", "light", "flags", "added"])"));
  EXPECT_THAT(schema, Not(HasSubstr("not_described")));
}

// Runs Python's jsonschema (Debian's python3-jsonschema) on each line of `lines` against
// `schema`: the number of lines it refused, or -1 when it cannot run.
int refused_by_the_schema(const std::string& schema, const std::vector<std::string>& lines) {
  const fs::path dir = fs::temp_directory_path() / ("pneu_records_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "schema.json") << schema;
  {
    std::ofstream out(dir / "objects.jsonl");
    for (const auto& l : lines) out << l << '\n';
  }
  const std::string script =
      "import json, sys, jsonschema\n"
      "schema = json.load(open(sys.argv[1]))\n"
      "jsonschema.Draft202012Validator.check_schema(schema)\n"
      "v = jsonschema.Draft202012Validator(schema)\n"
      "print(sum(1 for line in open(sys.argv[2]) if not v.is_valid(json.loads(line))))\n";
  std::ofstream(dir / "check.py") << script;
  const std::string cmd = "/usr/bin/python3 '" + (dir / "check.py").string() + "' '" + (dir / "schema.json").string() +
                          "' '" + (dir / "objects.jsonl").string() + "' > '" + (dir / "out").string() + "' 2>&1";
  const int status = std::system(cmd.c_str());
  std::ifstream in(dir / "out");
  int refused = -1;
  if (status == 0) in >> refused;
  fs::remove_all(dir);
  return refused;
}

TEST(Records, TheJsonObjectsFollowTheirSchemaAndOnesThatDoNotAreRefused) {
  ProbeRecord no_value = probe();
  no_value.added_v = kNaN;
  const std::string schema = records::json_schema<ProbeRecord>("probe");
  ASSERT_EQ(refused_by_the_schema(schema, {json_object(probe()), json_object(no_value)}), 0)
      << "python3-jsonschema (scripts/deps) must run";
  EXPECT_EQ(refused_by_the_schema(schema, {R"({"n":7,"x":0.1,"ok":true,"light":2,"flags":5})",  // no added
                                           R"({"n":7,"x":0.1,"ok":true,"light":2,"flags":5,"added":"1.5"})",
                                           R"({"n":7,"x":0.1,"ok":true,"light":2,"flags":5,"added":1,"other":1})"}),
            3);
}

TickRecord tick() {
  TickRecord r;
  r.seq = 41;
  r.t_s = 0.041;
  r.y_d_m = 0.1;
  r.y_m = 0.0123456789012;
  r.v_hat_m_per_s = -0.02;
  r.a_hat_m_per_s2 = 1.5;
  r.p_p_pa = 412345.6;
  r.p_n_pa = 398765.4;
  r.force_n = -12.25;
  r.u_v = 0.75;
  r.stuck = true;
  r.mode = Mode::kHold;
  r.sensor_validity = 4;
  return r;
}

TEST(Records, TheTickIsTheTrajectorysRowUnderTheSpellingOfStateT) {
  EXPECT_EQ(records::csv_header<TickRecord>(), "seq,t,y_d,y,v_hat,a_hat,p_p,p_n,force,u,stuck,mode,validity");
  EXPECT_EQ(pneu::controller::TrajectoryFile::header(),
            "seq,t,y_d,y,v_hat,a_hat,p_p,p_n,force,u,stuck,mode,validity,p_p_linearized,p_n_linearized,"
            "force_linearized,p_p_nonlinear,p_n_nonlinear,force_nonlinear");
  EXPECT_EQ(csv_row(tick()), "41,0.041,0.1,0.0123456789012,-0.02,1.5,412345.6,398765.4,-12.25,0.75,1,3,4");
}

TEST(Records, TheTicksJsonFollowsTheSchemaTheBuildInstalls) {
  std::ifstream in(fs::path(PNEU_BINARY_DIR) / "share/pneu/schemas/tick.schema.json");
  ASSERT_TRUE(in) << "pneu-records writes it at build time";
  const std::string installed((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(installed, records::json_schema<TickRecord>("https://pneu.invalid/schemas/tick.schema.json"))
      << "written from this description";
  TickRecord nan_force = tick();
  nan_force.force_n = kNaN;
  EXPECT_EQ(refused_by_the_schema(installed, {json_object(tick()), json_object(nan_force)}), 0);
}

#ifdef PNEU_WITH_LCM
TEST(Records, TheLcmMessageCarriesEachFieldTheAddedOneTooThroughItsBytes) {
  pneu_test_lcm::probe_t m{};
  m.utime = 123;
  records::to_lcm(probe(), m);
  EXPECT_EQ(m.added, 1.5);
  EXPECT_EQ(m.light, 2);
  EXPECT_EQ(m.ok, 1);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  ASSERT_EQ(m.encode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  pneu_test_lcm::probe_t decoded{};
  ASSERT_EQ(decoded.decode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  ProbeRecord back;
  records::from_lcm(decoded, back);
  const ProbeRecord sent = probe();
  EXPECT_EQ(back.n, sent.n);
  EXPECT_EQ(back.x_m, sent.x_m);
  EXPECT_EQ(back.ok, sent.ok);
  EXPECT_EQ(back.light, sent.light);
  EXPECT_EQ(back.flags, sent.flags);
  EXPECT_EQ(back.added_v, sent.added_v);
  EXPECT_EQ(back.not_described, 0) << "not described, not carried";
}

TEST(Records, TheLcmDefinitionDeclaresEachFieldWithItsTypeDocumentationAndUnit) {
  const std::string lcm = records::lcm_field_declarations<ProbeRecord>();
  EXPECT_EQ(lcm,
            "  int64_t n;          // a count\n"
            "  double  x;          // a length [m]\n"
            "  boolean ok;         // a flag\n"
            "  int8_t  light;      // an enumeration\n"
            "  int32_t flags;      // unsigned bits\n"
            "  double  added;      // the field added by one line [V]\n");
}

TEST(Records, TheTickGoesThroughStateTAndBackUnchanged) {
  pneu_lcm::state_t m{};
  records::to_lcm(tick(), m);
  EXPECT_EQ(m.p_p, 412345.6);
  EXPECT_EQ(m.mode, pneu_lcm::state_t::MODE_HOLD);
  TickRecord back;
  records::from_lcm(m, back);
  EXPECT_EQ(csv_row(back), csv_row(tick()));
}
#endif

}  // namespace
