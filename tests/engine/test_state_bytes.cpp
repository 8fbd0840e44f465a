// engine/state_bytes: a state as bytes (pickled snapshots) round-trips exactly, carries its
// scenario's fingerprint, and bad bytes are InputErrors naming the field, never a crash.

#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "engine/state_bytes.hpp"
#include "engine/tick.hpp"
#include "runtime/headless_runner.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tissue/input_error.hpp"

using namespace stroma;

namespace {
const std::string kDir = std::string(STROMA_SOURCE_DIR) + "/scenarios/";

/// A state with every part in use: the probe pressed into the liver far enough to damage it.
State damaged_liver_state(const CompiledScenario& sc) {
  RunOptions o;
  o.progress = false;
  o.metrics = false;
  return run_headless(sc, o).final_state;
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}
}  // namespace

TEST(StateBytes, RoundTripsEveryFieldExactly) {
  const CompiledScenario sc = compile_scenario(load_scenario(kDir + "regression/liver_probe_damage.yaml"));
  const State s = damaged_liver_state(sc);
  ASSERT_GT(s.damage_count[kDamaged], 0) << "the state must exercise the damage arrays";
  ASSERT_GT(s.step, 0);
  const uint64_t fp = model_fingerprint(*sc.model);
  uint64_t got_fp = 0;
  const State t = decode_state(encode_state(s, fp), &got_fp);
  EXPECT_EQ(got_fp, fp);
  EXPECT_TRUE(same_bits(t.tissue.x, s.tissue.x));
  EXPECT_TRUE(same_bits(t.tissue.v, s.tissue.v));
  EXPECT_TRUE(same_bits(t.tissue.dv, s.tissue.dv));
  EXPECT_TRUE(same_bits(t.tissue.dv_prev, s.tissue.dv_prev));
  EXPECT_TRUE(same_bits(t.node_mass, s.node_mass));
  EXPECT_EQ(t.damage, s.damage);
  EXPECT_EQ(t.damage_level, s.damage_level);
  EXPECT_EQ(t.face_active, s.face_active);
  EXPECT_EQ(t.damage_count, s.damage_count);
  EXPECT_EQ(t.time, s.time);
  EXPECT_EQ(t.step, s.step);
  ASSERT_EQ(t.tools.size(), s.tools.size());
  EXPECT_EQ(std::memcmp(t.tools.data(), s.tools.data(), s.tools.size() * sizeof(ToolState)), 0);
  std::string why;
  EXPECT_TRUE(state_fits_model(t, *sc.model, &why)) << why;

  // The decoded state steps exactly as the original does.
  State a = s, b = t;
  TickWorkspace wa(*sc.model), wb(*sc.model);
  for (int k = 0; k < 20; ++k) {
    tick(*sc.model, a, wa, nullptr, 0);
    tick(*sc.model, b, wb, nullptr, 0);
  }
  EXPECT_TRUE(same_bits(a.tissue.x, b.tissue.x));
}

TEST(StateBytes, FingerprintsTellScenariosApartAndAgreeAcrossCompiles) {
  const CompiledScenario a = compile_scenario(load_scenario(kDir + "regression/liver_probe_damage.yaml"));
  const CompiledScenario a2 = compile_scenario(load_scenario(kDir + "regression/liver_probe_damage.yaml"));
  const CompiledScenario b = compile_scenario(load_scenario(kDir + "regression/liver_probe_press.yaml"));
  const CompiledScenario c = compile_scenario(load_scenario(kDir + "regression/cantilever_implicit_cg.yaml"));
  EXPECT_EQ(model_fingerprint(*a.model), model_fingerprint(*a2.model));
  EXPECT_NE(model_fingerprint(*a.model), model_fingerprint(*b.model)) << "same mesh, damage model differs";
  EXPECT_NE(model_fingerprint(*a.model), model_fingerprint(*c.model));
  std::string why;
  EXPECT_FALSE(state_fits_model(State::initial(*c.model), *a.model, &why));
  EXPECT_NE(why.find("positions"), std::string::npos) << why;
}

