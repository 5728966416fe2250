#include "pneu/dash/metrics.hpp"

#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "pneu/records/record.hpp"

namespace pneu::dash {
namespace {

using controller::EventMessage;
using controller::FaultCause;
using controller::HealthMessage;
using controller::IdentificationRecord;
namespace kind = controller::event_kind;

// health_t's counters served as they are: the metric, the field (its documentation is the HELP's),
// and what to add for people.
struct HealthCounter {
  const char* metric;
  const char* field;
  const char* more;
};
constexpr HealthCounter kHealthCounters[] = {
    {"pneu_ticks_total", "ticks", ""},
    {"pneu_overruns_total", "overruns", ""},
    {"pneu_deadlines_skipped_total", "deadlines_skipped", ""},
    {"pneu_comms_errors_total", "comms_errors",
     " (on a Modbus bench: the Modbus transactions that failed)"},
    {"pneu_telemetry_dropped_total", "telemetry_dropped", ""},
    {"pneu_commands_received_total", "commands_received", ""},
    {"pneu_commands_accepted_total", "commands_accepted", ""},
};
// health_t's counters of rejected commands by reason: its fields named so.
constexpr std::string_view kRejectedPrefix = "rejected_";
// health_t's distributions of durations, written as quantiles (DurationsSummary's fields).
struct DurationsSummary {
  const char* metric;
  const char* field;
  const char* what;
};
constexpr DurationsSummary kDurations[] = {
    {"pneu_wake_latency_seconds", "wake_latency_us",
     "the loop's wake-up latency, wake-up minus deadline"},
    {"pneu_compute_seconds", "compute_us", "one tick's computation time"}};
constexpr std::pair<const char*, const char*> kQuantileOf[] = {
    {"min", "0"}, {"median", "0.5"}, {"p99", "0.99"}, {"max", "1"}};

constexpr const char* kStaticPositive = "static_positive_n";
constexpr const char* kStaticNegative = "static_negative_n";

constexpr const char* kOutcomeNames[] = {"hit", "missed", "false_alarm", "untested"};
static_assert(std::size(kOutcomeNames) == Metrics::kOutcomes);

std::string health_doc(std::string_view name) {
  std::string doc;
  const bool found = records::with_field<HealthMessage>(name, [&](const auto& f) { doc = f.doc; });
  if (!found) throw std::logic_error("health_t has no field " + std::string(name));
  return doc;
}

std::size_t parameter_index(std::string_view name) {
  for (std::size_t i = 0; i < controller::kIdentifiedParameters.size(); ++i)
    if (name == controller::kIdentifiedParameters[i].name) return i;
  throw std::logic_error("identification_t has no parameter " + std::string(name));
}

std::size_t method_index(controller::PredictionMethod m) {
  for (std::size_t i = 0; i < Metrics::kMethods; ++i)
    if (controller::kPredictionMethods[i].value == m) return i;
  return Metrics::kMethods;
}

std::vector<MetricFamily> make_families() {
  std::vector<MetricFamily> f;
  const std::string since_start = "; from pneud's start-up (health_t)";
  for (const HealthCounter& c : kHealthCounters)
    f.push_back({c.metric, "counter", health_doc(c.field) + c.more + since_start, ""});
  f.push_back({"pneu_commands_rejected_total", "counter",
               "commands pneud rejected, by reason (health_t's rejected_* counters)" + since_start,
               "reason"});
  for (const DurationsSummary& d : kDurations)
    f.push_back({d.metric, "summary",
                 std::string(d.what) + " (health_t." + d.field +
                     "), in seconds: quantiles over the last health period (0: min, 0.5: median, "
                     "0.99, 1: max; no "
                     "_sum, no _count: pneud sends the quantiles only)",
                 "quantile"});
  f.push_back(
      {"pneu_mode", "gauge", "1 for pneud's mode (health_t.mode), 0 for the others", "mode"});
  f.push_back({"pneu_fault_latched", "gauge",
               "1 for the cause of the fault latched now (health_t.fault_cause), 0 for the others",
               "cause"});
  f.push_back({"pneu_pneud_start_time_seconds", "gauge",
               "when pneud started, seconds since the Unix epoch (health_t.start_utime)", ""});
  f.push_back({"pneu_last_health_timestamp_seconds", "gauge",
               "when the dashboard last heard pneud's health, seconds since the Unix epoch (alert "
               "on time() minus it)",
               ""});
  const std::string since_dash = "; from the dashboard's start (event_t)";
  const auto event_counter = [&](const char* metric, const char* what) {
    f.push_back({metric, "counter", what + since_dash, ""});
  };
  event_counter("pneu_stops_total", "stops: the carriage came to rest");
  event_counter("pneu_restarts_total",
                "restarts: the carriage moved again after a stop, the set point unchanged "
                "(stick-slip)");
  event_counter("pneu_starts_total",
                "starts: the carriage moved on a set point change (restarts not counted)");
  f.push_back(
      {"pneu_faults_total", "counter",
       "faults latched, by cause (\"unknown\": a cause this dashboard does not know)" + since_dash,
       "cause"});
  f.push_back({"pneu_fault_resets_total", "counter",
               "fault resets: cleared, or refused while the cause was present" + since_dash,
               "result"});
  event_counter("pneu_holds_total", "in-position holds that took over");
  f.push_back({"pneu_hold_seconds_total", "counter",
               "loop time spent in the in-position hold (an open hold counted up to the latest "
               "loop time heard)" +
                   since_dash,
               ""});
  f.push_back({"pneu_forecasts_total", "counter",
               "restart forecasts (prediction_t), by method, made at a stop or made again while "
               "stuck; from the dashboard's start",
               "method, made"});
  f.push_back(
      {"pneu_forecast_outcomes_total", "counter",
       "forecasts made at a stop, judged when the stop ended: hit (forecast a restart, it "
       "restarted), missed "
       "(forecast none, it restarted), false_alarm (forecast a restart, the stop outlasted its "
       "time without one), "
       "untested (the stop ended otherwise before the forecast time); from the dashboard's start",
       "method, outcome"});
  f.push_back(
      {"pneu_forecast_abs_error_seconds", "histogram",
       "|forecast restart time - actual restart time| of the hits; from the dashboard's start",
       "method"});
  f.push_back(
      {"pneu_forecast_error_seconds", "gauge",
       "forecast restart time - actual restart time of the latest hit (positive: forecast late)",
       "method"});
  f.push_back({"pneu_forecast_force_error_newtons", "gauge",
               "pressure force the forecast made at the stop expected minus the force measured, at "
               "the latest forecast "
               "made again while stuck",
               "method"});
  f.push_back({"pneu_identification_updates_total", "counter",
               "updates of online identification (identification_t.updates), from pneud's start-up",
               ""});
  f.push_back({"pneu_stiction_newtons", "gauge",
               "identified static friction (breakaway force), its magnitude, each direction; "
               "rising over weeks: seal wear",
               "direction"});
  f.push_back({"pneu_stiction_sigma_newtons", "gauge",
               "1 sigma uncertainty of pneu_stiction_newtons", "direction"});
  f.push_back({"pneu_stiction_drift_newtons", "gauge",
               "pneu_stiction_newtons minus its first identified value since pneud started "
               "(positive: rising)",
               "direction"});
  f.push_back({"pneu_coulomb_friction_newtons", "gauge",
               "identified Coulomb (sliding) friction, its magnitude, each direction",
               "direction"});
  f.push_back({"pneu_identified_value", "gauge",
               "every identified parameter (identification_t.value), signed, in the unit its name "
               "ends with "
               "(plant.<section>.<parameter> in pneud's configuration)",
               "parameter"});
  f.push_back({"pneu_identified_sigma", "gauge",
               "1 sigma uncertainty of pneu_identified_value, same unit", "parameter"});
  return f;
}

// The text format's escapes: a backslash and a line feed in a HELP text; a double quote too in a
// label's value.
std::string escape(std::string_view s, bool double_quote) {
  std::string o;
  for (char c : s) {
    if (c == '\\')
      o += "\\\\";
    else if (c == '"' && double_quote)
      o += "\\\"";
    else if (c == '\n')
      o += "\\n";
    else
      o += c;
  }
  return o;
}

// Writes the families in the table's order: each begun by name, so that the text and the table
// cannot part.
class Writer {
 public:
  Writer(const std::vector<MetricFamily>& families, std::string_view bench)
      : families_(families), bench_("bench=\"" + escape_label_value(bench) + "\"") {}

