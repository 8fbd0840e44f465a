// Heterogeneous bodies: regions of a mesh (gmsh physical volumes) with their own material
// (issue 17 §3, first slice).
//
// Asserted, and against what:
//  - the gmsh readers keep each tetrahedron's physical group (2.2: its first tag; 4.1: through
//    $Entities) and the volumes' $PhysicalNames;
//  - a bimaterial bar (ν = 0, two regions in series, consistent end load) stretches statically
//    by F·L₁/(E₁A) + F·L₂/(E₂A) within 0.5 % (linear tetrahedra represent the piecewise-uniform
//    strain exactly; what is left is the corotational model's geometric nonlinearity at 1e-4
//    strain and the solver's tolerance);
//  - its mass is ρ₁V₁ + ρ₂V₂ to 1e-12;
//  - bad regions are load errors naming the scenario's line and field: a name the mesh lacks
//    (listing its regions), a tag no tetrahedron has, a mesh without regions, a region given
//    twice, a region material that changes nothing.

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <sstream>
#include <string>

#include "engine/model.hpp"
#include "engine/scenario_spec.hpp"
#include "engine/state.hpp"
#include "engine/static_run.hpp"
#include "engine/tick.hpp"
#include "test_meshes.hpp"
#include "test_scenarios.hpp"
#include "tissue/input_error.hpp"
#include "tissue/mesh_io.hpp"

using namespace stroma;
using test_scenarios::write_temp;

namespace {

constexpr double kL = 0.1, kW = 0.02;     // bar 100 × 20 × 20 mm
constexpr double kSplit = 0.04;           // region 1 (soft) for x < 40 mm, region 2 (stiff) beyond
constexpr double kE1 = 5e3, kE2 = 5e4;    // Pa: liver-like and a tumour-like inclusion
constexpr double kRho1 = 1000, kRho2 = 1100;

/// The bar as a gmsh 2.2 file: physical volumes 1 "soft" (x < kSplit) and 2 "stiff".
std::string bimaterial_msh() {
  const TetMesh m = test_meshes::box_mesh(10, 2, 2, {kL, kW, kW});
  std::ostringstream o;
  o.precision(17);
  o << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n3 1 \"soft\"\n3 2 \"stiff\"\n$EndPhysicalNames\n";
  o << "$Nodes\n" << m.nodes.size() << "\n";
  for (size_t i = 0; i < m.nodes.size(); ++i) o << i + 1 << " " << m.nodes[i][0] << " " << m.nodes[i][1] << " " << m.nodes[i][2] << "\n";
  o << "$EndNodes\n$Elements\n" << m.tets.size() << "\n";
  for (size_t e = 0; e < m.tets.size(); ++e) {
    double cx = 0;
    for (int32_t n : m.tets[e]) cx += 0.25 * m.nodes[n][0];
    const int tag = cx < kSplit ? 1 : 2;
    o << e + 1 << " 4 2 " << tag << " " << tag;
    for (int32_t n : m.tets[e]) o << " " << n + 1;
    o << "\n";
  }
  o << "$EndElements\n";
  return o.str();
}

std::string bar_yaml(const std::string& mesh, const std::string& regions) {
  return "name: bimaterial\ntime_step: 0.001\ngravity: [0, 0, 0]\n"
         "solver: {integrator: static, linear_solver: cholmod}\n"
         "bodies:\n"
         "  - name: bar\n"
         "    mesh: " + mesh + "\n"
         "    material: {model: corotational, young_modulus: 5000, poisson_ratio: 0, density: 1000}\n"
         "    fixed:\n"
         "      - box: {min: [-1.0e-6, -1, -1], max: [1.0e-6, 1, 1]}\n" +
         regions + "run: {steps: 1}\n";
}

const std::string kRegions =
    "    regions:\n"
    "      - {region: stiff, material: {young_modulus: 50000, density: 1100}}\n";

}  // namespace

TEST(Regions, GmshReadersKeepPhysicalVolumes) {
  const TetMesh m2 = load_tet_mesh(write_temp("bimaterial.msh", bimaterial_msh()));
  ASSERT_EQ(m2.tet_tags.size(), m2.tets.size());
  EXPECT_EQ(std::count(m2.tet_tags.begin(), m2.tet_tags.end(), 1) + std::count(m2.tet_tags.begin(), m2.tet_tags.end(), 2),
            static_cast<long>(m2.tets.size()));
  EXPECT_GT(std::count(m2.tet_tags.begin(), m2.tet_tags.end(), 1), 0);
  ASSERT_EQ(m2.tag_names.size(), 2u);
  EXPECT_EQ(m2.tag_names[1], (std::pair<int32_t, std::string>{2, "stiff"}));
  // 4.1: a tetrahedron in volume entity 7, which is physical group 5 "tumour".
  const std::string v41 =
      "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 5 \"tumour\"\n$EndPhysicalNames\n"
      "$Entities\n0 0 0 1\n7 0 0 0 1 1 1 1 5 0\n$EndEntities\n"
      "$Nodes\n1 4 1 4\n3 7 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n"
      "$Elements\n1 1 1 1\n3 7 4 1\n1 1 2 3 4\n$EndElements\n";
  const TetMesh m4 = load_tet_mesh(write_temp("tumour41.msh", v41));
  ASSERT_EQ(m4.tet_tags.size(), 1u);
  EXPECT_EQ(m4.tet_tags[0], 5);
  ASSERT_EQ(m4.tag_names.size(), 1u);
  EXPECT_EQ(m4.tag_names[0].second, "tumour");
  // No physical groups: no regions.
  const std::string plain = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"
                            "$EndNodes\n$Elements\n1\n1 4 0 1 2 3 4\n$EndElements\n";
  EXPECT_TRUE(load_tet_mesh(write_temp("plain.msh", plain)).tet_tags.empty());
}

