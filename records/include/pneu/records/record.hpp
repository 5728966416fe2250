// A record type described once. A record is a plain struct (the tick, an event, a forecast, ...);
// its description names the fields the outside world sees, in order, each once:
//
//   template <> struct pneu::records::Description<TickRecord> {
//     static constexpr const char* kName = "tick";
//     static constexpr const char* kDoc = "one tick of the loop";
//     static constexpr auto kFields = std::tuple{
//         field("seq", &TickRecord::seq, "", "tick sequence number, from 0 at start-up, no gaps"),
//         field("t", &TickRecord::t_s, "s", "loop time of the sample since start-up", 12),
//         ...};
//   };
//
// The field's name is its one spelling: the CSV column, the JSON key and the LCM field. Its type
// follows from the member's: a floating-point number, an integer (unsigned ones and enumerations
// travel as the signed integer of their size, as LCM has no other, or as the type `.as<T>()`
// says), a boolean, or a string (std::string, std::string_view, const char*). A field may read a
// member of a member (field("method", &R::prediction, &Prediction::method, ...)). Further, each
// said by one call on the field:
//   .named(table)    an enumeration written as text: each value's name and its number on the wire
//                    (LCM's constants NAME_VALUE); CSV writes both (columns NAME and NAME_name)
//   .when(f)         in JSON only when f(record) holds (an optional member: not required)
//   .null_when(f)    in JSON null when f(record) holds ("no value" for a field of any kind)
//   .fixed(n)        a number in CSV with n decimals (printf's %.nf), not significant digits
//   .nan_as_text()   NaN in CSV as printf writes it (nan), not as an empty cell: a file that
//                    always did so keeps doing it
// A member of type std::optional<T> is a T that may have no value (an empty CSV cell, JSON's
// null). A member that is itself a described record, or an optional one, is a group
// (group("lin", &R::lin, "lin_", doc)): its fields are columns of their own in CSV, each named
// with the group's prefix (empty cells when it has no value), a nested object in JSON. A
// std::vector of described records is a list: an array of objects in JSON (not in CSV), and one of
// strings an array of strings; a std::vector of (std::string, T) pairs, T a described record or
// a number, an integer or a bool, is a map: an object in JSON keyed by the pairs' names, in their
// order (not in CSV). A member of type std::array<T, N> (T a number, an integer or a bool) is a
// fixed array indexed by a table of N names (.indexed(table, suffix)): an array of N in LCM (the
// table's constants its indices), an object keyed by the names in JSON, a column a name in CSV
// (NAME followed by the field's suffix); the fixed arrays indexed by one table are written
// together in CSV, at the first one's place, element by element (NAME,NAME_sigma,... for each
// name in turn).
// Everything else derives from the description (csv.hpp, json.hpp, schema.hpp, lcm.hpp): a new
// field is one line. A view (View) is a named selection of a record's fields in an order of its
// own: one kind of line in a JSON lines file ({"event":"stop",...}).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

