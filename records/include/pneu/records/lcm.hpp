// A record as an LCM message. The message's definition (.lcm text) is written from the record's
// description at build time (pneu-records, tools/records/), lcm-gen makes the C++ type from it, and
// pneu-records also writes which of that type's members each field is (LcmMembers<Message>, in the
// description's order): to_lcm and from_lcm convert field by field (a group of fields of one type
// travels as an array, element k its field k). A field added to the
// description is in the message, the conversion and every decoder lcm-gen writes.
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <string_view>
#include <tuple>
#include <type_traits>

#include "pneu/records/csv.hpp"
#include "pneu/records/record.hpp"

namespace pneu::records {

/// The LCM type a member of type T travels as.
template <class T>
constexpr const char* lcm_type_name() {
  if constexpr (kIsString<T>) return "string";
  else if constexpr (kind_of<T>() == Kind::kBoolean) return "boolean";
  else if constexpr (std::is_same_v<T, float>) return "float";
  else if constexpr (kind_of<T>() == Kind::kNumber) return "double";
  else if constexpr (sizeof(T) == 1) return "int8_t";
  else if constexpr (sizeof(T) == 2) return "int16_t";
  else if constexpr (sizeof(T) == 4) return "int32_t";
  else return "int64_t";
}

/// The field declarations of `Record` in an LCM struct: one line each, its documentation (and
/// unit) as the comment, names aligned.
template <Described Record>
[[nodiscard]] std::string lcm_field_declarations() {
  std::string out;
  for_each_field<Record>([&](const auto& f) {
    using F = std::remove_cvref_t<decltype(f)>;
    std::string decl = "  ";
    std::string dimension;
    if constexpr (F::kind == Kind::kGroup) {  // an array of its fields, all of one type
      using G = typename F::member_type;
      using W = typename std::remove_cvref_t<decltype(std::get<0>(Description<G>::kFields))>::wire_type;
      decl += lcm_type_name<W>();
      dimension = "[" + std::to_string(kFieldCount<G>) + "]";
    } else if constexpr (F::kind == Kind::kArray) {  // an array of its elements
      decl += lcm_type_name<typename F::wire_type>();
      dimension = "[" + std::to_string(Array<typename F::member_type>::size) + "]";
    } else {
      decl += lcm_type_name<typename F::wire_type>();
    }
    decl.resize(std::max<std::size_t>(decl.size() + 1, 10), ' ');
    decl += f.name;
    decl += dimension;
    decl += ';';
    decl.resize(std::max<std::size_t>(decl.size() + 1, 22), ' ');
    out += decl + "// " + f.doc;
    if (f.unit[0] != '\0') out += std::string(" [") + f.unit + "]";
    out += '\n';
  });
  return out;
}

/// The constants of `Record`'s enumerations written as text (.named): for a field `kind` whose
/// table names `start` 1, `const int8_t KIND_START = 1, ...;`, one declaration a field; and the
/// indices of its fixed arrays whose tables name constants (`const int8_t NAME = 0, ...;`, one
/// declaration a table).
template <Described Record>
[[nodiscard]] std::string lcm_named_constants() {
  std::string out;
  for_each_field<Record>([&](const auto& f) {
    using F = std::remove_cvref_t<decltype(f)>;
    if constexpr (F::kind == Kind::kArray) {
      constexpr std::size_t n = Array<typename F::member_type>::size;
      if (!leads_its_index<Record>(f) || f.index[0].constant == nullptr) return;
      out += n <= 128 ? "  const int8_t " : "  const int32_t ";
      for (std::size_t k = 0; k < n; ++k) {
        if (k > 0) out += ", ";
        out += std::string(f.index[k].constant) + " = " + std::to_string(k);
      }
      out += ";\n";
    } else if constexpr (F::kind == Kind::kName) {
      out += std::string("  const ") + lcm_type_name<typename F::wire_type>() + " ";
      bool first = true;
      for (const auto& n : f.name_table()) {
        if (!first) out += ", ";
        first = false;
        for (const char* c = f.name; *c != '\0'; ++c) out += static_cast<char>(*c >= 'a' && *c <= 'z' ? *c - 'a' + 'A' : *c);
        out += '_';
        for (const char* c = n.name; *c != '\0'; ++c) out += static_cast<char>(*c >= 'a' && *c <= 'z' ? *c - 'a' + 'A' : *c);
        out += " = " + std::to_string(n.wire);
      }
      out += ";\n";
    }
  });
  return out;
}

/// The .lcm definition of `message` in `package` carrying `Record`'s fields: a comment saying where
/// it comes from, `doc` as the struct's comment, the `transport` declarations first (utime: lines
/// as in a .lcm file), the fields, then the `constants` declarations and those of the fields
/// written as text (lcm_named_constants).
template <Described Record>
[[nodiscard]] std::string lcm_message_text(std::string_view package, std::string_view message, std::string_view doc,
                                           std::string_view source, std::string_view transport,
                                           std::string_view constants) {
  std::string out = "// Written by pneu-records from the description of the record `";
  out += Description<Record>::kName;
  out += "` (";
  out += source;
  out += "): edit that, not this file.\npackage ";
  out += package;
  out += ";\n\n// ";
  out += doc;
  out += "\nstruct ";
  out += message;
  out += "\n{\n";
  out += transport;
  out += lcm_field_declarations<Record>();
  const std::string all_constants = std::string(constants) + lcm_named_constants<Record>();
  if (!all_constants.empty()) {
    out += '\n';
    out += all_constants;
  }
  out += "}\n";
  return out;
}

/// The members of the lcm-gen'd `Message` that carry a record's fields, in the description's
/// order: `static constexpr auto kMembers = std::tuple{&Message::a, ...};` (written by
/// pneu-records beside the message's header).
template <class Message>
struct LcmMembers;

/// The C++ header declaring LcmMembers<package::message> for `Record`'s fields: what pneu-records
/// writes beside lcm-gen's header of the message (package/message.hpp).
template <Described Record>
[[nodiscard]] std::string lcm_members_header(std::string_view package, std::string_view message_name) {
  const std::string message = std::string(package) + "::" + std::string(message_name);
  std::string out = "// Written by pneu-records: the members of " + message +
                    " that carry the fields of the record `" + Description<Record>::kName +
                    "`, in order.\n#pragma once\n\n#include <tuple>\n\n#include \"pneu/records/lcm.hpp\"\n#include \"" +
                    std::string(package) + "/" + std::string(message_name) + ".hpp\"\n\n" +
                    "template <>\nstruct pneu::records::LcmMembers<" + message +
                    "> {\n  static constexpr auto kMembers = std::tuple{";
  bool first = true;
  for_each_field<Record>([&](const auto& f) {
    out += first ? "\n      " : ",\n      ";
    first = false;
    out += "&" + std::string(message) + "::" + f.name;
  });
  out += "};\n};\n";
  return out;
}

/// Fills the members of `m` that carry `r`'s fields.
template <Described Record, class Message>
void to_lcm(const Record& r, Message& m) {
  constexpr auto& members = LcmMembers<Message>::kMembers;
  static_assert(std::tuple_size_v<std::remove_cvref_t<decltype(members)>> == kFieldCount<Record>,
                "the message was not generated from this record's description");
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (([&] {
       const auto& f = std::get<I>(Description<Record>::kFields);
       using F = std::remove_cvref_t<decltype(f)>;
       auto& to = m.*std::get<I>(members);
       using T = std::remove_cvref_t<decltype(to)>;
       if constexpr (F::kind == Kind::kGroup) {  // an array: element k, field k
         using G = typename F::member_type;
         std::size_t k = 0;
         for_each_field<G>([&](const auto& g) { to[k++] = static_cast<std::remove_cvref_t<decltype(to[0])>>(g.of(f.of(r))); });
       } else if constexpr (F::kind == Kind::kArray) {  // element k, element k
         for (std::size_t k = 0; k < f.of(r).size(); ++k) to[k] = static_cast<std::remove_cvref_t<decltype(to[0])>>(f.of(r)[k]);
       } else if constexpr (F::kind == Kind::kName) to = static_cast<T>(f.wire_of(f.of(r)));
       else if constexpr (F::kind == Kind::kString) {
         if constexpr (std::is_same_v<typename F::member_type, const char*>) to = f.of(r) == nullptr ? "" : f.of(r);
         else to = T(f.of(r));
       } else to = static_cast<T>(f.of(r));
     }()),
     ...);
  }(std::make_index_sequence<kFieldCount<Record>>{});
}

