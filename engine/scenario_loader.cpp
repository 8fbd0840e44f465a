/// \file scenario_loader.cpp
/// load_scenario / parse_scenario: YAML text -> validated ScenarioSpec.
///
/// The schema is strict: every map checks its keys against the allowed set (unknown keys are
/// errors, with a "did you mean" suggestion), every value is type- and range-checked, and every
/// error is an InputError carrying the file, the 1-based line and the dotted field path.
///
/// Structure: `Field` is one YAML node at a field path, with typed conversions that throw
/// InputError; `MapReader` is a YAML map at a field path that validates its keys on
/// construction and hands out `Field`s (optional or required). The section parsers below only
/// say which key goes where, with which range.

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "engine/scenario_spec.hpp"
#include "tissue/input_error.hpp"

namespace stroma {
namespace {

// ---------------------------------------------------------------------------------------------
// Small string helpers

std::string join(const std::vector<std::string>& items, const char* sep = ", ") {
  std::string s;
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i) s += sep;
    s += items[i];
  }
  return s;
}

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

std::string did_you_mean(const std::string& word, const std::vector<std::string>& candidates) {
  const std::string c = closest(word, candidates);
  return c.empty() ? std::string() : "did you mean '" + c + "'? ";
}

std::string format_number(double v) {
  std::ostringstream os;
  os.precision(15);
  os << v;
  return os.str();
}

std::string child_path(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}

std::string index_path(const std::string& parent, std::size_t i) {
  return parent + "[" + std::to_string(i) + "]";
}

/// Last component of a field path, for messages: "bodies[0].material.density" -> "density",
/// "gravity[1]" -> "gravity[1]".
std::string leaf_name(const std::string& path) {
  const auto dot = path.rfind('.');
  return dot == std::string::npos ? path : path.substr(dot + 1);
}

// ---------------------------------------------------------------------------------------------
// Numeric ranges

/// An allowed interval for a number; either bound may be absent, open or closed. A note can be
/// appended to the message when the value is below / above the range.
struct Range {
  std::optional<double> lo, hi;
  bool lo_closed = false, hi_closed = false;
  std::string note_lo, note_hi;

  /// -1 if v is below the range, +1 if above, 0 if inside.
  int violated(double v) const {
    if (lo && (lo_closed ? v < *lo : v <= *lo)) return -1;
    if (hi && (hi_closed ? v > *hi : v >= *hi)) return +1;
    return 0;
  }
  std::string describe() const {
    std::string s = "must be";
    if (lo) s += std::string(lo_closed ? " >= " : " > ") + format_number(*lo);
    if (lo && hi) s += " and";
    if (hi) s += std::string(hi_closed ? " <= " : " < ") + format_number(*hi);
    return s;
  }
};

Range any_value() { return {}; }
Range greater_than(double lo) { return Range{lo, std::nullopt, false, false, {}, {}}; }
Range at_least(double lo) { return Range{lo, std::nullopt, true, false, {}, {}}; }
Range open_interval(double lo, double hi) { return Range{lo, hi, false, false, {}, {}}; }

// ---------------------------------------------------------------------------------------------
// Enumerations

template <class E>
struct Choice {
  const char* name;
  E value;
};
template <class E>
using Choices = std::vector<Choice<E>>;

template <class E>
std::vector<std::string> names_of(const Choices<E>& choices) {
  std::vector<std::string> names;
  for (const auto& c : choices) names.emplace_back(c.name);
  return names;
}

const Choices<Integrator> kIntegrators = {{"implicit_euler", Integrator::ImplicitEuler},
                                          {"symplectic_euler", Integrator::SymplecticEuler},
                                          {"static", Integrator::Static}};
const Choices<LinearSolverKind> kLinearSolvers = {{"cg", LinearSolverKind::CG},
                                                  {"cholmod", LinearSolverKind::Cholmod}};
