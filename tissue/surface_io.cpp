/// \file surface_io.cpp
/// Surface mesh readers (see surface_io.hpp). The file is read into one buffer and walked line
/// by line (text formats) or record by record (binary STL); numbers go through std::from_chars,
/// which is exact and locale-independent.
#include "tissue/surface_io.hpp"

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
#include "tissue/text_scan.hpp"

namespace stroma {
namespace {

using namespace text;  // is_space, lower, iequals, clip, parse_number (tissue/text_scan.hpp)

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

}  // namespace

SurfaceMesh read_surface_mesh(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), lower);
  if (ext != ".obj" && ext != ".stl")
    throw InputError(path, 0, "",
                     fmt::format("unknown surface mesh file extension '{}' (expected .obj or .stl)",
                                 ext));
  const std::string bytes = read_file(path);
  return ext == ".obj" ? read_obj(bytes, path) : read_stl(bytes, path);
}

}  // namespace stroma
