/// \file yaml_schema.cpp
/// Out-of-line parts of the YAML schema layer (yaml_schema.hpp).

#include "scene/yaml_schema.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <yaml-cpp/anchor.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/parser.h>

namespace stroma::yaml {
namespace {

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

/// Optimal-string-alignment distance (Levenshtein plus adjacent transpositions), case-blind.
int edit_distance(const std::string& a_in, const std::string& b_in) {
  const std::string a = lower(a_in), b = lower(b_in);
  const std::size_t n = a.size(), m = b.size();
  std::vector<std::vector<int>> d(n + 1, std::vector<int>(m + 1, 0));
  for (std::size_t i = 0; i <= n; ++i) d[i][0] = static_cast<int>(i);
  for (std::size_t j = 0; j <= m; ++j) d[0][j] = static_cast<int>(j);
  for (std::size_t i = 1; i <= n; ++i) {
    for (std::size_t j = 1; j <= m; ++j) {
      const int cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[n][m];
}

/// The candidate closest to `word` if it is within edit distance 2 (and the distance is smaller
/// than the word itself, so one-letter keys don't "match" everything); empty otherwise.
std::string closest(const std::string& word, const std::vector<std::string>& candidates) {
  std::string best;
  int best_d = 3;
  for (const auto& c : candidates) {
    const int d = edit_distance(word, c);
    if (d < best_d && d < static_cast<int>(word.size())) {
      best_d = d;
      best = c;
    }
  }
  return best;
}

/// A number in YAML's plain-scalar spelling (leading '+' allowed); infinity when it overflows,
/// so the caller reports it as not finite. Empty when the text is not a number.
std::optional<double> parse_double(const std::string& text) {
  const char* first = text.data();
  const char* last = text.data() + text.size();
  if (first != last && *first == '+') ++first;
  if (first == last) return std::nullopt;
  double v = 0;
  const auto [ptr, ec] = std::from_chars(first, last, v, std::chars_format::general);
  if (ec == std::errc::result_out_of_range) return std::numeric_limits<double>::infinity();
  if (ec != std::errc() || ptr != last) return std::nullopt;
  return v;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Message and path helpers

std::string join(const std::vector<std::string>& items, const char* sep) {
  std::string s;
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i) s += sep;
    s += items[i];
  }
  return s;
}

std::string did_you_mean(const std::string& word, const std::vector<std::string>& candidates) {
  const std::string c = closest(word, candidates);
  return c.empty() ? std::string() : "did you mean '" + c + "'? ";
}

std::string format_number(double v) {
  // Shortest digits that read back as v; large and tiny magnitudes in scientific notation
  // (1e+12, not 1000000000000).
  const double a = std::fabs(v);
  if (std::isfinite(v) && v != 0 && (a >= 1e7 || a < 1e-4)) {
    char buf[40];
    for (int p = 1; p <= 17; ++p) {
      std::snprintf(buf, sizeof buf, "%.*g", p, v);
      if (std::strtod(buf, nullptr) == v) break;
    }
    return buf;
  }
  std::ostringstream os;
  os.precision(15);
  os << v;
  return os.str();
}

namespace {

/// Records where each document starts and whether its root is null (no content).
class DocumentProbe : public YAML::EventHandler {
 public:
  struct Document {
    int line = 0;         ///< 1-based line of its first node (0: none)
    bool null_root = true;
  };
  std::vector<Document> docs;
  void OnDocumentStart(const YAML::Mark&) override { docs.emplace_back(); depth_ = 0; }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& m, YAML::anchor_t) override { node(m, false); }
  void OnAlias(const YAML::Mark& m, YAML::anchor_t) override { node(m, true); }
  void OnScalar(const YAML::Mark& m, const std::string&, YAML::anchor_t, const std::string&) override { node(m, true); }
  void OnSequenceStart(const YAML::Mark& m, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    node(m, true);
    ++depth_;
  }
  void OnSequenceEnd() override { --depth_; }
  void OnMapStart(const YAML::Mark& m, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    node(m, true);
    ++depth_;
  }
  void OnMapEnd() override { --depth_; }

 private:
  void node(const YAML::Mark& m, bool content) {
    if (docs.empty() || depth_ > 0) return;
    docs.back().line = m.line >= 0 ? m.line + 1 : 0;
    docs.back().null_root = !content;
  }
  int depth_ = 0;
};

}  // namespace

YAML::Node load_single_document(const std::string& text, const std::string& file) {
  auto syntax_error = [&](const YAML::Exception& e) {
    const int line = e.mark.is_null() || e.mark.line < 0 ? 0 : e.mark.line + 1;
    return InputError(file, line, "", "YAML syntax error: " + e.msg);
  };
  DocumentProbe probe;
  try {
    std::istringstream in(text);
    YAML::Parser parser(in);
    for (int d = 0; d < 2 && parser.HandleNextDocument(probe); ++d) {
    }
  } catch (const YAML::Exception& e) {
    throw syntax_error(e);
  }
  if (probe.docs.size() > 1) {
    if (probe.docs[0].null_root && probe.docs[1].null_root)  // the parser is stuck on a token
      throw InputError(file, probe.docs[1].line, "", "YAML syntax error: cannot parse the text here");
    throw InputError(file, probe.docs[1].line, "", "expected a single YAML document, found another one here");
  }
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw syntax_error(e);
  }
}

std::string child_path(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}

std::string index_path(const std::string& parent, std::size_t i) {
  return parent + "[" + std::to_string(i) + "]";
}

std::string leaf_name(const std::string& path) {
  const auto dot = path.rfind('.');
  return dot == std::string::npos ? path : path.substr(dot + 1);
}

// ---------------------------------------------------------------------------------------------
// Numeric ranges

int Range::violated(double v) const {
  if (lo && (lo_closed ? v < *lo : v <= *lo)) return -1;
  if (hi && (hi_closed ? v > *hi : v >= *hi)) return +1;
  return 0;
}

std::string Range::describe() const {
  std::string s = "must be";
  if (lo) s += std::string(lo_closed ? " >= " : " > ") + format_number(*lo);
  if (lo && hi) s += " and";
  if (hi) s += std::string(hi_closed ? " <= " : " < ") + format_number(*hi);
  return s;
}

Range any_value() { return {}; }
Range greater_than(double lo) { return Range{lo, std::nullopt, false, false, {}, {}}; }
Range at_least(double lo) { return Range{lo, std::nullopt, true, false, {}, {}}; }
Range open_interval(double lo, double hi) { return Range{lo, hi, false, false, {}, {}}; }
Range physical_range(double lo, double hi, std::string why) { return Range{lo, hi, true, true, why, why}; }

// ---------------------------------------------------------------------------------------------
// Field

Field::Field(const std::string* file, YAML::Node node, std::string path, int key_line)
    : file_(file), node_(std::move(node)), path_(std::move(path)), key_line_(key_line) {
  const int own = node_.Mark().line;
  line_ = (node_.IsNull() || own < 0) ? key_line_ : own + 1;
  if (line_ <= 0) line_ = key_line_;
}

void Field::fail_at(int line, const std::string& message) const {
  throw InputError(*file_, line, path_, message);
}

std::string Field::got() const {
  if (!node_.IsDefined() || node_.IsNull()) return "an empty value";
  if (node_.IsSequence()) return "a list";
  if (node_.IsMap()) return "a map";
  if (is_string_tagged()) return "the quoted string '" + node_.Scalar() + "'";
  return "'" + node_.Scalar() + "'";
}

double Field::number(const Range& range) const {
  const std::string text = plain_scalar("a number");
  const auto v = parse_double(text);
  if (!v) fail("expected a number, got " + got());
  if (!std::isfinite(*v)) fail("expected a finite number, got " + got());
  check_range(*v, text, range);
  return *v;
}

bool Field::boolean() const {
  const std::string text = plain_scalar("true or false");
  if (text == "true" || text == "True" || text == "TRUE") return true;
  if (text == "false" || text == "False" || text == "FALSE") return false;
  fail("expected true or false, got " + got());
}

std::string Field::string() const {
  if (!node_.IsScalar()) fail("expected a string, got " + got());
  if (node_.Scalar().empty()) fail("must not be empty");
  return node_.Scalar();
}

Vec3 Field::vec3() const {
  if (!node_.IsSequence() || node_.size() != 3) {
    std::string what = got();
    if (node_.IsSequence())
      what = "a list of " + std::to_string(node_.size()) +
             (node_.size() == 1 ? " item" : " items");
    fail("expected a list of 3 numbers, got " + what);
  }
  const auto items = list();
  return {items[0].number(), items[1].number(), items[2].number()};
}

std::vector<Field> Field::list() const {
  if (!node_.IsSequence()) {
    fail("expected a list, got " + got() +
         (node_.IsNull() ? std::string(" (write [] for an empty list)") : std::string()));
  }
  std::vector<Field> items;
  std::size_t i = 0;
  for (const auto& item : node_) {
    const int l = item.Mark().line >= 0 ? item.Mark().line + 1 : line_;
    items.push_back(child(item, index_path(path_, i++), l));
  }
  return items;
}

MapReader Field::map(std::initializer_list<const char*> allowed) const {
  return MapReader(*this, allowed);
}

bool Field::is_string_tagged() const {
  const std::string& tag = node_.Tag();
  return tag == "!" || tag == "tag:yaml.org,2002:str";
}

std::string Field::plain_scalar(const char* what) const {
  if (!node_.IsScalar() || is_string_tagged())
    fail(std::string("expected ") + what + ", got " + got());
  return node_.Scalar();
}

void Field::check_range(double v, const std::string& text, const Range& range) const {
  const int side = range.violated(v);
  if (side == 0) return;
  std::string msg = leaf_name(path_) + " = " + text + " is out of range: " + range.describe();
  const std::string& note = side < 0 ? range.note_lo : range.note_hi;
  if (!note.empty()) msg += " (" + note + ")";
  fail(msg);
}

// ---------------------------------------------------------------------------------------------
// MapReader

MapReader::MapReader(const Field& self, std::initializer_list<const char*> allowed) : self_(self) {
  for (const char* k : allowed) allowed_.emplace_back(k);
  const YAML::Node& node = self_.yaml();
  if (!node.IsMap())
    self_.fail("expected a map with keys " + join(allowed_) + ", got " + self_.got());
  for (const auto& kv : node) {
    const int key_line = kv.first.Mark().line >= 0 ? kv.first.Mark().line + 1 : self_.line();
    if (!kv.first.IsScalar()) {
      throw InputError(self_.file(), key_line, self_.path(),
                       "expected a key name, got a complex key; allowed keys: " + join(allowed_));
    }
    const std::string key = kv.first.Scalar();
    const std::string path = child_path(self_.path(), key);
    if (std::find(allowed_.begin(), allowed_.end(), key) == allowed_.end()) {
      throw InputError(self_.file(), key_line, path,
                       "unknown key '" + key + "'; " + did_you_mean(key, allowed_) +
                           "allowed keys: " + join(allowed_));
    }
    for (const auto& [seen, field] : entries_) {
      if (seen == key) {
        throw InputError(self_.file(), key_line, path,
                         "duplicate key '" + key + "' (first given at line " +
                             std::to_string(field.key_line()) + ")");
      }
    }
    entries_.emplace_back(key, self_.child(kv.second, path, key_line));
  }
}

std::optional<Field> MapReader::opt(const std::string& key) const {
  for (const auto& [k, f] : entries_)
    if (k == key) return f;
  return std::nullopt;
}

Field MapReader::req(const std::string& key) const {
  if (auto f = opt(key)) return *f;
  throw InputError(self_.file(), line(), child_path(path(), key),
                   "missing required field '" + key + "'");
}

std::vector<Field> MapReader::list(const std::string& key) const {
  const auto f = opt(key);
  return f ? f->list() : std::vector<Field>{};
}

}  // namespace stroma::yaml
