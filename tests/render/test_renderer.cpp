// Tests for render/ (the off-screen OSMesa renderer and its helpers):
//  - RenderGolden: SOFA's liver (scenarios/liver.yaml, visual surface mapped onto the tets) in
//    the pressed state of scenarios/regression/liver_probe_press.ref.csv, coloured by the
//    displacement magnitude, with a spherical probe, compared with a stored golden PNG within
//    a tolerance; the rest state must NOT pass the same comparison (the tolerance can see the
//    press). STROMA_UPDATE_GOLDEN=1 rewrites the golden instead.
//  - RendererBasics: background gradient, framing by fit_camera, index checks, the stress and
//    damage colour maps, wireframe, MSAA edge blending, contact markers, clear_bodies, size
//    limits, and one GL context serving renderers smaller and larger than itself.
//  - PngIo: exact round trips, precise errors on unwritable and missing files.
//  - FrameWriter: numbered frames in order, the bounded buffer pool, write errors.
//  - CapsuleMesh: vertices on the capsule surface, outward unit normals, CCW triangles, spheres.
//  - RigidView: shapes posed in the world (a needle's tube along its straight or curved axis, a
//    box's faces outward), and rigid bodies and track marks drawn where they are.
// One GlContext per process (a gtest Environment); every Renderer draws into its own FBOs.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/model.hpp"
#include "render/capsule_mesh.hpp"
#include "render/frame_writer.hpp"
#include "render/gl_context.hpp"
#include "render/png_io.hpp"
#include "render/renderer.hpp"
#include "render/rigid_view.hpp"
#include "runtime/state_io.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"

namespace stroma::render {
namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// The GL context: one per process, larger than most images rendered here.

constexpr int kContextWidth = 640, kContextHeight = 480;

class GlEnvironment : public ::testing::Environment {
 public:
  void SetUp() override { context = std::make_unique<GlContext>(kContextWidth, kContextHeight); }
  void TearDown() override { context.reset(); }
  static inline std::unique_ptr<GlContext> context;
};
[[maybe_unused]] ::testing::Environment* const kGlEnvironment =
    ::testing::AddGlobalTestEnvironment(new GlEnvironment);

// ---------------------------------------------------------------------------------------------
// Small image helpers.

using Rgb = std::array<int, 3>;

Rgb pixel(const Image& im, int x, int y) {
  const size_t o = (static_cast<size_t>(y) * im.width + x) * im.channels;
  return {im.pixels[o], im.pixels[o + 1], im.pixels[o + 2]};
}

int max_channel_difference(const Rgb& a, const Rgb& b) {
  return std::max({std::abs(a[0] - b[0]), std::abs(a[1] - b[1]), std::abs(a[2] - b[2])});
}

double luminance(const Rgb& c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

int row_sum(const Image& im, int y) {
  int s = 0;
  for (int x = 0; x < im.width; ++x)
    for (int c : pixel(im, x, y)) s += c;
  return s;
}

/// Pixels of `im` that differ from the background-only frame `bg` (a body, a tool, a marker).
std::vector<bool> foreground_mask(const Image& im, const Image& bg, int threshold = 3) {
  std::vector<bool> m(static_cast<size_t>(im.width) * im.height);
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x)
      m[static_cast<size_t>(y) * im.width + x] = max_channel_difference(pixel(im, x, y), pixel(bg, x, y)) > threshold;
  return m;
}

size_t count(const std::vector<bool>& mask) { return static_cast<size_t>(std::count(mask.begin(), mask.end(), true)); }

struct PixelBox {
  int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
  int width() const { return x1 - x0 + 1; }
  int height() const { return y1 - y0 + 1; }
};

PixelBox bounding_box(const std::vector<bool>& mask, int w, int h) {
  PixelBox b;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if (mask[static_cast<size_t>(y) * w + x]) {
        b.x0 = std::min(b.x0, x), b.x1 = std::max(b.x1, x);
        b.y0 = std::min(b.y0, y), b.y1 = std::max(b.y1, y);
      }
  return b;
}

bool touches_border(const std::vector<bool>& mask, int w, int h) {
  for (int x = 0; x < w; ++x)
    if (mask[x] || mask[static_cast<size_t>(h - 1) * w + x]) return true;
  for (int y = 0; y < h; ++y)
    if (mask[static_cast<size_t>(y) * w] || mask[static_cast<size_t>(y) * w + w - 1]) return true;
  return false;
}

/// Mean of f(pixel) over the masked pixels.
template <class F>
double mean_over(const Image& im, const std::vector<bool>& mask, F f) {
  double s = 0;
  size_t n = 0;
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x)
      if (mask[static_cast<size_t>(y) * im.width + x]) s += f(pixel(im, x, y)), ++n;
  return n ? s / static_cast<double>(n) : 0.0;
}

/// Halves an image by averaging 2x2 blocks.
Image downsample_2x(const Image& im) {
  Image out;
  out.width = im.width / 2, out.height = im.height / 2, out.channels = 3;
  out.pixels.resize(static_cast<size_t>(out.width) * out.height * 3);
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const int s = pixel(im, 2 * x, 2 * y)[c] + pixel(im, 2 * x + 1, 2 * y)[c] + pixel(im, 2 * x, 2 * y + 1)[c] +
                      pixel(im, 2 * x + 1, 2 * y + 1)[c];
        out.pixels[(static_cast<size_t>(y) * out.width + x) * 3 + c] = static_cast<uint8_t>((s + 2) / 4);
      }
  return out;
}

/// The golden comparison's statistics.
struct ImageDifference {
  double mean_abs = 0;       ///< mean absolute channel difference (levels)
  double fraction_over = 0;  ///< pixels with some channel differing by more than 24 levels
};

ImageDifference compare_images(const Image& a, const Image& b) {
  ImageDifference d;
  if (a.width != b.width || a.height != b.height || a.channels != 3 || b.channels != 3) {
    d.mean_abs = d.fraction_over = 1e9;  // different shapes never match
    return d;
  }
  double sum = 0;
  size_t over = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      const Rgb p = pixel(a, x, y), q = pixel(b, x, y);
      for (int c = 0; c < 3; ++c) sum += std::abs(p[c] - q[c]);
      over += max_channel_difference(p, q) > 24;
    }
  const double pixels = static_cast<double>(a.width) * a.height;
  d.mean_abs = sum / (3 * pixels);
  d.fraction_over = static_cast<double>(over) / pixels;
  return d;
}

bool within_golden_tolerance(const ImageDifference& d) { return d.mean_abs < 1.5 && d.fraction_over < 0.01; }

/// |a − b| per channel, amplified 4x so small differences show.
Image difference_image(const Image& a, const Image& b) {
  Image d = a;
  for (size_t i = 0; i < d.pixels.size() && i < b.pixels.size(); ++i)
    d.pixels[i] = static_cast<uint8_t>(std::min(255, 4 * std::abs(int(a.pixels[i]) - int(b.pixels[i]))));
  return d;
}