const Choices<Preconditioner> kPreconditioners = {{"jacobi", Preconditioner::Jacobi},
                                                  {"block_jacobi", Preconditioner::BlockJacobi},
                                                  {"none", Preconditioner::None},
                                                  {"warped_cholesky", Preconditioner::WarpedCholesky}};
// true/false kept as aliases: true = the best guess (extrapolate), false = off.
const Choices<WarmStart> kWarmStarts = {{"extrapolate", WarmStart::Extrapolate},
                                        {"previous", WarmStart::Previous},
                                        {"off", WarmStart::Off},
                                        {"true", WarmStart::Extrapolate},
                                        {"false", WarmStart::Off}};
const Choices<DamageMeasure> kDamageMeasures = {{"von_mises", DamageMeasure::VonMises},
                                                {"principal_strain", DamageMeasure::PrincipalStrain}};
const Choices<ElementModel> kElementModels = {{"corotational", ElementModel::Corotational},
                                              {"linear", ElementModel::Linear},
                                              {"stable_neo_hookean", ElementModel::StableNeoHookean}};
const Choices<ColorFieldSpec> kColorFields = {{"none", ColorFieldSpec::None},
                                              {"stress", ColorFieldSpec::Stress},
                                              {"damage", ColorFieldSpec::Damage}};
const Choices<RotationMethod> kRotationMethods = {{"polar", RotationMethod::Polar},
                                                  {"qr", RotationMethod::QR}};

// ---------------------------------------------------------------------------------------------
// Field: one YAML node at a field path

class MapReader;

/// One YAML node at a dotted field path, with typed conversions. Every failure throws
/// InputError pointing at this node's line and path.
class Field {
 public:
  /// `key_line` is the 1-based line of the key that introduced the node (for list items and the
  /// root: the node's own line). It is used when the node has no reliable position (empty
  /// values) and for "missing field" errors inside a map.
  Field(const std::string* file, YAML::Node node, std::string path, int key_line)
      : file_(file), node_(std::move(node)), path_(std::move(path)), key_line_(key_line) {
    const int own = node_.Mark().line;
    line_ = (node_.IsNull() || own < 0) ? key_line_ : own + 1;
    if (line_ <= 0) line_ = key_line_;
  }

  const std::string& file() const { return *file_; }
  const std::string& path() const { return path_; }
  int line() const { return line_; }
  int key_line() const { return key_line_; }
  const YAML::Node& yaml() const { return node_; }
  SourceLocation location() const { return {*file_, key_line_}; }

  [[noreturn]] void fail(const std::string& message) const { fail_at(line_, message); }
  [[noreturn]] void fail_at(int line, const std::string& message) const {
    throw InputError(*file_, line, path_, message);
  }

  /// A node below this one (same file).
  Field child(YAML::Node node, std::string path, int key_line) const {
    return Field(file_, std::move(node), std::move(path), key_line);
  }

  /// What the node is, for "expected X, got Y" messages.
  std::string got() const {
    if (!node_.IsDefined() || node_.IsNull()) return "an empty value";
    if (node_.IsSequence()) return "a list";
    if (node_.IsMap()) return "a map";
    if (is_string_tagged()) return "the quoted string '" + node_.Scalar() + "'";
    return "'" + node_.Scalar() + "'";
  }

  // -- typed conversions ------------------------------------------------------------------------

  double number(const Range& range = any_value()) const {
    const std::string text = plain_scalar("a number");
    const auto v = parse_double(text);
    if (!v) fail("expected a number, got " + got());
    if (!std::isfinite(*v)) fail("expected a finite number, got " + got());
    check_range(*v, text, range);
    return *v;
  }

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

  bool is_scalar() const { return node_.IsScalar(); }
  bool is_null() const { return node_.IsNull(); }

  bool boolean() const {
    const std::string text = plain_scalar("true or false");
    if (text == "true" || text == "True" || text == "TRUE") return true;
    if (text == "false" || text == "False" || text == "FALSE") return false;
    fail("expected true or false, got " + got());
  }

