// The JSON Schema (draft 2020-12) of a record as json.hpp writes it: an object with every field
// required and no other; a number may be null (no value), an integer is an integer, a boolean a
// boolean. Each property carries the field's documentation, and its unit ("unit", an annotation).
#pragma once

#include <string>
#include <string_view>

#include "pneu/records/record.hpp"

namespace pneu::records {

namespace detail {
inline void append_json_string(std::string& out, std::string_view s) {
  out += '"';
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      static constexpr char kHex[] = "0123456789abcdef";
      out += "\\u00";
      out += kHex[(c >> 4) & 0xf];
      out += kHex[c & 0xf];
    } else {
      out += c;
    }
  }
  out += '"';
}
}  // namespace detail

/// The schema of `Record`'s JSON object, `id` its $id.
template <Described Record>
[[nodiscard]] std::string json_schema(std::string_view id) {
  using D = Description<Record>;
  std::string s = "{\n  \"$schema\": \"https://json-schema.org/draft/2020-12/schema\",\n  \"$id\": ";
  detail::append_json_string(s, id);
  s += ",\n  \"title\": ";
  detail::append_json_string(s, D::kName);
  s += ",\n  \"description\": ";
  detail::append_json_string(s, D::kDoc);
  s += ",\n  \"type\": \"object\",\n  \"properties\": {";
  std::string required;
  bool first = true;
  for_each_field<Record>([&](const auto& f) {
    using F = std::remove_cvref_t<decltype(f)>;
    s += first ? "\n    " : ",\n    ";
    required += first ? "" : ", ";
    first = false;
    detail::append_json_string(s, f.name);
    detail::append_json_string(required, f.name);
    s += ": {\"type\": ";
    if constexpr (F::kind == Kind::kNumber) s += "[\"number\", \"null\"]";
    else if constexpr (F::kind == Kind::kInteger) s += "\"integer\"";
    else s += "\"boolean\"";
    s += ", \"description\": ";
    detail::append_json_string(s, f.doc);
    if (f.unit[0] != '\0') {
      s += ", \"unit\": ";
      detail::append_json_string(s, f.unit);
    }
    s += '}';
  });
  s += "\n  },\n  \"required\": [" + required + "],\n  \"additionalProperties\": false\n}\n";
  return s;
}

}  // namespace pneu::records
