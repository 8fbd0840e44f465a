/// \file mesh_io.cpp
/// Tetrahedral mesh readers (see mesh_io.hpp). Each reader slurps the whole input into one
/// buffer and walks it with a small Scanner; numbers go through std::from_chars. Errors carry a
/// byte offset that is turned into a line number only when an error is actually thrown, so the
/// happy path never counts lines.
#include "io/mesh_io.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <bit>
#include <charconv>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <string_view>
#include <unordered_map>
#include <vector>


#include "io/inflate.hpp"
#include "tissue/input_error.hpp"
#include "io/text_scan.hpp"

namespace stroma {
namespace {

using namespace text;  // is_space, lower, iequals, clip, parse_number (io/text_scan.hpp)

constexpr size_t kNoPos = std::string_view::npos;

// =============================================================================================
// Shared text machinery
// =============================================================================================

/// Where an error is, in terms the user can act on: file text (to turn an offset into a line
/// number), file name and the section being read.
struct ParseContext {
  std::string_view text;
  std::string source;
  std::string field;
  /// Offsets from here on lie in or after raw binary data, where line numbers mean nothing.
  size_t binary_from = kNoPos;

  int line_at(size_t pos) const {
    if (pos == kNoPos || pos >= binary_from) return 0;
    pos = std::min(pos, text.size());
    // The end of a file that ends with a newline belongs to its last line, not a phantom one.
    if (pos == text.size() && pos > 0 && text[pos - 1] == '\n') --pos;
    return 1 +
           static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(pos), '\n'));
  }
  [[noreturn]] void fail(size_t pos, const std::string& message) const {
    throw InputError(source, line_at(pos), field, message);
  }
};

/// Walks a range [pos, end) of the file text: whitespace-separated tokens, numbers, lines.
/// A Scanner for a single line (from next_line) stops at that line's end.
class Scanner {
 public:
  Scanner(const ParseContext& ctx, size_t begin, size_t end, const char* end_name)
      : ctx_(&ctx), pos_(begin), end_(end), end_name_(end_name) {}

  size_t pos() const { return pos_; }
  size_t end() const { return end_; }
  void seek(size_t pos) { pos_ = pos; }
  const char* end_name() const { return end_name_; }

  void skip_space() {
    while (pos_ < end_ && is_space(ctx_->text[pos_])) ++pos_;
  }
  bool at_end() {
    skip_space();
    return pos_ >= end_;
  }
  /// Offset of the next token (after whitespace), for pointing errors at it.
  size_t token_pos() {
    skip_space();
    return pos_;
  }
  char peek() { return at_end() ? '\0' : ctx_->text[pos_]; }

  /// Next whitespace-delimited token; empty at the end of the range.
  std::string_view token() {
    skip_space();
    const size_t begin = pos_;
    while (pos_ < end_ && !is_space(ctx_->text[pos_])) ++pos_;
    return ctx_->text.substr(begin, pos_ - begin);
  }

  int64_t integer(std::string_view what) {
    const size_t at = token_pos();
    const std::string_view tok = token();
    if (tok.empty()) fail_missing(what);
    int64_t v = 0;
    if (!parse_number(tok, v))
      ctx_->fail(at, fmt::format("invalid {} '{}' (expected an integer)", what, clip(tok)));
    return v;
  }
  double real(std::string_view what) {
    const size_t at = token_pos();
    const std::string_view tok = token();
    if (tok.empty()) fail_missing(what);
    double v = 0;
    if (!parse_number(tok, v)) ctx_->fail(at, fmt::format("non-numeric {} '{}'", what, clip(tok)));
    if (!std::isfinite(v)) ctx_->fail(at, fmt::format("non-finite {} '{}'", what, clip(tok)));
    return v;
  }
  /// A count from a section header: an integer in [0, INT32_MAX] (indices are int32_t).
  int64_t count(std::string_view what) {
    const size_t at = token_pos();
    const int64_t n = integer(what);
    if (n < 0 || n > std::numeric_limits<int32_t>::max())
      ctx_->fail(at, fmt::format("invalid {} {}", what, n));
    return n;
  }

  /// For line scanners: nothing may follow what was read.
  void expect_line_end() {
    if (!at_end())
      ctx_->fail(pos_,
                 fmt::format("unexpected extra value '{}' at the end of the line", clip(token())));
  }
  /// The rest of the range, trimmed (for a line scanner: the rest of the line).
  std::string_view rest() {
    skip_space();
    return trim(ctx_->text.substr(pos_, end_ - pos_));
  }

  /// The rest of the current line, blank or not; nullopt at the end of the range.
  std::optional<std::string_view> raw_line() {
    if (pos_ >= end_) return std::nullopt;
    const size_t stop = line_stop();
    std::string_view line = ctx_->text.substr(pos_, stop - pos_);
    pos_ = stop < end_ ? stop + 1 : end_;
    return trim(line);
  }
  /// Moves past the end of the current line (binary data in legacy VTK starts after it).
  void skip_line() {
    const size_t stop = line_stop();
    pos_ = stop < end_ ? stop + 1 : end_;
  }
  /// The next non-blank line as a scanner of its own, positioned on its first token.
  std::optional<Scanner> next_line() {
    while (pos_ < end_) {
      const size_t begin = pos_;
      const size_t stop = line_stop();
      pos_ = stop < end_ ? stop + 1 : end_;
      Scanner line(*ctx_, begin, stop, "line");
      if (!line.at_end()) return line;
    }
    return std::nullopt;
  }

  [[noreturn]] void fail_missing(std::string_view what) const {
    ctx_->fail(pos_, fmt::format("missing {} (reached the end of the {})", what, end_name_));
  }

 private:
  size_t line_stop() const {
    const size_t nl = ctx_->text.find('\n', pos_);
    return (nl == kNoPos || nl >= end_) ? end_ : nl;
  }

  const ParseContext* ctx_;
  size_t pos_;
  size_t end_;
  const char* end_name_;  // what the range end is, for "missing X (reached the end of the ...)"
};

/// A keyword or tag where a number should be means the data ran out early ("truncated"), which is
/// a more useful message than "non-numeric value 'CELLS'".
bool looks_like_keyword(std::string_view tok) {
  if (tok.empty() || tok[0] == '$' || tok[0] == '<') return true;
  return tok.size() >= 3 && std::all_of(tok.begin(), tok.end(),
                                        [](char c) { return (c >= 'A' && c <= 'Z') || c == '_'; });
}

/// Reads exactly `count` whitespace-separated numbers (ASCII data blocks of VTK files).
template <class T>
std::vector<T> read_values(const ParseContext& ctx, Scanner& sc, size_t count,
                           std::string_view what) {
  std::vector<T> out;
  // Every value takes at least two characters: never let a bogus count allocate gigabytes.
  out.reserve(std::min(count, (sc.end() - sc.pos()) / 2 + 1));
  for (size_t i = 0; i < count; ++i) {
    const size_t at = sc.token_pos();
    const std::string_view tok = sc.token();
    T v{};
    if (!tok.empty() && parse_number(tok, v)) {
      if constexpr (std::is_floating_point_v<T>)
        if (!std::isfinite(v)) ctx.fail(at, fmt::format("non-finite value '{}' in {}", clip(tok), what));
      out.push_back(v);
      continue;
    }
    if (tok.empty())
      ctx.fail(at, fmt::format("truncated: expected {} {}, found {} before the end of the {}",
                               count, what, i, sc.end_name()));
    if (looks_like_keyword(tok))
      ctx.fail(at, fmt::format("truncated: expected {} {}, found {} before '{}'", count, what, i,
                               clip(tok)));
    if constexpr (std::is_integral_v<T>)
      ctx.fail(at, fmt::format("invalid value '{}' in {} (expected an integer)", clip(tok), what));
    else
      ctx.fail(at, fmt::format("non-numeric value '{}' in {}", clip(tok), what));
  }
  return out;
}

std::string slurp(std::istream& in) {
  std::ostringstream ss;
  ss << in.rdbuf();
  return std::move(ss).str();
}

// =============================================================================================
// Binary values (legacy VTK BINARY, VTU inline binary)
// =============================================================================================

enum class Kind { Signed, Unsigned, Float };
struct ScalarType {
  Kind kind;
  int size;  // bytes
};

