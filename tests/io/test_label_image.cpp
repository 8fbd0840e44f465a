// Label images (tissue/label_image): files written by nibabel read with their geometry, every
// format written and read back, and each bad input refused with a precise message.
// Mesh quality measures and surface checks (tissue/mesh_quality, tissue/surface_check).

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "tests/input_error_message.hpp"
#include "tissue/input_error.hpp"
#include "io/label_image.hpp"
#include "tissue/mesh_quality.hpp"
#include "io/surface_check.hpp"

using namespace stroma;
using stroma::test_support::message_of;
namespace fs = std::filesystem;

namespace {

std::string data(const std::string& name) { return std::string(STROMA_TEST_DATA) + "/images/" + name; }

fs::path temp_dir() {
  const fs::path d = fs::temp_directory_path() / ("stroma_label_image_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

/// World position of voxel (i, j, k) by the image's geometry.
Vec3 world(const LabelImage& im, double i, double j, double k) {
  const double p[3] = {i * im.spacing[0], j * im.spacing[1], k * im.spacing[2]};
  Vec3 x;
  for (int r = 0; r < 3; ++r)
    x[size_t(r)] = im.origin[size_t(r)] + im.direction[size_t(3 * r)] * p[0] + im.direction[size_t(3 * r + 1)] * p[1] +
                   im.direction[size_t(3 * r + 2)] * p[2];
  return x;
}

/// The oblique fixture's affine (scripts/meshes/write_phantom_images.py), in metres.
Vec3 oblique_world(double i, double j, double k) {
  const double c = std::cos(M_PI / 6), s = std::sin(M_PI / 6);
  const double a = 0.9 * i, b = -1.1 * j, z = 2.5 * k;  // diag(spacing), then the y flip
  return {1e-3 * (10 + c * a - s * b), 1e-3 * (-20 + s * a + c * b), 1e-3 * (30 + z)};
}

}  // namespace

TEST(LabelImage, NibabelObliqueSformAndQformGiveTheSameGeometry) {
  for (const char* name : {"oblique.nii", "oblique_qform.nii"}) {
    SCOPED_TRACE(name);
    const LabelImage im = read_label_image(data(name));
    ASSERT_EQ(im.dims, (std::array<int64_t, 3>{7, 5, 4}));
    EXPECT_NEAR(im.spacing[0], 0.9e-3, 1e-9);
    EXPECT_NEAR(im.spacing[1], 1.1e-3, 1e-9);
    EXPECT_NEAR(im.spacing[2], 2.5e-3, 1e-9);
    for (int64_t k = 0; k < 4; ++k)
      for (int64_t j = 0; j < 5; ++j)
        for (int64_t i = 0; i < 7; ++i) {
          ASSERT_EQ(im.at(i, j, k), 1 + i + 7 * j + 35 * k);
          const Vec3 got = world(im, double(i), double(j), double(k)), want = oblique_world(double(i), double(j), double(k));
          // 5 um: a qform is a float32 quaternion, and a rotation near 180 degrees (this one) loses
          // digits in a = sqrt(1 - b^2 - c^2 - d^2), as the NIfTI standard warns
          for (int a = 0; a < 3; ++a) ASSERT_NEAR(got[size_t(a)], want[size_t(a)], 5e-6) << i << " " << j << " " << k;
        }
  }
}

TEST(LabelImage, NibabelPhantomHasItsVoxelCountsAndSpacing) {
  const LabelImage im = read_label_image(data("phantom_aniso.nii.gz"));
  EXPECT_NEAR(im.spacing[0], 0.8e-3, 1e-9);
  EXPECT_NEAR(im.spacing[2], 2.0e-3, 1e-9);
  // The voxel counts give the ellipsoid shell's and the sphere's volumes within voxelisation error.
  double v1 = 0, v2 = 0;
  for (const auto& [label, n] : label_histogram(im)) {
    if (label == 1) v1 = double(n) * im.voxel_volume();
    if (label == 2) v2 = double(n) * im.voxel_volume();
  }
  EXPECT_NEAR(v1, 4.0 / 3.0 * M_PI * (0.040 * 0.030 * 0.025 - 1e-6), 0.01 * v1);
  EXPECT_NEAR(v2, 4.0 / 3.0 * M_PI * 1e-6, 0.02 * v2);
}

TEST(LabelImage, EveryFormatRoundTripsWithGeometry) {
  LabelImage im;
  im.dims = {5, 4, 3};
  im.spacing = {0.7e-3, 0.9e-3, 2.0e-3};
  im.origin = {0.01, -0.02, 0.035};
  const double c = std::cos(0.3), s = std::sin(0.3);
  im.direction = {c, -s, 0, s, c, 0, 0, 0, -1};  // a rotation and a z flip
  for (int big : {0, 1}) {
    im.labels.assign(60, 0);
    for (size_t i = 0; i < 60; ++i) im.labels[i] = big ? int32_t(i * 1000) - 7000 : int32_t(i % 7);
    const fs::path d = temp_dir();
    for (const char* ext : {".nrrd", ".nii", ".nii.gz", ".mha", ".inr", ".inr.gz"})
      for (bool compress : {false, true}) {
        SCOPED_TRACE(std::string(ext) + (compress ? " compressed" : "") + (big ? " int32" : " uint8"));
        const std::string path = (d / (std::string("im") + ext)).string();
        write_label_image(path, im, compress);
        const LabelImage back = read_label_image(path);
        EXPECT_EQ(back.dims, im.dims);
        EXPECT_EQ(back.labels, im.labels);
        for (int a = 0; a < 3; ++a) {
          EXPECT_NEAR(back.spacing[size_t(a)], im.spacing[size_t(a)], 1e-9);
          EXPECT_NEAR(back.origin[size_t(a)], im.origin[size_t(a)], 1e-9);
        }
        if (std::string(ext).find(".inr") == std::string::npos) {  // INR has no orientation
          for (int q = 0; q < 9; ++q) EXPECT_NEAR(back.direction[size_t(q)], im.direction[size_t(q)], 1e-6);
        }
      }
    fs::remove_all(d);
  }
}

TEST(LabelImage, UnitsComeFromTheFileOrTheOverride) {
  const fs::path d = temp_dir();
  const std::string path = (d / "u.nrrd").string();
  {
    std::ofstream out(path, std::ios::binary);
    out << "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 1 1\nspacings: 0.5 0.5 0.5\nspace units: \"um\" \"um\" \"um\"\n"
           "encoding: raw\n\n";
    out.put(1).put(2);
  }
  EXPECT_NEAR(read_label_image(path).spacing[0], 0.5e-6, 1e-15);
  LabelImageReadOptions o;
  o.unit_override = 1e-3;
  EXPECT_NEAR(read_label_image(path, o).spacing[0], 0.5e-3, 1e-12);
  fs::remove_all(d);
}

TEST(LabelImageErrors, TruncatedCorruptAndWrongFilesNameTheProblem) {
  const fs::path d = temp_dir();
  LabelImage im;
  im.dims = {8, 8, 8};
  im.labels.assign(512, 1);
  for (size_t i = 0; i < 512; i += 3) im.labels[i] = 2;
  // Truncated raw and compressed files, cut at several places.
  for (const char* ext : {".nrrd", ".nii", ".nii.gz", ".mha", ".inr"})
    for (bool compress : {false, true}) {
      const std::string path = (d / (std::string("t") + ext)).string();
      write_label_image(path, im, compress);
      const auto full = fs::file_size(path);
      for (double keep : {0.95, 0.6, 0.2}) {
        SCOPED_TRACE(std::string(ext) + " keep " + std::to_string(keep));
        write_label_image(path, im, compress);
        fs::resize_file(path, uintmax_t(double(full) * keep));
        const std::string m = message_of([&] { read_label_image(path); });
        EXPECT_NE(m, "(no error)");
        EXPECT_NE(m.find(path), std::string::npos) << m;
      }
    }
  // A corrupt compressed block.
  {
    const std::string path = (d / "c.mha").string();
    write_label_image(path, im, true);
    std::string bytes;
    {
      std::ifstream in(path, std::ios::binary);
      bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    const size_t data_at = bytes.find("LOCAL\n") + 6;
    ASSERT_LT(data_at + 6, bytes.size());
    for (size_t i = data_at + 2; i < bytes.size(); i += 2) bytes[i] = char(~bytes[i]);  // every other byte of the block
    std::ofstream(path, std::ios::binary) << bytes;
    const std::string m = message_of([&] { read_label_image(path); });
    EXPECT_TRUE(m.find("corrupt") != std::string::npos || m.find("truncated") != std::string::npos) << m;
  }
  auto write = [&](const std::string& name, const std::string& text) {
    const std::string p = (d / name).string();
    std::ofstream(p, std::ios::binary) << text;
    return p;
  };
  EXPECT_NE(message_of([&] { read_label_image(write("x.png", "abc")); }).find("unknown label image extension"), std::string::npos);
  EXPECT_NE(message_of([&] { read_label_image((d / "missing.nii").string()); }).find("cannot open"), std::string::npos);
  EXPECT_NE(message_of([&] { read_label_image(write("m.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nencoding: raw\n\n")); })
                .find("sizes: missing"),
            std::string::npos);
  EXPECT_NE(message_of([&] {
              read_label_image(write("f.nrrd", std::string("NRRD0004\ntype: float\ndimension: 3\nsizes: 1 1 1\nendian: little\n"
                                                           "encoding: raw\n\n") +
                                                   std::string("\x00\x00\xc0\x3f", 4)));
            }).find("not an integer label"),
            std::string::npos);
  EXPECT_NE(message_of([&] {
              read_label_image(write("s.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 1 1 1\nspace directions: (1,0,0) "
                                               "(1,1,0) (0,0,1)\nencoding: raw\n\n\x01"));
            }).find("not orthogonal"),
            std::string::npos);
  EXPECT_NE(message_of([&] {
              read_label_image(write("z.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 1 0 1\nencoding: raw\n\n\x01"));
            }).find("sizes: axis 1 size 0"),
            std::string::npos);
  EXPECT_NE(message_of([&] {
              read_label_image(write("h.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 100000 100000 100000\nencoding: "
                                               "raw\n\n\x01"));
            }).find("more than this reader takes"),
            std::string::npos);
  EXPECT_NE(message_of([&] { read_label_image(write("n.nii", std::string(100, 'x'))); }).find("truncated"), std::string::npos);
  fs::remove_all(d);
}

TEST(MeshQuality, RegularTetrahedronAndSliver) {
  const Vec3 a{1, 1, 1}, b{1, -1, -1}, c{-1, 1, -1}, d{-1, -1, 1};  // regular
  EXPECT_NEAR(tet_radius_ratio(a, b, c, d), 1.0, 1e-12);
  for (double x : tet_dihedral_angles_deg(a, b, c, d)) EXPECT_NEAR(x, std::acos(1.0 / 3.0) * 180 / M_PI, 1e-9);
  // A sliver: four nearly coplanar points on a square.
  const Vec3 p{0, 0, 0}, q{1, 0, 0.01}, r{1, 1, 0}, s{0, 1, 0.01};
  EXPECT_LT(tet_radius_ratio(p, q, r, s), 0.05);
  const auto ang = tet_dihedral_angles_deg(p, q, r, s);
  EXPECT_LT(*std::min_element(ang.begin(), ang.end()), 3.0);
  EXPECT_GT(*std::max_element(ang.begin(), ang.end()), 177.0);
  TetMesh m;
  m.nodes = {a, b, c, d, p, q, r, s};
  m.tets = {{0, 1, 2, 3}, {4, 5, 6, 7}};
  m.tet_tags = {1, 2};
  m.tag_names = {{1, "good"}, {2, "flat"}};
  const MeshQuality mq = measure_mesh_quality(m, 5.0);
  EXPECT_EQ(mq.slivers, 1);
  EXPECT_EQ(mq.tets, 2);
  ASSERT_EQ(mq.regions.size(), 2u);
  EXPECT_EQ(mq.regions[0].name, "good");
  EXPECT_NEAR(mq.regions[0].volume, 8.0 / 3.0, 1e-12);  // the regular tet in the cube [-1,1]^3: 8/3
  int64_t sum = 0;
  for (int64_t n : mq.dihedral.counts) sum += n;
  EXPECT_EQ(sum, 12);
}

namespace {

SurfaceMesh cube_surface() {
  SurfaceMesh s;
  for (int i = 0; i < 8; ++i) s.vertices.push_back({double(i & 1), double((i >> 1) & 1), double((i >> 2) & 1)});
  const int q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : q) {
    s.triangles.push_back({f[0], f[1], f[2]});
    s.triangles.push_back({f[0], f[2], f[3]});
  }
  s.source = "cube";
  return s;
}

}  // namespace

TEST(SurfaceCheck, ClosedCubeHasNoDefects) { EXPECT_TRUE(find_surface_defects(cube_surface()).empty()); }

TEST(SurfaceCheck, OpenSurfaceNamesItsBoundaryEdges) {
  SurfaceMesh s = cube_surface();
  s.triangles.pop_back();  // a hole: the triangle (1, 7, 5)
  const SurfaceDefects d = find_surface_defects(s);
  ASSERT_EQ(d.boundary_edges.size(), 3u);
  EXPECT_EQ(d.boundary_edges[0], (std::array<int32_t, 2>{1, 5}));
  const std::string m = describe_surface_defects(s, d);
  EXPECT_NE(m.find("3 boundary edges"), std::string::npos) << m;
  EXPECT_NE(m.find("edge #1 (1, 0, 0) - #5 (1, 0, 1)"), std::string::npos) << m;
}

TEST(SurfaceCheck, TwoCubesSharingAnEdgeAreNonManifold) {
  SurfaceMesh s = cube_surface(), t = cube_surface();
  // The second cube shifted by (1, 1, 0): it shares the edge x = 1, y = 1 (vertices 3 and 7).
  const int32_t base = int32_t(s.vertices.size());
  std::vector<int32_t> map(8);
  for (int i = 0; i < 8; ++i) {
    Vec3 p = t.vertices[size_t(i)];
    p[0] += 1;
    p[1] += 1;
    map[size_t(i)] = -1;
    for (size_t v = 0; v < s.vertices.size(); ++v)
      if (s.vertices[v] == p) map[size_t(i)] = int32_t(v);
    if (map[size_t(i)] < 0) {
      map[size_t(i)] = int32_t(s.vertices.size());
      s.vertices.push_back(p);
    }
  }
  (void)base;
  for (const Tri& tr : t.triangles) s.triangles.push_back({map[size_t(tr[0])], map[size_t(tr[1])], map[size_t(tr[2])]});
  const SurfaceDefects d = find_surface_defects(s);
  ASSERT_EQ(d.nonmanifold_edges.size(), 1u);
  EXPECT_EQ(d.nonmanifold_edges[0], (std::array<int32_t, 2>{3, 7}));
  EXPECT_NE(describe_surface_defects(s, d).find("non-manifold edges"), std::string::npos);
}
