/// \file main.cpp
/// The `stroma` command: one executable, one subcommand per job (CLI11).
///   stroma run SCENARIO      headless run, outputs into a directory
///   stroma check SCENARIO REFERENCE   run and compare the final state to a stored reference
///   stroma serve SCENARIO    real-time server at 1 kHz over DDS (loopback by default)
///   stroma tool              drive a served tool over DDS (script or stdin)
///   stroma render            record a served scenario off-screen (PNG frames, MP4)
/// Exit codes: 0 success, 1 check failed / run unhealthy, 2 bad input or usage.

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <spdlog/sinks/stdout_color_sinks.h>

#include "engine/headless_runner.hpp"
#include "engine/model.hpp"
#include "engine/output_dir.hpp"
#include "engine/scenario_spec.hpp"
#include "engine/state_io.hpp"
#include "bench/accuracy/accuracy_suite.hpp"
#include "bench/stability/stability_suite.hpp"
#include "render/render_process.hpp"
#include "server/serve.hpp"
#include "server/tool_client.hpp"
#include "tissue/input_error.hpp"

namespace fs = std::filesystem;
using namespace stroma;

namespace {

std::shared_ptr<const Model> load(const std::string& path) {
  spdlog::debug("loading scenario {}", path);
  const ScenarioSpec spec = load_scenario(path);
  auto model = compile_model(spec);
  for (const auto& n : model->notes) spdlog::warn("{}", n);
  spdlog::info("scenario '{}': {} bodies, {} nodes, {} tetrahedra, dt {} s", spec.name,
               spec.bodies.size(), model->fem.num_nodes, model->fem.elements.size(), spec.time_step);
  return model;
}

void print_summary(const Model& m, const RunResult& r) {
  if (m.stepper.integrator == Integrator::Static) {
    fmt::print("static solve: {} Newton iterations, relative residual {:.3g} ({}), {:.3f} s\n",
               r.newton_iterations, r.static_residual, r.static_converged ? "converged" : "NOT converged",
               r.wall_seconds);
  } else {
    fmt::print("{} steps, sim time {:.6g} s, wall {:.3f} s; step ms p50 {:.4f} p99 {:.4f} max {:.4f}; "
               "CG iterations mean {:.1f} max {}\n",
               r.steps, r.sim_time, r.wall_seconds, r.step_ms.p50, r.step_ms.p99, r.step_ms.max,
               r.cg_iterations_mean, r.cg_iterations_max);
    if (r.ticks_not_converged)
      fmt::print("warning: {} ticks hit the CG iteration cap\n", r.ticks_not_converged);
  }
  for (const ProbeModel& p : m.probes) {
    const Vec3 d = probe_displacement(m, r.final_state, p);
    fmt::print("probe {}: displacement [{:.6e}, {:.6e}, {:.6e}] m\n", p.name, d[0], d[1], d[2]);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Stroma: real-time soft-tissue simulation (corotational FEM, implicit Euler)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "stroma 0.1.0");
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|off")->capture_default_str();

  // ---- run ----
  std::string run_scenario, run_out;
  long run_steps = -1;
  double run_duration = -1;
  int vtu_every = 0;
  bool quiet = false, no_metrics = false;
  auto* run = app.add_subcommand("run", "Run a scenario headless as fast as possible and write results");
  run->add_option("scenario", run_scenario, "Scenario YAML file")->required()->check(CLI::ExistingFile);
  auto* o_steps = run->add_option("--steps", run_steps, "Number of ticks (overrides run: in the scenario)")->check(CLI::PositiveNumber);
  run->add_option("--duration", run_duration, "Simulated seconds (overrides run: in the scenario)")
      ->check(CLI::PositiveNumber)->excludes(o_steps);
  run->add_option("--out", run_out, "Output directory (default: out/<scenario name>)");
  run->add_option("--vtu-every", vtu_every, "Also write a VTU every K ticks and series.pvd")->check(CLI::NonNegativeNumber);
  run->add_flag("--quiet", quiet, "No progress messages");
  run->add_flag("--no-metrics", no_metrics, "Skip metrics.csv (saves an energy pass per tick)");
  std::string replay_file;
  run->add_option("--replay", replay_file, "Re-execute a session recorded by 'stroma serve --record' (ticks and inputs)")
      ->check(CLI::ExistingFile)->excludes(o_steps);
  run->footer("Writes summary.json, metrics.csv, final.vtu and final_state.csv into the output directory.");

  // ---- check ----
  std::string chk_scenario, chk_reference, chk_out;
  bool chk_update = false;
  auto* check = app.add_subcommand("check", "Run a scenario and compare its final state to a reference state");
  check->add_option("scenario", chk_scenario, "Scenario YAML file")->required()->check(CLI::ExistingFile);
  check->add_option("reference", chk_reference, "Reference state CSV (node,x,y,z), as written by run (final_state.csv)")->required();
  check->add_option("--out", chk_out, "Also write the run's outputs here");
  check->add_flag("--update", chk_update, "Write the reference from this run instead of comparing");
  check->footer("Tolerances come from the scenario's check: section (max_error, mean_error, metres).\n"
                "Exit status: 0 within tolerance, 1 outside, 2 bad input.");

  // ---- serve ----
  ServeOptions srv;
  auto* serve = app.add_subcommand("serve", "Run a scenario in real time (one tick per time step of wall time) and serve it over DDS");
  serve->add_option("scenario", srv.scenario, "Scenario YAML file")->required()->check(CLI::ExistingFile);
  serve->add_option("--dds-config", srv.dds_config, "Cyclone DDS XML configuration (default: CYCLONEDDS_URI, else built-in loopback-only)")
      ->check(CLI::ExistingFile);
  serve->add_option("--domain", srv.domain, "DDS domain id")->capture_default_str()->check(CLI::Range(0, 232));
  serve->add_option("--realtime", srv.realtime, "auto: try SCHED_FIFO + mlockall, warn and go on if denied; fifo: required; off")
      ->capture_default_str()->check(CLI::IsMember({"auto", "fifo", "off"}));
  serve->add_option("--cpu", srv.cpu, "Pin the physics thread to this CPU")->check(CLI::NonNegativeNumber);
  serve->add_option("--duration", srv.duration, "Stop after this many wall seconds (default: until Ctrl-C or Control SHUTDOWN)")
      ->check(CLI::NonNegativeNumber);
  serve->add_option("--stats", srv.stats_file, "Write timing statistics (JSON) here at exit");
  serve->add_option("--publish-hz", srv.publish_hz, "TissueState rate")->capture_default_str()->check(CLI::Range(1.0, 1000.0));
  serve->add_flag("--paused", srv.start_paused, "Start paused (resume or step with stroma_Control)");
  serve->add_option("--spin-us", srv.spin_us, "Wake this many microseconds early and spin to each deadline (0: sleep only)")
      ->capture_default_str()->check(CLI::Range(0, 900));
  serve->add_option("--record", srv.record_file, "Log every accepted tool command and control with its tick (replay: stroma run --replay)");
  serve->add_option("--final-state", srv.final_state_file, "Write the final state (node,x,y,z CSV) at exit");
  serve->footer(
      "Network: by default every DDS participant is on the loopback interface only, without multicast\n"
      "(secure by default). To serve on a LAN, copy server/cyclonedds-loopback.xml, replace \"lo\" by\n"
      "your interface and pass it with --dds-config FILE (or set CYCLONEDDS_URI).\n"
      "Topics: stroma_TissueMesh, stroma_TissueState, stroma_SimStatus (out), stroma_Control (in); see docs/DDS.md.");

  // ---- tool ----
  ToolClientOptions tco;
  auto* tool = app.add_subcommand("tool", "Drive a tool of a running server over DDS from a trajectory or stdin, and log force feedback");
  tool->add_option("--name", tco.name, "Tool name (as in the scenario's tools:)")->capture_default_str();
  tool->add_option("--script", tco.script, "Trajectory (YAML keyframes or CSV t,x,y,z[,qw,qx,qy,qz][,jaw]); default: read 'x y z [qw qx qy qz] [jaw]' lines from stdin")
      ->check(CLI::ExistingFile);
  tool->add_option("--rate", tco.rate, "Command rate in Hz (script mode)")->capture_default_str()->check(CLI::Range(1.0, 10000.0));
  tool->add_option("--duration", tco.duration, "Seconds (default: the script's length / until end of stdin)")->check(CLI::NonNegativeNumber);
  tool->add_option("--out", tco.out_csv, "CSV log: seq, sent, received, round trip (ms), force");
  tool->add_option("--dds-config", tco.dds_config, "Cyclone DDS XML (default: CYCLONEDDS_URI, else built-in loopback-only)")->check(CLI::ExistingFile);
  tool->add_option("--domain", tco.domain, "DDS domain id")->capture_default_str()->check(CLI::Range(0, 232));
  tool->add_option("--wait", tco.wait_server, "Seconds to wait for a server")->capture_default_str();
  tool->add_flag("!--no-realtime", tco.realtime, "Do not ask for SCHED_FIFO for the send/receive threads");

  // ---- render ----
  RenderOptions rdo;
  std::vector<double> cam_pos, cam_target, view_dir, light_dir;
  std::string color_field;
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
  rnd->add_option("--camera", cam_pos, "Camera position X Y Z (with --target; default: the scenario's render: section, else framing the scene)")
      ->expected(3)->delimiter(',');
  rnd->add_option("--target", cam_target, "Point the camera looks at X Y Z")->expected(3)->delimiter(',');
  rnd->add_option("--view", view_dir, "Automatic camera: frame the scene looking along X Y Z")->expected(3)->delimiter(',');
  rnd->add_option("--light", light_dir, "Key light direction X Y Z, world, from the light towards the scene (default: the scenario's, else above-left of the camera)")
      ->expected(3)->delimiter(',');
  rnd->add_option("--fov", rdo.fov, "Vertical field of view (degrees)")->check(CLI::Range(1.0, 170.0));
  rnd->add_option("--color", color_field, "Tissue colour: damage (default), stress, none")->check(CLI::IsMember({"none", "stress", "damage"}));
  rnd->add_flag("--wireframe", rdo.wireframe, "Draw the mesh edges");
  rnd->add_flag("--no-contacts", rdo.no_contacts, "No contact markers");
  rnd->add_option("--stats", rdo.stats_file, "Statistics JSON (default: <out>/render_stats.json)");
  rnd->add_option("--dds-config", rdo.dds_config, "Cyclone DDS XML (default: CYCLONEDDS_URI, else built-in loopback-only)")->check(CLI::ExistingFile);
  rnd->add_option("--domain", rdo.domain, "DDS domain id")->capture_default_str()->check(CLI::Range(0, 232));
  rnd->footer("Starts before or after the server (it waits for the mesh; the mesh is transient-local) and\n"
              "follows a restarted server. Frames are dropped (and counted), never queued, when rendering\n"
              "or writing falls behind. Stops at --frames/--duration or on Ctrl-C, then encodes the video.");

  // ---- bench ----
  AccuracyOptions aco;
  aco.source_dir = STROMA_SOURCE_DIR;
  auto* bench = app.add_subcommand("bench", "Measured claims: run time against error, numerical-stability stress suite");
  bench->require_subcommand(1);
  StabilityOptions sto;
  sto.source_dir = STROMA_SOURCE_DIR;
  auto* stab = bench->add_subcommand("stability", "Stress cases (time step x stiffness x Poisson x mesh quality; extreme loads) with pass criteria");
  auto* acc = bench->add_subcommand("accuracy", "Run time against error on the reference problems (cantilever static and dynamic, bonded block, sphere indentation), with Pareto fronts");
  acc->add_flag("--quick", aco.quick, "Fewer levels: a few minutes");
  acc->add_option("--runs", aco.runs, "Timing repetitions per configuration (median)")->capture_default_str()->check(CLI::Range(1, 50));
  acc->add_option("--out", aco.out_dir, "Output directory (CSV, PNG plots, gnuplot scripts)")->capture_default_str();
  bool with_peers = false;
  acc->add_option("--only", aco.only, "Run one problem only (cantilever: static and dynamic; with --peers: only its peer)")->check(CLI::IsMember({"cantilever", "indentation", "block_compression"}));
  acc->add_flag("--peers", with_peers, "Also run the Bullet peers (build/bench/stroma_bench_bullet) on the same problems and meshes and put them on the same tables and plots (adds ~25 min; ~12 min with --quick)");
  acc->add_option("--source-dir", aco.source_dir, "Repository with scenarios/ (default: where stroma was built from)")->check(CLI::ExistingDirectory);
  acc->footer("References: tip deflection -1.4735e-3 m (refs/a, converged C3D10), first frequency 16.100 Hz\n"
              "(refs/d), block top force 0.3049 N (refs/c), indentation force 0.019604 N at 1 mm (refs/e).\n"
              "Writes <problem>.csv and <problem>.png per problem into --out and prints Markdown tables.");
  stab->add_flag("--quick", sto.quick, "A subset that runs in under a minute (what ctest runs)");
  stab->add_option("--only", sto.only, "Run only the cases whose name contains this text (e.g. dropped)");
  stab->add_option("--newton", sto.newton_iterations, "Run every case with this many Newton iterations per tick (solver.newton_iterations)")->check(CLI::Range(1, 50));
  stab->add_option("--csv", sto.csv, "Write every case's figures here");
  stab->add_flag("--markdown", sto.markdown, "Print the table as Markdown (docs/STABILITY.md)");
  stab->add_option("--source-dir", sto.source_dir, "Repository with scenarios/ (default: where stroma was built from)")->check(CLI::ExistingDirectory);
  stab->footer("Pass: no NaN/Inf ever; total energy (kinetic + elastic + gravity + contact) never above its start\n"
               "(for driven cases: above its value when the drive stops) by more than 1 % of the energies seen;\n"
               "no element inverted at the end; every tick advanced (CG capped ticks are reported).\n"
               "Exit status 1 if any case fails.");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  auto logger = spdlog::stderr_color_mt("stroma");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
  spdlog::set_level(spdlog::level::from_str(log_level));

  try {
    if (*run) {
      auto model = load(run_scenario);
      RunOptions o;
      if (run_steps > 0) o.steps = run_steps;
      if (run_duration > 0) o.duration = run_duration;
      o.out_dir = run_out.empty() ? (fs::path("out") / (model->spec.name.empty() ? "run" : model->spec.name)).string() : run_out;
      o.vtu_every = vtu_every;
      o.progress = !quiet;
      o.metrics = !no_metrics;
      o.replay = replay_file;
      if (!replay_file.empty()) resolve_steps(*model, o);  // validates the log before any output
      ensure_writable_dir(o.out_dir);
      const RunResult r = run_headless(*model, o);
      print_summary(*model, r);
      fmt::print("results in {}/ (summary.json, metrics.csv, final.vtu, final_state.csv)\n", o.out_dir);
      const bool healthy = r.ticks_non_finite == 0 && r.static_converged;
      return healthy ? 0 : 1;
    }
    if (*serve) return run_serve(srv);
    if (*tool) return run_tool_client(tco);
    if (*acc) {
      ensure_writable_dir(aco.out_dir);
      if (with_peers) {
        const fs::path peer = fs::canonical("/proc/self/exe").parent_path() / "bench" / "stroma_bench_bullet";
        if (!fs::exists(peer))
          throw InputError("", 0, "--peers", fmt::format("{} not found (it is built when libbullet-dev is installed: scripts/setup.sh)", peer.string()));
        aco.peer_program = peer.string();
      }
      const auto points = run_accuracy_suite(aco);
      const long failed = std::count_if(points.begin(), points.end(), [](const AccuracyPoint& p) { return !p.ok; });
      fmt::print("{} configurations, {} failed to produce a measurement; results in {}/\n", points.size(), failed, aco.out_dir);
      return 0;
    }
    if (*stab) {
      const auto results = run_stability_suite(sto);
      const long failed = std::count_if(results.begin(), results.end(), [](const StabilityResult& r) { return !r.pass; });
      fmt::print("{} of {} cases passed\n", results.size() - failed, results.size());
      return failed ? 1 : 0;
    }
    if (*rnd) {
      if (!cam_pos.empty()) rdo.camera_position = std::array<double, 3>{cam_pos[0], cam_pos[1], cam_pos[2]};
      if (!cam_target.empty()) rdo.camera_target = std::array<double, 3>{cam_target[0], cam_target[1], cam_target[2]};
      if (!light_dir.empty()) {
        if (light_dir[0] == 0 && light_dir[1] == 0 && light_dir[2] == 0)
          throw InputError("", 0, "--light", "the light direction must not be zero");
        rdo.light_direction = std::array<double, 3>{light_dir[0], light_dir[1], light_dir[2]};
      }
      if (!view_dir.empty()) rdo.view_direction = std::array<double, 3>{view_dir[0], view_dir[1], view_dir[2]};
      if (cam_pos.empty() != cam_target.empty())
        throw InputError("", 0, cam_pos.empty() ? "--target" : "--camera", "--camera and --target go together");
      if (!color_field.empty()) rdo.color_field = color_field;
      return run_render(rdo);
    }
    if (*check) {
      auto model = load(chk_scenario);
      std::vector<double> ref;
      if (!chk_update) ref = read_state_csv(chk_reference);  // fail before running
      if (!ref.empty() && ref.size() != model->fem.rest.size())
        throw InputError(chk_reference, 0, "", fmt::format("reference has {} nodes, the scenario has {}",
                                                           ref.size() / 3, model->fem.num_nodes));
      RunOptions o;
      o.out_dir = chk_out;
      o.progress = false;
      o.metrics = !chk_out.empty();
      if (!chk_out.empty()) ensure_writable_dir(chk_out);
      const RunResult r = run_headless(*model, o);
      if (chk_update) {
        write_state_csv(chk_reference, r.final_state);
        fmt::print("reference written: {} ({} nodes, {} steps)\n", chk_reference, model->fem.num_nodes, r.steps);
        return 0;
      }
      const StateDifference d = compare_positions(r.final_state.tissue.x, ref);
      const CheckSpec& tol = model->spec.check;
      const bool ok = d.max_error <= tol.max_error && d.mean_error <= tol.mean_error &&
                      r.ticks_non_finite == 0;
      const std::string worst = d.worst_node >= 0 ? fmt::format(" at node {}", d.worst_node) : "";
      fmt::print("check {}: {} steps; max nodal error {:.3e} m{} (tolerance {:.1e}); mean {:.3e} m "
                 "(tolerance {:.1e}) -> {}\n",
                 model->spec.name, r.steps, d.max_error, worst, tol.max_error, d.mean_error,
                 tol.mean_error, ok ? "PASS" : "FAIL");
      return ok ? 0 : 1;
    }
  } catch (const InputError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  }
  return 0;
}
