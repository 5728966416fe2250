#include "pneu/dash/server.hpp"

#include <boost/asio/dispatch.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <deque>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>
#include <system_error>
#include <utility>

namespace pneu::dash {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using json = nlohmann::json;

namespace {

constexpr std::size_t kHeaderLimitBytes = 8u << 10;
constexpr std::size_t kBodyLimitBytes = 64u << 10;
// Replies (status, advertise) a client that does not read may have queued beyond its data queue's
// bound before it is disconnected: they are not dropped, as a client must know what it was told.
constexpr std::size_t kControlAllowanceBytes = 1u << 20;

void put_le(std::string& out, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out += static_cast<char>((v >> (8 * i)) & 0xff);
}

std::uint64_t get_le(const std::uint8_t* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

std::string trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return std::string(s);
}

bool offers_subprotocol(std::string_view header) {
  std::size_t start = 0;
  while (start <= header.size()) {
    const std::size_t comma = header.find(',', start);
    const std::size_t end = comma == std::string_view::npos ? header.size() : comma;
    if (trim(header.substr(start, end - start)) == kSubprotocol) return true;
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return false;
}

json status_json_object(int level, const std::string& message, const std::string& id = {}) {
  json j = {{"op", "status"}, {"level", level}, {"message", message}};
  if (!id.empty()) j["id"] = id;
  return j;
}

std::string status_json(int level, const std::string& message, const std::string& id = {}) {
  return status_json_object(level, message, id).dump();
}

// A rate as people write it: 60, 0.5, 2.5.
std::string rate_text(double hz) {
  std::ostringstream out;
  out << hz;
  return out.str();
}

// A subscription's optional "maxRateHz": nothing when absent, else a number from 0 (every message)
// to kMaxRateLimitHz; `why` says what is wrong with another.
std::optional<double> max_rate_of(const json& s, std::string& why) {
  if (!s.is_object()) return std::nullopt;
  const auto it = s.find("maxRateHz");
  if (it == s.end()) return std::nullopt;
  if (!it->is_number() || !(it->get<double>() >= 0.0) || it->get<double>() > kMaxRateLimitHz) {
    why = "\"maxRateHz\" must be a number from 0 (every message) to " + rate_text(kMaxRateLimitHz) + " Hz, got " +
          it->dump().substr(0, 40);
    return std::nullopt;
  }
  return it->get<double>();
}

// A client's integer field: an unsigned integer that fits uint32, or nothing.
std::optional<std::uint32_t> u32_of(const json& j, const char* key) {
  if (!j.is_object()) return std::nullopt;
  const auto it = j.find(key);
  if (it == j.end() || !it->is_number_integer()) return std::nullopt;
  if (it->is_number_unsigned()) {
    const auto v = it->get<std::uint64_t>();
    if (v > 0xffffffffu) return std::nullopt;
    return static_cast<std::uint32_t>(v);
  }
  const auto v = it->get<std::int64_t>();
  if (v < 0 || v > 0xffffffffLL) return std::nullopt;
  return static_cast<std::uint32_t>(v);
}

}  // namespace

std::string content_type_of(const std::filesystem::path& file) {
  static const std::map<std::string, std::string> kTypes = {
      {".html", "text/html; charset=utf-8"},   {".htm", "text/html; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"}, {".mjs", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},     {".json", "application/json"},
      {".svg", "image/svg+xml"},               {".png", "image/png"},
      {".jpg", "image/jpeg"},                  {".jpeg", "image/jpeg"},
      {".ico", "image/x-icon"},                {".txt", "text/plain; charset=utf-8"},
      {".map", "application/json"},            {".wasm", "application/wasm"},
      {".woff2", "font/woff2"}};
  const auto it = kTypes.find(file.extension().string());
  return it == kTypes.end() ? "application/octet-stream" : it->second;
}

class WsSession;

struct Channel {
  ChannelId id = 0;
  ChannelSpec spec;
  std::shared_ptr<const std::string> last;  // latched: the last message
  std::uint64_t last_time_ns = 0;
  mutable std::atomic<std::uint64_t> published{0}, sent{0}, dropped{0}, skipped{0};  // counters, read by counters()
};

// What outlives the Impl: counted by the sessions' destructors.
struct Live {
  std::atomic<std::size_t> connections{0};
  std::atomic<std::size_t> clients{0};
  std::atomic<std::uint64_t> clients_total{0};
  std::atomic<std::uint64_t> refused{0};
};

struct Server::Impl {
  asio::io_context ioc{1};  // first: destroyed last, its handlers (the sessions) before the rest
  ServerOptions options;
  tcp::acceptor acceptor;
  std::shared_ptr<Live> live = std::make_shared<Live>();
  mutable std::mutex table_mutex;  // the deque's growth against counters()
  std::deque<Channel> channels;    // id k at k - 1; grown on the server's thread only
  std::atomic<ChannelId> next_channel{1};
  std::vector<std::weak_ptr<WsSession>> sessions;
  std::vector<std::string> capabilities;
  std::map<std::pair<std::string, std::string>, RouteHandler> routes;
  std::function<std::string()> metrics;
  ClientPublishHandler client_publish;
  RouteHandlerCheck websocket_check;
  std::uint64_t next_client = 1;
  std::string session_id;
  std::atomic<bool> stopped{false};

