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
// travel as the signed integer of their size, as LCM has no other), or a boolean. Everything else
// derives from the description (csv.hpp, json.hpp, schema.hpp, lcm.hpp): a new field is one line.
#pragma once

#include <cstddef>
#include <cstdint>
#include <tuple>
#include <type_traits>
#include <utility>

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

/// What a value is, whatever the format.
enum class Kind : std::uint8_t { kNumber, kInteger, kBoolean };

/// The kind of a member of type T.
template <class T>
constexpr Kind kind_of() {
  if constexpr (std::is_same_v<T, bool>) return Kind::kBoolean;
  else if constexpr (std::is_floating_point_v<T>) return Kind::kNumber;
  else {
    static_assert(std::is_integral_v<T> || std::is_enum_v<T>, "a record field is a number, an integer or a bool");
    return Kind::kInteger;
  }
}

/// The signed integer a member of type T travels as (its size; an enumeration's underlying type's).
template <class T>
using wire_integer_t = std::conditional_t<
    sizeof(T) == 1, std::int8_t,
    std::conditional_t<sizeof(T) == 2, std::int16_t, std::conditional_t<sizeof(T) == 4, std::int32_t, std::int64_t>>>;

/// One field of a record: its one spelling, the member it reads, its unit, its documentation and
/// the significant digits a number is written with in text (CSV, JSON).
template <class Record, class Member>
struct Field {
  using record_type = Record;
  using member_type = Member;
  const char* name;
  Member Record::*member;
  const char* unit;  ///< SI unit, "" when it has none
  const char* doc;
  int digits;        ///< significant digits in text (numbers only)

  static constexpr Kind kind = kind_of<Member>();
  [[nodiscard]] constexpr const Member& of(const Record& r) const { return r.*member; }
  [[nodiscard]] constexpr Member& of(Record& r) const { return r.*member; }
};

/// A field: `name`, the member, its unit ("" for none), its documentation, and the significant
/// digits of a number written as text (9 unless said).
template <class Record, class Member>
constexpr Field<Record, Member> field(const char* name, Member Record::*member, const char* unit, const char* doc,
                                      int digits = 9) {
  return {name, member, unit, doc, digits};
}

/// The number of fields of `Record`.
template <Described Record>
inline constexpr std::size_t kFieldCount = std::tuple_size_v<std::remove_cvref_t<decltype(Description<Record>::kFields)>>;

/// Calls f(field) for each field of `Record`, in order.
template <Described Record, class F>
constexpr void for_each_field(F&& f) {
  std::apply([&](const auto&... fields) { (f(fields), ...); }, Description<Record>::kFields);
}

}  // namespace pneu::records
