#pragma once
/// \file text_scan.hpp
/// Small helpers shared by the text file readers (tet meshes, surfaces): whitespace, case-blind
/// comparison, exact number parsing and quoting file text in error messages.

#include <algorithm>
#include <charconv>
#include <string>
#include <string_view>

namespace stroma::text {

inline bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

inline char lower(char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c; }

inline bool iequals(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(),
                                            [](char x, char y) { return lower(x) == lower(y); });
}

/// Quotes file text in a message without flooding it (binary junk, long lines).
inline std::string clip(std::string_view s) {
  constexpr size_t kMax = 40;
  return s.size() <= kMax ? std::string(s) : std::string(s.substr(0, kMax)) + "...";
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

}  // namespace stroma::text
