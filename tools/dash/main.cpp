// pneu-dash: a bench's LCM channels (live, or a recorded log) to browsers and Foxglove Studio, over
// HTTP and the Foxglove WebSocket protocol (pneu_dash, tools/dash/lib).
#include <lcm/lcm-cpp.hpp>
#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <charconv>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "pneu/config/cli.hpp"
#include "pneu/config/config.hpp"
#include "pneu/telemetry/telemetry_params.hpp"
#include "pneu/dash/commands.hpp"
#include "pneu/dash/log_player.hpp"
#include "pneu/dash/metrics.hpp"
#include "pneu/dash/metrics_feed.hpp"
#include "pneu/dash/pneu_channels.hpp"
#include "pneu/dash/server.hpp"
#include "page.hpp"

namespace pneu {
namespace {

namespace fs = std::filesystem;

void print_usage(std::ostream& out) {
  out << R"(pneu-dash: a bench's telemetry in a browser and in Foxglove Studio.

usage:
  pneu-dash [--listen HOST:PORT] [--config FILE | --lcm-url URL] [--prefix PREFIX] [--www DIR]
            [--chart-js DIR] [--bench NAME] [--max-rate-hz HZ] [--commands-token-file FILE]
  pneu-dash --log FILE [--paused] [--listen HOST:PORT] [--prefix PREFIX] [--www DIR] [--chart-js DIR]
            [--bench NAME] [--max-rate-hz HZ]
  pneu-dash ... --check-config
  pneu-dash --help | --version

Subscribes to pneud's LCM channels (<prefix>STATE, EVENT, PREDICTION, HEALTH, IDENTIFICATION),
adds <prefix>PLANE (the pressure-force plane from the configuration's model: the stop and
no-restarting areas, the null-flow curve; latched) and <prefix>PLANE_FORECAST (each restart
forecast's path through the plane), and serves, on --listen (default 127.0.0.1:8765, loopback only):
  /          the page (static files of --www)
  /ws        the Foxglove WebSocket protocol (subprotocol foxglove.websocket.v1): one channel per
             LCM channel, JSON messages with the JSON Schema of their record; Foxglove Studio
             connects to ws://HOST:PORT/ws
  /metrics   the bench's metrics in the Prometheus text format, every series labelled
             bench="NAME" (docs/dashboard.md lists them)
  /playback  with --log: GET the player's state; POST {"play":true|false, "seek_s":S, "rate":R}

--config FILE   pneud's configuration: telemetry.lcm_url and telemetry.channel_prefix from it
--lcm-url URL   the LCM URL (default udpm://239.255.76.67:7667?ttl=0, pneud's default)
--prefix P      the channels' prefix (default: the configuration's, else PNEU_)
--bench NAME    the bench label of the metrics (default: this host's name)
--www DIR       the page's files (default: the installed share/pneu/dash, else the source tree's)
--chart-js DIR  where chart.min.js is, served at /js/chart.js/ (default /usr/share/javascript/chart.js,
                Debian's libjs-chart.js)
--max-rate-hz HZ
                the rate of <prefix>STATE (the ticks, 1 kHz) a WebSocket subscription gets when it
                asks none: at most HZ messages a second, the newest each time, the skipped ones
                counted (pneu_dash_messages_skipped_total); 0 (the default) every message. A
                subscription asks its own with "maxRateHz" (0 to 100000; the page: /?max_rate_hz=60).
                The other channels (events, forecasts, health, identification, the plane) are never
                decimated
--commands-token-file FILE
                take commands from the page (off without it): arm, disarm, fault reset, set point,
                set-point step, hold on/off, sent to pneud on <prefix>COMMAND as pneu-command sends
                them, so that pneud's own validation judges them; pneud's verdict comes back on
                <prefix>EVENT. A browser sends the token (the file's one line) once on its
                connection before it may command; a wrong one is refused, counted and nothing is
                sent. Refused (exit 2, saying why) unless the file's mode is 0640 or stricter, it
                is owned by group pneu when that group exists, the token has 16 characters or more,
                and --listen is a loopback address (pneu-dash has no TLS: reach it from elsewhere
                through an SSH tunnel). Each command names this dashboard ("pneu-dash HOST:PORT")
                and the browser's session, and pneud's events say so.
--check-config  read the options, the configuration and the log, say what would be served, exit
--log FILE      play a recorded LCM log (lcm-logger) instead of listening live; it plays from its
                start at once (--paused: waits for POST /playback {"play":true})

Exit status: 0 stopped by SIGINT or SIGTERM, 1 failed while serving, 2 bad command line, config
or log.
)";
}

// HOST:PORT, the port 0 to 65535 (0: a free one).
std::pair<std::string, std::uint16_t> parse_listen(const std::string& text) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == text.size())
    throw cli::UsageError("--listen: HOST:PORT expected, got '" + text + "'");
  std::string host = text.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  unsigned port = 0;
  const char* first = text.data() + colon + 1;
  const char* last = text.data() + text.size();
  const auto r = std::from_chars(first, last, port);
  if (r.ec != std::errc{} || r.ptr != last || port > 65535)
    throw cli::UsageError("--listen: the port must be a number from 0 to 65535, got '" + text.substr(colon + 1) + "'");
  return {host, static_cast<std::uint16_t>(port)};
}

// This host's name: the metrics' bench label unless --bench names it.
std::string host_name() {
  char name[256] = {};
  if (gethostname(name, sizeof name - 1) != 0 || name[0] == '\0') return "localhost";
  return name;
}

// The page's files: the installed share/pneu/dash beside bin/, else (run from the build tree) the
// source tree's.
fs::path default_www() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = exe.parent_path().parent_path() / "share" / "pneu" / "dash";
    if (fs::is_regular_file(installed / "index.html", ec)) return installed;
  }
  return PNEU_DASH_SOURCE_WWW;
}

