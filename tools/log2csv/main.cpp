// pneu-log2csv: an LCM log of the daemon's telemetry, as lcm-logger writes it, into one CSV file
// per channel.
//
// Two passes over the log: the first finds which types each channel carries (a channel with more
// than one is split into one file per type, so the file names are known only at the end of the
// log) and where the readable part of the log ends; the second writes the rows.
#include <regex.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "message_csv.hpp"
#include "pneu/config/cli.hpp"

namespace {

using namespace pneu;
using log2csv::kMessageTypeCount;
using log2csv::MessageType;
namespace fs = std::filesystem;

constexpr const char* kUsage =
    R"(pneu-log2csv: an LCM log (as lcm-logger writes it) into one CSV file per channel

Usage:
  pneu-log2csv LOGFILE OUTDIR [--channels REGEX]
  pneu-log2csv --help
  pneu-log2csv --version

  LOGFILE           the log
  OUTDIR            where the CSV files go; created if missing, files of the same name replaced
  --channels REGEX  convert only the channels whose whole name matches REGEX (POSIX extended
                    syntax, anchored like lcm-logger -c: "PNEU_.*"); default: every channel

One file per channel, OUTDIR/<channel>.csv, every character of the channel name outside
[A-Za-z0-9_.-] replaced by '_' (if two channels end up with the same file name, the later one in
name order gets "-2", "-3", ...). Each message is decoded by its fingerprint (its first 8 bytes) as
a pneu_lcm type. The first column is log_utime, when the logger received the message [us since
the Unix epoch]; then the message's fields in the order and units of its .lcm definition
(share/pneu/lcmtypes):
)";

// The columns of each type written from its description (the lines of the usage between kUsage
// and kUsageEnd): the header itself, wrapped.
constexpr const char* kUsageEnd =
    R"(  unknown       log_utime,bytes,fingerprint_hex: a message of another type, or one that does not
                decode as the type its fingerprint names (too short, or bytes left over); bytes
                is its size, fingerprint_hex its first 8 bytes. Counted on stderr.
A channel that carries more than one type (unknown counts as a type) is split by type into
OUTDIR/<channel>.<type>.csv, e.g. PNEU_X.state_t.csv and PNEU_X.unknown.csv, each message going
to the file of its own type.

Cells: doubles as %.17g (they read back bit for bit), NaN as an empty cell, infinities as inf and
-inf; booleans 0/1; kind_name and method_name "unknown" for a value the .lcm does not define;
event text and command origin always in double quotes, a quote in them doubled (""), commas and
newlines kept; a byte of a command origin that is not printable ASCII as ?.

Files appear whole or not at all. A log that ends inside an event (a logger killed mid-write) is
converted up to its last complete event, with a warning, and exits 0. Prints, per channel, the
type, the number of messages and the file (for state_t also the seq range and its gaps).

Exit codes: 0 success (also for a truncated log), 1 writing failed, 2 bad command line, or
LOGFILE missing, unreadable or not an LCM log (nothing written).
)";

// The usage, each type's columns as csv_header() names them.
std::string usage() {
  std::string u = kUsage;
  for (const MessageType type : {MessageType::kState, MessageType::kEvent, MessageType::kPrediction,
                                 MessageType::kHealth, MessageType::kCommand, MessageType::kIdentification}) {
    std::string line = "  " + std::string(log2csv::type_name(type));
    line.resize(std::max<std::size_t>(line.size() + 1, 16), ' ');
    const std::string header(log2csv::csv_header(type));
    std::size_t from = 0;
    while (from < header.size()) {  // wrapped after a comma, under 100 columns
      std::size_t to = header.size();
      if (line.size() + (to - from) > 99) {
        to = header.rfind(',', from + (99 - line.size()));
        to = (to == std::string::npos || to < from) ? header.size() : to + 1;
      }
      line += header.substr(from, to - from);
      u += line + "\n";
      line = std::string(16, ' ');
      from = to;
    }
  }
  return u + kUsageEnd;
}

void print_usage(std::ostream& out) { out << usage(); }

// An lcm-logger file is a sequence of events, each: the marker 0xEDA1DA01, event number (int64),
// timestamp [us] (int64), channel length (int32), payload length (int32), all big-endian, then the
// channel name and the payload.
constexpr std::array<unsigned char, 4> kEventMarker = {0xED, 0xA1, 0xDA, 0x01};
constexpr std::int64_t kEventHeaderBytes = 4 + 8 + 8 + 4 + 4;

