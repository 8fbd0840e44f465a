// libFuzzer target: the scenario loader — YAML parse and validation, then compile (meshes,
// selections, materials, tools, visuals) and two ticks of what loaded. Relative paths resolve
// against scenarios/regression/ (STROMA_SOURCE_DIR), so the seeds are the project's own scenarios and can
// name its meshes and trajectories. Scenes above kMaxNodes nodes are not ticked (speed).
// `preconditioner: auto` is compiled as `jacobi`: the automatic choice runs trial solves of the
// scene (tissue/solver_choice.cpp) — numerics, not input handling, tested in the unit tests —
// which take ~30 s per input under the fuzzer's instrumentation and would read as a hang. The
// ticks run under a 50 ms time budget (the served path's deadline, engine/step_with_recovery.hpp)
// for the same reason: a stiff scene's capped solves redone in up to 16 sub-steps otherwise.

#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tissue/input_error.hpp"

namespace {
constexpr int kMaxNodes = 3000;
constexpr double kTickBudget = 0.05;  // s
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    stroma::ScenarioSpec spec =
        stroma::parse_scenario(text, "fuzz.yaml", STROMA_SOURCE_DIR "/scenarios/regression");
    if (!spec.solver.preconditioner) spec.solver.preconditioner = stroma::Preconditioner::Jacobi;
    if (!(spec.solver.time_budget > 0 && spec.solver.time_budget < kTickBudget)) spec.solver.time_budget = kTickBudget;
    stroma::CompiledScenario sc = stroma::compile_scenario(spec);
    const stroma::Model& m = *sc.model;
    if (m.fem.num_nodes > kMaxNodes) return 0;
    stroma::State s = stroma::State::initial(m);
    stroma::TickWorkspace w(m);
    for (int k = 0; k < 2; ++k) stroma::tick(m, s, w, nullptr, 0);
  } catch (const stroma::InputError&) {
  }
  return 0;
}
