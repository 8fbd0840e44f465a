#pragma once
/// \file text_scan.hpp
/// Small helpers shared by the text file readers (tet meshes, surfaces): whitespace, case-blind
/// comparison, exact number parsing and quoting file text in error messages.

#include <algorithm>
#include <charconv>
#include <cmath>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace stroma::text {

inline bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

inline char lower(char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c; }

inline bool iequals(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(),
                                            [](char x, char y) { return lower(x) == lower(y); });
}

/// Quotes file text in a message without flooding it or the terminal: at most `max` bytes of it
/// (then "..." and how many more), every byte that is not printable ASCII written as \xHH
/// (binary junk, a stray CR: "\x0d" says why a line that looks valid was refused).
inline std::string clip(std::string_view s, size_t max = 60) {
  static const char* const kHex = "0123456789abcdef";
  std::string out;
  const size_t n = std::min(s.size(), max);
  out.reserve(n + 16);
  for (size_t i = 0; i < n; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 15];
    }
  }
  if (s.size() > max) out += "... (" + std::to_string(s.size() - max) + " more bytes)";
  return out;
}

/// Parses a whole token as a number, exactly and locale-independently. from_chars rejects a
/// leading '+', which some writers emit.
template <class T>
bool parse_number(std::string_view tok, T& out) {
  const char* b = tok.data();
  const char* e = b + tok.size();
  if (e - b > 1 && *b == '+' && b[1] != '-') ++b;
  auto [p, ec] = std::from_chars(b, e, out);
  return ec == std::errc() && p == e;
}

/// `s` without leading and trailing whitespace.
inline std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

/// The whitespace-separated words of `line`.
inline std::vector<std::string_view> words(std::string_view line) {
  std::vector<std::string_view> out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    const size_t b = i;
    while (i < line.size() && !is_space(line[i])) ++i;
    if (i > b) out.push_back(line.substr(b, i - b));
  }
  return out;
}

/// The lines of `text` that hold something, numbered from 1 as in the file, each trimmed and
/// cut at `comment` (a comment runs to the end of its line): blank and comment lines dropped.
inline std::vector<std::pair<int, std::string_view>> content_lines(std::string_view text, char comment = '#') {
  std::vector<std::pair<int, std::string_view>> out;
  size_t pos = 0;
  int line = 0;
  while (pos < text.size()) {
    size_t nl = text.find('\n', pos);
    if (nl == std::string_view::npos) nl = text.size();
    std::string_view l = text.substr(pos, nl - pos);
    pos = nl + 1;
    ++line;
    const size_t c = l.find(comment);
    if (c != std::string_view::npos) l = l.substr(0, c);
    l = trim(l);
    if (!l.empty()) out.emplace_back(line, l);
  }
  return out;
}

}  // namespace stroma::text
