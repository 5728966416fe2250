// pneu-dash's server: HTTP (the page's static files, /metrics, routes other parts add) and one
// WebSocket endpoint (/ws) speaking the Foxglove WebSocket protocol v1 (subprotocol
// foxglove.websocket.v1: serverInfo, status, advertise, subscribe/unsubscribe, binary message
// frames, time; the client may advertise channels and publish on them when a handler takes them).
// Boost.Beast on one Asio thread (run()); publish(), publish_time() and stop() may be called from
// any thread. Every client has a bounded send queue: one that stops reading loses messages (counted,
// and told in a status message when it reads again), never memory, and never slows the others; a
// full queue gives up its oldest states (latest-wins channels) first, then the newest message.
// A subscription to a latest-wins channel may ask for at most a rate (the subscription's optional
// "maxRateHz", else ServerOptions::max_rate_hz): it then gets the newest message at most that often,
// never a stale queue, and is told how many it skipped (status id kSkippedStatusId).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace pneu::dash {

/// The Foxglove subprotocol this server speaks; a WebSocket upgrade asking for no other is refused.
inline constexpr const char* kSubprotocol = "foxglove.websocket.v1";
/// The status a subscription that asked for "maxRateHz" gets, at most every kSkippedReportS while it
/// skips: {"op":"status","level":0,"id":kSkippedStatusId,"message":...,"subscriptionId":N,
/// "skipped":S}, S the messages skipped since it subscribed, among those older than the last
/// message it was sent before this status (so a client's sequence arithmetic up to that message,
/// less S, is what it really lost).
inline constexpr const char* kSkippedStatusId = "pneu-dash.skipped";
inline constexpr double kSkippedReportS = 0.5;
/// The highest "maxRateHz" a subscription may ask (0 asks for every message).
inline constexpr double kMaxRateLimitHz = 100000.0;

struct ServerOptions {
  std::string address = "127.0.0.1";  ///< where it listens (loopback by default)
  std::uint16_t port = 8765;          ///< 0: a free port (port() says which)
  std::filesystem::path www;          ///< the static files served at / (empty: none)
  std::string name = "pneu-dash";     ///< serverInfo's name
  /// serverInfo's metadata: what a client needs to read the messages beyond their schemas.
  std::vector<std::pair<std::string, std::string>> metadata;
  std::size_t max_queue_bytes = 4u << 20;        ///< a client's unsent messages, beyond which they are dropped
  std::size_t max_incoming_bytes = 64u << 10;    ///< a WebSocket message from a client, larger is refused
  std::size_t max_subscriptions = 256;           ///< a client's subscriptions at once
  std::size_t max_client_channels = 64;          ///< channels a client may advertise
  std::size_t max_clients = 64;                  ///< WebSocket clients at once
  std::size_t max_connections = 256;             ///< TCP connections at once (HTTP and WebSocket)
  double header_timeout_s = 10.0;                ///< an HTTP request's header must arrive within it (slow loris)
  /// The kernel's send buffer of each connection (SO_SNDBUF; 0: the system's): with
  /// max_queue_bytes, what a client that stops reading can hold.
  int socket_send_buffer_bytes = 256 << 10;
  /// The rate [Hz] of a latest-wins channel's messages a subscription gets when it asks none
  /// ("maxRateHz" absent): 0 every message, else at most that often, the newest one.
  double max_rate_hz = 0.0;
};

using ChannelId = std::uint32_t;

/// A channel the server advertises. Its messages are JSON (encoding "json") following `schema`
/// (a JSON Schema, schemaEncoding "jsonschema").
struct ChannelSpec {
  std::string topic;
  std::string schema_name;
  std::string schema;
  /// The last message goes to every new subscriber (a constant, such as the plane's geometry).
  bool latched = false;
  /// The field of each message that counts them without gaps ("" when the record has none: then
  /// only the drops this server reports in status messages tell what a client missed). Advertised
  /// as the channel's "sequenceField".
  std::string sequence_field;
  /// Each message supersedes the last (a state, such as the tick records): a subscription may ask
  /// for at most a rate and then gets the newest, and a full queue gives up its oldest first.
  /// Advertised as the channel's "latestWins". Other channels' messages all go, at any rate.
  bool latest_wins = false;
};

