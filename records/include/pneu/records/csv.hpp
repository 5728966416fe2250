// A record as CSV: its header (the fields' names) and its cells, as its description says.
// Numbers with the field's significant digits (or as many as asked), or its decimals (.fixed), an
// empty cell for NaN (printf's nan with .nan_as_text); integers and enumerations as integers;
// booleans as 1 and 0; free text (std::string, std::string_view) always quoted (RFC 4180: a quote
// doubled), a word (const char*: a name from a fixed table, never a comma or a quote) as it is;
// an enumeration written as text (.named) as two cells, its number and its name (columns NAME and
// NAME_name); an optional member with no value, an empty cell; a group, its record's cells (empty
// ones when it has no value) under its prefix; the fixed arrays indexed by one table, a cell an
// element, element by element at the first one's place (columns NAME<suffix>). Written to a stream
// or appended to a string; from the record, or from an LCM message carrying it (lcm.hpp: the
// message's values as they came, unknown numbers included). A view (record.hpp) selects and
// orders the columns.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdio>
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

template <Described Record, class Out>
void write_csv_cells(Out& out, const Record& r, bool leading_comma = false, int digits = 0);
template <Described Record, class Out>
void write_csv_empty_cells(Out& out, bool leading_comma = false);

/// Writes a number as CSV: with the field's decimals (.fixed) or `digits` significant digits (0:
/// the field's), NaN as nothing (or printf's nan: .nan_as_text).
template <class Out, class F>
void write_csv_number(Out& out, const F& field, double v, int digits) {
  if (std::isnan(v) && !field.nan_text) return;
  if (field.fixed_decimals >= 0 || std::isnan(v)) {
    char buf[352];
    const int n = std::snprintf(buf, sizeof buf, "%.*f", field.fixed_decimals >= 0 ? field.fixed_decimals : 6, v);
    put(out, buf, static_cast<std::size_t>(n));
    return;
  }
  const NumberText n = number_text(v, digits > 0 ? digits : field.digits);
  put(out, n.text, n.size);
}

/// Writes one element of a fixed array (as the record holds it, or as it travels) as a CSV cell.
template <class Out, class F, class E>
void write_csv_element(Out& out, const F& field, const E& v, int digits = 0) {
  if constexpr (std::is_same_v<E, bool>) put(out, v ? '1' : '0');
  else if constexpr (std::is_floating_point_v<E>) write_csv_number(out, field, static_cast<double>(v), digits);
  else write_csv_integer(out, static_cast<std::int64_t>(v));
}

/// Writes one value of a field as it travels (`w`, of its wire type, or an optional of it) as CSV
/// cells (no separator before); `digits`: 0 for the field's.
template <class Out, class F, class W>
void write_csv_wire_value(Out& out, const F& field, const W& w, int digits = 0) {
  if constexpr (kIsOptional<W>) {
    if (w.has_value()) write_csv_wire_value(out, field, *w, digits);
    else if constexpr (F::kind == Kind::kGroup) write_csv_empty_cells<value_t<W>>(out);
    else if constexpr (F::kind == Kind::kName) put(out, ',');
  } else if constexpr (F::kind == Kind::kGroup) {
    write_csv_cells(out, w, false, digits);
  } else if constexpr (F::kind == Kind::kBoolean) {
    put(out, w ? '1' : '0');
  } else if constexpr (F::kind == Kind::kNumber) {
    write_csv_number(out, field, static_cast<double>(w), digits);
  } else if constexpr (F::kind == Kind::kArray) {  // its own cells, one an element
    for (std::size_t k = 0; k < Array<typename F::member_type>::size; ++k) {
      if (k > 0) put(out, ',');
      write_csv_element(out, field, w[k], digits);
    }
  } else if constexpr (F::kind == Kind::kString) {
    if constexpr (std::is_same_v<W, const char*>) {
      if (w != nullptr) put(out, std::string_view(w));  // a word
    } else {
      write_csv_string(out, w);
    }
  } else {
    write_csv_integer(out, static_cast<std::int64_t>(w));
    if constexpr (F::kind == Kind::kName) {
      put(out, ',');
      put(out, std::string_view(field.name_of_wire(static_cast<std::int64_t>(w))));
    }
  }
}

/// Writes one value of a field as CSV cells (no separator before); `digits`: 0 for the field's.
template <class Out, class F, class V>
void write_csv_value(Out& out, const F& field, const V& v, int digits = 0) {
  if constexpr (kIsOptional<V>) {
    if (v.has_value()) write_csv_value(out, field, *v, digits);
    else write_csv_wire_value(out, field, v, digits);  // the empty cells
  } else if constexpr (F::kind == Kind::kName) {
    write_csv_wire_value(out, field, field.wire_of(v), digits);
  } else if constexpr (F::kind == Kind::kArray) {
    using E = typename Array<typename F::member_type>::element;
    for (std::size_t k = 0; k < v.size(); ++k) {
      if (k > 0) put(out, ',');
      if constexpr (std::is_same_v<E, bool> || std::is_floating_point_v<E>) write_csv_element(out, field, v[k], digits);
      else write_csv_element(out, field, static_cast<typename F::wire_type>(v[k]), digits);
    }
  } else if constexpr (F::kind == Kind::kInteger) {
    using W = std::conditional_t<kIsOptional<typename F::member_type>, wire_integer_t<V>, typename F::wire_type>;
    write_csv_wire_value(out, field, static_cast<W>(v), digits);
  } else {
    write_csv_wire_value(out, field, v, digits);
  }
}