std::optional<ScalarType> legacy_vtk_type(std::string_view name) {
  static constexpr std::pair<std::string_view, ScalarType> kTypes[] = {
      {"float", {Kind::Float, 4}},         {"double", {Kind::Float, 8}},
      {"char", {Kind::Signed, 1}},         {"unsigned_char", {Kind::Unsigned, 1}},
      {"short", {Kind::Signed, 2}},        {"unsigned_short", {Kind::Unsigned, 2}},
      {"int", {Kind::Signed, 4}},          {"unsigned_int", {Kind::Unsigned, 4}},
      {"long", {Kind::Signed, 8}},         {"unsigned_long", {Kind::Unsigned, 8}},
      {"vtktypeint32", {Kind::Signed, 4}}, {"vtktypeuint32", {Kind::Unsigned, 4}},
      {"vtktypeint64", {Kind::Signed, 8}}, {"vtktypeuint64", {Kind::Unsigned, 8}},
      {"vtkidtype", {Kind::Signed, 8}},
  };
  for (const auto& [n, t] : kTypes)
    if (iequals(n, name)) return t;
  return std::nullopt;
}

std::optional<ScalarType> xml_vtk_type(std::string_view name) {
  static constexpr std::pair<std::string_view, ScalarType> kTypes[] = {
      {"Float32", {Kind::Float, 4}}, {"Float64", {Kind::Float, 8}},
      {"Int8", {Kind::Signed, 1}},   {"UInt8", {Kind::Unsigned, 1}},
      {"Int16", {Kind::Signed, 2}},  {"UInt16", {Kind::Unsigned, 2}},
      {"Int32", {Kind::Signed, 4}},  {"UInt32", {Kind::Unsigned, 4}},
      {"Int64", {Kind::Signed, 8}},  {"UInt64", {Kind::Unsigned, 8}},
  };
  for (const auto& [n, t] : kTypes)
    if (n == name) return t;
  return std::nullopt;
}

uint64_t load_bits(const unsigned char* p, int size, bool big_endian) {
  uint64_t v = 0;
  for (int i = 0; i < size; ++i) v |= uint64_t{p[i]} << (8 * (big_endian ? size - 1 - i : i));
  return v;
}

int64_t sign_extend(uint64_t bits, int size) {
  if (size == 8) return static_cast<int64_t>(bits);
  const uint64_t sign = uint64_t{1} << (8 * size - 1);
  return static_cast<int64_t>((bits ^ sign) - sign);
}

/// Decodes `count` values of type `t` into doubles (coordinates) or int64_t (indices, types).
/// Integer outputs require an integer `t`; callers check that first, with a proper message.
template <class T>
std::vector<T> decode_values(const unsigned char* p, size_t count, ScalarType t, bool big_endian) {
  std::vector<T> out(count);
  for (size_t i = 0; i < count; ++i, p += t.size) {
    const uint64_t bits = load_bits(p, t.size, big_endian);
    if constexpr (std::is_floating_point_v<T>) {
      if (t.kind == Kind::Float)
        out[i] = t.size == 4 ? std::bit_cast<float>(static_cast<uint32_t>(bits))
                             : std::bit_cast<double>(bits);
      else
        out[i] = t.kind == Kind::Signed ? static_cast<T>(sign_extend(bits, t.size))
                                        : static_cast<T>(bits);
    } else {
      out[i] = t.kind == Kind::Signed ? sign_extend(bits, t.size) : static_cast<int64_t>(bits);
    }
  }
  return out;
}

std::vector<Vec3> to_points(const std::vector<double>& xyz) {
  std::vector<Vec3> points(xyz.size() / 3);
  for (size_t i = 0; i < points.size(); ++i)
    points[i] = {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]};
  return points;
}

// =============================================================================================
// gmsh
// =============================================================================================

constexpr int64_t kGmshTet4 = 4;

/// gmsh types of tetrahedra with more than 4 nodes (TET10, TET20, TET35, TET56).
/// Gmsh numbers its element types 1..140 (MSH_MAX_NUM); anything else is a corrupt file or a
/// format this reader does not know, not an element type to skip silently.
bool is_gmsh_element_type(int64_t type) { return type >= 1 && type <= 140; }

std::string gmsh_unknown_type_message(int64_t type) {
  return fmt::format("unknown element type {} (gmsh element types are 1..140; 4 is the linear "
                     "tetrahedron)", type);
}

bool is_gmsh_higher_order_tet(int64_t type) {
  return type == 11 || type == 29 || type == 30 || type == 31;
}

std::string gmsh_higher_order_message(int64_t type) {
  return fmt::format("{} tetrahedra (type {}) are not supported; re-mesh with -order 1",
                     type == 11 ? "quadratic" : "higher-order", type);
}

class GmshReader {
 public:
  explicit GmshReader(ParseContext& ctx) : ctx_(ctx), file_(ctx, 0, ctx.text.size(), "file") {}

  TetMesh read() {
    read_format();
    bool have_nodes = false;
    bool have_elements = false;
    const std::string_view nodes_name = version_ == 1 ? "$NOD" : "$Nodes";
    const std::string_view elements_name = version_ == 1 ? "$ELM" : "$Elements";
    while (auto line = file_.next_line()) {
      const size_t at = line->pos();
      const std::string_view name = line->rest();
      if (name[0] != '$') {
        ctx_.field.clear();
        ctx_.fail(at, fmt::format("unexpected text '{}' outside a section", clip(name)));
      }
      ctx_.field = std::string(name);
      if (name == nodes_name || name == elements_name) {
        const bool nodes = name == nodes_name;
        if (nodes ? have_nodes : have_elements)
          ctx_.fail(at, fmt::format("second {} section", name));
        if (!nodes && !have_nodes) ctx_.fail(at, fmt::format("{} before {}", name, nodes_name));
        (nodes ? have_nodes : have_elements) = true;
        if (nodes) {
          version_ == 4 ? read_nodes_v4() : read_nodes_v1v2();
        } else {
          elements_pos_ = at;
          version_ == 4 ? read_elements_v4() : read_elements_v1v2();
        }
      } else if (name == "$PhysicalNames") {
        read_physical_names();
      } else if (name == "$Entities" && version_ == 4) {
        if (have_elements) ctx_.fail(at, "$Entities after $Elements");
        read_entities_v4();
      } else {
        skip_section(name, at);
      }
    }
    ctx_.field.clear();
    if (!have_nodes) ctx_.fail(kNoPos, fmt::format("no {} section", nodes_name));
    if (!have_elements) ctx_.fail(kNoPos, fmt::format("no {} section", elements_name));
    if (tets_.empty()) {
      ctx_.field = std::string(elements_name);
      ctx_.fail(elements_pos_, fmt::format("no tetrahedra in the mesh (found {} elements of other "
                                           "types; only linear tetrahedra, type 4, are read)",
                                           other_elements_));
    }
    TetMesh out;
    out.nodes = std::move(nodes_);
    out.tets = std::move(tets_);
    out.source = ctx_.source;
    // Regions only when some tetrahedron has a physical group.
    if (std::any_of(tags_.begin(), tags_.end(), [](int32_t t) { return t != 0; })) out.tet_tags = std::move(tags_);
    out.tag_names = std::move(names_);
    return out;
  }

 private:
  /// "$PhysicalNames": a count, then "dimension tag \"name\"" per line; names of volumes kept.
  void read_physical_names() {
    Scanner header = header_line("physical name count");
    const int64_t count = header.count("physical name count");
    header.expect_line_end();
    for (int64_t i = 0; i < count; ++i) {
      Scanner line = body_line([&] { return fmt::format("expected {} physical names, found {}", count, i); });
      const int64_t dim = line.integer("dimension");
      const size_t tag_pos = line.token_pos();
      const int64_t tag = line.integer("physical tag");
      std::string_view rest = line.rest();
      while (!rest.empty() && (rest.front() == ' ' || rest.front() == '\t')) rest.remove_prefix(1);
      while (!rest.empty() && (rest.back() == ' ' || rest.back() == '\t' || rest.back() == '\r')) rest.remove_suffix(1);
      if (rest.size() < 2 || rest.front() != '"' || rest.back() != '"')
        ctx_.fail(tag_pos, fmt::format("physical name of tag {} is not in double quotes", tag));
      if (tag < INT32_MIN || tag > INT32_MAX) ctx_.fail(tag_pos, fmt::format("physical tag {} out of range", tag));
      if (dim == 3) names_.emplace_back(static_cast<int32_t>(tag), std::string(rest.substr(1, rest.size() - 2)));
    }
    expect_end_marker("$EndPhysicalNames", count, "physical names");
  }

