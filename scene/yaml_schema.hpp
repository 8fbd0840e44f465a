#pragma once
/// \file yaml_schema.hpp
/// A strict schema layer over yaml-cpp: typed, range-checked reading of a YAML document where
/// every error is an InputError "FILE:LINE: FIELD.PATH: MESSAGE" pointing at the value to fix.
///
/// `Field` is one YAML node at a dotted field path ("bodies[0].material.density"), with typed
/// conversions that throw InputError; `MapReader` is a YAML map at a field path that validates
/// its keys on construction (unknown keys are errors, with a "did you mean" suggestion) and hands
/// out `Field`s, optional or required. A schema built on it only says which key goes where, with
/// which range or choice table; this layer knows nothing about what the document describes.
///
/// Lines are 1-based everywhere (yaml-cpp's marks are 0-based, -1 when unknown).

#include <charconv>
#include <cstddef>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "tissue/input_error.hpp"
#include "tissue/tet_mesh.hpp"

namespace stroma::yaml {

// ---------------------------------------------------------------------------------------------
// Message and path helpers

/// `items` with `sep` between them: "a, b, c"; empty for no items.
std::string join(const std::vector<std::string>& items, const char* sep = ", ");

/// "did you mean 'X'? " (trailing space included: the rest of the message follows) where X is the
/// candidate closest to `word` by case-blind edit distance (Levenshtein plus adjacent
/// transpositions), if that distance is at most 2 and smaller than the word's length (so
/// one-letter keys don't "match" everything); the first such candidate on a tie. Empty otherwise.
std::string did_you_mean(const std::string& word, const std::vector<std::string>& candidates);

/// A number as messages show it: up to 15 significant digits, no trailing zeros ("0.49", "1e-06").
std::string format_number(double v);

/// The one YAML document of `text` (a scenario file). Throws InputError(file, line, "", ...) on
/// a syntax error, on a second document, and on input the parser cannot get through. yaml-cpp
/// 0.7's LoadAll loops for ever, allocating, on some malformed input (a document that consumes
/// no token, e.g. one starting with ',': jbeder/yaml-cpp#1040, fixed upstream by #1319, not in
/// Debian 12's 0.7.0); documents are counted here with a bounded parse instead.
YAML::Node load_single_document(const std::string& text, const std::string& file);

/// Path of map key `key` below `parent`: "parent.key", or just "key" below the root (empty path).
std::string child_path(const std::string& parent, const std::string& key);

/// Path of the 0-based list item `i` below `parent`: "parent[i]".
std::string index_path(const std::string& parent, std::size_t i);

/// Last component of a field path, for messages: "bodies[0].material.density" -> "density",
/// "gravity[1]" -> "gravity[1]".
std::string leaf_name(const std::string& path);

// ---------------------------------------------------------------------------------------------
// Numeric ranges

/// An allowed interval for a number; either bound may be absent, open or closed. A note can be
/// appended to the message when the value is below / above the range.
struct Range {
  std::optional<double> lo, hi;
  bool lo_closed = false, hi_closed = false;
  std::string note_lo, note_hi;  ///< shown in parentheses after the message; empty: none

  /// -1 if v is below the range, +1 if above, 0 if inside.
  int violated(double v) const;
  /// The range as a message: "must be > 0", "must be > -1 and < 0.5".
  std::string describe() const;
};

/// Every number (no bounds).
Range any_value();
/// v > lo.
Range greater_than(double lo);
/// v >= lo.
Range at_least(double lo);
/// lo < v < hi.
Range open_interval(double lo, double hi);
/// lo <= v <= hi, with the reason for the bounds shown on either side ("tissue is ...").
Range physical_range(double lo, double hi, std::string why);

// ---------------------------------------------------------------------------------------------
// Enumerations

/// One accepted spelling of an enumerated value.
template <class E>
struct Choice {
  const char* name;
  E value;
};

/// The accepted spellings of an enumeration, in the order messages list them. Several names may
/// map to the same value (aliases); the first matching name wins.
template <class E>
using Choices = std::vector<Choice<E>>;

/// The names of a choice table, in table order.
template <class E>
std::vector<std::string> names_of(const Choices<E>& choices) {
  std::vector<std::string> names;
  for (const auto& c : choices) names.emplace_back(c.name);
  return names;
}

// ---------------------------------------------------------------------------------------------
// Field: one YAML node at a field path

class MapReader;

/// One YAML node at a dotted field path, with typed conversions. Every failure throws
/// InputError pointing at this node's line and path.
class Field {
 public:
  /// `key_line` is the 1-based line of the key that introduced the node (for list items and the
  /// root: the node's own line). It is used when the node has no reliable position (empty
  /// values) and for "missing field" errors inside a map. `file` is borrowed: it must outlive
  /// this Field and every Field or MapReader made from it.
  Field(const std::string* file, YAML::Node node, std::string path, int key_line);

