/// \file surface_io.cpp
/// Surface mesh readers (see surface_io.hpp). The file is read into one buffer and walked line
/// by line (text formats) or record by record (binary STL); numbers go through std::from_chars,
/// which is exact and locale-independent.
#include "io/surface_io.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string_view>
#include <unordered_map>

#include "tissue/input_error.hpp"
#include "io/text_scan.hpp"

namespace stroma {
namespace {

using namespace text;  // is_space, iequals, clip, parse_number, words, content_lines (io/text_scan.hpp)

/// Whitespace-separated tokens of one line.
class Tokens {
 public:
  explicit Tokens(std::string_view line) : s_(line) {}
  /// Next token; empty at the end of the line.
  std::string_view next() {
    while (pos_ < s_.size() && is_space(s_[pos_])) ++pos_;
    const size_t begin = pos_;
    while (pos_ < s_.size() && !is_space(s_[pos_])) ++pos_;
    return s_.substr(begin, pos_ - begin);
  }

 private:
  std::string_view s_;
  size_t pos_ = 0;
};

/// Walks text one line at a time, counting lines so errors can name them.
class LineReader {
 public:
  explicit LineReader(std::string_view text) : text_(text) {}
  /// Next line without its '\n' (a trailing '\r' is whitespace to the tokenizer); false at the end.
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    size_t nl = text_.find('\n', pos_);
    if (nl == std::string_view::npos) nl = text_.size();
    line = text_.substr(pos_, nl - pos_);
    pos_ = nl + 1;
    ++line_;
    return true;
  }
  /// 1-based number of the line last returned.
  int line() const { return line_; }

 private:
  std::string_view text_;
  size_t pos_ = 0;
  int line_ = 0;
};

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "", "cannot open file");
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(path, 0, "", "read error");
  return bytes;
}

/// Appends triangle (a, b, c) unless it uses a vertex twice (no area, no normal: nothing to draw).
/// Returns whether it was kept.
bool add_triangle(SurfaceMesh& m, int32_t a, int32_t b, int32_t c) {
  if (a == b || b == c || a == c) return false;
  m.triangles.push_back(Tri{a, b, c});
  return true;
}

// =============================================================================================
// Wavefront OBJ
// =============================================================================================

/// OBJ face vertex "i", "i/t", "i//n" or "i/t/n" → zero-based vertex index. Negative indices
/// count back from the last vertex read so far (-1 is the latest).
int32_t obj_face_index(std::string_view tok, size_t num_vertices, const std::string& path,
                       int line) {
  const std::string_view head = tok.substr(0, tok.find('/'));
  int64_t i = 0;
  if (head.empty() || !parse_number(head, i))
    throw InputError(path, line, "",
                     fmt::format("invalid face vertex '{}' (expected i, i/t, i//n or i/t/n with "
                                 "an integer vertex index i)",
                                 clip(tok)));
  if (i == 0)
    throw InputError(path, line, "",
                     "face index 0 is invalid (OBJ indices start at 1; negative ones count back "
                     "from the last vertex)");
  const int64_t n = static_cast<int64_t>(num_vertices);
  const int64_t zero_based = i > 0 ? i - 1 : n + i;
  if (zero_based < 0 || zero_based >= n)
    throw InputError(path, line, "",
                     fmt::format("face index {} out of range (the file has {} vertices so far)",
                                 i, n));
  return static_cast<int32_t>(zero_based);
}

