#include "pneu/dash/log_player.hpp"

#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace pneu::dash {

using json = nlohmann::json;

LogPlayer::LogPlayer(const std::filesystem::path& log, Sink sink, TimeSink time)
    : sink_(std::move(sink)), time_(std::move(time)) {
  {
    // Once through: the span, and where every 256th message starts (seek() starts there).
    lcm::LogFile scan(log.string(), "r");
    if (!scan.good()) throw std::runtime_error("cannot read the LCM log " + log.string());
    bool any = false;
    std::size_t n = 0;
    for (;;) {
      const off_t at = ftello(scan.getFilePtr());
      const lcm::LogEvent* e = scan.readNextEvent();
      if (e == nullptr) break;
      if (!any) start_utime_ = e->timestamp;
      any = true;
      end_utime_ = std::max(end_utime_, e->timestamp);
      if (n++ % 256 == 0) index_.emplace_back(e->timestamp, static_cast<std::int64_t>(at));
    }
    if (!any) throw std::runtime_error("the LCM log " + log.string() + " holds no message");
  }
  log_ = std::make_unique<lcm::LogFile>(log.string(), "r");
  if (!log_->good()) throw std::runtime_error("cannot read the LCM log " + log.string());
  anchor_log_utime_ = start_utime_;
  anchor_wall_ = std::chrono::steady_clock::now();
  read_next_locked();
  thread_ = std::thread([this] { run(); });
}

LogPlayer::~LogPlayer() {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void LogPlayer::read_next_locked() {
  const lcm::LogEvent* e = log_->readNextEvent();
  have_next_ = e != nullptr;
  if (!e) return;
  next_channel_ = e->channel;
  const auto* p = static_cast<const std::uint8_t*>(e->data);
  next_data_.assign(p, p + std::max<std::int32_t>(e->datalen, 0));
  next_utime_ = e->timestamp;
}

std::int64_t LogPlayer::cursor_utime_locked() const {
  if (!playing_) return anchor_log_utime_;
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - anchor_wall_).count();
  return std::min(end_utime_, anchor_log_utime_ + static_cast<std::int64_t>(std::llround(wall_s * rate_ * 1e6)));
}

void LogPlayer::play(bool on) {
  {
    const std::lock_guard lock(mutex_);
    if (on == playing_) return;
    anchor_log_utime_ = cursor_utime_locked();
    anchor_wall_ = std::chrono::steady_clock::now();
    if (on && ended_) {  // from the start again
      anchor_log_utime_ = start_utime_;
      fseeko(log_->getFilePtr(), static_cast<off_t>(index_.front().second), SEEK_SET);
      read_next_locked();
      ended_ = false;
    }
    playing_ = on;
  }
  wake_.notify_all();
}

void LogPlayer::seek(double s) {
  std::int64_t said = 0;
  {
    const std::lock_guard lock(mutex_);
    const double span_s = static_cast<double>(end_utime_ - start_utime_) * 1e-6;
    const double at_s = std::clamp(std::isfinite(s) ? s : 0.0, 0.0, span_s);
    const std::int64_t target = start_utime_ + static_cast<std::int64_t>(std::llround(at_s * 1e6));
    // From the last indexed message before the time (lcm_eventlog_seek_to_timestamp lands near
    // it, past a message of that very time), on to the first at or after it.
    std::int64_t offset = index_.front().second;
    for (const auto& [utime, at] : index_)
      if (utime < target) offset = at;
    fseeko(log_->getFilePtr(), static_cast<off_t>(offset), SEEK_SET);
    read_next_locked();
    while (have_next_ && next_utime_ < target) read_next_locked();
    anchor_log_utime_ = target;
    anchor_wall_ = std::chrono::steady_clock::now();
    ended_ = false;
    said = target;
  }
  time_(static_cast<std::uint64_t>(said) * 1000u);  // a jump: the cursor is said at once
  wake_.notify_all();
}