  /// The file name errors report.
  const std::string& file() const { return *file_; }
  /// The dotted field path; empty for the document root.
  const std::string& path() const { return path_; }
  /// The line errors about the value report: the node's own line, or `key_line()` for an empty
  /// value or a node without a position.
  int line() const { return line_; }
  /// The line of the key that introduced the node (see the constructor).
  int key_line() const { return key_line_; }
  /// The underlying node, for checks the typed conversions don't cover.
  const YAML::Node& yaml() const { return node_; }

  /// Throws InputError(file, line(), path, message).
  [[noreturn]] void fail(const std::string& message) const { fail_at(line_, message); }
  /// Throws InputError(file, line, path, message).
  [[noreturn]] void fail_at(int line, const std::string& message) const;

  /// A node below this one (same file).
  Field child(YAML::Node node, std::string path, int key_line) const {
    return Field(file_, std::move(node), std::move(path), key_line);
  }

  /// What the node is, for "expected X, got Y" messages: "an empty value", "a list", "a map",
  /// "the quoted string 'x'" or "'x'".
  std::string got() const;

  // -- typed conversions ------------------------------------------------------------------------

  /// A finite number within `range`, from a plain (unquoted) scalar; a leading '+' is accepted.
  double number(const Range& range = any_value()) const;

  /// A whole number that fits `I` and lies within `range`, from a plain (unquoted) scalar; a
  /// leading '+' is accepted.
  template <class I>
  I integer(const Range& range = any_value()) const {
    const std::string text = plain_scalar("an integer");
    long long v = 0;
    const char* first = text.data();
    const char* last = text.data() + text.size();
    if (first != last && *first == '+') ++first;
    const auto [ptr, ec] = std::from_chars(first, last, v);
    if (ec == std::errc::result_out_of_range ||
        (ec == std::errc() && ptr == last &&
         (v < std::numeric_limits<I>::min() || v > std::numeric_limits<I>::max()))) {
      fail(leaf_name(path_) + " = " + text + " is out of range: must be between " +
           std::to_string(std::numeric_limits<I>::min()) + " and " +
           std::to_string(std::numeric_limits<I>::max()));
    }
    if (ec != std::errc() || ptr != last || first == last)
      fail("expected an integer, got " + got());
    check_range(static_cast<double>(v), text, range);
    return static_cast<I>(v);
  }

  /// Whether the node is a scalar (quoted or not).
  bool is_scalar() const { return node_.IsScalar(); }
  /// Whether the node is empty (`key:` with no value, or null).
  bool is_null() const { return node_.IsNull(); }

  /// true / True / TRUE or false / False / FALSE, unquoted.
  bool boolean() const;

  /// A non-empty string scalar.
  std::string string() const;

  /// A list of exactly 3 numbers.
  Vec3 vec3() const;

  /// The value of the choice whose name the scalar spells exactly (case-sensitive); an unknown
  /// name gets a "did you mean" and the list of accepted names.
  template <class E>
  E choice(const Choices<E>& choices) const {
    const std::vector<std::string> names = names_of(choices);
    if (!node_.IsScalar()) fail("expected one of " + join(names) + ", got " + got());
    const std::string& text = node_.Scalar();
    for (const auto& c : choices)
      if (text == c.name) return c.value;
    fail("unknown " + leaf_name(path_) + " '" + text + "': " + did_you_mean(text, names) +
         "expected one of " + join(names));
  }

