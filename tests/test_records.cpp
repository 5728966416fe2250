// Records described once (pneu/records): from one description per record type follow its CSV
// columns and cells, its JSON object, its JSON Schema and its LCM message with the conversion to
// and from it. A test-only record (records_probe.hpp) carries a field added by one line, `added`:
// each of the four has it; another (ProbeLine) has a string, a named enumeration, a member's
// member, optional and nullable members and a view. The controller's records
// (pneu/controller/records.hpp, summary_record.hpp) are held to the same: the tick, the events
// file's lines, the forecast, the event message and the health through their LCM messages (whose
// fingerprints are those of the hand-written .lcm files they replace), the summary.
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
#include <vector>
#include <algorithm>
#include <unistd.h>

#include "pneu/controller/events_file.hpp"
#include "pneu/controller/records.hpp"
#include "pneu/controller/run_summary.hpp"
#include "pneu/controller/trajectory_file.hpp"
#include "pneu/records/csv.hpp"
#include "pneu/records/json.hpp"
#include "pneu/records/lcm.hpp"
#include "pneu/records/schema.hpp"
#include "records_probe.hpp"
#include "support/schema_check.hpp"
#ifdef PNEU_WITH_LCM
#include "pneu_lcm/event_t.hpp"
#include "pneu_lcm/event_t_members.hpp"
#include "pneu_lcm/health_t.hpp"
#include "pneu_lcm/health_t_members.hpp"
#include "pneu_lcm/identification_t.hpp"
#include "pneu_lcm/identification_t_members.hpp"
#include "pneu_lcm/prediction_t.hpp"
#include "pneu_lcm/prediction_t_members.hpp"
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
using pneu::test::ProbeLine;
using pneu::test::ProbeRecord;
using pneu::test::installed_schema;
using pneu::test::refused_by_the_schema;
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

ProbeLine probe_line() {
  ProbeLine l;
  l.note = "say \"hi\", twice";
  l.light = Light::kBlinking;
  l.inner.level_m = 0.25;
  l.count = 3;
  return l;
}

TEST(Records, FreeTextIsQuotedInCsvAndEscapedInJsonAndANamedEnumerationIsItsNumberAndNameInCsvItsNameInJson) {
  EXPECT_EQ(records::csv_header<ProbeLine>(), "note,light,light_name,level,tag,count");
  EXPECT_EQ(csv_row(probe_line()), R"("say ""hi"", twice",7,blinking,0.25,,3)")
      << "the wire number of the name, not the enumeration's value";
  EXPECT_EQ(json_object(probe_line()), R"({"note":"say \"hi\", twice","light":"blinking","level":0.25,"count":3})");
  std::string empty;
  records::write_csv_empty_cells<ProbeLine>(empty);
  EXPECT_EQ(empty, ",,,,,") << "six columns: the name has one of its own";
}

TEST(Records, AMemberWrittenWhenItsConditionHoldsIsLeftOutOtherwiseAndANullableOneIsNullWhenItsHolds) {
  ProbeLine l = probe_line();
  l.tag = "first";
  l.known = false;
  EXPECT_EQ(json_object(l), R"({"note":"say \"hi\", twice","light":"blinking","level":0.25,"tag":"first","count":null})");
  EXPECT_EQ(csv_row(l), R"("say ""hi"", twice",7,blinking,0.25,first,3)")
      << "CSV has every column, always; a word (const char*) as it is, free text quoted";
}

TEST(Records, AViewWritesItsOwnSelectionInItsOwnOrderAfterItsName) {
  std::string line;
  records::write_json_line(line, pneu::test::kProbeLineView, probe_line());
  EXPECT_EQ(line, "{\"event\":\"probe\",\"light\":\"blinking\",\"note\":\"say \\\"hi\\\", twice\",\"level\":0.25,\"count\":3}\n");
  static_assert(records::names_fields_of<ProbeLine>(pneu::test::kProbeLineView));
  constexpr const char* kNotAField[] = {"note", "nothing"};
  static_assert(!records::names_fields_of<ProbeLine>(records::View{"x", "", kNotAField}));
}

