// The documented invariants of Model and State as checks (engine/model_check.hpp), and
// STROMA_DEMAND (tissue/demand.hpp): on in debug and sanitizer builds, at compile and tick entry.

#include <gtest/gtest.h>

#include <string>

#include "engine/model_check.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tissue/demand.hpp"
#include "tests/test_scenarios.hpp"

namespace stroma {
namespace {

const std::string kDir = std::string(STROMA_SOURCE_DIR) + "/scenarios/";

TEST(ModelCheck, CompiledModelsKeepTheirInvariantsAndABrokenOneIsNamed) {
  for (const char* f : {"liver.yaml", "regression/liver_probe_damage.yaml", "regression/liver_incision.yaml",
                        "cantilever_dynamic.yaml"}) {
    const CompiledScenario sc = compile_scenario(load_scenario(kDir + f));
    std::string why;
    EXPECT_TRUE(model_invariants_hold(*sc.model, &why)) << f << ": " << why;
    EXPECT_TRUE(state_sized_for(*sc.model, State::initial(*sc.model))) << f;
  }
  const CompiledScenario sc = compile_scenario(load_scenario(kDir + "regression/liver_probe_damage.yaml"));
  auto broken = [&](auto&& edit) {
    Model m = *sc.model;
    edit(m);
    std::string why;
    return model_invariants_hold(m, &why) ? std::string("(holds)") : why;
  };
  EXPECT_NE(broken([](Model& m) { m.fem.mass.pop_back(); }).find("fem.mass"), std::string::npos);
  EXPECT_NE(broken([](Model& m) { m.fem.ranges.back().end -= 1; }).find("fem.ranges"), std::string::npos);
  EXPECT_NE(broken([](Model& m) { m.fem.elements[3].volume = -1; }).find("volume > 0"), std::string::npos);
  EXPECT_NE(broken([](Model& m) { m.tools[0].contact_stiffness = 0; }).find("contact stiffness"), std::string::npos);
  EXPECT_NE(broken([](Model& m) { m.has_contact = false; }).find("has_contact"), std::string::npos);
  EXPECT_NE(broken([](Model& m) { m.element_node_mass.clear(); }).find("element_node_mass"), std::string::npos);
  EXPECT_NE(broken([](Model& m) { m.collision_edge.pop_back(); }).find("collision arrays"), std::string::npos);

  State s = State::initial(*sc.model);
  s.tissue.x.pop_back();
  EXPECT_FALSE(state_sized_for(*sc.model, s));
  s = State::initial(*sc.model);
  s.damage.clear();
  EXPECT_FALSE(state_sized_for(*sc.model, s));
}

TEST(ModelCheck, ATickOnAStateOfAnotherModelStopsAtTheDemandInCheckedBuilds) {
  if (!STROMA_DEMANDS_ON) GTEST_SKIP() << "STROMA_DEMAND is compiled out in Release (on in debug and sanitizer builds)";
  const CompiledScenario a = compile_scenario(load_scenario(kDir + "liver.yaml"));
  const CompiledScenario b = compile_scenario(test_scenarios::cantilever_dynamic());
  TickWorkspace w(*a.model);
  State wrong = State::initial(*b.model);
  EXPECT_DEATH(tick(*a.model, wrong, w), "STROMA_DEMAND\\(state_sized_for\\(m, s\\)\\) failed");
}

}  // namespace
}  // namespace stroma
