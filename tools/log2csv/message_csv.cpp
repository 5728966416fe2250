#include "message_csv.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>

#include "pneu/controller/records.hpp"
#include "pneu/records/csv.hpp"
#include "pneu/records/lcm.hpp"
#include "pneu_lcm/command_t.hpp"
#include "pneu_lcm/state_t.hpp"
#include "pneu_lcm/event_t_members.hpp"
#include "pneu_lcm/health_t_members.hpp"
#include "pneu_lcm/identification_t_members.hpp"
#include "pneu_lcm/prediction_t_members.hpp"
#include "pneu_lcm/state_t_members.hpp"

namespace pneu::log2csv {
namespace {

// Appends the cells of one row to a line, commas between them.
class Row {
 public:
  Row(std::string& line, std::int64_t log_utime) : line_(line) {
    line_.clear();
    integer(log_utime);
  }
  // %.17g reads back to the same double; NaN ("no value" in these messages) is an empty cell.
  Row& number(double v) {
    separate();
    if (std::isnan(v)) return *this;
    char buf[32];
    const int n = std::snprintf(buf, sizeof buf, "%.17g", v);
    line_.append(buf, static_cast<std::size_t>(n));
    return *this;
  }
  Row& integer(std::int64_t v) {
    separate();
    char buf[24];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    line_.append(buf, r.ptr);
    return *this;
  }
  // The fields of a described record as its message `m` carries them (pneu/records/lcm.hpp),
  // numbers to the last bit.
  template <records::Described R, class M>
  Row& message(const M& m) {
    separate();
    records::write_lcm_csv_cells<R>(line_, m, false, records::kDigitsToTheLastBit);
    return *this;
  }
  // Free text: quoted, a quote doubled (RFC 4180).
  Row& text(std::string_view v) {
    separate();
    line_ += '"';
    for (const char c : v) {
      if (c == '"') line_ += '"';
      line_ += c;
    }
    line_ += '"';
    return *this;
  }
  // A name from a fixed table: never holds a comma or a quote.
  Row& word(std::string_view v) {
    separate();
    line_ += v;
    return *this;
  }
  void end() { line_ += '\n'; }