  explicit Impl(ServerOptions o) : options(std::move(o)), acceptor(ioc) {
    const tcp::endpoint ep(asio::ip::make_address(options.address), options.port);
    acceptor.open(ep.protocol());
    acceptor.set_option(asio::socket_base::reuse_address(true));
    acceptor.bind(ep);
    acceptor.listen(asio::socket_base::max_listen_connections);
    session_id = std::to_string(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                    std::chrono::system_clock::now().time_since_epoch())
                                    .count());
  }

  Channel* channel(ChannelId id) { return id >= 1 && id <= channels.size() ? &channels[id - 1] : nullptr; }

  void accept();
  void do_publish(ChannelId id, std::uint64_t time_ns, std::shared_ptr<const std::string> payload);
  void do_time(std::uint64_t time_ns);
  void do_add_channel(ChannelId id, ChannelSpec spec);
  std::string server_info() const;
  static json channel_json(const Channel& c);
  template <class F>
  void for_each_session(F&& f) {
    std::erase_if(sessions, [](const std::weak_ptr<WsSession>& w) { return w.expired(); });
    const auto copy = sessions;
    for (const auto& w : copy)
      if (auto s = w.lock()) f(*s);
  }
  HttpResponse respond(const HttpRequest& req);
};

// ---------------------------------------------------------------------------------------------
// A WebSocket client: the Foxglove protocol.

class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(beast::tcp_stream&& stream, Server::Impl& server, std::shared_ptr<Live> live)
      : ws_(std::move(stream)), server_(server), live_(std::move(live)), id_(server.next_client++) {
    ++live_->connections;
  }
  ~WsSession() {
    --live_->connections;
    if (counted_) --live_->clients;
  }

  void start(http::request<http::string_body> req) {
    beast::get_lowest_layer(ws_).expires_never();
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.set_option(websocket::stream_base::decorator([](websocket::response_type& res) {
      res.set(http::field::server, "pneu-dash");
      res.set(http::field::sec_websocket_protocol, kSubprotocol);
    }));
    ws_.read_message_max(server_.options.max_incoming_bytes);
    ws_.async_accept(req, [self = shared_from_this()](beast::error_code ec) { self->on_accept(ec); });
  }

  // A message on `channel` to each subscription of it: now, or, for a subscription at most at a
  // rate, held until its time comes unless a newer one replaces it first (then it is skipped).
  void send_message(const Channel& c, std::uint64_t time_ns, const std::shared_ptr<const std::string>& payload) {
    for (auto& [sub, s] : subscriptions_) {
      if (s.channel != c.id) continue;
      if (s.interval.count() <= 0) {
        send_frame_of(sub, s, c, time_ns, *payload);
        continue;
      }
      const auto now = Clock::now();
      if (!s.pending && now >= s.last_sent + s.interval) {
        send_frame_of(sub, s, c, time_ns, *payload);
        s.last_sent = now;
        schedule(sub, s);
        continue;
      }
      if (s.pending) {
        ++s.skipped_since_sent;
        ++c.skipped;
      }
      s.pending = payload;
      s.pending_time_ns = time_ns;
      schedule(sub, s);
    }
  }

  void send_time(std::uint64_t time_ns) {
    auto frame = std::make_shared<std::string>();
    *frame += static_cast<char>(0x02);
    put_le(*frame, time_ns, 8);
    enqueue_data(std::move(frame));
  }

  void advertise(const std::vector<const Channel*>& channels) {
    if (channels.empty()) return;
    json list = json::array();
    for (const Channel* c : channels) list.push_back(Server::Impl::channel_json(*c));
    send_control(json{{"op", "advertise"}, {"channels", list}}.dump());
  }

  [[nodiscard]] std::uint64_t id() const noexcept { return id_; }
  void send_status(int level, const std::string& message, const std::string& id) {
    send_control(status_json(level, message, id));
  }

  void close() {
    if (closed_) return;
    closed_ = true;
    ws_.async_close(websocket::close_reason(websocket::close_code::going_away, "server stopping"),
                    [self = shared_from_this()](beast::error_code) {});
  }

