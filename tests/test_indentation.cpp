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

#include "engine/headless_runner.hpp"
#include "engine/model.hpp"
#include "engine/trajectory.hpp"

using namespace stroma;
namespace fs = std::filesystem;

namespace {

/// 0, h0, h0(1+r), … up to `length` (last spacing absorbed), i.e. cells growing by `ratio`.
std::vector<double> graded(double h0, double ratio, double length) {
  std::vector<double> p{0.0};
  double h = h0;
  while (p.back() + h < length * 0.999) {
    p.push_back(p.back() + h);
    h *= ratio;
  }
  if (length - p.back() < 0.5 * h / ratio && p.size() > 1) p.back() = length;
  else p.push_back(length);
  return p;
}

/// Quarter block [0, a]² × [0, H] graded towards (0, 0, H), 6 tetrahedra per hexahedron
/// (Kuhn split along the main diagonal: conforming), written as Gmsh 2.2.
std::string write_quarter_block(double a, double H, double h0, double ratio) {
  const std::vector<double> xs = graded(h0, ratio, a);
  std::vector<double> zs = graded(h0, ratio, H);
  for (double& z : zs) z = H - z;
  std::reverse(zs.begin(), zs.end());
  const int nx = static_cast<int>(xs.size()), nz = static_cast<int>(zs.size());
  auto id = [&](int i, int j, int k) { return 1 + i + nx * (j + nx * k); };
  const fs::path path = fs::temp_directory_path() / "stroma_indentation_block.msh";
  std::FILE* f = std::fopen(path.c_str(), "w");
  std::fprintf(f, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n", nx * nx * nz);
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < nx; ++j)
      for (int i = 0; i < nx; ++i) std::fprintf(f, "%d %.17g %.17g %.17g\n", id(i, j, k), xs[i], xs[j], zs[k]);
  const int cells = (nx - 1) * (nx - 1) * (nz - 1);
  std::fprintf(f, "$EndNodes\n$Elements\n%d\n", 6 * cells);
  int e = 0;
  for (int k = 0; k + 1 < nz; ++k)
    for (int j = 0; j + 1 < nx; ++j)
      for (int i = 0; i + 1 < nx; ++i) {
        const int v000 = id(i, j, k), v100 = id(i + 1, j, k), v010 = id(i, j + 1, k), v110 = id(i + 1, j + 1, k);
        const int v001 = id(i, j, k + 1), v101 = id(i + 1, j, k + 1), v011 = id(i, j + 1, k + 1), v111 = id(i + 1, j + 1, k + 1);
        const int tets[6][4] = {{v000, v100, v110, v111}, {v000, v110, v010, v111}, {v000, v010, v011, v111},
                                {v000, v011, v001, v111}, {v000, v001, v101, v111}, {v000, v101, v100, v111}};
        for (const auto& t : tets) std::fprintf(f, "%d 4 2 0 1 %d %d %d %d\n", ++e, t[0], t[1], t[2], t[3]);
      }
  std::fprintf(f, "$EndElements\n");
  std::fclose(f);
  return path.string();
}

}  // namespace

TEST(Indentation, SphereForceWithinTenPercentOfTheBondedLayerHertzReference) {
  const double a = 0.05, H = 0.05, R = 0.005, d = 0.001;
  const std::string mesh = write_quarter_block(a, H, 1.0e-4, 1.3);
  const std::string traj = (fs::temp_directory_path() / "stroma_indent.csv").string();
  {
    std::FILE* f = std::fopen(traj.c_str(), "w");
    std::fprintf(f, "t,x,y,z\n0,0,0,%.17g\n", H + R - d);
    std::fclose(f);
  }
  const std::string yaml =
      "name: indentation\n"
      "gravity: [0, 0, 0]\n"
      "solver: {integrator: static, linear_solver: cholmod, static_tolerance: 1.0e-9, static_max_newton: 40}\n"
      "bodies:\n"
      "  - name: block\n"
      "    mesh: " + mesh + "\n"
      "    material: {model: linear, young_modulus: 5000, poisson_ratio: 0.45, density: 1000}\n"
      "    fixed:\n"
      "      - box: {min: [-1, -1, -1.0e-9], max: [1, 1, 1.0e-9]}\n"
      "      - {box: {min: [-1.0e-9, -1, -1], max: [1.0e-9, 1, 1]}, axes: [x]}\n"
      "      - {box: {min: [-1, -1.0e-9, -1], max: [1, 1.0e-9, 1]}, axes: [y]}\n"
      "tools:\n"
      "  - name: sphere\n"
      "    script: " + traj + "\n"
      "    shape: {type: sphere, radius: 0.005}\n"
      "    contact: {stiffness: 1.0e9}\n";
  const ScenarioSpec spec = parse_scenario(yaml, "indentation.yaml", "");
  auto m = compile_model(spec);
  RunOptions o;
  o.progress = false;
  const RunResult r = run_headless(*m, o);
  ASSERT_TRUE(r.static_converged) << "residual " << r.static_residual << " after " << r.newton_iterations;
  const ToolState& ts = r.final_state.tools.at(0);
  ASSERT_GT(ts.contacts, 0);
  const double F = 4.0 * ts.force[2];  // quarter model
  const double reference = 0.019604;
  std::printf("indentation: %d nodes, %zu tets, %d contact samples, F = %.6f N (reference %.6f N, %+.2f %%)\n",
              m->fem.num_nodes, m->fem.elements.size(), ts.contacts, F, reference, 100 * (F / reference - 1));
  EXPECT_NEAR(F, reference, 0.10 * reference);
  // (The quarter's lateral force components are balanced by the other three quarters.)
}
