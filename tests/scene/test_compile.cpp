// compile_model: everything that can only be checked once the meshes are read — selections,
// probes, material ranges — fails with the scenario file, line and field.

#include <gtest/gtest.h>

#include <string>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "scene/starter_scenario.hpp"
#include "tissue/input_error.hpp"

using namespace stroma;

namespace {

const std::string kMeshDir = std::string(STROMA_SOURCE_DIR) + "/scenarios/meshes";

std::string beam_scenario(const std::string& fixed, const std::string& probe_point) {
  return "name: t\n"                                                              // 1
         "bodies:\n"                                                              // 2
         "  - name: beam\n"                                                       // 3
         "    mesh: beam_tet4_h5p000mm.msh\n"                                     // 4
         "    material: {young_modulus: 1.0e7, poisson_ratio: 0.3, density: 1000}\n"  // 5
         "    fixed:\n"                                                           // 6
         "      - " + fixed + "\n"                                                // 7
         "probes:\n"                                                              // 8
         "  - {name: tip, body: beam, point: " + probe_point + "}\n";             // 9
}

void expect_compile_error(const std::string& yaml, int line, const std::string& field,
                          const std::string& words) {
  const ScenarioSpec spec = parse_scenario(yaml, "t.yaml", kMeshDir);
  try {
    compile_model(spec);
    FAIL() << "expected an InputError mentioning " << words;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "t.yaml");
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_EQ(e.field(), field) << e.what();
    EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
  }
}

}  // namespace

TEST(Compile, BoxSelectingNoNodeIsAnError) {
  expect_compile_error(beam_scenario("box: {min: [5, 5, 5], max: [6, 6, 6]}", "[0.1, 0.005, 0.005]"), 7,
                       "bodies[0].fixed[0].box", "selects no node");
}

// A tool's rest pose (`pose:`) outside its workspace is an error at the tool's line; without a
// pose, the tool rests where its script starts (every front end reports it before a command).
TEST(Compile, ARestPoseOutsideTheWorkspaceIsAnErrorAndTheScriptStartIsTheDefault) {
  const std::string base = beam_scenario("nodes: [0]", "[0.1, 0.005, 0.005]") + "tools:\n";
  expect_compile_error(base + "  - name: probe\n    workspace: {min: [0, 0, 0], max: [1, 1, 1]}\n"
                              "    pose: {position: [0.5, 2, 0.5]}\n",
                       11, "tools[0].pose", "position[1] = 2 is outside the tool's workspace");
  const std::string script = std::string(STROMA_SOURCE_DIR) + "/scenarios/trajectories/liver_press.yaml";
  const CompiledScenario sc =
      compile_scenario(parse_scenario(base + "  - name: probe\n    script: " + script + "\n", "t.yaml", kMeshDir));
  EXPECT_EQ(sc.model->tools[0].rest_pose.position, sc.tool_scripts[0].keys.front().pose.position);
  EXPECT_EQ(State::initial(*sc.model).tools[0].pose.position, sc.tool_scripts[0].keys.front().pose.position);
}

TEST(Compile, NodeIndexOutOfRangeIsAnError) {
  expect_compile_error(beam_scenario("nodes: [0, 191]", "[0.1, 0.005, 0.005]"), 7,
                       "bodies[0].fixed[0].nodes", "node 191 is out of range");
}

TEST(Compile, ProbeFarOutsideTheBodyIsAnError) {
  expect_compile_error(beam_scenario("nodes: [0]", "[1.0, 0.005, 0.005]"), 9, "probes[0].point",
                       "outside body 'beam'");
}

TEST(Compile, MissingMeshNamesTheMeshLine) {
  std::string yaml = beam_scenario("nodes: [0]", "[0.1, 0.005, 0.005]");
  yaml.replace(yaml.find("beam_tet4_h5p000mm.msh"), 22, "nope.msh");
  expect_compile_error(yaml, 4, "bodies[0].mesh", "cannot open");
}

