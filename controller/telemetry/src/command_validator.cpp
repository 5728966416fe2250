#include "pneu/telemetry/command_validator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace pneu::telemetry {

using controller::LoopCommand;
using controller::Mode;

namespace {
std::string mm(double m) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f mm", m * 1e3);
  return buf;
}
const char* mode_name(Mode m) {
  switch (m) {
    case Mode::kArmed: return "armed";
    case Mode::kDisarmed: return "disarmed";
    case Mode::kFault: return "fault";
    case Mode::kHold: return "holding";
    case Mode::kMovementTest: return "movement test";
  }
  return "?";
}
}  // namespace

const char* to_string(Rejection r) noexcept {
  switch (r) {
    case Rejection::kNone: return "none";
    case Rejection::kMalformed: return "malformed";
    case Rejection::kInvalid: return "invalid";
    case Rejection::kRate: return "rate";
    case Rejection::kMode: return "mode";
    case Rejection::kSequence: return "sequence";
    case Rejection::kStale: return "stale";
    case Rejection::kForeign: return "foreign";
    case Rejection::kOversized: return "oversized";
  }
  return "?";
}

const char* wire_kind_name(std::int8_t kind) noexcept {
  switch (kind) {
    case kWireSetPoint: return "set_point";
    case kWireSetPointStep: return "set_point_step";
    case kWireArm: return "arm";
    case kWireDisarm: return "disarm";
    case kWireFaultReset: return "fault_reset";
    case kWireHoldOn: return "hold_on";
    case kWireHoldOff: return "hold_off";
    default: return "unknown";
  }
}

std::string printable_origin(const std::array<char, kOriginBytes>& origin) {
  std::string out(origin_text(origin));
  for (char& c : out)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7e) c = '?';
  return out;
}

CommandValidator::CommandValidator(const CommandsConfig& commands, double soft_limit_min_m, double soft_limit_max_m)
    : min_m_(soft_limit_min_m),
      max_m_(soft_limit_max_m),
      rate_hz_(commands.max_rate_hz),
      burst_(commands.burst),
      max_age_s_(commands.max_age_s),
      max_step_m_(commands.max_setpoint_step_m),
      tokens_(commands.burst) {}

Verdict CommandValidator::reject(Rejection why, std::string text) {
  ++counters_.rejected;
  switch (why) {
    case Rejection::kMalformed: ++counters_.malformed; break;
    case Rejection::kInvalid: ++counters_.invalid; break;
    case Rejection::kRate: ++counters_.rate; break;
    case Rejection::kMode: ++counters_.mode; break;
    case Rejection::kSequence: ++counters_.sequence; break;
    case Rejection::kStale: ++counters_.stale; break;
    case Rejection::kForeign: ++counters_.foreign; break;
    case Rejection::kOversized: ++counters_.oversized; break;
    case Rejection::kNone: break;
  }
  Verdict v;
  v.rejection = why;
  v.text = std::move(text);
  return v;
}

Verdict CommandValidator::malformed(const std::string& why) {
  return refuse(Rejection::kMalformed, "malformed command: " + why);
}

Verdict CommandValidator::refuse(Rejection why, const std::string& text) {
  ++counters_.received;
  return reject(why, text);
}