 private:
  struct Out {
    std::shared_ptr<const std::string> data;
    bool binary;
    const Channel* state = nullptr;  // a latest-wins channel's message frame: may make room
  };
  using Clock = std::chrono::steady_clock;
  static constexpr auto kReportEvery =
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(kSkippedReportS));
  struct Subscription {
    explicit Subscription(const asio::any_io_executor& ex) : timer(ex) {}
    ChannelId channel = 0;
    Clock::duration interval{0};    // 0: every message
    bool reports = false;           // asked "maxRateHz": told its skips
    Clock::time_point last_sent{};  // of the last message sent now or when its time came
    std::shared_ptr<const std::string> pending;  // the newest message, held until its time
    std::uint64_t pending_time_ns = 0;
    std::uint64_t skipped_since_sent = 0;   // skipped since the last message queued to it
    std::uint64_t skipped_before_sent = 0;  // skipped before the last message queued to it
    std::uint64_t skipped_told = 0;         // the last report's
    Clock::time_point last_report{};
    asio::steady_timer timer;
    bool armed = false;
  };

  void on_accept(beast::error_code ec) {
    if (ec) return;
    if (server_.stopped) return close();
    counted_ = true;
    ++live_->clients;
    ++live_->clients_total;
    server_.sessions.push_back(weak_from_this());
    send_control(server_.server_info());
    std::vector<const Channel*> all;
    for (const Channel& c : server_.channels) all.push_back(&c);
    advertise(all);
    do_read();
  }

  void do_read() {
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
  }

  void on_read(beast::error_code ec) {
    if (ec) {
      // Beast has already closed with the reason's code: 1009 too big, 1002 a malformed frame,
      // 1007 text that is not UTF-8.
      if (ec != websocket::error::closed && ec != asio::error::operation_aborted) ++live_->refused;
      closed_ = true;
      return;
    }
    const auto data = buffer_.cdata();
    const auto* bytes = static_cast<const std::uint8_t*>(data.data());
    if (ws_.got_text()) {
      handle_text(std::string_view(reinterpret_cast<const char*>(bytes), data.size()));
    } else {
      handle_binary(std::span<const std::uint8_t>(bytes, data.size()));
    }
    buffer_.consume(buffer_.size());
    if (!closed_) do_read();
  }

  void refuse(const std::string& why) {
    ++live_->refused;
    send_control(status_json(2, why));
  }

  void handle_text(std::string_view text) {
    const json j = json::parse(text, nullptr, false);
    if (j.is_discarded()) return refuse("malformed JSON: a text message must be one JSON object with an \"op\"");
    if (!j.is_object() || !j.contains("op") || !j["op"].is_string())
      return refuse("a text message must be a JSON object with a string \"op\"");
    const std::string op = j["op"].get<std::string>();
    if (op == "subscribe") return subscribe(j);
    if (op == "unsubscribe") return unsubscribe(j);
    if (op == "advertise") return client_advertise(j);
    if (op == "unadvertise") return client_unadvertise(j);
    std::string shown = op.substr(0, 64);
    refuse("unknown op \"" + json(shown).get<std::string>() + "\" (this server takes subscribe, unsubscribe" +
           (server_.client_publish ? ", advertise, unadvertise" : "") + ")");
  }

  void subscribe(const json& j) {
    const auto it = j.find("subscriptions");
    if (it == j.end() || !it->is_array()) return refuse("subscribe: \"subscriptions\" must be an array");
    std::size_t refused = 0, over = 0;
    std::string first;
    for (const json& s : *it) {
      const auto sub = u32_of(s, "id");
      const auto ch = u32_of(s, "channelId");
      std::string why;
      const auto rate = max_rate_of(s, why);  // "maxRateHz", optional
      if (!why.empty()) {
        // refused for its rate
      } else if (!sub || !ch) {
        why = "each subscription needs an unsigned 32-bit \"id\" and \"channelId\"";
      } else if (server_.channel(*ch) == nullptr) {
        why = "no channel " + std::to_string(*ch);
      } else if (subscriptions_.contains(*sub)) {
        why = "subscription id " + std::to_string(*sub) + " already in use";
      } else if (subscriptions_.size() >= server_.options.max_subscriptions) {
        ++over;
        why = "more than " + std::to_string(server_.options.max_subscriptions) + " subscriptions at once";
      }
      if (!why.empty()) {
        if (first.empty()) first = why;
        ++refused;
        continue;
      }
      const Channel* c = server_.channel(*ch);
      Subscription& added = subscriptions_.try_emplace(*sub, ws_.get_executor()).first->second;
      added.channel = *ch;
      // A rate applies to a latest-wins channel's messages only: the others all go.
      const double hz = c->spec.latest_wins ? rate.value_or(server_.options.max_rate_hz) : 0.0;
      if (hz > 0.0)
        added.interval = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / hz));
      added.reports = rate.has_value();
      if (hz > 0.0 && !rate)
        send_status(0,
                    c->spec.topic + ": at most " + rate_text(hz) + " Hz to subscription " + std::to_string(*sub) +
                        " (pneu-dash --max-rate-hz), the newest message each time; a subscription's \"maxRateHz\" "
                        "asks another rate, 0 every message",
                    "pneu-dash.rate");
      if (c->spec.latched && c->last) {
        auto frame = std::make_shared<std::string>();
        *frame += static_cast<char>(0x01);
        put_le(*frame, *sub, 4);
        put_le(*frame, c->last_time_ns, 8);
        *frame += *c->last;
        send_frame(std::move(frame));  // the constant a subscriber needs: never dropped
      }
    }
    if (refused > 0)
      refuse("subscribe: refused " + std::to_string(refused) + " subscription" + (refused > 1 ? "s" : "") + " (" +
             first + (over > 0 && first.find("more than") == std::string::npos
                          ? "; " + std::to_string(over) + " over the limit of " +
                                std::to_string(server_.options.max_subscriptions)
                          : "") +
             ")");
  }

  void unsubscribe(const json& j) {
    const auto it = j.find("subscriptionIds");
    if (it == j.end() || !it->is_array()) return refuse("unsubscribe: \"subscriptionIds\" must be an array");
    std::size_t unknown = 0;
    for (const json& id : *it) {
      if (!id.is_number_unsigned() || id.get<std::uint64_t>() > 0xffffffffu ||
          subscriptions_.erase(static_cast<std::uint32_t>(id.get<std::uint64_t>())) == 0)
        ++unknown;  // an erased subscription's held message goes with it, its timer is cancelled
    }
    if (unknown > 0) refuse("unsubscribe: " + std::to_string(unknown) + " unknown subscription id(s)");
  }

  void client_advertise(const json& j) {
    if (!server_.client_publish) return refuse("advertise: this server does not take clients' messages (no clientPublish)");
    const auto it = j.find("channels");
    if (it == j.end() || !it->is_array()) return refuse("advertise: \"channels\" must be an array");
    for (const json& c : *it) {
      const auto id = u32_of(c, "id");
      if (!id || !c.contains("topic") || !c["topic"].is_string() || !c.contains("encoding") || !c["encoding"].is_string())
        return refuse("advertise: each channel needs an unsigned 32-bit \"id\", a \"topic\" and an \"encoding\"");
      if (!client_channels_.contains(*id) && client_channels_.size() >= server_.options.max_client_channels)
        return refuse("advertise: more than " + std::to_string(server_.options.max_client_channels) + " channels");
      ClientChannel cc;
      cc.topic = c["topic"].get<std::string>();
      cc.encoding = c["encoding"].get<std::string>();
      if (c.contains("schemaName") && c["schemaName"].is_string()) cc.schema_name = c["schemaName"].get<std::string>();
      client_channels_[*id] = std::move(cc);
    }
  }

  void client_unadvertise(const json& j) {
    const auto it = j.find("channelIds");
    if (it == j.end() || !it->is_array()) return refuse("unadvertise: \"channelIds\" must be an array");
    for (const json& id : *it)
      if (id.is_number_unsigned() && id.get<std::uint64_t>() <= 0xffffffffu)
        client_channels_.erase(static_cast<std::uint32_t>(id.get<std::uint64_t>()));
  }

  void handle_binary(std::span<const std::uint8_t> bytes) {
    if (bytes.empty()) return refuse("an empty binary message");
    if (bytes[0] != 0x01)
      return refuse("binary op " + std::to_string(bytes[0]) + " not supported (this server takes 1: a message on a channel the client advertised)");
    if (!server_.client_publish) return refuse("this server does not take clients' messages (no clientPublish)");
    if (bytes.size() < 5) return refuse("a client message needs a 4-byte channel id");
    const auto id = static_cast<std::uint32_t>(get_le(bytes.data() + 1, 4));
    const auto it = client_channels_.find(id);
    if (it == client_channels_.end()) return refuse("client message on channel " + std::to_string(id) + ", which this client did not advertise");
    const ClientMessage m{id_, it->second.topic, it->second.encoding, it->second.schema_name, bytes.subspan(5)};
    const std::string why = server_.client_publish(m);
    if (!why.empty()) refuse(why);
  }

  // The data queue: beyond its bound, the oldest frames of latest-wins channels queued (not the one
  // being written) make room, each dropped and counted; when they do not suffice, this frame is
  // dropped (false).
  bool enqueue_data(std::shared_ptr<std::string> frame, const Channel* channel = nullptr) {
    if (closed_) return false;
    const std::size_t bound = server_.options.max_queue_bytes;
    if (queued_bytes_ + frame->size() > bound) evict_states(queued_bytes_ + frame->size() - bound);
    if (queued_bytes_ + frame->size() > bound) {
      count_drop(channel);
      return false;
    }
    push({std::move(frame), true, channel != nullptr && channel->spec.latest_wins ? channel : nullptr});
    return true;
  }

  void count_drop(const Channel* channel) {
    ++dropped_unreported_;
    ++dropped_total_;
    if (channel == nullptr) {
      ++dropped_by_topic_["(time)"];
      return;
    }
    ++channel->dropped;
    ++dropped_by_topic_[channel->spec.topic];
  }

  // Drops the oldest queued frames of latest-wins channels until `bytes` are freed or none is left.
  void evict_states(std::size_t bytes) {
    std::size_t freed = 0;
    // The front is being written when writing_.
    for (auto it = queue_.begin() + (writing_ && !queue_.empty() ? 1 : 0); it != queue_.end() && freed < bytes;) {
      if (it->state == nullptr) {
        ++it;
        continue;
      }
      freed += it->data->size();
      queued_bytes_ -= it->data->size();
      --it->state->sent;  // counted sent when it was queued
      count_drop(it->state);
      it = queue_.erase(it);
    }
  }

  void send_frame(std::shared_ptr<std::string> frame) { push_control({std::move(frame), true}); }
  void send_control(std::string text) { push_control({std::make_shared<std::string>(std::move(text)), false}); }

  // A message frame to subscription `sub`: queued (counted sent) or dropped (counted).
  void send_frame_of(std::uint32_t sub, Subscription& s, const Channel& c, std::uint64_t time_ns,
                     const std::string& payload) {
    auto frame = std::make_shared<std::string>();
    frame->reserve(13 + payload.size());
    *frame += static_cast<char>(0x01);
    put_le(*frame, sub, 4);
    put_le(*frame, time_ns, 8);
    *frame += payload;
    if (enqueue_data(std::move(frame), &c)) {
      ++c.sent;
      // The skips before it are now among those older than the last message sent.
      s.skipped_before_sent += s.skipped_since_sent;
      s.skipped_since_sent = 0;
    }
  }

  // Arms the subscription's timer for what it owes next: its held message when its time comes, the
  // report of its skips every kSkippedReportS.
  void schedule(std::uint32_t sub, Subscription& s) {
    auto next = Clock::time_point::max();
    if (s.pending) next = s.last_sent + s.interval;
    if (s.reports && s.skipped_before_sent != s.skipped_told)
      next = std::min(next, s.last_report + kReportEvery);
    if (next == Clock::time_point::max() || (s.armed && s.timer.expiry() <= next)) return;
    s.armed = true;
    s.timer.expires_at(next);
    s.timer.async_wait([self = shared_from_this(), sub](beast::error_code ec) {
      if (!ec) self->on_timer(sub);
    });
  }

  void on_timer(std::uint32_t sub) {
    const auto it = subscriptions_.find(sub);
    if (it == subscriptions_.end() || closed_) return;
    Subscription& s = it->second;
    s.armed = false;
    const auto now = Clock::now();
    if (s.pending && now >= s.last_sent + s.interval) {
      const Channel* c = server_.channel(s.channel);
      if (c != nullptr) send_frame_of(sub, s, *c, s.pending_time_ns, *s.pending);
      s.pending.reset();
      s.last_sent = now;
    }
    if (s.reports && s.skipped_before_sent != s.skipped_told && now >= s.last_report + kReportEvery) {
      s.skipped_told = s.skipped_before_sent;
      s.last_report = now;
      const Channel* c = server_.channel(s.channel);
      json j = status_json_object(0,
                                  std::to_string(s.skipped_told) + " messages of " + (c ? c->spec.topic : "?") +
                                      " skipped for subscription " + std::to_string(sub) + " since it subscribed (at most " +
                                      rate_text(1.0 / std::chrono::duration<double>(s.interval).count()) +
                                      " Hz asked: the newest message each time)",
                                  kSkippedStatusId);
      j["subscriptionId"] = sub;
      j["skipped"] = s.skipped_told;
      send_control(j.dump());
    }
    schedule(sub, s);
  }

  void push_control(Out out) {
    if (closed_) return;
    if (queued_bytes_ + out.data->size() > server_.options.max_queue_bytes + kControlAllowanceBytes) {
      // It does not read what it asks for: it goes.
      ++live_->refused;
      closed_ = true;
      beast::get_lowest_layer(ws_).close();
      return;
    }
    push(std::move(out));
  }

  void push(Out out) {
    queued_bytes_ += out.data->size();
    queue_.push_back(std::move(out));
    if (!writing_) do_write();
  }

  void do_write() {
    if (queue_.empty() || closed_) {
      writing_ = false;
      return;
    }
    writing_ = true;
    ws_.binary(queue_.front().binary);
    ws_.async_write(asio::buffer(*queue_.front().data),
                    [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_write(ec); });
  }

  void on_write(beast::error_code ec) {
    queued_bytes_ -= queue_.front().data->size();
    queue_.pop_front();
    if (ec) {
      closed_ = true;
      writing_ = false;
      return;
    }
    // It reads again: tell it what it missed.
    if (dropped_unreported_ > 0 && queued_bytes_ <= server_.options.max_queue_bytes / 2) {
      std::string by;
      for (const auto& [topic, n] : dropped_by_topic_) by += (by.empty() ? "" : ", ") + topic + " " + std::to_string(n);
      const std::string text = "dropped " + std::to_string(dropped_unreported_) + " messages (" + by +
                               ") as this client read too slowly; " + std::to_string(dropped_total_) +
                               " since it connected";
      dropped_unreported_ = 0;
      dropped_by_topic_.clear();
      push_control({std::make_shared<std::string>(status_json(1, text, "pneu-dash.dropped")), false});
    }
    do_write();
  }

  struct ClientChannel {
    std::string topic, encoding, schema_name;
  };

  websocket::stream<beast::tcp_stream> ws_;
  Server::Impl& server_;
  std::shared_ptr<Live> live_;
  std::uint64_t id_;
  beast::flat_buffer buffer_;
  std::deque<Out> queue_;
  std::size_t queued_bytes_ = 0;
  bool writing_ = false;
  bool closed_ = false;
  bool counted_ = false;
  std::map<std::uint32_t, Subscription> subscriptions_;
  std::map<std::uint32_t, ClientChannel> client_channels_;
  std::uint64_t dropped_unreported_ = 0, dropped_total_ = 0;
  std::map<std::string, std::uint64_t> dropped_by_topic_;
};