SurfaceMesh read_obj(std::string_view text, const std::string& path) {
  SurfaceMesh m;
  m.source = path;
  LineReader lines(text);
  std::string_view line;
  std::vector<int32_t> polygon;  // reused: one face's vertex indices
  size_t faces = 0;
  while (lines.next(line)) {
    const int ln = lines.line();
    line = line.substr(0, line.find('#'));  // comments, whole-line or trailing
    Tokens tk(line);
    const std::string_view kw = tk.next();
    if (kw == "v") {
      // x y z, then an optional w or (a common extension) r g b [a]: checked, not kept.
      Vec3 p{};
      int count = 0;
      for (std::string_view tok = tk.next(); !tok.empty(); tok = tk.next(), ++count) {
        double value = 0;
        if (!parse_number(tok, value))
          throw InputError(path, ln, "",
                           fmt::format("non-numeric value '{}' in vertex {}", clip(tok),
                                       m.vertices.size() + 1));
        if (count < 3) {
          if (!std::isfinite(value))
            throw InputError(path, ln, "",
                             fmt::format("non-finite coordinate '{}' in vertex {}", clip(tok),
                                         m.vertices.size() + 1));
          p[count] = value;
        }
      }
      if (count < 3)
        throw InputError(path, ln, "",
                         fmt::format("vertex {} has {} coordinates (x y z needed)",
                                     m.vertices.size() + 1, count));
      if (count > 7)
        throw InputError(path, ln, "",
                         fmt::format("vertex {} has {} values (expected x y z [w] or x y z r g b)",
                                     m.vertices.size() + 1, count));
      if (m.vertices.size() >= static_cast<size_t>(std::numeric_limits<int32_t>::max()))
        throw InputError(path, ln, "", "too many vertices for 32-bit indices");
      m.vertices.push_back(p);
    } else if (kw == "f") {
      polygon.clear();
      for (std::string_view tok = tk.next(); !tok.empty(); tok = tk.next())
        polygon.push_back(obj_face_index(tok, m.vertices.size(), path, ln));
      if (polygon.size() < 3)
        throw InputError(path, ln, "",
                         fmt::format("face has {} vertices (at least 3 needed)", polygon.size()));
      ++faces;
      // Fan from the first corner: exact for the convex polygons exporters write.
      for (size_t k = 1; k + 1 < polygon.size(); ++k)
        add_triangle(m, polygon[0], polygon[k], polygon[k + 1]);
    }
    // Everything else (vt, vn, vp, o, g, s, usemtl, mtllib, l, p, free-form geometry, blank
    // lines) carries nothing a visual surface mapped onto tetrahedra needs.
  }
  if (m.vertices.empty()) throw InputError(path, 0, "", "no vertices (no 'v' lines)");
  if (faces == 0) throw InputError(path, 0, "", "no faces (no 'f' lines)");
  if (m.triangles.empty())
    throw InputError(path, 0, "",
                     fmt::format("no triangles: all {} faces use a vertex more than once", faces));
  return m;
}

// =============================================================================================
// STL
// =============================================================================================

/// Merges exactly equal corner positions into shared vertices: STL stores every triangle's
/// corners separately, but the mapping and the renderer's normals need an indexed mesh.
class Welder {
 public:
  explicit Welder(SurfaceMesh& m, size_t expected_corners) : m_(m) {
    index_.reserve(expected_corners / 4 + 16);  // closed surfaces: ~6 triangles per vertex
  }
  int32_t add(double x, double y, double z) {
    // + 0.0 turns -0.0 into +0.0: they are equal values, so they must weld.
    const Vec3 p{x + 0.0, y + 0.0, z + 0.0};
    auto [it, inserted] = index_.try_emplace(p, static_cast<int32_t>(m_.vertices.size()));
    if (inserted) m_.vertices.push_back(p);
    return it->second;
  }

 private:
  struct Hash {
    size_t operator()(const Vec3& p) const {
      uint64_t h = 0x9e3779b97f4a7c15ull;
      for (double c : p) {
        h ^= std::bit_cast<uint64_t>(c) + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2);
        h *= 0xbf58476d1ce4e5b9ull;
      }
      return static_cast<size_t>(h ^ (h >> 31));
    }
  };
  SurfaceMesh& m_;
  std::unordered_map<Vec3, int32_t, Hash> index_;
};

uint32_t read_u32_le(const char* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  if constexpr (std::endian::native == std::endian::big) v = __builtin_bswap32(v);
  return v;
}

float read_f32_le(const char* p) { return std::bit_cast<float>(read_u32_le(p)); }

constexpr size_t kStlHeader = 84;  // 80-byte header + uint32 triangle count
constexpr size_t kStlRecord = 50;  // normal, 3 corners (12 floats) + uint16 attribute

