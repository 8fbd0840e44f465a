// Tests for the scenario loader (scene/scenario_loader.cpp): a full valid scenario, defaults,
// path resolution, and every kind of input error with its exact line, field path and message.

#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <string>

#include <unistd.h>

#include "scene/scenario_spec.hpp"
#include "tissue/input_error.hpp"

namespace stroma {
namespace {

namespace fs = std::filesystem;

constexpr const char* kFile = "scenes/test.yaml";
constexpr const char* kBase = "/data/scenes";

// A complete scenario, every key set to a non-default value. Line numbers are referenced below.
const std::string kFull = R"(name: cantilever
time_step: 0.002
gravity: [0, -9.81, 1.5]
solver:
  integrator: symplectic_euler
  linear_solver: cholmod
  preconditioner: block_jacobi
  max_iterations: 321
  tolerance: 1.0e-8
  warm_start: false
  static_tolerance: 1.0e-9
  static_max_newton: 17
bodies:
  - name: beam
    mesh: meshes/beam.msh
    scale: 0.001
    material:
      model: linear
      rotation: qr
      young_modulus: 1.0e7
      poisson_ratio: 0.3
      density: 1000
      rayleigh_mass: 0.1
      rayleigh_stiffness: 0.002
    fixed:
      - box: {min: [-1.0e-6, -1, -1], max: [1.0e-6, 1, 1]}
      - nodes: [0, 5, 7]
    loads:
      - box: {min: [0.09, 0, 0], max: [0.1, 0.01, 0.01]}
        force: [0, -1, 0]
        per_node: true
      - nodes: [3]
        force: [1, 2, 3]
  - name: plate
    mesh: /abs/plate.msh
    material:
      young_modulus: 5000
      poisson_ratio: -0.2
      density: 1100
probes:
  - name: tip
    body: beam
    point: [0.1, 0.005, 0.005]
  - name: corner
    body: plate
    point: [0, 0, 0]
run:
  steps: 500
check:
  max_error: 1.0e-7
  mean_error: 1.0e-8
)";

// The smallest valid scenario. Lines: 1 name, 2 bodies, 3 - name, 4 mesh, 5 material,
// 6 young_modulus, 7 poisson_ratio, 8 density.
const std::string kMinimal = R"(name: minimal
bodies:
  - name: beam
    mesh: beam.msh
    material:
      young_modulus: 1.0e7
      poisson_ratio: 0.3
      density: 1000
)";

/// `text` with the single occurrence of `from` replaced by `to` (fails the test if absent).
std::string replace(std::string text, const std::string& from, const std::string& to) {
  const auto pos = text.find(from);
  EXPECT_NE(pos, std::string::npos) << "test bug: '" << from << "' not in the scenario";
  if (pos != std::string::npos) text.replace(pos, from.size(), to);
  return text;
}

ScenarioSpec parse(const std::string& text) { return parse_scenario(text, kFile, kBase); }

/// Parses `text`, expecting an InputError at `line` on `field` whose message contains every
/// one of `words`.
void expect_error(const std::string& text, int line, const std::string& field,
                  std::initializer_list<std::string> words) {
  try {
    parse(text);
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), kFile) << e.what();
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_EQ(e.field(), field) << e.what();
    for (const auto& w : words)
      EXPECT_NE(e.message().find(w), std::string::npos)
          << "message lacks '" << w << "': " << e.what();
    return;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected InputError, got another exception: " << e.what();
    return;
  }
  ADD_FAILURE() << "expected an InputError at line " << line << " on " << field
                << ", but the scenario was accepted";
}

/// A scratch directory, removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    path_ = fs::temp_directory_path() /
            ("stroma_scenario_test_" + std::to_string(::getpid()) + "_" +
             std::to_string(counter++));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

void write_file(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << "cannot write " << p;
}

// ---------------------------------------------------------------------------------------------
// Valid input

TEST(ScenarioLoader, FullScenarioEveryField) {
  const ScenarioSpec s = parse(kFull);
  EXPECT_EQ(s.name, "cantilever");
  EXPECT_EQ(s.file, kFile);
  EXPECT_DOUBLE_EQ(s.time_step, 0.002);
  EXPECT_EQ(s.gravity, (Vec3{0, -9.81, 1.5}));

  EXPECT_EQ(s.solver.integrator, Integrator::SymplecticEuler);
  EXPECT_EQ(s.solver.linear_solver, LinearSolverKind::Cholmod);
  EXPECT_EQ(s.solver.preconditioner, Preconditioner::BlockJacobi);
  EXPECT_EQ(s.solver.max_iterations, 321);
  EXPECT_DOUBLE_EQ(s.solver.tolerance, 1.0e-8);
  EXPECT_EQ(s.solver.warm_start, WarmStart::Off);
  EXPECT_DOUBLE_EQ(s.solver.static_tolerance, 1.0e-9);
  EXPECT_EQ(s.solver.static_max_newton, 17);

  ASSERT_EQ(s.bodies.size(), 2u);
  const BodySpec& beam = s.bodies[0];
  EXPECT_EQ(beam.name, "beam");
  EXPECT_EQ(beam.mesh_path, "/data/scenes/meshes/beam.msh");
  EXPECT_DOUBLE_EQ(beam.scale, 0.001);
  EXPECT_EQ(beam.where.file, kFile);
  EXPECT_EQ(beam.where.line, 14);

  const MaterialSpec& m = beam.material;
  EXPECT_EQ(m.model, ElementModel::Linear);
  EXPECT_EQ(m.rotation, RotationMethod::QR);
  EXPECT_DOUBLE_EQ(m.young_modulus, 1.0e7);
  EXPECT_DOUBLE_EQ(m.poisson_ratio, 0.3);
  EXPECT_DOUBLE_EQ(m.density, 1000);
  EXPECT_DOUBLE_EQ(m.rayleigh_mass, 0.1);
  EXPECT_DOUBLE_EQ(m.rayleigh_stiffness, 0.002);
  EXPECT_EQ(m.where.file, kFile);
  EXPECT_EQ(m.where.line, 17);

  ASSERT_EQ(beam.fixed.size(), 2u);
  ASSERT_TRUE(beam.fixed[0].box.has_value());
  EXPECT_EQ(beam.fixed[0].box->min, (Vec3{-1.0e-6, -1, -1}));
  EXPECT_EQ(beam.fixed[0].box->max, (Vec3{1.0e-6, 1, 1}));
  EXPECT_TRUE(beam.fixed[0].nodes.empty());
  EXPECT_EQ(beam.fixed[0].where.line, 26);
  EXPECT_FALSE(beam.fixed[1].box.has_value());
  EXPECT_EQ(beam.fixed[1].nodes, (std::vector<int>{0, 5, 7}));
  EXPECT_EQ(beam.fixed[1].where.line, 27);
  EXPECT_EQ(beam.fixed[1].where.file, kFile);

  ASSERT_EQ(beam.loads.size(), 2u);
  ASSERT_TRUE(beam.loads[0].select.box.has_value());
  EXPECT_EQ(beam.loads[0].select.box->min, (Vec3{0.09, 0, 0}));
  EXPECT_EQ(beam.loads[0].select.box->max, (Vec3{0.1, 0.01, 0.01}));
  EXPECT_EQ(beam.loads[0].select.where.line, 29);
  EXPECT_EQ(beam.loads[0].force, (Vec3{0, -1, 0}));
  EXPECT_TRUE(beam.loads[0].per_node);
  EXPECT_FALSE(beam.loads[1].select.box.has_value());
  EXPECT_EQ(beam.loads[1].select.nodes, (std::vector<int>{3}));
  EXPECT_EQ(beam.loads[1].select.where.line, 32);
  EXPECT_EQ(beam.loads[1].force, (Vec3{1, 2, 3}));
  EXPECT_FALSE(beam.loads[1].per_node);

  const BodySpec& plate = s.bodies[1];
  EXPECT_EQ(plate.name, "plate");
  EXPECT_EQ(plate.mesh_path, "/abs/plate.msh");
  EXPECT_DOUBLE_EQ(plate.scale, 1.0);
  EXPECT_EQ(plate.where.line, 34);
  EXPECT_EQ(plate.material.model, ElementModel::Corotational);
  EXPECT_EQ(plate.material.rotation, RotationMethod::Polar);
  EXPECT_DOUBLE_EQ(plate.material.young_modulus, 5000);
  EXPECT_DOUBLE_EQ(plate.material.poisson_ratio, -0.2);
  EXPECT_DOUBLE_EQ(plate.material.density, 1100);
  EXPECT_TRUE(plate.fixed.empty());
  EXPECT_TRUE(plate.loads.empty());

  ASSERT_EQ(s.probes.size(), 2u);
  EXPECT_EQ(s.probes[0].name, "tip");
  EXPECT_EQ(s.probes[0].body, "beam");
  EXPECT_EQ(s.probes[0].point, (Vec3{0.1, 0.005, 0.005}));
  EXPECT_EQ(s.probes[0].where.file, kFile);
  EXPECT_EQ(s.probes[0].where.line, 41);
  EXPECT_EQ(s.probes[1].name, "corner");
  EXPECT_EQ(s.probes[1].body, "plate");
  EXPECT_EQ(s.probes[1].where.line, 44);

  EXPECT_FALSE(s.run.duration.has_value());
  ASSERT_TRUE(s.run.steps.has_value());
  EXPECT_EQ(*s.run.steps, 500);
  EXPECT_DOUBLE_EQ(s.check.max_error, 1.0e-7);
  EXPECT_DOUBLE_EQ(s.check.mean_error, 1.0e-8);
}

