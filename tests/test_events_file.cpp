// The events file's record of the commands' verdicts: one "command" event per verdict, JSON like
// the others, dated by the last tick the runtime drained. And the movement test at ARM: its end,
// and its finding on the fault it latches.
#include <gtest/gtest.h>

#include <memory>
#include <sstream>
#include <string>

#include "pneu/controller/events_file.hpp"
#include "pneu/controller/runtime.hpp"

namespace {

using namespace pneu;

struct RuntimeWithEvents {
  std::ostringstream events;
  controller::EventsFile sink{events};
  controller::Runtime runtime{controller::PredictorModel{}, nullptr, true, true};
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

TEST(EventsFile, WritesAnAcceptedCommandWithItsKindSequenceNumberValueAndWhoSentIt) {
  RuntimeWithEvents r;
  r.tick(1.25);
  controller::CommandRecord c;
  c.accepted = true;
  c.decoded = true;
  c.kind = "set_point";
  c.seq = 1718000000000123;
  c.value = -0.005;
  c.origin = "pneu-dash 127.0.0.1:8765";
  c.session = 4503599627370497;
  c.text = "set point -5.000 mm";
  r.runtime.record_command(c);
  EXPECT_EQ(r.events.str(),
            "{\"event\":\"command\",\"t\":1.25,\"verdict\":\"accepted\",\"reason\":null,\"kind\":\"set_point\","
            "\"seq\":1718000000000123,\"value\":-0.005,\"origin\":\"pneu-dash 127.0.0.1:8765\","
            "\"session\":4503599627370497,\"text\":\"set point -5.000 mm\"}\n");
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
            "\"seq\":null,\"value\":null,\"origin\":null,\"session\":null,"
            "\"text\":\"malformed: \\\"LC02\\\" \\\\ cut\\u000ashort\\u0001\"}\n");
}

TEST(EventsFile, WritesTheMovementTestsEndAndTheFindingOnItsFault) {
  std::ostringstream out;
  controller::EventsFile sink{out};
  controller::LoopEvent e;
  e.kind = controller::LoopEvent::Kind::kMovementTest;
  e.t_s = 2.5;
  e.movement_end = controller::MovementTestEnd::kFinding;
  e.movement_test.finding = controller::MovementFinding::kTubesSwapped;
  e.movement_test.pulses = 1;
  e.movement_test.duration_s = 0.25;
  e.movement_test.y_start_m = e.movement_test.y_end_m = 0.2195;
  sink.on_event(e);
  e.kind = controller::LoopEvent::Kind::kFault;
  e.fault_cause = controller::FaultCause::kMovementTest;
  e.fault_key = "controller.movement_test";
  sink.on_event(e);
  std::istringstream lines(out.str());
  std::string test, fault;
  std::getline(lines, test);
  std::getline(lines, fault);
  EXPECT_EQ(test.substr(0, test.find(",\"text\":")),
            "{\"event\":\"movement_test\",\"t\":2.5,\"end\":\"finding\",\"finding\":\"tubes-swapped\",\"pulses\":1,"
            "\"duration\":0.25,\"y_start\":0.2195,\"y_end\":0.2195");
  EXPECT_NE(test.find(",\"text\":\"tubes-swapped in 0.25 s (y 219.5 -> 219.5 mm): u_0 +0.00 V"), std::string::npos) << test;
  EXPECT_NE(fault.find("\"cause\":\"movement-test\""), std::string::npos) << fault;
  EXPECT_NE(fault.find(",\"key\":\"controller.movement_test\",\"finding\":\"tubes-swapped\"}"), std::string::npos) << fault;
}

}  // namespace