SurfaceMesh read_stl_binary(std::string_view bytes, const std::string& path) {
  SurfaceMesh m;
  m.source = path;
  const size_t n = read_u32_le(bytes.data() + 80);
  Welder weld(m, 3 * n);
  m.triangles.reserve(n);
  for (size_t t = 0; t < n; ++t) {
    const char* rec = bytes.data() + kStlHeader + kStlRecord * t;
    int32_t idx[3];
    for (int c = 0; c < 3; ++c) {
      const char* v = rec + 12 + 12 * c;  // skip the stored normal: it is recomputed anyway
      const double x = read_f32_le(v), y = read_f32_le(v + 4), z = read_f32_le(v + 8);
      if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
        throw InputError(path, 0, "",
                         fmt::format("binary STL triangle {} (0-based), corner {}: non-finite "
                                     "coordinate ({}, {}, {})",
                                     t, c, x, y, z));
      idx[c] = weld.add(x, y, z);
    }
    add_triangle(m, idx[0], idx[1], idx[2]);
  }
  if (n == 0) throw InputError(path, 0, "", "binary STL with no triangles");
  if (m.triangles.empty())
    throw InputError(path, 0, "",
                     fmt::format("no triangles: all {} triangles have coincident corners", n));
  return m;
}

SurfaceMesh read_stl_ascii(std::string_view text, const std::string& path) {
  SurfaceMesh m;
  m.source = path;
  Welder weld(m, text.size() / 40);  // a corner line is ~40 characters
  LineReader lines(text);
  std::string_view line;
  int facet_line = 0;  // line of the open 'facet', 0 when none is open
  int corners = 0;
  int32_t idx[3] = {0, 0, 0};
  size_t facets = 0;
  while (lines.next(line)) {
    const int ln = lines.line();
    Tokens tk(line);
    const std::string_view kw = tk.next();
    if (kw.empty()) continue;
    if (iequals(kw, "facet")) {
      if (facet_line)
        throw InputError(path, ln, "",
                         fmt::format("'facet' before the 'endfacet' of the facet on line {}",
                                     facet_line));
      facet_line = ln;
      corners = 0;
    } else if (iequals(kw, "vertex")) {
      if (!facet_line) throw InputError(path, ln, "", "'vertex' outside a facet");
      double p[3];
      for (double& c : p) {
        const std::string_view tok = tk.next();
        if (tok.empty())
          throw InputError(path, ln, "", "vertex has fewer than 3 coordinates (x y z needed)");
        if (!parse_number(tok, c))
          throw InputError(path, ln, "", fmt::format("non-numeric coordinate '{}'", clip(tok)));
        if (!std::isfinite(c))
          throw InputError(path, ln, "", fmt::format("non-finite coordinate '{}'", clip(tok)));
      }
      if (const std::string_view extra = tk.next(); !extra.empty())
        throw InputError(path, ln, "",
                         fmt::format("unexpected extra value '{}' after x y z", clip(extra)));
      if (corners == 3)
        throw InputError(path, ln, "",
                         fmt::format("the facet on line {} has more than 3 vertices (STL facets "
                                     "are triangles)",
                                     facet_line));
      idx[corners++] = weld.add(p[0], p[1], p[2]);
    } else if (iequals(kw, "endfacet")) {
      if (!facet_line) throw InputError(path, ln, "", "'endfacet' without a 'facet'");
      if (corners != 3)
        throw InputError(path, ln, "",
                         fmt::format("the facet on line {} has {} vertices (STL facets are "
                                     "triangles)",
                                     facet_line, corners));
      add_triangle(m, idx[0], idx[1], idx[2]);
      ++facets;
      facet_line = 0;
    } else if (iequals(kw, "outer") || iequals(kw, "endloop")) {
      if (!facet_line)
        throw InputError(path, ln, "", fmt::format("'{}' outside a facet", clip(kw)));
    } else if (iequals(kw, "solid") || iequals(kw, "endsolid")) {
      // Several solids may follow one another; their names are free text.
      if (facet_line)
        throw InputError(path, ln, "",
                         fmt::format("'{}' inside the facet on line {} (missing 'endfacet')",
                                     clip(kw), facet_line));
    } else {
      throw InputError(path, ln, "",
                       fmt::format("unexpected '{}' (expected solid, facet, outer loop, vertex, "
                                   "endloop, endfacet or endsolid)",
                                   clip(kw)));
    }
  }
  if (facet_line)
    throw InputError(path, facet_line, "", "facet not closed: the file ends before 'endfacet'");
  if (facets == 0) throw InputError(path, 0, "", "ASCII STL with no facets");
  if (m.triangles.empty())
    throw InputError(path, 0, "",
                     fmt::format("no triangles: all {} facets have coincident corners", facets));
  return m;
}

