// pneu-dash's server (tools/dash/lib), in process: a Beast client against it on 127.0.0.1, a free
// port. The Foxglove WebSocket protocol v1 (serverInfo, advertise with the schemas derived from the
// records' descriptions, subscribe/unsubscribe, binary message frames of the records' JSON, time),
// the static files, /metrics, and bad input of every kind refused with a reason while the others
// are served.
#include <gtest/gtest.h>
#include <unistd.h>
#include <lcm/lcm-cpp.hpp>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "pneu/controller/records.hpp"
#include "pneu/dash/log_player.hpp"
#include "pneu/dash/pneu_channels.hpp"
#include "pneu/dash/server.hpp"
#include "pneu/records/lcm.hpp"
#include "pneu_lcm/event_t_members.hpp"
#include "pneu_lcm/health_t_members.hpp"
#include "pneu_lcm/state_t_members.hpp"
#include "support/child_process.hpp"
#include "support/paths.hpp"

namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace fs = std::filesystem;
using tcp = asio::ip::tcp;
using json = nlohmann::json;
using namespace std::chrono_literals;
using pneu::dash::ChannelSpec;
using pneu::dash::PneuChannel;
using pneu::dash::PneuFeed;
using pneu::dash::Server;
using pneu::dash::ServerOptions;