  void begin(std::string_view name) {
    if (next_ >= families_.size() || families_[next_].name != name)
      throw std::logic_error("metrics: " + std::string(name) + " written out of the table's order");
    const MetricFamily& f = families_[next_++];
    name_ = f.name;
    out_ += "# HELP " + f.name + " " + escape(f.help, false) + "\n# TYPE " + f.name + " " + f.type +
            "\n";
  }
  using Labels = std::initializer_list<std::pair<const char*, std::string_view>>;
  void sample(double v, Labels labels = {}, std::string_view suffix = "") {
    out_ += name_;
    out_ += suffix;
    out_ += "{" + bench_;
    for (const auto& [k, value] : labels)
      out_ += std::string(",") + k + "=\"" + escape_label_value(value) + "\"";
    out_ += "} " + format_sample_value(v) + "\n";
  }
  std::string finish() {
    if (next_ != families_.size())
      throw std::logic_error("metrics: " + families_[next_].name + " not written");
    return std::move(out_);
  }

 private:
  const std::vector<MetricFamily>& families_;
  std::string bench_, name_, out_;
  std::size_t next_ = 0;
};

}  // namespace

const std::vector<MetricFamily>& metric_families() {
  static const std::vector<MetricFamily> families = make_families();
  return families;
}

std::string metric_families_markdown() {
  std::string md = "| Metric | Type | Labels besides `bench` | Meaning |\n|---|---|---|---|\n";
  for (const MetricFamily& f : metric_families()) {
    std::string help;
    for (char c : f.help) help += c == '|' ? std::string("\\|") : std::string(1, c);
    md += "| `" + f.name + "` | " + f.type + " | " + (f.labels.empty() ? "" : f.labels) + " | " +
          help + " |\n";
  }
  return md;
}

std::string format_sample_value(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  char buf[32];
  // Whole numbers (counters, most of them) as integers, others in the shortest form that reads
  // back.
  if (v == std::trunc(v) && std::fabs(v) < 1e15) {
    std::snprintf(buf, sizeof buf, "%.0f", v);
    return buf;
  }
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return {buf, r.ptr};
}

std::string escape_label_value(std::string_view v) { return escape(v, true); }

std::string with_label(std::string_view text, std::string_view name, std::string_view value) {
  const std::string label = std::string(name) + "=\"" + escape_label_value(value) + "\"";
  std::string out;
  while (!text.empty()) {
    const auto end = text.find('\n');
    std::string_view line = text.substr(0, end);
    text = end == std::string_view::npos ? std::string_view() : text.substr(end + 1);
    const auto name_end = line.find_first_of("{ ");
    if (line.empty() || line.front() == '#' || name_end == std::string_view::npos) {
      out += line;
    } else if (line[name_end] == '{') {
      out += std::string(line.substr(0, name_end + 1)) + label +
             (line[name_end + 1] == '}' ? "" : ",");
      out += line.substr(name_end + 1);
    } else {
      out += std::string(line.substr(0, name_end)) + "{" + label + "}" +
             std::string(line.substr(name_end));
    }
    if (end != std::string_view::npos) out += '\n';
  }
  return out;
}

Metrics::Metrics(std::string bench, WallClock now)
    : bench_(std::move(bench)), now_(std::move(now)) {
  if (!now_)
    now_ = [] {
      return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch())
          .count();
    };
}