TEST(StateBytes, FingerprintIsOfTheWholeCompiledModelNotOfTheMeshAlone) {
  // liver.yaml and liver_probe_press.yaml share the mesh, its nodes and masses: their states
  // have the same sizes, yet the models differ (gravity, fixed set, damping, tool), so a
  // snapshot of one must not restore into the other. Each single change is told apart too.
  const CompiledScenario liver = compile_scenario(load_scenario(kDir + "liver.yaml"));
  const CompiledScenario press = compile_scenario(load_scenario(kDir + "regression/liver_probe_press.yaml"));
  EXPECT_NE(model_fingerprint(*liver.model), model_fingerprint(*press.model));
  const uint64_t base = model_fingerprint(*liver.model);
  auto changed = [&](auto&& edit) {
    Model m = *liver.model;
    edit(m);
    return model_fingerprint(m);
  };
  EXPECT_NE(changed([](Model& m) { m.fem.gravity[1] += 1e-9; }), base) << "gravity";
  EXPECT_NE(changed([](Model& m) { m.fem.f_ext[1] += 1e-12; }), base) << "external force";
  EXPECT_NE(changed([](Model& m) { m.fem.constrained[0] ^= 1; }), base) << "fixed set";
  EXPECT_NE(changed([](Model& m) { m.fem.alpha[0] += 1e-9; }), base) << "Rayleigh mass damping";
  EXPECT_NE(changed([](Model& m) { m.fem.elements[0].beta += 1e-12; }), base) << "Rayleigh stiffness damping";
  EXPECT_NE(changed([](Model& m) { m.stepper.tolerance *= 2; }), base) << "solver tolerance";
  EXPECT_NE(changed([](Model& m) { m.time_step *= 2; }), base) << "time step";
  EXPECT_NE(changed([](Model& m) { m.fem.ranges[0].kernel = ElementKernel::Linear; }), base) << "element kernel";
  EXPECT_EQ(changed([](Model& m) { m.name = "renamed"; }), base) << "a name is not physics";
}

TEST(StateBytes, BadBytesAreInputErrorsNamingTheField) {
  const CompiledScenario sc = compile_scenario(load_scenario(kDir + "regression/liver_probe_damage.yaml"));
  const std::string good = encode_state(State::initial(*sc.model), 7);
  auto field_of = [](const std::string& bytes) -> std::string {
    try {
      decode_state(bytes, nullptr);
    } catch (const InputError& e) {
      return e.field();
    }
    return "";
  };
  // Every truncation is refused (the field named is the one the bytes end in).
  for (size_t n = 0; n < good.size(); n += (n < 64 ? 1 : 97))
    ASSERT_NE(field_of(good.substr(0, n)), "") << "truncated to " << n << " bytes was accepted";
  EXPECT_EQ(field_of(good.substr(0, 5)), "magic");
  EXPECT_EQ(field_of(good + "x"), "trailing bytes");
  std::string bad = good;
  bad[0] = 'X';
  EXPECT_EQ(field_of(bad), "magic");
  bad = good;
  bad[12] = static_cast<char>(bad[12] + 1);  // the format version: a later one
  EXPECT_EQ(field_of(bad), "version");
  bad = good;
  bad[24] ^= 1;  // sizeof(ToolState)
  EXPECT_EQ(field_of(bad), "tool size");
  // A count of 2^62 positions: refused before anything is allocated.
  bad = good;
  const uint64_t huge = uint64_t{1} << 62;
  std::memcpy(&bad[28], &huge, sizeof huge);
  EXPECT_EQ(field_of(bad), "x");
}

// The format has one encoding per state (the fuzz target's invariant): refresh ids, which name a
// factor within one process only, are stored as presence flags, and a flag byte other than 0 or
// 1 is refused rather than read as "set".
TEST(StateBytes, ADecodedStateReencodesToTheSameBytes) {
  const CompiledScenario sc = compile_scenario(load_scenario(kDir + "regression/liver_probe_damage.yaml"));
  State s = State::initial(*sc.model);
  s.tissue.solver.factor_id = 12345;
  s.tissue.solver.pending_id = 678;
  s.tissue.solver.demand = true;
  const std::string bytes = encode_state(s, 7);
  const State t = decode_state(bytes, nullptr);
  EXPECT_NE(t.tissue.solver.factor_id, 0u);
  EXPECT_NE(t.tissue.solver.pending_id, 0u);
  EXPECT_NE(t.tissue.solver.factor_id, s.tissue.solver.factor_id) << "decode gives this process's own ids";
  EXPECT_TRUE(t.tissue.solver.demand);
  EXPECT_EQ(encode_state(t, 7), bytes);
  s.tissue.solver.factor_id = s.tissue.solver.pending_id = 0;
  const State u = decode_state(encode_state(s, 7), nullptr);
  EXPECT_EQ(u.tissue.solver.factor_id, 0u);
  EXPECT_EQ(u.tissue.solver.pending_id, 0u);

  // demand is the byte before three 8-byte fields and the kept stiffness blocks' key (8 bytes),
  // phase (4) and two arrays (here empty: their 8-byte sizes).
  ASSERT_TRUE(s.tissue.solver.element_blocks.empty());
  std::string bad = bytes;
  bad[bad.size() - 25 - 28] = 2;
  try {
    decode_state(bad, nullptr);
    ADD_FAILURE() << "a flag byte of 2 was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "solver.demand");
  }
}