std::vector<std::uint8_t> encoded_state(std::uint64_t seq, double y_m = 0.01) {
  pneu::controller::TickRecord r{};
  r.seq = seq;
  r.t_s = 0.001 * static_cast<double>(seq);
  r.y_m = y_m;
  r.p_p_pa = 3e5;
  pneu_lcm::state_t m{};
  m.utime = 1'700'000'000'000'000 + static_cast<std::int64_t>(seq) * 1000;
  pneu::records::to_lcm(r, m);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

std::vector<std::uint8_t> encoded_event(const std::string& text) {
  pneu::controller::EventMessage e{};
  e.kind = 1;
  e.t_s = 1.5;
  e.text = text;
  pneu_lcm::event_t m{};
  pneu::records::to_lcm(e, m);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

// What the derived schemas ask (type, required, additionalProperties), checked on a message's
// top level: enough to fail on a missing, extra or mistyped field (the node test validates whole).
bool type_matches(const json& value, const json& type) {
  if (type.is_array()) {
    for (const json& t : type)
      if (type_matches(value, t)) return true;
    return false;
  }
  const std::string t = type.get<std::string>();
  if (t == "number") return value.is_number();
  if (t == "integer") return value.is_number_integer();
  if (t == "boolean") return value.is_boolean();
  if (t == "string") return value.is_string();
  if (t == "null") return value.is_null();
  if (t == "object") return value.is_object();
  if (t == "array") return value.is_array();
  return false;
}

std::string schema_violation(const json& message, const json& schema) {
  if (!message.is_object()) return "not an object";
  for (const json& name : schema["required"])
    if (!message.contains(name.get<std::string>())) return "missing " + name.get<std::string>();
  for (const auto& [key, value] : message.items()) {
    if (!schema["properties"].contains(key)) return "unknown member " + key;
    const json& p = schema["properties"][key];
    if (p.contains("type") && !type_matches(value, p["type"])) return key + " of the wrong type: " + value.dump();
  }
  return "";
}

struct Frame {
  bool text = false;
  std::string data;
};

class Client {
 public:
  explicit Client(std::uint16_t port, const std::string& protocol = pneu::dash::kSubprotocol, int receive_buffer = 0) {
    auto& socket = ws_.next_layer();
    socket.open(tcp::v4());
    if (receive_buffer > 0) socket.set_option(asio::socket_base::receive_buffer_size(receive_buffer));
    socket.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    ws_.set_option(websocket::stream_base::decorator([protocol](websocket::request_type& req) {
      req.set(http::field::sec_websocket_protocol, protocol);
    }));
    ws_.read_message_max(64u << 20);
    ws_.handshake(response_, "127.0.0.1", "/ws");
  }

  // The next frame; nothing (and a failure) when none comes within `timeout`, or the error.
  std::optional<Frame> read(std::chrono::milliseconds timeout = 10s, beast::error_code* error = nullptr) {
    beast::flat_buffer buffer;
    std::optional<beast::error_code> result;
    ws_.async_read(buffer, [&](beast::error_code ec, std::size_t) { result = ec; });
    ioc_.restart();
    ioc_.run_for(timeout);
    if (!result) {
      ws_.next_layer().cancel();
      ioc_.restart();
      ioc_.run();
      if (error == nullptr) ADD_FAILURE() << "no frame within " << timeout.count() << " ms";
      return std::nullopt;
    }
    if (*result) {
      if (error != nullptr) *error = *result;
      else ADD_FAILURE() << "read: " << result->message();
      return std::nullopt;
    }
    return Frame{ws_.got_text(), beast::buffers_to_string(buffer.data())};
  }

  json read_json() {
    const auto f = read();
    if (!f) return json();
    EXPECT_TRUE(f->text) << "a binary frame where a JSON message was expected";
    return json::parse(f->data, nullptr, false);
  }

  // A message frame (opcode 1): subscription id, time, payload.
  struct Message {
    std::uint32_t subscription = 0;
    std::uint64_t time_ns = 0;
    std::string payload;
  };
  std::optional<Message> read_message() {
    for (;;) {
      const auto f = read();
      if (!f) return std::nullopt;
      if (f->text) {
        last_status_ = json::parse(f->data, nullptr, false);
        continue;  // a status
      }
      if (f->data.size() < 13 || f->data[0] != 0x01) {
        ADD_FAILURE() << "not a message frame";
        return std::nullopt;
      }
      Message m;
      const auto* b = reinterpret_cast<const std::uint8_t*>(f->data.data());
      for (int i = 3; i >= 0; --i) m.subscription = (m.subscription << 8) | b[1 + i];
      for (int i = 7; i >= 0; --i) m.time_ns = (m.time_ns << 8) | b[5 + i];
      m.payload = f->data.substr(13);
      return m;
    }
  }

  void send(const std::string& text) {
    ws_.text(true);
    ws_.write(asio::buffer(text));
  }
  void send_binary(const std::string& bytes) {
    ws_.binary(true);
    ws_.write(asio::buffer(bytes));
  }

  // Past serverInfo and advertise: the channels by topic.
  std::map<std::string, json> handshake_messages() {
    const json info = read_json();
    EXPECT_EQ(info.value("op", ""), "serverInfo");
    const json adv = read_json();
    EXPECT_EQ(adv.value("op", ""), "advertise");
    std::map<std::string, json> by_topic;
    for (const json& c : adv["channels"]) by_topic[c["topic"].get<std::string>()] = c;
    return by_topic;
  }

  websocket::stream<tcp::socket>& ws() { return ws_; }
  const websocket::response_type& response() const { return response_; }
  const json& last_status() const { return last_status_; }

 private:
  asio::io_context ioc_;
  websocket::stream<tcp::socket> ws_{ioc_};
  websocket::response_type response_;
  json last_status_;
};

// One HTTP exchange: the raw response text.
std::string http_raw(std::uint16_t port, const std::string& request) {
  asio::io_context ioc;
  tcp::socket s(ioc);
  s.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
  asio::write(s, asio::buffer(request));
  std::string out;
  beast::error_code ec;
  char buf[4096];
  for (;;) {
    const std::size_t n = s.read_some(asio::buffer(buf), ec);
    out.append(buf, n);
    if (ec) break;
  }
  return out;
}

std::string get(std::uint16_t port, const std::string& target, const std::string& method = "GET") {
  return http_raw(port, method + " " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\nContent-Length: 0\r\n\r\n");
}

class DashServer : public ::testing::Test {
 protected:
  void SetUp() override {
    www_ = fs::temp_directory_path() / ("pneu_dash_www_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(www_ / "js");
    std::ofstream(www_ / "index.html") << "<!doctype html><title>pneu</title>";
    std::ofstream(www_ / "js" / "app.js") << "console.log(1);";
    std::ofstream(www_.parent_path() / "pneu_dash_secret.txt") << "secret";
    options_.port = 0;
    options_.www = www_;
    options_.metadata = pneu::dash::pneud_metadata();
  }
  void TearDown() override {
    if (server_) {
      server_->stop();
      if (thread_.joinable()) thread_.join();
    }
    feed_.reset();
    server_.reset();
    fs::remove_all(www_);
  }
  // Makes the server and its pneud channels; run() starts serving.
  void make() {
    server_ = std::make_unique<Server>(options_);
    feed_ = std::make_unique<PneuFeed>(*server_, "PNEU_");
  }
  void run() {
    thread_ = std::thread([this] { server_->run(); });
  }
  void start() {
    make();
    run();
  }
  void forward_state(std::uint64_t seq, double y_m = 0.01) {
    const auto b = encoded_state(seq, y_m);
    ASSERT_TRUE(feed_->forward("PNEU_STATE", b.data(), b.size(), 1'700'000'000'000'000 + static_cast<std::int64_t>(seq)));
  }
  // What `c` sent before has been taken: the server answers in order, here an op it does not know.
  static void barrier(Client& c) {
    c.send(R"({"op":"barrier"})");
    for (;;) {
      const auto f = c.read();
      ASSERT_TRUE(f);
      if (f->text && json::parse(f->data).value("message", "").find("unknown op \"barrier\"") != std::string::npos) return;
    }
  }
  void subscribe(Client& c, std::uint32_t sub, pneu::dash::ChannelId channel) {
    c.send(json{{"op", "subscribe"}, {"subscriptions", {{{"id", sub}, {"channelId", channel}}}}}.dump());
  }

  ServerOptions options_;
  fs::path www_;
  std::unique_ptr<Server> server_;
  std::unique_ptr<PneuFeed> feed_;
  std::thread thread_;
};

TEST_F(DashServer, SaysServerInfoThenAdvertisesEveryPneudChannelWithTheSchemaDerivedFromItsRecord) {
  start();
  Client c(server_->port());
  EXPECT_EQ(c.response()[http::field::sec_websocket_protocol], pneu::dash::kSubprotocol);
  const json info = c.read_json();
  EXPECT_EQ(info["op"], "serverInfo");
  EXPECT_EQ(info["name"], "pneu-dash");
  EXPECT_EQ(info["supportedEncodings"], json::array({"json"}));
  EXPECT_TRUE(info["capabilities"].is_array());
  // The modes' names for state_t's and health_t's numbers, from the controller's table.
  EXPECT_EQ(info["metadata"]["modes"], "0:DISARMED,1:ARMED,2:FAULT,3:HOLD,4:MOVEMENT_TEST");
  const json adv = c.read_json();
  ASSERT_EQ(adv["op"], "advertise");
  ASSERT_EQ(adv["channels"].size(), 5u);
  const std::map<std::string, std::string> schema_file = {{"PNEU_STATE", "tick"},
                                                          {"PNEU_EVENT", "event_message"},
                                                          {"PNEU_PREDICTION", "forecast"},
                                                          {"PNEU_HEALTH", "health"},
                                                          {"PNEU_IDENTIFICATION", "identification"}};
  for (const json& ch : adv["channels"]) {
    const std::string topic = ch["topic"];
    ASSERT_TRUE(schema_file.contains(topic)) << topic;
    EXPECT_EQ(ch["encoding"], "json");
    EXPECT_EQ(ch["schemaEncoding"], "jsonschema");
    EXPECT_EQ(ch["schemaName"], schema_file.at(topic));
    EXPECT_TRUE(ch["id"].is_number_unsigned());
    // The schema pneu-records installs (share/pneu/schemas), derived from the same description.
    std::ifstream in(fs::path(PNEU_BINARY_DIR) / "share/pneu/schemas" / (schema_file.at(topic) + ".schema.json"));
    ASSERT_TRUE(in) << schema_file.at(topic);
    const std::string installed((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(ch["schema"].get<std::string>(), installed) << topic;
  }
  EXPECT_EQ(adv["channels"][0]["sequenceField"], "seq");
}

TEST_F(DashServer, SendsASubscribedChannelsMessagesAsTheirRecordsJsonInBinaryFramesAndNoOtherChannels) {
  start();
  Client c(server_->port());
  auto channels = c.handshake_messages();
  subscribe(c, 7, feed_->id(PneuChannel::kState));
  c.send(json{{"op", "subscribe"}, {"subscriptions", {{{"id", 8}, {"channelId", feed_->id(PneuChannel::kHealth)}}}}}.dump());
  barrier(c);  // the subscriptions are taken before the messages come
  const auto ev = encoded_event("not subscribed");
  ASSERT_TRUE(feed_->forward("PNEU_EVENT", ev.data(), ev.size(), 5));
  forward_state(42, 0.0125);
  const auto m = c.read_message();
  ASSERT_TRUE(m);
  EXPECT_EQ(m->subscription, 7u);
  EXPECT_EQ(m->time_ns, (1'700'000'000'000'000ull + 42) * 1000u);
  const json record = json::parse(m->payload);
  EXPECT_EQ(record["seq"], 42);
  EXPECT_DOUBLE_EQ(record["y"].get<double>(), 0.0125);
  EXPECT_DOUBLE_EQ(record["p_p"].get<double>(), 3e5);
  const json schema = json::parse(channels["PNEU_STATE"]["schema"].get<std::string>());
  EXPECT_EQ(schema_violation(record, schema), "");
  // The check fails on a missing field.
  json missing = record;
  missing.erase("force");
  EXPECT_EQ(schema_violation(missing, schema), "missing force");

  // Unsubscribed: no more of it; the next message is the other subscription's.
  c.send(R"({"op":"unsubscribe","subscriptionIds":[7]})");
  barrier(c);
  forward_state(43);
  pneu::controller::HealthMessage h{};
  h.ticks = 1234;
  h.host = "bench";
  pneu_lcm::health_t hm{};
  pneu::records::to_lcm(h, hm);
  std::vector<std::uint8_t> hb(static_cast<std::size_t>(hm.getEncodedSize()));
  hm.encode(hb.data(), 0, static_cast<int>(hb.size()));
  ASSERT_TRUE(feed_->forward("PNEU_HEALTH", hb.data(), hb.size(), 6));
  const auto m2 = c.read_message();
  ASSERT_TRUE(m2);
  EXPECT_EQ(m2->subscription, 8u);
  const json health = json::parse(m2->payload);
  EXPECT_EQ(health["ticks"], 1234);
  EXPECT_EQ(health["host"], "bench");
  EXPECT_EQ(schema_violation(health, json::parse(channels["PNEU_HEALTH"]["schema"].get<std::string>())), "");
}

TEST_F(DashServer, ForwardsOnlyMessagesThatDecodeWholeAsTheirChannelsType) {
  make();
  const auto ev = encoded_event("an event on the state channel");
  EXPECT_FALSE(feed_->forward("PNEU_STATE", ev.data(), ev.size(), 1));
  auto st = encoded_state(1);
  st.push_back(0);
  EXPECT_FALSE(feed_->forward("PNEU_STATE", st.data(), st.size(), 1));
  EXPECT_FALSE(feed_->forward("PNEU_STATE", st.data(), 4, 1));
  EXPECT_EQ(feed_->undecodable(), 3u);
  EXPECT_FALSE(feed_->forward("OTHER_STATE", st.data(), st.size() - 1, 1));
  EXPECT_EQ(feed_->undecodable(), 3u);
}

TEST_F(DashServer, ALatchedChannelsLastMessageGoesToEveryNewSubscriber) {
  make();
  const auto id = server_->add_channel(ChannelSpec{"plane", "plane", R"({"type":"object"})", true, ""});
  run();
  server_->publish(id, 1, R"({"v":1})");
  server_->publish(id, 2, R"({"v":2})");
  std::this_thread::sleep_for(100ms);
  for (int k = 0; k < 2; ++k) {
    Client c(server_->port());
    const auto channels = c.handshake_messages();
    ASSERT_TRUE(channels.contains("plane"));
    subscribe(c, 3, id);
    const auto m = c.read_message();
    ASSERT_TRUE(m);
    EXPECT_EQ(m->payload, R"({"v":2})");
    EXPECT_EQ(m->time_ns, 2u);
  }
}

TEST_F(DashServer, AdvertisesAChannelAddedWhileClientsAreConnected) {
  start();
  Client c(server_->port());
  c.handshake_messages();
  server_->add_channel(ChannelSpec{"late", "late", R"({"type":"object"})", false, ""});
  const json adv = c.read_json();
  EXPECT_EQ(adv["op"], "advertise");
  ASSERT_EQ(adv["channels"].size(), 1u);
  EXPECT_EQ(adv["channels"][0]["topic"], "late");
}

TEST_F(DashServer, RefusesMalformedJsonAndUnknownOpsWithAnErrorStatusAndKeepsServingTheClient) {
  start();
  Client c(server_->port());
  c.handshake_messages();
  c.send("{not json");
  json s = c.read_json();
  EXPECT_EQ(s["op"], "status");
  EXPECT_EQ(s["level"], 2);
  EXPECT_NE(s["message"].get<std::string>().find("malformed JSON"), std::string::npos) << s.dump();
  c.send(R"({"op":"fly"})");
  s = c.read_json();
  EXPECT_EQ(s["level"], 2);
  EXPECT_NE(s["message"].get<std::string>().find("unknown op \"fly\""), std::string::npos) << s.dump();
  c.send(R"([1,2])");
  EXPECT_EQ(c.read_json()["level"], 2);
  c.send(R"({"op":"subscribe","subscriptions":[{"id":-1,"channelId":1},{"id":1,"channelId":999}]})");
  s = c.read_json();
  EXPECT_NE(s["message"].get<std::string>().find("refused 2 subscriptions"), std::string::npos) << s.dump();
  c.send_binary(std::string("\x07\x00", 2));
  s = c.read_json();
  EXPECT_NE(s["message"].get<std::string>().find("binary op 7"), std::string::npos) << s.dump();
  c.send(R"({"op":"advertise","channels":[{"id":1,"topic":"x","encoding":"json"}]})");
  s = c.read_json();
  EXPECT_NE(s["message"].get<std::string>().find("clientPublish"), std::string::npos) << s.dump();
  // Still served.
  subscribe(c, 1, feed_->id(PneuChannel::kState));
  barrier(c);
  forward_state(5);
  const auto m = c.read_message();
  ASSERT_TRUE(m);
  EXPECT_EQ(json::parse(m->payload)["seq"], 5);
  EXPECT_GE(server_->counters().refused_requests, 6u);
}

TEST_F(DashServer, ClosesAClientThatSendsAnOversizedMessageWithCode1009AndServesTheOthers) {
  options_.max_incoming_bytes = 4096;
  start();
  Client bad(server_->port());
  Client good(server_->port());
  bad.handshake_messages();
  good.handshake_messages();
  subscribe(good, 1, feed_->id(PneuChannel::kState));
  bad.send(std::string(5000, ' '));
  beast::error_code ec;
  EXPECT_FALSE(bad.read(10s, &ec));
  EXPECT_EQ(ec, websocket::error::closed) << ec.message();
  EXPECT_EQ(bad.ws().reason().code, websocket::close_code::too_big);
  barrier(good);
  forward_state(9);
  const auto m = good.read_message();
  ASSERT_TRUE(m);
  EXPECT_EQ(json::parse(m->payload)["seq"], 9);
}

TEST_F(DashServer, ClosesAClientThatSendsAMalformedFrameWithAProtocolErrorAndServesTheOthers) {
  start();
  Client bad(server_->port());
  Client good(server_->port());
  bad.handshake_messages();
  good.handshake_messages();
  subscribe(good, 1, feed_->id(PneuChannel::kState));
  // A frame of the reserved opcode 3, masked as a client's must be, empty.
  const unsigned char frame[] = {0x83, 0x80, 0x01, 0x02, 0x03, 0x04};
  asio::write(bad.ws().next_layer(), asio::buffer(frame));
  beast::error_code ec;
  EXPECT_FALSE(bad.read(10s, &ec));
  EXPECT_EQ(ec, websocket::error::closed) << ec.message();
  EXPECT_EQ(bad.ws().reason().code, websocket::close_code::protocol_error);
  barrier(good);
  forward_state(10);
  const auto m = good.read_message();
  ASSERT_TRUE(m);
  EXPECT_EQ(json::parse(m->payload)["seq"], 10);
}

TEST_F(DashServer, ClosesAClientThatSendsTextThatIsNotUtf8WithCode1007) {
  start();
  Client bad(server_->port());
  bad.handshake_messages();
  bad.send(std::string("{\"op\":\"\xff\xfe\"}"));
  beast::error_code ec;
  EXPECT_FALSE(bad.read(10s, &ec));
  EXPECT_EQ(ec, websocket::error::closed) << ec.message();
  EXPECT_EQ(bad.ws().reason().code, websocket::close_code::bad_payload);
}

TEST_F(DashServer, RefusesAFloodOfSubscriptionsBeyondItsLimitInOneStatusAndKeepsTheOnesWithin) {
  options_.max_subscriptions = 16;
  start();
  Client c(server_->port());
  c.handshake_messages();
  json subs = json::array();
  for (int i = 0; i < 1000; ++i) subs.push_back({{"id", i}, {"channelId", feed_->id(PneuChannel::kState)}});
  c.send(json{{"op", "subscribe"}, {"subscriptions", subs}}.dump());
  const json s = c.read_json();
  EXPECT_EQ(s["level"], 2);
  EXPECT_NE(s["message"].get<std::string>().find("refused 984 subscriptions"), std::string::npos) << s.dump();
  EXPECT_NE(s["message"].get<std::string>().find("more than 16"), std::string::npos) << s.dump();
  forward_state(11);
  std::set<std::uint32_t> ids;
  for (int i = 0; i < 16; ++i) {
    const auto m = c.read_message();
    ASSERT_TRUE(m);
    ids.insert(m->subscription);
  }
  EXPECT_EQ(ids.size(), 16u);
  EXPECT_EQ(*ids.rbegin(), 15u);
}

// What the subscriptions get: each message's "seq" (-1 when it has none) and the statuses, read
// until `done` holds (or 10 s pass: a failure).
struct Received {
  std::map<std::uint32_t, std::vector<std::int64_t>> seqs;  // subscription -> its messages' seq
  std::vector<json> statuses;
};
template <class Done>
Received read_until(Client& c, Done done) {
  Received r;
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (!done(r)) {
    if (std::chrono::steady_clock::now() > deadline) {
      ADD_FAILURE() << "not done within 10 s";
      break;
    }
    const auto f = c.read(10s);
    if (!f) break;
    if (f->text) {
      r.statuses.push_back(json::parse(f->data));
      continue;
    }
    const auto* b = reinterpret_cast<const std::uint8_t*>(f->data.data());
    std::uint32_t sub = 0;
    for (int i = 3; i >= 0; --i) sub = (sub << 8) | b[1 + i];
    const json m = json::parse(f->data.substr(13));
    r.seqs[sub].push_back(m.value("seq", std::int64_t{-1}));
  }
  return r;
}

TEST_F(DashServer, ASubscriptionAtMostAtARateGetsTheNewestTickEveryEventAndIsToldWhatItSkipped) {
  start();
  Client c(server_->port());
  auto channels = c.handshake_messages();
  // The ticks are advertised latest-wins, no other channel.
  for (const auto& [topic, ch] : channels) EXPECT_EQ(ch.value("latestWins", false), topic == "PNEU_STATE") << topic;
  // 1 Hz: of the burst below the first goes at once, the newest when its second is up; events all.
  c.send(json{{"op", "subscribe"},
              {"subscriptions",
               {{{"id", 1}, {"channelId", feed_->id(PneuChannel::kState)}, {"maxRateHz", 1}},
                {{"id", 2}, {"channelId", feed_->id(PneuChannel::kEvent)}, {"maxRateHz", 1}}}}}
             .dump());
  barrier(c);
  constexpr int kTicks = 500;
  const auto ev = encoded_event("every one");
  for (int i = 0; i < kTicks; ++i) {
    forward_state(static_cast<std::uint64_t>(i));
    if (i % 100 == 50) {
      ASSERT_TRUE(feed_->forward("PNEU_EVENT", ev.data(), ev.size(), 5));
    }
  }
  const Received r = read_until(c, [](const Received& got) {
    return !got.statuses.empty() && got.seqs.contains(1) && got.seqs.at(1).back() == kTicks - 1;
  });
  EXPECT_EQ(r.seqs.at(1), (std::vector<std::int64_t>{0, kTicks - 1})) << "the first, then the newest";
  ASSERT_TRUE(r.seqs.contains(2));
  EXPECT_EQ(r.seqs.at(2).size(), 5u) << "every event, whatever rate was asked";
  ASSERT_EQ(r.statuses.size(), 1u);
  const json& report = r.statuses[0];
  EXPECT_EQ(report["id"], pneu::dash::kSkippedStatusId) << report.dump();
  EXPECT_EQ(report["level"], 0);
  EXPECT_EQ(report["subscriptionId"], 1);
  EXPECT_EQ(report["skipped"], kTicks - 2);
  EXPECT_NE(report["message"].get<std::string>().find("498 messages of PNEU_STATE skipped for subscription 1"),
            std::string::npos) << report.dump();
  for (const auto& ch : server_->counters().channels) {
    if (ch.topic == "PNEU_STATE") {
      EXPECT_EQ(ch.sent, 2u);
      EXPECT_EQ(ch.skipped, kTicks - 2u);
      EXPECT_EQ(ch.dropped, 0u);
    } else if (ch.topic == "PNEU_EVENT") {
      EXPECT_EQ(ch.sent, 5u);
      EXPECT_EQ(ch.skipped, 0u);
    }
  }
  EXPECT_NE(get(server_->port(), "/metrics").find("pneu_dash_messages_skipped_total{channel=\"PNEU_STATE\"} 498\n"),
            std::string::npos);
}

TEST_F(DashServer, TheServersRateGoesToASubscriptionThatAsksNoneSaidOnceAndMaxRate0AsksEveryMessage) {
  options_.max_rate_hz = 1;  // pneu-dash --max-rate-hz 1
  start();
  Client c(server_->port());
  c.handshake_messages();
  c.send(json{{"op", "subscribe"},
              {"subscriptions",
               {{{"id", 1}, {"channelId", feed_->id(PneuChannel::kState)}},
                {{"id", 2}, {"channelId", feed_->id(PneuChannel::kState)}, {"maxRateHz", 0}}}}}
             .dump());
  const json said = c.read_json();
  EXPECT_EQ(said["id"], "pneu-dash.rate") << said.dump();
  EXPECT_EQ(said["level"], 0);
  EXPECT_NE(said["message"].get<std::string>().find("PNEU_STATE: at most 1 Hz to subscription 1 (pneu-dash --max-rate-hz)"),
            std::string::npos) << said.dump();
  barrier(c);
  constexpr int kTicks = 100;
  for (int i = 0; i < kTicks; ++i) forward_state(static_cast<std::uint64_t>(i));
  Received r = read_until(c, [](const Received& got) {
    return got.seqs.contains(1) && got.seqs.at(1).back() == kTicks - 1 && got.seqs.contains(2) &&
           got.seqs.at(2).size() == kTicks;
  });
  EXPECT_EQ(r.seqs.at(1), (std::vector<std::int64_t>{0, kTicks - 1}));
  for (int i = 0; i < kTicks; ++i) ASSERT_EQ(r.seqs.at(2)[static_cast<std::size_t>(i)], i) << "every message";
  // Not told its skips (it did not ask, it may not know the status): past a report's time, nothing.
  std::this_thread::sleep_for(std::chrono::duration<double>(2 * pneu::dash::kSkippedReportS));
  c.send(R"({"op":"barrier"})");
  r = read_until(c, [](const Received& got) { return !got.statuses.empty(); });
  ASSERT_EQ(r.statuses.size(), 1u);
  EXPECT_NE(r.statuses[0]["message"].get<std::string>().find("unknown op \"barrier\""), std::string::npos)
      << r.statuses[0].dump();
}

TEST_F(DashServer, RefusesARateThatIsNotANumberFrom0To100kHzSayingWhyAndKeepsTheOthers) {
  start();
  Client c(server_->port());
  c.handshake_messages();
  const auto state = feed_->id(PneuChannel::kState);
  c.send(json{{"op", "subscribe"},
              {"subscriptions",
               {{{"id", 1}, {"channelId", state}, {"maxRateHz", -1}},
                {{"id", 2}, {"channelId", state}, {"maxRateHz", "60"}},
                {{"id", 3}, {"channelId", state}, {"maxRateHz", 1e9}},
                {{"id", 4}, {"channelId", state}, {"maxRateHz", nullptr}},
                {{"id", 5}, {"channelId", state}, {"maxRateHz", true}},
                {{"id", 6}, {"channelId", state}, {"maxRateHz", 60}}}}}
             .dump());
  const json s = c.read_json();
  EXPECT_EQ(s["level"], 2);
  EXPECT_NE(s["message"].get<std::string>().find(
                "refused 5 subscriptions (\"maxRateHz\" must be a number from 0 (every message) to 100000 Hz, got -1)"),
            std::string::npos) << s.dump();
  barrier(c);
  forward_state(7);
  const auto m = c.read_message();
  ASSERT_TRUE(m);
  EXPECT_EQ(m->subscription, 6u);
  EXPECT_EQ(json::parse(m->payload)["seq"], 7);
}

TEST(DashCli, RefusesAServerRateThatIsNotANumberFrom0To100kHzAndSaysTheRateItServes) {
  const fs::path dir = fs::temp_directory_path() / ("pneu_dash_cli_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const auto run = [&](const std::string& rate) {
    pneu::test::Child c = pneu::test::Child::spawn(
        {pneu::test::bin("pneu-dash"), "--listen", "127.0.0.1:0", "--max-rate-hz", rate, "--check-config"}, dir / "out",
        dir / "err");
    const int code = c.wait();
    return std::make_tuple(code, pneu::test::slurp(dir / "out"), pneu::test::slurp(dir / "err"));
  };
  for (const char* bad : {"-1", "1e6", "abc", "nan"}) {
    const auto [code, out, err] = run(bad);
    EXPECT_EQ(code, 2) << bad;
    EXPECT_NE(err.find("--max-rate-hz"), std::string::npos) << err;
  }
  const auto [code, out, err] = run("60");
  EXPECT_EQ(code, 0) << err;
  EXPECT_NE(out.find("PNEU_STATE at most 60 Hz unless a subscription asks"), std::string::npos) << out;
  fs::remove_all(dir);
}

TEST_F(DashServer, RefusesAWebSocketWithoutTheFoxgloveSubprotocolSayingWhich) {
  start();
  try {
    Client c(server_->port(), "other.v2");
    FAIL() << "the handshake succeeded";
  } catch (const beast::system_error& e) {
    EXPECT_EQ(e.code(), websocket::error::upgrade_declined) << e.code().message();
  }
  const std::string r = http_raw(server_->port(),
                                 "GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: Upgrade\r\nUpgrade: websocket\r\n"
                                 "Sec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n");
  EXPECT_EQ(r.rfind("HTTP/1.1 400", 0), 0u) << r;
  EXPECT_NE(r.find("foxglove.websocket.v1 required"), std::string::npos) << r;
}

TEST_F(DashServer, AnswersASlowLorisWith408AfterTheHeaderTimeoutWhileServingOthers) {
  options_.header_timeout_s = 1.0;
  start();
  asio::io_context ioc;
  tcp::socket slow(ioc);
  slow.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), server_->port()));
  asio::write(slow, asio::buffer(std::string("GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n")));
  // Meanwhile another is served.
  const std::string other = get(server_->port(), "/");
  EXPECT_EQ(other.rfind("HTTP/1.1 200", 0), 0u) << other;
  std::string out;
  beast::error_code ec;
  char buf[1024];
  for (;;) {
    const std::size_t n = slow.read_some(asio::buffer(buf), ec);
    out.append(buf, n);
    if (ec) break;
  }
  EXPECT_EQ(out.rfind("HTTP/1.1 408", 0), 0u) << out;
  EXPECT_NE(out.find("did not arrive within"), std::string::npos) << out;
  EXPECT_EQ(ec, asio::error::eof) << ec.message();  // and closed
}

TEST_F(DashServer, ServesStaticFilesWithTheirContentTypesAndNothingOutsideItsDirectory) {
  start();
  const auto p = server_->port();
  std::string r = get(p, "/");
  EXPECT_EQ(r.rfind("HTTP/1.1 200", 0), 0u) << r;
  EXPECT_NE(r.find("Content-Type: text/html; charset=utf-8"), std::string::npos) << r;
  EXPECT_NE(r.find("<title>pneu</title>"), std::string::npos);
  r = get(p, "/js/app.js?v=1");
  EXPECT_NE(r.find("Content-Type: text/javascript"), std::string::npos) << r;
  for (const std::string bad : {"/../pneu_dash_secret.txt", "/js/../../pneu_dash_secret.txt", "/%2e%2e/pneu_dash_secret.txt",
                                "//etc/passwd", "/js\\..\\..\\pneu_dash_secret.txt"}) {
    r = get(p, bad);
    EXPECT_EQ(r.rfind("HTTP/1.1 400", 0), 0u) << bad << ": " << r;
    EXPECT_EQ(r.find("secret\n"), std::string::npos);
  }
  EXPECT_EQ(get(p, "/missing.js").rfind("HTTP/1.1 404", 0), 0u);
  EXPECT_EQ(get(p, "/", "POST").rfind("HTTP/1.1 405", 0), 0u);
  EXPECT_EQ(http_raw(p, "NOT A REQUEST\r\n\r\n").rfind("HTTP/1.1 400", 0), 0u);
  EXPECT_EQ(http_raw(p, "GET / HTTP/1.1\r\nX: " + std::string(10000, 'a') + "\r\n\r\n").rfind("HTTP/1.1 431", 0), 0u);
  EXPECT_EQ(http_raw(p, "POST /playback HTTP/1.1\r\nHost: x\r\nContent-Length: 70000\r\n\r\n")
                .rfind("HTTP/1.1 413", 0),
            0u);
}

TEST_F(DashServer, ClosesAnIdleKeptAliveConnectionAfterTheHeaderTimeoutWithoutA408) {
  options_.header_timeout_s = 0.5;
  start();
  const std::string r = http_raw(server_->port(), "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");  // kept alive
  EXPECT_EQ(r.rfind("HTTP/1.1 200", 0), 0u) << r;
  EXPECT_EQ(r.find("408"), std::string::npos) << r;
}

TEST_F(DashServer, ServesItsCountersAtMetricsUntilAMetricsHookIsSet) {
  start();
  forward_state(1);
  forward_state(2);
  std::this_thread::sleep_for(100ms);
  std::string r = get(server_->port(), "/metrics");
  EXPECT_NE(r.find("text/plain; version=0.0.4"), std::string::npos) << r;
  EXPECT_NE(r.find("pneu_dash_messages_published_total{channel=\"PNEU_STATE\"} 2\n"), std::string::npos) << r;
  EXPECT_NE(r.find("pneu_dash_messages_published_total{channel=\"PNEU_HEALTH\"} 0\n"), std::string::npos) << r;
}

TEST(DashServerHooks, RoutesTheMetricsHookAndClientsMessagesGoWhereTheyAreGiven) {
  ServerOptions o;
  o.port = 0;
  Server server(o);
  server.set_metrics([] { return std::string("pneu_bench_up 1\n"); });
  server.add_route("POST", "/echo", [](const pneu::dash::HttpRequest& r) {
    return pneu::dash::HttpResponse{201, "application/json", r.body + r.header("X-Bench") + " " + r.remote};
  });
  server.set_websocket_check([](const pneu::dash::HttpRequest& r) -> std::string {
    return r.header("sec-websocket-protocol") == "foxglove.websocket.v1, refuse-me" ? "not you" : "";
  });
  std::vector<std::string> taken;
  server.set_client_publish([&](const pneu::dash::ClientMessage& m) -> std::string {
    const std::string payload(m.payload.begin(), m.payload.end());
    if (payload == "bad") return "refused: bad";
    taken.push_back(m.topic + ":" + payload);
    return "";
  });
  std::thread t([&] { server.run(); });
  EXPECT_NE(get(server.port(), "/metrics").find("\r\n\r\npneu_bench_up 1\n"), std::string::npos);
  const std::string r = http_raw(server.port(),
                                 "POST /echo HTTP/1.1\r\nHost: x\r\nx-bench: b7\r\nConnection: close\r\nContent-Length: 4\r\n\r\n{\"a\"");
  EXPECT_EQ(r.rfind("HTTP/1.1 201", 0), 0u) << r;
  EXPECT_NE(r.find("{\"a\"b7 127.0.0.1"), std::string::npos) << r;
  const std::string refused =
      http_raw(server.port(), "GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: Upgrade\r\nUpgrade: websocket\r\n"
                              "Sec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                              "Sec-WebSocket-Protocol: foxglove.websocket.v1, refuse-me\r\n\r\n");
  EXPECT_EQ(refused.rfind("HTTP/1.1 403", 0), 0u) << refused;
  EXPECT_NE(refused.find("not you"), std::string::npos) << refused;
  EXPECT_EQ(get(server.port(), "/echo").rfind("HTTP/1.1 405", 0), 0u);
  {
    Client c(server.port());
    const json info = c.read_json();
    EXPECT_NE(info["capabilities"].dump().find("clientPublish"), std::string::npos) << info.dump();
    c.send(R"({"op":"advertise","channels":[{"id":4,"topic":"/cmd","encoding":"json","schemaName":"command"}]})");
    c.send_binary(std::string("\x01\x04\x00\x00\x00", 5) + "arm");
    c.send_binary(std::string("\x01\x04\x00\x00\x00", 5) + "bad");
    const json s = c.read_json();
    EXPECT_EQ(s["message"], "refused: bad");
    c.send_binary(std::string("\x01\x05\x00\x00\x00", 5) + "x");
    EXPECT_NE(c.read_json()["message"].get<std::string>().find("did not advertise"), std::string::npos);
  }
  server.stop();
  t.join();
  EXPECT_EQ(taken, std::vector<std::string>{"/cmd:arm"});
}

TEST_F(DashServer, AClientThatStopsReadingCostsBoundedMemoryGivesUpItsOldestTicksIsToldItsDropsAndSlowsNoOther) {
  options_.max_queue_bytes = 64u << 10;
  options_.socket_send_buffer_bytes = 16u << 10;
  start();
  Client slow(server_->port(), pneu::dash::kSubprotocol, 8u << 10);
  Client fast(server_->port());
  slow.handshake_messages();
  fast.handshake_messages();
  subscribe(slow, 1, feed_->id(PneuChannel::kState));
  subscribe(slow, 2, feed_->id(PneuChannel::kEvent));
  subscribe(fast, 1, feed_->id(PneuChannel::kState));
  barrier(slow);
  barrier(fast);
  constexpr int kMessages = 3000;  // ~250 bytes each: far more than the slow one's queue and buffers
  std::atomic<int> fast_received{0};
  std::thread reader([&] {
    for (int i = 0; i < kMessages; ++i) {
      const auto m = fast.read_message();
      ASSERT_TRUE(m) << i;
      ASSERT_EQ(json::parse(m->payload)["seq"], i) << "the fast client missed one";
      ++fast_received;
    }
  });
  // In bursts the fast one reads before the next: what it misses, the slow one made it miss. Events
  // among them, while the slow one's queue is full.
  constexpr int kEvents = 10;
  const auto ev = encoded_event("never dropped while states can make room");
  for (int i = 0; i < kMessages; ++i) {
    forward_state(static_cast<std::uint64_t>(i));
    if (i % (kMessages / kEvents) == kMessages / kEvents - 1) {
      ASSERT_TRUE(feed_->forward("PNEU_EVENT", ev.data(), ev.size(), 5));
    }
    if (i % 50 == 49)
      for (int w = 0; w < 2000 && fast_received < i + 1; ++w) std::this_thread::sleep_for(1ms);
  }
  reader.join();
  const auto counters = server_->counters();
  std::uint64_t dropped = 0;
  for (const auto& c : counters.channels)
    if (c.topic == "PNEU_STATE") dropped = c.dropped;
  EXPECT_GT(dropped, 0u);
  // The slow one reads again: what it gets plus what it is told it missed is every message; its
  // full queue gave up its oldest states, not the newest (it gets the last), nor an event.
  int received = 0, events = 0;
  std::uint64_t told = 0;
  std::int64_t last_seq = -1;
  while (received + static_cast<int>(told) < kMessages || events < kEvents) {
    const auto f = slow.read(10s);
    ASSERT_TRUE(f) << received << " received, " << told << " told dropped";
    if (f->text) {
      const json s = json::parse(f->data);
      ASSERT_EQ(s["op"], "status");
      EXPECT_EQ(s["level"], 1);
      EXPECT_EQ(s["id"], "pneu-dash.dropped");
      const std::string text = s["message"];
      told += std::stoull(text.substr(std::string("dropped ").size()));
      EXPECT_NE(text.find("PNEU_STATE"), std::string::npos) << text;
      continue;
    }
    if (f->data[1] == 2) {
      ++events;
      continue;
    }
    const json record = json::parse(f->data.substr(13));
    EXPECT_GT(record["seq"].get<std::int64_t>(), last_seq);
    last_seq = record["seq"];
    ++received;
  }
  EXPECT_EQ(told, dropped);
  EXPECT_LT(received, kMessages);
  EXPECT_GT(told, 0u);
  EXPECT_EQ(events, kEvents);
  EXPECT_EQ(last_seq, kMessages - 1) << "the newest state";
}

// A log of 200 states 10 ms apart, an event at 1 s.
fs::path write_log(const fs::path& dir) {
  const fs::path file = dir / "run.lcmlog";
  lcm::LogFile log(file.string(), "w");
  for (int i = 0; i < 200; ++i) {
    auto b = encoded_state(static_cast<std::uint64_t>(i));
    lcm::LogEvent e{};
    e.timestamp = 1'700'000'000'000'000 + i * 10'000;
    e.channel = "PNEU_STATE";
    e.datalen = static_cast<std::int32_t>(b.size());
    e.data = b.data();
    log.writeEvent(&e);
    if (i == 100) {
      auto ev = encoded_event("at one second");
      e.channel = "PNEU_EVENT";
      e.datalen = static_cast<std::int32_t>(ev.size());
      e.data = ev.data();
      log.writeEvent(&e);
    }
  }
  return file;
}

TEST_F(DashServer, PlaysALogWithPlayPauseSeekAndTheTimeCursorOverHttp) {
  make();
  const fs::path log = write_log(www_);
  pneu::dash::LogPlayer player(
      log,
      [this](const std::string& channel, const void* data, std::size_t size, std::int64_t utime) {
        feed_->forward(channel, data, size, utime);
      },
      [this](std::uint64_t t) { server_->publish_time(t); });
  player.attach(*server_);
  run();
  Client c(server_->port());
  const json info = c.read_json();
  EXPECT_NE(info["capabilities"].dump().find("\"time\""), std::string::npos);
  c.read_json();  // advertise
  subscribe(c, 1, feed_->id(PneuChannel::kState));
  barrier(c);
  std::string r = get(server_->port(), "/playback");
  json state = json::parse(r.substr(r.find("\r\n\r\n") + 4));
  EXPECT_EQ(state["playing"], false);
  EXPECT_NEAR(state["duration_s"].get<double>(), 1.99, 1e-9);
  // Seek to 1 s and play fast: from the state at 1 s on, in order, a time message among them.
  const std::string go = R"({"seek_s":1.0,"rate":20.0,"play":true})";
  r = http_raw(server_->port(), "POST /playback HTTP/1.1\r\nHost: x\r\nConnection: close\r\nContent-Length: " +
                                    std::to_string(go.size()) + "\r\n\r\n" + go);
  EXPECT_EQ(r.rfind("HTTP/1.1 200", 0), 0u) << r;
  int expected = 100;
  bool time_seen = false;
  while (expected < 200) {
    const auto f = c.read();
    ASSERT_TRUE(f);
    ASSERT_FALSE(f->text) << f->data;
    if (f->data[0] == 0x02) {
      time_seen = true;
      continue;
    }
    ASSERT_EQ(json::parse(f->data.substr(13))["seq"], expected);
    ++expected;
  }
  EXPECT_TRUE(time_seen);
  for (int i = 0; i < 100 && !player.state().ended; ++i) std::this_thread::sleep_for(20ms);
  EXPECT_TRUE(player.state().ended);
  EXPECT_FALSE(player.state().playing);
  // Refused with a reason.
  for (const std::string body : {R"({"rate":0})", R"({"play":"yes"})", R"({"jump":1})", "nonsense"}) {
    r = http_raw(server_->port(), "POST /playback HTTP/1.1\r\nHost: x\r\nConnection: close\r\nContent-Length: " +
                                      std::to_string(body.size()) + "\r\n\r\n" + body);
    EXPECT_EQ(r.rfind("HTTP/1.1 400", 0), 0u) << body << ": " << r;
  }
  // Paused at 0.5 s: nothing more comes but the cursor.
  player.seek(0.5);
  EXPECT_NEAR(player.state().position_s, 0.5, 1e-9);
  EXPECT_FALSE(player.state().playing);
}

TEST(DashLogPlayer, RefusesALogItCannotReadOrThatHoldsNothing) {
  EXPECT_THROW(pneu::dash::LogPlayer("/nonexistent/run.lcmlog", nullptr, nullptr), std::runtime_error);
  const fs::path empty = fs::temp_directory_path() / ("pneu_dash_empty_" + std::to_string(::getpid()) + ".lcmlog");
  { lcm::LogFile log(empty.string(), "w"); }
  EXPECT_THROW(pneu::dash::LogPlayer(empty, nullptr, nullptr), std::runtime_error);
  fs::remove(empty);
}

}  // namespace