  /// 4.1 "$Entities": "numPoints numCurves numSurfaces numVolumes", a line per point, curve and
  /// surface (skipped), then per volume "tag minX minY minZ maxX maxY maxZ numPhysicalTags
  /// physicalTag... numBoundingSurfaces surfaceTag...": the volume's first physical tag.
  void read_entities_v4() {
    Scanner header = header_line("entity counts");
    int64_t n[4];
    for (int64_t& k : n) k = header.count("number of entities");
    header.expect_line_end();
    for (int d = 0; d < 3; ++d)
      for (int64_t i = 0; i < n[d]; ++i) body_line([&] { return fmt::format("expected {} entities of dimension {}", n[d], d); });
    for (int64_t i = 0; i < n[3]; ++i) {
      Scanner line = body_line([&] { return fmt::format("expected {} volumes, found {}", n[3], i); });
      const int64_t tag = line.integer("volume tag");
      for (int k = 0; k < 6; ++k) line.real("bounding box");
      const int64_t np = line.count("number of physical tags");
      int64_t physical = 0;
      for (int64_t j = 0; j < np; ++j) {
        const int64_t p = line.integer("physical tag");
        if (j == 0) physical = p;
      }
      if (physical < INT32_MIN || physical > INT32_MAX) physical = 0;
      volume_physical_[tag] = static_cast<int32_t>(physical);
    }
    expect_end_marker("$EndEntities", n[3], "volumes");
  }

  /// Version 1.0 files start directly with $NOD; later ones with a $MeshFormat section.
  void read_format() {
    ctx_.field = "$MeshFormat";
    auto first = file_.next_line();
    if (!first) ctx_.fail(0, "empty file: not a gmsh file");
    const size_t first_pos = first->pos();
    const std::string_view head = first->rest();
    if (head == "$NOD") {
      version_ = 1;
      file_.seek(first_pos);  // the main loop reads $NOD as a section
      return;
    }
    if (head != "$MeshFormat")
      ctx_.fail(first_pos, fmt::format("not a gmsh file: expected $MeshFormat or $NOD, found '{}'",
                                       clip(head)));

    Scanner line = body_line([] { return std::string("missing the version line"); });
    const size_t version_pos = line.token_pos();
    const std::string_view version = line.token();
    double v = 0;
    if (!parse_number(version, v))
      ctx_.fail(version_pos, fmt::format("invalid gmsh version '{}'", clip(version)));
    // 2.0-2.2 share the node and element layout; 4.0 differs from 4.1 and is not read.
    if (v >= 2.0 && v < 3.0) {
      version_ = 2;
    } else if (v == 4.1) {
      version_ = 4;
    } else {
      ctx_.fail(version_pos,
                fmt::format("unsupported gmsh version {} (supported: 1.0, 2.x and 4.1)", version));
    }
    const size_t type_pos = line.token_pos();
    if (line.integer("file type") != 0)
      ctx_.fail(type_pos, "binary .msh not supported; save as ASCII");
    line.integer("data size");
    line.expect_line_end();
    expect_end_marker("$EndMeshFormat", 1, "format line");
  }

  /// The next data line of the current section. Running into a '$' line or the end of the file
  /// means the section holds less than its header announced; `describe` says what was expected.
  template <class Describe>
  Scanner body_line(Describe&& describe) {
    auto line = file_.next_line();
    if (!line)
      ctx_.fail(ctx_.text.size(),
                fmt::format("truncated: {} before the end of the file", describe()));
    if (line->peek() == '$')
      ctx_.fail(line->pos(),
                fmt::format("truncated: {} before '{}'", describe(), clip(line->rest())));
    return *line;
  }

  Scanner header_line(std::string_view what) {
    return body_line([&] { return fmt::format("missing the {}", what); });
  }

  /// After the announced number of entries the closing marker must follow; anything else means
  /// the count in the section header is wrong.
  void expect_end_marker(std::string_view marker, int64_t count, std::string_view what) {
    auto line = file_.next_line();
    if (!line)
      ctx_.fail(ctx_.text.size(), fmt::format("missing {} at the end of the file", marker));
    const size_t at = line->pos();
    const std::string_view text = line->rest();
    if (!iequals(text, marker))
      ctx_.fail(at, fmt::format("expected {} after {} {}, found '{}' (is the count in the section "
                                "header wrong?)",
                                marker, count, what, clip(text)));
  }

  /// Sections this reader does not need ($PhysicalNames, $Entities, $NodeData, ...).
  void skip_section(std::string_view name, size_t at) {
    const std::string end_marker = "$End" + std::string(name.substr(1));
    while (auto line = file_.next_line())
      if (iequals(line->rest(), end_marker)) return;
    ctx_.fail(at, fmt::format("section {} is never closed (missing {})", name, end_marker));
  }

  void map_tag(int64_t tag, size_t index, size_t at) {
    if (!index_of_tag_.try_emplace(tag, static_cast<int32_t>(index)).second)
      ctx_.fail(at, fmt::format("duplicate node tag {}", tag));
  }

  static Vec3 read_xyz(Scanner& line) {
    const double x = line.real("x coordinate");
    const double y = line.real("y coordinate");
    const double z = line.real("z coordinate");
    return {x, y, z};
  }

  void reserve_nodes(int64_t count) {
    // Guard against absurd header counts: a node line takes at least 8 characters.
    const size_t n = std::min(static_cast<size_t>(count), ctx_.text.size() / 8 + 1);
    nodes_.reserve(n);
    index_of_tag_.reserve(n);
  }

  /// 1.0 and 2.x: a count, then one "tag x y z" line per node.
  void read_nodes_v1v2() {
    Scanner header = header_line("node count");
    const int64_t count = header.count("node count");
    header.expect_line_end();
    reserve_nodes(count);
    for (int64_t i = 0; i < count; ++i) {
      Scanner line =
          body_line([&] { return fmt::format("expected {} nodes, found {}", count, i); });
      const size_t at = line.token_pos();
      map_tag(line.integer("node tag"), nodes_.size(), at);
      nodes_.push_back(read_xyz(line));
      line.expect_line_end();
    }
    expect_end_marker(version_ == 1 ? "$ENDNOD" : "$EndNodes", count, "nodes");
  }

  /// 4.1: "numEntityBlocks numNodes minTag maxTag", then per block
  /// "entityDim entityTag parametric numNodesInBlock", the block's tags, then its coordinates.
  void read_nodes_v4() {
    Scanner header = header_line("node section header");
    const size_t header_pos = header.pos();
    const int64_t blocks = header.count("number of entity blocks");
    const int64_t total = header.count("number of nodes");
    header.integer("minimum node tag");
    header.integer("maximum node tag");
    header.expect_line_end();
    reserve_nodes(total);
    for (int64_t b = 0; b < blocks; ++b) {
      Scanner bh =
          body_line([&] { return fmt::format("expected {} node blocks, found {}", blocks, b); });
      const size_t dim_pos = bh.token_pos();
      const int64_t dim = bh.integer("entity dimension");
      bh.integer("entity tag");
      const size_t param_pos = bh.token_pos();
      const int64_t parametric = bh.integer("parametric flag");
      const int64_t n = bh.count("number of nodes in block");
      bh.expect_line_end();
      if (dim < 0 || dim > 3) ctx_.fail(dim_pos, fmt::format("invalid entity dimension {}", dim));
      if (parametric != 0 && parametric != 1)
        ctx_.fail(param_pos,
                  fmt::format("invalid parametric flag {} (expected 0 or 1)", parametric));

      const size_t first = nodes_.size();
      for (int64_t j = 0; j < n; ++j) {
        Scanner line = body_line([&] {
          return fmt::format("expected {} node tags in block {}, found {}", n, b + 1, j);
        });
        const size_t at = line.token_pos();
        map_tag(line.integer("node tag"), first + static_cast<size_t>(j), at);
        line.expect_line_end();
      }
      for (int64_t j = 0; j < n; ++j) {
        Scanner line = body_line([&] {
          return fmt::format("expected {} coordinate lines in block {}, found {}", n, b + 1, j);
        });
        nodes_.push_back(read_xyz(line));
        // Parametric nodes append one coordinate per dimension of their entity (u, v, w): the
        // position is already in x y z, so they are read and dropped.
        if (parametric == 1)
          for (int64_t k = 0; k < dim; ++k) line.real("parametric coordinate");
        line.expect_line_end();
      }
    }
    expect_end_marker("$EndNodes", blocks, "node blocks");
    if (nodes_.size() != static_cast<size_t>(total))
      ctx_.fail(header_pos, fmt::format("header announces {} nodes but the blocks hold {}", total,
                                        nodes_.size()));
  }

