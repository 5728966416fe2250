// A record as a JSON object: its fields' names as keys, in the description's order. Numbers with
// the field's significant digits, null for NaN; integers and enumerations as integers; booleans as
// true and false. Written to a stream or appended to a string.
#pragma once

#include <charconv>
#include <cmath>

#include "pneu/records/record.hpp"
#include "pneu/records/text.hpp"

namespace pneu::records {

/// Writes the members of `r` ("name":value, comma-separated, no braces); `leading_comma`: one
/// before the first too.
template <Described Record, class Out>
void write_json_members(Out& out, const Record& r, bool leading_comma = false) {
  bool comma = leading_comma;
  for_each_field<Record>([&](const auto& f) {
    using F = std::remove_cvref_t<decltype(f)>;
    using M = typename F::member_type;
    if (comma) put(out, ',');
    comma = true;
    put(out, '"');
    put(out, std::string_view(f.name));  // names are identifiers: nothing to escape
    put(out, std::string_view("\":"));
    const M& v = f.of(r);
    if constexpr (F::kind == Kind::kBoolean) {
      put(out, std::string_view(v ? "true" : "false"));
    } else if constexpr (F::kind == Kind::kNumber) {
      if (!std::isfinite(static_cast<double>(v))) {
        put(out, std::string_view("null"));
      } else {
        const NumberText n = number_text(static_cast<double>(v), f.digits);
        put(out, n.text, n.size);
      }
    } else {
      char buf[24];
      const auto res = std::to_chars(buf, buf + sizeof buf, static_cast<wire_integer_t<M>>(v));
      put(out, buf, static_cast<std::size_t>(res.ptr - buf));
    }
  });
}

/// Writes `r` as one JSON object on one line (no newline).
template <Described Record, class Out>
void write_json_object(Out& out, const Record& r) {
  put(out, '{');
  write_json_members(out, r);
  put(out, '}');
}

}  // namespace pneu::records
