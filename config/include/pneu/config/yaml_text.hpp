// A YAML configuration's text edited in place: a key's value replaced, or the key added in its
// section, every other byte kept, the comments among them (yaml-cpp drops comments when it writes
// a document). Line by line, for the block style the shipped configurations use: a key in flow
// style ({...}), a block scalar (| or >), a value spanning lines, an anchor or a tag is refused,
// naming the key and why, never guessed at. Then a whole configuration written into the text it
// came from (with_values_of), as pneud --identify writes what it identified.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "pneu/config/config.hpp"

namespace pneu::config::yaml_text {

inline constexpr std::size_t kNone = std::string_view::npos;

/// Where a key's value lies in a text (byte offsets into it).
struct ValueAt {
  std::size_t line = 0;         ///< the key's line, its first byte
  std::size_t column = 0;       ///< the key's column (its indentation)
  std::size_t colon = 0;        ///< the ':' after the key
  /// The value written on the key's line, [value_begin, value_end): a scalar, an alias or a
  /// collection in flow style; empty for a value in block style below the line, or none.
  std::size_t value_begin = 0;
  std::size_t value_end = 0;
  std::size_t comment = kNone;  ///< the '#' of the key's inline comment, or kNone
  std::size_t line_end = 0;     ///< the end of the key's line (its '\n' or '\r\n', or the text's end)
  /// The end of the last line below that holds the value in block style (a list of "- " lines, a
  /// section's keys); line_end when there is none.
  std::size_t block_end = 0;
  bool section = false;         ///< the value is a mapping in block style (a section)
  bool list = false;            ///< the value is a list in block style ("- " lines)
};

/// The value of `dotted_key` ("plant.friction.static_positive_n") in `text`, or nothing when the
/// text lacks the key or a section on its way. Throws ConfigError at the key when the way to it
/// cannot be read line by line: a section on it in flow style, a list, a value, or a value of the
/// key spanning lines.
[[nodiscard]] std::optional<ValueAt> find(std::string_view text, std::string_view dotted_key);

/// `text` with `dotted_key`'s value replaced by `value` (YAML on one line: a scalar, or a
/// collection in flow style; a list in block style is replaced whole), every other byte kept: its
/// inline comment stays (at its column where the value leaves room), and `note`, when given, follows
/// it as a comment of its own ("  # note"), in place of an earlier note that begins with the same
/// word. A key the text lacks is added at the end of its section (after the last key's comment
/// lines), with the sections on its way the text lacks, indented as the section's keys are. Throws
/// ConfigError at the key where find() does, and when the key is a section, or its value carries an
/// anchor or a tag (other keys may share it: edit the file by hand), or is a block scalar.
[[nodiscard]] std::string with_value(std::string_view text, std::string_view dotted_key, std::string_view value,
                                     std::string_view note = {});

}  // namespace pneu::config::yaml_text

namespace pneu::config {

/// The text load_file_or_default() loads: the file's (refused as load_file refuses it: no such
/// file, a directory, over 1 MiB), or the embedded default's when `path` is empty.
[[nodiscard]] std::string text_of(const std::filesystem::path& path);

/// The note with_values_of() writes beside a key: given the key's path and its value in the
/// source as schema::values_of() says it ("" where the source leaves the key out); "" for none.
using NoteOf = std::function<std::string(const std::string& path, const std::string& was)>;

/// `source`, a configuration's YAML text (named `origin` in messages), edited to hold `target`:
/// each key whose value in `target` differs from the one `source` loads to, and each key of
/// `always`, written in place with the note `note_of` gives (yaml_text::with_value(): every other
/// byte kept, the comments among them; a key the text lacks added in its section, a list written
/// whole, an optional section `target` has and `source` lacks written with all of its keys). The
/// keys are those to_yaml() writes, by the schema's description: no list of them here. Loaded back,
/// the text is `target` (schema::values_of() equal), which is checked. Throws ConfigError when
/// `source` does not load, when a key cannot be edited in place (yaml_text::with_value()), or when
/// `target` lacks an optional section `source` has (a section is not removed).
[[nodiscard]] std::string with_values_of(std::string_view source, const Config& target,
                                         const std::vector<std::string>& always, const NoteOf& note_of,
                                         std::string_view origin);

}  // namespace pneu::config
