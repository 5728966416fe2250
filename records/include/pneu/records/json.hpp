// A record as a JSON object: its fields' names as keys, in the description's order (or a view's).
// Numbers with the field's significant digits, null for NaN; integers and enumerations as
// integers; booleans as true and false; strings escaped (RFC 8259); an enumeration written as
// text (.named) as its name; an optional member with no value as null; a group as an object
// (null when it has no value); a list as an array (of objects or strings); a map or a fixed array
// as an object keyed by its names. A field with .when(f) is left out unless f holds; one with
// .null_when(f) is null when f holds. Written to a stream or appended to a string.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdio>
#include <string_view>

#include "pneu/records/record.hpp"
#include "pneu/records/text.hpp"

namespace pneu::records {

/// Writes `s` as a JSON string: quotes, backslashes and control characters escaped.
template <class Out>
void write_json_string(Out& out, std::string_view s) {
  put(out, '"');
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      put(out, '\\');
      put(out, c);
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      const int n = std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(c));
      put(out, buf, static_cast<std::size_t>(n));
    } else {
      put(out, c);
    }
  }
  put(out, '"');
}

template <Described Record, class Out>
void write_json_object(Out& out, const Record& r);

/// Writes a number, an integer or a bool as JSON (a number with `digits` significant digits).
template <class Out, class E>
void write_json_scalar(Out& out, const E& v, int digits) {
  if constexpr (std::is_same_v<E, bool>) {
    put(out, std::string_view(v ? "true" : "false"));
  } else if constexpr (std::is_floating_point_v<E>) {
    if (!std::isfinite(static_cast<double>(v))) {
      put(out, std::string_view("null"));
    } else {
      const NumberText n = number_text(static_cast<double>(v), digits);
      put(out, n.text, n.size);
    }
  } else {
    char buf[24];
    const auto res = std::to_chars(buf, buf + sizeof buf, static_cast<std::int64_t>(v));
    put(out, buf, static_cast<std::size_t>(res.ptr - buf));
  }
}

/// Writes one element of a fixed array as JSON.
template <class Out, class F, class E>
void write_json_element(Out& out, const F& f, const E& v) {
  if constexpr (std::is_same_v<E, bool> || std::is_floating_point_v<E>) write_json_scalar(out, v, f.digits);
  else write_json_scalar(out, static_cast<typename F::wire_type>(v), f.digits);
}

/// Writes one value of a map as JSON.
template <class Out, class F, class E>
void write_json_map_value(Out& out, const F& f, const E& v) {
  if constexpr (Described<E>) write_json_object(out, v);
  else write_json_scalar(out, v, f.digits);
}

/// Writes one value of a field as JSON.
template <class Out, class F, class V>
void write_json_value(Out& out, const F& f, const V& v) {
  if constexpr (kIsOptional<V>) {
    if (v.has_value()) write_json_value(out, f, *v);
    else put(out, std::string_view("null"));
  } else if constexpr (F::kind == Kind::kGroup) {
    write_json_object(out, v);
  } else if constexpr (F::kind == Kind::kList) {
    put(out, '[');
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (i > 0) put(out, ',');
      if constexpr (kIsString<typename List<V>::element>) write_json_string(out, v[i]);
      else write_json_object(out, v[i]);
    }
    put(out, ']');
  } else if constexpr (F::kind == Kind::kMap) {
    put(out, '{');
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (i > 0) put(out, ',');
      write_json_string(out, v[i].first);
      put(out, ':');
      write_json_map_value(out, f, v[i].second);
    }
    put(out, '}');
  } else if constexpr (F::kind == Kind::kArray) {
    put(out, '{');
    for (std::size_t k = 0; k < v.size(); ++k) {
      if (k > 0) put(out, ',');
      put(out, '"');
      put(out, std::string_view(f.index[k].name));  // identifiers: nothing to escape
      put(out, std::string_view("\":"));
      write_json_element(out, f, v[k]);
    }
    put(out, '}');
  } else if constexpr (F::kind == Kind::kBoolean) {
    put(out, std::string_view(v ? "true" : "false"));
  } else if constexpr (F::kind == Kind::kNumber) {
    if (!std::isfinite(static_cast<double>(v))) {
      put(out, std::string_view("null"));
    } else {
      const NumberText n = number_text(static_cast<double>(v), f.digits);
      put(out, n.text, n.size);
    }
  } else if constexpr (F::kind == Kind::kString) {
    if constexpr (std::is_same_v<V, const char*>) write_json_string(out, v == nullptr ? "" : v);
    else write_json_string(out, v);
  } else if constexpr (F::kind == Kind::kName) {
    write_json_string(out, f.name_of(v));
  } else {
    using W = std::conditional_t<kIsOptional<typename F::member_type>, wire_integer_t<V>, typename F::wire_type>;
    char buf[24];
    const auto res = std::to_chars(buf, buf + sizeof buf, static_cast<std::int64_t>(static_cast<W>(v)));
    put(out, buf, static_cast<std::size_t>(res.ptr - buf));
  }
}

