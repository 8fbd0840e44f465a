// Heterogeneous bodies: regions of a mesh (gmsh physical volumes) with their own material
// (issue 17 §3, first slice).
//
// Asserted, and against what:
//  - the gmsh readers keep each tetrahedron's physical group (2.2: its first tag; 4.1: through
//    $Entities) and the volumes' $PhysicalNames; the VTU reader an integer cell-data array
//    named as meshers name regions;
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
#include <fstream>
#include <numeric>
#include <sstream>
#include <string>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/static_run.hpp"
#include "engine/tick.hpp"
#include "io/mesh_io.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/test_fem.hpp"
#include "tests/test_meshes.hpp"
#include "tests/test_scenarios.hpp"
#include "tissue/input_error.hpp"

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
  return test_fem::gmsh22(
      m,
      [&](size_t e) {
        double cx = 0;
        for (int32_t n : m.tets[e]) cx += 0.25 * m.nodes[n][0];
        return cx < kSplit ? 1 : 2;
      },
      {"3 1 \"soft\"", "3 2 \"stiff\""});
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

TEST(Regions, MeshReadersKeepRegionTags) {
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
  // VTU: an integer cell-data array named as meshers name regions ("region", "gmsh:physical",
  // "MaterialIds", ...); other cell data is not a region.
  auto vtu = [](const std::string& array) {
    return "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\">\n<UnstructuredGrid>\n"
           "<Piece NumberOfPoints=\"5\" NumberOfCells=\"2\">\n"
           "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">"
           "0 0 0 1 0 0 0 1 0 0 0 1 1 1 1</DataArray></Points>\n"
           "<Cells><DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2 3 1 2 3 4</DataArray>"
           "<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4 8</DataArray>"
           "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10 10</DataArray></Cells>\n"
           "<CellData><DataArray type=\"Int32\" Name=\"" + array + "\" format=\"ascii\">1 2</DataArray></CellData>\n"
           "</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
  };
  const TetMesh mv = load_tet_mesh(write_temp("regions.vtu", vtu("MaterialIds")));
  EXPECT_EQ(mv.tet_tags, (std::vector<int32_t>{1, 2}));
  EXPECT_TRUE(load_tet_mesh(write_temp("quality.vtu", vtu("quality"))).tet_tags.empty());
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
  const double face_area = test_fem::add_end_traction(m.fem, kL, F / (kW * kW));
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

namespace {

/// SOFA's liver at 16 cm (×0.025) as a gmsh 2.2 file whose tetrahedra within `radius` of
/// `centre` form physical volume 2 "tumour" (the rest: 1 "liver"). Returns the tumour's count.
int tumour_liver_msh(const std::string& path, const Vec3& centre, double radius) {
  const TetMesh m = load_tet_mesh(std::string(STROMA_SOURCE_DIR) + "/scenarios/meshes/liver.msh");
  std::ostringstream o;
  o.precision(17);
  o << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n3 1 \"liver\"\n3 2 \"tumour\"\n$EndPhysicalNames\n";
  o << "$Nodes\n" << m.nodes.size() << "\n";
  for (size_t i = 0; i < m.nodes.size(); ++i)
    o << i + 1 << " " << 0.025 * m.nodes[i][0] << " " << 0.025 * m.nodes[i][1] << " " << 0.025 * m.nodes[i][2] << "\n";
  o << "$EndNodes\n$Elements\n" << m.tets.size() << "\n";
  int inside = 0;
  for (size_t e = 0; e < m.tets.size(); ++e) {
    double d2 = 0;
    for (int k = 0; k < 3; ++k) {
      double c = 0;
      for (int32_t n : m.tets[e]) c += 0.25 * 0.025 * m.nodes[n][k];
      d2 += (c - centre[k]) * (c - centre[k]);
    }
    const int tag = d2 < radius * radius ? 2 : 1;
    inside += tag == 2;
    o << e + 1 << " 4 2 " << tag << " " << tag;
    for (int32_t n : m.tets[e]) o << " " << n + 1;
    o << "\n";
  }
  o << "$EndElements\n";
  std::ofstream(path) << o.str();
  return inside;
}

std::string tumour_yaml(const std::string& mesh, bool tumour, bool dynamic, const std::string& tumour_extra = "") {
  return std::string("name: tumour\ntime_step: 0.001\n") + (dynamic ? "gravity: [0, -9.81, 0]\n" : "gravity: [0, 0, 0]\n") +
         (dynamic ? "solver: {integrator: implicit_euler, linear_solver: cg, preconditioner: jacobi, max_iterations: 200, "
                    "tolerance: 1.0e-6}\n"
                  : "solver: {integrator: static, linear_solver: cholmod}\n") +
         "bodies:\n"
         "  - name: liver\n"
         "    mesh: " + mesh + "\n"
         "    material: {model: corotational, young_modulus: 5000, poisson_ratio: 0.45, density: 1060,\n"
         "               rayleigh_mass: 1.0, rayleigh_stiffness: 0.005}\n" +
         (tumour ? "    regions:\n      - {region: tumour, material: {young_modulus: 50000" + tumour_extra + "}}\n" : "") +
         "    fixed:\n"
         "      - surface: {normal: [0, -1, 0], max_angle: 45}\n"
         "    loads:\n"
         "      - box: {min: [-0.05, 0.105, 0.0], max: [-0.025, 0.2, 0.025]}\n"
         "        force: [0, -0.3, 0]\n"
         "run: {steps: 1}\n";
}

}  // namespace

// A stiff tumour (10× the liver's E) under the upper surface lowers the indentation depth of a
// load pressed on the surface above it, against the homogeneous liver; the liver with the tumour
// runs 1 s at 1 kHz under gravity and the load, finite and at rest at the end.
TEST(Regions, AStiffTumourLowersTheIndentationAboveIt) {
  const std::string mesh = write_temp("tumour_liver.msh", "");
  const int tumour_tets = tumour_liver_msh(mesh, {-0.0375, 0.095, 0.0125}, 0.022);
  ASSERT_GT(tumour_tets, 5);
  auto depth = [&](bool tumour) {
    auto model = compile_model(load_scenario(write_temp(tumour ? "t.yaml" : "h.yaml", tumour_yaml(mesh, tumour, false))));
    State s = State::initial(*model);
    TickWorkspace w(*model);
    StaticParameters from, to;
    from.load = 0;
    const StaticOutcome out = solve_equilibrium(*model, s, w, from, to);
    EXPECT_TRUE(out.converged);
    // The loaded nodes' mean downward displacement.
    double dy = 0;
    int n = 0;
    for (int32_t i = 0; i < model->fem.num_nodes; ++i)
      if (model->fem.f_ext[3 * i + 1] < 0) {
        dy += model->fem.rest[3 * i + 1] - s.tissue.x[3 * i + 1];
        ++n;
      }
    EXPECT_GT(n, 0);
    return dy / n;
  };
  const double homogeneous = depth(false), with_tumour = depth(true);
  EXPECT_GT(homogeneous, 1e-4) << "the load pressed the liver";
  EXPECT_LT(with_tumour, 0.9 * homogeneous) << "the tumour did not stiffen the liver under the load";
  RecordProperty("depth_homogeneous_mm", std::to_string(1e3 * homogeneous));
  RecordProperty("depth_tumour_mm", std::to_string(1e3 * with_tumour));
  // Dynamic, 1 s at 1 kHz.
  auto model = compile_model(load_scenario(write_temp("td.yaml", tumour_yaml(mesh, true, true))));
  State s = State::initial(*model);
  TickWorkspace w(*model);
  double max_disp = 0;
  for (int k = 0; k < 1000; ++k) {
    const TickReport& r = tick(*model, s, w, nullptr, 0);
    ASSERT_NE(r.status, TickStatus::NonFinite) << "tick " << k;
  }
  for (int32_t i = 0; i < model->fem.num_nodes; ++i)
    for (int c = 0; c < 3; ++c) max_disp = std::max(max_disp, std::abs(s.tissue.x[3 * i + c] - model->fem.rest[3 * i + c]));
  EXPECT_LT(max_disp, 0.03) << "the liver with its tumour stays in place";
  EXPECT_LT(w.stepper().kinetic_energy(s.tissue), 1e-6) << "at rest after 1 s";
}

// Damage thresholds per region: only the tumour has a damage model (thresholds far below the
// stresses the press makes), so under the load only tumour tetrahedra are damaged, and some are.
TEST(Regions, DamageThresholdsPerRegion) {
  const std::string mesh = write_temp("tumour_liver_d.msh", "");
  tumour_liver_msh(mesh, {-0.0375, 0.095, 0.0125}, 0.022);
  auto model = compile_model(load_scenario(write_temp(
      "tumour_damage.yaml", tumour_yaml(mesh, true, true, ", damage: {measure: von_mises, onset: 5, rupture: 1.0e6}"))));
  ASSERT_TRUE(model->has_damage);
  ASSERT_FALSE(model->body_damage[0].enabled);
  ASSERT_EQ(model->region_damage.size(), 1u);
  State s = State::initial(*model);
  TickWorkspace w(*model);
  for (int k = 0; k < 200; ++k) ASSERT_NE(tick(*model, s, w, nullptr, 0).status, TickStatus::NonFinite);
  int damaged = 0, outside = 0;
  for (size_t e = 0; e < s.damage_level.size(); ++e) {
    if (s.damage_level[e] == 0) continue;
    ++damaged;
    outside += model->element_region_damage[e] < 0;
  }
  EXPECT_GT(damaged, 0) << "the tumour's thresholds are far below its stress";
  EXPECT_EQ(outside, 0) << "elements outside the tumour have no damage model";
}
