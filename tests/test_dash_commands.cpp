// Commands from the dashboard (issue 31): the token file is refused unless private, a browser
// commands only after it sent the right token, a wrong token sends nothing, and every command sent
// names this dashboard and the browser's session.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <grp.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "pneu/dash/commands.hpp"
#include "support/child_process.hpp"
#include "support/paths.hpp"

namespace {

namespace fs = std::filesystem;
using namespace pneu::dash;
using ::testing::HasSubstr;

constexpr const char* kToken = "s3cret-T0ken-of-24-chars";

class DashCommands : public ::testing::Test {
 protected:
  fs::path write(const std::string& name, const std::string& text, unsigned mode) {
    const fs::path p = dir_.path() / name;
    std::ofstream(p) << text;
    ::chmod(p.c_str(), mode);
    return p;
  }
  // The group this process's files get, and one it does not (when this host has another).
  static std::string own_group() {
    const group* g = ::getgrgid(::getegid());
    return g != nullptr ? g->gr_name : std::string();
  }
  pneu::test::TestDir dir_{"pneu_dash_commands_"};
};

std::string refusal(const fs::path& file, const std::string& group) {
  try {
    (void)read_token_file(file, group);
  } catch (const CommandsRefused& e) {
    return e.what();
  }
  return "";
}

TEST_F(DashCommands, TheTokenFileIsReadWhenItsModeIsAtMost0640AndItsGroupIsTheOneNamed) {
  const std::string group = own_group();
  ASSERT_FALSE(group.empty());
  EXPECT_EQ(read_token_file(write("t640", std::string(kToken) + "\n", 0640), group), kToken);
  EXPECT_EQ(read_token_file(write("t600", kToken, 0600), group), kToken);
  EXPECT_EQ(read_token_file(write("t400", kToken, 0400), "no-such-group-on-this-host"), kToken)
      << "a group this host does not have is no requirement";
}

TEST_F(DashCommands, TheTokenFileIsRefusedSayingWhyWhenOthersCanReadItOrItsGroupCanWriteIt) {
  const std::string group = own_group();
  EXPECT_THAT(refusal(write("t644", kToken, 0644), group), HasSubstr("mode 0644 grants more than 0640"));
  EXPECT_THAT(refusal(write("t660", kToken, 0660), group), HasSubstr("mode 0660 grants more than 0640"));
  EXPECT_THAT(refusal(write("t740", kToken, 0740), group), HasSubstr("chmod 0640"));
}

TEST_F(DashCommands, TheTokenFileIsRefusedWhenNotOwnedByTheGroupThatExists) {
  // "root" exists on every host: a file of the test's group is not root's unless the test runs
  // with group root, when "daemon" plays the other group.
  const std::string other = ::getegid() == 0 ? "daemon" : "root";
  ASSERT_NE(::getgrnam(other.c_str()), nullptr);
  EXPECT_THAT(refusal(write("t", kToken, 0640), other), HasSubstr("not by group '" + other + "'"));
}

TEST_F(DashCommands, TheTokenFileIsRefusedWhenItIsALinkShortOrNotOneLine) {
  const std::string group = own_group();
  const fs::path target = write("target", kToken, 0640);
  fs::create_symlink(target, dir_.path() / "link");
  EXPECT_THAT(refusal(dir_.path() / "link", group), HasSubstr("a symbolic link"));
  EXPECT_THAT(refusal(write("short", "abc\n", 0640), group), HasSubstr("a token of 3 characters; at least 16"));
  EXPECT_THAT(refusal(write("spaces", "a token with spaces in it\n", 0640), group), HasSubstr("one line"));
  EXPECT_THAT(refusal(write("lines", std::string(kToken) + "\nmore\n", 0640), group), HasSubstr("one line"));
  EXPECT_THAT(refusal(dir_.path() / "missing", group), HasSubstr("No such file"));
  EXPECT_THAT(refusal(dir_.path(), group), HasSubstr("not a regular file"));
}

// pneu-dash itself: it refuses to start with commands that could not be safe, saying why, before
// it listens (exit 2), and the check-config run says commands are judged as they would be.
TEST_F(DashCommands, PneuDashRefusesToStartWithATokenFileOthersCanReadOrOnANonLoopbackAddress) {
  const auto run = [&](const std::vector<std::string>& args) {
    std::vector<std::string> argv = {pneu::test::bin("pneu-dash"), "--lcm-url", "udpm://239.255.76.67:7667?ttl=0"};
    argv.insert(argv.end(), args.begin(), args.end());
    pneu::test::Child c = pneu::test::Child::spawn(argv, dir_.path() / "out", dir_.path() / "err");
    const int code = c.wait();
    return std::make_pair(code, pneu::test::slurp(dir_.path() / "err"));
  };
  const fs::path open_file = write("open.token", kToken, 0644);
  auto [code, err] = run({"--listen", "127.0.0.1:0", "--commands-token-file", open_file.string(), "--check-config"});
  EXPECT_EQ(code, 2);
  EXPECT_THAT(err, HasSubstr("mode 0644 grants more than 0640"));
  const fs::path good = write("good.token", kToken, 0600);
  if (const group* g = ::getgrnam("pneu"); g != nullptr) {  // this host has the group: the file must be its
    ASSERT_EQ(::chown(good.c_str(), static_cast<uid_t>(-1), g->gr_gid), 0) << "chgrp pneu: run as root";
  }
  std::tie(code, err) = run({"--listen", "0.0.0.0:0", "--commands-token-file", good.string(), "--check-config"});
  EXPECT_EQ(code, 2);
  EXPECT_THAT(err, HasSubstr("loopback --listen address only, not on '0.0.0.0'"));
  EXPECT_THAT(err, HasSubstr("no TLS"));
  std::tie(code, err) = run({"--listen", "127.0.0.1:0", "--commands-token-file", good.string(), "--check-config"});
  EXPECT_EQ(code, 0) << err;
}

TEST(DashCommandsListen, CommandsAreTakenOnLoopbackOnlySayingWhy) {
  EXPECT_NO_THROW(listen_allows_commands("127.0.0.1"));
  EXPECT_NO_THROW(listen_allows_commands("127.3.2.1"));
  EXPECT_NO_THROW(listen_allows_commands("::1"));
  EXPECT_NO_THROW(listen_allows_commands("localhost"));
  for (const char* host : {"0.0.0.0", "192.168.1.20", "::", "bench.local", "128.0.0.1"}) {
    try {
      listen_allows_commands(host);
      ADD_FAILURE() << host << " taken";
    } catch (const CommandsRefused& e) {
      EXPECT_THAT(e.what(), HasSubstr("no TLS")) << host;
      EXPECT_THAT(e.what(), HasSubstr("SSH tunnel")) << host;
    }
  }
}

TEST(DashCommandsToken, IsComparedWholeTheSameOnlyWhenEqual) {
  EXPECT_TRUE(same_token(kToken, kToken));
  EXPECT_FALSE(same_token(kToken, ""));
  EXPECT_FALSE(same_token(kToken, std::string(kToken).substr(0, 10)));
  EXPECT_FALSE(same_token(kToken, std::string(kToken) + "x"));
  std::string last = kToken;
  last.back() = 'X';
  EXPECT_FALSE(same_token(kToken, last));
  std::string first = kToken;
  first.front() = 'X';
  EXPECT_FALSE(same_token(kToken, first));
}

// A gate whose transport records what it is given, on clocks the test moves.
struct Bench {
  std::vector<pneu_lcm::command_t> sent;
  double now_s = 100.0;
  std::int64_t now_us = 1'800'000'000'000'000;
  bool transport_up = true;
  CommandGate gate{GateOptions{.token = kToken, .origin = "pneu-dash 127.0.0.1:8765"},
                   [this](const pneu_lcm::command_t& c) {
                     if (transport_up) sent.push_back(c);
                     return transport_up;
                   },
                   [this] { return now_s; }, [this] { return now_us; }};
};

std::string login_json(const std::string& token) { return "{\"token\":\"" + token + "\"}"; }

TEST(DashCommandGate, ACommandFromAConnectionThatSentNoTokenIsRefusedAndNothingIsSent) {
  Bench b;
  const GateAnswer a = b.gate.command(1, R"({"kind":"arm"})");
  EXPECT_FALSE(a.ok);
  EXPECT_THAT(a.message, HasSubstr("not logged in"));
  EXPECT_TRUE(b.sent.empty());
  EXPECT_EQ(b.gate.counters().commands_refused, 1u);
}

TEST(DashCommandGate, AWrongTokenIsRefusedCountedAndGivesNoSessionSoItsCommandsAreNotSent) {
  Bench b;
  for (const std::string& wrong : {std::string("nope"), std::string(kToken) + "!", std::string()}) {
    const GateAnswer a = b.gate.login(7, login_json(wrong));
    EXPECT_FALSE(a.ok) << wrong;
    EXPECT_THAT(a.message, HasSubstr("wrong token"));
  }
  EXPECT_FALSE(b.gate.login(7, "not json").ok);
  EXPECT_FALSE(b.gate.login(7, R"({"token": 12})").ok);
  EXPECT_EQ(b.gate.counters().refused_tokens, 5u);
  EXPECT_EQ(b.gate.session_of(7), 0);
  EXPECT_FALSE(b.gate.command(7, R"({"kind":"set_point","value":0.1})").ok);
  EXPECT_TRUE(b.sent.empty());
}

TEST(DashCommandGate, TheRightTokenGivesTheConnectionASessionAndItsCommandsGoOutAttributed) {
  Bench b;
  const GateAnswer in = b.gate.login(3, login_json(kToken));
  ASSERT_TRUE(in.ok) << in.message;
  EXPECT_GT(in.session, 0);
  EXPECT_EQ(b.gate.session_of(3), in.session);
  EXPECT_EQ(b.gate.session_of(4), 0) << "another connection has no session";
  const GateAnswer sp = b.gate.command(3, R"({"kind":"set_point","value":0.17})");
  ASSERT_TRUE(sp.ok) << sp.message;
  ASSERT_EQ(b.sent.size(), 1u);
  const pneu_lcm::command_t& c = b.sent[0];
  EXPECT_EQ(c.kind, int{pneu_lcm::command_t::KIND_SET_POINT});
  EXPECT_EQ(c.value, 0.17);
  EXPECT_EQ(c.utime, b.now_us);
  EXPECT_EQ(c.seq, sp.seq);
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(c.origin)), "pneu-dash 127.0.0.1:8765");
  EXPECT_EQ(c.session, in.session);
  EXPECT_FALSE(b.gate.command(4, R"({"kind":"arm"})").ok) << "the session is the connection's, not the host's";
  EXPECT_EQ(b.sent.size(), 1u);
}