void LogPlayer::set_rate(double rate) {
  {
    const std::lock_guard lock(mutex_);
    anchor_log_utime_ = cursor_utime_locked();
    anchor_wall_ = std::chrono::steady_clock::now();
    rate_ = rate;
  }
  wake_.notify_all();
}

PlaybackState LogPlayer::state() const {
  const std::lock_guard lock(mutex_);
  PlaybackState s;
  s.playing = playing_;
  s.rate = rate_;
  s.position_s = static_cast<double>(cursor_utime_locked() - start_utime_) * 1e-6;
  s.duration_s = static_cast<double>(end_utime_ - start_utime_) * 1e-6;
  s.start_utime = start_utime_;
  s.ended = ended_;
  return s;
}

void LogPlayer::run() {
  using namespace std::chrono_literals;
  auto last_time_sent = std::chrono::steady_clock::time_point{};
  std::unique_lock lock(mutex_);
  while (!stop_) {
    if (!playing_) {
      wake_.wait(lock, [&] { return stop_ || playing_; });
      continue;
    }
    const std::int64_t cursor = cursor_utime_locked();
    while (have_next_ && next_utime_ <= cursor) {
      const std::string channel = next_channel_;
      const std::vector<std::uint8_t> data = next_data_;
      const std::int64_t utime = next_utime_;
      read_next_locked();
      lock.unlock();
      sink_(channel, data.data(), data.size(), utime);
      lock.lock();
      if (stop_ || !playing_) break;
    }
    const auto now = std::chrono::steady_clock::now();
    if (now - last_time_sent >= 50ms) {
      last_time_sent = now;
      const std::int64_t at = cursor_utime_locked();
      lock.unlock();
      time_(static_cast<std::uint64_t>(at) * 1000u);
      lock.lock();
    }
    if (!have_next_ && playing_) {  // the end: paused there
      anchor_log_utime_ = end_utime_;
      playing_ = false;
      ended_ = true;
      continue;
    }
    wake_.wait_for(lock, 5ms);
  }
}

void LogPlayer::attach(Server& server) {
  server.add_capability("time");
  const auto state_json = [this] {
    const PlaybackState s = state();
    return json{{"playing", s.playing},      {"rate", s.rate},
                {"position_s", s.position_s}, {"duration_s", s.duration_s},
                {"start_utime", s.start_utime}, {"ended", s.ended}}
        .dump();
  };
  server.add_route("GET", "/playback", [state_json](const HttpRequest&) {
    return HttpResponse{200, "application/json", state_json()};
  });
  server.add_route("POST", "/playback", [this, state_json](const HttpRequest& req) {
    const json j = json::parse(req.body, nullptr, false);
    const auto bad = [](const std::string& why) { return HttpResponse{400, "text/plain; charset=utf-8", why + "\n"}; };
    if (j.is_discarded() || !j.is_object())
      return bad("POST /playback takes a JSON object: {\"play\":true|false, \"seek_s\":S, \"rate\":R}");
    for (const auto& [key, value] : j.items())
      if (key != "play" && key != "seek_s" && key != "rate") return bad("unknown member \"" + key + "\" (play, seek_s, rate)");
    if (j.contains("play") && !j["play"].is_boolean()) return bad("play must be true or false");
    if (j.contains("seek_s") && (!j["seek_s"].is_number() || !std::isfinite(j["seek_s"].get<double>())))
      return bad("seek_s must be a number of seconds from the log's start");
    if (j.contains("rate") &&
        (!j["rate"].is_number() || !(j["rate"].get<double>() > 0.0) || !(j["rate"].get<double>() <= 1000.0)))
      return bad("rate must be a number above 0 and at most 1000");
    if (j.contains("rate")) set_rate(j["rate"].get<double>());
    if (j.contains("seek_s")) seek(j["seek_s"].get<double>());
    if (j.contains("play")) play(j["play"].get<bool>());
    return HttpResponse{200, "application/json", state_json()};
  });
}

}  // namespace pneu::dash
