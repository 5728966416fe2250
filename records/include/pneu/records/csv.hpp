// A record as CSV: its header (the fields' names) and its cells, as its description says.
// Numbers with the field's significant digits (or as many as asked), an empty cell for NaN;
// integers and enumerations as integers; booleans as 1 and 0. Written to a stream or appended to
// a string.
#pragma once

#include <charconv>
#include <string>
#include <string_view>

#include "pneu/records/record.hpp"
#include "pneu/records/text.hpp"

namespace pneu::records {

/// Writes one value of a field as a CSV cell (no separator); `digits`: 0 for the field's.
template <class Out, class F>
void write_csv_value(Out& out, const F& field, const typename F::member_type& v, int digits = 0) {
  using M = typename F::member_type;
  if constexpr (F::kind == Kind::kBoolean) {
    put(out, v ? '1' : '0');
  } else if constexpr (F::kind == Kind::kNumber) {
    const NumberText n = number_text(static_cast<double>(v), digits > 0 ? digits : field.digits);
    put(out, n.text, n.size);
  } else {
    char buf[24];
    const auto r = std::to_chars(buf, buf + sizeof buf, static_cast<wire_integer_t<M>>(v));
    put(out, buf, static_cast<std::size_t>(r.ptr - buf));
  }
}

/// The CSV header of `Record`: its fields' names, each followed by `suffix`, comma-separated.
template <Described Record>
[[nodiscard]] std::string csv_header(std::string_view suffix = {}) {
  std::string h;
  for_each_field<Record>([&](const auto& f) {
    if (!h.empty()) h += ',';
    h += f.name;
    h += suffix;
  });
  return h;
}

/// Writes the cells of `r`, comma-separated; `leading_comma`: one before the first too; `digits`:
/// the significant digits of every number (0: each field's own).
template <Described Record, class Out>
void write_csv_cells(Out& out, const Record& r, bool leading_comma = false, int digits = 0) {
  bool comma = leading_comma;
  for_each_field<Record>([&](const auto& f) {
    if (comma) put(out, ',');
    comma = true;
    write_csv_value(out, f, f.of(r), digits);
  });
}

/// Writes as many empty cells as `Record` has fields (a group of columns with no value).
template <Described Record, class Out>
void write_csv_empty_cells(Out& out, bool leading_comma = false) {
  for (std::size_t i = 0; i < kFieldCount<Record>; ++i)
    if (leading_comma || i > 0) put(out, ',');
}

}  // namespace pneu::records
