// Tests for tissue/surface_io: OBJ and STL surfaces (the real liver surface, small fixtures for
// every syntax variant, STL welding, exact file:line errors).
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "tests/test_meshes.hpp"
#include "tissue/barycentric.hpp"
#include "tissue/input_error.hpp"
#include "io/mesh_io.hpp"
#include "tissue/mesh_prepare.hpp"
#include "io/surface_io.hpp"
#include "tissue/visual_mapping.hpp"

namespace stroma {
namespace {

std::string real_mesh(const std::string& name) {
  return std::string(STROMA_SOURCE_DIR) + "/scenarios/meshes/" + name;
}
std::string fixture(const std::string& name) {
  return std::string(STROMA_TEST_DATA) + "/surface/" + name;
}
std::string write_temp_file(const std::string& name, const std::string& bytes) {
  // TempDir() ends with a separator; the prefix keeps clear of other suites' files.
  const std::string path = ::testing::TempDir() + "surface_io_" + name;
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return path;
}
std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Reads `path`, which must fail with exactly `what` and `line`.
void expect_error(const std::string& path, int line, const std::string& what) {
  try {
    read_surface_mesh(path);
    ADD_FAILURE() << "no InputError for " << path;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_EQ(std::string(e.what()), what);
  }
}

/// Reads `path`, which must fail at `line` with a message containing every one of `words`.
void expect_error_words(const std::string& path, int line, const std::vector<std::string>& words) {
  try {
    read_surface_mesh(path);
    ADD_FAILURE() << "no InputError for " << path;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.line(), line) << what;
    const std::string where = line > 0 ? path + ":" + std::to_string(line) + ": " : path + ": ";
    EXPECT_EQ(what.rfind(where, 0), 0u) << what;
    for (const std::string& w : words)
      EXPECT_NE(what.find(w), std::string::npos) << "missing '" << w << "' in: " << what;
  }
}

// The unit cube the fixtures describe: 6 outward quads, each split (a b c), (a c d).
const std::vector<Vec3> kCubeVertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                         {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
const std::vector<Tri> kCubeTriangles = {{0, 3, 2}, {0, 2, 1}, {4, 5, 6}, {4, 6, 7},
                                         {0, 1, 5}, {0, 5, 4}, {3, 7, 6}, {3, 6, 2},
                                         {0, 4, 7}, {0, 7, 3}, {1, 2, 6}, {1, 6, 5}};

/// The triangles of `m` as corner positions, to compare meshes whose vertex numbering differs.
std::vector<std::array<Vec3, 3>> corner_positions(const SurfaceMesh& m) {
  std::vector<std::array<Vec3, 3>> out;
  for (const Tri& t : m.triangles)
    out.push_back({m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]});
  return out;
}
std::vector<std::array<Vec3, 3>> cube_corner_positions() {
  SurfaceMesh cube;
  cube.vertices = kCubeVertices;
  cube.triangles = kCubeTriangles;
  return corner_positions(cube);
}

/// A closed, consistently oriented surface: every directed edge once, its reverse once. Only
/// true of a welded STL if equal corners really became one vertex.
void expect_closed_oriented(const SurfaceMesh& m) {
  std::map<std::pair<int32_t, int32_t>, int> edges;
  for (const Tri& t : m.triangles)
    for (int k = 0; k < 3; ++k) ++edges[{t[k], t[(k + 1) % 3]}];
  for (const auto& [e, n] : edges) {
    EXPECT_EQ(n, 1) << e.first << "-" << e.second;
    EXPECT_EQ(edges.count({e.second, e.first}), 1u) << e.first << "-" << e.second;
  }
}

/// Binary STL of the cube; the header starts with "solid" as some exporters write it.
std::string cube_binary_stl() {
  std::string bytes(80, ' ');
  const std::string header = "solid cube, binary despite the word solid";
  std::memcpy(bytes.data(), header.data(), header.size());
  auto put_u32 = [&](uint32_t v) {
    for (int i = 0; i < 4; ++i) bytes.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
  };
  auto put_f32 = [&](float f) { put_u32(std::bit_cast<uint32_t>(f)); };
  put_u32(static_cast<uint32_t>(kCubeTriangles.size()));
  bool negative_zero_written = false;
  for (const Tri& t : kCubeTriangles) {
    for (int k = 0; k < 3; ++k) put_f32(0.0f);  // normal: readers recompute it
    for (int32_t v : t)
      for (double c : kCubeVertices[v]) {
        // One -0.0 corner: equal to 0.0, so it must weld with it.
        float f = static_cast<float>(c);
        if (f == 0.0f && !negative_zero_written) {
          f = -0.0f;
          negative_zero_written = true;
        }
        put_f32(f);
      }
    bytes.push_back('\0');
    bytes.push_back('\0');
  }
  return bytes;
}

// ---------------------------------------------------------------------------------------------
// SurfaceIo
// ---------------------------------------------------------------------------------------------

TEST(SurfaceIo, LiverSmoothObj) {
  const std::string path = real_mesh("liver-smooth.obj");
  const SurfaceMesh m = read_surface_mesh(path);
  EXPECT_EQ(m.source, path);
  ASSERT_EQ(m.vertices.size(), 2194u);
  ASSERT_EQ(m.triangles.size(), 4384u);
  EXPECT_EQ(m.vertices.front(), (Vec3{-0.937089, 2.350946, 2.588653}));  // line 5
  EXPECT_EQ(m.vertices.back(), (Vec3{-1.035663, 2.325666, 2.427308}));   // line 2198
  EXPECT_EQ(m.triangles.front(), (Tri{0, 2193, 1374}));  // "f 1//1 2194//2 1375//3"
  EXPECT_EQ(m.triangles.back(), (Tri{1374, 2193, 552}));  // "f 1375//3 2194//2 553//2117"
}

TEST(SurfaceIo, CubeObjQuadsNegativeIndicesCrlf) {
  const std::string path = fixture("cube.obj");
  // Guards the fixture itself: a checkout that normalised line endings would test less.
  ASSERT_NE(read_bytes(path).find("\r\n"), std::string::npos);
  const SurfaceMesh m = read_surface_mesh(path);
  EXPECT_EQ(m.vertices, kCubeVertices);
  // 6 quads → 12 triangles; "f 1 2 2" is dropped (repeated vertex).
  EXPECT_EQ(m.triangles, kCubeTriangles);
  expect_closed_oriented(m);
}

TEST(SurfaceIo, ExtensionIsCaseInsensitive) {
  const std::string path = write_temp_file("CUBE.OBJ", read_bytes(fixture("cube.obj")));
  EXPECT_EQ(read_surface_mesh(path).triangles, kCubeTriangles);
}

TEST(SurfaceIo, AsciiStlWeldsToIndexedMesh) {
  const SurfaceMesh m = read_surface_mesh(fixture("cube_ascii.stl"));
  EXPECT_EQ(m.vertices.size(), 8u);
  EXPECT_EQ(m.triangles.size(), 12u);
  EXPECT_EQ(corner_positions(m), cube_corner_positions());
  expect_closed_oriented(m);
}

TEST(SurfaceIo, BinaryStlStartingWithSolidWeldsToIndexedMesh) {
  const std::string bytes = cube_binary_stl();
  ASSERT_EQ(bytes.size(), 84u + 50u * 12u);
  const SurfaceMesh m = read_surface_mesh(write_temp_file("cube_binary.stl", bytes));
  EXPECT_EQ(m.vertices.size(), 8u);  // the -0.0 corner welded with 0.0
  EXPECT_EQ(m.triangles.size(), 12u);
  EXPECT_EQ(corner_positions(m), cube_corner_positions());
  expect_closed_oriented(m);
}

TEST(SurfaceIo, BinaryStlTruncated) {
  std::string bytes = cube_binary_stl();
  bytes.resize(bytes.size() - 10);
  const std::string path = write_temp_file("truncated.stl", bytes);
  expect_error(path, 0,
               path + ": truncated or damaged binary STL: the header announces 12 triangles "
                      "(684 bytes) but the file has 674 bytes");
}

TEST(SurfaceIo, ObjBadIndex) {
  const std::string path = fixture("bad_index.obj");
  expect_error(path, 7, path + ":7: face index 5 out of range (the file has 4 vertices so far)");
}

TEST(SurfaceIo, ObjBadNumber) {
  const std::string path = fixture("bad_number.obj");
  expect_error(path, 3, path + ":3: non-numeric value '1,5' in vertex 2");
}

TEST(SurfaceIo, ObjIndexErrors) {
  // Relative indices count vertices read so far: -4 is out of range after 3 vertices even though
  // a fourth vertex follows.
  const std::string relative =
      write_temp_file("relative.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\nv 0 0 1\n");
  expect_error(relative, 4,
               relative + ":4: face index -4 out of range (the file has 3 vertices so far)");
  const std::string zero = write_temp_file("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
  expect_error_words(zero, 4, {"face index 0 is invalid", "start at 1"});
  const std::string junk = write_temp_file("junk.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x/3\n");
  expect_error_words(junk, 4, {"invalid face vertex 'x/3'"});
  const std::string two = write_temp_file("two.obj", "v 0 0 0\nv 1 0 0\n\nf 1 2\n");
  expect_error(two, 4, two + ":4: face has 2 vertices (at least 3 needed)");
}

TEST(SurfaceIo, ObjVertexErrors) {
  const std::string nan = write_temp_file("nan.obj", "# x\nv 0 0 0\nv 1 nan 0\n");
  expect_error(nan, 3, nan + ":3: non-finite coordinate 'nan' in vertex 2");
  const std::string inf = write_temp_file("inf.obj", "v 1e999 0 0\n");  // overflows: not finite
  expect_error_words(inf, 1, {"1e999"});
  const std::string short_v = write_temp_file("short.obj", "v 0 0 0\nv 1 2\n");
  expect_error(short_v, 2, short_v + ":2: vertex 2 has 2 coordinates (x y z needed)");
}

TEST(SurfaceIo, ObjWholeFileErrors) {
  const std::string no_v = write_temp_file("no_v.obj", "# nothing\ng empty\n");
  expect_error(no_v, 0, no_v + ": no vertices (no 'v' lines)");
  const std::string no_f = write_temp_file("no_f.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  expect_error(no_f, 0, no_f + ": no faces (no 'f' lines)");
  const std::string degenerate =
      write_temp_file("degenerate.obj", "v 0 0 0\nv 1 0 0\nf 1 2 2\nf 1 1 1\n");
  expect_error(degenerate, 0,
               degenerate + ": no triangles: all 2 faces use a vertex more than once");
}

TEST(SurfaceIo, AsciiStlErrors) {
  const std::string two = write_temp_file(
      "two.stl",
      "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\n"
      "endfacet\nendsolid t\n");
  expect_error(two, 7,
               two + ":7: the facet on line 2 has 2 vertices (STL facets are triangles)");
  const std::string bad = write_temp_file(
      "bad.stl",
      "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 zero 0\n");
  expect_error(bad, 5, bad + ":5: non-numeric coordinate 'zero'");
  const std::string open = write_temp_file(
      "open.stl",
      "solid t\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n"
      "   vertex 0 1 0\n  endloop\n");
  expect_error_words(open, 2, {"facet not closed"});
}

TEST(SurfaceIo, NotAnStl) {
  const std::string path = write_temp_file("short.stl", "hello\n");
  expect_error_words(path, 0, {"not an STL file", "6 bytes"});
}

TEST(SurfaceIo, UnknownExtensionAndMissingFile) {
  const std::string gltf = write_temp_file("cube.gltf", "{}\n");
  expect_error(gltf, 0,
               gltf + ": unknown surface mesh file extension '.gltf' (expected .obj, .stl, .off or .ply)");
  const std::string missing = ::testing::TempDir() + "surface_io_no_such_file.obj";
  std::remove(missing.c_str());
  expect_error(missing, 0, missing + ": cannot open file");
}

}  // namespace
}  // namespace stroma

namespace stroma {
namespace {

/// The cube of cube.obj as quads (0-based), for the OFF and PLY writers below.
std::vector<std::array<int32_t, 4>> cube_quads() {
  const SurfaceMesh m = read_surface_mesh(fixture("cube.obj"));
  std::vector<std::array<int32_t, 4>> q;
  for (size_t t = 0; t + 1 < m.triangles.size(); t += 2)  // fan pairs: (a b c), (a c d)
    q.push_back({m.triangles[t][0], m.triangles[t][1], m.triangles[t][2], m.triangles[t + 1][2]});
  return q;
}

}  // namespace

TEST(SurfaceIo, OffAndPlyGiveTheSameCubeAsObj) {
  const SurfaceMesh obj = read_surface_mesh(fixture("cube.obj"));
  const auto quads = cube_quads();
  // OFF, with a comment and the counts on the header line's next line.
  std::string off = "OFF\n# a cube\n8 6 12\n";
  for (const Vec3& v : obj.vertices) off += fmt::format("{} {} {}\n", v[0], v[1], v[2]);
  for (const auto& q : quads) off += fmt::format("4 {} {} {} {}\n", q[0], q[1], q[2], q[3]);
  SurfaceMesh m = read_surface_mesh(write_temp_file("cube.off", off));
  EXPECT_EQ(m.vertices, obj.vertices);
  EXPECT_EQ(m.triangles, obj.triangles);
  // PLY: ASCII and both binary byte orders, with an extra vertex property and an extra element.
  for (const std::string format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    SCOPED_TRACE(format);
    std::string ply = "ply\nformat " + format + " 1.0\ncomment made by a test\nelement vertex 8\nproperty float x\n"
                      "property float y\nproperty float z\nproperty uchar red\nelement face 6\n"
                      "property list uchar int vertex_indices\nelement edge 1\nproperty int vertex1\nproperty int vertex2\n"
                      "end_header\n";
    const bool big = format == "binary_big_endian";
    auto put = [&](auto x) {
      char b[sizeof x];
      std::memcpy(b, &x, sizeof x);
      if (big != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof x);
      ply.append(b, sizeof x);
    };
    for (const Vec3& v : obj.vertices) {
      if (format == "ascii") ply += fmt::format("{} {} {} 200\n", v[0], v[1], v[2]);
      else { put(float(v[0])); put(float(v[1])); put(float(v[2])); put(uint8_t(200)); }
    }
    for (const auto& q : quads) {
      if (format == "ascii") ply += fmt::format("4 {} {} {} {}\n", q[0], q[1], q[2], q[3]);
      else { put(uint8_t(4)); for (int32_t i : q) put(i); }
    }
    if (format == "ascii") ply += "0 1\n";
    else { put(int32_t(0)); put(int32_t(1)); }
    m = read_surface_mesh(write_temp_file("cube_" + format + ".ply", ply));
    EXPECT_EQ(m.vertices, obj.vertices);
    EXPECT_EQ(m.triangles, obj.triangles);
    // Cut inside the data: refused as truncated.
    const std::string cut = ply.substr(0, ply.size() - 12);
    try {
      read_surface_mesh(write_temp_file("cut_" + format + ".ply", cut));
      ADD_FAILURE() << "a truncated PLY was read";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
    }
  }
  try {
    read_surface_mesh(write_temp_file("bad.off", "OFF\n8 6 12\n0 0 0\n"));
    ADD_FAILURE() << "a truncated OFF was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("truncated: 8 vertices and 6 faces announced"), std::string::npos) << e.what();
  }
}

}  // namespace stroma