  /// The items of a list (an empty value is not a list: write [] for an empty one). Item paths
  /// are "path[i]"; each item's key line is its own line (the list's when it has none).
  std::vector<Field> list() const;

  /// The node as a map whose keys must all be in `allowed` (see MapReader).
  MapReader map(std::initializer_list<const char*> allowed) const;

  // -- uniform "store into" interface used by MapReader::read / require -------------------------

  /// Stores number(r).
  void get(double& out, const Range& r = any_value()) const { out = number(r); }
  /// Stores integer<int>(r).
  void get(int& out, const Range& r = any_value()) const { out = integer<int>(r); }
  /// Stores integer<long>(r).
  void get(long& out, const Range& r = any_value()) const { out = integer<long>(r); }
  /// Stores boolean().
  void get(bool& out) const { out = boolean(); }
  /// Stores string().
  void get(std::string& out) const { out = string(); }
  /// Stores vec3().
  void get(Vec3& out) const { out = vec3(); }
  /// Stores choice(choices).
  template <class E>
  void get(E& out, const Choices<E>& choices) const { out = choice(choices); }
  /// Stores choice(choices) for a table whose entries may disengage `out` ("auto" → nullopt).
  /// Declared so clang does not find the two templates around it equally good.
  template <class T>
  void get(std::optional<T>& out, const Choices<std::optional<T>>& choices) const { out = choice(choices); }
  /// Converts as for a plain T and engages `out`.
  template <class T, class... A>
  void get(std::optional<T>& out, const A&... args) const {
    T v{};
    get(v, args...);
    out = v;
  }

 private:
  /// Whether the scalar was quoted (or tagged !!str): then it is text, never a number or bool.
  bool is_string_tagged() const;

  /// The text of a plain (unquoted) scalar, or an "expected <what>" error.
  std::string plain_scalar(const char* what) const;

  /// Fails with "<leaf> = <text> is out of range: <range>" (plus the range's note) if `v` is
  /// outside `range`; `text` is the value as written.
  void check_range(double v, const std::string& text, const Range& range) const;

  const std::string* file_;
  YAML::Node node_;
  std::string path_;
  int key_line_;
  int line_;
};

// ---------------------------------------------------------------------------------------------
// MapReader: a YAML map at a field path, with a fixed set of allowed keys

/// A YAML map whose keys were checked against a fixed allowed set, handing out its values as
/// `Field`s at "path.key" whose key line is the key's own line.
class MapReader {
 public:
  /// Checks that `self` is a map whose keys are all scalars in `allowed`, each at most once.
  /// Errors about a key report the key's line and path.
  MapReader(const Field& self, std::initializer_list<const char*> allowed);

  /// The file name errors report.
  const std::string& file() const { return self_.file(); }
  /// The map's dotted field path; empty for the document root.
  const std::string& path() const { return self_.path(); }
  /// Line of the map: the line of the key that introduced it, or of the list item.
  int line() const { return self_.key_line(); }
  /// Throws InputError(file, line(), path, message): an error about the map as a whole.
  [[noreturn]] void fail(const std::string& message) const { self_.fail_at(line(), message); }

  /// The value of `key` if the key is present.
  std::optional<Field> opt(const std::string& key) const;

  /// The value of `key`; a "missing required field" error at the map's line otherwise.
  Field req(const std::string& key) const;

  /// Stores the converted value of `key` into `out` if the key is present (else `out` keeps its
  /// default). Extra arguments are passed to the conversion (a Range, a Choices table).
  template <class T, class... A>
  bool read(const std::string& key, T& out, const A&... args) const {
    const auto f = opt(key);
    if (!f) return false;
    f->get(out, args...);
    return true;
  }

  /// Same, but the key must be present.
  template <class T, class... A>
  void require(const std::string& key, T& out, const A&... args) const {
    req(key).get(out, args...);
  }

  /// Items of the list at `key` (empty when the key is absent).
  std::vector<Field> list(const std::string& key) const;

 private:
  Field self_;
  std::vector<std::string> allowed_;
  std::vector<std::pair<std::string, Field>> entries_;  ///< in file order
};

}  // namespace stroma::yaml
