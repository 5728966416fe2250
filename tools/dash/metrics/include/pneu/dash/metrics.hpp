// pneu-dash's /metrics: a bench's records (health_t, event_t, prediction_t, identification_t, as
// the dashboard receives them decoded) summed up in the Prometheus text exposition format
// (version 0.0.4), every series labelled bench="NAME", so that one Prometheus watches a fleet.
// Counters taken from health_t run from pneud's start-up (a pneud restart is a counter reset, which
// rate() and increase() handle); counters of events and forecasts run from this object's creation.
// Not the loop: thread-safe (a mutex), allocates freely.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "pneu/controller/records.hpp"
#include "pneu/controller/supervisor.hpp"

namespace pneu::dash {

/// One family of metrics /metrics serves: its name, its Prometheus type, its HELP text, and its
/// labels besides `bench`.
struct MetricFamily {
  std::string name;
  const char* type;  ///< counter, gauge, summary or histogram
  std::string help;
  std::string labels;  ///< "cause", "method, outcome", ... ("" for none)
};

/// Every family /metrics serves, in the order Metrics::text() writes them (the documentation's
/// table is checked against it).
[[nodiscard]] const std::vector<MetricFamily>& metric_families();

/// The families as a Markdown table (name, type, labels, meaning), as docs/dashboard.md has it.
[[nodiscard]] std::string metric_families_markdown();

/// A value written as the exposition format reads it: shortest round-trip decimal, NaN, +Inf, -Inf.
[[nodiscard]] std::string format_sample_value(double v);
/// A label value escaped as the exposition format wants it (\\, \", \n).
[[nodiscard]] std::string escape_label_value(std::string_view v);

/// `text` (the exposition format) with the label `name`="`value`" first on every sample: another
/// part's metrics (the server's own counters) labelled with the bench as these are.
[[nodiscard]] std::string with_label(std::string_view text, std::string_view name,
                                     std::string_view value);

/// The upper bounds of pneu_forecast_abs_error_seconds' buckets [s] (then +Inf).
inline constexpr std::array<double, 10> kForecastErrorBuckets_s = {0.005, 0.01, 0.02, 0.05, 0.1,
                                                                   0.2,   0.5,  1.0,  2.0,  5.0};

/// The metrics of one bench, fed with its records, rendered on demand.
class Metrics {
 public:
  /// Wall-clock time now, seconds since the Unix epoch (the time a health message arrived).
  using WallClock = std::function<double()>;

  /// `bench`: every series' bench label. `now`: the wall clock (the system clock by default).
  explicit Metrics(std::string bench, WallClock now = {});

  void on_health(const controller::HealthMessage& health);
  void on_event(const controller::EventMessage& event);
  void on_forecast(const controller::ForecastRecord& forecast);
  void on_identification(const controller::IdentificationRecord& record);

  /// The metrics now, in the Prometheus text exposition format.
  [[nodiscard]] std::string text() const;

  [[nodiscard]] const std::string& bench() const noexcept { return bench_; }

  /// The fault cause whose name an event_t fault's text gives (FaultCause::kNone: none it knows).
  [[nodiscard]] static controller::FaultCause fault_cause_of(std::string_view event_text);

  static constexpr std::size_t kMethods = std::size(controller::kPredictionMethods);
  /// How the forecast made at a stop by one method turned out when the stop ended.
  enum Outcome : std::uint8_t { kHit, kMissed, kFalseAlarm, kUntested, kOutcomes };

 private:
  struct Pending {  // the forecast made at the open stop by one method
    bool open = false;
    std::int64_t stop = 0;
    bool will_restart = false;
    double t_restart_s = 0.0;
  };
  struct Identity {
    std::string host;
    std::int32_t pid = 0;
    std::int64_t start_utime = 0, nonce = 0;
    bool operator==(const Identity&) const = default;
  };

  void new_process_locked();
  void judge_locked(std::size_t method, bool restarted, double t_s);
  void judge_open_locked(double t_s);
  void see_time_locked(double t_s);
  [[nodiscard]] double hold_seconds_locked() const;

  std::string bench_;
  WallClock now_;
  mutable std::mutex mutex_;

  // health_t
  std::optional<controller::HealthMessage> health_;
  std::optional<Identity> identity_;
  double health_received_unix_s_ = 0.0;

  // event_t
  std::uint64_t stops_ = 0, restarts_ = 0, starts_ = 0, holds_ = 0, fault_resets_ = 0,
                fault_resets_refused_ = 0;
  std::array<std::uint64_t, controller::kFaultCauseCount>
      faults_{};  // [0]: a cause it does not know
  double hold_completed_s_ = 0.0;
  std::optional<double> hold_since_s_;
  double last_t_s_ = 0.0;  // the latest loop time seen of this pneud

  // prediction_t
  std::array<std::uint64_t, kMethods> forecasts_at_stop_{}, forecasts_again_{};
  std::array<Pending, kMethods> pending_{};
  std::array<std::array<std::uint64_t, kOutcomes>, kMethods> outcomes_{};
  std::array<std::array<std::uint64_t, kForecastErrorBuckets_s.size()>, kMethods> error_buckets_{};
  std::array<double, kMethods> error_abs_sum_s_{};
  std::array<std::uint64_t, kMethods> error_count_{};
  std::array<std::optional<double>, kMethods> last_error_s_{}, last_force_error_n_{};

  // identification_t
  std::optional<controller::IdentificationRecord> identification_;
  std::array<std::optional<double>, controller::kIdentifiedParameterKeys.size()> first_value_{};
};

}  // namespace pneu::dash