  int32_t node_index(Scanner& line) {
    const size_t at = line.token_pos();
    const int64_t tag = line.integer("node tag");
    const auto it = index_of_tag_.find(tag);
    if (it == index_of_tag_.end())
      ctx_.fail(at, fmt::format("element refers to unknown node tag {}", tag));
    return it->second;
  }

  void add_tet(Scanner& line) {
    Tet t;
    for (int32_t& n : t) n = node_index(line);
    line.expect_line_end();
    tets_.push_back(t);
  }

  /// 1.0: "number type reg-phys reg-elem number-of-nodes nodes..."; 2.x: "tag type ntags tags...
  /// nodes...".
  void read_elements_v1v2() {
    Scanner header = header_line("element count");
    const int64_t count = header.count("element count");
    header.expect_line_end();
    tets_.reserve(std::min(static_cast<size_t>(count), ctx_.text.size() / 16 + 1));
    for (int64_t i = 0; i < count; ++i) {
      Scanner line =
          body_line([&] { return fmt::format("expected {} elements, found {}", count, i); });
      line.integer("element number");
      const size_t type_pos = line.token_pos();
      const int64_t type = line.integer("element type");
      int64_t physical = 0;
      if (version_ == 1) {
        physical = line.integer("physical region");
        line.integer("elementary region");
        const size_t n_pos = line.token_pos();
        const int64_t n = line.integer("number of nodes");
        if (type == kGmshTet4 && n != 4)
          ctx_.fail(n_pos, fmt::format(
                               "a linear tetrahedron (type 4) has 4 nodes, this line gives {}", n));
      } else {
        const int64_t ntags = line.count("number of tags");
        for (int64_t t = 0; t < ntags; ++t) {
          const int64_t v = line.integer("element tag");
          if (t == 0) physical = v;  // the first tag is the physical group
        }
      }
      if (!is_gmsh_element_type(type))
        ctx_.fail(type_pos, gmsh_unknown_type_message(type));
      if (type == kGmshTet4) {
        add_tet(line);
        tags_.push_back(physical < INT32_MIN || physical > INT32_MAX ? 0 : static_cast<int32_t>(physical));
      }
      else if (is_gmsh_higher_order_tet(type))
        ctx_.fail(type_pos, gmsh_higher_order_message(type));
      else
        ++other_elements_;
    }
    expect_end_marker(version_ == 1 ? "$ENDELM" : "$EndElements", count, "elements");
  }

  /// 4.1: "numEntityBlocks numElements minTag maxTag", then per block
  /// "entityDim entityTag elementType numElementsInBlock" and one "tag n1 n2 ..." line per element.
  void read_elements_v4() {
    Scanner header = header_line("element section header");
    const size_t header_pos = header.pos();
    const int64_t blocks = header.count("number of entity blocks");
    const int64_t total = header.count("number of elements");
    header.integer("minimum element tag");
    header.integer("maximum element tag");
    header.expect_line_end();
    int64_t seen = 0;
    for (int64_t b = 0; b < blocks; ++b) {
      Scanner bh =
          body_line([&] { return fmt::format("expected {} element blocks, found {}", blocks, b); });
      bh.integer("entity dimension");
      const int64_t entity = bh.integer("entity tag");
      const auto ph = volume_physical_.find(entity);
      const int32_t physical = ph == volume_physical_.end() ? 0 : ph->second;
      const size_t type_pos = bh.token_pos();
      const int64_t type = bh.integer("element type");
      const int64_t n = bh.count("number of elements in block");
      bh.expect_line_end();
      if (!is_gmsh_element_type(type)) ctx_.fail(type_pos, gmsh_unknown_type_message(type));
      if (is_gmsh_higher_order_tet(type)) ctx_.fail(type_pos, gmsh_higher_order_message(type));
      for (int64_t j = 0; j < n; ++j) {
        Scanner line = body_line(
            [&] { return fmt::format("expected {} elements in block {}, found {}", n, b + 1, j); });
        if (type == kGmshTet4) {
          line.integer("element tag");
          add_tet(line);
          tags_.push_back(physical);
        }
      }
      if (type != kGmshTet4) other_elements_ += n;
      seen += n;
    }
    expect_end_marker("$EndElements", blocks, "element blocks");
    if (seen != total)
      ctx_.fail(header_pos,
                fmt::format("header announces {} elements but the blocks hold {}", total, seen));
  }

  ParseContext& ctx_;
  Scanner file_;
  int version_ = 0;  // 1, 2 or 4
  std::vector<Vec3> nodes_;
  std::unordered_map<int64_t, int32_t> index_of_tag_;
  std::vector<Tet> tets_;
  std::vector<int32_t> tags_;  // per tetrahedron, its physical group (0: none)
  std::vector<std::pair<int32_t, std::string>> names_;  // physical names of volumes
  std::unordered_map<int64_t, int32_t> volume_physical_;  // 4.1: volume entity → physical group
  int64_t other_elements_ = 0;
  size_t elements_pos_ = kNoPos;  // the element section's header line, for "no tetrahedra"
};

// =============================================================================================
// VTK cells, shared by the legacy and XML readers
// =============================================================================================

constexpr int64_t kVtkTetra = 10;

/// VTK tetrahedra with more than 4 nodes (QUADRATIC_TETRA, LAGRANGE_TETRAHEDRON,
/// BEZIER_TETRAHEDRON): an error, not something to drop silently.
std::optional<std::string> vtk_higher_order_message(int64_t type) {
  if (type != 24 && type != 71 && type != 78) return std::nullopt;
  return fmt::format(
      "{} tetrahedra (VTK cell type {}) are not supported; export linear tetrahedra (type 10)",
      type == 24 ? "quadratic" : "higher-order", type);
}

/// A VTK cell list in the one layout both readers convert to. Positions and field names say
/// where each array sits in the file, for errors found only when the arrays are combined.
struct CellArrays {
  /// Cell i uses connectivity[offsets[i], offsets[i+1]); offsets[0] == 0.
  std::vector<int64_t> offsets;
  std::vector<int64_t> connectivity;
  std::vector<int64_t> types;
  size_t offsets_pos = kNoPos, connectivity_pos = kNoPos, types_pos = kNoPos;
  std::string offsets_field, connectivity_field, types_field;
  /// Per cell its region tag (VTU cell data), or empty.
  std::vector<int64_t> cell_tags;
  /// Per cell a fibre direction (3 values; VTU cell data), or empty.
  std::vector<double> cell_fibres;
};