 private:
  void separate() {
    if (!first_) line_ += ',';
    first_ = false;
  }
  std::string& line_;
  bool first_ = true;
};

// command_t.origin up to its first NUL, a byte that is not printable ASCII as '?' (a log is
// anyone's: its text is not trusted).
std::string origin_of(const pneu_lcm::command_t& m) {
  std::string out;
  for (const std::int8_t b : m.origin) {
    if (b == 0) break;
    const auto c = static_cast<unsigned char>(b);
    out += c < 0x20 || c > 0x7e ? '?' : static_cast<char>(c);
  }
  return out;
}

const char* command_kind_name(std::int8_t kind) {
  using C = pneu_lcm::command_t;
  switch (kind) {
    case C::KIND_SET_POINT:
      return "set_point";
    case C::KIND_SET_POINT_STEP:
      return "set_point_step";
    case C::KIND_ARM:
      return "arm";
    case C::KIND_DISARM:
      return "disarm";
    case C::KIND_FAULT_RESET:
      return "fault_reset";
    case C::KIND_HOLD_ON:
      return "hold_on";
    case C::KIND_HOLD_OFF:
      return "hold_off";
    default:
      return "unknown";
  }
}

// The fingerprint: the payload's first 8 bytes, big-endian, as T::getHash() gives it.
bool read_fingerprint(const void* data, std::int32_t size, std::int64_t* fingerprint) {
  if (size < 8) return false;
  const auto* b = static_cast<const unsigned char*>(data);
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | b[i];
  *fingerprint = static_cast<std::int64_t>(v);
  return true;
}

// Decoded whole: the fingerprint matches and the payload holds exactly one message. Trailing
// bytes are refused, since the daemon never sends them and they mean the type is not what it says.
template <class T>
bool decode_whole(const void* data, std::int32_t size, T* msg) {
  return msg->decode(data, 0, size) == size;
}

void unknown_row(std::int64_t log_utime, const void* data, std::int32_t size, std::string& line) {
  Row row(line, log_utime);
  row.integer(size);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex;
  const auto* b = static_cast<const unsigned char*>(data);
  for (std::int32_t i = 0; i < size && i < 8; ++i) {
    hex += kHex[b[i] >> 4];
    hex += kHex[b[i] & 0xf];
  }
  row.word(hex);
  row.end();
}

}  // namespace

const char* type_name(MessageType type) {
  switch (type) {
    case MessageType::kState:
      return "state_t";
    case MessageType::kEvent:
      return "event_t";
    case MessageType::kPrediction:
      return "prediction_t";
    case MessageType::kHealth:
      return "health_t";
    case MessageType::kCommand:
      return "command_t";
    case MessageType::kIdentification:
      return "identification_t";
    case MessageType::kUnknown:
      return "unknown";
  }
  return "unknown";
}

std::string_view csv_header(MessageType type) {
  switch (type) {
    case MessageType::kState: {
      static const std::string header = "log_utime,utime," + records::csv_header<controller::TickRecord>();
      return header;
    }
    case MessageType::kEvent: {
      static const std::string header = "log_utime,utime," + records::csv_header<controller::EventMessage>();
      return header;
    }
    case MessageType::kPrediction: {
      static const std::string header = "log_utime,utime," + records::csv_header<controller::ForecastRecord>();
      return header;
    }
    case MessageType::kHealth: {
      static const std::string header = "log_utime,utime," + records::csv_header<controller::HealthMessage>();
      return header;
    }
    case MessageType::kCommand:
      return "log_utime,utime,seq,kind,kind_name,value,origin,session";
    case MessageType::kIdentification: {
      static const std::string header = "log_utime,utime," + records::csv_header<controller::IdentificationRecord>();
      return header;
    }
    case MessageType::kUnknown:
      return "log_utime,bytes,fingerprint_hex";
  }
  return "log_utime,bytes,fingerprint_hex";
}

MessageType classify(const void* data, std::int32_t size) {
  std::int64_t fingerprint = 0;
  if (!read_fingerprint(data, size, &fingerprint)) return MessageType::kUnknown;
  const auto as = [&](auto msg, MessageType type) {
    return decode_whole(data, size, &msg) ? type : MessageType::kUnknown;
  };
  if (fingerprint == pneu_lcm::state_t::getHash())
    return as(pneu_lcm::state_t{}, MessageType::kState);
  if (fingerprint == pneu_lcm::event_t::getHash())
    return as(pneu_lcm::event_t{}, MessageType::kEvent);
  if (fingerprint == pneu_lcm::prediction_t::getHash())
    return as(pneu_lcm::prediction_t{}, MessageType::kPrediction);
  if (fingerprint == pneu_lcm::health_t::getHash())
    return as(pneu_lcm::health_t{}, MessageType::kHealth);
  if (fingerprint == pneu_lcm::command_t::getHash())
    return as(pneu_lcm::command_t{}, MessageType::kCommand);
  if (fingerprint == pneu_lcm::identification_t::getHash())
    return as(pneu_lcm::identification_t{}, MessageType::kIdentification);
  return MessageType::kUnknown;
}

RowInfo format_csv_row(std::int64_t log_utime, const void* data, std::int32_t size,
                       std::string& line) {
  std::int64_t fingerprint = 0;
  if (!read_fingerprint(data, size, &fingerprint)) {
    unknown_row(log_utime, data, size, line);
    return {};
  }
  if (fingerprint == pneu_lcm::state_t::getHash()) {
    pneu_lcm::state_t m{};
    if (decode_whole(data, size, &m)) {
      Row(line, log_utime).integer(m.utime).message<controller::TickRecord>(m).end();
      return {MessageType::kState, m.seq};
    }
  } else if (fingerprint == pneu_lcm::event_t::getHash()) {
    pneu_lcm::event_t m{};
    if (decode_whole(data, size, &m)) {
      Row(line, log_utime).integer(m.utime).message<controller::EventMessage>(m).end();
      return {MessageType::kEvent, 0};
    }
  } else if (fingerprint == pneu_lcm::prediction_t::getHash()) {
    pneu_lcm::prediction_t m{};
    if (decode_whole(data, size, &m)) {
      Row(line, log_utime).integer(m.utime).message<controller::ForecastRecord>(m).end();
      return {MessageType::kPrediction, 0};
    }
  } else if (fingerprint == pneu_lcm::health_t::getHash()) {
    pneu_lcm::health_t m{};
    if (decode_whole(data, size, &m)) {
      Row(line, log_utime).integer(m.utime).message<controller::HealthMessage>(m).end();
      return {MessageType::kHealth, 0};
    }
  } else if (fingerprint == pneu_lcm::command_t::getHash()) {
    pneu_lcm::command_t m{};
    if (decode_whole(data, size, &m)) {
      Row(line, log_utime)
          .integer(m.utime)
          .integer(m.seq)
          .integer(m.kind)
          .word(command_kind_name(m.kind))
          .number(m.value)
          .text(origin_of(m))
          .integer(m.session)
          .end();
      return {MessageType::kCommand, 0};
    }
  } else if (fingerprint == pneu_lcm::identification_t::getHash()) {
    pneu_lcm::identification_t m{};
    if (decode_whole(data, size, &m)) {
      Row(line, log_utime).integer(m.utime).message<controller::IdentificationRecord>(m).end();
      return {MessageType::kIdentification, 0};
    }
  }
  unknown_row(log_utime, data, size, line);
  return {};
}

std::string sanitize_file_name(std::string_view channel) {
  std::string name(channel);
  for (char& c : name) {
    const bool keep = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                      c == '_' || c == '.' || c == '-';
    if (!keep) c = '_';
  }
  return name;
}

}  // namespace pneu::log2csv