FaultCause Metrics::fault_cause_of(std::string_view text) {
  // What pneud writes for each cause (event_message), up to the cause's name: "fault (NAME)".
  static const auto prefixes = [] {
    std::array<std::string, controller::kFaultCauseCount> p;
    for (std::size_t c = 1; c < p.size(); ++c) {
      controller::LoopEvent e;
      e.kind = controller::LoopEvent::Kind::kFault;
      e.fault_cause = static_cast<FaultCause>(c);
      const std::string t = controller::event_message(e).text;
      p[c] = t.substr(0, t.find(')') + 1);
    }
    return p;
  }();
  for (std::size_t c = 1; c < prefixes.size(); ++c)
    if (text.starts_with(prefixes[c])) return static_cast<FaultCause>(c);
  return FaultCause::kNone;
}

void Metrics::new_process_locked() {
  for (Pending& p : pending_) p.open = false;
  hold_since_s_.reset();
  last_t_s_ = 0.0;
  first_value_ = {};
}

void Metrics::see_time_locked(double t_s) {
  if (std::isfinite(t_s) && t_s > last_t_s_) last_t_s_ = t_s;
}

void Metrics::on_health(const HealthMessage& h) {
  const double received = now_();
  std::lock_guard lock(mutex_);
  Identity id{h.host, h.pid, h.start_utime, h.nonce};
  if (identity_ && !(*identity_ == id)) new_process_locked();
  identity_ = std::move(id);
  health_ = h;
  health_received_unix_s_ = received;
  see_time_locked(h.t_s);
}