// ---------------------------------------------------------------------------------------------
// An HTTP connection: requests until it closes or upgrades to a WebSocket.

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket&& socket, Server::Impl& server, std::shared_ptr<Live> live)
      : stream_(std::move(socket)), timer_(stream_.get_executor()), server_(server), live_(std::move(live)) {
    ++live_->connections;
  }
  ~HttpSession() { --live_->connections; }

  void start() {
    if (live_->connections > server_.options.max_connections)
      return reply(503, "too many connections (" + std::to_string(server_.options.max_connections) + ")", false, 11);
    do_read();
  }

 private:
  void do_read() {
    parser_.emplace();
    parser_->header_limit(kHeaderLimitBytes);
    parser_->body_limit(kBodyLimitBytes);
    timed_out_ = false;
    timer_.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(server_.options.header_timeout_s)));
    timer_.async_wait([self = shared_from_this()](beast::error_code ec) {
      if (ec) return;
      self->timed_out_ = true;
      beast::error_code ignored;
      self->stream_.socket().cancel(ignored);
    });
    http::async_read(stream_, buffer_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
  }

  void on_read(beast::error_code ec) {
    timer_.cancel();
    if (timed_out_) {
      if (!parser_->got_some()) return shut();  // an idle kept-alive connection: closed, nothing refused
      ++live_->refused;
      return reply(408, "the request did not arrive within " + std::to_string(server_.options.header_timeout_s) + " s",
                   false, 11);
    }
    if (ec == http::error::end_of_stream || ec == asio::error::operation_aborted) return shut();
    if (ec) {
      ++live_->refused;
      if (ec == http::error::header_limit)
        return reply(431, "request header larger than " + std::to_string(kHeaderLimitBytes) + " bytes", false, 11);
      if (ec == http::error::body_limit)
        return reply(413, "request body larger than " + std::to_string(kBodyLimitBytes) + " bytes", false, 11);
      if (ec == asio::error::eof || ec == asio::error::connection_reset) return shut();
      return reply(400, "malformed request: " + ec.message(), false, 11);
    }
    auto req = parser_->release();
    if (websocket::is_upgrade(req)) {
      if (server_.websocket_check) {
        const HttpRequest r = request_of(req);
        if (std::string why = server_.websocket_check(r); !why.empty()) {
          ++live_->refused;
          return reply(403, why, false, req.version());
        }
      }
      const std::string target(req.target());
      if (target.substr(0, target.find('?')) != "/ws") {
        ++live_->refused;
        return reply(404, "WebSocket only at /ws", false, req.version());
      }
      const auto proto = req[http::field::sec_websocket_protocol];
      if (!offers_subprotocol(std::string_view(proto.data(), proto.size()))) {
        ++live_->refused;
        return reply(400,
                     std::string("WebSocket subprotocol ") + kSubprotocol + " required (offered: \"" +
                         std::string(proto.substr(0, 200)) + "\")",
                     false, req.version());
      }
      if (live_->clients >= server_.options.max_clients) {
        ++live_->refused;
        return reply(503, "too many WebSocket clients (" + std::to_string(server_.options.max_clients) + ")", false,
                     req.version());
      }
      std::make_shared<WsSession>(std::move(stream_), server_, live_)->start(std::move(req));
      return;
    }
    HttpRequest r = request_of(req);
    HttpResponse res = server_.respond(r);
    if (res.status >= 400) ++live_->refused;
    send(std::move(res), req.keep_alive(), req.version());
  }

  HttpRequest request_of(http::request<http::string_body>& req) {
    HttpRequest r;
    r.method = std::string(req.method_string());
    const std::string target(req.target());
    const auto q = target.find('?');
    r.path = target.substr(0, q);
    r.query = q == std::string::npos ? "" : target.substr(q + 1);
    for (const auto& field : req) {
      std::string name(field.name_string());
      for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      r.headers.emplace_back(std::move(name), std::string(field.value()));
    }
    beast::error_code ec;
    const auto peer = stream_.socket().remote_endpoint(ec);
    if (!ec) r.remote = peer.address().to_string();
    r.body = req.body();
    return r;
  }

  void reply(unsigned status, std::string text, bool keep_alive, unsigned version) {
    send(HttpResponse{status, "text/plain; charset=utf-8", std::move(text) + "\n"}, keep_alive, version);
  }

  void send(HttpResponse r, bool keep_alive, unsigned version) {
    auto res = std::make_shared<http::response<http::string_body>>(static_cast<http::status>(r.status), version);
    res->set(http::field::server, "pneu-dash");
    res->set(http::field::content_type, r.content_type);
    res->set(http::field::cache_control, "no-cache");
    res->set("X-Content-Type-Options", "nosniff");
    res->keep_alive(keep_alive);
    res->body() = std::move(r.body);
    res->prepare_payload();
    stream_.expires_after(std::chrono::seconds(30));
    http::async_write(stream_, *res, [self = shared_from_this(), res, keep_alive](beast::error_code ec, std::size_t) {
      if (ec || !keep_alive) return self->shut();
      self->stream_.expires_never();
      self->do_read();
    });
  }

  void shut() {
    beast::error_code ignored;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
    stream_.close();
  }

  beast::tcp_stream stream_;
  asio::steady_timer timer_;
  Server::Impl& server_;
  std::shared_ptr<Live> live_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  bool timed_out_ = false;
};