/// Reads `r`'s fields from `m` (the record's other members are left as they are).
template <Described Record, class Message>
void from_lcm(const Message& m, Record& r) {
  constexpr auto& members = LcmMembers<Message>::kMembers;
  static_assert(std::tuple_size_v<std::remove_cvref_t<decltype(members)>> == kFieldCount<Record>,
                "the message was not generated from this record's description");
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (([&] {
       const auto& f = std::get<I>(Description<Record>::kFields);
       using F = std::remove_cvref_t<decltype(f)>;
       using M = typename F::member_type;
       const auto& v = m.*std::get<I>(members);
       if constexpr (F::kind == Kind::kGroup) {
         using G = typename F::member_type;
         std::size_t k = 0;
         for_each_field<G>([&](const auto& g) {
           g.of(f.of(r)) = static_cast<typename std::remove_cvref_t<decltype(g)>::member_type>(v[k++]);
         });
       } else if constexpr (F::kind == Kind::kArray) {
         for (std::size_t k = 0; k < f.of(r).size(); ++k)
           f.of(r)[k] = static_cast<typename Array<M>::element>(v[k]);
       } else if constexpr (F::kind == Kind::kName) {
         for (const auto& n : f.name_table())
           if (n.wire == static_cast<std::int64_t>(v)) f.of(r) = n.value;
       } else if constexpr (F::kind == Kind::kString) {
         if constexpr (std::is_same_v<M, std::string>) f.of(r) = v;  // a borrowed string cannot be filled
       } else if constexpr (std::is_same_v<M, bool>) f.of(r) = v != 0;
       else f.of(r) = static_cast<M>(v);
     }()),
     ...);
  }(std::make_index_sequence<kFieldCount<Record>>{});
}