struct HttpRequest {
  std::string method;  ///< GET, POST, ...
  std::string path;    ///< the target without its query
  std::string query;   ///< after '?', "" when none
  std::vector<std::pair<std::string, std::string>> headers;  ///< names in lower case, in order
  std::string remote;  ///< the peer's address
  std::string body;
  /// The first header of that name (any case), "" when none.
  [[nodiscard]] std::string header(std::string_view name) const;
};

struct HttpResponse {
  unsigned status = 200;
  std::string content_type = "text/plain; charset=utf-8";
  std::string body;
};

/// Answers one request on a route (add_route); runs on the server's thread.
using RouteHandler = std::function<HttpResponse(const HttpRequest&)>;
/// Judges a request: "" lets it through, else why not. Runs on the server's thread.
using RouteHandlerCheck = std::function<std::string(const HttpRequest&)>;

/// A message a client published on a channel it advertised (capability clientPublish).
struct ClientMessage {
  std::uint64_t client;      ///< which connection (one number per connection, from 1)
  std::string topic;
  std::string encoding;
  std::string schema_name;
  std::span<const std::uint8_t> payload;
};
/// Takes a client's message; returns "" when taken, else why not (sent to that client as an error
/// status). Runs on the server's thread.
using ClientPublishHandler = std::function<std::string(const ClientMessage&)>;

/// Counters, per channel in add_channel()'s order.
struct ChannelCounters {
  std::string topic;
  std::uint64_t published = 0;  ///< messages publish() was given
  std::uint64_t sent = 0;       ///< message frames queued to subscribers
  std::uint64_t dropped = 0;    ///< message frames dropped as a subscriber's queue was full
  std::uint64_t skipped = 0;    ///< messages not sent to a subscription that asked for at most a rate (a newer one was)
};
struct ServerCounters {
  std::vector<ChannelCounters> channels;
  std::uint64_t clients = 0;           ///< WebSocket clients now
  std::uint64_t clients_total = 0;     ///< since start
  std::uint64_t refused_requests = 0;  ///< HTTP requests and WebSocket inputs refused with a reason
};

class Server {
 public:
  /// Binds and listens (throws std::system_error when it cannot); serves once run() runs.
  explicit Server(ServerOptions options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// The port it listens on.
  [[nodiscard]] std::uint16_t port() const noexcept;

  /// Adds a channel, advertised to every client (those connected now too). Thread-safe.
  ChannelId add_channel(ChannelSpec spec);
  /// Sends `json` on `channel` to its subscribers, stamped `time_ns` (ns since the Unix epoch).
  /// Thread-safe.
  void publish(ChannelId channel, std::uint64_t time_ns, std::string json);
  /// Sends a time message (capability "time": the time of a log being played) to every client.
  /// Thread-safe.
  void publish_time(std::uint64_t time_ns);
  // The hooks below are set before run().
  /// Adds a capability to serverInfo: "time" when a log is played, ...
  void add_capability(std::string capability);
  /// Serves `method` `path` (exactly) with `handler`, before the static files.
  void add_route(std::string method, std::string path, RouteHandler handler);
  /// GET /metrics: `text` gives the Prometheus text (until set: the counters()).
  void set_metrics(std::function<std::string()> text);
  /// Takes the messages clients publish: advertises the capability clientPublish.
  void set_client_publish(ClientPublishHandler handler);
  /// Sends a status message (level 0 info, 1 warning, 2 error; `id`: the status's "id", "" for
  /// none) to the client `client` (ClientMessage::client), if it is still connected: the answer
  /// to what it published. Thread-safe.
  void send_status(std::uint64_t client, int level, std::string message, std::string id = {});
  /// Judges each WebSocket upgrade (its headers, its peer) before it is accepted: one refused gets
  /// 403 and the reason.
  void set_websocket_check(RouteHandlerCheck check);

  /// Serves until stop().
  void run();
  /// Stops run(): closes the listener and every connection. Thread-safe.
  void stop();

  /// Thread-safe.
  [[nodiscard]] ServerCounters counters() const;
  /// The counters as Prometheus text (pneu_dash_*).
  [[nodiscard]] std::string counters_text() const;

  struct Impl;

 private:
  static std::string counters_text_of(const Impl& impl);
  std::shared_ptr<Impl> impl_;
};

/// The content type of a file, by its extension.
[[nodiscard]] std::string content_type_of(const std::filesystem::path& file);

}  // namespace pneu::dash
