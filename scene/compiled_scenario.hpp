#pragma once
/// \file compiled_scenario.hpp
/// What compiling a scenario produces: the immutable Model the tick reads, and beside it what
/// only the commands around the tick use — the validated scenario text (run length, check
/// tolerances, render settings), the headless tool scripts, the visual surfaces the server
/// publishes, and load-time notes worth logging.

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "engine/model.hpp"
#include "engine/trajectory.hpp"
#include "scene/scenario_spec.hpp"
#include "tissue/solver_choice.hpp"
#include "tissue/visual_mapping.hpp"

namespace stroma {

/// A body's visual surface (scenario `visual:`): drawn instead of the tetrahedra's boundary,
/// following them through a fixed barycentric mapping (tissue/visual_mapping.hpp).
/// Invariant: every index in `triangles` is < rest.size(); mapping has one entry per vertex.
struct VisualModel {
  std::string source;                  ///< the mesh file
  std::vector<Vec3> rest;              ///< vertex rest positions (scaled like the body)
  std::vector<uint32_t> triangles;     ///< 3 per triangle, into `rest`
  VisualMapping mapping;               ///< vertex = Σ w · x(node), global node indices
};

/// A compiled scenario. Invariants: `model` is non-null; tool_scripts and visuals have one
/// entry per tool and per body (a tool without a script has no keyframes; a body without a
/// visual surface has none).
struct CompiledScenario {
  ScenarioSpec spec;                       ///< the validated scenario it was compiled from
  std::shared_ptr<const Model> model;      ///< what the tick reads
  std::vector<Trajectory> tool_scripts;    ///< per tool: headless inputs (may be empty)
  std::vector<std::optional<VisualModel>> visuals;  ///< per body
  std::vector<std::string> notes;          ///< load-time observations (reoriented, unused nodes)
  /// `preconditioner: auto`: what the engine chose and why (the model's stepper has it);
  /// empty when the scenario named its preconditioner.
  std::optional<PreconditionerChoice> solver_choice;
};

/// How the scenario will be run, where that changes what compile resolves.
struct CompileOptions {
  /// Every tick runs under a time budget (`stroma serve`, the replay of a served session): the
  /// preconditioner choice charges each candidate the iteration a budget cut may overshoot by
  /// (tissue/solver_choice.hpp). A scenario's own `time_budget` implies it.
  bool budgeted = false;
  /// `--converge`: the solver left to the engine at the scenario's tolerance
  /// (scene/solver_comparison.hpp, converge_solver) — for SOFA scenes, which reproduce SOFA's
  /// capped, unpreconditioned CG by default. The compiled spec is the converged one.
  bool converge = false;
};

/// Loads every mesh, surface and tool script, validates materials and selections against the
/// meshes, and compiles. Throws InputError with the scenario file, line and field on any
/// problem; nothing is half-built.
CompiledScenario compile_scenario(const ScenarioSpec& spec, const CompileOptions& options = {});

/// Loads every mesh, validates materials and selections against them, and compiles the model
/// alone (tests and benchmarks; the commands use compile_scenario). Throws InputError with the
/// scenario file, line and field on any problem.
std::shared_ptr<const Model> compile_model(const ScenarioSpec& spec);

}  // namespace stroma