TEST(ScenarioLoader, DefaultsWhenOmitted) {
  const ScenarioSpec s = parse(kMinimal);
  const ScenarioSpec d;  // the documented defaults
  EXPECT_EQ(s.name, "minimal");
  EXPECT_DOUBLE_EQ(s.time_step, 0.001);
  EXPECT_EQ(s.gravity, (Vec3{0, -9.81, 0}));
  EXPECT_EQ(s.solver.integrator, Integrator::ImplicitEuler);
  EXPECT_EQ(s.solver.linear_solver, LinearSolverKind::CG);
  EXPECT_FALSE(s.solver.preconditioner.has_value()) << "auto: the engine chooses (tissue/solver_choice.hpp)";
  EXPECT_EQ(s.solver.max_iterations, d.solver.max_iterations);
  EXPECT_DOUBLE_EQ(s.solver.tolerance, d.solver.tolerance);
  EXPECT_EQ(s.solver.warm_start, WarmStart::Extrapolate);
  EXPECT_DOUBLE_EQ(s.solver.static_tolerance, d.solver.static_tolerance);
  EXPECT_EQ(s.solver.static_max_newton, d.solver.static_max_newton);
  ASSERT_EQ(s.bodies.size(), 1u);
  EXPECT_DOUBLE_EQ(s.bodies[0].scale, 1.0);
  EXPECT_EQ(s.bodies[0].material.model, ElementModel::Corotational);
  EXPECT_EQ(s.bodies[0].material.rotation, RotationMethod::Polar);
  EXPECT_DOUBLE_EQ(s.bodies[0].material.rayleigh_mass, 0.0);
  EXPECT_DOUBLE_EQ(s.bodies[0].material.rayleigh_stiffness, 0.0);
  EXPECT_TRUE(s.bodies[0].fixed.empty());
  EXPECT_TRUE(s.bodies[0].loads.empty());
  EXPECT_TRUE(s.probes.empty());
  EXPECT_FALSE(s.run.duration.has_value());
  EXPECT_FALSE(s.run.steps.has_value());
  EXPECT_DOUBLE_EQ(s.check.max_error, 1.0e-9);
  EXPECT_DOUBLE_EQ(s.check.mean_error, 1.0e-10);
  // Defaults inside a present-but-partial section.
  const ScenarioSpec p = parse(kMinimal + "solver:\n  integrator: static\n");
  EXPECT_EQ(p.solver.integrator, Integrator::Static);
  EXPECT_EQ(p.solver.max_iterations, d.solver.max_iterations);
  EXPECT_EQ(p.solver.warm_start, WarmStart::Extrapolate);
  // The cap policy is auto by default (compile resolves it); substep and continue are kept.
  EXPECT_EQ(s.solver.on_cg_cap, CapPolicy::Auto);
  EXPECT_EQ(parse(kMinimal + "solver:\n  on_cg_cap: auto\n").solver.on_cg_cap, CapPolicy::Auto);
  EXPECT_EQ(parse(kMinimal + "solver:\n  on_cg_cap: substep\n").solver.on_cg_cap, CapPolicy::Substep);
  EXPECT_EQ(parse(kMinimal + "solver:\n  on_cg_cap: continue\n").solver.on_cg_cap, CapPolicy::Continue);
  // `preconditioner: auto` is the default spelled out; a named one is kept.
  EXPECT_FALSE(parse(kMinimal + "solver:\n  preconditioner: auto\n").solver.preconditioner.has_value());
  EXPECT_EQ(parse(kMinimal + "solver:\n  preconditioner: jacobi\n").solver.preconditioner, Preconditioner::Jacobi);
}