/// The folder of this executable (the build tree): where failing images are written.
std::string build_dir() { return fs::read_symlink("/proc/self/exe").parent_path().string(); }

/// A fresh directory under the test temp dir.
std::string fresh_dir(const std::string& name) {
  const fs::path p = fs::path(::testing::TempDir()) / ("stroma_render_" + name);
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

// ---------------------------------------------------------------------------------------------
// Test geometry.

struct Mesh {
  std::vector<float> positions;  // 3 per vertex
  std::vector<uint32_t> triangles;
  size_t vertices() const { return positions.size() / 3; }
  size_t triangle_count() const { return triangles.size() / 3; }
};

/// A latitude–longitude sphere with single pole vertices, triangles counter-clockwise outside.
Mesh uv_sphere(const Vec3f& c, float r, int rings = 24, int segments = 48) {
  Mesh m;
  auto add = [&](float x, float y, float z) { m.positions.insert(m.positions.end(), {c[0] + r * x, c[1] + r * y, c[2] + r * z}); };
  add(0, 1, 0);  // north pole: vertex 0
  for (int i = 1; i < rings; ++i) {
    const double th = M_PI * i / rings;
    for (int j = 0; j < segments; ++j) {
      const double ph = 2 * M_PI * j / segments;
      add(float(std::sin(th) * std::cos(ph)), float(std::cos(th)), float(std::sin(th) * std::sin(ph)));
    }
  }
  add(0, -1, 0);  // south pole
  const uint32_t south = static_cast<uint32_t>(m.vertices() - 1), S = static_cast<uint32_t>(segments);
  auto ring = [&](int i, int j) { return 1 + static_cast<uint32_t>(i - 1) * S + static_cast<uint32_t>(j % segments); };
  // Seen from outside, with longitude φ increasing from +x towards +z, CCW is (pole, j+1, j) at
  // the north pole.
  for (int j = 0; j < segments; ++j) m.triangles.insert(m.triangles.end(), {0u, ring(1, j + 1), ring(1, j)});
  for (int i = 1; i + 1 < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const uint32_t a = ring(i, j), b = ring(i, j + 1), c2 = ring(i + 1, j), d = ring(i + 1, j + 1);
      m.triangles.insert(m.triangles.end(), {a, b, d, a, d, c2});
    }
  for (int j = 0; j < segments; ++j) m.triangles.insert(m.triangles.end(), {south, ring(rings - 1, j), ring(rings - 1, j + 1)});
  return m;
}

/// A square of side `side` in the plane z = 0 facing +z, rotated by `degrees` about z.
Mesh tilted_square(float side, float degrees) {
  const float a = degrees * static_cast<float>(M_PI) / 180, h = side / 2;
  Mesh m;
  for (auto [x, y] : {std::pair{-h, -h}, {h, -h}, {h, h}, {-h, h}})
    m.positions.insert(m.positions.end(), {x * std::cos(a) - y * std::sin(a), x * std::sin(a) + y * std::cos(a), 0.0f});
  m.triangles = {0, 1, 2, 0, 2, 3};
  return m;
}

int add_mesh(Renderer& r, const Mesh& m) { return r.add_body(m.positions.data(), m.vertices(), m.triangles.data(), m.triangle_count()); }

/// A renderer's image of nothing but the background, for the same size and look.
Image background_frame(int w, int h, const Look& look) {
  Renderer r(w, h, look);
  Image im;
  r.render(im);
  return im;
}

Image render_once(Renderer& r) {
  Image im;
  r.render(im);
  return im;
}

/// A renderer showing `m` framed by fit_camera from `view`.
std::unique_ptr<Renderer> framed_renderer(int w, int h, const Look& look, const Mesh& m,
                                          Vec3f view = {0.25f, -0.55f, -1.0f}) {
  auto r = std::make_unique<Renderer>(w, h, look);
  add_mesh(*r, m);
  r->set_camera(r->fit_camera(view, {0, 1, 0}));
  return r;
}

Look plain_look(ColorField field = ColorField::None, int msaa = 4) {
  Look l;
  l.field = field;
  l.msaa = msaa;
  return l;
}

// ---------------------------------------------------------------------------------------------
// The liver of scenarios/liver.yaml: its visual surface, at rest and pressed.

struct LiverScene {
  std::shared_ptr<const Model> model;
  VisualMapping mapping;                      // visual vertex ← tetrahedra
  Mesh visual;                                // rest positions of the visual surface
  std::vector<double> pressed_nodes;          // liver_probe_press.ref.csv
  std::vector<float> rest_positions, pressed_positions;  // the mapping applied to fem.rest / pressed
  std::vector<float> pressed_stress;          // |pressed − rest| per visual vertex
};

/// Positions of the visual vertices for node positions `x` (3 per node).
std::vector<float> map_to_visual(const VisualMapping& m, const std::vector<double>& x) {
  std::vector<float> out(3 * m.size());
  m.apply(x.data(), out.data());
  return out;
}

/// Per-vertex displacement magnitude: the deterministic "stress" field of the golden test.
std::vector<float> displacement_magnitude(const std::vector<float>& x, const std::vector<float>& rest) {
  std::vector<float> d(x.size() / 3);
  for (size_t i = 0; i < d.size(); ++i)
    d[i] = std::hypot(x[3 * i] - rest[3 * i], x[3 * i + 1] - rest[3 * i + 1], x[3 * i + 2] - rest[3 * i + 2]);
  return d;
}

const LiverScene& liver() {
  static const LiverScene scene = [] {
    LiverScene s;
    const CompiledScenario sc = compile_scenario(load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/liver.yaml"));
    s.model = sc.model;
    if (sc.visuals.empty() || !sc.visuals[0]) throw std::runtime_error("liver.yaml has no visual");
    const VisualModel& v = *sc.visuals[0];
    s.mapping = v.mapping;
    for (const Vec3& p : v.rest)
      s.visual.positions.insert(s.visual.positions.end(), {float(p[0]), float(p[1]), float(p[2])});
    s.visual.triangles = v.triangles;
    s.pressed_nodes = read_state_csv(std::string(STROMA_SOURCE_DIR) + "/scenarios/regression/liver_probe_press.ref.csv");
    if (s.pressed_nodes.size() != s.model->fem.rest.size())
      throw std::runtime_error("liver_probe_press.ref.csv does not match liver.yaml's mesh");
    s.rest_positions = map_to_visual(v.mapping, s.model->fem.rest);
    s.pressed_positions = map_to_visual(v.mapping, s.pressed_nodes);
    s.pressed_stress = displacement_magnitude(s.pressed_positions, s.rest_positions);
    return s;
  }();
  return scene;
}

// ---------------------------------------------------------------------------------------------
// RenderGolden

constexpr int kGoldenWidth = 320, kGoldenHeight = 240;
constexpr float kGoldenFieldMax = 2.0f;  // mesh units of displacement: the top of the colour map

std::string golden_path() { return std::string(STROMA_TEST_DATA) + "/render/golden_liver_pressed.png"; }

/// The golden scene: the liver at `positions` coloured by `stress`, the probe's sphere.
Image render_liver(const std::vector<float>& positions, const std::vector<float>& stress) {
  const LiverScene& s = liver();
  Look look;
  look.field = ColorField::Stress;
  look.field_min = 0;
  look.field_max = kGoldenFieldMax;
  look.msaa = 4;
  Renderer r(kGoldenWidth, kGoldenHeight, look);
  const int id = add_mesh(r, s.visual);
  r.update_body(id, positions.data(), stress.data(), nullptr);
  r.set_camera(r.fit_camera({0.25f, -0.55f, -1.0f}, {0, 1, 0}));
  ToolView probe;
  probe.capsules.push_back({{-1.5f, 4.6f, 0.5f}, {-1.5f, 4.6f, 0.5f}, 0.3f});
  r.set_tools({probe});
  return render_once(r);
}

bool updating_golden() {
  const char* e = std::getenv("STROMA_UPDATE_GOLDEN");
  return e && std::string(e) == "1";
}

TEST(RenderGolden, PressedLiverMatchesGolden) {
  const LiverScene& s = liver();
  const Image actual = render_liver(s.pressed_positions, s.pressed_stress);
  std::printf("largest visual-vertex displacement %.4f (colour map top %.2f)\n",
              *std::max_element(s.pressed_stress.begin(), s.pressed_stress.end()), kGoldenFieldMax);
  ASSERT_EQ(actual.width, kGoldenWidth);
  ASSERT_EQ(actual.height, kGoldenHeight);
  if (updating_golden()) {
    std::string err;
    ASSERT_TRUE(write_png(golden_path(), actual, 9, &err)) << err;
    std::printf("wrote the golden image %s\n", golden_path().c_str());
    GTEST_SKIP() << "STROMA_UPDATE_GOLDEN=1: golden written to " << golden_path();
  }
  const Image golden = read_png(golden_path());
  const ImageDifference d = compare_images(actual, golden);
  std::printf("pressed vs golden: mean |diff| %.4f levels, %.4f %% of pixels over 24 levels\n", d.mean_abs,
              100 * d.fraction_over);
  if (!within_golden_tolerance(d)) {
    const std::string a = build_dir() + "/render_golden_actual.png", diff = build_dir() + "/render_golden_diff.png";
    std::string e1, e2;
    write_png(a, actual, 1, &e1);
    write_png(diff, difference_image(actual, golden), 1, &e2);
    ADD_FAILURE() << "the pressed liver differs from " << golden_path() << ": mean |diff| " << d.mean_abs
                  << " levels (limit 1.5), " << 100 * d.fraction_over << " % of pixels over 24 levels (limit 1 %)\n"
                  << "actual image: " << a << " " << e1 << "\ndifference (x4): " << diff << " " << e2;
  }
}

TEST(RenderGolden, RestStateIsDetectablyDifferent) {
  if (updating_golden()) GTEST_SKIP() << "STROMA_UPDATE_GOLDEN=1";
  const LiverScene& s = liver();
  // The rest state with the same field definition (displacement from rest: zero everywhere).
  const Image rest = render_liver(s.rest_positions, displacement_magnitude(s.rest_positions, s.rest_positions));
  const Image golden = read_png(golden_path());
  const ImageDifference d = compare_images(rest, golden);
  std::printf("rest vs golden: mean |diff| %.4f levels, %.4f %% of pixels over 24 levels\n", d.mean_abs,
              100 * d.fraction_over);
  EXPECT_FALSE(within_golden_tolerance(d)) << "the rest state passes the golden comparison: the tolerance "
                                              "cannot see the press (mean " << d.mean_abs << ", "
                                           << 100 * d.fraction_over << " % over 24)";
}

TEST(RenderGolden, PressedShapeAloneIsDetectable) {
  // Geometry only: the rest shape wearing the pressed colours must not pass either, so the
  // comparison sees the dent itself and not only the colour map.
  if (updating_golden()) GTEST_SKIP() << "STROMA_UPDATE_GOLDEN=1";
  const LiverScene& s = liver();
  const Image rest_shape = render_liver(s.rest_positions, s.pressed_stress);
  const ImageDifference d = compare_images(rest_shape, read_png(golden_path()));
  std::printf("rest shape, pressed colours vs golden: mean |diff| %.4f levels, %.4f %% of pixels over 24 levels\n",
              d.mean_abs, 100 * d.fraction_over);
  EXPECT_FALSE(within_golden_tolerance(d)) << "mean " << d.mean_abs << ", " << 100 * d.fraction_over << " % over 24";
}

// ---------------------------------------------------------------------------------------------
// RendererBasics

TEST(RendererBasics, ContextIsCoreProfile33OrNewer) {
  ASSERT_TRUE(GlEnvironment::context);
  const std::string v = GlEnvironment::context->version();
  int major = 0, minor = 0;
  ASSERT_EQ(std::sscanf(v.c_str(), "%d.%d", &major, &minor), 2) << v;
  EXPECT_GE(major * 10 + minor, 33) << v;
  EXPECT_NE(v.find("Core"), std::string::npos) << v;
  std::printf("GL %s on %s\n", v.c_str(), GlEnvironment::context->renderer().c_str());
}

TEST(RendererBasics, BackgroundIsAVerticalGradient) {
  const Image bg = background_frame(320, 240, plain_look());
  ASSERT_EQ(bg.width, 320);
  ASSERT_EQ(bg.height, 240);
  ASSERT_EQ(bg.pixels.size(), size_t{320 * 240 * 3});
  EXPECT_GT(row_sum(bg, 0), row_sum(bg, bg.height - 1) + 3 * 320 * 20) << "top row not clearly brighter";
  for (int y = 0; y < bg.height; ++y) {
    for (int x = 1; x < bg.width; ++x)
      ASSERT_LE(max_channel_difference(pixel(bg, x, y), pixel(bg, 0, y)), 1) << "row " << y << " not uniform at x " << x;
    if (y > 0) {
      ASSERT_LE(row_sum(bg, y), row_sum(bg, y - 1)) << "row " << y << " brighter than the row above";
    }
  }
  // The colours are the look's (sRGB 0..1 → levels) within a few levels at the ends.
  const Look look = plain_look();
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(pixel(bg, 0, 0)[c], 255 * look.background_top[c], 3);
    EXPECT_NEAR(pixel(bg, 0, bg.height - 1)[c], 255 * look.background_bottom[c], 3);
  }
}

TEST(RendererBasics, BodyAtTheTargetCoversTheCentre) {
  const Look look = plain_look();
  const Image bg = background_frame(320, 240, look);
  auto r = framed_renderer(320, 240, look, uv_sphere({1, 2, 3}, 0.5f));
  const Image im = render_once(*r);
  const Camera cam = r->fit_camera({0.25f, -0.55f, -1.0f}, {0, 1, 0});
  EXPECT_NEAR(cam.target[0], 1, 1e-5);
  EXPECT_NEAR(cam.target[1], 2, 1e-5);
  EXPECT_NEAR(cam.target[2], 3, 1e-5);
  EXPECT_GT(max_channel_difference(pixel(im, 160, 120), pixel(bg, 160, 120)), 24);
  EXPECT_GT(r->last_triangles(), 0u);
}

TEST(RendererBasics, FitCameraKeepsTheWholeBodyInside) {
  const Look look = plain_look();
  const int w = 320, h = 240;
  const Image bg = background_frame(w, h, look);
  const LiverScene& s = liver();
  const std::vector<std::pair<const char*, Mesh>> bodies = {{"sphere", uv_sphere({1, 2, 3}, 0.5f)}, {"liver", s.visual}};
  const std::vector<Vec3f> views = {{0.25f, -0.55f, -1.0f}, {1, 0, 0}, {0, 0, -1}, {-0.3f, 0.2f, 0.8f}, {0.1f, -1, 0.05f}};
  for (const auto& [name, mesh] : bodies)
    for (const Vec3f& v : views) {
      auto r = framed_renderer(w, h, look, mesh, v);
      const std::vector<bool> fg = foreground_mask(render_once(*r), bg);
      const PixelBox box = bounding_box(fg, w, h);
      SCOPED_TRACE(std::string(name) + " seen along (" + std::to_string(v[0]) + ", " + std::to_string(v[1]) + ", " +
                   std::to_string(v[2]) + ")");
      EXPECT_FALSE(touches_border(fg, w, h));
      EXPECT_GE(std::max(box.width(), box.height()), 0.4 * std::min(w, h))
          << "extent " << box.width() << "x" << box.height();
    }
}

TEST(RendererBasics, TriangleIndexOutOfRangeThrows) {
  Renderer r(64, 64, plain_look());
  const Mesh m = tilted_square(1, 0);
  const std::vector<uint32_t> bad = {0, 1, 4};  // 4 vertices: index 4 is one past the end
  EXPECT_THROW(r.add_body(m.positions.data(), m.vertices(), bad.data(), 1), std::runtime_error);
  const std::vector<uint32_t> good = {0, 1, 3};
  EXPECT_NO_THROW(r.add_body(m.positions.data(), m.vertices(), good.data(), 1));
  EXPECT_THROW(r.replace_body(0, m.positions.data(), 3, good.data(), 1), std::runtime_error);
}

/// The sphere rendered with the same value of `field` at every vertex.
Image sphere_with_field(ColorField field, float value) {
  Look look = plain_look(field);
  look.field_min = 0;
  look.field_max = 100;
  const Mesh m = uv_sphere({0, 0, 0}, 1);
  auto r = framed_renderer(160, 120, look, m);
  const std::vector<float> f(m.vertices(), value);
  r->update_body(0, m.positions.data(), field == ColorField::Stress ? f.data() : nullptr,
                 field == ColorField::Damage ? f.data() : nullptr);
  return render_once(*r);
}

TEST(RendererBasics, StressAtTheTopOfTheRangeIsRedderThanZero) {
  const Image bg = background_frame(160, 120, plain_look());
  const Image low = sphere_with_field(ColorField::Stress, 0), high = sphere_with_field(ColorField::Stress, 100);
  const std::vector<bool> body = foreground_mask(low, bg);
  ASSERT_GT(count(body), 1000u);
  auto red_minus_blue = [](const Rgb& c) { return double(c[0] - c[2]); };
  const double rb_low = mean_over(low, body, red_minus_blue), rb_high = mean_over(high, body, red_minus_blue);
  std::printf("mean R-B: stress 0 %.1f, stress max %.1f\n", rb_low, rb_high);
  EXPECT_GT(rb_high, rb_low + 40);
}

TEST(RendererBasics, DamageDarkens) {
  const Image bg = background_frame(160, 120, plain_look());
  const Image intact = sphere_with_field(ColorField::Damage, 0), ruptured = sphere_with_field(ColorField::Damage, 1);
  const std::vector<bool> body = foreground_mask(intact, bg);
  ASSERT_GT(count(body), 1000u);
  const double l0 = mean_over(intact, body, luminance), l1 = mean_over(ruptured, body, luminance);
  std::printf("mean luminance: damage 0 %.1f, damage 1 %.1f\n", l0, l1);
  EXPECT_LT(l1, l0 - 20);
}

TEST(RendererBasics, WireframeChangesPixels) {
  Look look = plain_look();
  const Mesh m = uv_sphere({0, 0, 0}, 1, 12, 24);
  auto r = framed_renderer(160, 120, look, m);
  const Image solid = render_once(*r);
  look.wireframe = true;
  r->set_look(look);
  const Image wire = render_once(*r);
  const std::vector<bool> changed = foreground_mask(wire, solid, 24);
  const std::vector<bool> body = foreground_mask(solid, background_frame(160, 120, plain_look()));
  std::printf("wireframe: %zu of %zu body pixels changed by more than 24 levels\n", count(changed), count(body));
  EXPECT_GT(count(changed), count(body) / 20);
  // The lines are dark: the changed pixels got darker.
  EXPECT_LT(mean_over(wire, changed, luminance), mean_over(solid, changed, luminance));
}

/// Pixels strictly between the background (`bg`, per pixel) and the darkest body pixel of the
/// aliased image (with a margin of 6 levels of luminance): the blended colours of MSAA edges.
size_t intermediate_pixels(const Image& im, const Image& bg, double body_min) {
  size_t n = 0;
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x) {
      const double l = luminance(pixel(im, x, y));
      n += l > luminance(pixel(bg, x, y)) + 6 && l < body_min - 6;
    }
  return n;
}

