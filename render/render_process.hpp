#pragma once
/// \file render_process.hpp
/// `stroma render`: a process of its own that subscribes to a server's TissueMesh, TissueState,
/// ToolState, Scene and DamageEvent topics, renders frames off-screen at a fixed rate and writes
/// numbered PNGs (and an MP4 when ffmpeg is installed). No DDS or GL header here: the CLI
/// includes this.

#include <array>
#include <optional>
#include <string>

namespace stroma {

/// Options of `stroma render`. Unset optionals take the scenario's `render:` section (Scene
/// topic), then the defaults.
struct RenderOptions {
  std::string dds_config;   ///< Cyclone XML; empty: CYCLONEDDS_URI or built-in loopback
  std::string security_dir; ///< --security: a `stroma security init` directory (identity "renderer")
  int domain = 0;
  std::string out_dir = "out/render";
  double fps = 30;
  int width = 640, height = 480;
  long frames = 0;          ///< stop after this many frames written (0: no limit)
  double duration = 0;      ///< stop after this many wall seconds of recording (0: no limit)
  double wait = 0;          ///< s to wait for a server's mesh (0: forever)
  std::string video;        ///< MP4 path; empty: <out>/video.mp4 when ffmpeg exists
  bool no_video = false;
  int msaa = 4;
  int png_level = 1;
  std::optional<std::array<double, 3>> camera_position, camera_target, view_direction;
  std::optional<double> fov;
  std::optional<std::array<double, 3>> light_direction;  ///< key light, world (towards the scene)
  std::optional<std::string> color_field;  ///< none | stress | damage
  bool wireframe = false;
  bool no_contacts = false;
  std::string stats_file;   ///< default <out>/render_stats.json
};

/// Runs the renderer until frames/duration is reached or SIGINT/SIGTERM; returns the exit code
/// (0 ok, 1 runtime failure such as no server or a write error, 2 bad input).
int run_render(const RenderOptions& options);

}  // namespace stroma