TEST(DashCommandGate, EachKindMapsToItsWireKindAndSequenceNumbersIncreaseEvenOnAStoppedClock) {
  Bench b;
  ASSERT_TRUE(b.gate.login(1, login_json(kToken)).ok);
  using C = pneu_lcm::command_t;
  const std::vector<std::pair<std::string, int>> kinds = {
      {R"({"kind":"arm"})", C::KIND_ARM},
      {R"({"kind":"disarm"})", C::KIND_DISARM},
      {R"({"kind":"fault_reset"})", C::KIND_FAULT_RESET},
      {R"({"kind":"set_point_step","value":-0.002})", C::KIND_SET_POINT_STEP},
      {R"({"kind":"hold_on"})", C::KIND_HOLD_ON},
      {R"({"kind":"hold_off"})", C::KIND_HOLD_OFF}};
  for (const auto& [json, kind] : kinds) ASSERT_TRUE(b.gate.command(1, json).ok) << json;
  ASSERT_EQ(b.sent.size(), kinds.size());
  for (std::size_t i = 0; i < kinds.size(); ++i) {
    EXPECT_EQ(b.sent[i].kind, kinds[i].second);
    if (i > 0) {
      EXPECT_GT(b.sent[i].seq, b.sent[i - 1].seq) << "pneud refuses a sequence number going back";
    }
  }
  EXPECT_EQ(b.sent[3].value, -0.002);
}

