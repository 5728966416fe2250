// A record as CSV: its header (the fields' names) and its cells, as its description says.
// Numbers with the field's significant digits (or as many as asked), an empty cell for NaN;
// integers and enumerations as integers; booleans as 1 and 0; strings always quoted (RFC 4180: a
// quote doubled); an enumeration written as text (.named) as two cells, its number and its name
// (columns NAME and NAME_name). Written to a stream or appended to a string; from the record, or
// from an LCM message carrying it (the message's values as they came, unknown numbers included).
#pragma once

#include <charconv>
#include <string>
#include <string_view>
#include <tuple>

#include "pneu/records/record.hpp"
#include "pneu/records/text.hpp"

namespace pneu::records {

template <class Out>
void write_csv_integer(Out& out, std::int64_t v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  put(out, buf, static_cast<std::size_t>(r.ptr - buf));
}

template <class Out>
void write_csv_string(Out& out, std::string_view v) {
  put(out, '"');
  for (const char c : v) {
    if (c == '"') put(out, '"');
    put(out, c);
  }
  put(out, '"');
}

/// Writes one value of a field as it travels (`w`, of its wire type) as CSV cells (no separator
/// before); `digits`: 0 for the field's.
template <class Out, class F, class W>
void write_csv_wire_value(Out& out, const F& field, const W& w, int digits = 0) {
  if constexpr (F::kind == Kind::kBoolean) {
    put(out, w ? '1' : '0');
  } else if constexpr (F::kind == Kind::kNumber) {
    const NumberText n = number_text(static_cast<double>(w), digits > 0 ? digits : field.digits);
    put(out, n.text, n.size);
  } else if constexpr (F::kind == Kind::kString) {
    if constexpr (std::is_same_v<W, const char*>) write_csv_string(out, w == nullptr ? "" : w);
    else write_csv_string(out, w);
  } else {
    write_csv_integer(out, static_cast<std::int64_t>(w));
    if constexpr (F::kind == Kind::kName) {
      put(out, ',');
      put(out, std::string_view(field.name_of_wire(static_cast<std::int64_t>(w))));
    }
  }
}

/// Writes one value of a field as CSV cells (no separator before); `digits`: 0 for the field's.
template <class Out, class F>
void write_csv_value(Out& out, const F& field, const typename F::member_type& v, int digits = 0) {
  using M = typename F::member_type;
  if constexpr (F::kind == Kind::kName) write_csv_wire_value(out, field, field.wire_of(v), digits);
  else if constexpr (F::kind == Kind::kString) write_csv_wire_value(out, field, v, digits);
  else if constexpr (F::kind == Kind::kInteger) write_csv_wire_value(out, field, static_cast<typename F::wire_type>(v), digits);
  else write_csv_wire_value(out, field, static_cast<M>(v), digits);
}

/// The CSV columns of one field: its name, each followed by `suffix` (and NAME_name for an
/// enumeration written as text).
template <class F>
void append_csv_columns(std::string& h, const F& f, std::string_view suffix = {}) {
  h += f.name;
  h += suffix;
  if constexpr (F::kind == Kind::kName) {
    h += ',';
    h += f.name;
    h += "_name";
    h += suffix;
  }
}

/// The number of CSV columns of `Record`.
template <Described Record>
constexpr std::size_t csv_column_count() {
  std::size_t n = 0;
  for_each_field<Record>([&](const auto& f) { n += std::remove_cvref_t<decltype(f)>::kind == Kind::kName ? 2 : 1; });
  return n;
}

/// The CSV header of `Record`: its fields' names, each followed by `suffix`, comma-separated.
template <Described Record>
[[nodiscard]] std::string csv_header(std::string_view suffix = {}) {
  std::string h;
  for_each_field<Record>([&](const auto& f) {
    if (!h.empty()) h += ',';
    append_csv_columns(h, f, suffix);
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

/// Writes as many empty cells as `Record` has columns (a group of columns with no value).
template <Described Record, class Out>
void write_csv_empty_cells(Out& out, bool leading_comma = false) {
  for (std::size_t i = 0; i < csv_column_count<Record>(); ++i)
    if (leading_comma || i > 0) put(out, ',');
}

}  // namespace pneu::records
