// pneud's LCM side: a sink of the runtime that publishes what it drains and forecasts (state every
// tick, events, predictions, health), and the command channel, which takes commands in, validated,
// towards the loop. Lives on the non-real-time service
// thread: LCM::publish allocates and must never run on the loop thread.
#pragma once

#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "pneu/controller/run_figures.hpp"
#include "pneu/controller/run_listener.hpp"
#include "pneu/controller/runtime.hpp"
#include "pneu/telemetry/command_socket.hpp"
#include "pneu/telemetry/command_validator.hpp"
#include "pneu/telemetry/instance_watch.hpp"
#include "pneu/telemetry/telemetry_params.hpp"

namespace pneu::telemetry {

class LcmError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class LcmBridge final : public controller::RunListener {
 public:
  /// Opens LCM on `telemetry`'s lcm_url; commands are checked by `validator`. Throws LcmError when LCM cannot start (bad URL, no
  /// multicast route). On a udpm:// URL, opens its own socket on the group (CommandSocket): with
  /// `accept_commands`, for <prefix>COMMAND (datagrams from this host only), and in any case to
  /// hear another controller's <prefix>HEALTH (from any host). Without it (another URL, or the
  /// socket refused while commands are not taken) no other controller can be heard: watch_off()
  /// says why.
  LcmBridge(const TelemetryConfig& telemetry, CommandValidator validator, controller::LoopOutputs& loop,
            bool accept_commands);
  ~LcmBridge() override;

  /// Waits up to `timeout_ms` for datagrams and handles those waiting (at most a bounded number
  /// per call, so that a flood cannot starve the telemetry drain): commands, and another
  /// controller's health. While another controller is heard, the loop is asked to latch
  /// FaultCause::kAnotherController (LoopOutputs::external_fault), and stderr says who, once;
  /// and again when it is no longer heard. Returns false on a socket failure.
  bool handle(int timeout_ms);

  /// Before the run (nothing of this pneud published yet): listens up to `listen_s` for another
  /// controller on the channels, and says who: the first whose health is heard on <prefix>HEALTH
  /// (at once), or, when only its <prefix>STATE was (a loaded machine can drop a datagram now and
  /// then, and state comes every tick), where that came from, once another 2 `listen_s` brought no
  /// health to name it. Nothing: none.
  [[nodiscard]] std::optional<std::string> listen_for_another(double listen_s);
  /// Why no other controller can be heard (empty: it can).
  [[nodiscard]] const std::string& watch_off() const noexcept { return watch_off_; }
  /// This pneud, as its health messages name it.
  [[nodiscard]] const InstanceId& instance() const noexcept { return watch_.self(); }

  /// Where each command's verdict also goes (Runtime::record_command: its sinks, the events file
  /// among them); may be null; must outlive the bridge. The runtime is not thread-safe: handle()
  /// must be called from the thread that drains it (the service thread does both).
  void set_command_log(controller::Runtime* runtime) noexcept { command_log_ = runtime; }

  void on_tick(const controller::TickRecord& record, const controller::ExpectedAtTick& expected) override;
  void on_event(const controller::LoopEvent& event) override;
  void on_forecast(const controller::ForecastRecord& forecast) override;
  void on_health(const controller::HealthRecord& health) override;
  void on_identification(const controller::IdentificationRecord& record) override;
  void on_end(double t_end_s) override;

  /// For the run's summary.
  [[nodiscard]] controller::TelemetryFigures figures() const;

  [[nodiscard]] const CommandCounters& command_counters() const noexcept { return validator_.counters(); }
  [[nodiscard]] std::uint64_t publish_errors() const noexcept { return publish_errors_; }
  /// Commands that passed validation but found the loop's command queue full.
  [[nodiscard]] std::uint64_t commands_dropped() const noexcept { return commands_dropped_; }
  [[nodiscard]] std::string channel(const char* suffix) const { return prefix_ + suffix; }

 private:
  void on_datagram(std::span<const std::uint8_t> bytes, const CommandSocket::Datagram& d);
  /// One datagram off the group: a command, another controller's health, or neither.
  void dispatch(std::span<const std::uint8_t> bytes, const CommandSocket::Datagram& d);
  /// Asks the loop to latch the fault while another controller is heard, and says so.
  void update_watch();
  [[nodiscard]] double watch_time_s() const;
  void publish_text_event(std::int8_t kind, const std::string& text, std::int64_t seq = 0, std::string origin = {},
                          std::int64_t session = 0);
  [[nodiscard]] std::int64_t utime_of(double t_s) const noexcept;
  template <typename T>
  void publish(const std::string& channel, const T& msg);

  std::unique_ptr<lcm::LCM> lcm_;
  std::string url_;
  std::string prefix_;
  // <prefix>STATE, ...: built once, not per message (STATE goes out every tick).
  std::string state_channel_, event_channel_, prediction_channel_, health_channel_, command_channel_,
      identification_channel_;
  controller::LoopOutputs& loop_;
  std::unique_ptr<CommandSocket> socket_;  // the group: commands in, other controllers' health
  bool accept_commands_ = false;
  InstanceWatch watch_;
  std::string watch_off_;
  double health_period_s_ = 0.0;  // telemetry.health_period_s, as health_t.period
  bool other_said_ = false;  // another controller announced on stderr, the loop asked to fault
  CommandValidator validator_;
  controller::Runtime* command_log_ = nullptr;
  double last_t_s_ = 0.0;
  std::int64_t epoch_utime_ = 0;                     // Unix time of loop time 0 [us]
  std::chrono::steady_clock::time_point started_;
  std::uint64_t publish_errors_ = 0;
  std::uint64_t commands_dropped_ = 0;
  // Rejection events are published (and written to the command log) at most
  // kRejectionEventsPerSecond a second: a flood of bad datagrams must not become a flood of
  // events, nor fill the disk; all are counted in health.
  double rejection_window_s_ = -1.0;
  int rejection_events_in_window_ = 0;
  std::uint64_t rejection_events_suppressed_ = 0;
};

}  // namespace pneu::telemetry