TetMesh assemble_vtk_mesh(ParseContext& ctx, std::vector<Vec3> points, const CellArrays& c) {
  auto fail = [&](const std::string& field, size_t pos, const std::string& message) {
    ctx.field = field;
    ctx.fail(pos, message);
  };
  const size_t ncells = c.types.size();
  if (c.offsets.size() != ncells + 1)
    fail(c.types_field, c.types_pos,
         fmt::format("{} cell types for {} cells", ncells, c.offsets.size() - 1));
  for (size_t i = 0; i < ncells; ++i)
    if (c.offsets[i + 1] < c.offsets[i])
      fail(c.offsets_field, c.offsets_pos, fmt::format("offsets decrease at cell {}", i));
  if (c.offsets.back() != static_cast<int64_t>(c.connectivity.size()))
    fail(c.offsets_field, c.offsets_pos,
         fmt::format("last offset {} does not match the {} connectivity values", c.offsets.back(),
                     c.connectivity.size()));

  TetMesh mesh;
  mesh.tets.reserve(ncells);
  size_t others = 0;
  for (size_t i = 0; i < ncells; ++i) {
    const int64_t type = c.types[i];
    if (type != kVtkTetra) {
      if (auto message = vtk_higher_order_message(type))
        fail(c.types_field, c.types_pos, fmt::format("cell {}: {}", i, *message));
      ++others;
      continue;
    }
    const int64_t begin = c.offsets[i];
    if (c.offsets[i + 1] - begin != 4)
      fail(c.types_field, c.types_pos,
           fmt::format("cell {} is a tetrahedron (type 10) but has {} points", i,
                       c.offsets[i + 1] - begin));
    Tet t;
    for (int k = 0; k < 4; ++k) {
      const int64_t index = c.connectivity[static_cast<size_t>(begin + k)];
      if (index < 0 || index >= static_cast<int64_t>(points.size()))
        fail(c.connectivity_field, c.connectivity_pos,
             fmt::format("cell {} refers to point {}, but there are {} points", i, index,
                         points.size()));
      t[static_cast<size_t>(k)] = static_cast<int32_t>(index);
    }
    mesh.tets.push_back(t);
    if (!c.cell_tags.empty()) {
      const int64_t tag = c.cell_tags[i];
      mesh.tet_tags.push_back(tag < INT32_MIN || tag > INT32_MAX ? 0 : static_cast<int32_t>(tag));
    }
    if (!c.cell_fibres.empty()) mesh.tet_fibres.push_back({c.cell_fibres[3 * i], c.cell_fibres[3 * i + 1], c.cell_fibres[3 * i + 2]});
  }
  if (std::none_of(mesh.tet_tags.begin(), mesh.tet_tags.end(), [](int32_t t) { return t != 0; })) mesh.tet_tags.clear();
  if (mesh.tets.empty())
    fail(c.types_field, c.types_pos,
         fmt::format("no tetrahedra in the mesh (found {} cells of other types; "
                     "only linear tetrahedra, type 10, are read)",
                     others));
  mesh.nodes = std::move(points);
  mesh.source = ctx.source;
  return mesh;
}

// =============================================================================================
// Legacy VTK
// =============================================================================================

class VtkLegacyReader {
 public:
  explicit VtkLegacyReader(ParseContext& ctx) : ctx_(ctx), file_(ctx, 0, ctx.text.size(), "file") {}

  TetMesh read() {
    read_header();
    while (!file_.at_end()) {
      const size_t at = file_.token_pos();
      const std::string_view keyword = file_.token();
      ctx_.field = clip(keyword);
      if (iequals(keyword, "POINTS")) {
        read_points();
      } else if (iequals(keyword, "CELLS")) {
        read_cells(at);
      } else if (iequals(keyword, "CELL_TYPES")) {
        read_cell_types(at);
      } else if (iequals(keyword, "FIELD")) {
        skip_field_data();
      } else if (iequals(keyword, "METADATA")) {
        skip_metadata();
      } else if (iequals(keyword, "POINT_DATA") || iequals(keyword, "CELL_DATA")) {
        break;  // attribute data: everything after is not geometry
      } else {
        ctx_.fail(at, fmt::format("unexpected keyword '{}'", clip(keyword)));
      }
    }
    ctx_.field.clear();
    if (!have_points_) ctx_.fail(kNoPos, "no POINTS section");
    if (!have_cells_) ctx_.fail(kNoPos, "no CELLS section");
    if (!have_types_) ctx_.fail(kNoPos, "no CELL_TYPES section");
    return assemble_vtk_mesh(ctx_, std::move(points_), cells_);
  }

 private:
  void read_header() {
    ctx_.field = "header";
    const auto magic = file_.raw_line();
    constexpr std::string_view kMagic = "# vtk DataFile Version";
    if (!magic || magic->size() < kMagic.size() ||
        !iequals(magic->substr(0, kMagic.size()), kMagic))
      ctx_.fail(0, fmt::format("not a VTK file: the first line must start with '{}'", kMagic));
    double version = 0;
    const std::string_view version_text = trim(magic->substr(kMagic.size()));
    if (!parse_number(version_text, version))
      ctx_.fail(0, fmt::format("invalid VTK file version '{}'", clip(version_text)));
    // VTK 5 writes CELLS as separate OFFSETS and CONNECTIVITY arrays.
    new_cell_layout_ = version >= 5.0;

    if (!file_.raw_line()) ctx_.fail(ctx_.text.size(), "truncated header: missing the title line");
    const size_t mode_pos = file_.pos();
    const auto mode = file_.raw_line();
    if (mode && iequals(*mode, "ASCII")) {
      binary_ = false;
    } else if (mode && iequals(*mode, "BINARY")) {
      binary_ = true;
    } else {
      ctx_.fail(mode_pos, fmt::format("expected ASCII or BINARY on line 3, found '{}'",
                                      clip(mode.value_or(""))));
    }
    const size_t at = file_.token_pos();
    if (!iequals(file_.token(), "DATASET")) ctx_.fail(at, "expected 'DATASET UNSTRUCTURED_GRID'");
    const size_t type_pos = file_.token_pos();
    const std::string_view type = file_.token();
    if (!iequals(type, "UNSTRUCTURED_GRID"))
      ctx_.fail(type_pos,
                fmt::format("dataset type '{}' is not supported; expected UNSTRUCTURED_GRID",
                            clip(type)));
  }

  ScalarType read_type(bool need_integer) {
    const size_t at = file_.token_pos();
    const std::string_view name = file_.token();
    const auto type = legacy_vtk_type(name);
    if (!type) ctx_.fail(at, fmt::format("unknown data type '{}'", clip(name)));
    if (need_integer && type->kind == Kind::Float)
      ctx_.fail(at, fmt::format("data type '{}' must be an integer type", name));
    return *type;
  }

  /// Returns the keyword's offset. (Never use token_pos() to locate binary data: it would skip
  /// the newline that ends the keyword line, and skip_line() would then eat into the values.)
  size_t expect_keyword(std::string_view keyword) {
    const size_t at = file_.token_pos();
    const std::string_view tok = file_.token();
    if (!iequals(tok, keyword))
      ctx_.fail(at, fmt::format("expected '{}', found '{}'", keyword, clip(tok)));
    ctx_.field = std::string(keyword);
    return at;
  }

  /// An array's values: text numbers, or (BINARY files) raw big-endian values starting on the
  /// line after the keyword line.
  template <class T>
  std::vector<T> read_array(size_t count, ScalarType type, std::string_view what) {
    if (!binary_) return read_values<T>(ctx_, file_, count, what);
    file_.skip_line();
    const size_t begin = file_.pos();
    ctx_.binary_from = std::min(ctx_.binary_from, begin);
    const size_t bytes = count * static_cast<size_t>(type.size);
    if (ctx_.text.size() - begin < bytes)
      ctx_.fail(begin,
                fmt::format("truncated binary data: expected {} {} ({} bytes), found {} bytes",
                            count, what, bytes, ctx_.text.size() - begin));
    auto values = decode_values<T>(reinterpret_cast<const unsigned char*>(ctx_.text.data() + begin),
                                   count, type, /*big_endian=*/true);
    file_.seek(begin + bytes);
    return values;
  }

  void read_points() {
    const int64_t n = file_.count("number of points");
    const ScalarType type = read_type(false);
    points_ = to_points(read_array<double>(3 * static_cast<size_t>(n), type, "point coordinates"));
    have_points_ = true;
  }

  void read_cells(size_t at) {
    const int64_t n = file_.count(new_cell_layout_ ? "number of offsets" : "number of cells");
    const int64_t size =
        file_.count(new_cell_layout_ ? "number of connectivity values" : "cell list size");
    if (new_cell_layout_) {
      cells_.offsets_pos = expect_keyword("OFFSETS");
      const ScalarType offset_type = read_type(true);
      cells_.offsets = read_array<int64_t>(static_cast<size_t>(n), offset_type, "offsets");
      if (cells_.offsets.empty() || cells_.offsets[0] != 0)
        ctx_.fail(cells_.offsets_pos, "OFFSETS must start with 0");
      cells_.offsets_field = "OFFSETS";
      cells_.connectivity_pos = expect_keyword("CONNECTIVITY");
      const ScalarType conn_type = read_type(true);
      cells_.connectivity =
          read_array<int64_t>(static_cast<size_t>(size), conn_type, "connectivity values");
      cells_.connectivity_field = "CONNECTIVITY";
    } else {
      // Classic layout: per cell "npts id0 id1 ...", all as int32 in BINARY files.
      cells_.connectivity_pos = cells_.offsets_pos = at;
      cells_.offsets_field = cells_.connectivity_field = "CELLS";
      const auto list = read_array<int64_t>(static_cast<size_t>(size), ScalarType{Kind::Signed, 4},
                                            "cell list values");
      split_cell_list(list, static_cast<size_t>(n), at);
    }
    have_cells_ = true;
  }