namespace pneu::records {

/// The description of `Record`: specialise it beside the record (see above).
template <class Record>
struct Description;

/// Whether `Record` has a description.
template <class Record>
concept Described = requires {
  Description<Record>::kName;
  Description<Record>::kDoc;
  Description<Record>::kFields;
};

/// What a value is, whatever the format. kName: an enumeration written as its name; kGroup: a
/// described record within a record; kList: a list of them or of strings (JSON only); kArray: a
/// fixed array indexed by a table of names; kMap: named values or records (JSON only).
enum class Kind : std::uint8_t { kNumber, kInteger, kBoolean, kString, kName, kGroup, kList, kArray, kMap };

template <class T>
inline constexpr bool kIsString =
    std::is_same_v<T, std::string> || std::is_same_v<T, std::string_view> || std::is_same_v<T, const char*>;

/// std::optional<T>: a T that may have no value.
template <class T>
struct Optional : std::false_type {
  using type = T;
};
template <class T>
struct Optional<std::optional<T>> : std::true_type {
  using type = T;
};
template <class T>
inline constexpr bool kIsOptional = Optional<T>::value;
/// T, or what an optional T holds.
template <class T>
using value_t = typename Optional<T>::type;

/// std::vector<T> of a described record T: a list (JSON's array of objects).
template <class T>
struct List : std::false_type {};
template <class T>
struct List<std::vector<T>> : std::true_type {
  using element = T;
};

/// std::array<T, N>: a fixed array (its elements numbers, integers or booleans).
template <class T>
struct Array : std::false_type {};
template <class T, std::size_t N>
struct Array<std::array<T, N>> : std::true_type {
  using element = T;
  static constexpr std::size_t size = N;
};

/// One index of a fixed array: its name (its CSV columns' and its JSON key) and the name of the
/// LCM constant that is its index (nullptr: none).
struct IndexName {
  const char* name;
  const char* constant = nullptr;
};

/// The last part of a dotted key ("plant.valve.null_offset_v": "null_offset_v"), in the key's text.
constexpr const char* last_part(const char* key) {
  const char* part = key;
  for (const char* c = key; *c != '\0'; ++c)
    if (*c == '.') part = c + 1;
  return part;
}

/// std::vector<std::pair<std::string, T>>: a map (JSON's object keyed by the names, in order).
template <class T>
struct Map : std::false_type {};
template <class T>
struct Map<std::vector<std::pair<std::string, T>>> : std::true_type {
  using element = T;
};

/// The kind of a member of type T (an optional's: its value's).
template <class T>
constexpr Kind kind_of() {
  if constexpr (kIsOptional<T>) return kind_of<value_t<T>>();
  else if constexpr (Map<T>::value) {
    static_assert(Described<typename Map<T>::element> || std::is_arithmetic_v<typename Map<T>::element>,
                  "a map holds described records, or numbers, integers or booleans");
    return Kind::kMap;
  }
  else if constexpr (List<T>::value) {
    static_assert(Described<typename List<T>::element> || kIsString<typename List<T>::element>,
                  "a list holds described records or strings");
    return Kind::kList;
  }
  else if constexpr (Array<T>::value) {
    static_assert(std::is_arithmetic_v<typename Array<T>::element>, "a fixed array holds numbers, integers or booleans");
    return Kind::kArray;
  }
  else if constexpr (Described<T>) return Kind::kGroup;
  else if constexpr (std::is_same_v<T, bool>) return Kind::kBoolean;
  else if constexpr (std::is_floating_point_v<T>) return Kind::kNumber;
  else if constexpr (kIsString<T>) return Kind::kString;
  else {
    static_assert(std::is_integral_v<T> || std::is_enum_v<T>, "a record field is a number, an integer, a bool or a string");
    return Kind::kInteger;
  }
}

/// The signed integer a member of type T travels as (its size; an enumeration's underlying type's).
template <class T>
using wire_integer_t = std::conditional_t<
    sizeof(T) == 1, std::int8_t,
    std::conditional_t<sizeof(T) == 2, std::int16_t, std::conditional_t<sizeof(T) == 4, std::int32_t, std::int64_t>>>;

/// The type a member of type T travels as by default (LCM's; the text formats write its value; a
/// fixed array's: its elements').
template <class T>
struct DefaultWire {
  using type = std::conditional_t<
      kIsOptional<T> || Described<T> || List<T>::value, T,
      std::conditional_t<kIsString<T>, std::string,
                         std::conditional_t<std::is_same_v<T, bool> || std::is_floating_point_v<T>, T, wire_integer_t<T>>>>;
};
template <class T, std::size_t N>
struct DefaultWire<std::array<T, N>> {
  using type = typename DefaultWire<T>::type;
};
template <class T>
using default_wire_t = typename DefaultWire<T>::type;

/// One value of an enumeration written as text: the value, its number on the wire, its name.
template <class T>
struct Named {
  T value;
  std::int64_t wire;
  const char* name;
};

/// Where a field reads its value: a member, or a member of a member.
template <class Record, class Member>
struct MemberPath {
  Member Record::*member;
  [[nodiscard]] constexpr const Member& of(const Record& r) const { return r.*member; }
  [[nodiscard]] constexpr Member& of(Record& r) const { return r.*member; }
};
template <class Record, class Inner, class Member>
struct NestedPath {
  Inner Record::*outer;
  Member Inner::*member;
  [[nodiscard]] constexpr const Member& of(const Record& r) const { return (r.*outer).*member; }
  [[nodiscard]] constexpr Member& of(Record& r) const { return (r.*outer).*member; }
};

/// One field of a record: its one spelling, where it reads its value, its unit, its documentation
/// and the significant digits a number is written with in text (CSV, JSON); what it travels as
/// (Wire), whether it is an enumeration written as text (its names), when JSON writes it, when
/// JSON writes null.
template <class Record, class Member, class Path, class Wire = default_wire_t<Member>, bool IsNamed = false>
struct Field {
  using record_type = Record;
  using member_type = Member;
  using wire_type = Wire;
  const char* name;
  Path path;
  const char* unit;  ///< SI unit, "" when it has none
  const char* doc;
  int digits;        ///< significant digits in text (numbers only)
  const Named<Member>* names = nullptr;  ///< IsNamed: the values' names and wire numbers
  std::size_t name_count = 0;
  bool (*present)(const Record&) = nullptr;  ///< JSON writes it only when this holds (nullptr: always)
  bool (*absent)(const Record&) = nullptr;   ///< JSON writes null when this holds (nullptr: never)
  int fixed_decimals = -1;  ///< >= 0: a number in CSV with this many decimals (%.nf)
  bool nan_text = false;    ///< NaN in CSV as printf writes it (nan)
  const char* prefix = "";  ///< a group: its columns' prefix in CSV
  const IndexName* index = nullptr;  ///< a fixed array: its indices' names, in order
  const char* index_suffix = "";     ///< a fixed array: its CSV columns are NAME<index_suffix>