int run(int argc, char** argv) {
  const cli::Args args(argc, argv, 1,
                       {"listen", "config", "lcm-url", "prefix", "www", "log", "chart-js", "bench",
                        "commands-token-file", "max-rate-hz"},
                       {"help", "version", "paused", "check-config"});
  if (args.flag("help")) {
    print_usage(std::cout);
    return cli::kExitOk;
  }
  if (args.flag("version")) {
    std::printf("pneu-dash %s\n", PNEU_VERSION);
    return cli::kExitOk;
  }
  const auto log = args.value("log");
  if (log && (args.value("lcm-url") || args.value("config")))
    throw cli::UsageError("--log plays a recorded log: --lcm-url and --config are for a live bench");
  if (args.flag("paused") && !log) throw cli::UsageError("--paused is for --log");
  if (args.value("lcm-url") && args.value("config"))
    throw cli::UsageError("--lcm-url and --config exclude each other (the URL is the configuration's)");

  // The configuration's model draws the plane (the embedded default's without --config).
  const auto config_file = args.value("config");
  const config::Config cfg = config_file ? config::load_file(*config_file) : config::load_file_or_default("");
  telemetry::TelemetryConfig telemetry;
  if (config_file) telemetry = cfg.telemetry;
  if (const auto url = args.value("lcm-url")) telemetry.lcm_url = *url;
  if (const auto prefix = args.value("prefix")) telemetry.channel_prefix = *prefix;

  dash::ServerOptions options;
  options.metadata = dash::pneud_metadata();  // the modes' names, for the page
  std::tie(options.address, options.port) = parse_listen(args.value("listen").value_or("127.0.0.1:8765"));
  options.www = args.value("www") ? fs::path(*args.value("www")) : default_www();
  options.max_rate_hz = args.number("max-rate-hz", 0.0);
  if (options.max_rate_hz < 0.0 || options.max_rate_hz > dash::kMaxRateLimitHz)
    throw cli::UsageError("--max-rate-hz: from 0 (every message) to " + std::to_string(static_cast<int>(dash::kMaxRateLimitHz)) +
                          " Hz, got " + *args.value("max-rate-hz"));
  if (!fs::is_directory(options.www)) throw cli::UsageError("--www: not a directory: " + options.www.string());
  const fs::path chart_js = args.value("chart-js").value_or("/usr/share/javascript/chart.js");
  if (!fs::is_regular_file(chart_js / "chart.min.js"))
    throw cli::UsageError("--chart-js: no chart.min.js in " + chart_js.string() +
                          ": the page draws with Chart.js (Debian package libjs-chart.js)");

  // Commands (off without a token file): refused before anything listens when they cannot be safe.
  const auto token_file = args.value("commands-token-file");
  std::string token;
  if (token_file) {
    if (log) throw cli::UsageError("--commands-token-file: commands go to a live pneud, not to a log played (--log)");
    try {
      dash::listen_allows_commands(options.address);
      token = dash::read_token_file(*token_file);
    } catch (const dash::CommandsRefused& e) {
      throw cli::UsageError(e.what());
    }
  }

  if (args.flag("check-config")) {
    if (log) {
      try {
        const dash::LogPlayer readable(*log, nullptr, nullptr);
      } catch (const std::runtime_error& e) {
        throw cli::UsageError(std::string("--log: ") + e.what());
      }
    }
    std::cout << "pneu-dash: would serve http://" << options.address << ":" << options.port << "/ from "
              << options.www.string() << ", " << (log ? "playing " + *log : "live from " + telemetry.lcm_url)
              << ", channels " << telemetry.channel_prefix << "*"
              << (options.max_rate_hz > 0 ? ", " + telemetry.channel_prefix + "STATE at most " + args.value("max-rate-hz").value() + " Hz unless a subscription asks" : std::string())
              << "\n";
    return cli::kExitOk;
  }

  // SIGINT and SIGTERM are waited for by this thread, blocked in every other.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  std::unique_ptr<dash::Server> server;
  try {
    server = std::make_unique<dash::Server>(options);
  } catch (const std::exception& e) {
    throw cli::UsageError("--listen " + options.address + ":" + std::to_string(options.port) + ": " + e.what());
  }
  dash::PneuFeed feed(*server, telemetry.channel_prefix);
  try {
    dash::serve_chart_js(*server, chart_js);
  } catch (const std::runtime_error& e) {
    throw cli::UsageError(std::string("--chart-js: ") + e.what());
  }
  dash::PlaneFeed plane(*server, telemetry.channel_prefix, cfg,
                        config_file ? fs::path(*config_file).parent_path() : fs::current_path());
  dash::Metrics metrics(args.value("bench").value_or(host_name()));
  if (metrics.bench().empty()) throw cli::UsageError("--bench: a name, not empty");
  dash::MetricsFeed metrics_feed(metrics, telemetry.channel_prefix);
  std::unique_ptr<dash::CommandGate> gate;  // with --commands-token-file
  server->set_metrics([&metrics, &server, &gate] {
    return metrics.text() + dash::with_label(server->counters_text() + (gate ? dash::counters_text(gate->counters()) : ""),
                                             "bench", metrics.bench());
  });
  // Every LCM message to each: the channels as pneud publishes them, the plane's forecasts, the metrics.
  auto forward = [&feed, &plane, &metrics_feed](const std::string& channel, const void* data, std::size_t size,
                                                std::int64_t utime) {
    feed.forward(channel, data, size, utime);
    plane.forward(channel, data, size, utime);
    metrics_feed.forward(channel, data, size);
  };

  std::unique_ptr<dash::LogPlayer> player;
  std::unique_ptr<lcm::LCM> lcm;
  std::atomic<bool> stopping{false};
  std::thread lcm_thread;
  if (log) {
    try {
      player = std::make_unique<dash::LogPlayer>(
          *log,
          [&forward](const std::string& channel, const void* data, std::size_t size, std::int64_t utime) {
            forward(channel, data, size, utime);
          },
          [&server](std::uint64_t t_ns) { server->publish_time(t_ns); });
    } catch (const std::runtime_error& e) {
      throw cli::UsageError(std::string("--log: ") + e.what());
    }
    player->attach(*server);
    if (!args.flag("paused")) player->play(true);
  } else {
    lcm = std::make_unique<lcm::LCM>(telemetry.lcm_url);
    if (!lcm->good())
      throw std::runtime_error("LCM does not start on " + telemetry.lcm_url +
                               " (a udpm:// URL needs a multicast route: see docs/dashboard.md)");
    lcm_subscribe(lcm->getUnderlyingLCM(), (telemetry::regex_literal(telemetry.channel_prefix) + ".*").c_str(),
                  [](const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
                    (*static_cast<decltype(forward)*>(user))(channel, rbuf->data, rbuf->data_size, rbuf->recv_utime);
                  },
                  &forward);
    if (token_file) {
      const std::string command_channel = telemetry.channel_prefix + "COMMAND";
      gate = std::make_unique<dash::CommandGate>(
          dash::GateOptions{.token = token,
                            .origin = "pneu-dash " + options.address + ":" + std::to_string(server->port())},
          [&lcm, command_channel](const pneu_lcm::command_t& c) { return lcm->publish(command_channel, &c) == 0; });
      token.assign(token.size(), '\0');
      server->set_client_publish([&gate, &server](const dash::ClientMessage& m) -> std::string {
        const std::string_view payload(reinterpret_cast<const char*>(m.payload.data()), m.payload.size());
        dash::GateAnswer a;
        const char* id = nullptr;
        if (m.topic == dash::kLoginTopic) {
          a = gate->login(m.client, payload);
          id = dash::kLoginStatusId;
        } else if (m.topic == dash::kCommandTopic) {
          a = gate->command(m.client, payload);
          id = dash::kCommandStatusId;
        } else {
          return "this server takes client messages on " + std::string(dash::kLoginTopic) + " and " +
                 dash::kCommandTopic + " only";
        }
        // An audit trail (the journal): who logged in, what was refused, what was sent.
        std::cerr << "pneu-dash: connection " << m.client << ": " << a.message << "\n";
        server->send_status(m.client, a.ok ? 0 : 2, a.message, id);
        return "";
      });
    }
    lcm_thread = std::thread([&] {
      while (!stopping) {
        if (lcm->handleTimeout(100) < 0) {
          std::cerr << "pneu-dash: LCM failed; stopping\n";
          server->stop();
          return;
        }
      }
    });
  }

  std::cerr << "pneu-dash: serving http://" << options.address << ":" << server->port() << "/ (WebSocket /ws), "
            << (log ? "playing " + *log : "live from " + telemetry.lcm_url) << ", channels "
            << telemetry.channel_prefix << "*"
            << (gate ? "; commands on (token from " + *token_file + "), sent as \"" + gate->origin() + "\""
                     : std::string("; commands off"))
            << "\n";
  std::thread server_thread([&] { server->run(); });
  std::thread signal_thread([&] {
    int sig = 0;
    sigwait(&stop_signals, &sig);
    server->stop();
  });
  server_thread.join();
  stopping = true;
  if (lcm_thread.joinable()) lcm_thread.join();
  // The signal thread still waits when the server stopped on its own: wake it.
  pthread_kill(signal_thread.native_handle(), SIGTERM);
  signal_thread.join();
  player.reset();
  return cli::kExitOk;
}

}  // namespace
}  // namespace pneu

int main(int argc, char** argv) { return pneu::cli::run_main("pneu-dash", pneu::run, argc, argv); }