  void split_cell_list(const std::vector<int64_t>& list, size_t n, size_t at) {
    cells_.offsets.assign(1, 0);
    cells_.offsets.reserve(std::min(n, list.size()) + 1);  // a cell takes at least one value
    cells_.connectivity.reserve(list.size());
    size_t pos = 0;
    for (size_t i = 0; i < n; ++i) {
      const int64_t npts = pos < list.size() ? list[pos] : -1;
      if (npts < 0 || static_cast<size_t>(npts) > list.size() - pos - 1)
        ctx_.fail(at, fmt::format(
                          "cell {} does not fit in the cell list of {} values (wrong CELLS size?)",
                          i, list.size()));
      cells_.connectivity.insert(
          cells_.connectivity.end(), list.begin() + static_cast<long>(pos + 1),
          list.begin() + static_cast<long>(pos + 1 + static_cast<size_t>(npts)));
      cells_.offsets.push_back(static_cast<int64_t>(cells_.connectivity.size()));
      pos += 1 + static_cast<size_t>(npts);
    }
    if (pos != list.size())
      ctx_.fail(at, fmt::format("CELLS announces a list of {} values, but its {} cells use {}",
                                list.size(), n, pos));
  }

  void read_cell_types(size_t at) {
    const int64_t n = file_.count("number of cell types");
    cells_.types_pos = at;
    cells_.types_field = "CELL_TYPES";
    cells_.types =
        read_array<int64_t>(static_cast<size_t>(n), ScalarType{Kind::Signed, 4}, "cell types");
    have_types_ = true;
  }

  /// "FIELD name n", then n arrays "name components tuples type" followed by their values.
  void skip_field_data() {
    file_.token();
    const int64_t arrays = file_.count("number of field arrays");
    for (int64_t a = 0; a < arrays; ++a) {
      file_.token();
      const int64_t components = file_.count("number of components");
      const int64_t tuples = file_.count("number of tuples");
      const ScalarType type = read_type(false);
      read_array<double>(static_cast<size_t>(components * tuples), type, "field values");
      if (iequals(peek_token(), "METADATA")) {
        file_.token();
        skip_metadata();
      }
    }
  }

  /// METADATA blocks (VTK >= 8) run up to the next blank line.
  void skip_metadata() {
    file_.skip_line();
    while (auto line = file_.raw_line())
      if (line->empty()) return;
  }

  std::string_view peek_token() {
    const size_t at = file_.pos();
    const std::string_view tok = file_.token();
    file_.seek(at);
    return tok;
  }

  ParseContext& ctx_;
  Scanner file_;
  bool binary_ = false;
  bool new_cell_layout_ = false;
  std::vector<Vec3> points_;
  CellArrays cells_;
  bool have_points_ = false, have_cells_ = false, have_types_ = false;
};

// =============================================================================================
// VTK XML (.vtu)
// =============================================================================================

/// A start tag found in the document: `tag` is the text between '<' and '>' (or '/>').
struct XmlTag {
  std::string_view tag;
  size_t begin = 0;          // offset of '<'
  size_t content_begin = 0;  // just past '>'
  bool self_closing = false;
};

/// The value of attribute `name` in a start tag, if present. Handles either quote character and
/// any attribute order; names are matched exactly (so "type" never matches "header_type").
std::optional<std::string_view> xml_attribute(std::string_view tag, std::string_view name) {
  size_t i = 0;
  while (i < tag.size() && !is_space(tag[i])) ++i;  // element name
  while (true) {
    while (i < tag.size() && is_space(tag[i])) ++i;
    const size_t name_begin = i;
    while (i < tag.size() && tag[i] != '=' && !is_space(tag[i])) ++i;
    const std::string_view attr = tag.substr(name_begin, i - name_begin);
    while (i < tag.size() && is_space(tag[i])) ++i;
    if (attr.empty() || i >= tag.size() || tag[i] != '=') return std::nullopt;
    ++i;
    while (i < tag.size() && is_space(tag[i])) ++i;
    if (i >= tag.size() || (tag[i] != '"' && tag[i] != '\'')) return std::nullopt;
    const size_t close = tag.find(tag[i], i + 1);
    if (close == kNoPos) return std::nullopt;
    if (attr == name) return tag.substr(i + 1, close - i - 1);
    i = close + 1;
  }
}

class VtuReader {
 public:
  explicit VtuReader(ParseContext& ctx) : ctx_(ctx), doc_(ctx.text) {}

  TetMesh read() {
    ctx_.field = "VTKFile";
    const auto root = find_tag("VTKFile", 0, doc_.size());
    if (!root) ctx_.fail(kNoPos, "not a VTK XML file: no <VTKFile> element");
    const auto type = xml_attribute(root->tag, "type");
    if (type != "UnstructuredGrid")
      ctx_.fail(root->begin,
                fmt::format("VTK XML file of type '{}' is not supported; expected UnstructuredGrid",
                            clip(type.value_or(""))));
    const auto byte_order = xml_attribute(root->tag, "byte_order").value_or("LittleEndian");
    if (byte_order != "LittleEndian" && byte_order != "BigEndian")
      ctx_.fail(root->begin, fmt::format("unknown byte_order '{}'", clip(byte_order)));
    big_endian_ = byte_order == "BigEndian";
    const auto header_type = xml_attribute(root->tag, "header_type").value_or("UInt32");
    if (header_type != "UInt32" && header_type != "UInt64")
      ctx_.fail(root->begin, fmt::format("unknown header_type '{}' (expected UInt32 or UInt64)",
                                         clip(header_type)));
    header_size_ = header_type == "UInt64" ? 8 : 4;
    compressor_ = xml_attribute(root->tag, "compressor").value_or("");
    if (!compressor_.empty() && compressor_ != "vtkZLibDataCompressor")
      ctx_.fail(root->begin, fmt::format("compressor '{}' is not supported (vtkZLibDataCompressor, VTK's default, is)",
                                         clip(compressor_)));
    // Appended data (VTK's default): after the XML, `<AppendedData encoding="raw|base64">_`
    // and the arrays' blocks at their `offset`s. The XML before it is all that is scanned for
    // tags (raw bytes may hold anything).
    if (const auto appended = find_tag("AppendedData", root->content_begin, doc_.size())) {
      ctx_.field = "AppendedData";
      const auto encoding = xml_attribute(appended->tag, "encoding").value_or("");
      if (encoding != "raw" && encoding != "base64")
        ctx_.fail(appended->begin, fmt::format("AppendedData encoding '{}' is not supported (raw or base64)", clip(encoding)));
      appended_raw_ = encoding == "raw";
      size_t u = appended->content_begin;
      while (u < doc_.size() && is_space(doc_[u])) ++u;
      if (u >= doc_.size() || doc_[u] != '_') ctx_.fail(appended->begin, "appended data must start with '_'");
      appended_begin_ = u + 1;
      appended_end_ = doc_.size();
      if (!appended_raw_) {
        const size_t close = doc_.find('<', appended_begin_);
        if (close != kNoPos) appended_end_ = close;
      } else {
        ctx_.binary_from = appended_begin_;
      }
      has_appended_ = true;
      doc_ = doc_.substr(0, appended->begin);
    }

    ctx_.field = "Piece";
    const auto piece = find_tag("Piece", root->content_begin, doc_.size());
    if (!piece) ctx_.fail(kNoPos, "no <Piece> element");
    const size_t piece_end = find_closing("Piece", *piece);
    if (const auto second = find_tag("Piece", piece_end, doc_.size()))
      ctx_.fail(second->begin, "several <Piece> elements are not supported");
    const int64_t npoints = count_attribute(*piece, "NumberOfPoints");
    const int64_t ncells = count_attribute(*piece, "NumberOfCells");

    ctx_.field = "Points";
    const XmlTag points = require_tag("Points", *piece, piece_end);
    const XmlTag coords = require_tag("DataArray", points, find_closing("Points", points));
    if (xml_attribute(coords.tag, "NumberOfComponents") != "3")
      ctx_.fail(coords.begin, "the points DataArray must have NumberOfComponents=\"3\"");
    auto points_xyz = read_array<double>(coords, 3 * static_cast<size_t>(npoints), "Points",
                                         "point coordinates (3 x NumberOfPoints)");

    ctx_.field = "Cells";
    const XmlTag cells = require_tag("Cells", *piece, piece_end);
    const size_t cells_end = find_closing("Cells", cells);
    const XmlTag offsets = named_array(cells, cells_end, "offsets");
    const XmlTag connectivity = named_array(cells, cells_end, "connectivity");
    const XmlTag types = named_array(cells, cells_end, "types");

    CellArrays c;
    // VTU offsets are the end of each cell; the shared layout wants a leading 0.
    c.offsets = read_array<int64_t>(offsets, static_cast<size_t>(ncells), "offsets",
                                    "offsets (NumberOfCells)");
    c.offsets.insert(c.offsets.begin(), 0);
    const int64_t nconn = c.offsets.back();
    if (nconn < 0 || nconn > std::numeric_limits<int32_t>::max())
      ctx_.fail(offsets.begin, fmt::format("invalid last offset {}", nconn));
    c.connectivity = read_array<int64_t>(connectivity, static_cast<size_t>(nconn), "connectivity",
                                         "connectivity values (last offset)");
    c.types = read_array<int64_t>(types, static_cast<size_t>(ncells), "types",
                                  "cell types (NumberOfCells)");
    // Regions: an integer cell-data array with one of the names meshers use for them; fibre
    // directions: a 3-component array named as fibre fields are.
    if (const auto cell_data = find_tag("CellData", piece->content_begin, piece_end)) {
      ctx_.field = "CellData";
      const size_t cd_end = find_closing("CellData", *cell_data);
      size_t pos = cell_data->content_begin;
      while (const auto tag = find_tag("DataArray", pos, cd_end)) {
        pos = tag->content_begin;
        const auto name = xml_attribute(tag->tag, "Name");
        static constexpr std::string_view kNames[] = {"region", "regions", "tag", "label", "labels",
                                                      "gmsh:physical", "MaterialIds", "CellEntityIds"};
        static constexpr std::string_view kFibreNames[] = {"fibres", "fibers", "fibre", "fiber",
                                                           "FibreDirection", "FiberDirection"};
        if (!name) continue;
        const auto comps = xml_attribute(tag->tag, "NumberOfComponents");
        if (c.cell_tags.empty() && std::find(std::begin(kNames), std::end(kNames), *name) != std::end(kNames) &&
            (!comps || trim(*comps) == "1")) {
          c.cell_tags = read_array<int64_t>(*tag, static_cast<size_t>(ncells), "CellData",
                                            "region tags (NumberOfCells)");
        } else if (c.cell_fibres.empty() &&
                   std::find(std::begin(kFibreNames), std::end(kFibreNames), *name) != std::end(kFibreNames)) {
          if (!comps || trim(*comps) != "3")
            ctx_.fail(tag->begin, fmt::format("cell data '{}' (fibre directions) must have NumberOfComponents=\"3\"", *name));
          c.cell_fibres = read_array<double>(*tag, 3 * static_cast<size_t>(ncells), "CellData",
                                             "fibre directions (3 x NumberOfCells)");
        }
      }
    }
    c.offsets_pos = offsets.begin;
    c.connectivity_pos = connectivity.begin;
    c.types_pos = types.begin;
    c.offsets_field = "offsets";
    c.connectivity_field = "connectivity";
    c.types_field = "types";
    return assemble_vtk_mesh(ctx_, to_points(points_xyz), c);
  }