template <Described Record>
[[nodiscard]] std::string csv_header(std::string_view suffix = {}, std::string_view prefix = {});

/// The CSV columns of one field: its name, after `prefix`, followed by `suffix` (and NAME_name
/// for an enumeration written as text; a group's columns, after its own prefix too).
template <class F>
void append_csv_columns(std::string& h, const F& f, std::string_view suffix = {}, std::string_view prefix = {}) {
  if constexpr (F::kind == Kind::kGroup) {
    h += csv_header<value_t<typename F::member_type>>(suffix, std::string(prefix) + f.prefix);
  } else if constexpr (F::kind == Kind::kArray) {  // its own columns, one an element
    for (std::size_t k = 0; k < Array<typename F::member_type>::size; ++k) {
      if (k > 0) h += ',';
      h += prefix;
      h += f.index[k].name;
      h += f.index_suffix;
      h += suffix;
    }
  } else {
    h += prefix;
    h += f.name;
    h += suffix;
    if constexpr (F::kind == Kind::kName) {
      h += ',';
      h += prefix;
      h += f.name;
      h += "_name";
      h += suffix;
    }
  }
}

/// The number of CSV columns of `Record`.
template <Described Record>
constexpr std::size_t csv_column_count() {
  std::size_t n = 0;
  for_each_field<Record>([&](const auto& f) {
    using F = std::remove_cvref_t<decltype(f)>;
    if constexpr (F::kind == Kind::kGroup) n += csv_column_count<value_t<typename F::member_type>>();
    else if constexpr (F::kind == Kind::kArray) n += Array<typename F::member_type>::size;
    else n += F::kind == Kind::kName ? 2 : 1;
  });
  return n;
}

/// The CSV header of `Record`: its fields' names, each after `prefix` and followed by `suffix`,
/// comma-separated.
template <Described Record>
[[nodiscard]] std::string csv_header(std::string_view suffix, std::string_view prefix) {
  std::string h;
  for_each_field<Record>([&](const auto& f) {
    using F = std::remove_cvref_t<decltype(f)>;
    if constexpr (F::kind == Kind::kArray) {  // the arrays of its index, element by element
      if (!leads_its_index<Record>(f)) return;
      for (std::size_t k = 0; k < Array<typename F::member_type>::size; ++k)
        for_each_indexed_by<Record>(f.index, [&](const auto& g) {
          if (!h.empty()) h += ',';
          h += prefix;
          h += g.index[k].name;
          h += g.index_suffix;
          h += suffix;
        });
      return;
    }
    if (!h.empty()) h += ',';
    append_csv_columns(h, f, suffix, prefix);
  });
  return h;
}

/// The CSV header of the columns `view` selects of `Record`, in its order.
template <Described Record>
[[nodiscard]] std::string csv_header(const View& view) {
  std::string h;
  for (const char* name : view.fields)
    with_field<Record>(name, [&](const auto& f) {
      if (!h.empty()) h += ',';
      append_csv_columns(h, f);
    });
  return h;
}

/// Writes the cells of `r`, comma-separated; `leading_comma`: one before the first too; `digits`:
/// the significant digits of every number (0: each field's own).
template <Described Record, class Out>
void write_csv_cells(Out& out, const Record& r, bool leading_comma, int digits) {
  bool comma = leading_comma;
  for_each_field<Record>([&](const auto& f) {
    using F = std::remove_cvref_t<decltype(f)>;
    if constexpr (F::kind == Kind::kArray) {  // the arrays of its index, element by element
      if (!leads_its_index<Record>(f)) return;
      for (std::size_t k = 0; k < Array<typename F::member_type>::size; ++k)
        for_each_indexed_by<Record>(f.index, [&](const auto& g) {
          if (comma) put(out, ',');
          comma = true;
          using G = std::remove_cvref_t<decltype(g)>;
          using E = typename Array<typename G::member_type>::element;
          if constexpr (std::is_same_v<E, bool> || std::is_floating_point_v<E>) write_csv_element(out, g, g.of(r)[k], digits);
          else write_csv_element(out, g, static_cast<typename G::wire_type>(g.of(r)[k]), digits);
        });
      return;
    }
    if (comma) put(out, ',');
    comma = true;
    write_csv_value(out, f, f.of(r), digits);
  });
}

/// Writes the cells `view` selects of `r`, in its order, and the newline.
template <Described Record, class Out>
void write_csv_row(Out& out, const View& view, const Record& r) {
  bool comma = false;
  for (const char* name : view.fields)
    with_field<Record>(name, [&](const auto& f) {
      if (comma) put(out, ',');
      comma = true;
      write_csv_value(out, f, f.of(r));
    });
  put(out, '\n');
}

/// Writes as many empty cells as `Record` has columns (a group of columns with no value).
template <Described Record, class Out>
void write_csv_empty_cells(Out& out, bool leading_comma) {
  for (std::size_t i = 0; i < csv_column_count<Record>(); ++i)
    if (leading_comma || i > 0) put(out, ',');
}

}  // namespace pneu::records