// solver.newton_iterations: a count, or auto (the default): Newton iterations only for steps
// longer than 1 ms (the 1 kHz loop keeps the single linearised step; docs/STABILITY.md).
TEST(ScenarioLoader, NewtonIterationsAutoByDefault) {
  EXPECT_EQ(parse(kMinimal).solver.newton_iterations, 0);
  EXPECT_EQ(parse(kMinimal + "solver:\n  newton_iterations: auto\n").solver.newton_iterations, 0);
  EXPECT_EQ(parse(kMinimal + "solver:\n  newton_iterations: 3\n").solver.newton_iterations, 3);
  EXPECT_EQ(resolved_newton_iterations(0, 0.001), 1);
  EXPECT_EQ(resolved_newton_iterations(0, 0.0005), 1);
  EXPECT_EQ(resolved_newton_iterations(0, 0.002), kAutoNewtonLargeStep);
  EXPECT_EQ(resolved_newton_iterations(0, 0.033), kAutoNewtonLargeStep);
  EXPECT_EQ(resolved_newton_iterations(1, 0.033), 1);  // an explicit count is kept
  EXPECT_EQ(resolved_newton_iterations(6, 0.001), 6);
  expect_error(kMinimal + "solver:\n  newton_iterations: 0\n", 10, "solver.newton_iterations", {"0"});
  expect_error(kMinimal + "solver:\n  newton_iterations: sometimes\n", 10, "solver.newton_iterations",
               {"whole number >= 1 or auto", "'sometimes'"});
  expect_error(kMinimal + "solver:\n  newton_iterations: [4]\n", 10, "solver.newton_iterations",
               {"whole number >= 1 or auto", "a list"});
}

// solver.preconditioner_refresh: steps between refreshes of the warped factor, auto (the
// default, -1) or off (0).
TEST(ScenarioLoader, PreconditionerRefresh) {
  EXPECT_EQ(parse(kMinimal).solver.preconditioner_refresh, -1);
  EXPECT_EQ(parse(kMinimal + "solver:\n  preconditioner_refresh: auto\n").solver.preconditioner_refresh, -1);
  EXPECT_EQ(parse(kMinimal + "solver:\n  preconditioner_refresh: off\n").solver.preconditioner_refresh, 0);
  EXPECT_EQ(parse(kMinimal + "solver:\n  preconditioner_refresh: 25\n").solver.preconditioner_refresh, 25);
  expect_error(kMinimal + "solver:\n  preconditioner_refresh: 0\n", 10, "solver.preconditioner_refresh", {"0"});
  expect_error(kMinimal + "solver:\n  preconditioner_refresh: often\n", 10, "solver.preconditioner_refresh",
               {"whole number of steps >= 1, auto or off", "'often'"});
  expect_error(kMinimal + "solver:\n  preconditioner_refresh: 2.5\n", 10, "solver.preconditioner_refresh",
               {"whole number of steps"});
}

// solver.stiffness_every: the elements' stiffness made every N implicit steps (1, the default:
// every step).
TEST(ScenarioLoader, StiffnessEvery) {
  EXPECT_EQ(parse(kMinimal).solver.stiffness_every, 1);
  EXPECT_EQ(parse(kMinimal + "solver:\n  stiffness_every: 3\n").solver.stiffness_every, 3);
  expect_error(kMinimal + "solver:\n  stiffness_every: 0\n", 10, "solver.stiffness_every", {"0"});
  expect_error(kMinimal + "solver:\n  stiffness_every: often\n", 10, "solver.stiffness_every",
               {"whole number of steps >= 1", "'often'"});
  expect_error(kMinimal + "solver:\n  stiffness_every: 1.5\n", 10, "solver.stiffness_every",
               {"whole number of steps"});
}

TEST(ScenarioLoader, RunDuration) {
  const ScenarioSpec s = parse(kMinimal + "run:\n  duration: 0.5\n");
  ASSERT_TRUE(s.run.duration.has_value());
  EXPECT_DOUBLE_EQ(*s.run.duration, 0.5);
  EXPECT_FALSE(s.run.steps.has_value());
}

TEST(ScenarioLoader, MeshPathResolution) {
  const std::string rel = replace(kMinimal, "mesh: beam.msh", "mesh: ./sub/../meshes/beam.msh");
  EXPECT_EQ(parse_scenario(rel, kFile, "/data/scenes").bodies[0].mesh_path,
            "/data/scenes/meshes/beam.msh");
  EXPECT_EQ(parse_scenario(rel, kFile, "scenes").bodies[0].mesh_path, "scenes/meshes/beam.msh");
  EXPECT_EQ(parse_scenario(rel, kFile, "").bodies[0].mesh_path, "meshes/beam.msh");
  const std::string up = replace(kMinimal, "mesh: beam.msh", "mesh: ../shared/beam.msh");
  EXPECT_EQ(parse_scenario(up, kFile, "/data/scenes").bodies[0].mesh_path,
            "/data/shared/beam.msh");
  const std::string abs = replace(kMinimal, "mesh: beam.msh", "mesh: /m/beam.msh");
  EXPECT_EQ(parse_scenario(abs, kFile, "/data/scenes").bodies[0].mesh_path, "/m/beam.msh");
}

TEST(ScenarioLoader, LoadFromFileResolvesMeshNextToTheFile) {
  TempDir dir;
  const fs::path file = dir.path() / "scene.yaml";
  write_file(file, replace(kMinimal, "mesh: beam.msh", "mesh: meshes/beam.msh"));
  const ScenarioSpec s = load_scenario(file.string());
  EXPECT_EQ(s.file, file.string());
  EXPECT_EQ(s.name, "minimal");
  EXPECT_EQ(s.bodies[0].mesh_path, (dir.path() / "meshes/beam.msh").lexically_normal().string());
  EXPECT_EQ(s.bodies[0].where.file, file.string());
}

TEST(ScenarioLoader, LoadFromFileReportsErrorsWithThePath) {
  TempDir dir;
  const fs::path file = dir.path() / "bad.yaml";
  write_file(file, replace(kMinimal, "density: 1000", "density: 0"));
  try {
    load_scenario(file.string());
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), file.string());
    EXPECT_EQ(e.line(), 8);
    EXPECT_EQ(e.field(), "bodies[0].material.density");
    EXPECT_EQ(std::string(e.what()),
              file.string() + ":8: bodies[0].material.density: " + e.message());
  }
}

// ---------------------------------------------------------------------------------------------
// Files and YAML syntax

TEST(ScenarioLoaderErrors, MissingFile) {
  TempDir dir;
  const std::string path = (dir.path() / "no_such_scene.yaml").string();
  try {
    load_scenario(path);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), 0);
    EXPECT_NE(e.message().find("cannot open scenario file"), std::string::npos) << e.what();
  }
}

TEST(ScenarioLoaderErrors, DirectoryIsNotAFile) {
  TempDir dir;
  try {
    load_scenario(dir.path().string());
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(e.message().find("cannot open scenario file"), std::string::npos) << e.what();
  }
}

TEST(ScenarioLoaderErrors, YamlSyntaxErrorLine) {
  // Line 3 is indented under a scalar: yaml-cpp reports "illegal map value" there.
  expect_error("name: t\ntime_step: 0.001\n  gravity: [0, 0, 0]\n", 3, "",
               {"YAML syntax error", "illegal map value"});
  // A list item where the top-level map continues.
  expect_error("name: t\ntime_step: 0.001\n- oops\n", 3, "", {"YAML syntax error"});
}

