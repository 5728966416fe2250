// The journal's lines (JournalLines): each fault, reset, refused reset, arming, disarming, hold
// start and end, and the link to the device lost and back is one line, written as its record is
// handed over, with the syslog priority prefix journald reads.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "pneu/controller/journal.hpp"
#include "pneu/controller/movement_test.hpp"
#include "pneu/hal/types.hpp"

namespace {

using namespace pneu::controller;
using ::testing::HasSubstr;
using ::testing::StartsWith;

// A sink writing to a memory stream, and what it wrote so far.
class Journal {
 public:
  Journal() : out_(open_memstream(&buffer_, &size_)), lines_(out_) {}
  ~Journal() {
    std::fclose(out_);
    std::free(buffer_);
  }
  JournalLines& sink() { return lines_; }
  std::string text() {
    std::fflush(out_);
    return std::string(buffer_, size_);
  }

 private:
  char* buffer_ = nullptr;
  std::size_t size_ = 0;
  std::FILE* out_;
  JournalLines lines_;
};

TickRecord tick(double t_s, Mode mode, std::uint32_t validity = 0) {
  TickRecord r;
  r.t_s = t_s;
  r.mode = mode;
  r.y_m = 0.095;
  r.y_d_m = 0.095;
  r.sensor_validity = validity;
  return r;
}

LoopEvent event(LoopEvent::Kind kind, double t_s, FaultCause cause = FaultCause::kNone) {
  LoopEvent e;
  e.kind = kind;
  e.t_s = t_s;
  e.fault_cause = cause;
  return e;
}

TEST(JournalLines, AFaultIsOneErrorLineNamingItsCauseWrittenAsItsEventArrives) {
  Journal j;
  j.sink().on_tick(tick(0.0, Mode::kArmed), {});
  EXPECT_EQ(j.text(), "") << "a tick like the last says nothing";
  j.sink().on_event(event(LoopEvent::Kind::kFault, 1.25, FaultCause::kComms));
  EXPECT_THAT(j.text(), StartsWith("<3>pneud: FAULT at 1.250 s (y = 0.000 mm): comms: sensor samples stale"));
  EXPECT_EQ(j.sink().lines(), 1);
  EXPECT_EQ(j.text().back(), '\n');
}

TEST(JournalLines, ResetsAndRefusedResetsAreNoticeAndWarningLines) {
  Journal j;
  j.sink().on_event(event(LoopEvent::Kind::kResetRefused, 2.0, FaultCause::kEStop));
  j.sink().on_event(event(LoopEvent::Kind::kFaultReset, 3.0, FaultCause::kEStop));
  const std::string text = j.text();
  EXPECT_THAT(text, HasSubstr("<4>pneud: fault reset refused at 2.000 s: the cause is still present (e-stop)"));
  EXPECT_THAT(text, HasSubstr("\n<5>pneud: fault (e-stop) reset at 3.000 s: disarmed, send ARM to drive\n"));
}

TEST(JournalLines, ArmingAndDisarmingAreNoticeLinesButAFaultsResetIsNoArming) {
  Journal j;
  j.sink().on_tick(tick(0.0, Mode::kDisarmed), {});
  j.sink().on_tick(tick(0.5, Mode::kArmed), {});
  j.sink().on_tick(tick(0.6, Mode::kHold), {});
  j.sink().on_tick(tick(0.7, Mode::kDisarmed), {});
  j.sink().on_tick(tick(0.8, Mode::kFault), {});
  j.sink().on_tick(tick(0.9, Mode::kDisarmed), {});  // a reset: its own event says so
  const std::string text = j.text();
  EXPECT_THAT(text, StartsWith("<5>pneud: armed at 0.500 s: the law drives the valves, holding 95.000 mm\n"));
  EXPECT_THAT(text, HasSubstr("\n<5>pneud: disarmed at 0.700 s (y = 95.000 mm): valve power off"));
  EXPECT_EQ(j.sink().lines(), 2) << text;
}

TEST(JournalLines, TheHoldsStartAndEndAreInfoLines) {
  Journal j;
  LoopEvent start = event(LoopEvent::Kind::kHoldStart, 1.0);
  start.y_m = 0.0951;
  start.y_d_m = 0.095;
  j.sink().on_event(start);
  LoopEvent end = event(LoopEvent::Kind::kHoldEnd, 2.0);
  end.hold_end = HoldEnd::kSetPoint;
  j.sink().on_event(end);
  const std::string text = j.text();
  EXPECT_THAT(text, StartsWith("<6>pneud: hold from 1.000 s: at rest at 95.100 mm, within the window of the set point 95.000 mm\n"));
  EXPECT_THAT(text, HasSubstr("\n<6>pneud: hold ended at 2.000 s (y = 0.000 mm): setpoint\n"));
}

// The movement test at the first ARM: arming into it, its pass with the figures, and a finding
// as the fault's error line naming it.
TEST(JournalLines, TheMovementTestAtArmIsANoticeWhenItStartsAndPassesAndItsFindingTheFaultsErrorLine) {
  Journal j;
  j.sink().on_tick(tick(0.0, Mode::kDisarmed), {});
  j.sink().on_tick(tick(0.5, Mode::kMovementTest), {});
  LoopEvent passed = event(LoopEvent::Kind::kMovementTest, 1.4);
  passed.movement_end = MovementTestEnd::kPassed;
  passed.y_d_m = 0.2195;
  passed.movement_test.pulses = 2;
  passed.movement_test.duration_s = 0.9;
  j.sink().on_event(passed);
  j.sink().on_tick(tick(1.4, Mode::kArmed), {});
  EXPECT_THAT(j.text(), StartsWith("<5>pneud: armed at 0.500 s: the movement test first (controller.movement_test)"));
  EXPECT_THAT(j.text(), HasSubstr("\n<5>pneud: movement test passed at 1.400 s: passed in 0.90 s (y 0.0 -> 0.0 mm): "
                                  "u_0 +0.00 V for 0.00 s"));
  EXPECT_THAT(j.text(), HasSubstr("; the law drives the valves, holding 219.500 mm\n"));
  EXPECT_EQ(j.sink().lines(), 2) << "the pass arms: no second arming line";

  Journal k;
  LoopEvent found = event(LoopEvent::Kind::kMovementTest, 2.0);
  found.movement_end = MovementTestEnd::kFinding;
  found.movement_test.finding = MovementFinding::kTubesSwapped;
  k.sink().on_event(found);
  EXPECT_EQ(k.text(), "") << "the fault's line names it";
  LoopEvent fault = event(LoopEvent::Kind::kFault, 2.0, FaultCause::kMovementTest);
  fault.movement_test = found.movement_test;
  k.sink().on_event(fault);
  EXPECT_THAT(k.text(), StartsWith("<3>pneud: FAULT at 2.000 s (y = 0.000 mm): movement-test: tubes-swapped: tubes "
                                   "swapped: +u moved the carriage towards -y"));
  EXPECT_THAT(k.text(), HasSubstr("reset the fault, and the next ARM tests again\n"));

  Journal a;
  LoopEvent aborted = event(LoopEvent::Kind::kMovementTest, 3.0, FaultCause::kEStop);
  aborted.movement_end = MovementTestEnd::kFault;
  a.sink().on_event(aborted);
  EXPECT_EQ(a.text(), "<5>pneud: movement test aborted at 3.000 s (y = 0.000 mm) by a fault: e-stop: the next ARM runs "
                      "it again\n");
}

TEST(JournalLines, TheLinkLostAndBackAreOneLineEachNotOnePerTick) {
  Journal j;
  j.sink().on_tick(tick(0.000, Mode::kArmed), {});
  for (int k = 1; k <= 100; ++k)
    j.sink().on_tick(tick(0.001 * k, Mode::kArmed, pneu::hal::kCommsError | pneu::hal::kSampleStale), {});
  j.sink().on_tick(tick(0.101, Mode::kArmed, pneu::hal::kSampleStale), {});  // stale, but the link is up
  j.sink().on_tick(tick(0.102, Mode::kArmed), {});
  const std::string text = j.text();
  EXPECT_THAT(text, StartsWith("<4>pneud: link to the device lost at 0.001 s"));
  EXPECT_THAT(text, HasSubstr("\n<5>pneud: link to the device back at 0.101 s, after 0.100 s\n"));
  EXPECT_EQ(j.sink().lines(), 2) << text;
}

TEST(JournalLines, StartAndStopEventsAreNotTheJournals) {
  Journal j;
  j.sink().on_event(event(LoopEvent::Kind::kStop, 1.0));
  j.sink().on_event(event(LoopEvent::Kind::kStart, 2.0));
  EXPECT_EQ(j.text(), "");
}

}  // namespace