/// Writes the cells of the record `Record` carried by `m` as the record's CSV (csv.hpp), from the
/// message's values as they came (an enumeration's number the table does not know is written,
/// its name "unknown"); `digits`: of every number (0: each field's own).
template <Described Record, class Message, class Out>
void write_lcm_csv_cells(Out& out, const Message& m, bool leading_comma = false, int digits = 0) {
  constexpr auto& members = LcmMembers<Message>::kMembers;
  static_assert(std::tuple_size_v<std::remove_cvref_t<decltype(members)>> == kFieldCount<Record>,
                "the message was not generated from this record's description");
  bool comma = leading_comma;
  for_each_field_at<Record>([&](const auto& f, [[maybe_unused]] auto i) {
    using F = std::remove_cvref_t<decltype(f)>;
    if constexpr (F::kind == Kind::kArray) {  // the arrays of its index, element by element
      if (!leads_its_index<Record>(f)) return;
      for (std::size_t k = 0; k < Array<typename F::member_type>::size; ++k)
        for_each_field_at<Record>([&](const auto& g, [[maybe_unused]] auto j) {
          if constexpr (std::remove_cvref_t<decltype(g)>::kind == Kind::kArray) {
            if (g.index != f.index) return;
            if (comma) put(out, ',');
            comma = true;
            write_csv_element(out, g, (m.*std::get<decltype(j)::value>(members))[k], digits);
          }
        });
      return;
    }
    if (comma) put(out, ',');
    comma = true;
    if constexpr (F::kind == Kind::kGroup) {  // an array: element k, field k
      const auto& a = m.*std::get<decltype(i)::value>(members);
      std::size_t k = 0;
      for_each_field<typename F::member_type>([&](const auto& g) {
        if (k > 0) put(out, ',');
        write_csv_wire_value(out, g, a[k++], digits);
      });
    } else {
      write_csv_wire_value(out, f, m.*std::get<decltype(i)::value>(members), digits);
    }
  });
}

}  // namespace pneu::records
