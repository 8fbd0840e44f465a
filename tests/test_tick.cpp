// The tick pipeline: stages a scene does not need are skipped; a non-finite solve never enters
// the state.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"

using namespace stroma;

namespace {
const std::string kDir = std::string(STROMA_SOURCE_DIR) + "/scenarios/";
}

TEST(Tick, SceneWithoutToolsSkipsInputAndCollisionStages) {
  auto m = compile_model(load_scenario(kDir + "regression/liver_damped.yaml"));
  ASSERT_TRUE(m->tools.empty());
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const TickReport r = tick(*m, s, w);
  EXPECT_FALSE(r.stage_ran[static_cast<int>(Stage::ReadInputs)]);
  EXPECT_FALSE(r.stage_ran[static_cast<int>(Stage::Collide)]);
  EXPECT_EQ(r.stage_ns[static_cast<int>(Stage::Collide)], 0);
  EXPECT_TRUE(r.stage_ran[static_cast<int>(Stage::Assemble)]);
  EXPECT_TRUE(r.stage_ran[static_cast<int>(Stage::Solve)]);
  EXPECT_TRUE(r.stage_ran[static_cast<int>(Stage::Integrate)]);

  auto mt = compile_model(load_scenario(kDir + "liver.yaml"));
  ASSERT_FALSE(mt->tools.empty());
  State st = State::initial(*mt);
  TickWorkspace wt(*mt);
  EXPECT_TRUE(tick(*mt, st, wt).stage_ran[static_cast<int>(Stage::ReadInputs)]);
}

TEST(Tick, NonFiniteSolveLeavesTheStateUnadvanced) {
  auto m = compile_model(load_scenario(kDir + "liver.yaml"));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  for (int k = 0; k < 10; ++k) tick(*m, s, w);
  // Corrupt one velocity (as a broken input would): the solve turns non-finite.
  s.tissue.v[3 * 10 + 1] = std::numeric_limits<double>::quiet_NaN();
  const std::vector<double> x_before = s.tissue.x;
  const int64_t step_before = s.step;
  const TickReport r = tick(*m, s, w);
  EXPECT_EQ(r.status, TickStatus::NonFinite);
  EXPECT_EQ(s.tissue.x, x_before) << "positions must not take a NaN step";
  EXPECT_EQ(s.step, step_before);
  for (double d : s.tissue.dv) EXPECT_TRUE(std::isfinite(d)) << "warm start cleared";
}

TEST(Tick, SnapshotAndRestoreIsACopyAndReproducesBitForBit) {
  auto m = compile_model(load_scenario(kDir + "liver.yaml"));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  for (int k = 0; k < 50; ++k) tick(*m, s, w);
  const State snapshot = s;
  for (int k = 0; k < 50; ++k) tick(*m, s, w);
  const std::vector<double> first = s.tissue.x;
  s = snapshot;  // roll back
  for (int k = 0; k < 50; ++k) tick(*m, s, w);
  EXPECT_EQ(s.tissue.x, first);
  EXPECT_EQ(s.step, 100);
}