TEST(RendererBasics, MsaaBlendsEdges) {
  // A pale square facing the camera, tilted so that its edges are slanted (aliased without MSAA).
  Look look = plain_look(ColorField::None, 0);
  look.tissue = {0.9f, 0.9f, 0.9f};
  const Mesh square = tilted_square(2, 17);
  auto r = framed_renderer(160, 120, look, square, {0, 0, -1});
  const Image bg = background_frame(160, 120, look);
  const Image aliased = render_once(*r);
  look.msaa = 4;
  r->set_look(look);
  const Image smooth = render_once(*r);
  const std::vector<bool> body = foreground_mask(aliased, bg);
  ASSERT_GT(count(body), 500u);
  double body_min = 1e9, bg_max = 0;
  for (int y = 0; y < aliased.height; ++y)
    for (int x = 0; x < aliased.width; ++x) {
      if (body[static_cast<size_t>(y) * aliased.width + x]) body_min = std::min(body_min, luminance(pixel(aliased, x, y)));
      bg_max = std::max(bg_max, luminance(pixel(bg, x, y)));
    }
  ASSERT_GT(body_min, bg_max + 40) << "the square is not clearly brighter than the background";
  const size_t n_aliased = intermediate_pixels(aliased, bg, body_min), n_smooth = intermediate_pixels(smooth, bg, body_min);
  std::printf("edge pixels between background and body: msaa 0 %zu, msaa 4 %zu (body %zu pixels)\n", n_aliased,
              n_smooth, count(body));
  EXPECT_GE(n_smooth, 40u);
  EXPECT_GT(n_smooth, 4 * n_aliased + 10);
}