// ---------------------------------------------------------------------------------------------

void Server::Impl::accept() {
  acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted || !acceptor.is_open()) return;
    if (!ec) {
      beast::error_code ignored;
      if (options.socket_send_buffer_bytes > 0)
        socket.set_option(asio::socket_base::send_buffer_size(options.socket_send_buffer_bytes), ignored);
      socket.set_option(tcp::no_delay(true), ignored);
      std::make_shared<HttpSession>(std::move(socket), *this, live)->start();
    }
    accept();
  });
}

json Server::Impl::channel_json(const Channel& c) {
  json j = {{"id", c.id},
            {"topic", c.spec.topic},
            {"encoding", "json"},
            {"schemaName", c.spec.schema_name},
            {"schema", c.spec.schema},
            {"schemaEncoding", "jsonschema"}};
  if (!c.spec.sequence_field.empty()) j["sequenceField"] = c.spec.sequence_field;
  if (c.spec.latest_wins) j["latestWins"] = true;
  return j;
}

std::string Server::Impl::server_info() const {
  json caps = json::array();
  for (const auto& c : capabilities) caps.push_back(c);
  if (client_publish) caps.push_back("clientPublish");
  json metadata = json::object();
  for (const auto& [key, value] : options.metadata) metadata[key] = value;
  return json{{"op", "serverInfo"},
              {"name", options.name},
              {"capabilities", caps},
              {"supportedEncodings", json::array({"json"})},
              {"metadata", metadata},
              {"sessionId", session_id}}
      .dump();
}