std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

std::string plural(std::int64_t n, const char* word) {
  return std::to_string(n) + " " + word + (n == 1 ? "" : "s");
}

// Refuses, before anything is written, what is not an lcm-logger file; returns its size [bytes].
std::int64_t check_log_file(const fs::path& path) {
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (!fs::exists(status)) throw cli::UsageError(quoted(path) + ": no such file");
  if (fs::is_directory(status))
    throw cli::UsageError(quoted(path) + ": is a directory, not an LCM log");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw cli::UsageError(quoted(path) + ": cannot open: " + std::strerror(errno));
  std::array<unsigned char, 4> head{};
  in.read(reinterpret_cast<char*>(head.data()), head.size());
  const auto got = in.gcount();
  if (got == 0) return 0;  // lcm-logger that received nothing leaves an empty file: a valid log
  if (got < 4 || head != kEventMarker)
    throw cli::UsageError(
        quoted(path) +
        ": not an LCM log (it does not begin with the LCM event marker 0xEDA1DA01; "
        "LOGFILE is a file written by lcm-logger)");
  const auto size = fs::file_size(path, ec);
  if (ec) throw cli::UsageError(quoted(path) + ": " + ec.message());
  return static_cast<std::int64_t>(size);
}

// How far reading a log got.
struct ReadReport {
  std::int64_t events = 0;         // complete events read
  std::int64_t end_offset = 0;     // the byte after the last complete event
  std::int64_t skipped_bytes = 0;  // bytes between events that LCM skipped to find a marker
};

// Calls on_event(event) for each complete event, at most max_events. LCM's reader gives no error:
// it stops at the end of the file and at an event cut short alike, and silently skips bytes
// before a marker (newer versions; 1.3.1 stops there). The file position after each event tells
// them apart. `file_size`: the log's size when it was checked [bytes].
template <class OnEvent>
ReadReport read_log(const fs::path& path, std::int64_t file_size, std::int64_t max_events,
                    OnEvent&& on_event) {
  errno = 0;
  lcm::LogFile log(path.string(), "r");
  if (!log.good())
    throw cli::UsageError(quoted(path) +
                          ": cannot open: " + (errno ? std::strerror(errno) : "unknown error"));
  ReadReport report;
  while (report.events < max_events) {
    const lcm::LogEvent* event = log.readNextEvent();
    if (event == nullptr) break;
    const std::int64_t position = ::ftello(log.getFilePtr());
    if (position < 0) throw std::runtime_error(quoted(path) + ": " + std::strerror(errno));
    const std::int64_t contiguous_end = report.end_offset + kEventHeaderBytes +
                                        static_cast<std::int64_t>(event->channel.size()) +
                                        event->datalen;
    // LCM 1.3.1 peeks at the next 4 bytes for a marker and seeks back, except when fewer than 4
    // are left: then it stays at the end of the file, up to 3 bytes past the event's end.
    const bool peeked_at_end =
        position == file_size && position > contiguous_end && position - contiguous_end < 4;
    const std::int64_t end = peeked_at_end ? contiguous_end : position;
    report.skipped_bytes += end - contiguous_end;
    report.end_offset = end;
    ++report.events;
    on_event(*event);
  }
  return report;
}

std::int64_t big_endian(const unsigned char* b, int n) {
  std::uint64_t v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | b[i];
  return static_cast<std::int64_t>(v);
}

