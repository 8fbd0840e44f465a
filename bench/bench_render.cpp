/// \file bench_render.cpp
/// Off-screen rendering speed: frames per second of the renderer alone (draw + read-back) and
/// of PNG encoding, for a surface (OBJ/STL) or a tet mesh's boundary, at one image size. The
/// surface is deformed every frame (a travelling wave) so normals and buffers are rebuilt as in
/// a live run. Reports median and p99 over many frames.
///   stroma_bench_render MESH [--width W --height H --frames N --runs R --msaa S --png-level L
///                             --out F.png --markdown --label TEXT]
/// With --runs R the frames are timed R times; the median over runs of each run's p50/p99 is
/// reported (with the range), so one noisy run on a shared machine does not decide the figure.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "bench/bench_stats.hpp"
#include "render/gl_context.hpp"
#include "render/png_io.hpp"
#include "render/renderer.hpp"
#include "io/mesh_io.hpp"
#include "tissue/mesh_prepare.hpp"
#include "io/surface_io.hpp"

using namespace stroma;
using namespace stroma::render;

using bench::median;
using bench::percentile;

namespace {


double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Off-screen rendering speed (renderer and PNG encoding)"};
  std::string mesh_path, out;
  int width = 640, height = 480, frames = 200, msaa = 4, level = 1, runs = 1;
  bool markdown = false;
  std::string label;
  app.add_option("mesh", mesh_path, "surface (.obj, .stl) or tet mesh (.msh, .vtu, .vtk: its boundary)")->required();
  app.add_option("--width", width)->capture_default_str();
  app.add_option("--height", height)->capture_default_str();
  app.add_option("--frames", frames, "frames to time")->capture_default_str();
  app.add_option("--msaa", msaa, "samples per pixel (0: none)")->capture_default_str();
  app.add_option("--png-level", level, "zlib level for the PNG timing")->capture_default_str();
  app.add_option("--out", out, "write the last frame to this PNG");
  app.add_option("--runs", runs, "repeat the timing this many times")->capture_default_str();
  app.add_flag("--markdown", markdown, "print one table row");
  app.add_option("--label", label, "first column of the table row");
  CLI11_PARSE(app, argc, argv);

  std::vector<float> rest;
  std::vector<uint32_t> tris;
  const std::string ext = std::filesystem::path(mesh_path).extension().string();
  if (ext == ".obj" || ext == ".stl" || ext == ".OBJ" || ext == ".STL") {
    const SurfaceMesh s = read_surface_mesh(mesh_path);
    for (const Vec3& p : s.vertices) rest.insert(rest.end(), {float(p[0]), float(p[1]), float(p[2])});
    for (const Tri& t : s.triangles) tris.insert(tris.end(), {uint32_t(t[0]), uint32_t(t[1]), uint32_t(t[2])});
  } else {
    const PreparedMesh pm = prepare_mesh(load_tet_mesh(mesh_path));
    for (const Vec3& p : pm.mesh.nodes) rest.insert(rest.end(), {float(p[0]), float(p[1]), float(p[2])});
    for (const Tri& t : pm.boundary) tris.insert(tris.end(), {uint32_t(t[0]), uint32_t(t[1]), uint32_t(t[2])});
  }
  const size_t nv = rest.size() / 3;

  GlContext gl(width, height);
  Look look;
  look.msaa = msaa;
  look.field = ColorField::Stress;
  Renderer r(width, height, look);
  const int body = r.add_body(rest.data(), nv, tris.data(), tris.size() / 3);
  r.set_camera(r.fit_camera({-0.35f, -0.45f, -1.0f}, {0, 1, 0}));
  // A tool pressing the middle of the bounding box.
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  for (size_t i = 0; i < nv; ++i)
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], rest[3 * i + k]);
      hi[k] = std::max(hi[k], rest[3 * i + k]);
    }
  const float size = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  ToolView tool;
  tool.capsules.push_back({{0.5f * (lo[0] + hi[0]), hi[1], 0.5f * (lo[2] + hi[2])},
                           {0.5f * (lo[0] + hi[0]), hi[1] + 0.5f * size, 0.5f * (lo[2] + hi[2])},
                           0.04f * size});
  r.set_tools({tool});

  std::vector<float> x(rest.size()), stress(nv);
  Image img;
  std::vector<double> run_p50, run_p99, run_png;
  const std::string tmp = (std::filesystem::temp_directory_path() / "stroma_bench_frame.png").string();
  for (int run = 0; run < runs; ++run) {
    std::vector<double> render_ms, png_ms;
    for (int f = 0; f < frames + 5; ++f) {
      const float phase = 0.2f * static_cast<float>(f);
      for (size_t i = 0; i < nv; ++i) {
        const float w = 0.02f * size * std::sin(phase + 6.0f * (rest[3 * i] - lo[0]) / size);
        x[3 * i] = rest[3 * i];
        x[3 * i + 1] = rest[3 * i + 1] + w;
        x[3 * i + 2] = rest[3 * i + 2];
        stress[i] = std::abs(w);
      }
      const double t0 = now_ms();
      r.update_body(body, x.data(), stress.data(), nullptr);
      r.render(img);
      const double t1 = now_ms();
      if (f >= 5) render_ms.push_back(t1 - t0);  // the first frames compile shaders lazily
      if (f >= 5 && f % 4 == 0) {
        std::string err;
        const double p0 = now_ms();
        if (!write_png(tmp, img, level, &err)) {
          fmt::print(stderr, "{}\n", err);
          return 1;
        }
        png_ms.push_back(now_ms() - p0);
      }
    }
    run_p50.push_back(percentile(render_ms, 0.5));
    run_p99.push_back(percentile(render_ms, 0.99));
    run_png.push_back(percentile(png_ms, 0.5));
  }
  std::filesystem::remove(tmp);
  if (!out.empty()) {
    std::string err;
    if (!write_png(out, img, 6, &err)) fmt::print(stderr, "{}\n", err);
  }
  const double p50 = percentile(run_p50, 0.5), p99 = percentile(run_p99, 0.5), png = percentile(run_png, 0.5);
  auto range = [](const std::vector<double>& v) {
    return fmt::format("{:.1f}–{:.1f}", *std::min_element(v.begin(), v.end()), *std::max_element(v.begin(), v.end()));
  };
  const char* threads = std::getenv("LP_NUM_THREADS");
  if (markdown) {
    fmt::print("| {} | {} | {} | {}x{} | {} | {} | {:.1f} ({}) | {:.1f} ({}) | {:.0f} | {:.1f} |\n",
               label.empty() ? mesh_path : label, nv, tris.size() / 3, width, height, msaa,
               threads ? threads : "default", p50, range(run_p50), p99, range(run_p99), 1000.0 / p50, png);
    return 0;
  }
  fmt::print("{}: {} vertices, {} triangles, {}x{}, msaa {} ({}, {})\n", mesh_path, nv, tris.size() / 3, width,
             height, msaa, gl.renderer(), gl.version());
  fmt::print("render+readback ms: p50 {:.2f} p99 {:.2f} -> {:.1f} FPS (p50), median of {} runs\n", p50, p99,
             1000.0 / p50, runs);
  fmt::print("png level {} ms: p50 {:.2f}\n", level, png);
  return 0;
}
