// Sphere indentation of a soft block (refs/e_indentation_small): E = 5 kPa, ν = 0.45, block
// 0.1 × 0.1 × 0.05 m bonded at the bottom, rigid frictionless sphere R = 5 mm pushed d = 1 mm
// into the top centre. Reference force 0.019604 N (Hertz with the bonded-layer correction of
// Dimitriadis et al. 2002). Quarter model (symmetry planes x = 0, y = 0 sliding), a structured
// mesh graded geometrically towards the contact point, static solve with the contact recomputed
// at every Newton iteration.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <vector>

#include "bench/accuracy/quarter_block_mesh.hpp"
#include "engine/model.hpp"
#include "engine/trajectory.hpp"
#include "runtime/headless_runner.hpp"
#include "scene/compiled_scenario.hpp"
#include "tests/test_scenarios.hpp"

using namespace stroma;
namespace fs = std::filesystem;

TEST(Indentation, SphereForceWithinTenPercentOfTheBondedLayerHertzReference) {
  const double a = 0.05, H = 0.05, R = 0.005, d = 0.001;
  const std::string mesh =
      write_quarter_block((fs::temp_directory_path() / "stroma_indentation_block.msh").string(), a, H, 1.0e-4, 1.3);
  const std::string traj = (fs::temp_directory_path() / "stroma_indent.csv").string();
  {
    std::FILE* f = std::fopen(traj.c_str(), "w");
    std::fprintf(f, "t,x,y,z\n0,0,0,%.17g\n", H + R - d);
    std::fclose(f);
  }
  const std::string yaml = test_scenarios::indentation_block_yaml(
      mesh, traj, "{integrator: static, linear_solver: cholmod, static_tolerance: 1.0e-9, static_max_newton: 40}");
  const ScenarioSpec spec = parse_scenario(yaml, "indentation.yaml", "");
  const CompiledScenario sc_m = compile_scenario(spec);
  const auto& m = sc_m.model;
  RunOptions o;
  o.progress = false;
  const RunResult r = run_headless(sc_m, o);
  ASSERT_TRUE(r.static_converged) << "residual " << r.static_residual << " after " << r.newton_iterations;
  const ToolOutput& ts = r.final_tools.at(0);
  ASSERT_GT(ts.contacts, 0);
  const double F = 4.0 * ts.force[2];  // quarter model
  const double reference = 0.019604;
  std::printf("indentation: %d nodes, %zu tets, %d contact samples, F = %.6f N (reference %.6f N, %+.2f %%)\n",
              m->fem.num_nodes, m->fem.elements.size(), ts.contacts, F, reference, 100 * (F / reference - 1));
  EXPECT_NEAR(F, reference, 0.10 * reference);
  // (The quarter's lateral force components are balanced by the other three quarters.)
}
