#include "pneu/config/yaml_text.hpp"

#include <stdexcept>
#include <vector>

#include "pneu/config/describe.hpp"

namespace pneu::config::yaml_text {

namespace {

constexpr auto npos = std::string_view::npos;

bool blank(char c) { return c == ' ' || c == '\t'; }

// One line of the text.
struct Line {
  std::size_t begin = 0;
  std::size_t end = 0;     // before its "\n" or "\r\n"
  std::size_t next = 0;    // the next line's first byte (the text's size after the last line)
  std::size_t indent = 0;  // its leading spaces
  bool content = false;    // neither blank, nor a comment, nor a document marker (--- or ...)
  bool comment = false;    // a comment alone on its line
};

std::vector<Line> lines_of(std::string_view text) {
  std::vector<Line> lines;
  for (std::size_t b = 0; b < text.size();) {
    const std::size_t nl = text.find('\n', b);
    Line l;
    l.begin = b;
    l.next = nl == npos ? text.size() : nl + 1;
    l.end = nl == npos ? text.size() : nl;
    if (l.end > b && text[l.end - 1] == '\r') --l.end;
    while (b + l.indent < l.end && text[b + l.indent] == ' ') ++l.indent;
    const std::string_view rest = text.substr(b + l.indent, l.end - b - l.indent);
    const auto marker = [&](std::string_view m) {
      return l.indent == 0 && rest.starts_with(m) && (rest.size() == 3 || blank(rest[3]));
    };
    const std::size_t first = rest.find_first_not_of(" \t");
    l.comment = first != npos && rest[first] == '#';
    l.content = first != npos && !l.comment && !marker("---") && !marker("...");
    lines.push_back(l);
    b = l.next;
  }
  return lines;
}

// A list entry ("- " or a lone "-").
bool is_entry(std::string_view text, const Line& l) {
  const std::size_t i = l.begin + l.indent;
  return i < l.end && text[i] == '-' && (i + 1 == l.end || blank(text[i + 1]));
}

// The end of a quoted scalar that starts at `i` (its closing quote + 1), or npos when it does not
// close before `end`.
std::size_t quoted_end(std::string_view text, std::size_t i, std::size_t end) {
  const char q = text[i];
  for (std::size_t j = i + 1; j < end; ++j) {
    if (q == '"' && text[j] == '\\') {
      ++j;
    } else if (text[j] == q) {
      if (q == '\'' && j + 1 < end && text[j + 1] == '\'') ++j;  // '' is a quote inside
      else return j + 1;
    }
  }
  return npos;
}

// The key a content line starts with, and where its ':' is; nothing for a list entry or a line
// without a key.
struct KeyOnLine {
  std::string_view name;
  std::size_t colon = 0;
};
std::optional<KeyOnLine> key_on(std::string_view text, const Line& l) {
  const std::size_t i = l.begin + l.indent;
  if (i >= l.end) return std::nullopt;
  const char c = text[i];
  if (c == '"' || c == '\'') {
    const std::size_t close = quoted_end(text, i, l.end);
    if (close == npos) return std::nullopt;
    std::size_t k = close;
    while (k < l.end && blank(text[k])) ++k;
    if (k < l.end && text[k] == ':' && (k + 1 == l.end || blank(text[k + 1])))
      return KeyOnLine{text.substr(i + 1, close - i - 2), k};
    return std::nullopt;
  }
  if ((c == '-' || c == '?') && (i + 1 == l.end || blank(text[i + 1]))) return std::nullopt;
  for (std::size_t j = i; j < l.end; ++j) {
    if (text[j] == '#' && j > i && blank(text[j - 1])) return std::nullopt;
    if (text[j] == ':' && (j + 1 == l.end || blank(text[j + 1]))) {
      std::size_t e = j;
      while (e > i && blank(text[e - 1])) --e;
      return KeyOnLine{text.substr(i, e - i), j};
    }
  }
  return std::nullopt;
}

// What follows a key's ':' on its line: the value's extent and the inline comment.
struct Inline {
  std::size_t begin = 0, end = 0;
  std::size_t comment = kNone;
};
Inline inline_value(std::string_view text, const Line& l, std::size_t colon, const std::string& key) {
  std::size_t i = colon + 1;
  while (i < l.end && blank(text[i])) ++i;
  Inline v{i, i, kNone};
  if (i == l.end) return v;
  if (text[i] == '#') {
    v.comment = i;
    return v;
  }
  const char c = text[i];
  if (c == '&' || c == '!')
    throw ConfigError(key, std::string("its value carries ") + (c == '&' ? "an anchor (&)" : "a tag (!)") +
                               ": other keys may share it; edit the file by hand");
  if (c == '|' || c == '>') throw ConfigError(key, "its value is a block scalar (| or >): edit the file by hand");
  std::size_t e = i;
  if (c == '"' || c == '\'') {
    e = quoted_end(text, i, l.end);
    if (e == npos) throw ConfigError(key, "its quoted value spans lines: edit the file by hand");
  } else if (c == '[' || c == '{') {
    int depth = 0;
    for (; e < l.end; ++e) {
      const char d = text[e];
      if (d == '"' || d == '\'') {
        const std::size_t close = quoted_end(text, e, l.end);
        if (close == npos) break;
        e = close - 1;
      } else if (d == '[' || d == '{') {
        ++depth;
      } else if ((d == ']' || d == '}') && --depth == 0) {
        ++e;
        break;
      }
    }
    if (depth != 0) throw ConfigError(key, "its value in flow style spans lines: edit the file by hand");
  } else {  // a plain scalar or an alias: to the comment or the line's end
    while (e < l.end && !(text[e] == '#' && blank(text[e - 1]))) ++e;
    while (e > i && blank(text[e - 1])) --e;
  }
  v.end = e;
  std::size_t k = e;
  while (k < l.end && blank(text[k])) ++k;
  if (k < l.end) {
    if (text[k] != '#' || k == e) throw ConfigError(key, "text after its value that is not a comment: edit the file by hand");
    v.comment = k;
  }
  return v;
}

// The index of the last line holding the value of the key on line `k` in block style: content
// lines deeper than the key, or list entries at its column (a list may sit at its key's column);
// `k` itself when none.
std::size_t block_last(std::string_view text, const std::vector<Line>& lines, std::size_t k) {
  const std::size_t column = lines[k].indent;
  std::size_t last = k;
  for (std::size_t j = k + 1; j < lines.size(); ++j) {
    const Line& l = lines[j];
    if (!l.content) continue;
    if (l.indent > column || (l.indent == column && is_entry(text, l))) last = j;
    else break;
  }
  return last;
}

std::vector<std::string_view> parts_of(std::string_view dotted) {
  std::vector<std::string_view> parts;
  for (std::size_t b = 0;;) {
    const std::size_t dot = dotted.find('.', b);
    parts.push_back(dotted.substr(b, dot == npos ? npos : dot - b));
    if (dot == npos) break;
    b = dot + 1;
  }
  for (const std::string_view p : parts)
    if (p.empty()) throw std::invalid_argument("yaml_text: an empty key in '" + std::string(dotted) + "'");
  return parts;
}

// How far the text has a key: the parts found, the lines of the deepest section found (below its
// key's line), and the key's value when it has all of them.
struct Walk {
  std::size_t found = 0;
  std::size_t section_line = kNone;  // the deepest section's key line (kNone: the document)
  std::size_t first = 0, last = 0;   // its lines, [first, last)
  std::optional<ValueAt> at;
};

Walk walk(std::string_view text, const std::vector<Line>& lines, std::string_view dotted) {
  const std::vector<std::string_view> parts = parts_of(dotted);
  const std::string key(dotted);
  Walk w;
  w.last = lines.size();
  std::string path;
  for (std::size_t p = 0; p < parts.size(); ++p) {
    path += (p > 0 ? "." : "") + std::string(parts[p]);
    // The section's keys stand at the column of its first content line.
    std::size_t column = kNone, hit = kNone;
    for (std::size_t j = w.first; j < w.last && hit == kNone; ++j) {
      if (!lines[j].content) continue;
      if (column == kNone) column = lines[j].indent;
      if (lines[j].indent != column) continue;
      if (const auto k = key_on(text, lines[j]); k && k->name == parts[p]) hit = j;
    }
    if (hit == kNone) return w;
    const Line& l = lines[hit];
    const KeyOnLine k = *key_on(text, l);
    const Inline v = inline_value(text, l, k.colon, key);
    ValueAt at;
    at.line = l.begin;
    at.column = l.indent;
    at.colon = k.colon;
    at.value_begin = v.begin;
    at.value_end = v.end;
    at.comment = v.comment;
    at.line_end = l.end;
    const std::size_t last = block_last(text, lines, hit);
    at.block_end = lines[last].end;
    if (last > hit) {
      if (v.end > v.begin) throw ConfigError(key, path + "'s value spans lines: edit the file by hand");
      std::size_t below = hit + 1;
      while (!lines[below].content) ++below;
      at.list = is_entry(text, lines[below]);
      at.section = !at.list;
    }
    w.found = p + 1;
    if (p + 1 == parts.size()) {
      w.at = at;
      return w;
    }
    if (v.end > v.begin) {
      if (text[v.begin] == '{')
        throw ConfigError(key, path + " is a section in flow style ({...}): its keys cannot be edited in place; "
                                      "write it in block style, one key a line");
      throw ConfigError(key, path + " is a value, not a section");
    }
    if (at.list) throw ConfigError(key, path + " is a list: its entries are not reached by a key path");
    w.section_line = hit;
    w.first = hit + 1;
    w.last = last + 1;
  }
  return w;
}

// The column of a line's inline comment, or kNone.
std::size_t comment_column(std::string_view text, const Line& l) {
  for (std::size_t j = l.begin + l.indent; j < l.end; ++j) {
    if (text[j] == '"' || text[j] == '\'') {
      const std::size_t close = quoted_end(text, j, l.end);
      if (close == npos) return kNone;
      j = close - 1;
    } else if (text[j] == '#' && (j == l.begin || blank(text[j - 1]))) {
      return j - l.begin;
    }
  }
  return kNone;
}

// `comment` (from its '#') without its last part that is a note beginning with `word`.
std::string without_note(std::string comment, std::string_view word) {
  const std::string mark = "# " + std::string(word) + " ";
  for (std::size_t at = comment.rfind(mark); at != std::string::npos; at = at == 0 ? std::string::npos : comment.rfind(mark, at - 1)) {
    if (at > 0 && !blank(comment[at - 1])) continue;
    comment.erase(at);
    while (!comment.empty() && blank(comment.back())) comment.pop_back();
    break;
  }
  return comment;
}

std::string first_word(std::string_view note) { return std::string(note.substr(0, note.find(' '))); }

// `line` with `comment` at `column` when it has room there, two spaces after it otherwise.
void append_comment(std::string& line, std::string_view comment, std::size_t column) {
  const std::size_t at = column != kNone && line.size() + 1 <= column ? column : line.size() + 2;
  line.append(at - line.size(), ' ');
  line += comment;
}

std::string added(std::string_view text, const std::vector<Line>& lines, std::string_view dotted, const Walk& w,
                  std::string_view value, std::string_view note) {
  const std::vector<std::string_view> parts = parts_of(dotted);
  // The section's keys' column and its last content line.
  std::size_t column = kNone, last = kNone;
  for (std::size_t j = w.first; j < w.last; ++j) {
    if (!lines[j].content) continue;
    if (column == kNone) column = lines[j].indent;
    last = j;
  }
  const std::size_t parent = w.section_line == kNone ? kNone : lines[w.section_line].indent;
  const std::size_t unit = parent != kNone && column != kNone && column > parent ? column - parent : 2;
  if (column == kNone) column = parent == kNone ? 0 : parent + unit;
  // After the section's last line, and the comment lines below it deeper than its keys (the
  // comment of that line, continued).
  std::size_t after = last != kNone ? last : w.section_line;
  if (after != kNone)
    while (after + 1 < lines.size() && lines[after + 1].comment && lines[after + 1].indent > column) ++after;
  const std::string eol = text.find("\r\n") != npos ? "\r\n" : "\n";
  std::string insert;
  std::size_t offset = 0;
  if (after != kNone) {
    offset = lines[after].next;
    if (lines[after].next == lines[after].end) insert += eol;  // the last line, without its end
  } else if (!lines.empty()) {
    offset = text.size();
    if (text.back() != '\n') insert += eol;
  }
  if (w.found == 0 && last != kNone) insert += eol;  // a section of its own: a blank line before it
  const std::size_t note_column = after != kNone ? comment_column(text, lines[after]) : kNone;
  for (std::size_t p = w.found; p < parts.size(); ++p) {
    std::string line(column + (p - w.found) * unit, ' ');
    line += std::string(parts[p]) + ":";
    if (p + 1 == parts.size()) {
      line += " " + std::string(value);
      if (!note.empty()) append_comment(line, "# " + std::string(note), note_column);
    }
    insert += line + eol;
  }
  std::string out(text.substr(0, offset));
  out += insert;
  out += text.substr(offset);
  return out;
}

}  // namespace

std::optional<ValueAt> find(std::string_view text, std::string_view dotted_key) {
  return walk(text, lines_of(text), dotted_key).at;
}

std::string with_value(std::string_view text, std::string_view dotted_key, std::string_view value,
                       std::string_view note) {
  if (value.find_first_of("\r\n") != npos || note.find_first_of("\r\n") != npos)
    throw std::invalid_argument("yaml_text::with_value: a value or note of more than one line for " +
                                std::string(dotted_key));
  const std::vector<Line> lines = lines_of(text);
  const Walk w = walk(text, lines, dotted_key);
  if (!w.at) return added(text, lines, dotted_key, w, value, note);
  const ValueAt& at = *w.at;
  if (at.section) throw ConfigError(std::string(dotted_key), "is a section: its keys are written one by one");
  std::string line(text.substr(at.line, (at.value_end > at.value_begin ? at.value_begin : at.colon + 1) - at.line));
  if (at.value_end == at.value_begin) line += ' ';
  line += value;
  std::string comment;
  if (at.comment != kNone) {
    comment = text.substr(at.comment, at.line_end - at.comment);
    while (!comment.empty() && blank(comment.back())) comment.pop_back();
    if (!note.empty()) comment = without_note(std::move(comment), first_word(note));
  }
  if (!comment.empty()) append_comment(line, comment, at.comment - at.line);
  if (!note.empty()) append_comment(line, "# " + std::string(note), kNone);
  std::string out(text.substr(0, at.line));
  out += line;
  out += text.substr(at.list ? at.block_end : at.line_end);
  return out;
}

}  // namespace pneu::config::yaml_text
