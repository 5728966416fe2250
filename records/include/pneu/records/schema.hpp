// The JSON Schema (draft 2020-12) of a record as json.hpp writes it: an object with every field
// required (but those written .when(f): optional) and no other; a number may be null (no value),
// an integer is an integer, a boolean a boolean, a string a string, an enumeration written as text
// one of its names, a group an object, a list an array of objects (or strings), a fixed array an
// object with a member for each of its indices' names, a map an object of any names whose members
// are all of its kind; a field written .null_when(f), or an optional member, may also be null.
// Each property carries the field's documentation, and its unit ("unit", an annotation). A JSON
// lines file of views (one object per line, its "event" member naming the view) has the schema
// of one line: one of the views' objects.
#pragma once

#include <string>
#include <string_view>
#include <vector>

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

template <class Record>
std::string object_schema_body(const std::string& indent);

// One property: "name": {"type": ..., "description": ..., "unit": ...}; `indent`: a group's
// nested object's lines.
template <class F>
std::string property_schema(const F& f, const std::string& indent = "    ") {
  std::string s;
  append_json_string(s, f.name);
  s += ": {";
  const bool nullable = f.nullable() || kIsOptional<typename F::member_type>;
  const char* nul = nullable ? ", \"null\"]" : "";
  if constexpr (F::kind == Kind::kNumber) {
    s += "\"type\": [\"number\", \"null\"]";
  } else if constexpr (F::kind == Kind::kName) {
    s += "\"enum\": [";
    bool first = true;
    for (const auto& n : f.name_table()) {
      if (!first) s += ", ";
      first = false;
      append_json_string(s, n.name);
    }
    s += nullable ? ", null]" : "]";
  } else if constexpr (F::kind == Kind::kGroup) {
    s += "\"type\": ";
    s += nullable ? "[\"object\", \"null\"]" : "\"object\"";
    s += object_schema_body<value_t<typename F::member_type>>(indent + "  ");
  } else if constexpr (F::kind == Kind::kArray) {
    using E = typename Array<typename F::member_type>::element;
    const char* type = std::is_same_v<E, bool>            ? "\"boolean\""
                       : std::is_floating_point_v<E> ? "[\"number\", \"null\"]"
                                                     : "\"integer\"";
    s += "\"type\": ";
    s += nullable ? "[\"object\", \"null\"]" : "\"object\"";
    s += ", \"properties\": {";
    std::string required;
    for (std::size_t k = 0; k < Array<typename F::member_type>::size; ++k) {
      s += k > 0 ? ",\n" : "\n";
      s += indent + "  ";
      append_json_string(s, f.index[k].name);
      s += ": {\"type\": ";
      s += type;
      s += "}";
      required += k > 0 ? ", " : "";
      append_json_string(required, f.index[k].name);
    }
    s += "}, \"required\": [" + required + "], \"additionalProperties\": false";
  } else if constexpr (F::kind == Kind::kList) {
    using E = typename List<typename F::member_type>::element;
    if constexpr (kIsString<E>) {
      s += "\"type\": \"array\", \"items\": {\"type\": \"string\"}";
    } else {
      s += "\"type\": \"array\", \"items\": {\"type\": \"object\"";
      s += object_schema_body<E>(indent + "  ");
      s += "}";
    }
  } else if constexpr (F::kind == Kind::kMap) {
    using E = typename Map<typename F::member_type>::element;
    s += "\"type\": \"object\", \"additionalProperties\": {";
    if constexpr (Described<E>) {
      s += "\"type\": \"object\"";
      s += object_schema_body<E>(indent + "  ");
    } else {
      s += "\"type\": ";
      s += std::is_same_v<E, bool> ? "\"boolean\"" : std::is_floating_point_v<E> ? "[\"number\", \"null\"]" : "\"integer\"";
    }
    s += "}";
  } else {
    const char* type = F::kind == Kind::kInteger ? "\"integer\"" : F::kind == Kind::kBoolean ? "\"boolean\"" : "\"string\"";
    s += "\"type\": ";
    if (*nul != '\0') s += "[";
    s += type;
    s += nul;
  }
  s += ", \"description\": ";
  append_json_string(s, f.doc);
  if (f.unit[0] != '\0') {
    s += ", \"unit\": ";
    append_json_string(s, f.unit);
  }
  s += '}';
  return s;
}