void Metrics::judge_locked(std::size_t m, bool restarted, double t_s) {
  Pending& p = pending_[m];
  if (!p.open) return;
  p.open = false;
  Outcome o;
  if (restarted && p.will_restart) {
    o = kHit;
    const double error_s = p.t_restart_s - t_s;
    const double abs_s = std::fabs(error_s);
    for (std::size_t b = 0; b < kForecastErrorBuckets_s.size(); ++b)
      if (abs_s <= kForecastErrorBuckets_s[b]) ++error_buckets_[m][b];
    error_abs_sum_s_[m] += abs_s;
    ++error_count_[m];
    last_error_s_[m] = error_s;
  } else if (restarted) {
    o = kMissed;
  } else if (p.will_restart && p.t_restart_s <= t_s) {
    o = kFalseAlarm;
  } else {
    o = kUntested;
  }
  ++outcomes_[m][o];
}

void Metrics::judge_open_locked(double t_s) {
  for (std::size_t m = 0; m < kMethods; ++m) judge_locked(m, false, t_s);
}

void Metrics::on_event(const EventMessage& e) {
  std::lock_guard lock(mutex_);
  see_time_locked(e.t_s);
  switch (e.kind) {
    case kind::kStop:
      judge_open_locked(e.t_s);  // a stop before the last one ended: it ended unseen
      ++stops_;
      break;
    case kind::kRestart:
      ++restarts_;
      for (std::size_t m = 0; m < kMethods; ++m)
        if (pending_[m].open && pending_[m].stop == e.stop) judge_locked(m, true, e.t_s);
      judge_open_locked(e.t_s);
      break;
    case kind::kStart:
      ++starts_;
      judge_open_locked(e.t_s);
      break;
    case kind::kFault:
      ++faults_[static_cast<std::size_t>(fault_cause_of(e.text))];
      judge_open_locked(e.t_s);
      break;
    case kind::kEnd:
      judge_open_locked(e.t_s);
      if (hold_since_s_) {  // the run ended in the hold
        hold_completed_s_ += std::max(0.0, last_t_s_ - *hold_since_s_);
        hold_since_s_.reset();
      }
      break;
    case kind::kFaultReset:
      ++fault_resets_;
      break;
    case kind::kFaultResetRefused:
      ++fault_resets_refused_;
      break;
    case kind::kHoldStart:
      if (!hold_since_s_) {
        ++holds_;
        hold_since_s_ = e.t_s;
      }
      break;
    case kind::kHoldEnd:
      if (hold_since_s_) {
        hold_completed_s_ += std::max(0.0, last_t_s_ - *hold_since_s_);
        hold_since_s_.reset();
      }
      break;
    default:
      break;
  }
}

void Metrics::on_forecast(const controller::ForecastRecord& f) {
  const std::size_t m = method_index(f.prediction.method);
  if (m >= kMethods) return;
  std::lock_guard lock(mutex_);
  see_time_locked(f.t_s);
  if (f.update == 0) {
    ++forecasts_at_stop_[m];
    judge_locked(m, false, f.t_s);  // one at a stop is judged by the next, at the latest
    pending_[m] = {true, static_cast<std::int64_t>(f.stop), f.prediction.will_restart,
                   f.prediction.t_restart_s};
  } else {
    ++forecasts_again_[m];
    if (std::isfinite(f.stop_forecast_force_n) && std::isfinite(f.force_n))
      last_force_error_n_[m] = f.stop_forecast_force_n - f.force_n;
  }
}

