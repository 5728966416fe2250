// The sweep's rows described once (pneu/sweep/rows.hpp): the stops and scenarios files' columns
// are the descriptions', every row has as many cells as the header, and the rows of a real sweep
// follow the JSON Schemas the build installs; so does its summary (pneu/sweep/summary_record.hpp),
// with and without --identify's part.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/records/csv.hpp"
#include "pneu/records/json.hpp"
#include "pneu/sweep/report.hpp"
#include "pneu/sweep/rows.hpp"
#include "support/schema_check.hpp"

namespace {

using namespace pneu;
using test::installed_schema;
using test::refused_by_the_schema;

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  return lines;
}

// Cells of a CSV line (a quoted cell holds no comma in these files but the reason, which is
// counted as one).
std::size_t cells(const std::string& line) {
  std::size_t n = 1;
  bool quoted = false;
  for (const char c : line) {
    if (c == '"') quoted = !quoted;
    else if (c == ',' && !quoted) ++n;
  }
  return n;
}

// Six scenarios of the shipped default, run once, with the identification's failure of a
// seventh made by hand (it did not run).
class SweepRows : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const config::Config config = config::load_file_or_default("");
    sweep::Options o;
    o.steps = 6;
    const auto scenarios = sweep::draw_scenarios(o, config.plant.geometry.half_stroke_m());
    options_ = o;
    results_ = new std::vector<sweep::ScenarioResult>(sweep::run_all(config, o, scenarios, 2).results);
    sweep::ScenarioResult failed = results_->front();
    failed.scenario.index = 6;
    failed.identification_failed = "too little \"shown\"";
    failed.stops.clear();
    results_->push_back(failed);
  }
  static void TearDownTestSuite() { delete results_; }
  static std::vector<sweep::ScenarioResult>* results_;
  static sweep::Options options_;
};
std::vector<sweep::ScenarioResult>* SweepRows::results_ = nullptr;
sweep::Options SweepRows::options_;

TEST_F(SweepRows, TheStopsFilesHeaderIsTheDescriptionsAndEachRowHasACellForEachColumn) {
  std::ostringstream out;
  sweep::write_stops_csv(out, *results_, false);
  const auto lines = lines_of(out.str());
  ASSERT_GT(lines.size(), 7u);
  EXPECT_EQ(lines[0], records::csv_header<sweep::StopRow>());
  EXPECT_THAT(lines[0], ::testing::HasSubstr(",lin_will_restart,lin_t_restart_s,") ) << "a group's columns, prefixed";
  for (std::size_t i = 1; i < lines.size(); ++i) EXPECT_EQ(cells(lines[i]), cells(lines[0])) << lines[i];
}

TEST_F(SweepRows, EachScenarioRowHasACellForEachColumnAFailedIdentificationsToo) {
  for (const bool identify : {false, true}) {
    std::ostringstream out;
    sweep::write_scenarios_csv(out, *results_, identify);
    const auto lines = lines_of(out.str());
    ASSERT_EQ(lines.size(), results_->size() + 1);
    EXPECT_EQ(lines[0], records::csv_header<sweep::ScenarioRow>(identify ? sweep::kIdentifiedScenarioColumns
                                                                          : sweep::kScenarioColumns));
    EXPECT_EQ(identify, lines[0].find(",identified_static_positive_n,") != std::string::npos);
    for (std::size_t i = 1; i < lines.size(); ++i) EXPECT_EQ(cells(lines[i]), cells(lines[0])) << lines[i];
    if (identify) {
      EXPECT_THAT(lines.back(), ::testing::EndsWith(",\"too little 'shown'\",,,"));
    }
  }
}

TEST_F(SweepRows, TheRowsOfARealSweepFollowTheSchemasTheBuildInstalls) {
  std::vector<std::string> stops, scenarios;
  for (const sweep::ScenarioResult& r : *results_) {
    std::string s;
    records::write_json_object(s, sweep::scenario_row(r));
    scenarios.push_back(s);
    for (const sweep::JudgedStop& j : r.stops) {
      for (const bool online : {false, true}) {
        std::string t;
        records::write_json_object(t, sweep::stop_row(r, j, online));
        stops.push_back(t);
      }
    }
  }
  ASSERT_GT(stops.size(), 10u);
  const std::string stop_schema = installed_schema("sweep_stop"), scenario_schema = installed_schema("sweep_scenario");
  ASSERT_FALSE(stop_schema.empty());
  ASSERT_FALSE(scenario_schema.empty());
  EXPECT_EQ(refused_by_the_schema(stop_schema, stops), 0);
  EXPECT_EQ(refused_by_the_schema(scenario_schema, scenarios), 0);
  EXPECT_THAT(scenarios.back(), ::testing::HasSubstr(R"("identification_failed":"too little 'shown'")"));
  EXPECT_THAT(scenarios.back(), ::testing::HasSubstr(R"("bench":{"static_positive_n":)")) << "a group: an object";
  EXPECT_EQ(refused_by_the_schema(scenario_schema, {R"({"scenario":1})"}), 1);
}

TEST_F(SweepRows, TheSummaryOfARealSweepFollowsTheSchemaTheBuildInstallsWithAndWithoutTheIdentification) {
  const config::Config config = config::load_file_or_default("");
  sweep::Setting setting = sweep::setting_of(config, options_);
  const sweep::Statistics plain = sweep::aggregate(setting, *results_);
  setting.options.identify = true;
  const sweep::Statistics identified = sweep::aggregate(setting, *results_);
  std::string a, b;
  records::write_json_object(a, sweep::summary_record(plain));
  records::write_json_object(b, sweep::summary_record(identified));
  EXPECT_THAT(a, ::testing::Not(::testing::HasSubstr(R"("identification":)")));
  EXPECT_THAT(b, ::testing::HasSubstr(R"("failed":["scenario 6: too little)"));
  EXPECT_THAT(a, ::testing::HasSubstr(R"("long_within":{"2_percent":)"));
  EXPECT_THAT(a, ::testing::HasSubstr(R"("outcomes":{"settled":{"count":)"));
  const std::string schema = installed_schema("sweep_summary");
  ASSERT_FALSE(schema.empty());
  EXPECT_EQ(refused_by_the_schema(schema, {a, b}), 0);
  std::string short_of_one = a;
  short_of_one.replace(short_of_one.find(R"("jobs":)"), std::string(R"("jobs":)").size(), R"("threads":)");
  EXPECT_EQ(refused_by_the_schema(schema, {short_of_one}), 1);
  std::ostringstream document;
  sweep::write_summary_json(document, plain);
  EXPECT_THAT(document.str(), ::testing::StartsWith("{\n  \"scenarios\": "));
}

}  // namespace
