// Rigid bodies in scenarios (issue 42, first slice): `rigid_bodies:` loaded with every error at
// its line and field, compiled (mass properties, the body frame at the centre of mass), held in
// the State, stepped by the tick with the tissue (free bodies under gravity: the implicit
// Euler's exact discrete fall; a fixed one stays), carried bit for bit through a snapshot.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>

#include "engine/state.hpp"
#include "engine/state_bytes.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/input_error_message.hpp"

using namespace stroma;
using stroma::test_support::message_of;

namespace {

const std::string kBeam = std::string(STROMA_SOURCE_DIR) + "/scenarios/meshes/beam_tet4_h3p333mm.msh";

std::string scenario(const std::string& rigid, const std::string& solver = "") {
  return R"(name: rigid
time_step: 0.001
gravity: [0, 0, -9.81]
)" + solver + R"(bodies:
  - name: beam
    mesh: )" + kBeam + R"(
    material: {young_modulus: 1.0e5, poisson_ratio: 0.45, density: 1000}
    fixed:
      - box: {min: [-1.0e-6, -1, -1], max: [1.0e-6, 1, 1]}
rigid_bodies:
)" + rigid;
}

std::shared_ptr<const Model> model_of(const std::string& yaml) {
  return compile_model(parse_scenario(yaml, "rigid.yaml", STROMA_SOURCE_DIR));
}

const char* kTwoBodies = R"(  - name: ball
    shape: {type: sphere, radius: 0.005}
    density: 7800
    pose: {position: [0.5, 0, 1.0]}
    velocity: {linear: [0.1, 0, 0.2], angular: [0, 3, 0]}
  - name: table
    shape: {type: box, size: [0.2, 0.2, 0.01]}
    density: 1000
    pose: {position: [0.5, 0, 0.0], orientation: [0.9238795325, 0, 0, 0.3826834324]}
    fixed: true
)";

}  // namespace

TEST(RigidBodies, AFreeBodyFallsAsTheImplicitEulerSaysAndAFixedOneStays) {
  const auto m = model_of(scenario(kTwoBodies));
  ASSERT_EQ(m->rigid_bodies.size(), 2u);
  const RigidBodyModel& ball = m->rigid_bodies[0];
  EXPECT_NEAR(ball.mass.mass, 7800 * 4.0 / 3.0 * M_PI * 1.25e-7, 1e-12);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const int n = 300;
  for (int k = 0; k < n; ++k) ASSERT_EQ(tick(*m, s, w).status, TickStatus::Ok) << k;
  const double h = 0.001, t = n * h;
  EXPECT_NEAR(s.rigid[0].x[0], 0.5 + 0.1 * t, 1e-12);
  EXPECT_NEAR(s.rigid[0].x[2], 1.0 + 0.2 * t - 9.81 * h * h * n * (n + 1) / 2.0, 1e-12);
  EXPECT_NEAR(s.rigid[0].v[2], 0.2 - 9.81 * t, 1e-12);
  // A sphere's spin about any axis is steady: it has turned by 3 t about y.
  const auto R = rotation_of(s.rigid[0].q);
  EXPECT_NEAR(std::atan2(R[2], R[0]), 3 * t, 1e-9);
  EXPECT_EQ(s.rigid[1].x, m->rigid_bodies[1].initial.x);
  EXPECT_EQ(s.rigid[1].q, m->rigid_bodies[1].initial.q);
}

TEST(RigidBodies, ASnapshotCarriesThemBitForBit) {
  const auto m = model_of(scenario(kTwoBodies));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  for (int k = 0; k < 100; ++k) tick(*m, s, w);
  const std::string bytes = encode_state(s, model_fingerprint(*m));
  for (int k = 0; k < 50; ++k) tick(*m, s, w);
  uint64_t fp = 0;
  State r = decode_state(bytes, &fp);
  EXPECT_EQ(fp, model_fingerprint(*m));
  std::string why;
  ASSERT_TRUE(state_fits_model(r, *m, &why)) << why;
  TickWorkspace w2(*m);
  for (int k = 0; k < 50; ++k) tick(*m, r, w2);
  ASSERT_EQ(r.rigid.size(), s.rigid.size());
  for (size_t i = 0; i < s.rigid.size(); ++i) {
    EXPECT_EQ(r.rigid[i].x, s.rigid[i].x);
    EXPECT_EQ(r.rigid[i].q, s.rigid[i].q);
    EXPECT_EQ(r.rigid[i].v, s.rigid[i].v);
    EXPECT_EQ(r.rigid[i].w, s.rigid[i].w);
  }
  // A model with another rigid body has another fingerprint.
  const auto other = model_of(scenario(std::string(kTwoBodies).replace(std::string(kTwoBodies).find("7800"), 4, "7900")));
  EXPECT_NE(model_fingerprint(*other), model_fingerprint(*m));
}