TEST(ScenarioLoaderErrors, EmptyOrNonMapDocument) {
  expect_error("", 0, "", {"empty"});
  expect_error("# only a comment\n", 0, "", {"empty"});
  expect_error("- a\n- b\n", 1, "", {"expected a map", "got a list"});
  expect_error(kMinimal + "---\nname: second\n", 10, "", {"single YAML document"});
  // yaml-cpp 0.7's LoadAll looped for ever (allocating) on these (found by fuzz_scenario).
  expect_error(",8YAML9ExceptionEs$", 1, "", {"YAML syntax error"});
  expect_error(",\n", 1, "", {"YAML syntax error"});
  expect_error("\n\n  ,", 3, "", {"YAML syntax error"});
}

// ---------------------------------------------------------------------------------------------
// Schema: keys

TEST(ScenarioLoaderErrors, UnknownKeyWithSuggestion) {
  expect_error(replace(kMinimal, "young_modulus:", "youngs_modulus:"), 6,
               "bodies[0].material.youngs_modulus",
               {"unknown key 'youngs_modulus'", "did you mean 'young_modulus'?",
                "allowed keys: model, rotation, young_modulus, poisson_ratio, density, "
                "rayleigh_mass, rayleigh_stiffness"});
  expect_error(kMinimal + "solver:\n  integratr: static\n", 10, "solver.integratr",
               {"unknown key", "did you mean 'integrator'?"});
  expect_error("time_setp: 0.01\n" + kMinimal, 1, "time_setp",
               {"did you mean 'time_step'?"});
}

TEST(ScenarioLoaderErrors, UnknownKeyWithoutSuggestion) {
  try {
    parse(kMinimal + "solver_settings: {}\n");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 9);
    EXPECT_EQ(e.field(), "solver_settings");
    EXPECT_NE(e.message().find("unknown key 'solver_settings'"), std::string::npos);
    EXPECT_NE(e.message().find("name, time_step, gravity, solver, bodies, probes, tools, rigid_bodies, threads, body_contact, run, check"),
              std::string::npos)
        << e.message();
    EXPECT_EQ(e.message().find("did you mean"), std::string::npos) << e.message();
  }
}

TEST(ScenarioLoaderErrors, UnknownKeysAtEveryLevel) {
  expect_error(replace(kMinimal, "    mesh: beam.msh\n", "    mesh: beam.msh\n    colour: red\n"),
               5, "bodies[0].colour", {"unknown key", "allowed keys: name, mesh, scale"});
  expect_error(kMinimal + "run:\n  step: 10\n", 10, "run.step", {"did you mean 'steps'?"});
  expect_error(kMinimal + "check:\n  max_eror: 1.0e-9\n", 10, "check.max_eror",
               {"did you mean 'max_error'?"});
  expect_error(kMinimal + "probes:\n  - name: p\n    body: beam\n    pointt: [0, 0, 0]\n", 12,
               "probes[0].pointt", {"did you mean 'point'?"});
  expect_error(kMinimal + "    fixed:\n      - box: {min: [0, 0, 0], maxx: [1, 1, 1]}\n", 10,
               "bodies[0].fixed[0].box.maxx", {"did you mean 'max'?"});
  expect_error(kMinimal + "    loads:\n      - nodes: [1]\n        forse: [0, 0, 1]\n", 11,
               "bodies[0].loads[0].forse", {"did you mean 'force'?"});
}

TEST(ScenarioLoaderErrors, DuplicateYamlKey) {
  expect_error(kMinimal + "time_step: 0.01\ntime_step: 0.02\n", 10, "time_step",
               {"duplicate key 'time_step'", "first given at line 9"});
}

TEST(ScenarioLoaderErrors, MissingRequiredField) {
  // Reported on the line of the map that lacks it (here `material:`).
  expect_error(replace(kMinimal, "      density: 1000\n", ""), 5, "bodies[0].material.density",
               {"missing required field 'density'"});
  expect_error(replace(kMinimal, "      young_modulus: 1.0e7\n", ""), 5,
               "bodies[0].material.young_modulus", {"missing required field"});
  expect_error(replace(kMinimal, "      poisson_ratio: 0.3\n", ""), 5,
               "bodies[0].material.poisson_ratio", {"missing required field"});
  expect_error(replace(kMinimal, "    mesh: beam.msh\n", ""), 3, "bodies[0].mesh",
               {"missing required field 'mesh'"});
  expect_error("name: nothing\ntime_step: 0.01\n", 1, "bodies", {"missing required field"});
  expect_error(kMinimal + "    loads:\n      - nodes: [1]\n", 10, "bodies[0].loads[0].force",
               {"missing required field 'force'"});
}

TEST(ScenarioLoaderErrors, EmptyBodies) {
  expect_error("name: t\nbodies: []\n", 2, "bodies", {"at least one body"});
  expect_error("name: t\nbodies:\n", 2, "bodies", {"expected a list", "empty value"});
  expect_error("name: t\nbodies: {name: b}\n", 2, "bodies", {"expected a list", "got a map"});
}

// ---------------------------------------------------------------------------------------------
// Schema: types

TEST(ScenarioLoaderErrors, WrongTypeNumber) {
  expect_error(replace(kMinimal, "young_modulus: 1.0e7", "young_modulus: abc"), 6,
               "bodies[0].material.young_modulus", {"expected a number, got 'abc'"});
  expect_error(replace(kMinimal, "young_modulus: 1.0e7", "young_modulus: \"1.0e7\""), 6,
               "bodies[0].material.young_modulus", {"expected a number", "quoted string"});
  expect_error(replace(kMinimal, "young_modulus: 1.0e7", "young_modulus: [1, 2]"), 6,
               "bodies[0].material.young_modulus", {"expected a number, got a list"});
  expect_error(replace(kMinimal, "young_modulus: 1.0e7", "young_modulus:"), 6,
               "bodies[0].material.young_modulus", {"expected a number, got an empty value"});
  expect_error("time_step: .inf\n" + kMinimal, 1, "time_step", {"expected a number"});
  expect_error("time_step: nan\n" + kMinimal, 1, "time_step", {"expected a finite number"});
}

TEST(ScenarioLoaderErrors, WrongTypeVector) {
  expect_error("gravity: [0, -9.81]\n" + kMinimal, 1, "gravity",
               {"expected a list of 3 numbers", "got a list of 2 items"});
  expect_error("gravity: 9.81\n" + kMinimal, 1, "gravity",
               {"expected a list of 3 numbers, got '9.81'"});
  expect_error("gravity: [0, down, 0]\n" + kMinimal, 1, "gravity[1]",
               {"expected a number, got 'down'"});
  expect_error(kMinimal + "probes:\n  - name: p\n    body: beam\n    point: [0, 0, 0, 0]\n", 12,
               "probes[0].point", {"expected a list of 3 numbers", "4 items"});
}