void Server::Impl::do_add_channel(ChannelId id, ChannelSpec spec) {
  {
    const std::lock_guard lock(table_mutex);
    while (channels.size() < id) channels.emplace_back();
    channels[id - 1].id = id;
    channels[id - 1].spec = std::move(spec);
  }
  const Channel* c = &channels[id - 1];
  for_each_session([&](WsSession& s) { s.advertise({c}); });
}

void Server::Impl::do_publish(ChannelId id, std::uint64_t time_ns, std::shared_ptr<const std::string> payload) {
  Channel* c = channel(id);
  if (c == nullptr) return;
  ++c->published;
  if (c->spec.latched) {
    c->last = payload;
    c->last_time_ns = time_ns;
  }
  for_each_session([&](WsSession& s) { s.send_message(*c, time_ns, payload); });
}

void Server::Impl::do_time(std::uint64_t time_ns) {
  for_each_session([&](WsSession& s) { s.send_time(time_ns); });
}

HttpResponse Server::Impl::respond(const HttpRequest& req) {
  if (const auto it = routes.find({req.method, req.path}); it != routes.end()) return it->second(req);
  bool path_known = false;
  for (const auto& [key, handler] : routes) path_known = path_known || key.second == req.path;
  if (path_known) return {405, "text/plain; charset=utf-8", "method " + req.method + " not allowed on " + req.path + "\n"};
  if (req.path == "/metrics") {
    if (req.method != "GET" && req.method != "HEAD") return {405, "text/plain; charset=utf-8", "GET /metrics\n"};
    const std::string text = metrics ? metrics() : Server::counters_text_of(*this);
    return {200, "text/plain; version=0.0.4; charset=utf-8", text};
  }
  if (req.method != "GET" && req.method != "HEAD")
    return {405, "text/plain; charset=utf-8", "method " + req.method + " not allowed on " + req.path + "\n"};
  // A static file: a plain path under www, nothing that could leave it.
  const std::string& p = req.path;
  if (p.empty() || p[0] != '/' || p.find("..") != std::string::npos || p.find('\\') != std::string::npos ||
      p.find('%') != std::string::npos || p.find('\0') != std::string::npos || p.find("//") != std::string::npos)
    return {400, "text/plain; charset=utf-8", "bad path: a file under / by its plain name, without .. or %\n"};
  if (options.www.empty()) return {404, "text/plain; charset=utf-8", "no static files served (--www)\n"};
  std::filesystem::path file = options.www / (p == "/" || p.back() == '/' ? p.substr(1) + "index.html" : p.substr(1));
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) return {404, "text/plain; charset=utf-8", "not found: " + p + "\n"};
  std::ifstream in(file, std::ios::binary);
  std::ostringstream body;
  body << in.rdbuf();
  return {200, content_type_of(file), body.str()};
}

