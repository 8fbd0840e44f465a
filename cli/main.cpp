/// \file main.cpp
/// The `stroma` command: one executable, one subcommand per job (CLI11).
///   stroma run SCENARIO      headless run, outputs into a directory
///   stroma check SCENARIO REFERENCE   run and compare the final state to a stored reference
///   stroma bench stability|accuracy   measured claims (stress suite, run time against error)
///   stroma serve SCENARIO    real-time server at 1 kHz over DDS (loopback by default)
///   stroma tool              drive a served tool over DDS (script or stdin)
///   stroma render            record a served scenario off-screen (PNG frames, MP4)
///   stroma security init DIR certificates and signed documents for a protected DDS domain
///   stroma mesh surface|image  a closed surface or a labelled image to a tet mesh (CGAL)
/// serve and tool exist when built with STROMA_WITH_DDS, render with STROMA_WITH_RENDER, mesh
/// with STROMA_WITH_MESHING.
/// Exit codes: 0 success, 1 check failed / run unhealthy, 2 bad input or usage.

#include <cstdio>

#include <fmt/format.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "tissue/input_error.hpp"

using namespace stroma;

namespace {
std::string g_invocation;
}

const std::string& stroma::cli::invocation() { return g_invocation; }

int main(int argc, char** argv) {
  for (int i = 0; i < argc; ++i) g_invocation += (i ? " " : "") + std::string(i ? argv[i] : "stroma");
  CLI::App app{"Stroma: real-time soft-tissue simulation (corotational FEM, implicit Euler)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "stroma 0.1.0");
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|off")->capture_default_str();

  std::vector<cli::Command> commands;
  cli::add_run(app, commands);
  cli::add_check(app, commands);
#ifdef STROMA_WITH_DDS
  cli::add_serve(app, commands);
  cli::add_tool(app, commands);
  cli::add_security(app, commands);
#endif
#ifdef STROMA_WITH_RENDER
  cli::add_render(app, commands);
#endif
  cli::add_bench(app, commands);
#ifdef STROMA_WITH_MESHING
  cli::add_mesh(app, commands);
#endif

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
    for (const cli::Command& c : commands)
      if (c.app->parsed()) return c.run();
  } catch (const std::exception& e) {  // InputError included: file:line: field: message
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  }
  return 0;
}