TEST(RendererBasics, ContactMarkersWhereAToolTouches) {
  const Mesh m = uv_sphere({0, 0, 0}, 1);
  auto r = framed_renderer(160, 120, plain_look(), m);
  ToolView touching;
  touching.capsules.push_back({{1, 0, 0}, {1.5f, 0, 0}, 0.3f});
  r->set_tools({touching});
  const Image with_markers = render_once(*r);
  EXPECT_GT(r->last_markers(), 0u);
  ToolView far;
  far.capsules.push_back({{10, 10, 10}, {10, 10, 11}, 0.3f});
  r->set_tools({far});
  render_once(*r);
  EXPECT_EQ(r->last_markers(), 0u);
  // Markers off in the look: none even when touching.
  Look off = plain_look();
  off.contacts = false;
  r->set_look(off);
  r->set_tools({touching});
  const Image without_markers = render_once(*r);
  EXPECT_EQ(r->last_markers(), 0u);
  EXPECT_GT(count(foreground_mask(with_markers, without_markers, 24)), 0u) << "markers drew nothing";
}

TEST(RendererBasics, ClearBodiesLeavesTheBackground) {
  const Look look = plain_look();
  auto r = framed_renderer(160, 120, look, uv_sphere({0, 0, 0}, 1));
  const Image bg = background_frame(160, 120, look);
  const Image with_body = render_once(*r);
  ASSERT_GT(count(foreground_mask(with_body, bg)), 1000u);
  r->clear_bodies();
  EXPECT_EQ(r->body_count(), 0u);
  const Image cleared = render_once(*r);
  EXPECT_EQ(cleared.pixels, bg.pixels) << count(foreground_mask(cleared, bg, 0)) << " pixels differ";
  EXPECT_EQ(r->last_triangles(), 0u);
}