TEST(Regions, ABimaterialBarStretchesAsTwoSpringsInSeries) {
  const std::string mesh = write_temp("bimaterial.msh", bimaterial_msh());
  const auto model = compile_model(load_scenario(write_temp("bimaterial.yaml", bar_yaml(mesh, kRegions))));
  const FemModel& f = model->fem;
  // Mass: each region's density times its volume.
  double v1 = 0, v2 = 0;
  for (const ElementParams& e : f.elements) {
    double cx = 0;
    for (int32_t n : e.node) cx += 0.25 * f.rest[3 * n];
    (cx < kSplit ? v1 : v2) += e.volume;
  }
  const double mass = std::accumulate(f.mass.begin(), f.mass.end(), 0.0);
  EXPECT_NEAR(mass, kRho1 * v1 + kRho2 * v2, 1e-12 * mass);
  EXPECT_NEAR(v1, kSplit * kW * kW, 1e-15);
  // A consistent traction F/A on the end face x = L: each node gets F/A × a third of the area of
  // its end-face triangles.
  const double F = 1e-4 * kE1 * kW * kW;  // strain 1e-4 in the soft region
  Model m = *model;
  std::fill(m.fem.f_ext.begin(), m.fem.f_ext.end(), 0.0);
  double face_area = 0;
  for (const Tri& t : f.bodies[0].boundary) {
    bool end = true;
    for (int32_t n : t) end &= std::abs(f.rest[3 * n] - kL) < 1e-9;
    if (!end) continue;
    const double* a = &f.rest[3 * t[0]];
    const double* b = &f.rest[3 * t[1]];
    const double* c = &f.rest[3 * t[2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double area = 0.5 * std::sqrt(std::pow(u[1] * v[2] - u[2] * v[1], 2) + std::pow(u[2] * v[0] - u[0] * v[2], 2) +
                                        std::pow(u[0] * v[1] - u[1] * v[0], 2));
    face_area += area;
    for (int32_t n : t) m.fem.f_ext[3 * n] += F / (kW * kW) * area / 3.0;
  }
  ASSERT_NEAR(face_area, kW * kW, 1e-15);
  State s = State::initial(m);
  TickWorkspace w(m);
  StaticParameters from, to;
  from.load = 0;
  to.load = 1;
  const StaticOutcome out = solve_equilibrium(m, s, w, from, to);
  ASSERT_TRUE(out.converged);
  // The end face's mean displacement against two springs in series.
  double ux = 0;
  int n_end = 0;
  for (int32_t n = 0; n < f.num_nodes; ++n)
    if (std::abs(f.rest[3 * n] - kL) < 1e-9) {
      ux += s.tissue.x[3 * n] - f.rest[3 * n];
      ++n_end;
    }
  ux /= n_end;
  const double expected = F * kSplit / (kE1 * kW * kW) + F * (kL - kSplit) / (kE2 * kW * kW);
  EXPECT_NEAR(ux, expected, 0.005 * expected) << "homogeneous soft bar: " << F * kL / (kE1 * kW * kW);
  RecordProperty("extension_relative_error", std::to_string(ux / expected - 1));
  // The same bar without its stiff region stretches as the soft material alone (the regions
  // are what made the difference).
  const auto uniform = compile_model(load_scenario(write_temp("uniform.yaml", bar_yaml(mesh, ""))));
  EXPECT_NE(uniform->fem.elements.back().mu, model->fem.elements.back().mu);
  EXPECT_EQ(uniform->fem.elements.front().mu, model->fem.elements.front().mu);
}

TEST(Regions, BadRegionsAreLoadErrorsNamingTheField) {
  const std::string mesh = write_temp("bimaterial.msh", bimaterial_msh());
  auto error_of = [&](const std::string& regions, const std::string& m = "") {
    try {
      compile_model(load_scenario(write_temp("bad_regions.yaml", bar_yaml(m.empty() ? mesh : m, regions))));
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  std::string e = error_of("    regions:\n      - {region: tumour, material: {young_modulus: 50000}}\n");
  EXPECT_NE(e.find("bodies[0].regions[0].region"), std::string::npos) << e;
  EXPECT_NE(e.find("no region named 'tumour'"), std::string::npos) << e;
  EXPECT_NE(e.find("'stiff'"), std::string::npos) << "lists the mesh's regions: " << e;
  EXPECT_NE(e.find(":12:"), std::string::npos) << "the scenario line: " << e;
  e = error_of("    regions:\n      - {region: 9, material: {young_modulus: 50000}}\n");
  EXPECT_NE(e.find("region 9"), std::string::npos) << e;
  e = error_of("    regions:\n      - {region: 2, material: {young_modulus: 50000}}\n"
               "      - {region: stiff, material: {density: 900}}\n");
  EXPECT_NE(e.find("given twice"), std::string::npos) << e;
  EXPECT_NE(e.find("regions[1]"), std::string::npos) << e;
  e = error_of("    regions:\n      - {region: stiff, material: {}}\n");
  EXPECT_NE(e.find("at least one of"), std::string::npos) << e;
  e = error_of("    regions:\n      - {region: stiff, material: {poisson_ratio: 0.5}}\n");
  EXPECT_NE(e.find("poisson_ratio"), std::string::npos) << e;
  const std::string plain = write_temp("plain.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n"
                                                    "3 0 1 0\n4 0 0 1\n$EndNodes\n$Elements\n1\n1 4 0 1 2 3 4\n$EndElements\n");
  e = error_of(kRegions, plain);
  EXPECT_NE(e.find("has no regions"), std::string::npos) << e;
}