TEST(ScenarioLoaderErrors, WrongTypeOther) {
  expect_error(kMinimal + "solver:\n  warm_start: maybe\n", 10, "solver.warm_start",
               {"unknown warm_start 'maybe'", "extrapolate", "previous", "off"});
  expect_error(kMinimal + "solver: fast\n", 9, "solver", {"expected a map", "got 'fast'"});
  expect_error(replace(kMinimal, "  - name: beam", "  - name: [a, b]"), 3, "bodies[0].name",
               {"expected a string, got a list"});
  expect_error(replace(kMinimal, "  - name: beam", "  - name: ''"), 3, "bodies[0].name",
               {"must not be empty"});
}

TEST(ScenarioLoaderErrors, NonIntegerWhereIntegerRequired) {
  expect_error(kMinimal + "solver:\n  max_iterations: 1.5\n", 10, "solver.max_iterations",
               {"expected an integer, got '1.5'"});
  expect_error(kMinimal + "solver:\n  max_iterations: many\n", 10, "solver.max_iterations",
               {"expected an integer, got 'many'"});
  expect_error(kMinimal + "solver:\n  static_max_newton: 1e2\n", 10,
               "solver.static_max_newton", {"expected an integer"});
  expect_error(kMinimal + "run:\n  steps: 2.5\n", 10, "run.steps", {"expected an integer"});
  expect_error(kMinimal + "    fixed:\n      - nodes: [0, 1.5]\n", 10,
               "bodies[0].fixed[0].nodes[1]", {"expected an integer, got '1.5'"});
  expect_error(kMinimal + "solver:\n  max_iterations: 99999999999\n", 10,
               "solver.max_iterations", {"out of range"});
}

// ---------------------------------------------------------------------------------------------
// Schema: ranges

TEST(ScenarioLoaderErrors, PoissonRatioHalfIsIncompressible) {
  try {
    parse(replace(kMinimal, "poisson_ratio: 0.3", "poisson_ratio: 0.5"));
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 7);
    EXPECT_EQ(e.field(), "bodies[0].material.poisson_ratio");
    EXPECT_EQ(e.message(),
              "poisson_ratio = 0.5 is out of range: must be > -1 and < 0.5 "
              "(0.5 is incompressible; use 0.49 or lower)");
  }
  expect_error(replace(kMinimal, "poisson_ratio: 0.3", "poisson_ratio: 0.7"), 7,
               "bodies[0].material.poisson_ratio", {"0.7 is out of range", "incompressible"});
}

TEST(ScenarioLoaderErrors, PoissonRatioAtOrBelowMinusOne) {
  expect_error(replace(kMinimal, "poisson_ratio: 0.3", "poisson_ratio: -1"), 7,
               "bodies[0].material.poisson_ratio",
               {"poisson_ratio = -1 is out of range: must be > -1 and < 0.5"});
  expect_error(replace(kMinimal, "poisson_ratio: 0.3", "poisson_ratio: -1.2"), 7,
               "bodies[0].material.poisson_ratio", {"-1.2 is out of range"});
}

TEST(ScenarioLoaderErrors, YoungModulusNotPositive) {
  expect_error(replace(kMinimal, "young_modulus: 1.0e7", "young_modulus: 0"), 6,
               "bodies[0].material.young_modulus",
               {"young_modulus = 0 is out of range: must be >= 1e-09 and <= 1e+12"});
  expect_error(replace(kMinimal, "young_modulus: 1.0e7", "young_modulus: -1.0e7"), 6,
               "bodies[0].material.young_modulus", {"-1.0e7 is out of range", "must be >= 1e-09"});
}

TEST(ScenarioLoaderErrors, DensityNotPositive) {
  expect_error(replace(kMinimal, "density: 1000", "density: 0"), 8,
               "bodies[0].material.density", {"density = 0 is out of range: must be >= 1e-12 and <= 1000000"});
  expect_error(replace(kMinimal, "density: 1000", "density: -5"), 8,
               "bodies[0].material.density", {"must be >= 1e-12"});
}

// Values that loaded and then failed at tick 0 (issue 15): refused at load, with the reason.
TEST(ScenarioLoaderErrors, PhysicalRangesAreCheckedAtLoad) {
  expect_error("time_step: 1.8e19\n" + kMinimal, 1, "time_step", {"1.8e19 is out of range", "resolves no tissue motion"});
  expect_error("time_step: 1.0e-12\n" + kMinimal, 1, "time_step", {"out of range", "h^2*K"});
  expect_error(replace(kMinimal, "density: 1000", "density: 1e308"), 8, "bodies[0].material.density",
               {"1e308 is out of range", "t/mm^3"});
  expect_error(replace(kMinimal, "young_modulus: 1.0e7", "young_modulus: 1e300"), 6, "bodies[0].material.young_modulus",
               {"out of range", "diamond"});
  expect_error("gravity: [0, -1e308, 0]\n" + kMinimal, 1, "gravity", {"component 1", "out of range"});
  expect_error(replace(kMinimal, "density: 1000", "density: 1000\n      rayleigh_mass: 1e9"), 9,
               "bodies[0].material.rayleigh_mass", {"out of range", "microsecond"});
  expect_error(replace(kMinimal, "    mesh: beam.msh", "    mesh: beam.msh\n    scale: 1e300"), 5, "bodies[0].scale",
               {"out of range"});
  // Other unit systems stay legal: mm-tonne-s (water 1e-9 t/mm^3, E in MPa, g in mm/s^2).
  EXPECT_NO_THROW(parse_scenario(replace(replace("gravity: [0, -9810, 0]\n" + kMinimal, "density: 1000", "density: 1.0e-9"),
                                         "young_modulus: 1.0e7", "young_modulus: 0.005"),
                                 "mm.yaml", "."));
}

TEST(ScenarioLoaderErrors, OtherRanges) {
  expect_error("time_step: 0\n" + kMinimal, 1, "time_step", {"must be >= 1e-07 and <= 1"});
  expect_error(kMinimal + "solver:\n  tolerance: 1\n", 10, "solver.tolerance",
               {"tolerance = 1 is out of range: must be > 0 and < 1"});
  expect_error(kMinimal + "solver:\n  max_iterations: 0\n", 10, "solver.max_iterations",
               {"must be > 0"});
  expect_error(replace(kMinimal, "density: 1000", "density: 1000\n      rayleigh_mass: -0.1"), 9,
               "bodies[0].material.rayleigh_mass", {"must be >= 0"});
  expect_error(replace(kMinimal, "    mesh: beam.msh", "    mesh: beam.msh\n    scale: 0"), 5,
               "bodies[0].scale", {"must be >= 1e-09"});
  expect_error(kMinimal + "run:\n  steps: -3\n", 10, "run.steps", {"must be > 0"});
  expect_error(kMinimal + "run:\n  duration: 0\n", 10, "run.duration", {"must be > 0"});
  expect_error(kMinimal + "check:\n  mean_error: 0\n", 10, "check.mean_error", {"must be > 0"});
}

