// What an operator must hear at the moment it happens, as one line each on stderr with the syslog
// priority prefix journald reads (sd-daemon.h's SD_ERR "<3>", SD_WARNING "<4>", SD_NOTICE "<5>",
// SD_INFO "<6>"): a sink of the runtime (JournalLines) on the service thread, never on the loop's.
// Faults, fault resets and refused resets, arming and disarming, the movement test's pass or abort
// at ARM (a finding is its fault's line), the in-position hold's start and end, and the backend's
// link to its device lost and back. pneud writes them quiet or not: they are
// the journal's.
#pragma once

#include <cstdio>
#include <string_view>

#include "pneu/controller/loop.hpp"
#include "pneu/controller/run_listener.hpp"

namespace pneu::controller {

/// The syslog priorities pneud's lines carry.
enum class Priority : int { kErr = 3, kWarning = 4, kNotice = 5, kInfo = 6 };

/// Writes "<N>pneud: `text`\n" to `out` and flushes it, so that the line is there at once.
void journal_line(std::FILE* out, Priority priority, std::string_view text);

class JournalLines final : public RunListener {
 public:
  /// Writes to `out` (stderr for pneud), which must outlive the sink.
  explicit JournalLines(std::FILE* out) : out_(out) {}

  /// Arming and disarming (the mode each tick record carries), the link lost and back (its
  /// sensor validity's hal::kCommsError).
  void on_tick(const TickRecord& tick, const ExpectedAtTick& expected) override;
  /// Faults, resets, refused resets, the movement test's end, the hold's start and end.
  void on_event(const LoopEvent& event) override;

  /// Lines written so far.
  [[nodiscard]] int lines() const noexcept { return lines_; }

 private:
  void line(Priority priority, const char* format, ...) __attribute__((format(printf, 3, 4)));

  std::FILE* out_;
  int lines_ = 0;
  bool seen_tick_ = false;
  Mode mode_ = Mode::kArmed;  // of the last tick record
  bool link_down_ = false;
  double link_down_since_s_ = 0.0;
};

}  // namespace pneu::controller
