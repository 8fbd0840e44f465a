#pragma once
/// \file commands.hpp
/// The `stroma` command's subcommands: each adds itself to the CLI11 app and returns what runs
/// it once the arguments are parsed. One file per subcommand (cmd_*.cpp); main.cpp wires them
/// and maps errors to exit codes (0 success, 1 check failed or run unhealthy, 2 bad input).

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "scene/compiled_scenario.hpp"

namespace stroma::cli {

/// A parsed subcommand: `selected` says whether the user chose it, `run` does its work.
struct Command {
  CLI::App* app = nullptr;
  std::function<int()> run;
};

/// The command line this process was started with (for reports that record how they were made).
const std::string& invocation();

/// Loads and compiles a scenario, logging its notes, its size and the solver it runs.
CompiledScenario load(const std::string& path, const CompileOptions& options = {});

void add_run(CLI::App& app, std::vector<Command>& out);     ///< stroma run
void add_check(CLI::App& app, std::vector<Command>& out);   ///< stroma check
void add_bench(CLI::App& app, std::vector<Command>& out);   ///< stroma bench stability | accuracy
#ifdef STROMA_WITH_DDS
void add_serve(CLI::App& app, std::vector<Command>& out);   ///< stroma serve
void add_tool(CLI::App& app, std::vector<Command>& out);    ///< stroma tool
void add_security(CLI::App& app, std::vector<Command>& out);  ///< stroma security init
#endif
#ifdef STROMA_WITH_MESHING
void add_mesh(CLI::App& app, std::vector<Command>& out);    ///< stroma mesh surface | image
#endif
#ifdef STROMA_WITH_RENDER
void add_render(CLI::App& app, std::vector<Command>& out);  ///< stroma render
#endif

}  // namespace stroma::cli
