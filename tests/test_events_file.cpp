// The events file's record of the commands' verdicts: one "command" event per verdict, JSON like
// the others, dated by the last tick the runtime drained.
#include <gtest/gtest.h>

#include <memory>
#include <sstream>

#include "pneu/controller/events_file.hpp"
#include "pneu/controller/runtime.hpp"

namespace {

using namespace pneu;

struct RuntimeWithEvents {
  std::ostringstream events;
  controller::EventsFile sink{events};
  controller::Runtime runtime{controller::PredictorModel{}, true, true};
  std::unique_ptr<controller::LoopOutputs> outputs = std::make_unique<controller::LoopOutputs>();

  RuntimeWithEvents() { runtime.add_sink(sink); }
  // Drains one tick at `t_s`: the runtime's clock for what comes between ticks.
  void tick(double t_s) {
    controller::TickRecord r;
    r.t_s = t_s;
    ASSERT_TRUE(outputs->ticks.try_push(r));
    runtime.drain(*outputs);
  }
};

TEST(EventsFile, WritesAnAcceptedCommandWithItsKindSequenceNumberAndValue) {
  RuntimeWithEvents r;
  r.tick(1.25);
  controller::CommandRecord c;
  c.accepted = true;
  c.decoded = true;
  c.kind = "set_point";
  c.seq = 1718000000000123;
  c.value = -0.005;
  c.text = "set point -5.000 mm";
  r.runtime.record_command(c);
  EXPECT_EQ(r.events.str(),
            "{\"event\":\"command\",\"t\":1.25,\"verdict\":\"accepted\",\"reason\":null,\"kind\":\"set_point\","
            "\"seq\":1718000000000123,\"value\":-0.005,\"text\":\"set point -5.000 mm\"}\n");
}

TEST(EventsFile, WritesARejectionWithItsReasonAndNullsForWhatDidNotDecode) {
  RuntimeWithEvents r;
  r.tick(0.5);
  controller::CommandRecord c;
  c.reason = "malformed";
  c.text = "malformed: \"LC02\" \\ cut\nshort\x01";
  r.runtime.record_command(c);
  EXPECT_EQ(r.events.str(),
            "{\"event\":\"command\",\"t\":0.5,\"verdict\":\"rejected\",\"reason\":\"malformed\",\"kind\":null,"
            "\"seq\":null,\"value\":null,\"text\":\"malformed: \\\"LC02\\\" \\\\ cut\\u000ashort\\u0001\"}\n");
}

}  // namespace