  static constexpr Kind kind = IsNamed ? Kind::kName : kind_of<Member>();
  [[nodiscard]] constexpr const Member& of(const Record& r) const { return path.of(r); }
  [[nodiscard]] constexpr Member& of(Record& r) const { return path.of(r); }

  /// An enumeration written as text: `table` names each value and its number on the wire.
  template <std::size_t N>
  [[nodiscard]] constexpr Field<Record, Member, Path, Wire, true> named(const Named<Member> (&table)[N]) const {
    return {name, path, unit, doc, digits, table, N, present, absent, fixed_decimals, nan_text, prefix, index, index_suffix};
  }
  /// Travels as `W` (LCM's type, the integer the text formats write).
  template <class W>
  [[nodiscard]] constexpr Field<Record, Member, Path, W, IsNamed> as() const {
    return {name, path, unit, doc, digits, names, name_count, present, absent, fixed_decimals, nan_text, prefix, index,
            index_suffix};
  }
  /// In JSON only when `f(record)` holds.
  [[nodiscard]] constexpr Field when(bool (*f)(const Record&)) const {
    Field g = *this;
    g.present = f;
    return g;
  }
  /// In JSON null when `f(record)` holds.
  [[nodiscard]] constexpr Field null_when(bool (*f)(const Record&)) const {
    Field g = *this;
    g.absent = f;
    return g;
  }

  /// A fixed array indexed by `table` (a name an element, in order); its CSV columns NAME<suffix>.
  template <std::size_t N>
  [[nodiscard]] constexpr Field indexed(const std::array<IndexName, N>& table, const char* suffix) const {
    static_assert(Array<Member>::value && Array<Member>::size == N, "a fixed array has a name for each element");
    Field g = *this;
    g.index = table.data();
    g.index_suffix = suffix;
    return g;
  }

  /// In CSV with `n` decimals.
  [[nodiscard]] constexpr Field fixed(int n) const {
    Field g = *this;
    g.fixed_decimals = n;
    return g;
  }
  /// NaN in CSV as printf writes it.
  [[nodiscard]] constexpr Field nan_as_text() const {
    Field g = *this;
    g.nan_text = true;
    return g;
  }

