// The vocabulary a configuration is described with (schema.hpp tells how a description reads):
// the key, its presence, the values it accepts (Range, IntRange, Choices, Flags), and ConfigError,
// the refusal of a bad configuration. A component that owns its parameters (its struct and its
// describe()) includes this, not the root configuration (config.hpp).
#pragma once

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <concepts>
#include <cstdio>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

namespace pneu::config {

/// Bad user configuration: `what()` reads "<key.path>: <reason>".
class ConfigError : public std::runtime_error {
 public:
  ConfigError(std::string key_path, const std::string& reason)
      : std::runtime_error(key_path.empty() ? reason : key_path + ": " + reason),
        key_path_(std::move(key_path)) {}
  [[nodiscard]] const std::string& key_path() const noexcept { return key_path_; }

 private:
  std::string key_path_;
};

}  // namespace pneu::config

namespace pneu::config::schema {

// ---------------------------------------------------------------------------------------------
// The vocabulary

/// A number as the messages quote it: up to 9 significant digits ("0.032", "1e-07").
inline std::string fmt(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

/// Whether a key may be left out of its mapping.
enum class Presence : std::uint8_t {
  kRequired,  ///< left out: refused ("missing")
  kOptional,  ///< left out: the member keeps its default (the struct's initializer)
  kIgnored,   ///< meaningless here: accepted and type-checked when given, not kept, not written
};

/// How to_yaml writes a mapping.
enum class Style : std::uint8_t { kBlock, kFlow };

/// A key of a mapping, and when it may be left out.
struct Key {
  const char* name;
  Presence presence = Presence::kRequired;
  const char* required_because = nullptr;  ///< the reason a conditionally required key is missing
  Style style = Style::kBlock;

  constexpr Key(const char* key_name) : name(key_name) {}  // NOLINT: a key is its name
};

/// A key and the member it fills.
template <class T>
struct Field {
  constexpr Field(Key k, T& member) : key(k), value(member) {}
  Key key;
  T& value;
};

/// The key named as the member it fills, as Drake's DRAKE_NVP: `PNEU_NVP(g, stroke_m)` is the key
/// "stroke_m" of g.stroke_m. (A key named otherwise: `Field("register", c.address)`.)
#define PNEU_NVP(object, member) ::pneu::config::schema::Field(#member, (object).member)

template <class T>
[[nodiscard]] constexpr Field<T> optional(Field<T> f) {
  f.key.presence = Presence::kOptional;
  return f;
}
/// Required when `condition` (left out: refused as "missing: <because>"), optional otherwise.
template <class T>
[[nodiscard]] constexpr Field<T> required_when(bool condition, Field<T> f, const char* because) {
  f.key.presence = condition ? Presence::kRequired : Presence::kOptional;
  f.key.required_because = because;
  return f;
}
/// Accepted and type-checked when given, not kept, not written, unless `condition` (then required).
template <class T>
[[nodiscard]] constexpr Field<T> meaningful_when(bool condition, Field<T> f) {
  f.key.presence = condition ? Presence::kRequired : Presence::kIgnored;
  return f;
}
/// Written as a mapping on one line.
template <class T>
[[nodiscard]] constexpr Field<T> flow(Field<T> f) {
  f.key.style = Style::kFlow;
  return f;
}

/// The values a number accepts (every one finite), and the refusal of the others.
class Range {
 public:
  [[nodiscard]] static constexpr Range any() { return {Kind::kAny, 0.0, 0.0}; }
  [[nodiscard]] static constexpr Range positive() { return {Kind::kPositive, 0.0, 0.0}; }         ///< > 0
  [[nodiscard]] static constexpr Range non_negative() { return {Kind::kNonNegative, 0.0, 0.0}; }  ///< >= 0
  [[nodiscard]] static constexpr Range negative() { return {Kind::kNegative, 0.0, 0.0}; }         ///< < 0
  [[nodiscard]] static constexpr Range non_zero() { return {Kind::kNonZero, 0.0, 0.0}; }          ///< != 0
  /// [lo, hi]
  [[nodiscard]] static constexpr Range closed(double lo, double hi) { return {Kind::kClosed, lo, hi}; }
  /// (lo, hi)
  [[nodiscard]] static constexpr Range open(double lo, double hi) { return {Kind::kOpen, lo, hi}; }
  /// (lo, hi]
  [[nodiscard]] static constexpr Range left_open(double lo, double hi) { return {Kind::kLeftOpen, lo, hi}; }

  [[nodiscard]] constexpr bool contains(double v) const {
    switch (kind_) {
      case Kind::kAny: return true;
      case Kind::kPositive: return v > 0.0;
      case Kind::kNonNegative: return v >= 0.0;
      case Kind::kNegative: return v < 0.0;
      case Kind::kNonZero: return v != 0.0;
      case Kind::kClosed: return v >= lo_ && v <= hi_;
      case Kind::kOpen: return v > lo_ && v < hi_;
      case Kind::kLeftOpen: return v > lo_ && v <= hi_;
    }
    return false;
  }
  /// The range as the documentation states it: "> 0", "in [1, 1.4]"; empty for any().
  [[nodiscard]] std::string text() const {
    switch (kind_) {
      case Kind::kAny: return "";
      case Kind::kPositive: return "> 0";
      case Kind::kNonNegative: return ">= 0";
      case Kind::kNegative: return "< 0";
      case Kind::kNonZero: return "!= 0";
      case Kind::kClosed: return "in [" + fmt(lo_) + ", " + fmt(hi_) + "]";
      case Kind::kOpen: return "in (" + fmt(lo_) + ", " + fmt(hi_) + ")";
      case Kind::kLeftOpen: return "in (" + fmt(lo_) + ", " + fmt(hi_) + "]";
    }
    return "";
  }
  /// "must be > 0 (got -1)"; "must not be 0".
  [[nodiscard]] std::string refusal(double v) const {
    if (kind_ == Kind::kNonZero) return "must not be 0";
    return "must be " + text() + " (got " + fmt(v) + ")";
  }

 private:
  enum class Kind : std::uint8_t { kAny, kPositive, kNonNegative, kNegative, kNonZero, kClosed, kOpen, kLeftOpen };
  constexpr Range(Kind kind, double lo, double hi) : kind_(kind), lo_(lo), hi_(hi) {}
  Kind kind_;
  double lo_, hi_;
};

/// The values an integer accepts, [lo, hi], and the refusal of the others: "must be in [lo, hi]",
/// "must be >= lo", or a text of its own where "{}" stands for the value given.
class IntRange {
 public:
  [[nodiscard]] static constexpr IntRange in(long long lo, long long hi) { return {lo, hi}; }
  [[nodiscard]] static constexpr IntRange at_least(long long lo) {
    return {lo, std::numeric_limits<long long>::max()};
  }
  [[nodiscard]] constexpr IntRange says(const char* refusal) const {
    IntRange r = *this;
    r.says_ = refusal;
    return r;
  }

  [[nodiscard]] constexpr bool contains(long long v) const { return v >= lo_ && v <= hi_; }
  /// ">= 0", "in [1, 247]"
  [[nodiscard]] std::string text() const {
    if (hi_ == std::numeric_limits<long long>::max()) return ">= " + std::to_string(lo_);
    return "in [" + std::to_string(lo_) + ", " + std::to_string(hi_) + "]";
  }
  [[nodiscard]] std::string refusal(long long v) const {
    if (says_ == nullptr) return "must be " + text();
    std::string out = says_;
    if (const auto at = out.find("{}"); at != std::string::npos) out.replace(at, 2, std::to_string(v));
    return out;
  }

 private:
  constexpr IntRange(long long lo, long long hi) : lo_(lo), hi_(hi) {}
  long long lo_, hi_;
  const char* says_ = nullptr;
};

/// One name of an enum-valued key.
template <class E>
struct Choice {
  const char* name;
  E value;
};

/// The names an enum-valued key accepts, and the refusal of the others: "must be 'a', 'b' or 'c'
/// (got 'x')", or "must be a, b or c (got 'x')" unquoted(), or "unknown <noun> 'x' (a, b)".
template <class E>
struct Choices {
  std::span<const Choice<E>> names;
  const char* noun = nullptr;
  bool quoted = true;

  [[nodiscard]] constexpr Choices unquoted() const {
    Choices c = *this;
    c.quoted = false;
    return c;
  }
  [[nodiscard]] constexpr Choices unknown(const char* what) const {
    Choices c = *this;
    c.noun = what;
    return c;
  }
  /// The name of `value` (the first name for a value that has none, which the reader never makes).
  [[nodiscard]] constexpr const char* name_of(E value) const {
    for (const Choice<E>& c : names)
      if (c.value == value) return c.name;
    return names.front().name;
  }
  [[nodiscard]] std::string refusal(const std::string& given) const {
    if (noun != nullptr) return "unknown " + std::string(noun) + " '" + given + "' (" + listed(", ", ", ") + ")";
    return "must be " + listed(", ", " or ") + " (got '" + given + "')";
  }
  /// "'a', 'b' or 'c'" (`last` before the last name).
  [[nodiscard]] std::string listed(const char* between, const char* last) const {
    std::string text;
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (i > 0) text += i + 1 == names.size() ? last : between;
      text += quoted && noun == nullptr ? "'" + std::string(names[i].name) + "'" : names[i].name;
    }
    return text;
  }
};

template <class E, std::size_t N>
[[nodiscard]] constexpr Choices<E> one_of(const Choice<E> (&names)[N]) {
  return {std::span<const Choice<E>>(names)};
}

/// One name of a list of names: present, it sets `member` of the owner.
template <class S>
struct Flag {
  const char* name;
  bool S::* member;
};

/// The names a list of names may hold ("unknown <noun> 'x' (a, b)" for any other).
template <class S>
struct Flags {
  std::span<const Flag<S>> names;
  const char* noun;

  /// "a, b"
  [[nodiscard]] std::string listed() const {
    std::string text;
    for (const Flag<S>& f : names) text += (text.empty() ? "" : ", ") + std::string(f.name);
    return text;
  }
};

template <class S, std::size_t N>
[[nodiscard]] constexpr Flags<S> any_of(const Flag<S> (&names)[N], const char* noun) {
  return {std::span<const Flag<S>>(names), noun};
}

/// `T` or `const T`: a description serves the reader (mutable) and the other archives (const).
template <class T, class U>
concept Like = std::same_as<std::remove_const_t<T>, U>;

// ---------------------------------------------------------------------------------------------
// Messages shared by several rules

/// "must lie inside the stroke [-0.25, 0.25] m (got 0.3)"
inline std::string outside_the_stroke(double half_stroke_m, double v) {
  return "must lie inside the stroke [" + fmt(-half_stroke_m) + ", " + fmt(half_stroke_m) + "] m (got " + fmt(v) +
         ")";
}

}  // namespace pneu::config::schema
