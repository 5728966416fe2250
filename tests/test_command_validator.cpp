// Inbound commands are checked off the loop: what passes, what is refused, and why.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <span>
#include <limits>
#include <string>

#include "pneu/config/config.hpp"
#include "pneu/telemetry/command_datagram.hpp"
#include "pneu/telemetry/command_validator.hpp"

namespace {

using namespace pneu;
using controller::LoopCommand;
using controller::Mode;
using telemetry::CommandFields;
using telemetry::CommandValidator;
using telemetry::Rejection;
using ::testing::HasSubstr;

config::Config make_config() {
  config::Config c = config::load_string(config::default_config_yaml());
  c.controller.soft_limit_min_m = -0.2;
  c.controller.soft_limit_max_m = 0.2;
  c.commands.max_rate_hz = 10.0;
  c.commands.burst = 3.0;
  return c;
}

CommandValidator validator_of(const config::Config& c) {
  return {c.commands, c.controller.soft_limit_min_m, c.controller.soft_limit_max_m};
}

CommandFields at(std::int64_t utime, std::int64_t seq, std::int8_t kind, double value = 0.0) {
  CommandFields f;
  f.utime = utime;
  f.seq = seq;
  f.kind = kind;
  f.value = value;
  return f;
}
CommandFields cmd(std::int64_t seq, std::int8_t kind, double value = 0.0) { return at(0, seq, kind, value); }

TEST(CommandValidator, RefusesACommandStampedOutsideTheAgeLimitEitherWay) {
  const config::Config c = make_config();
  CommandValidator v = validator_of(c);
  const std::int64_t now_us = 1'800'000'000'000'000;
  const auto age_us = static_cast<std::int64_t>(c.commands.max_age_s * 1e6);
  auto r = v.validate(at(now_us - age_us - 1000, 1, telemetry::kWireSetPoint, 0.1), 0.0, now_us, 0.0, Mode::kArmed);
  EXPECT_EQ(r.rejection, Rejection::kStale) << "a captured command replayed later";
  r = v.validate(at(now_us + age_us + 1000, 2, telemetry::kWireSetPoint, 0.1), 0.1, now_us, 0.0, Mode::kArmed);
  EXPECT_EQ(r.rejection, Rejection::kStale) << "stamped in the future";
  r = v.validate(at(now_us - age_us / 2, 3, telemetry::kWireSetPoint, 0.1), 0.2, now_us, 0.0, Mode::kArmed);
  EXPECT_TRUE(r.accepted) << r.text;
  EXPECT_EQ(v.counters().stale, 2u);
}

TEST(CommandValidator, RefusesASetPointChangeLargerThanTheStepLimit) {
  config::Config c = make_config();
  c.commands.max_setpoint_step_m = 0.05;
  CommandValidator v = validator_of(c);
  auto r = v.validate(cmd(1, telemetry::kWireSetPoint, 0.16), 0.0, 0, 0.1, Mode::kArmed);
  EXPECT_EQ(r.rejection, Rejection::kInvalid);
  EXPECT_THAT(r.text, HasSubstr("max_setpoint_step_m"));
  r = v.validate(cmd(2, telemetry::kWireSetPointStep, -0.06), 0.1, 0, 0.1, Mode::kArmed);
  EXPECT_EQ(r.rejection, Rejection::kInvalid);
  EXPECT_TRUE(v.validate(cmd(3, telemetry::kWireSetPoint, 0.14), 0.2, 0, 0.1, Mode::kArmed).accepted);
}

TEST(CommandValidator, AcceptsASetPointInsideTheSoftLimits) {
  CommandValidator v = validator_of(make_config());
  const auto r = v.validate(cmd(1, telemetry::kWireSetPoint, 0.15), 0.0, 0, 0.0, Mode::kArmed);
  ASSERT_TRUE(r.accepted) << r.text;
  EXPECT_EQ(r.command.kind, LoopCommand::Kind::kSetPoint);
  EXPECT_DOUBLE_EQ(r.command.value_m, 0.15);
  EXPECT_EQ(v.counters().accepted, 1u);
}

TEST(CommandValidator, RefusesSetPointsOutsideTheSoftLimitsIncludingByAStep) {
  CommandValidator v = validator_of(make_config());
  auto r = v.validate(cmd(1, telemetry::kWireSetPoint, 0.21), 0.0, 0, 0.0, Mode::kArmed);
  EXPECT_FALSE(r.accepted);
  EXPECT_EQ(r.rejection, Rejection::kInvalid);
  EXPECT_THAT(r.text, HasSubstr("outside the soft limits"));
  // A step is judged by where it lands: 0.19 + 0.02 = 0.21 m.
  r = v.validate(cmd(2, telemetry::kWireSetPointStep, 0.02), 0.1, 0, 0.19, Mode::kArmed);
  EXPECT_FALSE(r.accepted);
  r = v.validate(cmd(3, telemetry::kWireSetPointStep, -0.02), 0.2, 0, 0.19, Mode::kArmed);
  EXPECT_TRUE(r.accepted) << r.text;
  EXPECT_EQ(v.counters().invalid, 2u);
}

TEST(CommandValidator, RefusesNonFiniteValuesAndUnknownKinds) {
  CommandValidator v = validator_of(make_config());
  EXPECT_EQ(v.validate(cmd(1, telemetry::kWireSetPoint, std::numeric_limits<double>::quiet_NaN()), 0, 0, 0, Mode::kArmed)
                .rejection,
            Rejection::kInvalid);
  EXPECT_EQ(v.validate(cmd(2, telemetry::kWireSetPoint, std::numeric_limits<double>::infinity()), 1, 0, 0, Mode::kArmed)
                .rejection,
            Rejection::kInvalid);
  const auto r = v.validate(cmd(3, 99), 2, 0, 0, Mode::kArmed);
  EXPECT_EQ(r.rejection, Rejection::kInvalid);
  EXPECT_THAT(r.text, HasSubstr("unknown command kind 99"));
}

TEST(CommandValidator, RequiresIncreasingSequenceNumbers) {
  CommandValidator v = validator_of(make_config());
  ASSERT_TRUE(v.validate(cmd(10, telemetry::kWireSetPoint, 0.1), 0, 0, 0, Mode::kArmed).accepted);
  EXPECT_EQ(v.validate(cmd(10, telemetry::kWireSetPoint, 0.1), 1, 0, 0, Mode::kArmed).rejection, Rejection::kSequence);
  EXPECT_EQ(v.validate(cmd(9, telemetry::kWireSetPoint, 0.1), 2, 0, 0, Mode::kArmed).rejection, Rejection::kSequence);
  EXPECT_TRUE(v.validate(cmd(11, telemetry::kWireSetPoint, 0.1), 3, 0, 0, Mode::kArmed).accepted);
}

TEST(CommandValidator, RateLimitAllowsTheBurstThenTheSustainedRate) {
  CommandValidator v = validator_of(make_config());  // burst 3, 10 per second
  int accepted = 0;
  for (int i = 0; i < 6; ++i)  // six at the same instant: the burst passes, the rest do not
    accepted += v.validate(cmd(i + 1, telemetry::kWireSetPoint, 0.1), 5.0, 0, 0, Mode::kArmed).accepted;
  EXPECT_EQ(accepted, 3);
  EXPECT_EQ(v.counters().rate, 3u);
  // 0.125 s later 1.25 tokens are back (10 per second): one more command, not two.
  EXPECT_TRUE(v.validate(cmd(10, telemetry::kWireSetPoint, 0.1), 5.125, 0, 0, Mode::kArmed).accepted);
  EXPECT_FALSE(v.validate(cmd(11, telemetry::kWireSetPoint, 0.1), 5.125, 0, 0, Mode::kArmed).accepted);
}

TEST(CommandValidator, EachCommandIsAllowedOnlyInItsModes) {
  CommandValidator v = validator_of(make_config());
  double t = 0.0;
  std::int64_t seq = 0;
  const auto check = [&](std::int8_t kind, Mode mode) {
    t += 1.0;  // never rate limited
    return v.validate(cmd(++seq, kind, 0.0), t, 0, 0.0, mode);
  };
  EXPECT_TRUE(check(telemetry::kWireArm, Mode::kDisarmed).accepted);
  EXPECT_THAT(check(telemetry::kWireArm, Mode::kArmed).text, HasSubstr("already armed"));
  EXPECT_THAT(check(telemetry::kWireArm, Mode::kFault).text, HasSubstr("reset it first"));
  EXPECT_TRUE(check(telemetry::kWireDisarm, Mode::kArmed).accepted);
  EXPECT_FALSE(check(telemetry::kWireDisarm, Mode::kDisarmed).accepted);
  EXPECT_TRUE(check(telemetry::kWireFaultReset, Mode::kFault).accepted);
  EXPECT_THAT(check(telemetry::kWireFaultReset, Mode::kArmed).text, HasSubstr("no fault is latched"));
  EXPECT_TRUE(check(telemetry::kWireSetPoint, Mode::kArmed).accepted);
  EXPECT_TRUE(check(telemetry::kWireSetPoint, Mode::kHold).accepted);
  EXPECT_EQ(check(telemetry::kWireSetPoint, Mode::kDisarmed).rejection, Rejection::kMode);
  EXPECT_EQ(check(telemetry::kWireSetPoint, Mode::kFault).rejection, Rejection::kMode);
  EXPECT_EQ(v.counters().mode, 6u);
}

// Arming holds the carriage where it is (the loop's bumpless arm), whatever set point came before:
// a set point sent while disarmed would be a promise the arm breaks, so it is refused, saying what
// arming will do.
TEST(CommandValidator, RefusesASetPointWhileDisarmedSayingThatArmingHoldsWhereTheCarriageIs) {
  CommandValidator v = validator_of(make_config());
  for (const std::int8_t kind : {telemetry::kWireSetPoint, telemetry::kWireSetPointStep}) {
    const auto r = v.validate(cmd(kind, kind, 0.005), static_cast<double>(kind), 0, 0.1, Mode::kDisarmed);
    EXPECT_FALSE(r.accepted) << telemetry::wire_kind_name(kind);
    EXPECT_EQ(r.rejection, Rejection::kMode);
    EXPECT_EQ(r.text, "set point refused: disarmed: arm first; on arm the carriage holds where it is");
  }
  EXPECT_EQ(v.counters().mode, 2u);
}

// The movement test at the first ARM (Mode::kMovementTest) drives the valves open loop: set points
// wait for its pass, as they wait for arming; a disarm ends it at once.
TEST(CommandValidator, DuringTheMovementTestRefusesSetPointsSayingWhyAndTakesADisarm) {
  CommandValidator v = validator_of(make_config());
  double t = 0.0;
  std::int64_t seq = 0;
  const auto check = [&](std::int8_t kind) {
    t += 1.0;
    return v.validate(cmd(++seq, kind, 0.005), t, 0, 0.1, Mode::kMovementTest);
  };
  for (const std::int8_t kind : {telemetry::kWireSetPoint, telemetry::kWireSetPointStep}) {
    const auto r = check(kind);
    EXPECT_EQ(r.rejection, Rejection::kMode) << telemetry::wire_kind_name(kind);
    EXPECT_EQ(r.text, "set point refused: the movement test runs (open loop, before the law drives): once it passed "
                      "the carriage holds where it is, then send it");
  }
  EXPECT_EQ(check(telemetry::kWireArm).text, "arm refused: already armed, the movement test runs");
  EXPECT_THAT(check(telemetry::kWireFaultReset).text, HasSubstr("no fault is latched"));
  EXPECT_TRUE(check(telemetry::kWireDisarm).accepted);
  EXPECT_EQ(v.counters().mode, 4u);
}

// Issue 31: hold on / hold off, a setting taken in any mode.
TEST(CommandValidator, TakesHoldOnAndHoldOffInEveryMode) {
  CommandValidator v = validator_of(make_config());
  std::int64_t seq = 0;
  double t = 0.0;
  for (const Mode m : {Mode::kArmed, Mode::kHold, Mode::kDisarmed, Mode::kFault, Mode::kMovementTest}) {
    auto on = v.validate(cmd(++seq, telemetry::kWireHoldOn), t += 0.2, 0, 0.0, m);
    ASSERT_TRUE(on.accepted) << on.text;
    EXPECT_EQ(on.command.kind, LoopCommand::Kind::kHoldOn);
    EXPECT_THAT(on.text, HasSubstr("hold on"));
    auto off = v.validate(cmd(++seq, telemetry::kWireHoldOff), t += 0.2, 0, 0.0, m);
    ASSERT_TRUE(off.accepted) << off.text;
    EXPECT_EQ(off.command.kind, LoopCommand::Kind::kHoldOff);
  }
  EXPECT_STREQ(telemetry::wire_kind_name(telemetry::kWireHoldOff), "hold_off");
  EXPECT_EQ(v.validate(cmd(++seq, 8), t += 0.2, 0, 0.0, Mode::kArmed).rejection, Rejection::kInvalid)
      << "the next number is no command";
}

// Issue 31: who sent a command goes into pneud's events as it is, so it must be text.
TEST(CommandValidator, RefusesAnOriginWithControlCharactersOrBytesAfterItsPaddingAndTakesPrintableOnes) {
  CommandValidator v = validator_of(make_config());
  CommandFields c = cmd(1, telemetry::kWireSetPoint, 0.1);
  telemetry::set_origin(c.origin, "pneu-dash 127.0.0.1:8765");
  c.session = 77;
  EXPECT_TRUE(v.validate(c, 0.0, 0, 0.0, Mode::kArmed).accepted);
  c.seq = 2;
  telemetry::set_origin(c.origin, "");
  EXPECT_TRUE(v.validate(c, 0.1, 0, 0.0, Mode::kArmed).accepted) << "an unnamed sender is taken, recorded as such";
  c.seq = 3;
  telemetry::set_origin(c.origin, "pneu-dash \x1b[2J");
  auto r = v.validate(c, 0.2, 0, 0.0, Mode::kArmed);
  EXPECT_EQ(r.rejection, Rejection::kInvalid);
  EXPECT_THAT(r.text, HasSubstr("origin is not printable ASCII"));
  c.seq = 4;
  telemetry::set_origin(c.origin, "ok");
  c.origin[20] = 'x';  // hidden behind the NUL that ends "ok"
  EXPECT_EQ(v.validate(c, 0.3, 0, 0.0, Mode::kArmed).rejection, Rejection::kInvalid);
  c.seq = 5;
  telemetry::set_origin(c.origin, "caf\xc3\xa9");
  EXPECT_EQ(v.validate(c, 0.4, 0, 0.0, Mode::kArmed).rejection, Rejection::kInvalid) << "ASCII only";
  EXPECT_EQ(v.counters().invalid, 3u);
}

TEST(CommandOrigin, IsTextUpToItsFirstNulCutAtThirtyTwoBytesAndPrintedWithQuestionMarksForOtherBytes) {
  std::array<char, telemetry::kOriginBytes> o{};
  telemetry::set_origin(o, "pneu-command alice");
  EXPECT_EQ(telemetry::origin_text(o), "pneu-command alice");
  EXPECT_TRUE(telemetry::origin_is_clean(o));
  telemetry::set_origin(o, std::string(40, 'a'));
  EXPECT_EQ(telemetry::origin_text(o), std::string(32, 'a')) << "cut to the field, no NUL needed";
  EXPECT_TRUE(telemetry::origin_is_clean(o));
  telemetry::set_origin(o, "a\tb\x7f");
  EXPECT_FALSE(telemetry::origin_is_clean(o));
  EXPECT_EQ(telemetry::printable_origin(o), "a?b?");
}

TEST(CommandDatagram, CarriesTheOriginAndSessionThereAndBackAtItsFixedSize) {
  CommandFields c = at(1'800'000'000'000'000, 42, telemetry::kWireSetPoint, 0.125);
  telemetry::set_origin(c.origin, "pneu-dash 127.0.0.1:8765");
  c.session = 0x1234'5678'9abc'def0;
  std::array<std::uint8_t, telemetry::kMaxCommandDatagramBytes> buffer{};
  const std::size_t n = telemetry::encode_command_datagram(c, "PNEU_COMMAND", 7, buffer);
  ASSERT_EQ(n, 8 + sizeof "PNEU_COMMAND" + telemetry::kCommandPayloadBytes);
  const auto d = telemetry::decode_command_datagram(std::span<const std::uint8_t>(buffer.data(), n), "PNEU_COMMAND");
  ASSERT_EQ(d.kind, telemetry::DatagramKind::kCommand) << d.why;
  EXPECT_EQ(telemetry::origin_text(d.fields.origin), "pneu-dash 127.0.0.1:8765");
  EXPECT_EQ(d.fields.session, c.session);
  EXPECT_EQ(d.fields.seq, 42);
  EXPECT_EQ(d.fields.value, 0.125);
  // One byte less is not a command: the origin and session are part of every command.
  EXPECT_EQ(telemetry::decode_command_datagram(std::span<const std::uint8_t>(buffer.data(), n - 1), "PNEU_COMMAND").kind,
            telemetry::DatagramKind::kMalformed);
}

TEST(CommandValidator, CountsMalformedMessagesAmongTheRejected) {
  CommandValidator v = validator_of(make_config());
  const auto r = v.malformed("3 bytes");
  EXPECT_FALSE(r.accepted);
  EXPECT_EQ(r.rejection, Rejection::kMalformed);
  EXPECT_EQ(v.counters().received, 1u);
  EXPECT_EQ(v.counters().rejected, 1u);
  EXPECT_EQ(v.counters().malformed, 1u);
}

}  // namespace
