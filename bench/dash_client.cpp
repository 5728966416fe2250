// A client of pneu-dash's Foxglove WebSocket endpoint for bench/dash_clients.sh: subscribes to every
// channel advertised, receives every message frame and decodes its JSON (nlohmann), and writes, for
// each state message (<prefix>STATE), its seq, its t (the loop's time of the tick), the frame's
// timestamp (pneu-dash's LCM receipt, ns since the Unix epoch) and this client's CLOCK_MONOTONIC
// once the JSON is decoded. --stop-reading-after S: it stops reading S seconds after its handshake
// (the socket stays open), and reads again for the last --resume-s seconds to take the status
// message in which pneu-dash tells what it dropped. --max-rate-hz HZ: it asks the latest-wins
// channels (the ticks) at most at HZ ("maxRateHz"), and keeps pneu-dash's last report of what it
// skipped.
//
// usage: dash_client PORT SECONDS OUT_FILE [--stop-reading-after S] [--resume-s S] [--max-rate-hz HZ]
// OUT_FILE: "# key value" lines (the clock offset, counts by topic, statuses), then one line per
// state message: seq t_s frame_ns recv_mono_ns.
#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <string>
#include <thread>
#include <vector>

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using json = nlohmann::json;

namespace {

std::chrono::nanoseconds for_s(double s) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::duration<double>(std::max(0.0, s)));
}