TEST(ScenarioLoaderErrors, NegativeNodeIndex) {
  expect_error(kMinimal + "    fixed:\n      - box: {min: [0, 0, 0], max: [1, 1, 1]}\n"
                          "      - nodes: [0, -3, 7]\n",
               11, "bodies[0].fixed[1].nodes[1]",
               {"nodes[1] = -3 is out of range: must be >= 0", "0-based"});
}

TEST(ScenarioLoaderErrors, BoxMinGreaterThanMax) {
  expect_error(kMinimal + "    fixed:\n      - nodes: [1]\n"
                          "      - box: {min: [0, 2, 0], max: [1, 1, 1]}\n",
               11, "bodies[0].fixed[1].box.min",
               {"min[1] = 2 is greater than max[1] = 1", "componentwise"});
}

TEST(ScenarioLoaderErrors, SelectionNeedsExactlyOneOfBoxOrNodes) {
  expect_error(kMinimal + "    fixed:\n      - nodes: [1]\n        box: {min: [0, 0, 0], "
                          "max: [1, 1, 1]}\n",
               11, "bodies[0].fixed[0]", {"give 'nodes' alone, or 'box' and/or 'surface', not both kinds"});
  expect_error(kMinimal + "    fixed:\n      - surface: {normal: [0, -1, 0]}\n        nodes: [1]\n", 11,
               "bodies[0].fixed[0]", {"'nodes' alone"});
  expect_error(kMinimal + "    loads:\n      - force: [0, 0, 1]\n", 10, "bodies[0].loads[0]",
               {"needs 'box', 'surface' (or both) or 'nodes'"});
  expect_error(kMinimal + "    fixed:\n      - surface: {normal: [0, 0, 0]}\n", 10,
               "bodies[0].fixed[0].surface.normal", {"non-zero"});
  expect_error(kMinimal + "    fixed:\n      - surface: {normal: [0, -1, 0], max_angle: 0}\n", 10,
               "bodies[0].fixed[0].surface.max_angle", {"must be > 0"});
  expect_error(kMinimal + "    fixed:\n      - surface: {normal: [0, -1, 0], max_angle: 181}\n", 10,
               "bodies[0].fixed[0].surface.max_angle", {"<= 180"});
  expect_error(kMinimal + "    fixed:\n      - surface: {normal: [0, -1, 0], side: 1}\n", 10,
               "bodies[0].fixed[0].surface.side", {"unknown"});
  expect_error(kMinimal + "    fixed:\n      - nodes: []\n", 10, "bodies[0].fixed[0].nodes",
               {"empty node list"});
}

// ---------------------------------------------------------------------------------------------
// Enumerations, run, names

TEST(ScenarioLoaderErrors, UnknownIntegrator) {
  expect_error(kMinimal + "solver:\n  integrator: rk4\n", 10, "solver.integrator",
               {"unknown integrator 'rk4'", "implicit_euler, symplectic_euler, static"});
  expect_error(kMinimal + "solver:\n  integrator: implicit_eulr\n", 10, "solver.integrator",
               {"did you mean 'implicit_euler'?"});
  expect_error(replace(kMinimal, "density: 1000", "density: 1000\n      model: neohookean"), 9,
               "bodies[0].material.model", {"unknown model 'neohookean'", "corotational, linear"});
  expect_error(kMinimal + "solver:\n  preconditioner: ilu\n", 10, "solver.preconditioner",
               {"jacobi, block_jacobi, none"});
  expect_error(kMinimal + "solver:\n  preconditioner: atuo\n", 10, "solver.preconditioner",
               {"did you mean 'auto'?"});
  expect_error(kMinimal + "solver:\n  on_cg_cap: sometimes\n", 10, "solver.on_cg_cap",
               {"'sometimes'", "auto", "substep", "continue"});
}

TEST(ScenarioLoaderErrors, BothStepsAndDuration) {
  expect_error(kMinimal + "run:\n  duration: 0.5\n  steps: 500\n", 11, "run",
               {"either 'duration' or 'steps', not both"});
}

TEST(ScenarioLoaderErrors, DuplicateBodyNames) {
  const std::string two = kMinimal + R"(  - name: beam
    mesh: other.msh
    material: {young_modulus: 1.0e6, poisson_ratio: 0.4, density: 900}
)";
  expect_error(two, 9, "bodies[1].name", {"duplicate body name 'beam'", "first defined at line 3"});
}

TEST(ScenarioLoaderErrors, DuplicateProbeNames) {
  expect_error(kMinimal + "probes:\n  - {name: tip, body: beam, point: [0, 0, 0]}\n"
                          "  - {name: tip, body: beam, point: [1, 0, 0]}\n",
               11, "probes[1].name", {"duplicate probe name 'tip'", "first defined at line 10"});
}

TEST(ScenarioLoaderErrors, ProbeWithUnknownBody) {
  expect_error(kMinimal + "probes:\n  - name: tip\n    body: bem\n    point: [0, 0, 0]\n", 11,
               "probes[0].body",
               {"unknown body 'bem'", "did you mean 'beam'?", "bodies are: beam"});
}

TEST(ScenarioLoaderErrors, WhatIncludesFileLineAndField) {
  try {
    parse(replace(kMinimal, "density: 1000", "density: 0"));
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("scenes/test.yaml:8: bodies[0].material.density: ", 0),
              0u)
        << e.what();
  }
}

TEST(ScenarioLoaderTools, ParsesToolsWithLimitsAndResolvesScript) {
  const ScenarioSpec s = parse_scenario(kMinimal +
                                            "tools:\n"
                                            "  - name: probe\n"
                                            "    script: traj/press.yaml\n"
                                            "    workspace: {min: [-1, -2, -3], max: [1, 2, 3]}\n"
                                            "    max_speed: 2.5\n"
                                            "    timeout: 0.25\n"
                                            "    on_invalid: clamp\n",
                                        "dir/s.yaml", "dir");
  ASSERT_EQ(s.tools.size(), 1u);
  const ToolSpec& t = s.tools[0].spec;
  EXPECT_EQ(t.name, "probe");
  EXPECT_EQ(s.tools[0].script, "dir/traj/press.yaml");
  EXPECT_EQ(t.workspace_min, (Vec3{-1, -2, -3}));
  EXPECT_EQ(t.workspace_max, (Vec3{1, 2, 3}));
  EXPECT_DOUBLE_EQ(t.max_speed, 2.5);
  EXPECT_DOUBLE_EQ(t.timeout, 0.25);
  EXPECT_EQ(t.on_invalid, InvalidCommandPolicy::Clamp);
}