SurfaceMesh read_stl(std::string_view bytes, const std::string& path) {
  // The only reliable test for binary is the size the header's count implies: binary files
  // may start with "solid" too (some exporters write it into the 80-byte header).
  if (bytes.size() >= kStlHeader) {
    const uint64_t n = read_u32_le(bytes.data() + 80);
    if (kStlHeader + kStlRecord * n == bytes.size()) return read_stl_binary(bytes, path);
  }
  size_t first = 0;
  while (first < bytes.size() && is_space(bytes[first])) ++first;
  const bool says_solid = bytes.size() - first >= 5 && iequals(bytes.substr(first, 5), "solid");
  // Text never holds a NUL byte; binary STL nearly always does (count, attribute bytes), so a
  // "solid" file with NULs is a damaged binary one and deserves the "truncated" message.
  if (says_solid && bytes.find('\0') == std::string_view::npos) return read_stl_ascii(bytes, path);
  if (bytes.size() < kStlHeader)
    throw InputError(path, 0, "",
                     fmt::format("not an STL file: {} bytes is too short for a binary STL (84-byte "
                                 "header) and it does not start with 'solid'",
                                 bytes.size()));
  const uint64_t n = read_u32_le(bytes.data() + 80);
  throw InputError(path, 0, "",
                   fmt::format("truncated or damaged binary STL: the header announces {} "
                               "triangles ({} bytes) but the file has {} bytes",
                               n, kStlHeader + kStlRecord * n, bytes.size()));
}


// =============================================================================================
// OFF (Geomview Object File Format, ASCII)
// =============================================================================================