TEST(DashCommandGate, AMalformedCommandIsRefusedSayingWhyAndNotSent) {
  Bench b;
  ASSERT_TRUE(b.gate.login(1, login_json(kToken)).ok);
  EXPECT_THAT(b.gate.command(1, "{").message, HasSubstr("not JSON"));
  EXPECT_THAT(b.gate.command(1, R"({"kind":"launch"})").message, HasSubstr("unknown kind 'launch'"));
  EXPECT_THAT(b.gate.command(1, R"({"kind":"set_point"})").message, HasSubstr("needs a finite number"));
  EXPECT_THAT(b.gate.command(1, R"({"kind":"set_point","value":"0.1"})").message, HasSubstr("needs a finite number"));
  EXPECT_THAT(b.gate.command(1, R"([1,2])").message, HasSubstr("unknown kind"));
  EXPECT_TRUE(b.sent.empty());
  EXPECT_EQ(b.gate.counters().commands_refused, 5u);
}

TEST(DashCommandGate, AfterFiveWrongTokensLoginsWaitForTheWindowEvenWithTheRightToken) {
  Bench b;
  for (int i = 0; i < 5; ++i) EXPECT_FALSE(b.gate.login(1, login_json("wrong")).ok);
  const GateAnswer held = b.gate.login(2, login_json(kToken));
  EXPECT_FALSE(held.ok);
  EXPECT_THAT(held.message, HasSubstr("too many wrong tokens"));
  EXPECT_EQ(b.gate.counters().throttled, 1u);
  b.now_s += 10.0;
  EXPECT_TRUE(b.gate.login(2, login_json(kToken)).ok) << "the window passed";
}

