/// \file cmd_render.cpp
/// `stroma render`: records a running server off-screen. Built with STROMA_WITH_RENDER.

#include "cli/commands.hpp"
#include "render/render_process.hpp"
#include "tissue/input_error.hpp"

namespace stroma::cli {

void add_render(CLI::App& app, std::vector<Command>& out) {
  struct Args {
    RenderOptions o;
    std::vector<double> cam_pos, cam_target, view_dir, light_dir;
    std::string color_field;
  };
  auto a = std::make_shared<Args>();
  RenderOptions& rdo = a->o;
  auto* rnd = app.add_subcommand("render", "Record what a running server simulates: off-screen frames (PNG) and an MP4, no display needed");
  rnd->add_option("--out", rdo.out_dir, "Output directory (frame_NNNNNN.png, frames.csv, render_stats.json, video.mp4)")->capture_default_str();
  rnd->add_option("--fps", rdo.fps, "Frames per second of wall time")->capture_default_str()->check(CLI::Range(0.1, 240.0));
  rnd->add_option("--width", rdo.width, "Image width")->capture_default_str()->check(CLI::Range(16, 8192));
  rnd->add_option("--height", rdo.height, "Image height")->capture_default_str()->check(CLI::Range(16, 8192));
  auto* o_frames = rnd->add_option("--frames", rdo.frames, "Stop after this many frames")->check(CLI::PositiveNumber);
  rnd->add_option("--duration", rdo.duration, "Stop after this many seconds of recording")->check(CLI::PositiveNumber)->excludes(o_frames);
  rnd->add_option("--wait", rdo.wait, "Give up if no server appears within this many seconds (default: wait forever)")->check(CLI::NonNegativeNumber);
  rnd->add_option("--video", rdo.video, "MP4 file (default: <out>/video.mp4 when ffmpeg is installed)");
  rnd->add_flag("--no-video", rdo.no_video, "PNG frames only");
  rnd->add_option("--msaa", rdo.msaa, "Anti-aliasing samples per pixel (0: off)")->capture_default_str()->check(CLI::Range(0, 16));
  rnd->add_option("--png-level", rdo.png_level, "PNG zlib level (1: fast, 9: small)")->capture_default_str()->check(CLI::Range(0, 9));
  rnd->add_option("--camera", a->cam_pos, "Camera position X Y Z (with --target; default: the scenario's render: section, else framing the scene)")
      ->expected(3)
      ->delimiter(',');
  rnd->add_option("--target", a->cam_target, "Point the camera looks at X Y Z")->expected(3)->delimiter(',');
  rnd->add_option("--view", a->view_dir, "Automatic camera: frame the scene looking along X Y Z")->expected(3)->delimiter(',');
  rnd->add_option("--light", a->light_dir, "Key light direction X Y Z, world, from the light towards the scene (default: the scenario's, else above-left of the camera)")
      ->expected(3)
      ->delimiter(',');
  rnd->add_option("--fov", rdo.fov, "Vertical field of view (degrees)")->check(CLI::Range(1.0, 170.0));
  rnd->add_option("--color", a->color_field, "Tissue colour: damage (default), stress, none")->check(CLI::IsMember({"none", "stress", "damage"}));
  rnd->add_flag("--wireframe", rdo.wireframe, "Draw the mesh edges");
  rnd->add_flag("--no-contacts", rdo.no_contacts, "No contact markers");
  rnd->add_option("--stats", rdo.stats_file, "Statistics JSON (default: <out>/render_stats.json)");
  rnd->add_option("--dds-config", rdo.dds_config, "Cyclone DDS XML (default: CYCLONEDDS_URI, else built-in loopback-only)")->check(CLI::ExistingFile);
  rnd->add_option("--security", rdo.security_dir, "Join a protected domain (DDS Security) with the identity 'renderer' of this 'stroma security init' directory")->check(CLI::ExistingDirectory);
  rnd->add_option("--domain", rdo.domain, "DDS domain id")->capture_default_str()->check(CLI::Range(0, 232));
  rnd->footer("Starts before or after the server (it waits for the mesh; the mesh is transient-local) and\n"
              "follows a restarted server. Frames are dropped (and counted), never queued, when rendering\n"
              "or writing falls behind. Stops at --frames/--duration or on Ctrl-C, then encodes the video.");
  out.push_back({rnd, [a] {
                   RenderOptions o = a->o;
                   const auto vec = [](const std::vector<double>& v) { return std::array<double, 3>{v[0], v[1], v[2]}; };
                   if (!a->cam_pos.empty()) o.camera_position = vec(a->cam_pos);
                   if (!a->cam_target.empty()) o.camera_target = vec(a->cam_target);
                   if (!a->light_dir.empty()) {
                     if (a->light_dir[0] == 0 && a->light_dir[1] == 0 && a->light_dir[2] == 0)
                       throw InputError("", 0, "--light", "the light direction must not be zero");
                     o.light_direction = vec(a->light_dir);
                   }
                   if (!a->view_dir.empty()) o.view_direction = vec(a->view_dir);
                   if (a->cam_pos.empty() != a->cam_target.empty())
                     throw InputError("", 0, a->cam_pos.empty() ? "--target" : "--camera", "--camera and --target go together");
                   if (!a->color_field.empty()) o.color_field = a->color_field;
                   return run_render(o);
                 }});
}

}  // namespace stroma::cli