// ---------------------------------------------------------------------------------------------

Server::Server(ServerOptions options) : impl_(std::make_shared<Impl>(std::move(options))) { impl_->accept(); }

Server::~Server() {
  stop();
  // The handlers left (the sessions) go with the io_context, before the rest of Impl.
}

std::uint16_t Server::port() const noexcept { return impl_->acceptor.local_endpoint().port(); }

ChannelId Server::add_channel(ChannelSpec spec) {
  const ChannelId id = impl_->next_channel++;
  asio::post(impl_->ioc, [impl = impl_.get(), id, spec = std::move(spec)]() mutable {
    impl->do_add_channel(id, std::move(spec));
  });
  return id;
}

void Server::publish(ChannelId channel, std::uint64_t time_ns, std::string json_text) {
  asio::post(impl_->ioc, [impl = impl_.get(), channel, time_ns,
                          payload = std::make_shared<const std::string>(std::move(json_text))]() mutable {
    impl->do_publish(channel, time_ns, std::move(payload));
  });
}

void Server::publish_time(std::uint64_t time_ns) {
  asio::post(impl_->ioc, [impl = impl_.get(), time_ns] { impl->do_time(time_ns); });
}

void Server::add_capability(std::string capability) { impl_->capabilities.push_back(std::move(capability)); }