TEST(DashCommandGate, AWrongTokenOrAClosedConnectionEndsItsSession) {
  Bench b;
  ASSERT_TRUE(b.gate.login(1, login_json(kToken)).ok);
  EXPECT_FALSE(b.gate.login(1, login_json("wrong")).ok);
  EXPECT_EQ(b.gate.session_of(1), 0);
  ASSERT_TRUE(b.gate.login(2, login_json(kToken)).ok);
  b.gate.forget(2);
  EXPECT_FALSE(b.gate.command(2, R"({"kind":"arm"})").ok);
  EXPECT_TRUE(b.sent.empty());
}

TEST(DashCommandGate, EachLoginIsANewSession) {
  Bench b;
  const GateAnswer first = b.gate.login(1, login_json(kToken));
  const GateAnswer second = b.gate.login(2, login_json(kToken));
  ASSERT_TRUE(first.ok && second.ok);
  EXPECT_NE(first.session, second.session);
}

TEST(DashCommandGate, ItsCountersAreWrittenInThePrometheusTextFormat) {
  Bench b;
  EXPECT_FALSE(b.gate.login(1, login_json("wrong")).ok);
  EXPECT_FALSE(b.gate.login(1, login_json("wrong again")).ok);
  ASSERT_TRUE(b.gate.login(1, login_json(kToken)).ok);
  ASSERT_TRUE(b.gate.command(1, R"({"kind":"arm"})").ok);
  const std::string text = counters_text(b.gate.counters());
  EXPECT_THAT(text, HasSubstr("# TYPE pneu_dash_command_tokens_refused_total counter\n"
                              "pneu_dash_command_tokens_refused_total 2\n"));
  EXPECT_THAT(text, HasSubstr("\npneu_dash_command_logins_total 1\n"));
  EXPECT_THAT(text, HasSubstr("\npneu_dash_commands_sent_total 1\n"));
}

TEST(DashCommandGate, AFailedTransportIsCountedAndSaid) {
  Bench b;
  ASSERT_TRUE(b.gate.login(1, login_json(kToken)).ok);
  b.transport_up = false;
  const GateAnswer a = b.gate.command(1, R"({"kind":"arm"})");
  EXPECT_FALSE(a.ok);
  EXPECT_THAT(a.message, HasSubstr("failed"));
  EXPECT_EQ(b.gate.counters().send_failures, 1u);
}

}  // namespace