TEST(RigidBodies, AMeshBodyHasItsFrameAtItsCentreOfMass) {
  // A closed tetrahedron whose centroid is not at its file's origin.
  const std::string obj = testing::TempDir() + "rigid_tet.obj";
  {
    std::ofstream f(obj);
    f << "v 0 0 0\nv 0.03 0 0\nv 0 0.03 0\nv 0 0 0.03\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
  }
  const auto m = model_of(scenario("  - name: wedge\n    shape: {type: mesh, file: " + obj +
                                   "}\n    density: 1000\n    pose: {position: [1, 2, 3]}\n"));
  const RigidBodyModel& b = m->rigid_bodies.at(0);
  EXPECT_NEAR(b.mass.volume, 0.03 * 0.03 * 0.03 / 6, 1e-15);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(b.shape_origin[size_t(k)], -0.0075, 1e-12);        // the centroid (0.0075, …) of the file
    EXPECT_NEAR(b.initial.x[size_t(k)], (k + 1) + 0.0075, 1e-12);  // posed at the file's origin
  }
  double c[3] = {0, 0, 0};
  for (const Vec3& v : b.surface_vertices)
    for (int k = 0; k < 3; ++k) c[k] += v[size_t(k)] / 4;
  for (double x : c) EXPECT_NEAR(x, 0.0, 1e-12);
}

TEST(RigidBodies, BadEntriesAreRefusedAtTheirLineAndField) {
  struct Case {
    std::string rigid, solver, want;
  };
  const std::vector<Case> cases = {
      {"  - {name: a, shape: {type: cone, radius: 0.01}, density: 1000}\n", "", "unknown type 'cone'"},
      {"  - {name: a, shape: {type: sphere, radius: 0.01}, density: -5}\n", "", "rigid_bodies[0].density"},
      {"  - {name: a, shape: {type: sphere, radius: 0.01, size: [1, 1, 1]}, density: 1000}\n", "", "a sphere has no size"},
      {"  - {name: a, shape: {type: box, size: [0.1, 0, 0.1]}, density: 1000}\n", "", "box sizes must be within"},
      {"  - {name: a, shape: {type: sphere, radius: 0.01}, density: 1000}\n  - {name: a, shape: {type: sphere, radius: 0.01}, "
       "density: 1000}\n", "", "duplicate rigid body name 'a'"},
      {"  - {name: beam, shape: {type: sphere, radius: 0.01}, density: 1000}\n", "", "already the name of a tissue body"},
      {"  - {name: a, shape: {type: sphere, radius: 0.01}, density: 1000, pose: {orientation: [1, 1, 0, 0]}}\n", "",
       "unit quaternion"},
      {"  - {name: a, shape: {type: sphere, radius: 0.01}, density: 1000, fixed: true, velocity: {linear: [1, 0, 0]}}\n", "",
       "a fixed body does not move"},
      {"  - {name: a, shape: {type: sphere, radius: 0.01}, density: 1000}\n", "solver: {integrator: static}\n",
       "rigid bodies move"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.rigid);
    const std::string m = message_of([&] { model_of(scenario(c.rigid, c.solver)); });
    EXPECT_NE(m.find(c.want), std::string::npos) << m;
    EXPECT_NE(m.find("rigid.yaml:"), std::string::npos) << m;
  }
  // An open surface names its boundary edges.
  const std::string obj = testing::TempDir() + "rigid_open.obj";
  {
    std::ofstream f(obj);
    f << "v 0 0 0\nv 0.03 0 0\nv 0 0.03 0\nv 0 0 0.03\nf 1 3 2\nf 1 2 4\nf 1 4 3\n";
  }
  const std::string m =
      message_of([&] { model_of(scenario("  - {name: a, shape: {type: mesh, file: " + obj + "}, density: 1000}\n")); });
  EXPECT_NE(m.find("rigid_bodies[0].shape.file"), std::string::npos) << m;
  EXPECT_NE(m.find("boundary edges"), std::string::npos) << m;
}
