// One logged pneu_lcm message as one CSV row: the type found by its fingerprint, the fields in
// .lcm order, numbers written so that they read back bit for bit.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace pneu::log2csv {

/// What a logged message decodes as. kUnknown: a fingerprint of no pneu_lcm type, or a payload
/// that does not decode as the type its fingerprint names (too short, or bytes left over).
enum class MessageType : std::uint8_t { kState, kEvent, kPrediction, kHealth, kCommand, kIdentification, kUnknown };
inline constexpr std::size_t kMessageTypeCount = 7;
inline constexpr std::array<MessageType, kMessageTypeCount> kAllMessageTypes = {
    MessageType::kState,   MessageType::kEvent,          MessageType::kPrediction, MessageType::kHealth,
    MessageType::kCommand, MessageType::kIdentification, MessageType::kUnknown};

/// "state_t", "event_t", "prediction_t", "health_t", "command_t", "identification_t" or "unknown".
[[nodiscard]] const char* type_name(MessageType type);

/// The CSV header of a type's file, without the newline.
[[nodiscard]] std::string_view csv_header(MessageType type);

/// The type a payload of `size` bytes decodes as (decoding it whole: the fingerprint alone is not
/// enough). Agrees with format_csv_row().type.
[[nodiscard]] MessageType classify(const void* data, std::int32_t size);

/// What format_csv_row() wrote.
struct RowInfo {
  MessageType type = MessageType::kUnknown;
  std::int64_t state_seq = 0;  ///< state_t.seq when type is kState, else 0
};

/// Decodes a payload of `size` bytes and replaces `line` by its CSV row (newline included):
/// log_utime [us] first, then the fields of its type as csv_header() names them. A payload that
/// is not a pneu_lcm message gives the kUnknown row: log_utime, its size in bytes, its first 8
/// bytes (fewer if it is shorter) in lowercase hex.
RowInfo format_csv_row(std::int64_t log_utime, const void* data, std::int32_t size,
                       std::string& line);

/// Replaces every character outside [A-Za-z0-9_.-] by '_' (a channel name made a file name).
[[nodiscard]] std::string sanitize_file_name(std::string_view channel);

}  // namespace pneu::log2csv
