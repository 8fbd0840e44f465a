/// \file main.cpp
/// Embedding Stroma in a C++ program (docs/EMBEDDING.md): load and compile a scenario, step it
/// the way `stroma run` does (its tool scripts drive its tools), and read its probes. The engine
/// is split as MuJoCo's is: a compiled, immutable Model; a small State you may copy to snapshot;
/// a TickWorkspace of scratch memory; and tick(), which advances the State by one time step.
///
/// Usage: embed_stroma SCENARIO [--steps N] [--state OUT.csv]
///   N defaults to the scenario's run length; --state writes the final positions as `stroma run`
///   writes final_state.csv (so `stroma check SCENARIO OUT.csv` can compare them).

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <stroma/scene/compiled_scenario.hpp>
#include <stroma/runtime/headless_runner.hpp>
#include <stroma/scene/scenario_spec.hpp>
#include <stroma/engine/state.hpp>
#include <stroma/runtime/state_io.hpp>
#include <stroma/engine/tick.hpp>
#include <stroma/tissue/input_error.hpp>

int main(int argc, char** argv) {
  using namespace stroma;
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) {
    std::printf("Usage: embed_stroma SCENARIO [--steps N] [--state OUT.csv]\n"
                "Loads a Stroma scenario, steps it as `stroma run` does and prints its probes.\n");
    return argc < 2 ? 2 : 0;
  }
  const std::string path = argv[1];
  long steps = -1;
  std::string state_out;
  for (int i = 2; i < argc; ++i) {
    if (std::strcmp(argv[i], "--steps") == 0 && i + 1 < argc) {
      steps = std::strtol(argv[++i], nullptr, 10);
    } else if (std::strcmp(argv[i], "--state") == 0 && i + 1 < argc) {
      state_out = argv[++i];
    } else {
      std::fprintf(stderr, "embed_stroma: unknown argument '%s' (see --help)\n", argv[i]);
      return 2;
    }
  }

  CompiledScenario sc;
  try {
    sc = compile_scenario(load_scenario(path));  // every check happens here: file:line: field
  } catch (const InputError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
  const Model& m = *sc.model;
  if (steps < 0) steps = resolve_steps(sc, RunOptions{});  // as `stroma run`: the scenario's run length

  State s = State::initial(m);  // copy it to take a snapshot; assign it back to roll back
  TickWorkspace w(m);           // sized once here: tick() allocates nothing
  std::vector<ToolInput> inputs;
  for (long k = 0; k < steps; ++k) {
    inputs.clear();
    for (size_t t = 0; t < m.tools.size(); ++t)
      if (!sc.tool_scripts[t].keys.empty())
        inputs.push_back(ToolInput{static_cast<int32_t>(t), static_cast<uint64_t>(k + 1), 0,
                                   sc.tool_scripts[t].sample(s.time)});
    const TickReport& r = tick(m, s, w, inputs.data(), static_cast<int>(inputs.size()));
    if (r.status == TickStatus::NonFinite) {
      std::fprintf(stderr, "embed_stroma: tick %ld did not advance (non-finite)\n", k + 1);
      return 1;
    }
  }
  std::printf("%s: %ld ticks, t = %.3f s, %d nodes\n", m.name.c_str(), steps, s.time, m.fem.num_nodes);
  for (const ProbeModel& p : m.probes) {
    const Vec3 d = probe_displacement(m, s, p);
    std::printf("probe %s: displacement %.9g %.9g %.9g\n", p.name.c_str(), d[0], d[1], d[2]);
  }
  if (!state_out.empty()) write_state_csv(state_out, s);
  return 0;
}