// Why LCM's reader stopped at `offset`, before the end of the file: the log is either cut inside
// its last event (a logger killed mid-write: the expected damage) or damaged further on.
std::string describe_unread_tail(const fs::path& path, std::int64_t offset, std::int64_t file_size,
                                 std::int64_t events) {
  std::array<unsigned char, kEventHeaderBytes> header{};
  std::ifstream in(path, std::ios::binary);
  in.seekg(offset);
  in.read(reinterpret_cast<char*>(header.data()), header.size());
  const auto got = in.gcount();
  // The marker, or as much of it as the file holds.
  const auto marker_bytes = std::min<std::streamsize>(got, 4);
  const bool marker = got > 0 && std::equal(kEventMarker.begin(),
                                            kEventMarker.begin() + marker_bytes, header.begin());
  const std::int64_t channel_bytes = got == kEventHeaderBytes ? big_endian(&header[20], 4) : 0;
  const std::int64_t data_bytes = got == kEventHeaderBytes ? big_endian(&header[24], 4) : 0;
  const std::int64_t event_end = offset + kEventHeaderBytes + channel_bytes + data_bytes;
  const bool sane = channel_bytes > 0 && channel_bytes < 1000 && data_bytes >= 0;
  const std::int64_t unread = file_size - offset;
  const std::string tail =
      "its last " + plural(unread, "byte") + " (from byte " + std::to_string(offset) + ")";
  const std::string converted = plural(events, "complete event") + " before them were converted";
  if (marker && (got < kEventHeaderBytes || (sane && event_end > file_size)))
    return quoted(path) + " is truncated: " + tail +
           " are an incomplete event, as when a logger stops mid-write; the " + converted;
  if (marker && sane)  // LCM 1.3.1 drops an event that is not followed by a marker, and stops
    return quoted(path) + " is damaged at byte " + std::to_string(event_end) +
           " (no event marker after the event at byte " + std::to_string(offset) +
           "); LCM's log reader stops there, so " + tail + " were not converted; the " + converted;
  return quoted(path) + " is damaged at byte " + std::to_string(offset) +
         " (not a valid event header); " + "LCM's log reader stops there, so " + tail +
         " were not converted; the " + converted;
}

// --channels: a POSIX extended regular expression that must match a whole channel name, as LCM
// anchors its own (GLib) channel patterns. POSIX rather than std::regex: GCC 12's <regex> trips
// -Wmaybe-uninitialized in sanitizer builds with -Werror.
class ChannelPattern {
 public:
  explicit ChannelPattern(const std::string& pattern) {
    const std::string anchored = "^(" + pattern + ")$";
    if (const int rc = ::regcomp(&re_, anchored.c_str(), REG_EXTENDED | REG_NOSUB); rc != 0) {
      char message[256];
      ::regerror(rc, &re_, message, sizeof message);
      throw cli::UsageError("--channels: '" + pattern +
                            "' is not a regular expression: " + message);
    }
  }
  ~ChannelPattern() { ::regfree(&re_); }
  ChannelPattern(const ChannelPattern&) = delete;
  ChannelPattern& operator=(const ChannelPattern&) = delete;

  [[nodiscard]] bool matches(const std::string& channel) const {
    return ::regexec(&re_, channel.c_str(), 0, nullptr, 0) == 0;
  }

 private:
  ::regex_t re_{};
};

struct ChannelStats {
  std::array<std::int64_t, kMessageTypeCount> messages{};  // by MessageType
  std::array<std::string, kMessageTypeCount> file;         // file name in OUTDIR, "" if none
  // state_t sequence numbers, from the write pass.
  std::optional<std::int64_t> first_seq, last_seq;
  std::int64_t seq_gaps = 0, seq_missing = 0, seq_backwards = 0;

  [[nodiscard]] int type_count() const {
    return static_cast<int>(
        std::count_if(messages.begin(), messages.end(), [](auto n) { return n > 0; }));
  }
};

std::size_t index(MessageType t) { return static_cast<std::size_t>(t); }

// Gives each (channel, type) with messages its file name: <channel>.csv, or <channel>.<type>.csv
// for a channel of several types; a name already taken gets -2, -3, ... before ".csv".
void plan_file_names(std::map<std::string, ChannelStats>& channels) {
  std::set<std::string> taken;
  for (auto& [channel, stats] : channels) {
    const bool split = stats.type_count() > 1;
    for (const MessageType type : log2csv::kAllMessageTypes) {
      if (stats.messages[index(type)] == 0) continue;
      std::string stem = log2csv::sanitize_file_name(channel);
      if (split) stem += std::string(".") + log2csv::type_name(type);
      std::string name = stem + ".csv";
      for (int k = 2; taken.count(name) != 0; ++k) name = stem + "-" + std::to_string(k) + ".csv";
      if (name != stem + ".csv")
        std::cerr << "pneu-log2csv: warning: channel '" << channel << "' written to " << name
                  << " (" << stem << ".csv is another channel's)\n";
      taken.insert(name);
      stats.file[index(type)] = name;
    }
  }
}