TEST(ScenarioLoaderTools, ToolErrors) {
  expect_error(kMinimal + "tools:\n  - name: probe\n    max_speed: -1\n", 11, "tools[0].max_speed",
               {"out of range"});
  expect_error(kMinimal + "tools:\n  - name: probe\n  - name: probe\n", 11, "tools[1].name",
               {"duplicate tool name 'probe'"});
  expect_error(kMinimal + "tools:\n  - name: probe\n    on_invalid: ignore\n", 11, "tools[0].on_invalid",
               {"unknown on_invalid 'ignore'", "reject", "clamp"});
  expect_error(kMinimal + "tools:\n  - name: probe\n    handle: long\n", 11, "tools[0].handle",
               {"unknown key 'handle'"});
  expect_error(kMinimal + "tools:\n  - name: probe\n    shape: {type: capsule, radius: 0.01}\n", 11,
               "tools[0].shape.type", {"unknown type 'capsule'", "sphere"});
  expect_error(kMinimal + "tools:\n  - name: probe\n    shape: {type: sphere, radius: -0.01}\n", 11,
               "tools[0].shape.radius", {"out of range"});
  expect_error(kMinimal + "tools:\n  - name: probe\n    contact: {stiffness: 0}\n", 11,
               "tools[0].contact.stiffness", {"out of range"});
}

// `pose:` (issue 41 §2): where the tool is before its first command — every front end reports it
// (CRTK's measured_cp). A quaternion of another norm or a pose outside the workspace is refused.
TEST(ScenarioLoaderTools, ARestPoseIsReadAndCheckedAndNormalised) {
  const ScenarioSpec s = parse(kMinimal + "tools:\n  - name: probe\n    pose: {position: [0.1, 0.2, 0.3], "
                                          "orientation: [0.70710678, 0, 0.70710678, 0]}\n");
  ASSERT_TRUE(s.tools[0].has_pose);
  EXPECT_EQ(s.tools[0].spec.rest_pose.position, (Vec3{0.1, 0.2, 0.3}));
  const auto& q = s.tools[0].spec.rest_pose.orientation;
  EXPECT_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1.0, 1e-15);
  expect_error(kMinimal + "tools:\n  - name: probe\n    pose: {orientation: [1, 1, 0, 0]}\n", 11,
               "tools[0].pose.orientation", {"unit quaternion"});
  expect_error(kMinimal + "tools:\n  - name: probe\n    pose: {orientation: [1, 0, 0]}\n", 11,
               "tools[0].pose.orientation", {"4 numbers"});
  expect_error(kMinimal + "tools:\n  - name: probe\n    pose: {place: [1, 0, 0]}\n", 11, "tools[0].pose.place",
               {"unknown key 'place'"});
}

// Finite but absurd tool values loaded and overflowed the contact or speed arithmetic at tick 0
// (issue 15): every tool quantity now has a bound, with the reason in the message.
TEST(ScenarioLoaderTools, ToolQuantitiesHaveBounds) {
  const std::string tool = kMinimal + "tools:\n  - name: probe\n";
  expect_error(tool + "    max_speed: 1e300\n", 11, "tools[0].max_speed", {"1e300 is out of range", "m/s"});
  expect_error(tool + "    timeout: 1e30\n", 11, "tools[0].timeout", {"out of range"});
  expect_error(tool + "    shape: {type: sphere, radius: 1e200}\n", 11, "tools[0].shape.radius", {"out of range"});
  expect_error(tool + "    contact: {stiffness: 1e300}\n", 11, "tools[0].contact.stiffness", {"out of range", "N/m"});
  expect_error(tool + "    contact: {friction: 1e6}\n", 11, "tools[0].contact.friction", {"out of range", "Coulomb"});
  expect_error(tool + "    max_force: 1e300\n", 11, "tools[0].max_force", {"out of range"});
  expect_error(tool + "    shape: {type: sphere, radius: 0.01}\n    coupling: {stiffness: 1e300}\n", 12,
               "tools[0].coupling.stiffness", {"out of range"});
  expect_error(tool + "    shape: {type: sphere, radius: 0.01}\n    grasp: {stiffness: 1e300}\n", 12,
               "tools[0].grasp.stiffness", {"out of range"});
  // mm-tonne-s values stay legal: 500 mm/s, 50 N/mm.
  EXPECT_NO_THROW(parse_scenario(tool + "    max_speed: 500\n    shape: {type: sphere, radius: 2}\n"
                                        "    contact: {stiffness: 50}\n",
                                 "mm.yaml", "."));
}

TEST(ScenarioLoaderTools, FixedAxes) {
  const ScenarioSpec s = parse_scenario(kMinimal + "    fixed:\n      - {box: {min: [0, 0, 0], max: [1, 1, 1]}, axes: [x, z]}\n      - {nodes: [3]}\n",
                                        "a.yaml", "");
  ASSERT_EQ(s.bodies[0].fixed.size(), 2u);
  EXPECT_EQ(s.bodies[0].fixed[0].axes, 1 | 4);
  EXPECT_EQ(s.bodies[0].fixed[1].axes, 7);
  expect_error(kMinimal + "    fixed:\n      - {nodes: [3], axes: [w]}\n", 10, "bodies[0].fixed[0].axes[0]",
               {"unknown axis 'w'"});
}

TEST(ScenarioLoaderTools, GraspSection) {
  const ScenarioSpec s = parse_scenario(kMinimal + "tools:\n  - name: g\n    shape: {type: sphere, radius: 0.01}\n    grasp: {close: 0.02, open: 0.2, reach: 1.5}\n",
                                        "a.yaml", "");
  const ToolSpec& t = s.tools.at(0).spec;
  EXPECT_TRUE(t.can_grasp);
  EXPECT_DOUBLE_EQ(t.grasp_close, 0.02);
  EXPECT_DOUBLE_EQ(t.grasp_open, 0.2);
  EXPECT_DOUBLE_EQ(t.grasp_reach, 1.5);
  expect_error(kMinimal + "tools:\n  - name: g\n    shape: {type: sphere, radius: 0.01}\n    grasp: {close: 0.2, open: 0.1}\n",
               12, "tools[0].grasp.open", {"open must be greater than close"});
  expect_error(kMinimal + "tools:\n  - name: g\n    grasp: {}\n", 11, "tools[0].grasp", {"needs a shape"});
}