TEST(Records, TheSchemaOfStringsNamesOptionalAndNullableMembersTakesWhatTheyWriteAndRefusesTheRest) {
  const std::string schema = records::json_schema<ProbeLine>("probe_line");
  EXPECT_THAT(schema, HasSubstr(R"("light": {"enum": ["off", "on", "blinking"], "description": "an enumeration as text"})"));
  EXPECT_THAT(schema, HasSubstr(R"("count": {"type": ["integer", "null"], "description": "null when not known"})"));
  EXPECT_THAT(schema, HasSubstr(R"("required": ["note", "light", "level", "count"])")) << "tag is optional";
  ProbeLine l = probe_line();
  l.tag = "first";
  l.known = false;
  ASSERT_EQ(refused_by_the_schema(schema, {json_object(probe_line()), json_object(l)}), 0);
  EXPECT_EQ(refused_by_the_schema(schema, {R"({"note":"n","light":"dim","level":0.25,"count":3})",
                                           R"({"note":"n","light":"on","level":0.25})",
                                           R"({"note":1,"light":"on","level":0.25,"count":3})",
                                           R"({"note":"n","light":"on","level":0.25,"count":"3"})"}),
            4);
}

// Every kind of line the events file writes, each way it can be written.
std::vector<std::string> every_kind_of_events_line() {
  using pneu::controller::LoopEvent;
  namespace c = pneu::controller;
  std::ostringstream out;
  c::EventsFile sink(out);
  LoopEvent e;
  e.t_s = 1.25;
  e.stop_index = 2;
  e.y_m = 0.01;
  e.force_n = kNaN;
  e.y_d_m = 0.1;
  e.direction = -1;
  for (const auto kind : {LoopEvent::Kind::kStop, LoopEvent::Kind::kStart, LoopEvent::Kind::kFault,
                          LoopEvent::Kind::kFaultReset, LoopEvent::Kind::kResetRefused, LoopEvent::Kind::kHoldStart,
                          LoopEvent::Kind::kHoldEnd, LoopEvent::Kind::kMovementTest})
    for (const bool other : {false, true}) {
      e.kind = kind;
      e.restart = other;
      e.fault_cause = other ? c::FaultCause::kMovementTest : c::FaultCause::kComms;
      e.fault_key = other ? "controller.movement_test" : nullptr;
      e.hold_end = other ? c::HoldEnd::kMoved : c::HoldEnd::kSetPoint;
      e.movement_end = other ? c::MovementTestEnd::kFault : c::MovementTestEnd::kPassed;
      e.movement_test.finding = other ? c::MovementFinding::kTubesSwapped : c::MovementFinding::kPassed;
      sink.on_event(e);
    }
  c::ForecastRecord f;
  f.stop = 2;
  for (const std::uint32_t update : {0u, 3u})
    for (const bool fits : {true, false}) {
      f.update = update;
      f.prediction.model_fits = fits;
      f.prediction.will_restart = fits;
      f.prediction.t_restart_s = fits ? 4.5 : kNaN;
      sink.on_forecast(f);
    }
  c::CommandRecord command;
  command.reason = "rate";
  command.kind = "arm";
  command.text = "too many";
  for (const bool accepted : {false, true})
    for (const bool decoded : {false, true}) {
      command.accepted = accepted;
      command.decoded = decoded;
      sink.on_command(command);
    }
  sink.on_end(9.5);
  std::vector<std::string> lines;
  std::istringstream in(out.str());
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  return lines;
}

TEST(Records, EveryLineTheEventsFileWritesFollowsTheEventsSchemaTheBuildInstalls) {
  const std::string installed = installed_schema("events");
  ASSERT_FALSE(installed.empty()) << "pneu-records writes it at build time";
  const std::vector<std::string> lines = every_kind_of_events_line();
  ASSERT_EQ(lines.size(), 16u + 4u + 4u + 1u);
  for (const char* event : {"start", "stop", "fault", "fault_reset", "fault_reset_refused", "hold_start", "hold_end",
                            "movement_test", "prediction", "reforecast", "command", "end"})
    EXPECT_TRUE(std::any_of(lines.begin(), lines.end(),
                            [&](const std::string& l) { return l.starts_with("{\"event\":\"" + std::string(event) + "\""); }))
        << event;
  EXPECT_EQ(refused_by_the_schema(installed, lines), 0);
  EXPECT_EQ(refused_by_the_schema(installed, {R"({"event":"stop","t":1,"stop":2,"y":0.1,"y_d":0.1})",
                                              R"({"event":"halt","t":1})",
                                              R"({"event":"end","t":1,"stop":2})",
                                              R"({"event":"prediction","t":1,"stop":2,"t_stop":1,"method":"guessed",)"
                                              R"("will_restart":false,"direction":0,"t_restart":null,"u_star":0,)"
                                              R"("equilibrium_force":0,"tau_p":0,"tau_n":0,"min_margin":0,)"
                                              R"("horizon_reached":false})"}),
            4)
      << "no force; no such event; a member the line has not; no such method";
}