void Server::add_route(std::string method, std::string path, RouteHandler handler) {
  impl_->routes[{std::move(method), std::move(path)}] = std::move(handler);
}

void Server::set_metrics(std::function<std::string()> text) { impl_->metrics = std::move(text); }

void Server::set_client_publish(ClientPublishHandler handler) { impl_->client_publish = std::move(handler); }

void Server::send_status(std::uint64_t client, int level, std::string message, std::string id) {
  asio::post(impl_->ioc, [impl = impl_.get(), client, level, message = std::move(message), id = std::move(id)] {
    impl->for_each_session([&](WsSession& s) {
      if (s.id() == client) s.send_status(level, message, id);
    });
  });
}

void Server::set_websocket_check(RouteHandlerCheck check) { impl_->websocket_check = std::move(check); }

std::string HttpRequest::header(std::string_view name) const {
  for (const auto& [key, value] : headers)
    if (key.size() == name.size() &&
        std::equal(key.begin(), key.end(), name.begin(), [](char a, char b) {
          return a == std::tolower(static_cast<unsigned char>(b));
        }))
      return value;
  return {};
}

void Server::run() {
  impl_->ioc.run();
}

void Server::stop() {
  if (impl_->stopped.exchange(true)) return;
  asio::post(impl_->ioc, [impl = impl_.get()] {
    beast::error_code ignored;
    impl->acceptor.close(ignored);
    impl->for_each_session([](WsSession& s) { s.close(); });
    // Give the closes a moment, then stop whatever is left.
    auto timer = std::make_shared<asio::steady_timer>(impl->ioc, std::chrono::milliseconds(200));
    timer->async_wait([impl, timer](beast::error_code) { impl->ioc.stop(); });
  });
}

ServerCounters Server::counters() const {
  ServerCounters out;
  {
    const std::lock_guard lock(impl_->table_mutex);
    for (const Channel& c : impl_->channels)
      out.channels.push_back({c.spec.topic, c.published, c.sent, c.dropped, c.skipped});
  }
  out.clients = impl_->live->clients;
  out.clients_total = impl_->live->clients_total;
  out.refused_requests = impl_->live->refused;
  return out;
}

std::string Server::counters_text_of(const Impl& impl) {
  std::string s;
  s += "# HELP pneu_dash_messages_published_total Messages pneu-dash received for a channel.\n";
  s += "# TYPE pneu_dash_messages_published_total counter\n";
  std::string sent, dropped, skipped;
  {
    const std::lock_guard lock(impl.table_mutex);
    for (const Channel& c : impl.channels) {
      const std::string label = "{channel=\"" + c.spec.topic + "\"} ";
      s += "pneu_dash_messages_published_total" + label + std::to_string(c.published) + "\n";
      sent += "pneu_dash_messages_sent_total" + label + std::to_string(c.sent) + "\n";
      dropped += "pneu_dash_messages_dropped_total" + label + std::to_string(c.dropped) + "\n";
      skipped += "pneu_dash_messages_skipped_total" + label + std::to_string(c.skipped) + "\n";
    }
  }
  s += "# HELP pneu_dash_messages_sent_total Message frames queued to subscribers.\n";
  s += "# TYPE pneu_dash_messages_sent_total counter\n" + sent;
  s += "# HELP pneu_dash_messages_dropped_total Message frames dropped as a subscriber read too slowly.\n";
  s += "# TYPE pneu_dash_messages_dropped_total counter\n" + dropped;
  s += "# HELP pneu_dash_messages_skipped_total Messages not sent to a subscription that asked for at most a rate (a newer one was).\n";
  s += "# TYPE pneu_dash_messages_skipped_total counter\n" + skipped;
  s += "# HELP pneu_dash_clients WebSocket clients connected.\n# TYPE pneu_dash_clients gauge\n";
  s += "pneu_dash_clients " + std::to_string(impl.live->clients.load()) + "\n";
  s += "# HELP pneu_dash_refused_total HTTP requests and WebSocket inputs refused with a reason.\n";
  s += "# TYPE pneu_dash_refused_total counter\n";
  s += "pneu_dash_refused_total " + std::to_string(impl.live->refused.load()) + "\n";
  return s;
}

std::string Server::counters_text() const { return counters_text_of(*impl_); }

}  // namespace pneu::dash