TEST(Compile, ProbeJustOutsideUsesTheNearestTetrahedron) {
  // 0.1 mm beyond the tip face: projected onto the face, weights non-negative and summing to 1.
  const ScenarioSpec spec = parse_scenario(beam_scenario("nodes: [0]", "[0.1001, 0.005, 0.005]"),
                                           "t.yaml", kMeshDir);
  auto m = compile_model(spec);
  const BarycentricPoint& w = m->probes.at(0).where;
  EXPECT_NEAR(w.distance, 1e-4, 1e-9);
  double sum = 0;
  for (double x : w.w) {
    EXPECT_GE(x, -1e-12);
    sum += x;
  }
  EXPECT_NEAR(sum, 1.0, 1e-12);
  const Vec3 p = probe_position(*m, State::initial(*m), m->probes[0]);
  EXPECT_NEAR(p[0], 0.1, 1e-12);
  EXPECT_NEAR(p[1], 0.005, 1e-12);
  EXPECT_NEAR(p[2], 0.005, 1e-12);
}

TEST(Compile, ProbeInsideInterpolatesAffineFieldsExactly) {
  // Barycentric interpolation reproduces any affine displacement field exactly.
  const ScenarioSpec spec = parse_scenario(beam_scenario("nodes: [0]", "[0.0373, 0.0041, 0.0077]"),
                                           "t.yaml", kMeshDir);
  auto m = compile_model(spec);
  State s = State::initial(*m);
  auto field = [](const double* X, int k) { return 1e-3 * (0.3 * X[0] - 0.7 * X[1] + 0.2 * X[2]) + 1e-4 * k; };
  for (int32_t i = 0; i < m->fem.num_nodes; ++i)
    for (int k = 0; k < 3; ++k) s.tissue.x[3 * i + k] += field(&m->fem.rest[3 * i], k);
  const Vec3 d = probe_displacement(*m, s, m->probes[0]);
  const double X[3] = {0.0373, 0.0041, 0.0077};
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(d[k], field(X, k), 1e-15);
  EXPECT_EQ(m->probes[0].where.distance, 0.0);
}

TEST(Compile, NodalLoadIsSplitOverTheSelection) {
  std::string yaml = beam_scenario("nodes: [0]", "[0.1, 0.005, 0.005]");
  yaml.replace(yaml.find("probes:"), 0,
               "    loads:\n      - box: {min: [0.0999, -1, -1], max: [1, 1, 1]}\n        force: [0, -2, 0]\n");
  ScenarioSpec spec = parse_scenario(yaml, "t.yaml", kMeshDir);
  spec.gravity = {0, 0, 0};
  auto m = compile_model(spec);
  double fy = 0;
  int loaded = 0;
  for (int32_t i = 0; i < m->fem.num_nodes; ++i)
    if (m->fem.f_ext[3 * i + 1] != 0) {
      fy += m->fem.f_ext[3 * i + 1];
      ++loaded;
      EXPECT_GE(m->fem.rest[3 * i], 0.0999);
    }
  EXPECT_NEAR(fy, -2.0, 1e-12);
  EXPECT_GT(loaded, 4);
}

// A fully fixed body costs only its surface: its elements stay out of the matrix pattern (each of
// its nodes keeps just its diagonal block), so CG products do not walk blocks that can only hold
// zeros. The moving body's pattern is what it would be alone.
TEST(Compile, FullyFixedBodyKeepsOnlyDiagonalBlocks) {
  const ScenarioSpec both = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/drop_on_block.yaml");
  ScenarioSpec bar_only = both;
  bar_only.bodies.erase(bar_only.bodies.begin());
  bar_only.probes.clear();
  bar_only.body_contact.reset();
  const auto m = compile_model(both);
  const auto b = compile_model(bar_only);
  const BodyRange& block = m->fem.bodies[0];
  const int32_t block_nodes = block.node_end - block.node_begin;
  for (int32_t i = block.node_begin; i < block.node_end; ++i)
    ASSERT_EQ(m->fem.pattern.row_ptr[i + 1] - m->fem.pattern.row_ptr[i], 1) << "block node " << i;
  EXPECT_EQ(m->fem.pattern.nnzb(), b->fem.pattern.nnzb() + block_nodes);
}