  [[nodiscard]] constexpr std::span<const Named<Member>> name_table() const { return {names, name_count}; }
  /// The name of `v` ("unknown" when the table has none).
  [[nodiscard]] constexpr const char* name_of(const Member& v) const {
    for (const auto& n : name_table())
      if (n.value == v) return n.name;
    return "unknown";
  }
  /// The name of the wire number `w` ("unknown" when the table has none).
  [[nodiscard]] constexpr const char* name_of_wire(std::int64_t w) const {
    for (const auto& n : name_table())
      if (n.wire == w) return n.name;
    return "unknown";
  }
  /// The wire number of `v` (0 when the table has none).
  [[nodiscard]] constexpr std::int64_t wire_of(const Member& v) const {
    for (const auto& n : name_table())
      if (n.value == v) return n.wire;
    return 0;
  }
  /// Whether JSON writes it for `r`; whether it may be left out of an object (not required).
  [[nodiscard]] constexpr bool written(const Record& r) const { return present == nullptr || present(r); }
  [[nodiscard]] constexpr bool optional() const { return present != nullptr; }
  [[nodiscard]] constexpr bool null_for(const Record& r) const { return absent != nullptr && absent(r); }
  [[nodiscard]] constexpr bool nullable() const { return absent != nullptr; }
};

/// A field: `name`, the member, its unit ("" for none), its documentation, and the significant
/// digits of a number written as text (9 unless said).
template <class Record, class Member>
constexpr Field<Record, Member, MemberPath<Record, Member>> field(const char* name, Member Record::*member,
                                                                  const char* unit, const char* doc, int digits = 9) {
  return {name, {member}, unit, doc, digits};
}

/// A field read from a member of a member: `record.*outer.*member`.
template <class Record, class Inner, class Member>
constexpr Field<Record, Member, NestedPath<Record, Inner, Member>> field(const char* name, Inner Record::*outer,
                                                                         Member Inner::*member, const char* unit,
                                                                         const char* doc, int digits = 9) {
  return {name, {outer, member}, unit, doc, digits};
}

/// A group: the described record (or optional one) `member`, its CSV columns prefixed `prefix`.
template <class Record, class Member>
constexpr Field<Record, Member, MemberPath<Record, Member>> group(const char* name, Member Record::*member,
                                                                  const char* prefix, const char* doc) {
  static_assert(kind_of<Member>() == Kind::kGroup, "a group is a described record, or an optional one");
  Field<Record, Member, MemberPath<Record, Member>> f{name, {member}, "", doc, 9};
  f.prefix = prefix;
  return f;
}

/// The number of fields of `Record`.
template <Described Record>
inline constexpr std::size_t kFieldCount = std::tuple_size_v<std::remove_cvref_t<decltype(Description<Record>::kFields)>>;

/// Calls f(field) for each field of `Record`, in order.
template <Described Record, class F>
constexpr void for_each_field(F&& f) {
  std::apply([&](const auto&... fields) { (f(fields), ...); }, Description<Record>::kFields);
}

/// Calls f(field, std::integral_constant<std::size_t, I>{}) for each field of `Record`, in order, I
/// its position.
template <Described Record, class F>
constexpr void for_each_field_at(F&& f) {
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (f(std::get<I>(Description<Record>::kFields), std::integral_constant<std::size_t, I>{}), ...);
  }(std::make_index_sequence<kFieldCount<Record>>{});
}

/// Calls f(field) for the field of `Record` named `name`; false when it has none.
template <Described Record, class F>
constexpr bool with_field(std::string_view name, F&& f) {
  bool found = false;
  for_each_field<Record>([&](const auto& field) {
    if (!found && name == std::string_view(field.name)) {
      found = true;
      f(field);
    }
  });
  return found;
}

/// Whether `f` is the first of `Record`'s fixed arrays indexed by its table: the one at whose
/// place CSV writes the columns of all of them.
template <Described Record, class F>
constexpr bool leads_its_index(const F& f) {
  bool seen = false, leads = false;
  for_each_field<Record>([&](const auto& g) {
    if constexpr (std::remove_cvref_t<decltype(g)>::kind == Kind::kArray) {
      if (!seen && g.index == f.index) {
        seen = true;
        leads = std::string_view(g.name) == f.name;
      }
    }
  });
  return leads;
}

/// Calls f(field) for each of `Record`'s fixed arrays indexed by `index`, in order.
template <Described Record, class F>
constexpr void for_each_indexed_by(const IndexName* index, F&& f) {
  for_each_field<Record>([&](const auto& g) {
    if constexpr (std::remove_cvref_t<decltype(g)>::kind == Kind::kArray) {
      if (g.index == index) f(g);
    }
  });
}

/// A named selection of a record's fields, in an order of its own: one kind of line of a JSON
/// lines file, whose "event" member is the view's name (JSON lines, schema.hpp).
struct View {
  const char* name;
  const char* doc;
  std::span<const char* const> fields;
};

/// Whether every name of `view` is a field of `Record` (for a static_assert beside the view).
template <Described Record>
constexpr bool names_fields_of(const View& view) {
  for (const char* n : view.fields)
    if (!with_field<Record>(n, [](const auto&) {})) return false;
  return true;
}

}  // namespace pneu::records