Verdict CommandValidator::validate(const CommandFields& c, double now_s, std::int64_t now_unix_us,
                                   double setpoint_m, Mode mode) {
  ++counters_.received;
  // Token bucket.
  if (last_refill_s_ >= 0.0) tokens_ = std::min(burst_, tokens_ + (now_s - last_refill_s_) * rate_hz_);
  last_refill_s_ = now_s;
  if (tokens_ < 1.0) return reject(Rejection::kRate, "rate limit: more than the allowed commands per second");
  tokens_ -= 1.0;

  // Age: a command is meant for now. A replayed capture, or one held up in a queue, is not.
  const double age_s = static_cast<double>(now_unix_us - c.utime) * 1e-6;
  if (!(std::abs(age_s) <= max_age_s_))
    return reject(Rejection::kStale, "stamped " + std::to_string(age_s) + " s from this host's clock (limit " +
                                         std::to_string(max_age_s_) + " s)");

  if (have_seq_ && c.seq <= last_seq_)
    return reject(Rejection::kSequence, "sequence number " + std::to_string(c.seq) +
                                            " is not above the last accepted " + std::to_string(last_seq_));
  // The origin goes into events, logs and the dashboard's page as it is: no control characters,
  // no bytes a terminal or a page would read as anything but text.
  if (!origin_is_clean(c.origin))
    return reject(Rejection::kInvalid, "origin is not printable ASCII followed by NUL padding");
  if (!std::isfinite(c.value)) return reject(Rejection::kInvalid, "value is not a finite number");

  LoopCommand cmd;
  cmd.seq = static_cast<std::uint64_t>(c.seq);
  cmd.value_m = c.value;
  std::string what;
  switch (c.kind) {
    case kWireSetPoint:
    case kWireSetPointStep: {
      const bool step = c.kind == kWireSetPointStep;
      const double target = step ? setpoint_m + c.value : c.value;
      if (target < min_m_ || target > max_m_)
        return reject(Rejection::kInvalid, std::string(step ? "set-point step to " : "set point ") + mm(target) +
                                               " is outside the soft limits [" + mm(min_m_) + ", " + mm(max_m_) + "]");
      if (std::abs(target - setpoint_m) > max_step_m_)
        return reject(Rejection::kInvalid, "set-point change of " + mm(target - setpoint_m) +
                                               " is larger than commands.max_setpoint_step_m (" + mm(max_step_m_) + ")");
      if (mode == Mode::kFault) return reject(Rejection::kMode, "set point refused: a fault is latched, reset it first");
      // Arming holds where the carriage is (ControlLoop: bumpless): a set point taken now would not
      // be the one in force once armed, so it is refused rather than promised.
      if (mode == Mode::kDisarmed)
        return reject(Rejection::kMode, "set point refused: disarmed: arm first; on arm the carriage holds where it is");
      if (mode == Mode::kMovementTest)
        return reject(Rejection::kMode, "set point refused: the movement test runs (open loop, before the law drives): "
                                        "once it passed the carriage holds where it is, then send it");
      cmd.kind = step ? LoopCommand::Kind::kSetPointStep : LoopCommand::Kind::kSetPoint;
      what = "set point " + mm(target);
      break;
    }
    case kWireArm:
      if (mode != Mode::kDisarmed)
        return reject(Rejection::kMode, std::string("arm refused: ") +
                                            (mode == Mode::kFault          ? "a fault is latched, reset it first"
                                             : mode == Mode::kMovementTest ? "already armed, the movement test runs"
                                                                           : "already armed"));
      cmd.kind = LoopCommand::Kind::kArm;
      what = "arm";
      break;
    case kWireDisarm:
      if (!controller::powered(mode)) return reject(Rejection::kMode, std::string("disarm refused: ") + mode_name(mode));
      cmd.kind = LoopCommand::Kind::kDisarm;
      what = "disarm";
      break;
    case kWireFaultReset:
      if (mode != Mode::kFault) return reject(Rejection::kMode, "fault reset refused: no fault is latched");
      cmd.kind = LoopCommand::Kind::kFaultReset;
      what = "fault reset";
      break;
    case kWireHoldOn:
    case kWireHoldOff:
      // A setting, taken in any mode: whether the in-position hold may take over once the carriage
      // is at rest near its set point (a hold in force ends at a hold off).
      cmd.kind = c.kind == kWireHoldOn ? LoopCommand::Kind::kHoldOn : LoopCommand::Kind::kHoldOff;
      what = c.kind == kWireHoldOn ? "hold on: the in-position hold may take over"
                                   : "hold off: the in-position hold is not taken (one in force ends)";
      break;
    default:
      return reject(Rejection::kInvalid, "unknown command kind " + std::to_string(c.kind));
  }
  have_seq_ = true;
  last_seq_ = c.seq;
  ++counters_.accepted;
  Verdict v;
  v.accepted = true;
  v.command = cmd;
  v.text = what;
  return v;
}

}  // namespace pneu::telemetry
