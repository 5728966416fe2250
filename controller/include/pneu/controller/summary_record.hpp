// The run's summary as pneud --summary-json writes it, described once (pneu/records/record.hpp):
// its members, their nesting and their spelling are said here; the JSON document and its JSON
// Schema (share/pneu/schemas/summary.schema.json) follow. run_summary_record() (run_summary.hpp)
// fills it from the run's figures and its runtime.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "pneu/records/record.hpp"

namespace pneu::controller {

/// A distribution of durations [us].
struct DurationsSummary {
  double min = 0.0, median = 0.0, p99 = 0.0, max = 0.0;
};
struct LoopSummary {
  std::uint64_t ticks = 0;
  double rate_hz = 0.0;
  std::uint64_t overruns = 0, deadlines_skipped = 0;
  DurationsSummary wake_latency_us, compute_us;
  std::uint64_t tick_records_dropped = 0, events_dropped = 0;
  double epoch_monotonic_s = 0.0;
};
struct RuntimeSummary {
  std::uint64_t ticks_seen = 0, sequence_gaps = 0, stops = 0, stops_forgotten = 0, model_updates_late = 0;
};
struct FaultSummary {
  double t_s = 0.0, y_m = 0.0;
  const char* cause = nullptr;
  const char* key = nullptr;  ///< the config key of the rule that latched it; none: not written
};
struct CommandsSummary {
  std::uint64_t received = 0, accepted = 0, rejected = 0, malformed = 0, oversized = 0, foreign = 0, stale = 0,
                sequence = 0, invalid = 0, rate = 0, mode = 0, queue_full = 0;
};
struct TelemetrySummary {
  std::string lcm_url, channel_prefix;
  std::uint64_t publish_errors = 0;
  CommandsSummary commands;
};
struct SafeOutputSummary {
  bool delivered = false;
  std::uint64_t attempts = 0, max_attempts = 0;
  double read_back_u_p_v = 0.0, read_back_u_n_v = 0.0;
};
struct ModbusSummary {
  std::uint64_t transactions = 0;
  double transactions_per_s = 0.0;
  std::uint64_t errors = 0, reconnects = 0, samples_out_of_range = 0, stale_reads = 0;
  double oldest_sample_ms = 0.0;
  std::string last_error;
  SafeOutputSummary safe_output_on_closing;
};
/// The run's summary.
struct RunSummaryRecord {
  std::string pneud;
  const char* exit_reason = nullptr;
  std::uint64_t exit_code = 0;
  const char* fault_at_end = nullptr;  ///< none: null
  std::string backend, clock, config;
  double u_0_v = 0.0, t_end_s = 0.0, wall_s = 0.0;
  LoopSummary loop;
  RuntimeSummary runtime;
  std::vector<FaultSummary> faults;
  std::optional<TelemetrySummary> telemetry;  ///< none: LCM did not run
  std::optional<ModbusSummary> modbus;        ///< none: no Modbus backend
};

}  // namespace pneu::controller

template <>
struct pneu::records::Description<pneu::controller::DurationsSummary> {
  using R = pneu::controller::DurationsSummary;
  static constexpr const char* kName = "durations";
  static constexpr const char* kDoc = "a distribution of durations over the run";
  static constexpr auto kFields = std::tuple{
      field("min", &R::min, "us", "the shortest"),
      field("median", &R::median, "us", "the median"),
      field("p99", &R::p99, "us", "the 99th percentile"),
      field("max", &R::max, "us", "the longest"),
  };
};

template <>
struct pneu::records::Description<pneu::controller::LoopSummary> {
  using R = pneu::controller::LoopSummary;
  static constexpr const char* kName = "loop";
  static constexpr const char* kDoc = "the real-time loop";
  static constexpr auto kFields = std::tuple{
      field("ticks", &R::ticks, "", "ticks run"),
      field("rate_hz", &R::rate_hz, "Hz", "the loop rate"),
      field("overruns", &R::overruns, "", "ticks that ended after the next deadline"),
      field("deadlines_skipped", &R::deadlines_skipped, "", "deadlines passed over after overruns"),
      group("wake_latency_us", &R::wake_latency_us, "", "wake-up minus deadline"),
      group("compute_us", &R::compute_us, "", "one tick's computation"),
      field("tick_records_dropped", &R::tick_records_dropped, "", "tick records the loop's full queue dropped"),
      field("events_dropped", &R::events_dropped, "", "events the loop's full queue dropped"),
      field("epoch_monotonic_s", &R::epoch_monotonic_s, "s",
            "CLOCK_MONOTONIC at loop time 0 (null on the simulated clock), to the microsecond", 16),
  };
};

template <>
struct pneu::records::Description<pneu::controller::RuntimeSummary> {
  using R = pneu::controller::RuntimeSummary;
  static constexpr const char* kName = "runtime";
  static constexpr const char* kDoc = "the non-real-time runtime";
  static constexpr auto kFields = std::tuple{
      field("ticks_seen", &R::ticks_seen, "", "tick records drained"),
      field("sequence_gaps", &R::sequence_gaps, "", "gaps in their sequence numbers"),
      field("stops", &R::stops, "", "stops"),
      field("stops_forgotten", &R::stops_forgotten, "", "stops no longer kept"),
      field("model_updates_late", &R::model_updates_late, "", "online model updates that came late"),
  };
};

template <>
struct pneu::records::Description<pneu::controller::FaultSummary> {
  using R = pneu::controller::FaultSummary;
  static constexpr const char* kName = "fault";
  static constexpr const char* kDoc = "a fault latched";
  static constexpr auto kFields = std::tuple{
      field("t_s", &R::t_s, "s", "when"),
      field("y_m", &R::y_m, "m", "the position then"),
      field("cause", &R::cause, "", "its cause"),
      field("key", &R::key, "", "the config key of the rule that latched it").when(+[](const R& r) {
        return r.key != nullptr;
      }),
  };
};