TEST(RendererBasics, RejectsImagesSmallerThan16) {
  EXPECT_THROW(Renderer(15, 240, plain_look()), std::runtime_error);
  EXPECT_THROW(Renderer(320, 15, plain_look()), std::runtime_error);
  EXPECT_NO_THROW(Renderer(16, 16, plain_look()));
}

TEST(RendererBasics, OneContextServesRenderersOfAnySize) {
  // The context is 640x480. A 320x240 renderer must draw the whole frame (not a corner of the
  // context's viewport): it agrees with the 640x480 image halved. A renderer larger than the
  // context (800x600) must work too, with the body scaled accordingly.
  const Look look = plain_look();
  const Mesh m = uv_sphere({0, 0, 0}, 1);
  Image small = render_once(*framed_renderer(320, 240, look, m));
  const Image full = render_once(*framed_renderer(kContextWidth, kContextHeight, look, m));
  const Image large = render_once(*framed_renderer(800, 600, look, m));
  ASSERT_EQ(small.width, 320);
  ASSERT_EQ(large.width, 800);
  ASSERT_EQ(large.height, 600);
  const ImageDifference d = compare_images(small, downsample_2x(full));
  std::printf("320x240 vs 640x480 halved: mean |diff| %.3f, %.3f %% over 24\n", d.mean_abs, 100 * d.fraction_over);
  EXPECT_LT(d.mean_abs, 2.0);
  EXPECT_LT(d.fraction_over, 0.02);
  const PixelBox bs = bounding_box(foreground_mask(small, background_frame(320, 240, look)), 320, 240);
  const PixelBox bl = bounding_box(foreground_mask(large, background_frame(800, 600, look)), 800, 600);
  EXPECT_NEAR(bl.width(), 2.5 * bs.width(), 4);
  EXPECT_NEAR(bl.height(), 2.5 * bs.height(), 4);
  EXPECT_NEAR(0.5 * (bl.x0 + bl.x1), 400, 3);
  EXPECT_NEAR(0.5 * (bl.y0 + bl.y1), 300, 3);
}

// ---------------------------------------------------------------------------------------------
// PngIo

Image test_pattern(int w, int h, int channels) {
  Image im;
  im.width = w, im.height = h, im.channels = channels;
  im.pixels.resize(static_cast<size_t>(w) * h * channels);
  uint32_t s = 12345;
  for (uint8_t& p : im.pixels) s = s * 1664525u + 1013904223u, p = static_cast<uint8_t>(s >> 24);
  return im;
}

TEST(PngIo, RoundTripsExactly) {
  const std::string dir = fresh_dir("png");
  for (int channels : {3, 4})
    for (int level : {1, 6}) {
      const Image im = test_pattern(37, 23, channels);
      const std::string path = dir + "/rt_" + std::to_string(channels) + "_" + std::to_string(level) + ".png";
      std::string err;
      ASSERT_TRUE(write_png(path, im, level, &err)) << err;
      EXPECT_TRUE(err.empty());
      const Image back = read_png(path);
      EXPECT_EQ(back.width, 37);
      EXPECT_EQ(back.height, 23);
      EXPECT_EQ(back.channels, channels);
      EXPECT_EQ(back.pixels, im.pixels) << path;
    }
}

TEST(PngIo, WriteIntoMissingDirectoryFailsNamingThePath) {
  const std::string path = fresh_dir("png_missing") + "/no_such_dir/out.png";
  std::string err;
  EXPECT_FALSE(write_png(path, test_pattern(8, 8, 3), 1, &err));
  EXPECT_NE(err.find(path), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(path));
}