 private:
  /// The first start tag `<name ...>` in [from, to), skipping comments.
  std::optional<XmlTag> find_tag(std::string_view name, size_t from, size_t to) const {
    size_t pos = from;
    while ((pos = doc_.find('<', pos)) != kNoPos && pos < to) {
      if (doc_.compare(pos, 4, "<!--") == 0) {
        const size_t end = doc_.find("-->", pos + 4);
        if (end == kNoPos) return std::nullopt;
        pos = end + 3;
        continue;
      }
      const size_t after = pos + 1 + name.size();
      if (doc_.compare(pos + 1, name.size(), name) == 0 && after < doc_.size() &&
          (is_space(doc_[after]) || doc_[after] == '>' || doc_[after] == '/')) {
        const size_t content = tag_end(pos);
        const bool self_closing = doc_[content - 2] == '/';
        const size_t length = content - pos - 2 - (self_closing ? 1 : 0);
        return XmlTag{doc_.substr(pos + 1, length), pos, content, self_closing};
      }
      ++pos;
    }
    return std::nullopt;
  }

  /// Offset just past the '>' closing the start tag at `begin` ('>' inside quotes does not count).
  size_t tag_end(size_t begin) const {
    char quote = 0;
    for (size_t i = begin + 1; i < doc_.size(); ++i) {
      const char c = doc_[i];
      if (quote) {
        if (c == quote) quote = 0;
      } else if (c == '"' || c == '\'') {
        quote = c;
      } else if (c == '>') {
        return i + 1;
      }
    }
    ctx_.fail(begin, "unterminated XML tag");
  }

  /// Offset of `</name` closing `open`.
  size_t find_closing(std::string_view name, const XmlTag& open) const {
    if (open.self_closing) return open.content_begin;
    const size_t pos = doc_.find(fmt::format("</{}", name), open.content_begin);
    if (pos == kNoPos) ctx_.fail(open.begin, fmt::format("<{}> is never closed", name));
    return pos;
  }

  XmlTag require_tag(std::string_view name, const XmlTag& parent, size_t parent_end) const {
    const auto tag = find_tag(name, parent.content_begin, parent_end);
    if (!tag) ctx_.fail(parent.begin, fmt::format("missing <{}> element", name));
    return *tag;
  }

  XmlTag named_array(const XmlTag& cells, size_t cells_end, std::string_view name) const {
    size_t pos = cells.content_begin;
    while (const auto tag = find_tag("DataArray", pos, cells_end)) {
      if (xml_attribute(tag->tag, "Name") == name) return *tag;
      pos = tag->content_begin;
    }
    ctx_.fail(cells.begin, fmt::format("<Cells> has no DataArray named '{}'", name));
  }

  int64_t count_attribute(const XmlTag& tag, std::string_view name) const {
    const auto text = xml_attribute(tag.tag, name);
    if (!text) ctx_.fail(tag.begin, fmt::format("missing attribute {}", name));
    int64_t n = 0;
    if (!parse_number(trim(*text), n) || n < 0 || n > std::numeric_limits<int32_t>::max())
      ctx_.fail(tag.begin, fmt::format("invalid {}=\"{}\"", name, clip(*text)));
    return n;
  }

  /// Reads exactly `count` values from a DataArray, ascii or inline binary.
  template <class T>
  std::vector<T> read_array(const XmlTag& array, size_t count, std::string_view field,
                            std::string_view what) {
    ctx_.field = std::string(field);
    // The values end at the first '<': VTK writes child elements (InformationKey) after them.
    const size_t content_end = std::min(find_closing("DataArray", array), doc_.find('<', array.content_begin));
    const auto type_name = xml_attribute(array.tag, "type").value_or("");
    const auto type = xml_vtk_type(type_name);
    if (!type) ctx_.fail(array.begin, fmt::format("unknown DataArray type '{}'", clip(type_name)));
    if (std::is_integral_v<T> && type->kind == Kind::Float)
      ctx_.fail(array.begin, fmt::format("{} must have an integer type, not {}", field, type_name));
    const auto format = xml_attribute(array.tag, "format").value_or("");
    if (format == "ascii") {
      Scanner sc(ctx_, array.content_begin, content_end, "DataArray");
      auto values = read_values<T>(ctx_, sc, count, what);
      if (!sc.at_end())
        ctx_.fail(sc.pos(), fmt::format("more values than the {} expected {}", count, what));
      return values;
    }
    if (format == "binary") {
      const std::vector<unsigned char> bytes = decode_base64(array.content_begin, content_end);
      return decode_block<T>(array, bytes.data(), bytes.size(), count, *type);
    }
    if (format == "appended") {
      if (!has_appended_) ctx_.fail(array.begin, "format=\"appended\" but the file has no <AppendedData>");
      const auto offset_text = xml_attribute(array.tag, "offset");
      uint64_t offset = 0;
      if (!offset_text || !parse_number(trim(*offset_text), offset))
        ctx_.fail(array.begin, "an appended DataArray needs offset=\"N\" (bytes into the appended data)");
      if (offset > appended_end_ - appended_begin_)
        ctx_.fail(array.begin, fmt::format("offset {} lies beyond the appended data ({} bytes)", offset,
                                           appended_end_ - appended_begin_));
      const size_t at = appended_begin_ + static_cast<size_t>(offset);
      if (appended_raw_)
        return decode_block<T>(array, reinterpret_cast<const unsigned char*>(ctx_.text.data()) + at,
                               appended_end_ - at, count, *type);
      // base64: each array's block is its own base64 text from its offset on; decoding to the end
      // of the section yields it first (the blocks after it are not read).
      const std::vector<unsigned char> bytes = decode_base64(at, appended_end_);
      return decode_block<T>(array, bytes.data(), bytes.size(), count, *type);
    }
    ctx_.fail(array.begin, fmt::format("unknown DataArray format '{}'", clip(format)));
  }