/// Writes one field of `r` as a member ("name":value, no separator), if it is written for `r`;
/// whether it was.
template <class Out, class F>
bool write_json_member(Out& out, const F& f, const typename F::record_type& r) {
  if (!f.written(r)) return false;
  put(out, '"');
  put(out, std::string_view(f.name));  // names are identifiers: nothing to escape
  put(out, std::string_view("\":"));
  if (f.null_for(r)) put(out, std::string_view("null"));
  else write_json_value(out, f, f.of(r));
  return true;
}

/// Writes the members of `r` ("name":value, comma-separated, no braces); `leading_comma`: one
/// before the first too.
template <Described Record, class Out>
void write_json_members(Out& out, const Record& r, bool leading_comma = false) {
  bool comma = leading_comma;
  for_each_field<Record>([&](const auto& f) {
    if (!f.written(r)) return;
    if (comma) put(out, ',');
    comma = true;
    write_json_member(out, f, r);
  });
}

/// Writes `r` as one JSON object on one line (no newline).
template <Described Record, class Out>
void write_json_object(Out& out, const Record& r) {
  put(out, '{');
  write_json_members(out, r);
  put(out, '}');
}

/// Writes `r` as one line of a JSON lines file of views: {"event":"<view>", then the view's
/// fields in its order}, and the newline.
template <Described Record, class Out>
void write_json_line(Out& out, const View& view, const Record& r) {
  put(out, std::string_view("{\"event\":\""));
  put(out, std::string_view(view.name));
  put(out, '"');
  for (const char* name : view.fields)
    with_field<Record>(name, [&](const auto& f) {
      if (!f.written(r)) return;
      put(out, ',');
      write_json_member(out, f, r);
    });
  put(out, std::string_view("}\n"));
}

namespace detail {
template <class Out>
void indent(Out& out, int depth) {
  put(out, '\n');
  for (int i = 0; i < depth; ++i) put(out, std::string_view("  "));
}

template <Described Record, class Out>
void write_json_pretty_object(Out& out, const Record& r, int depth);

// One value, as write_json_value, a group or a list laid out over lines.
template <class Out, class F, class V>
void write_json_pretty_value(Out& out, const F& f, const V& v, int depth) {
  if constexpr (kIsOptional<V>) {
    if (v.has_value()) write_json_pretty_value(out, f, *v, depth);
    else put(out, std::string_view("null"));
  } else if constexpr (F::kind == Kind::kGroup) {
    write_json_pretty_object(out, v, depth);
  } else if constexpr (F::kind == Kind::kList) {
    put(out, '[');
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (i > 0) put(out, ',');
      indent(out, depth + 1);
      if constexpr (kIsString<typename List<V>::element>) write_json_string(out, v[i]);
      else write_json_pretty_object(out, v[i], depth + 1);
    }
    if (!v.empty()) indent(out, depth);
    put(out, ']');
  } else if constexpr (F::kind == Kind::kMap) {
    put(out, '{');
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (i > 0) put(out, ',');
      indent(out, depth + 1);
      write_json_string(out, v[i].first);
      put(out, std::string_view(": "));
      if constexpr (Described<typename Map<V>::element>) write_json_pretty_object(out, v[i].second, depth + 1);
      else write_json_scalar(out, v[i].second, f.digits);
    }
    if (!v.empty()) indent(out, depth);
    put(out, '}');
  } else if constexpr (F::kind == Kind::kArray) {
    put(out, '{');
    for (std::size_t k = 0; k < v.size(); ++k) {
      if (k > 0) put(out, ',');
      indent(out, depth + 1);
      put(out, '"');
      put(out, std::string_view(f.index[k].name));
      put(out, std::string_view("\": "));
      write_json_element(out, f, v[k]);
    }
    indent(out, depth);
    put(out, '}');
  } else {
    write_json_value(out, f, v);
  }
}

template <Described Record, class Out>
void write_json_pretty_object(Out& out, const Record& r, int depth) {
  put(out, '{');
  bool first = true;
  for_each_field<Record>([&](const auto& f) {
    if (!f.written(r)) return;
    if (!first) put(out, ',');
    first = false;
    indent(out, depth + 1);
    put(out, '"');
    put(out, std::string_view(f.name));
    put(out, std::string_view("\": "));
    if (f.null_for(r)) put(out, std::string_view("null"));
    else write_json_pretty_value(out, f, f.of(r), depth + 1);
  });
  if (!first) indent(out, depth);
  put(out, '}');
}
}  // namespace detail

/// Writes `r` as a JSON document laid out for people: one member a line, indented by two spaces
/// a level ("key": value), and the newline.
template <Described Record, class Out>
void write_json_document(Out& out, const Record& r) {
  detail::write_json_pretty_object(out, r, 0);
  put(out, '\n');
}

}  // namespace pneu::records