TEST(Records, TheForecastsAndTheEventMessagesJsonFollowTheSchemasTheBuildInstalls) {
  pneu::controller::ForecastRecord f;
  f.prediction.method = pneu::controller::PredictionMethod::kHeld;
  f.prediction.model_fits = false;
  std::string forecast;
  records::write_json_object(forecast, f);
  EXPECT_THAT(forecast, HasSubstr(R"("method":"held")"));
  EXPECT_EQ(refused_by_the_schema(installed_schema("forecast"), {forecast}), 0);
  pneu::controller::LoopEvent e;
  e.kind = pneu::controller::LoopEvent::Kind::kHoldEnd;
  std::string message;
  records::write_json_object(message, pneu::controller::event_message(e));
  EXPECT_THAT(message, HasSubstr(R"("kind":"hold_end")"));
  EXPECT_EQ(refused_by_the_schema(installed_schema("event_message"), {message}), 0);
}

TEST(Records, ASummaryWithTelemetryModbusAndFaultsFollowsTheInstalledSchemaAndOneShortOfAMemberDoesNot) {
  pneu::controller::RunSummaryRecord s;
  s.pneud = "0.1.0";
  s.exit_reason = "fault";
  s.exit_code = 3;
  s.fault_at_end = "comms";
  s.loop.epoch_monotonic_s = kNaN;
  s.faults.push_back({1.5, 0.01, "comms", "controller.comms_fault_after_s"});
  s.faults.push_back({2.5, 0.02, "e-stop", nullptr});
  s.telemetry.emplace();
  s.telemetry->commands.queue_full = 2;
  s.modbus.emplace();
  s.modbus->safe_output_on_closing.read_back_u_p_v = kNaN;
  std::ostringstream document;
  records::write_json_document(document, s);
  std::string one_line;
  records::write_json_object(one_line, s);
  EXPECT_THAT(one_line, HasSubstr(R"("faults":[{"t_s":1.5,"y_m":0.01,"cause":"comms","key":"controller.comms_fault_after_s"},)"
                                  R"({"t_s":2.5,"y_m":0.02,"cause":"e-stop"}])"));
  EXPECT_THAT(one_line, HasSubstr(R"("last_error":null)")) << "no errors";
  EXPECT_THAT(one_line, HasSubstr(R"("read_back_u_p_v":null,"read_back_u_n_v":null)"));
  EXPECT_THAT(document.str(), HasSubstr("\n  \"loop\": {\n    \"ticks\": 0,\n")) << "one member a line, indented";
  const std::string schema = installed_schema("summary");
  ASSERT_FALSE(schema.empty());
  pneu::controller::RunSummaryRecord none;
  none.exit_reason = "ok";
  EXPECT_EQ(refused_by_the_schema(schema, {one_line, json_object(none)}), 0);
  std::string short_of_one = one_line;
  short_of_one.replace(short_of_one.find(R"("exit_code":3,)"), 14, "");
  EXPECT_EQ(refused_by_the_schema(schema, {short_of_one}), 1);
}