TEST(ScenarioLoaderTools, DamageThresholds) {
  const std::string mat = "      young_modulus: 1.0e7\n";
  const ScenarioSpec s = parse_scenario(
      replace(kMinimal, mat, mat + "      damage: {measure: von_mises, warning: 1000, onset: 2000, rupture: 8000}\n"), "a.yaml", "");
  const DamageSpec& d = s.bodies[0].material.damage;
  EXPECT_TRUE(d.enabled);
  EXPECT_EQ(d.measure, DamageMeasure::VonMises);
  EXPECT_DOUBLE_EQ(d.warning, 1000);
  EXPECT_DOUBLE_EQ(d.onset, 2000);
  EXPECT_DOUBLE_EQ(d.rupture, 8000);
  expect_error(replace(kMinimal, mat, mat + "      damage: {onset: 8000, rupture: 2000}\n"), 7,
               "bodies[0].material.damage.rupture", {"must be greater than onset"});
  expect_error(replace(kMinimal, mat, mat + "      damage: {warning: 9000, onset: 2000, rupture: 8000}\n"), 7,
               "bodies[0].material.damage.warning", {"must not exceed onset"});
  expect_error(replace(kMinimal, mat, mat + "      damage: {measure: tresca, onset: 1, rupture: 2}\n"), 7,
               "bodies[0].material.damage.measure", {"unknown measure 'tresca'", "principal_strain"});
}

TEST(ScenarioLoaderTools, ProbeShape) {
  const ScenarioSpec s = parse_scenario(kMinimal + "tools:\n  - name: p\n    shape: {type: probe, radius: 0.003, shaft_radius: 0.002, length: 0.1}\n",
                                        "a.yaml", "");
  const ToolSpec& t = s.tools.at(0).spec;
  EXPECT_EQ(t.shape, ToolShape::Probe);
  EXPECT_DOUBLE_EQ(t.shaft_radius, 0.002);
  EXPECT_DOUBLE_EQ(t.shaft_length, 0.1);
  expect_error(kMinimal + "tools:\n  - name: p\n    shape: {type: probe, radius: 0.003}\n", 11, "tools[0].shape.length",
               {"missing required field 'length'"});
  expect_error(kMinimal + "tools:\n  - name: p\n    shape: {type: probe, radius: 0.003, shaft_radius: 0.01, length: 1}\n", 11,
               "tools[0].shape.shaft_radius", {"must not exceed the tip radius"});
  expect_error(kMinimal + "tools:\n  - name: p\n    shape: {type: sphere, radius: 0.003, length: 1}\n", 11,
               "tools[0].shape", {"belong to types probe, blade, grasper"});
}

TEST(ScenarioLoaderTools, Coupling) {
  const ScenarioSpec s = parse_scenario(kMinimal + "tools:\n  - name: p\n    shape: {type: sphere, radius: 0.003}\n    coupling: {stiffness: 300}\n",
                                        "a.yaml", "");
  EXPECT_DOUBLE_EQ(s.tools.at(0).spec.coupling_stiffness, 300);
  const ScenarioSpec f = parse_scenario(kMinimal + "tools:\n  - name: p\n    shape: {type: sphere, radius: 0.003}\n    contact: {friction: 0.4}\n",
                                        "a.yaml", "");
  EXPECT_DOUBLE_EQ(f.tools.at(0).spec.friction, 0.4);
  expect_error(kMinimal + "tools:\n  - name: p\n    shape: {type: sphere, radius: 0.003}\n    contact: {friction: -0.1}\n", 12,
               "tools[0].contact.friction", {"out of range"});
  expect_error(kMinimal + "tools:\n  - name: p\n    coupling: {stiffness: 300}\n", 11, "tools[0].coupling",
               {"needs a shape"});
  expect_error(kMinimal + "tools:\n  - name: p\n    shape: {type: sphere, radius: 0.003}\n    coupling: {stiffness: -1}\n", 12,
               "tools[0].coupling.stiffness", {"out of range"});
}

TEST(ScenarioLoaderTools, BladeAndGrasperShapes) {
  const ScenarioSpec s = parse_scenario(kMinimal + "tools:\n  - name: b\n    shape: {type: blade, radius: 0.0005, length: 0.02}\n"
                                                   "  - name: g\n    shape: {type: grasper, radius: 0.002, length: 0.015}\n",
                                        "a.yaml", "");
  EXPECT_EQ(s.tools.at(0).spec.shape, ToolShape::Blade);
  EXPECT_DOUBLE_EQ(s.tools.at(0).spec.shaft_length, 0.02);
  EXPECT_EQ(s.tools.at(1).spec.shape, ToolShape::Grasper);
  expect_error(kMinimal + "tools:\n  - name: b\n    shape: {type: blade, radius: 0.0005}\n", 11, "tools[0].shape.length",
               {"missing required field 'length'"});
}

TEST(ScenarioLoaderTools, CutSection) {
  const std::string blade = "tools:\n  - name: s\n    shape: {type: blade, radius: 0.0005, length: 0.02}\n";
  const ScenarioSpec s = parse_scenario(kMinimal + blade + "    cut: {toughness: 200, height: 0.008}\n", "a.yaml", "");
  EXPECT_TRUE(s.tools.at(0).spec.cuts);
  EXPECT_DOUBLE_EQ(s.tools.at(0).spec.cut_toughness, 200);
  EXPECT_DOUBLE_EQ(s.tools.at(0).spec.blade_height, 0.008);
  EXPECT_TRUE(parse_scenario(kMinimal + blade + "    cut: {}\n", "a.yaml", "").tools.at(0).spec.cuts);
  EXPECT_FALSE(parse_scenario(kMinimal + blade, "a.yaml", "").tools.at(0).spec.cuts);
  expect_error(kMinimal + "tools:\n  - name: s\n    shape: {type: sphere, radius: 0.003}\n    cut: {}\n", 12,
               "tools[0].cut", {"only a blade cuts"});
  expect_error(kMinimal + blade + "    cut: {toughness: -1}\n", 12, "tools[0].cut.toughness", {"-1"});
  expect_error(kMinimal + blade + "    cut: {sharpness: 3}\n", 12, "tools[0].cut.sharpness", {"unknown key"});
}

}  // namespace
TEST(ScenarioLoader, MultirateFemEveryAndHapticModel) {
  EXPECT_EQ(parse(kMinimal).solver.fem_every, 1);
  EXPECT_FALSE(parse(kMinimal).solver.haptic_secant);  // hold
  const ScenarioSpec s = parse(kMinimal + "solver:\n  fem_every: 10\n  haptic_model: secant\n");
  EXPECT_EQ(s.solver.fem_every, 10);
  EXPECT_TRUE(s.solver.haptic_secant);
  EXPECT_EQ(s.solver.fem_every_where.line, 10);
  expect_error(kMinimal + "solver:\n  fem_every: 0\n", 10, "solver.fem_every", {"0"});
  expect_error(kMinimal + "solver:\n  fem_every: 2.5\n", 10, "solver.fem_every", {"whole number of ticks >= 1", "'2.5'"});
  expect_error(kMinimal + "solver:\n  fem_every: often\n", 10, "solver.fem_every", {"whole number of ticks"});
  expect_error(kMinimal + "solver:\n  haptic_model: springy\n", 10, "solver.haptic_model", {"secant", "hold"});
}

}  // namespace stroma