int convert(const fs::path& log_path, const fs::path& out_dir, const ChannelPattern* pattern) {
  const std::int64_t file_size = check_log_file(log_path);
  if (fs::exists(out_dir) && !fs::is_directory(out_dir))
    throw cli::UsageError(quoted(out_dir) + ": exists and is not a directory");

  // Pass 1: what each selected channel carries, and where the readable log ends.
  std::map<std::string, ChannelStats> channels;
  std::unordered_map<std::string, bool> selected;  // channel name -> matches --channels
  std::int64_t skipped_events = 0;
  std::set<std::string> skipped_channels;
  const auto is_selected = [&](const std::string& channel) {
    auto it = selected.find(channel);
    if (it == selected.end())
      it = selected.emplace(channel, pattern == nullptr || pattern->matches(channel)).first;
    return it->second;
  };
  const ReadReport scan = read_log(log_path, file_size, INT64_MAX, [&](const lcm::LogEvent& e) {
    if (!is_selected(e.channel)) {
      ++skipped_events;
      skipped_channels.insert(e.channel);
      return;
    }
    ++channels[e.channel].messages[index(log2csv::classify(e.data, e.datalen))];
  });
  plan_file_names(channels);

  // Pass 2: the rows, into files that appear only once all are complete. Reads no further than
  // pass 1 did, should the log be growing.
  fs::create_directories(out_dir);
  std::vector<std::unique_ptr<cli::OutputFile>> files;
  std::unordered_map<std::string, std::array<cli::OutputFile*, kMessageTypeCount>> file_of;
  for (auto& [channel, stats] : channels) {
    auto& slots = file_of[channel];
    slots.fill(nullptr);
    for (const MessageType type : log2csv::kAllMessageTypes) {
      if (stats.file[index(type)].empty()) continue;
      files.push_back(std::make_unique<cli::OutputFile>(out_dir / stats.file[index(type)]));
      files.back()->stream() << log2csv::csv_header(type) << '\n';
      slots[index(type)] = files.back().get();
    }
  }
  std::string line;
  std::map<std::string, ChannelStats> written;
  read_log(log_path, file_size, scan.events, [&](const lcm::LogEvent& e) {
    const auto slots = file_of.find(e.channel);
    if (slots == file_of.end()) return;  // not selected
    const auto row = log2csv::format_csv_row(e.timestamp, e.data, e.datalen, line);
    cli::OutputFile* file = slots->second[index(row.type)];
    if (file == nullptr)
      throw std::runtime_error(quoted(log_path) + " changed while it was being read");
    file->stream() << line;
    auto& stats = written[e.channel];
    ++stats.messages[index(row.type)];
    if (row.type != MessageType::kState) return;
    if (stats.last_seq && row.state_seq != *stats.last_seq + 1) {
      if (row.state_seq > *stats.last_seq) {
        ++stats.seq_gaps;
        stats.seq_missing += row.state_seq - *stats.last_seq - 1;
      } else {
        ++stats.seq_backwards;  // a daemon restart, or two daemons on one channel
      }
    }
    if (!stats.first_seq) stats.first_seq = row.state_seq;
    stats.last_seq = row.state_seq;
  });
  for (auto& [channel, stats] : channels) {
    if (written[channel].messages != stats.messages)
      throw std::runtime_error(quoted(log_path) + " changed while it was being read");
  }
  for (auto& f : files) f->commit();

  // Summary on stdout, problems on stderr.
  std::int64_t converted = 0, unknown = 0, unknown_channels = 0;
  std::size_t channel_width = 7;
  for (const auto& [channel, stats] : channels) {
    channel_width = std::max(channel_width, channel.size());
    for (const auto n : stats.messages) converted += n;
    unknown += stats.messages[index(MessageType::kUnknown)];
    unknown_channels += stats.messages[index(MessageType::kUnknown)] > 0 ? 1 : 0;
  }
  std::printf("pneu-log2csv: %s: %s; %s on %s into %s in %s\n", log_path.c_str(),
              plural(scan.events, "event").c_str(), plural(converted, "message").c_str(),
              plural(static_cast<std::int64_t>(channels.size()), "channel").c_str(),
              plural(static_cast<std::int64_t>(files.size()), "file").c_str(), out_dir.c_str());
  if (!channels.empty())
    std::printf("  %-*s  %-12s %9s  %s\n", static_cast<int>(channel_width), "channel", "type",
                "messages", "file");
  for (const auto& [channel, stats] : channels) {
    const auto& seqs = written[channel];
    for (const MessageType type : log2csv::kAllMessageTypes) {
      const auto n = stats.messages[index(type)];
      if (n == 0) continue;
      std::printf("  %-*s  %-12s %9lld  %s", static_cast<int>(channel_width), channel.c_str(),
                  log2csv::type_name(type), static_cast<long long>(n),
                  stats.file[index(type)].c_str());
      if (type == MessageType::kState && seqs.first_seq) {
        std::printf("  (seq %lld..%lld, ", static_cast<long long>(*seqs.first_seq),
                    static_cast<long long>(*seqs.last_seq));
        if (seqs.seq_gaps == 0)
          std::printf("no gaps");
        else
          std::printf("%s, %lld missing", plural(seqs.seq_gaps, "gap").c_str(),
                      static_cast<long long>(seqs.seq_missing));
        if (seqs.seq_backwards > 0)
          std::printf(", goes back %s", plural(seqs.seq_backwards, "time").c_str());
        std::printf(")");
      }
      std::printf("\n");
    }
  }
  if (skipped_events > 0)
    std::printf("  not converted (not matching --channels): %s on %s\n",
                plural(skipped_events, "event").c_str(),
                plural(static_cast<std::int64_t>(skipped_channels.size()), "channel").c_str());
  std::fflush(stdout);

  if (file_size == 0)
    std::cerr << "pneu-log2csv: warning: " << quoted(log_path) << " is empty: no events\n";
  if (unknown > 0)
    std::cerr
        << "pneu-log2csv: warning: " << plural(unknown, "message") << " on "
        << plural(unknown_channels, "channel")
        << " undecodable (a fingerprint of no pneu_lcm type, or a payload that does not decode "
           "as its type): written as log_utime,bytes,fingerprint_hex rows\n";
  if (scan.skipped_bytes > 0)
    std::cerr << "pneu-log2csv: warning: " << quoted(log_path) << ": "
              << plural(scan.skipped_bytes, "byte")
              << " between events belong to no event and were skipped: the log is damaged there\n";
  if (scan.end_offset < file_size)
    std::cerr << "pneu-log2csv: warning: "
              << describe_unread_tail(log_path, scan.end_offset, file_size, scan.events) << "\n";
  return cli::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    // LOGFILE and OUTDIR are positional; the options may come before, between or after them.
    std::vector<std::string> positional;
    std::vector<char*> options = {argv[0]};
    for (int i = 1; i < argc; ++i) {
      const std::string arg = argv[i];
      if (arg == "-h") {
        options.push_back(const_cast<char*>("--help"));
      } else if (arg.rfind("--", 0) == 0) {
        options.push_back(argv[i]);
        if (arg == "--channels" && i + 1 < argc) options.push_back(argv[++i]);
      } else {
        positional.push_back(arg);
      }
    }
    const cli::Args args(static_cast<int>(options.size()), options.data(), 1, {"channels"},
                         {"help", "version"});
    if (args.flag("help")) {
      print_usage(std::cout);
      return cli::kExitOk;
    }
    if (args.flag("version")) {
      std::printf("pneu-log2csv %s\n", PNEU_VERSION);
      return cli::kExitOk;
    }
    if (positional.size() != 2) {
      std::cerr << "pneu-log2csv: "
                << (positional.size() < 2 ? "needs LOGFILE and OUTDIR"
                                          : "unexpected argument '" + positional[2] + "'")
                << "\n\n"
                << usage();
      return cli::kExitBadInput;
    }
    std::optional<ChannelPattern> channels;
    if (const auto pattern = args.value("channels")) channels.emplace(*pattern);
    return convert(positional[0], positional[1], channels ? &*channels : nullptr);
  } catch (const cli::UsageError& e) {
    std::cerr << "pneu-log2csv: " << e.what() << "\n";
    return cli::kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "pneu-log2csv: " << e.what() << "\n";
    return cli::kExitFailure;
  }
}