template <>
struct pneu::records::Description<pneu::controller::CommandsSummary> {
  using R = pneu::controller::CommandsSummary;
  static constexpr const char* kName = "commands";
  static constexpr const char* kDoc = "the command channel's counters";
  static constexpr auto kFields = std::tuple{
      field("received", &R::received, "", "commands received"),
      field("accepted", &R::accepted, "", "accepted"),
      field("rejected", &R::rejected, "", "rejected: the kinds below add up to it"),
      field("malformed", &R::malformed, "", "undecodable or of the wrong type"),
      field("oversized", &R::oversized, "", "longer than any command"),
      field("foreign", &R::foreign, "", "sent from another host"),
      field("stale", &R::stale, "", "stamped too far from this host's clock"),
      field("sequence", &R::sequence, "", "sequence number not increasing"),
      field("invalid", &R::invalid, "", "non-finite, unknown kind, out of bounds"),
      field("rate", &R::rate, "", "over the rate limit"),
      field("mode", &R::mode, "", "not allowed in the mode"),
      field("queue_full", &R::queue_full, "", "accepted but the loop's queue was full"),
  };
};

template <>
struct pneu::records::Description<pneu::controller::TelemetrySummary> {
  using R = pneu::controller::TelemetrySummary;
  static constexpr const char* kName = "telemetry";
  static constexpr const char* kDoc = "LCM while it ran";
  static constexpr auto kFields = std::tuple{
      field("lcm_url", &R::lcm_url, "", "telemetry.lcm_url"),
      field("channel_prefix", &R::channel_prefix, "", "telemetry.channel_prefix"),
      field("publish_errors", &R::publish_errors, "", "messages LCM failed to publish"),
      group("commands", &R::commands, "", "the command channel"),
  };
};

template <>
struct pneu::records::Description<pneu::controller::SafeOutputSummary> {
  using R = pneu::controller::SafeOutputSummary;
  static constexpr const char* kName = "safe_output_on_closing";
  static constexpr const char* kDoc = "the safe output written on closing";
  static constexpr auto kFields = std::tuple{
      field("delivered", &R::delivered, "", "written, then read back from the device's output registers"),
      field("attempts", &R::attempts, "", "attempts made (0: the backend never ran)"),
      field("max_attempts", &R::max_attempts, "", "of at most"),
      field("read_back_u_p_v", &R::read_back_u_p_v, "V", "u_P read back (null: none read back)"),
      field("read_back_u_n_v", &R::read_back_u_n_v, "V", "u_N read back (null: none read back)").null_when(+[](const R& r) {
        return r.read_back_u_p_v != r.read_back_u_p_v;  // NaN: none read back
      }),
  };
};

template <>
struct pneu::records::Description<pneu::controller::ModbusSummary> {
  using R = pneu::controller::ModbusSummary;
  static constexpr const char* kName = "modbus";
  static constexpr const char* kDoc = "the Modbus link";
  static constexpr auto kFields = std::tuple{
      field("transactions", &R::transactions, "", "successful exchanges"),
      field("transactions_per_s", &R::transactions_per_s, "1/s", "per second of the run (the exchanges before its time, the movement test's, left out)"),
      field("errors", &R::errors, "", "failed exchanges (timeout, exception, bad data)"),
      field("reconnects", &R::reconnects, "", "reconnections"),
      field("samples_out_of_range", &R::samples_out_of_range, "", "samples with a register outside its raw range"),
      field("stale_reads", &R::stale_reads, "", "loop reads that found the sample too old"),
      field("oldest_sample_ms", &R::oldest_sample_ms, "ms", "the oldest sample the loop took"),
      field("last_error", &R::last_error, "", "the last failure's text (null: none)").null_when(+[](const R& r) {
        return r.errors == 0;
      }),
      group("safe_output_on_closing", &R::safe_output_on_closing, "", "the safe output written on closing"),
  };
};

template <>
struct pneu::records::Description<pneu::controller::RunSummaryRecord> {
  using R = pneu::controller::RunSummaryRecord;
  static constexpr const char* kName = "summary";
  static constexpr const char* kDoc = "the run's figures (pneud --summary-json)";
  static constexpr auto kFields = std::tuple{
      field("pneud", &R::pneud, "", "pneud's version"),
      field("exit_reason", &R::exit_reason, "", "how the run ended"),
      field("exit_code", &R::exit_code, "", "pneud's exit code"),
      field("fault_at_end", &R::fault_at_end, "", "the fault still latched at the end (null: none)")
          .null_when(+[](const R& r) { return r.fault_at_end == nullptr; }),
      field("backend", &R::backend, "", "hal.backend: sim, modbus"),
      field("clock", &R::clock, "", "real, simulated"),
      field("config", &R::config, "", "the configuration file, or embedded sim.yaml"),
      field("u_0_v", &R::u_0_v, "V", "u_0 as run (controller.law.offset_v, resolved)"),
      field("t_end_s", &R::t_end_s, "s", "loop time at the end"),
      field("wall_s", &R::wall_s, "s", "wall time of the run"),
      group("loop", &R::loop, "", "the real-time loop"),
      group("runtime", &R::runtime, "", "the non-real-time runtime"),
      field("faults", &R::faults, "", "the faults latched, in order"),
      group("telemetry", &R::telemetry, "", "LCM (null: it did not run)"),
      group("modbus", &R::modbus, "", "the Modbus link (null: not used)"),
  };
};