SurfaceMesh read_off(std::string_view text, const std::string& path) {
  SurfaceMesh m;
  m.source = path;
  const auto lines = content_lines(text);
  size_t li = 0;
  if (lines.empty()) throw InputError(path, 0, "", "empty file");
  auto head = words(lines[0].second);
  if (!(head[0].size() >= 3 && head[0].substr(head[0].size() - 3) == "OFF"))
    throw InputError(path, lines[0].first, "", fmt::format("'{}' is not an OFF header", clip(lines[0].second)));
  if (head.size() == 1) {
    if (++li >= lines.size()) throw InputError(path, 0, "", "truncated: no counts line");
    head = words(lines[li].second);
  } else {
    head.erase(head.begin());
  }
  int64_t nv = -1, nf = -1;
  if (head.size() < 2 || !parse_number(head[0], nv) || !parse_number(head[1], nf) || nv < 0 || nf < 0 ||
      nv > (int64_t{1} << 30) || nf > (int64_t{1} << 30))
    throw InputError(path, lines[li].first, "counts", fmt::format("'{}' is not 'vertices faces edges'", clip(lines[li].second)));
  if (size_t(nv + nf) > lines.size() - li - 1)
    throw InputError(path, 0, "", fmt::format("truncated: {} vertices and {} faces announced, {} lines follow", nv, nf, lines.size() - li - 1));
  m.vertices.reserve(size_t(nv));
  for (int64_t v = 0; v < nv; ++v) {
    const auto& [n, l] = lines[++li];
    const auto t = words(l);
    Vec3 p;
    if (t.size() < 3 || !parse_number(t[0], p[0]) || !parse_number(t[1], p[1]) || !parse_number(t[2], p[2]) ||
        !std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
      throw InputError(path, n, "vertex", fmt::format("'{}' is not three finite coordinates", clip(l)));
    m.vertices.push_back(p);
  }
  for (int64_t f = 0; f < nf; ++f) {
    const auto& [n, l] = lines[++li];
    const auto t = words(l);
    int64_t k = 0;
    if (t.empty() || !parse_number(t[0], k) || k < 3 || size_t(k) + 1 > t.size())
      throw InputError(path, n, "face", fmt::format("'{}' is not 'N i1 ... iN' with N >= 3", clip(l)));
    std::vector<int32_t> idx(static_cast<size_t>(k));
    for (int64_t i = 0; i < k; ++i) {
      int64_t x = -1;
      if (!parse_number(t[size_t(i + 1)], x) || x < 0 || x >= nv)
        throw InputError(path, n, "face", fmt::format("vertex index '{}' is not in 0..{}", clip(t[size_t(i + 1)]), nv - 1));
      idx[size_t(i)] = int32_t(x);
    }
    for (int64_t i = 1; i + 1 < k; ++i) add_triangle(m, idx[0], idx[size_t(i)], idx[size_t(i + 1)]);
  }
  return m;
}

// =============================================================================================
// PLY (ASCII, binary little- and big-endian)
// =============================================================================================

struct PlyProperty {
  std::string name;
  std::string type;        // scalar type, or the item type of a list
  std::string count_type;  // empty: a scalar
};
struct PlyElement {
  std::string name;
  int64_t count = 0;
  std::vector<PlyProperty> props;
};

size_t ply_size(const std::string& t) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" || t == "float32") return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}

SurfaceMesh read_ply(std::string_view bytes, const std::string& path) {
  SurfaceMesh m;
  m.source = path;
  size_t pos = 0;
  int line = 0;
  auto next_line = [&]() -> std::string_view {
    const size_t nl = bytes.find('\n', pos);
    if (nl == std::string_view::npos) throw InputError(path, line + 1, "", "truncated: the header has no end_header");
    std::string_view l = bytes.substr(pos, nl - pos);
    pos = nl + 1;
    ++line;
    if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
    return l;
  };
  if (next_line() != "ply") throw InputError(path, 1, "", "not a PLY file (first line must be 'ply')");
  std::string format;
  std::vector<PlyElement> elements;
  while (true) {
    const std::string_view l = next_line();
    const auto t = words(l);
    if (t.empty() || t[0] == "comment" || t[0] == "obj_info") continue;
    if (t[0] == "end_header") break;
    if (t[0] == "format" && t.size() >= 2) {
      format = std::string(t[1]);
      if (format != "ascii" && format != "binary_little_endian" && format != "binary_big_endian")
        throw InputError(path, line, "format", fmt::format("'{}' is not ascii, binary_little_endian or binary_big_endian", clip(t[1])));
    } else if (t[0] == "element" && t.size() == 3) {
      PlyElement e;
      e.name = std::string(t[1]);
      if (!parse_number(t[2], e.count) || e.count < 0 || e.count > (int64_t{1} << 30))
        throw InputError(path, line, "element", fmt::format("'{}' is not a count", clip(t[2])));
      elements.push_back(e);
    } else if (t[0] == "property" && !elements.empty()) {
      PlyProperty p;
      if (t.size() == 5 && t[1] == "list") {
        p.count_type = std::string(t[2]);
        p.type = std::string(t[3]);
        p.name = std::string(t[4]);
        if (!ply_size(p.count_type) || p.count_type == "float" || p.count_type == "double")
          throw InputError(path, line, "property", fmt::format("list count type '{}' is not an integer type", clip(t[2])));
      } else if (t.size() == 3) {
        p.type = std::string(t[1]);
        p.name = std::string(t[2]);
      } else {
        throw InputError(path, line, "property", fmt::format("'{}' is not 'property TYPE NAME' or 'property list T T NAME'", clip(l)));
      }
      if (!ply_size(p.type)) throw InputError(path, line, "property", fmt::format("unknown type '{}'", clip(p.type)));
      elements.back().props.push_back(p);
    } else {
      throw InputError(path, line, "", fmt::format("'{}' is not a PLY header line", clip(l)));
    }
  }
  if (format.empty()) throw InputError(path, 0, "format", "missing");
  const bool ascii = format == "ascii";
  const bool swap = !ascii && ((format == "binary_big_endian") != (std::endian::native == std::endian::big));
  std::vector<std::string_view> toks;
  size_t tok_i = 0;
  if (ascii) toks = words(bytes.substr(pos));
  // One value of type `t`, as a double.
  auto value = [&](const std::string& t) -> double {
    if (ascii) {
      if (tok_i >= toks.size()) throw InputError(path, 0, "", "truncated: fewer values than the header announces");
      double v;
      if (!parse_number(toks[tok_i], v)) throw InputError(path, 0, "", fmt::format("'{}' is not a number", clip(toks[tok_i])));
      ++tok_i;
      return v;
    }
    const size_t n = ply_size(t);
    if (pos + n > bytes.size()) throw InputError(path, 0, "", "truncated: fewer bytes than the header announces");
    unsigned char b[8];
    std::memcpy(b, bytes.data() + pos, n);
    pos += n;
    if (swap) std::reverse(b, b + n);
    auto get = [&](auto x) { std::memcpy(&x, b, sizeof x); return double(x); };
    if (t == "char" || t == "int8") return get(int8_t{});
    if (t == "uchar" || t == "uint8") return get(uint8_t{});
    if (t == "short" || t == "int16") return get(int16_t{});
    if (t == "ushort" || t == "uint16") return get(uint16_t{});
    if (t == "int" || t == "int32") return get(int32_t{});
    if (t == "uint" || t == "uint32") return get(uint32_t{});
    if (t == "float" || t == "float32") return get(float{});
    return get(double{});
  };
  bool have_vertices = false, have_faces = false;
  for (const PlyElement& e : elements) {
    int ix = -1, iy = -1, iz = -1, ilist = -1;
    for (size_t k = 0; k < e.props.size(); ++k) {
      const auto& p = e.props[k];
      if (p.count_type.empty() && p.name == "x") ix = int(k);
      if (p.count_type.empty() && p.name == "y") iy = int(k);
      if (p.count_type.empty() && p.name == "z") iz = int(k);
      if (!p.count_type.empty() && (p.name == "vertex_indices" || p.name == "vertex_index")) ilist = int(k);
    }
    const bool is_vertex = e.name == "vertex", is_face = e.name == "face";
    if (is_vertex && (ix < 0 || iy < 0 || iz < 0)) throw InputError(path, 0, "element vertex", "has no x, y and z properties");
    if (is_face && ilist < 0) throw InputError(path, 0, "element face", "has no vertex_indices list");
    if (is_vertex) m.vertices.reserve(size_t(e.count));
    for (int64_t i = 0; i < e.count; ++i) {
      Vec3 p{0, 0, 0};
      std::vector<int32_t> idx;
      for (size_t k = 0; k < e.props.size(); ++k) {
        const auto& pr = e.props[k];
        if (pr.count_type.empty()) {
          const double v = value(pr.type);
          if (int(k) == ix) p[0] = v;
          if (int(k) == iy) p[1] = v;
          if (int(k) == iz) p[2] = v;
          continue;
        }
        const double c = value(pr.count_type);
        if (!(c >= 0 && c < 1e6)) throw InputError(path, 0, e.name, fmt::format("list length {} is not valid", c));
        for (int64_t j = 0; j < int64_t(c); ++j) {
          const double v = value(pr.type);
          if (int(k) == ilist && is_face) {
            if (!(v >= 0 && v == std::floor(v) && v < double(m.vertices.size())))
              throw InputError(path, 0, "face", fmt::format("face {}: vertex index {} is not in 0..{}", i, v, int64_t(m.vertices.size()) - 1));
            idx.push_back(int32_t(v));
          }
        }
      }
      if (is_vertex) {
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
          throw InputError(path, 0, "vertex", fmt::format("vertex {} is not finite", i));
        m.vertices.push_back(p);
      }
      if (is_face) {
        if (idx.size() < 3) throw InputError(path, 0, "face", fmt::format("face {} has {} vertices (at least 3)", i, idx.size()));
        for (size_t j = 1; j + 1 < idx.size(); ++j) add_triangle(m, idx[0], idx[j], idx[j + 1]);
      }
    }
    have_vertices |= is_vertex;
    have_faces |= is_face;
  }
  if (!have_vertices || !have_faces) throw InputError(path, 0, "", "a PLY surface needs a vertex and a face element");
  return m;
}

}  // namespace

SurfaceMesh read_surface_mesh(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), lower);
  if (ext != ".obj" && ext != ".stl" && ext != ".off" && ext != ".ply")
    throw InputError(path, 0, "",
                     fmt::format("unknown surface mesh file extension '{}' (expected .obj, .stl, .off or .ply)",
                                 ext));
  const std::string bytes = read_file(path);
  if (ext == ".off") return read_off(bytes, path);
  if (ext == ".ply") return read_ply(bytes, path);
  return ext == ".obj" ? read_obj(bytes, path) : read_stl(bytes, path);
}

}  // namespace stroma
