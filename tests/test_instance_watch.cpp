// One controller per bench: whose health a pneud hears on its channels, and for how long another
// one counts as there (InstanceWatch); a health datagram off the group decoded (decode_health_datagram).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstring>
#include <vector>

#include "pneu/telemetry/instance_watch.hpp"
#include "pneu_lcm/health_t.hpp"

namespace {

using namespace pneu::telemetry;
using ::testing::HasSubstr;

InstanceId id(std::int32_t pid, std::int64_t nonce = 7) { return {"bench-pc", pid, 1'795'000'000'000'000, nonce}; }
HealthHeard health(const InstanceId& from, bool is_final = false) { return {from, is_final}; }

TEST(InstanceWatch, ItsOwnHealthHeardBackIsNoOtherController) {
  InstanceWatch w(id(100), 1.0);
  w.heard(health(id(100)), 0.0);
  EXPECT_FALSE(w.other(0.0));
}

TEST(InstanceWatch, AnotherProcessOrTheSamePidWithAnotherNonceIsAnotherController) {
  InstanceWatch w(id(100), 1.0);
  w.heard(health(id(100, 8)), 0.0);  // a pid repeated in another container
  ASSERT_TRUE(w.other(0.0));
  EXPECT_EQ(w.other(0.0)->nonce, 8);
  InstanceWatch v(id(100), 1.0);
  v.heard(health(id(200)), 0.0);
  ASSERT_TRUE(v.other(0.5));
  EXPECT_EQ(v.other(0.5)->pid, 200);
}

TEST(InstanceWatch, AnotherCountsAsThereForThreeHealthPeriodsAfterItsLastMessage) {
  InstanceWatch w(id(100), 1.0);
  w.heard(health(id(200)), 10.0);
  EXPECT_TRUE(w.other(12.9));
  EXPECT_FALSE(w.other(13.1)) << "no longer heard: gone";
  w.heard(health(id(200)), 14.0);
  EXPECT_TRUE(w.other(14.0)) << "heard again";
}

TEST(InstanceWatch, AnotherWithALongerHealthPeriodCountsAsThereForThreeOfItsOwn) {
  InstanceWatch w(id(100), 0.1);
  w.heard(health(id(200)), 0.0);
  w.heard(health(id(200)), 5.0);  // it says its health every 5 s
  EXPECT_TRUE(w.other(19.9));
  EXPECT_FALSE(w.other(20.1));
}

TEST(InstanceWatch, AnotherCountsAsThereForThreeOfTheHealthPeriodsItsMessagesCarryFromTheFirstOn) {
  InstanceWatch w(id(100), 0.1);
  w.heard({id(200), false, 3.0}, 0.0);  // its first message: it speaks every 3 s
  EXPECT_TRUE(w.other(8.9)) << "not forgotten 0.3 s later, before it could speak again";
  EXPECT_FALSE(w.other(9.1));
}

TEST(InstanceWatch, AnothersLastMessageForgetsItAtOnce) {
  InstanceWatch w(id(100), 1.0);
  w.heard(health(id(200)), 0.0);
  w.heard(health(id(200), /*is_final=*/true), 0.5);
  EXPECT_FALSE(w.other(0.5));
  w.heard(health(id(300), /*is_final=*/true), 0.6);  // one that stops, never heard running
  EXPECT_FALSE(w.other(0.6));
}

TEST(InstanceWatch, NamesTheOtherByPidHostAndStartTime) {
  EXPECT_EQ(describe(id(4321)), "pneud pid 4321 on host bench-pc, started 2026-11-18 11:06:40 UTC");
}

TEST(InstanceWatch, ThisProcessIsNamedByItsPidAndADrawnNonce) {
  const InstanceId a = InstanceId::of_this_process(), b = InstanceId::of_this_process();
  EXPECT_EQ(a.pid, static_cast<std::int32_t>(::getpid()));
  EXPECT_FALSE(a.host.empty());
  EXPECT_GT(a.start_utime, 0);
  EXPECT_NE(a.nonce, b.nonce) << "two instances in one pid namespace of another host";
}

// The datagram as LCM sends it: "LC02", a sequence number, the channel and its NUL, the message.
std::vector<std::uint8_t> datagram(const std::string& channel, const pneu_lcm::health_t& h) {
  const std::size_t at = 8 + channel.size() + 1;
  std::vector<std::uint8_t> d(at + static_cast<std::size_t>(h.getEncodedSize()), 0);
  const std::uint8_t header[8] = {0x4c, 0x43, 0x30, 0x32, 0, 0, 0, 1};
  std::memcpy(d.data(), header, sizeof header);
  std::memcpy(d.data() + 8, channel.data(), channel.size());
  EXPECT_EQ(h.encode(d.data() + at, 0, h.getEncodedSize()), h.getEncodedSize());
  return d;
}

TEST(HealthDatagram, DecodesTheInstanceOfAHealthMessageOnTheHealthChannelOnly) {
  pneu_lcm::health_t h{};
  h.host = "bench-pc";
  h.pid = 4321;
  h.start_utime = 1'795'000'000'000'000;
  h.nonce = -5;
  h.is_final = true;
  h.period = 0.5;
  const auto heard = decode_health_datagram(datagram("PNEU_HEALTH", h), "PNEU_HEALTH");
  ASSERT_TRUE(heard);
  EXPECT_EQ(heard->period_s, 0.5);
  EXPECT_EQ(heard->from, (InstanceId{"bench-pc", 4321, 1'795'000'000'000'000, -5}));
  EXPECT_TRUE(heard->is_final);
  EXPECT_FALSE(decode_health_datagram(datagram("AXIS2_HEALTH", h), "PNEU_HEALTH")) << "another axis's prefix";
  EXPECT_EQ(lcm_channel_of(datagram("PNEU_STATE", h)), "PNEU_STATE");
  EXPECT_FALSE(lcm_channel_of(std::vector<std::uint8_t>{0x4c, 0x43, 0x30, 0x33, 0, 0, 0, 1, 'X', 0})) << "a fragment";
}

TEST(HealthDatagram, RefusesGarbageAHostileStringLengthAndTrailingBytes) {
  pneu_lcm::health_t h{};
  h.host = "x";
  std::vector<std::uint8_t> d = datagram("PNEU_HEALTH", h);
  std::vector<std::uint8_t> longer = d;
  longer.push_back(0);
  EXPECT_FALSE(decode_health_datagram(longer, "PNEU_HEALTH"));
  // The host string's length on the wire (its int32 before the "x\0"), made negative, then huge.
  const std::size_t len_at = d.size() - (4 + 2 + 4 + 8 + 8 + 8);  // length, "x\0", pid, start, nonce, period
  for (const std::uint8_t first : {std::uint8_t{0xff}, std::uint8_t{0x7f}}) {
    std::vector<std::uint8_t> bad = d;
    bad[len_at] = first;
    EXPECT_FALSE(decode_health_datagram(bad, "PNEU_HEALTH"));
  }
  std::vector<std::uint8_t> zero_length = d;
  std::memset(zero_length.data() + len_at, 0, 4);
  EXPECT_FALSE(decode_health_datagram(zero_length, "PNEU_HEALTH"));
  EXPECT_FALSE(decode_health_datagram(std::vector<std::uint8_t>{1, 2, 3}, "PNEU_HEALTH"));
}

}  // namespace