  /// A non-empty string scalar.
  std::string string() const {
    if (!node_.IsScalar()) fail("expected a string, got " + got());
    if (node_.Scalar().empty()) fail("must not be empty");
    return node_.Scalar();
  }

  Vec3 vec3() const {
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

  /// The items of a list (an empty value is not a list: write [] for an empty one).
  std::vector<Field> list() const {
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

  MapReader map(std::initializer_list<const char*> allowed) const;

  // -- uniform "store into" interface used by MapReader::read / require -------------------------

  void get(double& out, const Range& r = any_value()) const { out = number(r); }
  void get(int& out, const Range& r = any_value()) const { out = integer<int>(r); }
  void get(long& out, const Range& r = any_value()) const { out = integer<long>(r); }
  void get(bool& out) const { out = boolean(); }
  void get(std::string& out) const { out = string(); }
  void get(Vec3& out) const { out = vec3(); }
  template <class E>
  void get(E& out, const Choices<E>& choices) const { out = choice(choices); }
  template <class T, class... A>
  void get(std::optional<T>& out, const A&... args) const {
    T v{};
    get(v, args...);
    out = v;
  }

 private:
  bool is_string_tagged() const {
    const std::string& tag = node_.Tag();
    return tag == "!" || tag == "tag:yaml.org,2002:str";
  }

  /// The text of a plain (unquoted) scalar, or an "expected <what>" error.
  std::string plain_scalar(const char* what) const {
    if (!node_.IsScalar() || is_string_tagged())
      fail(std::string("expected ") + what + ", got " + got());
    return node_.Scalar();
  }

  static std::optional<double> parse_double(const std::string& text) {
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

  void check_range(double v, const std::string& text, const Range& range) const {
    const int side = range.violated(v);
    if (side == 0) return;
    std::string msg = leaf_name(path_) + " = " + text + " is out of range: " + range.describe();
    const std::string& note = side < 0 ? range.note_lo : range.note_hi;
    if (!note.empty()) msg += " (" + note + ")";
    fail(msg);
  }

  const std::string* file_;
  YAML::Node node_;
  std::string path_;
  int key_line_;
  int line_;
};

// ---------------------------------------------------------------------------------------------
// MapReader: a YAML map at a field path, with a fixed set of allowed keys

class MapReader {
 public:
  /// Checks that `self` is a map whose keys are all in `allowed`, each at most once.
  MapReader(const Field& self, std::initializer_list<const char*> allowed) : self_(self) {
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

  const std::string& file() const { return self_.file(); }
  const std::string& path() const { return self_.path(); }
  /// Line of the map: the line of the key that introduced it, or of the list item.
  int line() const { return self_.key_line(); }
  SourceLocation location() const { return self_.location(); }
  [[noreturn]] void fail(const std::string& message) const { self_.fail_at(line(), message); }

  std::optional<Field> opt(const std::string& key) const {
    for (const auto& [k, f] : entries_)
      if (k == key) return f;
    return std::nullopt;
  }

  Field req(const std::string& key) const {
    if (auto f = opt(key)) return *f;
    throw InputError(self_.file(), line(), child_path(path(), key),
                     "missing required field '" + key + "'");
  }

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
  std::vector<Field> list(const std::string& key) const {
    const auto f = opt(key);
    return f ? f->list() : std::vector<Field>{};
  }

 private:
  Field self_;
  std::vector<std::string> allowed_;
  std::vector<std::pair<std::string, Field>> entries_;  ///< in file order
};

MapReader Field::map(std::initializer_list<const char*> allowed) const {
  return MapReader(*this, allowed);
}

// ---------------------------------------------------------------------------------------------
// Section parsers

struct Context {
  std::string file;
  std::string base_dir;
};

std::string resolve_path(const std::string& p, const std::string& base_dir) {
  namespace fs = std::filesystem;
  const fs::path path(p);
  if (path.is_absolute() || base_dir.empty()) return path.lexically_normal().string();
  return (fs::path(base_dir) / path).lexically_normal().string();
}

// Each parser takes the Field of its section and declares the section's allowed keys.

const Choices<bool> kCapPolicies = {{"substep", true}, {"continue", false}};

SolverSpec parse_solver(const Field& f) {
  const MapReader m = f.map({"integrator", "linear_solver", "preconditioner", "max_iterations",
                             "tolerance", "warm_start", "static_tolerance", "static_max_newton", "on_cg_cap",
                             "newton_iterations", "newton_tolerance"});
  SolverSpec s;
  s.where = m.location();
  if (auto i = m.opt("integrator")) s.integrator_where = i->location();
  m.read("integrator", s.integrator, kIntegrators);
  m.read("linear_solver", s.linear_solver, kLinearSolvers);
  m.read("preconditioner", s.preconditioner, kPreconditioners);
  m.read("max_iterations", s.max_iterations, greater_than(0));
  m.read("tolerance", s.tolerance, open_interval(0, 1));
  m.read("warm_start", s.warm_start, kWarmStarts);
  m.read("static_tolerance", s.static_tolerance, greater_than(0));
  m.read("static_max_newton", s.static_max_newton, greater_than(0));
  m.read("on_cg_cap", s.substep_on_cg_cap, kCapPolicies);
  if (const auto f = m.opt("newton_iterations")) {  // a count ≥ 1, or auto (stored as 0)
    const std::string v = f->yaml().IsScalar() ? f->yaml().Scalar() : std::string();
    if (v == "auto")
      s.newton_iterations = 0;
    else if (v.empty() || v.find_first_not_of("+-0123456789") != std::string::npos)
      f->fail("expected a whole number >= 1 or auto, got " + f->got());
    else
      f->get(s.newton_iterations, greater_than(0));
  }
  m.read("newton_tolerance", s.newton_tolerance, open_interval(0, 1));
  return s;
}

MaterialSpec parse_material(const Field& f) {
  const MapReader m = f.map({"model", "rotation", "young_modulus", "poisson_ratio", "density",
                             "rayleigh_mass", "rayleigh_stiffness", "damage"});
  MaterialSpec mat;
  mat.where = m.location();
  Range nu = open_interval(-1, 0.5);
  nu.note_hi = "0.5 is incompressible; use 0.49 or lower";
  m.read("model", mat.model, kElementModels);
  m.read("rotation", mat.rotation, kRotationMethods);
  m.require("young_modulus", mat.young_modulus, greater_than(0));
  m.require("poisson_ratio", mat.poisson_ratio, nu);
  m.require("density", mat.density, greater_than(0));
  m.read("rayleigh_mass", mat.rayleigh_mass, at_least(0));
  m.read("rayleigh_stiffness", mat.rayleigh_stiffness, at_least(0));
  if (auto f2 = m.opt("damage")) {
    const MapReader dm = f2->map({"measure", "warning", "onset", "rupture"});
    DamageSpec& d = mat.damage;
    d.enabled = true;
    dm.read("measure", d.measure, kDamageMeasures);
    dm.require("onset", d.onset, greater_than(0));
    dm.require("rupture", d.rupture, greater_than(0));
    dm.read("warning", d.warning, greater_than(0));
    if (d.rupture <= d.onset)
      dm.req("rupture").fail("rupture = " + format_number(d.rupture) + " must be greater than onset = " +
                             format_number(d.onset));
    if (d.warning > d.onset)
      dm.req("warning").fail("warning = " + format_number(d.warning) + " must not exceed onset = " +
                             format_number(d.onset) + " (it warns before harm)");
    if (d.warning == 0) d.warning = d.onset;
  }
  return mat;
}

BoxSpec parse_box(const Field& f) {
  const MapReader m = f.map({"min", "max"});
  BoxSpec box;
  const Field min = m.req("min");
  const Field max = m.req("max");
  box.min = min.vec3();
  box.max = max.vec3();
  for (int k = 0; k < 3; ++k) {
    if (box.min[k] > box.max[k]) {
      min.fail("box min[" + std::to_string(k) + "] = " + format_number(box.min[k]) +
               " is greater than max[" + std::to_string(k) + "] = " + format_number(box.max[k]) +
               ": min must be <= max componentwise");
    }
  }
  return box;
}

/// The selection part of a `fixed:` or `loads:` entry: exactly one of `box` / `nodes`.
NodeSelection parse_selection(const MapReader& m) {
  NodeSelection sel;
  sel.where = m.location();
  const auto box = m.opt("box");
  const auto nodes = m.opt("nodes");
  if (box && nodes) {
    const int later = std::max(box->key_line(), nodes->key_line());
    throw InputError(m.file(), later, m.path(), "give either 'box' or 'nodes', not both");
  }
  if (!box && !nodes) m.fail("a node selection needs exactly one of 'box' or 'nodes'");
  if (box) sel.box = parse_box(*box);
  if (nodes) {
    const auto items = nodes->list();
    if (items.empty()) nodes->fail("empty node list: give at least one 0-based node index");
    Range index = at_least(0);
    index.note_lo = "node indices are 0-based";
    for (const auto& item : items) sel.nodes.push_back(item.integer<int>(index));
  }
  return sel;
}

NodeSelection parse_fixed(const Field& f) {
  const MapReader m = f.map({"box", "nodes", "axes"});
  NodeSelection sel = parse_selection(m);
  if (auto a = m.opt("axes")) {
    const auto items = a->list();
    if (items.empty()) a->fail("empty axes list: give some of x, y, z (or omit axes to fix all)");
    sel.axes = 0;
    for (const auto& item : items) {
      const std::string name = item.string();
      if (name == "x") sel.axes |= 1;
      else if (name == "y") sel.axes |= 2;
      else if (name == "z") sel.axes |= 4;
      else item.fail("unknown axis '" + name + "': expected x, y or z");
    }
  }
  return sel;
}

NodalLoadSpec parse_load(const Field& f) {
  const MapReader m = f.map({"box", "nodes", "force", "per_node"});
  NodalLoadSpec load;
  load.select = parse_selection(m);
  m.require("force", load.force);
  m.read("per_node", load.per_node);
  return load;
}

BodySpec parse_body(const MapReader& m, const Context& ctx) {
  BodySpec b;
  b.where = m.location();
  m.require("name", b.name);
  std::string mesh;
  m.require("mesh", mesh);
  b.mesh_where = m.req("mesh").location();
  b.mesh_path = resolve_path(mesh, ctx.base_dir);
  m.read("scale", b.scale, greater_than(0));
  m.read("translate", b.translate);
  b.material = parse_material(m.req("material"));
  for (const auto& item : m.list("fixed")) b.fixed.push_back(parse_fixed(item));
  for (const auto& item : m.list("loads")) b.loads.push_back(parse_load(item));
  if (auto f = m.opt("visual")) {
    // `visual: FILE` or `visual: {mesh: FILE, max_distance: D}`.
    VisualSpec v;
    std::string path;
    if (f->is_scalar()) {
      path = f->string();
      v.where = f->location();
    } else {
      const MapReader vm = f->map({"mesh", "max_distance"});
      vm.require("mesh", path);
      v.where = vm.req("mesh").location();
      vm.read("max_distance", v.max_distance, at_least(0));
    }
    v.mesh_path = resolve_path(path, ctx.base_dir);
    b.visual = v;
  }
  return b;
}

/// A colour: three numbers in 0..1 (sRGB).
Vec3 parse_color(const Field& f) {
  const Vec3 c = f.vec3();
  for (double x : c)
    if (!(x >= 0 && x <= 1)) f.fail("colour components must be in 0..1 (sRGB), got " + format_number(x));
  return c;
}

RenderSpec parse_render(const Field& f) {
  const MapReader m = f.map({"camera", "view_direction", "light", "colors", "color_field", "color_range",
                             "wireframe", "contacts"});
  RenderSpec r;
  if (auto c = m.opt("camera")) {
    const MapReader cm = c->map({"position", "target", "up", "fov"});
    if (cm.opt("position") || cm.opt("target")) {
      cm.require("position", r.camera_position);
      cm.require("target", r.camera_target);
      r.has_camera = true;
      const Vec3 d{r.camera_target[0] - r.camera_position[0], r.camera_target[1] - r.camera_position[1],
                   r.camera_target[2] - r.camera_position[2]};
      if (d[0] == 0 && d[1] == 0 && d[2] == 0) cm.req("target").fail("target must differ from position");
    }
    if (auto u = cm.opt("up")) {
      const Vec3 up = u->vec3();
      if (up[0] == 0 && up[1] == 0 && up[2] == 0) u->fail("up must not be zero");
      r.camera_up = up;
    }
    cm.read("fov", r.fov_deg, open_interval(0, 170));
  }
  if (auto v = m.opt("view_direction")) {
    r.view_direction = v->vec3();
    if (r.view_direction[0] == 0 && r.view_direction[1] == 0 && r.view_direction[2] == 0)
      v->fail("view_direction must not be zero");
  }
  if (auto l = m.opt("light")) {
    const MapReader lm = l->map({"direction"});
    lm.read("direction", r.light_direction);
  }
  if (auto c = m.opt("colors")) {
    const MapReader cm = c->map({"tissue", "background"});
    if (auto t = cm.opt("tissue")) r.tissue_color = parse_color(*t);
    if (auto b = cm.opt("background")) r.background_color = parse_color(*b);
  }
  m.read("color_field", r.color_field, kColorFields);
  if (auto cr = m.opt("color_range")) {
    const auto items = cr->list();
    if (items.size() != 2) cr->fail("expected [min, max]");
    r.color_min = items[0].number();
    r.color_max = items[1].number();
    if (!(r.color_max > r.color_min)) cr->fail("max must be greater than min");
  }
  m.read("wireframe", r.wireframe);
  m.read("contacts", r.contacts);
  return r;
}

ProbeSpec parse_probe(const MapReader& m) {
  ProbeSpec p;
  p.where = m.location();
  m.require("name", p.name);
  m.require("body", p.body);
  m.require("point", p.point);
  return p;
}

RunSpec parse_run(const Field& f) {
  const MapReader m = f.map({"duration", "steps"});
  RunSpec run;
  const auto duration = m.opt("duration");
  const auto steps = m.opt("steps");
  if (duration && steps) {
    const int later = std::max(duration->key_line(), steps->key_line());
    throw InputError(m.file(), later, m.path(), "give either 'duration' or 'steps', not both");
  }
  m.read("duration", run.duration, greater_than(0));
  m.read("steps", run.steps, greater_than(0));
  return run;
}

BodyContactSpec parse_body_contact(const Field& f) {
  BodyContactSpec c;
  c.where = f.location();
  if (f.is_null()) return c;  // `body_contact:` alone: automatic settings
  const MapReader m = f.map({"stiffness", "max_depth"});
  m.read("stiffness", c.stiffness, at_least(0));
  m.read("max_depth", c.max_depth, at_least(0));
  return c;
}

CheckSpec parse_check(const Field& f) {
  const MapReader m = f.map({"max_error", "mean_error"});
  CheckSpec c;
  m.read("max_error", c.max_error, greater_than(0));
  m.read("mean_error", c.mean_error, greater_than(0));
  return c;
}

const Choices<InvalidCommandPolicy> kInvalidPolicies = {{"reject", InvalidCommandPolicy::Reject},
                                                        {"clamp", InvalidCommandPolicy::Clamp}};

const Choices<ToolShape> kToolShapes = {{"sphere", ToolShape::Sphere},
                                        {"probe", ToolShape::Probe},
                                        {"blade", ToolShape::Blade},
                                        {"grasper", ToolShape::Grasper}};

ToolEntry parse_tool(const MapReader& m, const Context& ctx) {
  ToolEntry t;
  t.where = m.location();
  m.require("name", t.spec.name);
  std::string script;
  if (m.read("script", script)) t.script = resolve_path(script, ctx.base_dir);
  if (auto w = m.opt("workspace")) {
    const BoxSpec b = parse_box(*w);
    t.spec.workspace_min = b.min;
    t.spec.workspace_max = b.max;
  }
  m.read("max_speed", t.spec.max_speed, greater_than(0));
  m.read("timeout", t.spec.timeout, greater_than(0));
  m.read("on_invalid", t.spec.on_invalid, kInvalidPolicies);
  if (auto f = m.opt("shape")) {
    const MapReader sm = f->map({"type", "radius", "shaft_radius", "length"});
    sm.require("type", t.spec.shape, kToolShapes);
    sm.require("radius", t.spec.radius, greater_than(0));
    if (t.spec.shape == ToolShape::Probe) {
      sm.require("length", t.spec.shaft_length, greater_than(0));
      t.spec.shaft_radius = t.spec.radius;
      sm.read("shaft_radius", t.spec.shaft_radius, greater_than(0));
      if (t.spec.shaft_radius > t.spec.radius)
        sm.req("shaft_radius").fail("shaft_radius = " + format_number(t.spec.shaft_radius) +
                                    " must not exceed the tip radius " + format_number(t.spec.radius));
    } else if (t.spec.shape == ToolShape::Blade || t.spec.shape == ToolShape::Grasper) {
      sm.require("length", t.spec.shaft_length, greater_than(0));
      if (sm.opt("shaft_radius")) sm.req("shaft_radius").fail("'shaft_radius' belongs to type probe");
    } else if (sm.opt("length") || sm.opt("shaft_radius")) {
      sm.fail("'length' and 'shaft_radius' belong to types probe, blade, grasper (a sphere has only a radius)");
    }
  }
  if (auto f = m.opt("contact")) {
    const MapReader cm = f->map({"stiffness", "damping", "friction"});
    cm.read("stiffness", t.spec.contact_stiffness, greater_than(0));
    cm.read("damping", t.spec.contact_damping, at_least(0));
    cm.read("friction", t.spec.friction, at_least(0));
  }
  m.read("max_force", t.spec.max_force, greater_than(0));
  if (auto f = m.opt("coupling")) {
    const MapReader cm = f->map({"stiffness", "damping"});
    cm.require("stiffness", t.spec.coupling_stiffness, greater_than(0));
    cm.read("damping", t.spec.coupling_damping, at_least(0));
    if (t.spec.shape == ToolShape::None)
      f->fail("a coupled tool needs a shape (the proxy is what touches the tissue)");
  }
  if (auto f = m.opt("grasp")) {
    const MapReader gm = f->map({"close", "open", "reach", "stiffness"});
    t.spec.can_grasp = true;
    gm.read("close", t.spec.grasp_close, at_least(0));
    gm.read("open", t.spec.grasp_open, greater_than(0));
    gm.read("reach", t.spec.grasp_reach, greater_than(0));
    gm.read("stiffness", t.spec.grasp_stiffness, greater_than(0));
    if (t.spec.grasp_open <= t.spec.grasp_close)
      gm.req("open").fail("open must be greater than close (hysteresis), got open = " +
                          format_number(t.spec.grasp_open) + ", close = " + format_number(t.spec.grasp_close));
    if (t.spec.shape == ToolShape::None)
      f->fail("a grasping tool needs a shape (shape: {type: sphere, radius: ...})");
  }
  return t;
}

/// Names must be unique within a list; reports the second occurrence.
void check_unique_name(std::map<std::string, int>& seen, const std::string& name,
                       const Field& name_field, const char* what) {
  const auto [it, inserted] = seen.emplace(name, name_field.line());
  if (!inserted) {
    name_field.fail(std::string("duplicate ") + what + " name '" + name +
                    "' (first defined at line " + std::to_string(it->second) + ")");
  }
}

ScenarioSpec parse_root(const MapReader& m, const Context& ctx) {
  ScenarioSpec s;
  s.file = ctx.file;
  m.read("name", s.name);
  m.read("time_step", s.time_step, greater_than(0));
  m.read("gravity", s.gravity);
  if (auto f = m.opt("solver")) s.solver = parse_solver(*f);

  const Field bodies = m.req("bodies");
  const auto body_items = bodies.list();
  if (body_items.empty()) bodies.fail("at least one body is required");
  std::map<std::string, int> body_names;
  for (const auto& item : body_items) {
    const MapReader bm = item.map({"name", "mesh", "scale", "translate", "material", "fixed", "loads", "visual"});
    s.bodies.push_back(parse_body(bm, ctx));
    check_unique_name(body_names, s.bodies.back().name, bm.req("name"), "body");
  }

  std::map<std::string, int> probe_names;
  std::vector<std::string> known_bodies;
  for (const auto& b : s.bodies) known_bodies.push_back(b.name);
  for (const auto& item : m.list("probes")) {
    const MapReader pm = item.map({"name", "body", "point"});
    s.probes.push_back(parse_probe(pm));
    const ProbeSpec& p = s.probes.back();
    check_unique_name(probe_names, p.name, pm.req("name"), "probe");
    if (body_names.count(p.body) == 0) {
      pm.req("body").fail("unknown body '" + p.body + "': " + did_you_mean(p.body, known_bodies) +
                          "bodies are: " + join(known_bodies));
    }
  }

  std::map<std::string, int> tool_names;
  for (const auto& item : m.list("tools")) {
    const MapReader tm = item.map({"name", "script", "workspace", "max_speed", "timeout", "on_invalid",
                                   "shape", "contact", "max_force", "grasp", "coupling"});
    s.tools.push_back(parse_tool(tm, ctx));
    check_unique_name(tool_names, s.tools.back().spec.name, tm.req("name"), "tool");
  }

  if (auto f = m.opt("body_contact")) {
    if (s.bodies.size() < 2) f->fail("body_contact needs at least two bodies (this scenario has one)");
    s.body_contact = parse_body_contact(*f);
  }
  if (auto f = m.opt("run")) s.run = parse_run(*f);
  if (auto f = m.opt("check")) s.check = parse_check(*f);
  if (auto f = m.opt("render")) s.render = parse_render(*f);
  return s;
}

}  // namespace

ScenarioSpec parse_scenario(const std::string& yaml_text, const std::string& file,
                            const std::string& base_dir) {
  std::vector<YAML::Node> docs;
  try {
    docs = YAML::LoadAll(yaml_text);
  } catch (const YAML::Exception& e) {
    const int line = e.mark.is_null() || e.mark.line < 0 ? 0 : e.mark.line + 1;
    throw InputError(file, line, "", "YAML syntax error: " + e.msg);
  }
  if (docs.empty() || docs.front().IsNull())
    throw InputError(file, 0, "", "scenario file is empty");
  if (docs.size() > 1) {
    const int l = docs[1].Mark().line;
    throw InputError(file, l >= 0 ? l + 1 : 0, "",
                     "expected a single YAML document, found " + std::to_string(docs.size()));
  }

  const Context ctx{file, base_dir};
  const YAML::Node& root = docs.front();
  const int root_line = root.Mark().line >= 0 ? root.Mark().line + 1 : 1;
  const Field root_field(&ctx.file, root, "", root_line);
  const MapReader m = root_field.map(
      {"name", "time_step", "gravity", "solver", "bodies", "probes", "tools", "body_contact", "run", "check",
       "render"});
  return parse_root(m, ctx);
}

ScenarioSpec load_scenario(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_directory(path, ec))
    throw InputError(path, 0, "", "cannot open scenario file: it is a directory");
  errno = 0;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int err = errno;
    throw InputError(path, 0, "",
                     std::string("cannot open scenario file") +
                         (err != 0 ? std::string(": ") + std::strerror(err) : std::string()));
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw InputError(path, 0, "", "cannot read scenario file");
  return parse_scenario(text.str(), path, fs::path(path).parent_path().string());
}

}  // namespace stroma
