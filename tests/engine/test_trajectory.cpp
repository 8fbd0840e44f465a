// engine/trajectory: timed tool trajectories (interpolation, slerp, CSV/YAML, errors with lines).

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "engine/trajectory.hpp"
#include "tests/test_scenarios.hpp"
#include "tissue/input_error.hpp"

using namespace stroma;

using test_scenarios::write_temp;

TEST(Trajectory, InterpolatesPositionJawAndSlerpsOrientation) {
  const std::string path = write_temp("stroma_traj.yaml",
                                      "keyframes:\n"
                                      "  - {t: 0, position: [0, 0, 0], orientation: [1, 0, 0, 0], jaw: 0}\n"
                                      "  - {t: 2, position: [2, 4, -2], orientation: [0, 0, 0, 1], jaw: 1, buttons: 3}\n");
  const Trajectory tr = load_trajectory(path);
  const ToolPose p = tr.sample(0.5);
  EXPECT_NEAR(p.position[0], 0.5, 1e-15);
  EXPECT_NEAR(p.position[1], 1.0, 1e-15);
  EXPECT_NEAR(p.position[2], -0.5, 1e-15);
  EXPECT_NEAR(p.jaw, 0.25, 1e-15);
  // Slerp from identity to 180° about z: at u = 1/4 the angle is 45°: q = (cos 22.5°, 0, 0, sin 22.5°).
  EXPECT_NEAR(p.orientation[0], std::cos(M_PI / 8), 1e-12);
  EXPECT_NEAR(p.orientation[3], std::sin(M_PI / 8), 1e-12);
  EXPECT_EQ(tr.sample(-1).position, (Vec3{0, 0, 0}));   // held before the start
  EXPECT_EQ(tr.sample(9).position, (Vec3{2, 4, -2}));   // held after the end
  EXPECT_EQ(tr.sample(9).buttons, 3u);
}

TEST(Trajectory, CsvAndErrorsWithLine) {
  const Trajectory tr = parse_trajectory_csv("t,x,y,z,jaw\n0,0,0,0,0\n1,1,0,0,0.5\n", "a.csv");
  EXPECT_NEAR(tr.sample(0.5).position[0], 0.5, 1e-15);
  EXPECT_NEAR(tr.sample(0.5).jaw, 0.25, 1e-15);
  auto expect = [](const std::string& text, int line, const std::string& words) {
    try {
      parse_trajectory_csv(text, "b.csv");
      FAIL() << words;
    } catch (const InputError& e) {
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  expect("t,x,y\n0,0,0\n", 1, "missing column 'z'");
  expect("t,x,y,z\n0,0,0,0\n0,1,1,1\n", 3, "does not increase");
  expect("t,x,y,z\n0,0,zero,0\n", 2, "expected a finite number, got 'zero'");
  expect("t,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,1,0,0\n", 2, "not a unit quaternion");
  expect("t,x,y,z,speed\n0,0,0,0,1\n", 1, "unknown column 'speed'");
}


// `stroma tool --loop`: the script repeats from its start; before its end it is the script.
TEST(Trajectory, LoopingRepeatsTheScriptFromItsStart) {
  Trajectory tr;
  ToolPose a, b;
  a.position = {0, 0, 0};
  b.position = {2, 0, 0};
  tr.keys = {{0.0, a}, {2.0, b}};
  EXPECT_DOUBLE_EQ(tr.sample_looping(0.5).position[0], 0.5);
  EXPECT_DOUBLE_EQ(tr.sample_looping(2.5).position[0], 0.5);
  EXPECT_DOUBLE_EQ(tr.sample_looping(7.25).position[0], 1.25);
  EXPECT_DOUBLE_EQ(tr.sample(7.25).position[0], 2.0) << "without looping the last pose is held";
}

// YAML reads .nan and .inf as numbers; the unit-quaternion test |n − 1| > 1e-3 was false for a
// NaN. Every non-finite value is refused with its keyframe's line and field.
TEST(Trajectory, NonFiniteValuesAreRefusedWithLineAndField) {
  struct Case {
    const char* key;
    const char* field;
  };
  const Case cases[] = {{"t: .nan", "t"},
                        {"position: [0, .inf, 0]", "position"},
                        {"orientation: [.nan, 0, 0, 0]", "orientation"},
                        {"jaw: -.inf", "jaw"}};
  for (const Case& c : cases) {
    std::string key = c.key;
    std::string yaml = "keyframes:\n  - {t: 0, position: [0, 0, 0]}\n  - {";
    yaml += key.rfind("t:", 0) == 0 ? key + ", position: [0, 0, 0]" : "t: 1, " + key + (key.rfind("position", 0) == 0 ? "" : ", position: [0, 0, 0]");
    yaml += "}\n";
    const std::string path = write_temp("stroma_traj_nan.yaml", yaml);
    try {
      load_trajectory(path);
      ADD_FAILURE() << "accepted: " << yaml;
    } catch (const InputError& e) {
      EXPECT_EQ(e.line(), 3) << e.what();
      EXPECT_EQ(e.field(), c.field) << e.what();
    }
  }
  // CSV: a button mask must be an integer (a negative or huge value was cast blindly).
  for (const char* b : {"-1", "1e20", "2.5"}) {
    try {
      parse_trajectory_csv(std::string("t,x,y,z,buttons\n0,0,0,0,") + b + "\n", "b.csv");
      ADD_FAILURE() << "accepted buttons " << b;
    } catch (const InputError& e) {
      EXPECT_EQ(e.line(), 2);
      EXPECT_EQ(e.field(), "buttons");
    }
  }
}