TEST(Records, TheForecastMethodsAreNamedAsThePredictorNamesThem) {
  for (const auto& m : pneu::controller::kPredictionMethods) EXPECT_STREQ(m.name, pneu::controller::to_string(m.value));
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

// The fingerprint a message carries: lcm-gen's hash of the definition (what its generated header
// says, 0x... below, as lcm-gen wrote it from the hand-written .lcm files) rotated left by one bit.
constexpr std::uint64_t fingerprint_of_hash(std::uint64_t hash) { return (hash << 1) | (hash >> 63); }

TEST(Records, TheMessagesWrittenFromDescriptionsKeepTheirPinnedFingerprintsSoOldLogsDecode) {
  EXPECT_EQ(static_cast<std::uint64_t>(pneu_lcm::state_t::getHash()), fingerprint_of_hash(0x47b1a6eb2d982914ULL));
  // event_t changed on purpose in issue 31 (a command verdict's origin and session: who sent it):
  // logs recorded before decode their other channels, their events only with the older tools.
  EXPECT_EQ(static_cast<std::uint64_t>(pneu_lcm::event_t::getHash()), fingerprint_of_hash(0xf00c70fb1f46ac8dULL));
  EXPECT_EQ(static_cast<std::uint64_t>(pneu_lcm::prediction_t::getHash()), fingerprint_of_hash(0xba68c62bef413c1dULL));
  EXPECT_EQ(static_cast<std::uint64_t>(pneu_lcm::health_t::getHash()), fingerprint_of_hash(0x2a01330226809dfdULL));
  EXPECT_EQ(static_cast<std::uint64_t>(pneu_lcm::identification_t::getHash()),
            fingerprint_of_hash(0x3d13bd6016606726ULL));
  EXPECT_EQ(int{pneu_lcm::identification_t::MAX_CONDUCTANCE}, 5);
  EXPECT_EQ(int{pneu_lcm::identification_t::SPOOL_TIME_CONSTANT_S}, 12);
  EXPECT_EQ(int{pneu_lcm::event_t::KIND_START}, 1);
  EXPECT_EQ(int{pneu_lcm::event_t::KIND_MOVEMENT_TEST}, 12);
  EXPECT_EQ(int{pneu_lcm::event_t::KIND_HOLD_END}, int{pneu::controller::event_kind::kHoldEnd});
  EXPECT_EQ(int{pneu_lcm::prediction_t::METHOD_LINEARIZED}, 1);
  EXPECT_EQ(int{pneu_lcm::prediction_t::METHOD_HELD}, 4);
}

TEST(Records, TheForecastGoesThroughPredictionTsBytesAndBackUnchanged) {
  pneu::controller::ForecastRecord f;
  f.stop = 4;
  f.update = 2;
  f.t_s = 3.5;
  f.prediction.method = pneu::controller::PredictionMethod::kRelaxation;
  f.prediction.direction = -1;
  f.prediction.model_fits = false;
  f.stop_forecast_force_n = 12.5;
  pneu_lcm::prediction_t m{};
  records::to_lcm(f, m);
  EXPECT_EQ(m.method, int{pneu_lcm::prediction_t::METHOD_RELAXATION});
  EXPECT_EQ(m.direction, -1);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  ASSERT_EQ(m.encode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  pneu_lcm::prediction_t decoded{};
  ASSERT_EQ(decoded.decode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  pneu::controller::ForecastRecord back;
  records::from_lcm(decoded, back);
  EXPECT_EQ(csv_row(back), csv_row(f));
  EXPECT_EQ(json_object(back), json_object(f));
  std::string from_message;
  records::write_lcm_csv_cells<pneu::controller::ForecastRecord>(from_message, decoded);
  EXPECT_EQ(from_message, csv_row(f)) << "the message's CSV is the record's";
}

TEST(Records, TheHealthGoesThroughHealthTsBytesItsGroupsAsArraysAndBackUnchanged) {
  pneu::controller::HealthMessage h;
  h.t_s = 2.5;
  h.mode = 3;
  h.wake_latency_us = {1, 2, 3, 4};
  h.compute_us = {5, 6, 7, 8.5};
  h.rejected_stale = 9;
  h.is_final = true;
  h.host = "bench-1";
  h.period_s = 1.0;
  pneu_lcm::health_t m{};
  records::to_lcm(h, m);
  EXPECT_EQ(m.wake_latency_us[3], 4.0);
  EXPECT_EQ(m.compute_us[3], 8.5);
  EXPECT_EQ(m.host, "bench-1");
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  ASSERT_EQ(m.encode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  pneu_lcm::health_t decoded{};
  ASSERT_EQ(decoded.decode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  pneu::controller::HealthMessage back;
  records::from_lcm(decoded, back);
  EXPECT_EQ(csv_row(back), csv_row(h));
  EXPECT_EQ(json_object(back), json_object(h));
  std::string cells;
  records::write_lcm_csv_cells<pneu::controller::HealthMessage>(cells, decoded);
  EXPECT_EQ(cells, csv_row(h));
  EXPECT_THAT(records::csv_header<pneu::controller::HealthMessage>(),
              HasSubstr("overruns,wake_latency_us_min,wake_latency_us_median,wake_latency_us_p99,wake_latency_us_max,"
                        "compute_us_min,"));
  EXPECT_EQ(refused_by_the_schema(installed_schema("health"), {json_object(h)}), 0);
}

// Online identification's estimate: three arrays indexed by parameter, separate in LCM and JSON,
// interleaved per parameter in CSV.
pneu::controller::IdentificationRecord identification() {
  pneu::controller::IdentificationRecord r;
  r.t_s = 30.5;
  r.updates = 4;
  for (std::size_t i = 0; i < r.value.size(); ++i) {
    r.value[i] = 1.0 + static_cast<double>(i);
    r.sigma[i] = i == 12 ? kNaN : 0.25 * static_cast<double>(i);
    r.identified[i] = i % 2 == 1;
  }
  return r;
}

TEST(Records, TheIdentificationGoesThroughIdentificationTsBytesItsArraysIndexedByParameterAndBackUnchanged) {
  const auto r = identification();
  pneu_lcm::identification_t m{};
  records::to_lcm(r, m);
  EXPECT_EQ(m.updates, 4);
  EXPECT_EQ(m.value[pneu_lcm::identification_t::MAX_CONDUCTANCE], 6.0);
  EXPECT_EQ(m.sigma[2], 0.5);
  EXPECT_EQ(m.identified[5], 1);
  EXPECT_EQ(m.identified[6], 0);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  ASSERT_EQ(m.encode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  pneu_lcm::identification_t decoded{};
  ASSERT_EQ(decoded.decode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  pneu::controller::IdentificationRecord back;
  records::from_lcm(decoded, back);
  EXPECT_EQ(back.value, r.value);
  EXPECT_EQ(back.identified, r.identified);
  EXPECT_EQ(csv_row(back), csv_row(r));
  EXPECT_EQ(json_object(back), json_object(r));
  std::string cells;
  records::write_lcm_csv_cells<pneu::controller::IdentificationRecord>(cells, decoded);
  EXPECT_EQ(cells, csv_row(r));
  EXPECT_THAT(cells, ::testing::StartsWith("30.5,4,1,0,0,2,0.25,1,3,0.5,0,"));
  EXPECT_THAT(cells, ::testing::EndsWith(",13,,0"));
}

TEST(Records, TheIdentificationsColumnsInterleaveEachParametersValueSigmaAndFlagItsJsonKeysEachArrayByParameter) {
  const std::string header = records::csv_header<pneu::controller::IdentificationRecord>();
  EXPECT_THAT(header, ::testing::StartsWith("t,updates,static_positive_n,static_positive_n_sigma,"
                                            "static_positive_n_identified,static_negative_n,"));
  EXPECT_THAT(header, ::testing::EndsWith(",spool_time_constant_s,spool_time_constant_s_sigma,"
                                          "spool_time_constant_s_identified"));
  EXPECT_EQ(records::csv_column_count<pneu::controller::IdentificationRecord>(), 2u + 3u * 13u);
  const std::string json = json_object(identification());
  EXPECT_THAT(json, HasSubstr(R"("value":{"static_positive_n":1,"static_negative_n":2,)"));
  EXPECT_THAT(json, HasSubstr(R"("spool_time_constant_s":null},"identified":{"static_positive_n":false,)"));
  const std::string schema = installed_schema("identification");
  EXPECT_EQ(refused_by_the_schema(schema, {json}), 0);
  std::string short_of_one = json;
  short_of_one.replace(short_of_one.find(R"("static_negative_n":2,)"), std::string(R"("static_negative_n":2,)").size(), "");
  std::string a_flag_as_number = json;
  a_flag_as_number.replace(a_flag_as_number.find(R"("static_positive_n":false)"),
                           std::string(R"("static_positive_n":false)").size(), R"("static_positive_n":0)");
  EXPECT_EQ(refused_by_the_schema(schema, {short_of_one, a_flag_as_number}), 2);
}

TEST(Records, AnEventMessageCarriesItsTextThroughEventTAndAnUnknownKindIsWrittenAsItCame) {
  pneu::controller::LoopEvent e;
  e.kind = pneu::controller::LoopEvent::Kind::kStart;
  e.restart = true;
  pneu_lcm::event_t m{};
  records::to_lcm(pneu::controller::event_message(e), m);
  EXPECT_EQ(m.kind, int{pneu_lcm::event_t::KIND_RESTART});
  EXPECT_EQ(m.text, "restart after a stop, set point unchanged");
  pneu::controller::EventMessage back;
  records::from_lcm(m, back);
  EXPECT_EQ(back.text, m.text);
  m.kind = 99;
  m.text = "a \"quoted\" word";
  std::string cells;
  records::write_lcm_csv_cells<pneu::controller::EventMessage>(cells, m);
  EXPECT_THAT(cells, ::testing::StartsWith("99,unknown,"));
  EXPECT_THAT(cells, ::testing::EndsWith(R"(,"a ""quoted"" word")"));
}
#endif

}  // namespace