TEST(PngIo, ReadingAMissingFileThrowsNamingIt) {
  const std::string path = fresh_dir("png_read") + "/absent.png";
  try {
    read_png(path);
    FAIL() << "no exception for " << path;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------------------------
// FrameWriter

TEST(FrameWriter, WritesNumberedFramesInOrder) {
  const std::string dir = fresh_dir("frames");
  constexpr int kFrames = 5;
  std::vector<WrittenFrame> written;  // what the callback heard, on the writer thread
  FrameWriter w(dir, 1, kFrames, [&written](const WrittenFrame& f) { written.push_back(f); });
  for (int i = 0; i < kFrames; ++i) {
    Image* im = w.acquire();
    ASSERT_NE(im, nullptr);
    *im = test_pattern(24, 16, 3);
    im->pixels[0] = static_cast<uint8_t>(100 + i);  // which frame this is
    w.submit(im, 1000 + i, 0.01 * i, 7 + i);
  }
  w.finish();
  EXPECT_TRUE(w.error().empty()) << w.error();
  EXPECT_EQ(w.written(), uint64_t{kFrames});
  ASSERT_EQ(written.size(), size_t{kFrames});
  EXPECT_EQ(w.submitted(), uint64_t{kFrames});
  for (int i = 0; i < kFrames; ++i) {
    const WrittenFrame& f = written[i];
    EXPECT_EQ(f.index, uint64_t(i));
    EXPECT_EQ(f.stamp_ns, 1000 + i);
    EXPECT_EQ(f.state_frame, uint64_t(7 + i));
    if (i > 0) {
      EXPECT_GE(f.written_ns, written[i - 1].written_ns);
    }
    char name[32];
    std::snprintf(name, sizeof name, "/frame_%06d.png", i);
    EXPECT_EQ(w.path(i), dir + name);
    const Image back = read_png(dir + name);
    EXPECT_EQ(back.pixels[0], 100 + i) << name;
  }
  EXPECT_FALSE(fs::exists(dir + "/frame_000005.png"));
}

TEST(FrameWriter, PoolRunsOutAndRecovers) {
  FrameWriter w(fresh_dir("pool"), 1, 2);
  Image* a = w.acquire();
  Image* b = w.acquire();
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  EXPECT_NE(a, b);
  EXPECT_EQ(w.acquire(), nullptr);
  w.release(b);
  Image* c = w.acquire();
  EXPECT_EQ(c, b);
  w.release(a);
  w.release(c);
  w.finish();
  EXPECT_EQ(w.written(), 0u);
}

TEST(FrameWriter, UnwritableDirectoryReportsAnError) {
  const std::string dir = fresh_dir("unwritable");
  const std::string file = dir + "/plain_file";
  std::ofstream(file) << "not a directory";
  FrameWriter w(file + "/frames", 1, 2);
  Image* im = w.acquire();
  ASSERT_NE(im, nullptr);
  *im = test_pattern(16, 16, 3);
  w.submit(im, 0, 0, 0);
  w.finish();
  EXPECT_FALSE(w.error().empty());
  EXPECT_NE(w.error().find(file), std::string::npos) << w.error();
  EXPECT_EQ(w.written(), 0u);
}

// ---------------------------------------------------------------------------------------------
// CapsuleMesh

using D3 = std::array<double, 3>;
D3 sub(const D3& a, const D3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const D3& a, const D3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
D3 cross(const D3& a, const D3& b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
double norm(const D3& a) { return std::sqrt(dot(a, a)); }
D3 d3(const Vec3f& v) { return {v[0], v[1], v[2]}; }

/// The point of segment a–b closest to p.
D3 closest_on_segment(const D3& p, const D3& a, const D3& b) {
  const D3 ab = sub(b, a);
  const double l2 = dot(ab, ab);
  const double t = l2 > 0 ? std::clamp(dot(sub(p, a), ab) / l2, 0.0, 1.0) : 0.0;
  return {a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]};
}

struct CapsuleCase {
  Vec3f a, b;
  float r;
};

const std::vector<CapsuleCase> kCapsules = {
    {{0, 0, 0}, {0, 0, 1}, 0.25f},            // along z
    {{-1, 2, 3}, {2, 2, 3}, 0.3f},            // along x (the other helper axis)
    {{0.5f, -1, 2}, {1.5f, 3, -2}, 0.05f},    // oblique, thin
    {{-1.5f, 4.6f, 0.5f}, {-1.5f, 4.6f, 0.5f}, 0.3f},  // a = b: a sphere
};

constexpr int kStride = 8;

TEST(CapsuleMesh, VerticesLieOnTheSurfaceWithOutwardUnitNormals) {
  for (const CapsuleCase& c : kCapsules) {
    std::vector<float> v;
    std::vector<uint32_t> idx;
    append_capsule(c.a, c.b, c.r, v, idx, kStride);
    ASSERT_EQ(v.size() % kStride, 0u);
    ASSERT_GT(v.size() / kStride, 100u);
    for (size_t i = 0; i < v.size(); i += kStride) {
      const D3 p{v[i], v[i + 1], v[i + 2]}, n{v[i + 3], v[i + 4], v[i + 5]};
      const D3 q = closest_on_segment(p, d3(c.a), d3(c.b));
      SCOPED_TRACE("vertex " + std::to_string(i / kStride) + " of a capsule of radius " + std::to_string(c.r));
      ASSERT_NEAR(norm(sub(p, q)), c.r, 1e-5 * c.r);
      ASSERT_NEAR(norm(n), 1.0, 1e-5);
      ASSERT_GT(dot(sub(p, q), n), 0.0);
      ASSERT_EQ(v[i + 6], 0.0f);  // the padding after the normal stays zero
      ASSERT_EQ(v[i + 7], 0.0f);
    }
  }
}

TEST(CapsuleMesh, TrianglesAreCounterClockwiseFromOutside) {
  for (const CapsuleCase& c : kCapsules) {
    std::vector<float> v;
    std::vector<uint32_t> idx;
    append_capsule(c.a, c.b, c.r, v, idx, kStride);
    ASSERT_EQ(idx.size() % 3, 0u);
    const size_t nv = v.size() / kStride;
    auto pos = [&](uint32_t i) { return D3{v[i * kStride], v[i * kStride + 1], v[i * kStride + 2]}; };
    auto nrm = [&](uint32_t i) { return D3{v[i * kStride + 3], v[i * kStride + 4], v[i * kStride + 5]}; };
    size_t checked = 0, degenerate = 0;
    double area = 0;
    for (size_t t = 0; t < idx.size(); t += 3) {
      ASSERT_LT(std::max({idx[t], idx[t + 1], idx[t + 2]}), nv);
      const D3 g = cross(sub(pos(idx[t + 1]), pos(idx[t])), sub(pos(idx[t + 2]), pos(idx[t])));
      // Zero-area triangles (collapsed rings at the poles, and a = b's empty cylinder) have
      // no orientation; every other one must face out.
      if (norm(g) < 1e-6 * c.r * c.r) {
        ++degenerate;
        continue;
      }
      const D3 n0 = nrm(idx[t]), n1 = nrm(idx[t + 1]), n2 = nrm(idx[t + 2]);
      const D3 mean{n0[0] + n1[0] + n2[0], n0[1] + n1[1] + n2[1], n0[2] + n1[2] + n2[2]};
      ASSERT_GT(dot(g, mean), 0.0) << "triangle " << t / 3 << " is clockwise from outside";
      ++checked;
      area += 0.5 * norm(g);
    }
    // The checked triangles cover the surface: area within 2 % of the true capsule's.
    const double len = norm(sub(d3(c.b), d3(c.a)));
    const double true_area = 4 * M_PI * c.r * c.r + 2 * M_PI * c.r * len;
    std::printf("capsule r %.2f len %.2f: %zu triangles, %zu degenerate, area %.5f of %.5f\n", c.r, len, idx.size() / 3,
                degenerate, area, true_area);
    EXPECT_NEAR(area, true_area, 0.02 * true_area);
    EXPECT_GT(checked, idx.size() / 3 / 2);
  }
}

TEST(CapsuleMesh, EqualEndsGiveASphere) {
  const Vec3f c{-1.5f, 4.6f, 0.5f};
  const float r = 0.3f;
  std::vector<float> v;
  std::vector<uint32_t> idx;
  append_capsule(c, c, r, v, idx, kStride);
  // Every vertex at distance r from the centre, and the vertices reach r along every axis
  // direction (a full sphere, not a hemisphere).
  std::array<double, 6> reach{};  // +x, −x, +y, −y, +z, −z
  for (size_t i = 0; i < v.size(); i += kStride) {
    const D3 d = sub(D3{v[i], v[i + 1], v[i + 2]}, d3(c));
    ASSERT_NEAR(norm(d), r, 1e-5 * r);
    for (int k = 0; k < 3; ++k) {
      reach[2 * k] = std::max(reach[2 * k], d[k]);
      reach[2 * k + 1] = std::max(reach[2 * k + 1], -d[k]);
    }
  }
  for (double x : reach) EXPECT_GT(x, 0.98 * r);
}

TEST(CapsuleMesh, AppendsAfterExistingVertices) {
  std::vector<float> v;
  std::vector<uint32_t> idx;
  append_capsule({0, 0, 0}, {0, 0, 1}, 0.2f, v, idx, kStride);
  const size_t first_vertices = v.size() / kStride, first_indices = idx.size();
  append_capsule({5, 0, 0}, {5, 1, 0}, 0.2f, v, idx, kStride);
  ASSERT_GT(idx.size(), first_indices);
  for (size_t i = first_indices; i < idx.size(); ++i) {
    ASSERT_GE(idx[i], first_vertices);
    ASSERT_LT(idx[i], v.size() / kStride);
    ASSERT_GT(v[idx[i] * kStride], 4.0f);  // the second capsule's vertices (x ≈ 5)
  }
}

// ---------------------------------------------------------------------------------------------
// Rigid bodies (render/rigid_view.hpp): posed shapes, then drawn.

/// A quarter turn about y: shape z → world +x, shape x → world −z.
constexpr double kQuarterY[4] = {0.7071067811865476, 0, 0.7071067811865476, 0};

/// The camera 5 units up the z axis, looking at the origin.
void look_at_origin_from_z(Renderer& r) {
  Camera cam;
  cam.position = {0, 0, 5};
  cam.target = {0, 0, 0};
  r.set_camera(cam);
}

TEST(RigidView, AStraightNeedleIsOneSteelTubeAlongItsPosedAxis) {
  RigidShapeDesc s;
  s.kind = RigidShapeDesc::Needle;
  s.wire_radius = 0.0004;
  s.length = 0.08;
  const double pos[3] = {-0.08, 0.03, 0.025};
  const float track[6] = {0.01f, 0.03f, 0.025f, 0.02f, 0.03f, 0.025f};
  const RigidView v = make_rigid_view(s, pos, kQuarterY, track, 2);
  ASSERT_EQ(v.capsules.size(), 1u);
  EXPECT_TRUE(v.steel);
  EXPECT_FLOAT_EQ(v.capsules[0].r, 0.0004f);
  const Vec3f tail{-0.08f, 0.03f, 0.025f}, tip{0.0f, 0.03f, 0.025f};  // z → +x
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(v.capsules[0].a[k], tail[k], 1e-7);
    EXPECT_NEAR(v.capsules[0].b[k], tip[k], 1e-7);
  }
  ASSERT_EQ(v.track.size(), 2u);
  EXPECT_FLOAT_EQ(v.track[1][0], 0.02f);
  EXPECT_TRUE(v.triangles.empty());
}

TEST(RigidView, ACurvedNeedleIsAChainOnItsArc) {
  RigidShapeDesc s;
  s.kind = RigidShapeDesc::Needle;
  s.curved = true;
  s.wire_radius = 0.0004;
  s.arc_radius = 0.01;
  s.angle = M_PI;  // a half circle
  s.length = s.arc_radius * s.angle;
  const double pos[3] = {1, 2, 3};
  const RigidView v = make_rigid_view(s, pos, kQuarterY, nullptr, 0);
  ASSERT_EQ(v.capsules.size(), size_t(kNeedleSegments));
  for (size_t i = 0; i < v.capsules.size(); ++i) {
    for (const Vec3f& p : {v.capsules[i].a, v.capsules[i].b})
      EXPECT_NEAR(std::hypot(p[0] - 1, p[1] - 2, p[2] - 3), 0.01, 1e-6) << "on the arc about the origin";
    if (i > 0)
      for (int k = 0; k < 3; ++k) EXPECT_EQ(v.capsules[i].a[k], v.capsules[i - 1].b[k]) << "a continuous chain";
  }
  // Tail on the shape's +x (world −z), tip half a turn on (shape −x: world +z); shape y stays y.
  EXPECT_NEAR(v.capsules.front().a[2], 3 - 0.01, 1e-6);
  EXPECT_NEAR(v.capsules.back().b[2], 3 + 0.01, 1e-6);
  EXPECT_NEAR(v.capsules[kNeedleSegments / 2].a[1], 2 + 0.01, 1e-6) << "the arc's middle on the shape's +y";
}

TEST(RigidView, ABoxHasTwelveOutwardFacesOfItsArea) {
  RigidShapeDesc s;
  s.kind = RigidShapeDesc::Box;
  s.size = {0.03, 0.01, 0.02};
  const double pos[3] = {0.1, 0.2, 0.3};
  const double q[4] = {std::cos(0.3), std::sin(0.3) * 0.6, 0, std::sin(0.3) * 0.8};  // 0.6 rad about (0.6, 0, 0.8)
  const RigidView v = make_rigid_view(s, pos, q, nullptr, 0);
  ASSERT_EQ(v.triangles.size(), size_t(12 * 9));
  EXPECT_FALSE(v.steel);
  double area = 0;
  for (size_t t = 0; t < v.triangles.size(); t += 9) {
    D3 p[3];
    for (int i = 0; i < 3; ++i) p[i] = {v.triangles[t + 3 * i], v.triangles[t + 3 * i + 1], v.triangles[t + 3 * i + 2]};
    const D3 e1 = sub(p[1], p[0]), e2 = sub(p[2], p[0]);
    const D3 n = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    area += 0.5 * norm(n);
    const D3 out = sub(D3{(p[0][0] + p[1][0] + p[2][0]) / 3, (p[0][1] + p[1][1] + p[2][1]) / 3, (p[0][2] + p[1][2] + p[2][2]) / 3},
                       D3{0.1, 0.2, 0.3});
    EXPECT_GT(n[0] * out[0] + n[1] * out[1] + n[2] * out[2], 0) << "triangle " << t / 9 << " faces inwards";
  }
  EXPECT_NEAR(area, 2 * (0.03 * 0.01 + 0.01 * 0.02 + 0.02 * 0.03), 1e-8);
}

TEST(RigidView, AMeshSkipsTrianglesOutOfRange) {
  RigidShapeDesc s;
  s.kind = RigidShapeDesc::Mesh;
  s.vertices = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  s.triangles = {0, 1, 2, 0, 1, 7};
  const double pos[3] = {0, 0, 1}, q[4] = {1, 0, 0, 0};
  const RigidView v = make_rigid_view(s, pos, q, nullptr, 0);
  ASSERT_EQ(v.triangles.size(), 9u);
  EXPECT_FLOAT_EQ(v.triangles[5], 1.0f) << "moved to z = 1";
}

TEST(RigidView, RigidBodiesAndTrackMarksAreDrawnWhereTheyAre) {
  Renderer r(160, 120, plain_look());
  look_at_origin_from_z(r);
  const Image bg = render_once(r);
  // A needle across the middle, along x.
  RigidShapeDesc needle;
  needle.kind = RigidShapeDesc::Needle;
  needle.wire_radius = 0.05;
  needle.length = 2;
  const double tail[3] = {-1, 0, 0};
  const float track[9] = {-0.3f, 0.0f, 0.06f, 0.0f, 0.0f, 0.06f, 0.3f, 0.0f, 0.06f};
  r.set_rigid_bodies({make_rigid_view(needle, tail, kQuarterY, track, 0)});
  const Image tube = render_once(r);
  EXPECT_GT(max_channel_difference(pixel(tube, 80, 60), pixel(bg, 80, 60)), 24) << "the tube crosses the centre";
  EXPECT_LE(max_channel_difference(pixel(tube, 80, 20), pixel(bg, 80, 20)), 1) << "and nothing above it";
  EXPECT_EQ(r.last_track_marks(), 0u);
  r.set_rigid_bodies({make_rigid_view(needle, tail, kQuarterY, track, 3)});
  const Image marked = render_once(r);
  EXPECT_EQ(r.last_track_marks(), 3u);
  EXPECT_GT(count(foreground_mask(marked, tube, 24)), 0u) << "the marks drew nothing";
  EXPECT_LT(luminance(pixel(marked, 80, 60)), luminance(pixel(tube, 80, 60))) << "a mark is dark";
  // A box at the centre in the rigid colour: bluish, unlike the steel.
  RigidShapeDesc box;
  box.kind = RigidShapeDesc::Box;
  box.size = {1, 1, 1};
  const double centre[3] = {0, 0, 0}, id[4] = {1, 0, 0, 0};
  r.set_rigid_bodies({make_rigid_view(box, centre, id, nullptr, 0)});
  const Image boxed = render_once(r);
  const Rgb c = pixel(boxed, 80, 60);
  EXPECT_GT(c[2], c[0] + 20) << "the rigid colour is blue";
  EXPECT_EQ(r.last_triangles(), 12u);
}


// A cut's wound on the outer surface (docs/CUTTING.md): the outer faces' vertices at the place of
// a cut face's vertex are the lips, drawn as a dark line along the cut — a closed incision reads
// along its whole length though its cut faces are hidden. A flat sheet (z = 0, facing the camera)
// with a cut face hanging below it along x = 0 (edge-on: not itself visible).
TEST(RendererBasics, AWoundsEdgeIsDrawnAlongItsLips) {
  const Look look = plain_look();
  const std::vector<float> pos = {-1, -1, 0, 0, -1, 0, 1, -1, 0, -1, 1, 0, 0, 1, 0, 1, 1, 0,  // the sheet
                                  0, -1, 0, 0, 1, 0, 0, 0, -0.5f};                             // the cut face's own
  const std::vector<uint32_t> tris = {0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4, 6, 8, 7};
  auto frame = [&](bool cut) {
    Renderer r(160, 120, look);
    const std::vector<uint8_t> faces = {0, 0, 0, 0, uint8_t(cut ? 1 : 0)};
    r.add_body(pos.data(), pos.size() / 3, tris.data(), tris.size() / 3, faces.data());
    r.set_camera(r.fit_camera({0, 0, -1}, {0, 1, 0}));
    return render_once(r);
  };
  const Image cut = frame(true), uncut = frame(false);
  // The lip projects to the image's middle column; a quarter of the sheet's width away, none.
  auto row_mean = [](const Image& im, int x) {
    double s = 0;
    for (int y = 50; y < 70; ++y) s += luminance(pixel(im, x, y));
    return s / 20;
  };
  const double lip_cut = row_mean(cut, 80), side_cut = std::min(row_mean(cut, 60), row_mean(cut, 100));
  const double lip_uncut = row_mean(uncut, 80), side_uncut = std::min(row_mean(uncut, 60), row_mean(uncut, 100));
  std::printf("luminance at the lip / beside it: with the cut face %.1f / %.1f, without %.1f / %.1f\n", lip_cut,
              side_cut, lip_uncut, side_uncut);
  EXPECT_LT(lip_cut, side_cut - 30) << "the lip is a dark line";
  EXPECT_NEAR(lip_uncut, side_uncut, 8) << "no cut, no line";
  EXPECT_NEAR(side_cut, side_uncut, 3) << "away from the lip the sheet is as it was";
}

// A suture thread (issue 43) is a violet tube along its nodes: a capsule per segment, at least
// kThreadMinDrawRadius thick (a 0.2 mm suture would be below a pixel), drawn where it is in the
// thread's colour (redder and bluer than green, unlike the steel and the background).
TEST(ThreadView, AThreadIsATubeAlongItsNodesInItsColour) {
  const float nodes[9] = {-1.0f, -0.5f, 0.0f, 0.0f, 0.0f, 0.0f, 1.0f, -0.5f, 0.0f};
  const RigidView thin = make_thread_view(nodes, 3, 2e-4);
  ASSERT_EQ(thin.capsules.size(), 2u);
  EXPECT_TRUE(thin.thread);
  EXPECT_FLOAT_EQ(thin.capsules[0].r, static_cast<float>(kThreadMinDrawRadius));
  EXPECT_FLOAT_EQ(thin.capsules[1].a[0], 0.0f);
  EXPECT_FLOAT_EQ(thin.capsules[1].b[1], -0.5f);
  const RigidView thick = make_thread_view(nodes, 3, 0.1);
  EXPECT_FLOAT_EQ(thick.capsules[0].r, 0.05f);
  Renderer r(160, 120, plain_look());
  look_at_origin_from_z(r);
  const Image bg = render_once(r);
  r.set_rigid_bodies({thick});
  const Image drawn = render_once(r);
  const auto apex = pixel(drawn, 80, 60);  // the middle node, at the centre
  EXPECT_GT(max_channel_difference(apex, pixel(bg, 80, 60)), 24) << "the tube is at its middle node";
  EXPECT_GT(apex[2], apex[1] + 10) << "violet: more blue than green";
  EXPECT_GT(apex[0], apex[1]) << "and more red than green";
  EXPECT_LE(max_channel_difference(pixel(drawn, 80, 15), pixel(bg, 80, 15)), 1) << "and nothing above it";
}

}  // namespace
}  // namespace stroma::render