  /// One array's binary block (`bytes`, `avail` of them readable), in the file's byte order:
  /// uncompressed [byte count][values], or with zlib [#blocks][block size][last block's size]
  /// [compressed size of each block][the compressed blocks] (VTK's layout), header fields
  /// header_type wide. Every size is checked against what is there before it is used, and
  /// inflated output against what the header announced, so a corrupt or hostile file is an
  /// InputError, never a huge allocation.
  template <class T>
  std::vector<T> decode_block(const XmlTag& array, const unsigned char* bytes, size_t avail, size_t count,
                              ScalarType type) {
    const size_t hs = header_size_;
    // A count the data cannot hold is refused before count × size is formed.
    if (count > std::numeric_limits<size_t>::max() / 16)
      ctx_.fail(array.begin, fmt::format("{} values is more than any file holds", count));
    const size_t expected = count * static_cast<size_t>(type.size);
    if (compressor_.empty()) {
      if (avail < hs) ctx_.fail(array.begin, "binary DataArray too short for its size header");
      const uint64_t nbytes = load_bits(bytes, static_cast<int>(hs), big_endian_);
      if (nbytes != expected)
        ctx_.fail(array.begin,
                  fmt::format("binary DataArray holds {} bytes; expected {} for {} values", nbytes, expected, count));
      if (avail - hs < expected)
        ctx_.fail(array.begin,
                  fmt::format("truncated binary DataArray: {} bytes announced, {} present", expected, avail - hs));
      return decode_values<T>(bytes + hs, count, type, big_endian_);
    }
    if (avail < 3 * hs) ctx_.fail(array.begin, "compressed DataArray too short for its header");
    const uint64_t nblocks = load_bits(bytes, static_cast<int>(hs), big_endian_);
    const uint64_t block = load_bits(bytes + hs, static_cast<int>(hs), big_endian_);
    const uint64_t last = load_bits(bytes + 2 * hs, static_cast<int>(hs), big_endian_);
    if (nblocks > (avail - 3 * hs) / hs)
      ctx_.fail(array.begin, fmt::format("compressed DataArray announces {} blocks; its header is truncated", nblocks));
    // The uncompressed size the header announces, without overflow.
    const uint64_t last_size = last == 0 ? block : last;
    uint64_t total = 0;
    if (nblocks > 0 && (last_size > block || __builtin_mul_overflow(nblocks - 1, block, &total) ||
                        __builtin_add_overflow(total, last_size, &total)))
      ctx_.fail(array.begin, fmt::format("compressed DataArray: {} blocks of {} bytes, the last {}: inconsistent",
                                         nblocks, block, last));
    if (total != expected)
      ctx_.fail(array.begin,
                fmt::format("compressed DataArray holds {} bytes; expected {} for {} values", total, expected, count));
    const unsigned char* sizes = bytes + 3 * hs;
    size_t at = 3 * hs + static_cast<size_t>(nblocks) * hs;
    std::string out;  // grows with what really inflates (io/inflate.cpp)
    for (uint64_t b = 0; b < nblocks; ++b) {
      const uint64_t csize = load_bits(sizes + b * hs, static_cast<int>(hs), big_endian_);
      if (csize > avail - at)
        ctx_.fail(array.begin, fmt::format("compressed block {} of {} bytes runs past the data", b, csize));
      const uint64_t want = b + 1 == nblocks ? last_size : block;
      const std::string_view src(reinterpret_cast<const char*>(bytes + at), static_cast<size_t>(csize));
      const InflateOutcome r = inflate_bounded(src, static_cast<size_t>(want), InflateTail::exact, out);
      if (!r.error.empty() || r.produced != want || !r.ended)
        ctx_.fail(array.begin, fmt::format("compressed block {} does not inflate to its {} bytes ({})", b, want,
                                           !r.error.empty() ? r.error
                                           : r.produced < want ? fmt::format("{} bytes: truncated", r.produced)
                                                               : std::string("its end marker is missing")));
      at += static_cast<size_t>(csize);
    }
    return decode_values<T>(reinterpret_cast<const unsigned char*>(out.data()), count, type, big_endian_);
  }

  /// Decodes base64 group by group, so that '=' padding in the middle is accepted: some writers
  /// encode the size header and the values as two separate base64 strings.
  std::vector<unsigned char> decode_base64(size_t begin, size_t end) const {
    std::vector<unsigned char> out;
    out.reserve((end - begin) / 4 * 3 + 3);
    uint32_t group = 0;
    int chars = 0;
    int pad = 0;
    auto emit = [&](int nbytes) {
      for (int k = 0; k < nbytes; ++k)
        out.push_back(static_cast<unsigned char>(group >> (16 - 8 * k)));
    };
    for (size_t i = begin; i < end; ++i) {
      const char c = ctx_.text[i];  // the whole file: appended base64 lies after the XML
      if (is_space(c)) continue;
      int v = base64_value(c);
      if (c == '=' && chars >= 2) {
        ++pad;
        v = 0;
      } else if (v < 0 || pad > 0) {
        ctx_.fail(i, fmt::format("invalid base64 character '{}'", c));
      }
      group = (group << 6) | static_cast<uint32_t>(v);
      if (++chars == 4) {
        emit(3 - pad);
        group = 0;
        chars = pad = 0;
      }
    }
    if (chars == 1) ctx_.fail(end, "truncated base64 data");
    if (chars > 1) {  // unpadded tail
      group <<= 6 * (4 - chars);
      emit(chars - 1);
    }
    return out;
  }

  static int base64_value(char c) {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  }

  ParseContext& ctx_;
  std::string_view doc_;
  bool big_endian_ = false;
  size_t header_size_ = 4;
  std::string_view compressor_;
  bool has_appended_ = false, appended_raw_ = false;
  size_t appended_begin_ = 0, appended_end_ = 0;  ///< the appended data, in the file's text
};

/// Runs one reader over the whole input; they all work on a single in-memory buffer.
template <class Reader>
TetMesh read_with(std::istream& in, const std::string& source) {
  const std::string text = slurp(in);
  ParseContext ctx{text, source, {}};
  TetMesh mesh = Reader(ctx).read();
  // Text values were checked where they were read (with their line); binary ones are checked
  // here, so no reader hands on a NaN or an infinity.
  for (size_t i = 0; i < mesh.nodes.size(); ++i) {
    const Vec3& p = mesh.nodes[i];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
      throw InputError(source, 0, "points",
                       fmt::format("point {} has a non-finite coordinate ({}, {}, {})", i, p[0], p[1], p[2]));
  }
  return mesh;
}

}  // namespace

// =============================================================================================
// Public entry points
// =============================================================================================

TetMesh read_gmsh(std::istream& in, const std::string& source) {
  return read_with<GmshReader>(in, source);
}

TetMesh read_vtk_legacy(std::istream& in, const std::string& source) {
  return read_with<VtkLegacyReader>(in, source);
}

TetMesh read_vtu(std::istream& in, const std::string& source) {
  return read_with<VtuReader>(in, source);
}

TetMesh load_tet_mesh(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), lower);
  TetMesh (*reader)(std::istream&, const std::string&) = ext == ".msh"   ? &read_gmsh
                                                         : ext == ".vtk" ? &read_vtk_legacy
                                                         : ext == ".vtu" ? &read_vtu
                                                                         : nullptr;
  if (!reader)
    throw InputError(
        path, 0, "",
        fmt::format("unknown mesh file extension '{}' (expected .msh, .vtk or .vtu)", ext));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "", "cannot open file");
  return reader(in, path);
}

}  // namespace stroma
