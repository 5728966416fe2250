// The journal's lines (JournalLines): each fault, reset, refused reset, arming, disarming, hold
// start and end, and the link to the device lost and back is one line, written as its record is
// handed over, with the syslog priority prefix journald reads.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "pneu/controller/journal.hpp"
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