std::int64_t ns_of(clockid_t id) {
  timespec ts{};
  clock_gettime(id, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

// CLOCK_REALTIME minus CLOCK_MONOTONIC [ns], from the tightest of many bracketing reads.
std::int64_t realtime_minus_monotonic_ns() {
  std::int64_t best_gap = INT64_MAX, offset = 0;
  for (int i = 0; i < 1000; ++i) {
    const std::int64_t m0 = ns_of(CLOCK_MONOTONIC);
    const std::int64_t r = ns_of(CLOCK_REALTIME);
    const std::int64_t m1 = ns_of(CLOCK_MONOTONIC);
    if (m1 - m0 < best_gap) {
      best_gap = m1 - m0;
      offset = r - (m0 + (m1 - m0) / 2);
    }
  }
  return offset;
}

struct StateRow {
  std::uint64_t seq;
  double t_s;
  std::uint64_t frame_ns;
  std::int64_t recv_mono_ns;
};

struct Client {
  websocket::stream<beast::tcp_stream> ws;
  asio::steady_timer timer;
  beast::flat_buffer buffer;
  std::map<std::uint32_t, std::string> topic_of_channel, topic_of_sub;
  std::map<std::string, std::uint64_t> count;
  std::vector<StateRow> states;
  std::vector<std::string> statuses;
  std::uint64_t bad_frames = 0;
  std::uint32_t next_sub = 0;
  double max_rate_hz = -1.0;  // < 0: not asked
  std::uint64_t skipped = 0;  // pneu-dash's last report

  explicit Client(asio::io_context& ioc) : ws(ioc), timer(ioc) { states.reserve(200000); }

  void on_text(const std::string& text) {
    const json j = json::parse(text);
    const std::string op = j.value("op", "");
    if (op == "advertise") {
      json subs = json::array();
      for (const json& c : j["channels"]) {
        const auto id = c["id"].get<std::uint32_t>();
        topic_of_channel[id] = c["topic"].get<std::string>();
        topic_of_sub[next_sub] = topic_of_channel[id];
        json sub = {{"id", next_sub++}, {"channelId", id}};
        if (max_rate_hz >= 0.0 && c.value("latestWins", false)) sub["maxRateHz"] = max_rate_hz;
        subs.push_back(sub);
      }
      ws.text(true);
      ws.write(asio::buffer(json{{"op", "subscribe"}, {"subscriptions", subs}}.dump()));
    } else if (op == "status" && j.value("id", "") == "pneu-dash.skipped") {
      skipped = j.value("skipped", std::uint64_t{0});
    } else if (op == "status") {
      statuses.push_back(std::to_string(j.value("level", -1)) + " " + j.value("message", ""));
    }
  }

  void on_binary(const std::uint8_t* p, std::size_t n) {
    if (n < 13 || p[0] != 0x01) {
      ++bad_frames;
      return;
    }
    std::uint32_t sub = 0;
    std::uint64_t frame_ns = 0;
    std::memcpy(&sub, p + 1, 4);  // little-endian, as this host
    std::memcpy(&frame_ns, p + 5, 8);
    const json record = json::parse(reinterpret_cast<const char*>(p) + 13, reinterpret_cast<const char*>(p) + n);
    const std::int64_t recv = ns_of(CLOCK_MONOTONIC);
    const auto it = topic_of_sub.find(sub);
    if (it == topic_of_sub.end()) {
      ++bad_frames;
      return;
    }
    ++count[it->second];
    if (it->second.size() >= 5 && it->second.compare(it->second.size() - 5, 5, "STATE") == 0)
      states.push_back({record["seq"].get<std::uint64_t>(), record["t"].get<double>(), frame_ns, recv});
  }

  void read() {
    ws.async_read(buffer, [this](beast::error_code ec, std::size_t) {
      if (ec) return;
      if (ws.got_text()) {
        on_text(beast::buffers_to_string(buffer.data()));
      } else {
        const auto data = buffer.data();
        on_binary(static_cast<const std::uint8_t*>(data.data()), data.size());
      }
      buffer.consume(buffer.size());
      read();
    });
  }
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: dash_client PORT SECONDS OUT_FILE [--stop-reading-after S] [--resume-s S]\n");
    return 2;
  }
  const std::string port = argv[1];
  const double seconds = std::stod(argv[2]);
  const std::string out_file = argv[3];
  double stop_after = -1.0, resume_s = 2.0, max_rate_hz = -1.0;
  for (int i = 4; i + 1 < argc; i += 2) {
    if (std::strcmp(argv[i], "--stop-reading-after") == 0) stop_after = std::stod(argv[i + 1]);
    else if (std::strcmp(argv[i], "--resume-s") == 0) resume_s = std::stod(argv[i + 1]);
    else if (std::strcmp(argv[i], "--max-rate-hz") == 0) max_rate_hz = std::stod(argv[i + 1]);
    else {
      std::fprintf(stderr, "dash_client: unknown option %s\n", argv[i]);
      return 2;
    }
  }
  asio::io_context ioc;
  Client c(ioc);
  c.max_rate_hz = max_rate_hz;
  tcp::resolver resolver(ioc);
  beast::get_lowest_layer(c.ws).connect(resolver.resolve("127.0.0.1", port));
  c.ws.set_option(websocket::stream_base::decorator([](websocket::request_type& req) {
    req.set(beast::http::field::sec_websocket_protocol, "foxglove.websocket.v1");
  }));
  c.ws.handshake("127.0.0.1:" + port, "/ws");
  c.read();
  const std::int64_t offset_ns = realtime_minus_monotonic_ns();
  if (stop_after >= 0.0) {
    ioc.run_for(for_s(stop_after));
    // Nothing runs the io_context: the read in flight takes nothing from the socket.
    std::this_thread::sleep_for(for_s(seconds - stop_after - resume_s));
    ioc.restart();
    ioc.run_for(for_s(resume_s));
  } else {
    ioc.run_for(for_s(seconds));
  }
  FILE* out = std::fopen(out_file.c_str(), "w");
  if (out == nullptr) {
    std::perror(out_file.c_str());
    return 1;
  }
  std::fprintf(out, "# realtime_minus_monotonic_ns %lld\n", static_cast<long long>(offset_ns));
  std::fprintf(out, "# bad_frames %llu\n", static_cast<unsigned long long>(c.bad_frames));
  if (max_rate_hz >= 0.0)
    std::fprintf(out, "# max_rate_hz %g\n# skipped %llu\n", max_rate_hz, static_cast<unsigned long long>(c.skipped));
  for (const auto& [topic, n] : c.count) std::fprintf(out, "# count %s %llu\n", topic.c_str(), static_cast<unsigned long long>(n));
  for (const auto& s : c.statuses) std::fprintf(out, "# status %s\n", s.c_str());
  for (const auto& r : c.states)
    std::fprintf(out, "%llu %.9f %llu %lld\n", static_cast<unsigned long long>(r.seq), r.t_s,
                 static_cast<unsigned long long>(r.frame_ns), static_cast<long long>(r.recv_mono_ns));
  std::fclose(out);
  return 0;
}
