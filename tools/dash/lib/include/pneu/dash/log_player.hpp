// A recorded LCM log (lcm-logger, lcm::LogFile) played into the dashboard instead of a live bench:
// play, pause, a rate and a time cursor. Its messages go to a sink at their recorded times (scaled
// by the rate); the cursor goes out as Foxglove time messages (capability "time"). Controlled over
// HTTP (attach()):
//   GET  /playback  {"playing":true,"rate":1,"position_s":12.5,"duration_s":60.2,"start_utime":...}
//   POST /playback  a JSON object with any of {"play":true|false, "seek_s":S, "rate":R}; answers
//                   the state as GET does, or 400 saying what was wrong.
// position_s and seek_s count from the log's first message.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "pneu/dash/server.hpp"

namespace lcm {
class LogFile;
}

namespace pneu::dash {

struct PlaybackState {
  bool playing = false;
  double rate = 1.0;
  double position_s = 0.0;
  double duration_s = 0.0;
  std::int64_t start_utime = 0;  ///< the first message's time, us since the epoch
  bool ended = false;            ///< the cursor reached the log's end
};

class LogPlayer {
 public:
  /// One message of the log: its channel, bytes and recorded time (us since the epoch).
  using Sink = std::function<void(const std::string& channel, const void* data, std::size_t size, std::int64_t utime)>;
  /// The cursor's time (ns since the epoch), about 20 times a second while playing.
  using TimeSink = std::function<void(std::uint64_t time_ns)>;

  /// Opens the log and reads it through once for its span; throws std::runtime_error when it
  /// cannot be read or holds no message. Paused at its start until play().
  LogPlayer(const std::filesystem::path& log, Sink sink, TimeSink time);
  ~LogPlayer();
  LogPlayer(const LogPlayer&) = delete;
  LogPlayer& operator=(const LogPlayer&) = delete;

  void play(bool on);
  /// Moves the cursor to `s` from the start (clamped to the log).
  void seek(double s);
  /// Playback speed, > 0 (1: as recorded).
  void set_rate(double rate);
  [[nodiscard]] PlaybackState state() const;

  /// Serves GET and POST /playback on `server` and adds the capability "time".
  void attach(Server& server);

 private:
  void run();
  // Under mutex_: the cursor now, in the log's time.
  [[nodiscard]] std::int64_t cursor_utime_locked() const;
  void read_next_locked();

  Sink sink_;
  TimeSink time_;
  std::unique_ptr<lcm::LogFile> log_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  bool playing_ = false;
  bool ended_ = false;
  double rate_ = 1.0;
  std::int64_t start_utime_ = 0, end_utime_ = 0;
  std::vector<std::pair<std::int64_t, std::int64_t>> index_;  // (time, file offset) of every 256th message
  std::int64_t anchor_log_utime_ = 0;                 // the cursor at anchor_wall_
  std::chrono::steady_clock::time_point anchor_wall_;
  // The next message, read ahead.
  bool have_next_ = false;
  std::string next_channel_;
  std::vector<std::uint8_t> next_data_;
  std::int64_t next_utime_ = 0;
  std::thread thread_;
};

}  // namespace pneu::dash