// `surface:` selects the nodes of the boundary faces facing a direction. On the beam (a box
// 0.1 × 0.01 × 0.01 m) the faces facing −y within 45° are exactly its lower face: every node at
// y = 0 and no other; with a box, the intersection; a direction no face meets is an error.
TEST(Compile, SurfaceSelectsTheBoundaryFacesFacingTheDirection) {
  auto fixed_nodes = [](const std::string& sel) {
    ScenarioSpec spec = parse_scenario(beam_scenario(sel, "[0.1, 0.005, 0.005]"), "t.yaml", kMeshDir);
    auto m = compile_model(spec);
    std::vector<int32_t> out;
    for (int32_t i = 0; i < m->fem.num_nodes; ++i)
      if (m->fem.constrained[i] == 7) out.push_back(i);
    return std::make_pair(out, m);
  };
  const auto [lower, m] = fixed_nodes("surface: {normal: [0, -1, 0], max_angle: 45}");
  int on_face = 0;
  for (int32_t i = 0; i < m->fem.num_nodes; ++i) on_face += std::abs(m->fem.rest[3 * i + 1]) < 1e-12;
  EXPECT_EQ(static_cast<int>(lower.size()), on_face);
  EXPECT_GT(on_face, 10);
  for (int32_t i : lower) EXPECT_NEAR(m->fem.rest[3 * i + 1], 0.0, 1e-12) << "node " << i;
  // The normal need not be unit length; a box restricts the selection to its inside.
  const auto [half, m2] = fixed_nodes("{surface: {normal: [0, -5, 0], max_angle: 45}, box: {min: [-1, -1, -1], max: [0.05, 1, 1]}}");
  EXPECT_GT(half.size(), 2u);
  EXPECT_LT(half.size(), lower.size());
  for (int32_t i : half) {
    EXPECT_NEAR(m2->fem.rest[3 * i + 1], 0.0, 1e-12);
    EXPECT_LE(m2->fem.rest[3 * i], 0.05);
  }
  // Beyond 90° the side faces (normals ⟂ y) join: more nodes than the lower face alone.
  EXPECT_GT(fixed_nodes("surface: {normal: [0, -1, 0], max_angle: 91}").first.size(), lower.size());
  expect_compile_error(beam_scenario("surface: {normal: [1, 1, 1], max_angle: 10}", "[0.1, 0.005, 0.005]"), 7,
                       "bodies[0].fixed[0].surface", "no boundary face");
  expect_compile_error(beam_scenario("{surface: {normal: [0, -1, 0]}, box: {min: [-1, 0.5, -1], max: [1, 1, 1]}}",
                                     "[0.1, 0.005, 0.005]"),
                       7, "bodies[0].fixed[0]", "with the surface condition");
}

// The starter scenario of `stroma mesh --scenario` warns when its mesh is far beyond what one
// core steps at 1 kHz (issue 41 §8: a 573,000-element mesh could not step 200 ticks in 90 s),
// in the YAML and through real_time_warning; a mesh within reach gets no warning.
TEST(StarterScenario, AMeshFarBeyondRealTimeIsWarnedAbout) {
  TetMesh small;
  small.nodes = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  small.tets.assign(static_cast<size_t>(kRealTimeTets), Tet{0, 1, 2, 3});
  StarterScenarioSpec spec;
  spec.name = "m";
  spec.mesh_path = "m.msh";
  EXPECT_EQ(real_time_warning(small.tets.size()), "");
  EXPECT_EQ(starter_scenario_yaml(small, spec).find("WARNING"), std::string::npos);
  TetMesh big = small;
  big.tets.assign(static_cast<size_t>(kFarBeyondRealTime * kRealTimeTets + 1), Tet{0, 1, 2, 3});
  const std::string w = real_time_warning(big.tets.size());
  EXPECT_NE(w.find("slower than real time"), std::string::npos) << w;
  EXPECT_NE(w.find("--tets 5000"), std::string::npos) << w;
  EXPECT_NE(starter_scenario_yaml(big, spec).find("# WARNING: " + w), std::string::npos);
}