// ", "properties": {...}, "required": [...], "additionalProperties": false" of `Record`'s
// object, its properties one a line at `indent`.
template <class Record>
std::string object_schema_body(const std::string& indent) {
  std::string s = ", \"properties\": {";
  std::string required;
  bool first = true;
  for_each_field<Record>([&](const auto& f) {
    s += (first ? "\n" : ",\n") + indent;
    first = false;
    s += property_schema(f, indent);
    if (f.optional()) return;
    required += required.empty() ? "" : ", ";
    append_json_string(required, f.name);
  });
  s += "}, \"required\": [" + required + "], \"additionalProperties\": false";
  return s;
}

inline std::string header(std::string_view id, std::string_view title, std::string_view doc) {
  std::string s = "{\n  \"$schema\": \"https://json-schema.org/draft/2020-12/schema\",\n  \"$id\": ";
  append_json_string(s, id);
  s += ",\n  \"title\": ";
  append_json_string(s, title);
  s += ",\n  \"description\": ";
  append_json_string(s, doc);
  return s;
}
}  // namespace detail

/// The schema of `Record`'s JSON object, `id` its $id.
template <Described Record>
[[nodiscard]] std::string json_schema(std::string_view id) {
  using D = Description<Record>;
  std::string s = detail::header(id, D::kName, D::kDoc);
  s += ",\n  \"type\": \"object\",\n  \"properties\": {";
  std::string required;
  bool first = true;
  for_each_field<Record>([&](const auto& f) {
    s += first ? "\n    " : ",\n    ";
    first = false;
    s += detail::property_schema(f);
    if (f.optional()) return;
    required += required.empty() ? "" : ", ";
    detail::append_json_string(required, f.name);
  });
  s += "\n  },\n  \"required\": [" + required + "],\n  \"additionalProperties\": false\n}\n";
  return s;
}

/// The schema of one view's line ({"event":"<view>", its fields}), a member of a JSON lines
/// file's oneOf (json_lines_schema), indented to sit there.
template <Described Record>
[[nodiscard]] std::string json_line_schema(const View& view) {
  std::string s = "    {\n      \"title\": ";
  detail::append_json_string(s, view.name);
  s += ",\n      \"description\": ";
  detail::append_json_string(s, view.doc);
  s += ",\n      \"type\": \"object\",\n      \"properties\": {\n        \"event\": {\"const\": ";
  detail::append_json_string(s, view.name);
  s += "}";
  std::string required = "\"event\"";
  for (const char* name : view.fields)
    with_field<Record>(name, [&](const auto& f) {
      s += ",\n        " + detail::property_schema(f);
      if (f.optional()) return;
      required += ", ";
      detail::append_json_string(required, f.name);
    });
  s += "\n      },\n      \"required\": [" + required + "],\n      \"additionalProperties\": false\n    }";
  return s;
}

/// The schema of a line of a JSON lines file whose lines are views (json_line_schema of each).
[[nodiscard]] inline std::string json_lines_schema(std::string_view id, std::string_view title, std::string_view doc,
                                                   const std::vector<std::string>& line_schemas) {
  std::string s = detail::header(id, title, doc);
  s += ",\n  \"oneOf\": [\n";
  for (std::size_t i = 0; i < line_schemas.size(); ++i) s += line_schemas[i] + (i + 1 < line_schemas.size() ? ",\n" : "\n");
  s += "  ]\n}\n";
  return s;
}

}  // namespace pneu::records
