// Test support: a strict reader of JSON (RFC 8259), for what pneud writes as JSON
// (--summary-json). A document that is not valid JSON throws, naming the offset.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace pneu::test {

class Json {
 public:
  enum class Type { kNull, kBool, kNumber, kString, kArray, kObject };

  /// Throws std::runtime_error on anything but one JSON value (surrounded by white space).
  static Json parse(std::string_view text) {
    Parser p{text};
    Json v = p.value();
    p.space();
    if (p.at < text.size()) p.fail("text after the value");
    return v;
  }
  static Json read(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error(path.string() + ": cannot read");
    std::stringstream ss;
    ss << in.rdbuf();
    return parse(ss.str());
  }

  [[nodiscard]] Type type() const noexcept { return type_; }
  [[nodiscard]] bool is_null() const noexcept { return type_ == Type::kNull; }
  [[nodiscard]] bool has(std::string_view key) const { return find(key) != nullptr; }
  /// The member `key` of an object (throws when it is none).
  [[nodiscard]] const Json& operator[](std::string_view key) const {
    const Json* v = find(key);
    if (!v) throw std::runtime_error("no member \"" + std::string(key) + "\"");
    return *v;
  }
  [[nodiscard]] const std::vector<Json>& elements() const { return expect(Type::kArray).elements_; }
  [[nodiscard]] double number() const { return expect(Type::kNumber).number_; }
  /// A number that is a count: a whole number, not negative.
  [[nodiscard]] std::uint64_t count() const {
    const double v = number();
    if (v < 0 || v != static_cast<double>(static_cast<std::uint64_t>(v))) throw std::runtime_error("not a count");
    return static_cast<std::uint64_t>(v);
  }
  [[nodiscard]] bool flag() const { return expect(Type::kBool).flag_; }
  [[nodiscard]] const std::string& text() const { return expect(Type::kString).text_; }

 private:
  const Json* find(std::string_view key) const {
    for (const auto& [name, v] : expect(Type::kObject).members_)
      if (name == key) return &v;
    return nullptr;
  }
  const Json& expect(Type t) const {
    if (type_ != t) throw std::runtime_error("a JSON value of another type");
    return *this;
  }

  struct Parser {
    std::string_view s;
    std::size_t at = 0;

    [[noreturn]] void fail(const std::string& what) const {
      throw std::runtime_error("not JSON at offset " + std::to_string(at) + ": " + what);
    }
    void space() {
      while (at < s.size() && (s[at] == ' ' || s[at] == '\t' || s[at] == '\n' || s[at] == '\r')) ++at;
    }
    bool take(char c) {
      space();
      if (at < s.size() && s[at] == c) return ++at, true;
      return false;
    }
    void word(std::string_view w) {
      if (s.substr(at, w.size()) != w) fail("expected " + std::string(w));
      at += w.size();
    }
    Json value() {
      space();
      if (at >= s.size()) fail("a value expected");
      Json v;
      switch (s[at]) {
        case '{':
          ++at;
          v.type_ = Type::kObject;
          if (take('}')) return v;
          do {
            space();
            if (at >= s.size() || s[at] != '"') fail("a member's name expected");
            std::string key = string();
            if (!take(':')) fail("':' expected");
            if (v.has(key)) fail("a member named twice");
            Json member = value();
            v.members_.emplace_back(std::move(key), std::move(member));
          } while (take(','));
          if (!take('}')) fail("'}' expected");
          return v;
        case '[':
          ++at;
          v.type_ = Type::kArray;
          if (take(']')) return v;
          do v.elements_.push_back(value());
          while (take(','));
          if (!take(']')) fail("']' expected");
          return v;
        case '"':
          v.type_ = Type::kString;
          v.text_ = string();
          return v;
        case 't': word("true"); v.type_ = Type::kBool; v.flag_ = true; return v;
        case 'f': word("false"); v.type_ = Type::kBool; return v;
        case 'n': word("null"); return v;
        default:
          v.type_ = Type::kNumber;
          v.number_ = number();
          return v;
      }
    }
    std::string string() {
      ++at;  // the opening quote
      std::string out;
      while (at < s.size() && s[at] != '"') {
        const char c = s[at++];
        if (static_cast<unsigned char>(c) < 0x20) fail("a control character in a string");
        if (c != '\\') {
          out += c;
          continue;
        }
        if (at >= s.size()) fail("an escape cut short");
        const char e = s[at++];
        switch (e) {
          case '"': case '\\': case '/': out += e; break;
          case 'b': out += '\b'; break;
          case 'f': out += '\f'; break;
          case 'n': out += '\n'; break;
          case 'r': out += '\r'; break;
          case 't': out += '\t'; break;
          case 'u': {
            if (at + 4 > s.size()) fail("\\u cut short");
            const std::string hex(s.substr(at, 4));
            char* end = nullptr;
            const long code = std::strtol(hex.c_str(), &end, 16);
            if (end != hex.c_str() + 4) fail("\\u needs four hex digits");
            at += 4;
            if (code >= 0x80) fail("\\u beyond ASCII (not needed here)");
            out += static_cast<char>(code);
            break;
          }
          default: fail("an unknown escape");
        }
      }
      if (at >= s.size()) fail("a string not closed");
      ++at;
      return out;
    }
    // -?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)?
    double number() {
      const std::size_t start = at;
      const auto digits = [&] {
        const std::size_t from = at;
        while (at < s.size() && s[at] >= '0' && s[at] <= '9') ++at;
        if (at == from) fail("a digit expected");
      };
      if (at < s.size() && s[at] == '-') ++at;
      if (at < s.size() && s[at] == '0') ++at;
      else digits();
      if (at < s.size() && s[at] == '.') ++at, digits();
      if (at < s.size() && (s[at] == 'e' || s[at] == 'E')) {
        ++at;
        if (at < s.size() && (s[at] == '+' || s[at] == '-')) ++at;
        digits();
      }
      return std::strtod(std::string(s.substr(start, at - start)).c_str(), nullptr);
    }
  };

  Type type_ = Type::kNull;
  bool flag_ = false;
  double number_ = 0.0;
  std::string text_;
  std::vector<Json> elements_;
  std::vector<std::pair<std::string, Json>> members_;  // in order
};

}  // namespace pneu::test