void Metrics::on_identification(const IdentificationRecord& r) {
  std::lock_guard lock(mutex_);
  if (identification_ && r.updates < identification_->updates)
    first_value_ = {};  // pneud started again
  see_time_locked(r.t_s);
  for (std::size_t i = 0; i < r.value.size(); ++i)
    if (r.identified[i] && !first_value_[i] && std::isfinite(r.value[i]))
      first_value_[i] = r.value[i];
  identification_ = r;
}

double Metrics::hold_seconds_locked() const {
  return hold_completed_s_ + (hold_since_s_ ? std::max(0.0, last_t_s_ - *hold_since_s_) : 0.0);
}

std::string Metrics::text() const {
  std::lock_guard lock(mutex_);
  Writer w(metric_families(), bench_);
  const HealthMessage* h = health_ ? &*health_ : nullptr;

  for (const HealthCounter& c : kHealthCounters) {
    w.begin(c.metric);
    if (h)
      records::with_field<HealthMessage>(c.field, [&](const auto& f) {
        if constexpr (std::is_arithmetic_v<typename std::remove_cvref_t<decltype(f)>::member_type>)
          w.sample(static_cast<double>(f.of(*h)));
      });
  }
  w.begin("pneu_commands_rejected_total");
  if (h)
    records::for_each_field<HealthMessage>([&](const auto& f) {
      const std::string_view name = f.name;
      if constexpr (std::is_arithmetic_v<typename std::remove_cvref_t<decltype(f)>::member_type>)
        if (name.starts_with(kRejectedPrefix))
          w.sample(static_cast<double>(f.of(*h)),
                   {{"reason", name.substr(kRejectedPrefix.size())}});
    });
  for (const DurationsSummary& d : kDurations) {
    w.begin(d.metric);
    if (h)
      records::with_field<HealthMessage>(d.field, [&](const auto& g) {
        if constexpr (std::is_same_v<typename std::remove_cvref_t<decltype(g)>::member_type,
                                     controller::DurationsSummary>)
          records::for_each_field<controller::DurationsSummary>([&](const auto& q) {
            for (const auto& [field, quantile] : kQuantileOf)
              if (std::string_view(q.name) == field)
                w.sample(q.of(g.of(*h)) / 1e6, {{"quantile", quantile}});
          });
      });
  }
  w.begin("pneu_mode");
  if (h)
    for (const auto& [mode, name] : controller::kModeNames)
      w.sample(h->mode == static_cast<std::int8_t>(mode) ? 1 : 0, {{"mode", name}});
  w.begin("pneu_fault_latched");
  if (h)
    for (std::size_t c = 1; c < controller::kFaultCauseCount; ++c)
      w.sample(h->fault_cause == static_cast<std::int8_t>(c) ? 1 : 0,
               {{"cause", controller::fault_name(static_cast<FaultCause>(c))}});
  w.begin("pneu_pneud_start_time_seconds");
  if (h) w.sample(static_cast<double>(h->start_utime) / 1e6);
  w.begin("pneu_last_health_timestamp_seconds");
  if (h) w.sample(health_received_unix_s_);

  const auto counter = [&](std::string_view metric, std::uint64_t n) {
    w.begin(metric);
    w.sample(static_cast<double>(n));
  };
  counter("pneu_stops_total", stops_);
  counter("pneu_restarts_total", restarts_);
  counter("pneu_starts_total", starts_);
  w.begin("pneu_faults_total");
  for (std::size_t c = 1; c < controller::kFaultCauseCount; ++c)
    w.sample(static_cast<double>(faults_[c]),
             {{"cause", controller::fault_name(static_cast<FaultCause>(c))}});
  w.sample(static_cast<double>(faults_[0]), {{"cause", "unknown"}});
  w.begin("pneu_fault_resets_total");
  w.sample(static_cast<double>(fault_resets_), {{"result", "cleared"}});
  w.sample(static_cast<double>(fault_resets_refused_), {{"result", "refused"}});
  counter("pneu_holds_total", holds_);
  w.begin("pneu_hold_seconds_total");
  w.sample(hold_seconds_locked());

  w.begin("pneu_forecasts_total");
  for (std::size_t m = 0; m < kMethods; ++m) {
    const char* method = controller::kPredictionMethods[m].name;
    w.sample(static_cast<double>(forecasts_at_stop_[m]), {{"method", method}, {"made", "at_stop"}});
    w.sample(static_cast<double>(forecasts_again_[m]), {{"method", method}, {"made", "again"}});
  }
  w.begin("pneu_forecast_outcomes_total");
  for (std::size_t m = 0; m < kMethods; ++m)
    for (std::size_t o = 0; o < kOutcomes; ++o)
      w.sample(static_cast<double>(outcomes_[m][o]),
               {{"method", controller::kPredictionMethods[m].name}, {"outcome", kOutcomeNames[o]}});
  w.begin("pneu_forecast_abs_error_seconds");
  for (std::size_t m = 0; m < kMethods; ++m) {
    const char* method = controller::kPredictionMethods[m].name;
    for (std::size_t b = 0; b < kForecastErrorBuckets_s.size(); ++b)
      w.sample(static_cast<double>(error_buckets_[m][b]),
               {{"method", method}, {"le", format_sample_value(kForecastErrorBuckets_s[b])}},
               "_bucket");
    w.sample(static_cast<double>(error_count_[m]), {{"method", method}, {"le", "+Inf"}}, "_bucket");
    w.sample(error_abs_sum_s_[m], {{"method", method}}, "_sum");
    w.sample(static_cast<double>(error_count_[m]), {{"method", method}}, "_count");
  }
  w.begin("pneu_forecast_error_seconds");
  for (std::size_t m = 0; m < kMethods; ++m)
    if (last_error_s_[m])
      w.sample(*last_error_s_[m], {{"method", controller::kPredictionMethods[m].name}});
  w.begin("pneu_forecast_force_error_newtons");
  for (std::size_t m = 0; m < kMethods; ++m)
    if (last_force_error_n_[m])
      w.sample(*last_force_error_n_[m], {{"method", controller::kPredictionMethods[m].name}});

  const IdentificationRecord* id = identification_ ? &*identification_ : nullptr;
  w.begin("pneu_identification_updates_total");
  if (id) w.sample(static_cast<double>(id->updates));
  static const std::size_t kStatic[2] = {parameter_index(kStaticPositive),
                                         parameter_index(kStaticNegative)};
  static const std::size_t kCoulomb[2] = {parameter_index("coulomb_positive_n"),
                                          parameter_index("coulomb_negative_n")};
  constexpr const char* kDirections[2] = {"positive", "negative"};
  const auto each_direction = [&](const std::size_t(&index)[2], auto&& value) {
    if (!id) return;
    for (std::size_t d = 0; d < 2; ++d)
      if (id->identified[index[d]]) {
        const std::optional<double> v = value(index[d]);
        if (v) w.sample(*v, {{"direction", kDirections[d]}});
      }
  };
  w.begin("pneu_stiction_newtons");
  each_direction(kStatic, [&](std::size_t i) { return std::optional(std::fabs(id->value[i])); });
  w.begin("pneu_stiction_sigma_newtons");
  each_direction(kStatic, [&](std::size_t i) { return std::optional(id->sigma[i]); });
  w.begin("pneu_stiction_drift_newtons");
  each_direction(kStatic, [&](std::size_t i) {
    return first_value_[i] ? std::optional(std::fabs(id->value[i]) - std::fabs(*first_value_[i]))
                           : std::nullopt;
  });
  w.begin("pneu_coulomb_friction_newtons");
  each_direction(kCoulomb, [&](std::size_t i) { return std::optional(std::fabs(id->value[i])); });
  w.begin("pneu_identified_value");
  if (id)
    for (std::size_t i = 0; i < id->value.size(); ++i)
      if (id->identified[i])
        w.sample(id->value[i], {{"parameter", controller::kIdentifiedParameters[i].name}});
  w.begin("pneu_identified_sigma");
  if (id)
    for (std::size_t i = 0; i < id->sigma.size(); ++i)
      if (id->identified[i])
        w.sample(id->sigma[i], {{"parameter", controller::kIdentifiedParameters[i].name}});
  return w.finish();
}

}  // namespace pneu::dash
