// The hot loop does not allocate: this binary replaces the global operator new with a counting
// one and runs ticks of real scenarios (Jacobi-PCG, warped-Cholesky PCG with CHOLMOD solves,
// scripted tools) after a warm-up, asserting that not a single heap allocation happens.

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <string>

#include "engine/model.hpp"
#include "engine/scenario_spec.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"

namespace {
std::atomic<long> g_allocations{0};
}

void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

using namespace stroma;

namespace {

long allocations_during_ticks(ScenarioSpec spec, int ticks) {
  auto m = compile_model(spec);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  std::vector<ToolInput> inputs(m->tools.size());
  for (int k = 0; k < 5; ++k) tick(*m, s, w);  // warm-up: lazily sized buffers settle
  const long before = g_allocations.load();
  for (int k = 0; k < ticks; ++k) {
    int n = 0;
    for (size_t t = 0; t < m->tools.size(); ++t) {
      inputs[n].tool = static_cast<int32_t>(t);
      inputs[n].seq = static_cast<uint64_t>(k + 1);
      inputs[n].pose.position = {-1.5, 5.5 - 1.0 * k / ticks, 0.5};  // into the liver: contact
      inputs[n].pose.jaw = k < ticks / 2 ? 0.3 : 0.0;                  // then grasp
      ++n;
    }
    tick(*m, s, w, inputs.data(), n);
  }
  return g_allocations.load() - before;
}

const std::string kDir = std::string(STROMA_SOURCE_DIR) + "/scenarios/";

}  // namespace

TEST(NoAllocation, ImplicitEulerJacobiPcgWithTool) {
  EXPECT_EQ(allocations_during_ticks(load_scenario(kDir + "liver.yaml"), 200), 0);
}

TEST(NoAllocation, WarpedCholeskyPreconditioner) {
  EXPECT_EQ(allocations_during_ticks(load_scenario(kDir + "cantilever_dynamic.yaml"), 100), 0);
}

TEST(NoAllocation, BlockJacobiQrRotationSymplectic) {
  ScenarioSpec s = load_scenario(kDir + "liver.yaml");
  s.solver.preconditioner = Preconditioner::BlockJacobi;
  s.bodies[0].material.rotation = RotationMethod::QR;
  EXPECT_EQ(allocations_during_ticks(s, 100), 0);
  s.solver.integrator = Integrator::SymplecticEuler;
  s.time_step = 1e-5;
  EXPECT_EQ(allocations_during_ticks(s, 100), 0);
}

TEST(NoAllocation, ContactGraspAndDamageStages) {
  ScenarioSpec s = load_scenario(kDir + "regression/liver_probe_damage.yaml");
  s.tools[0].spec.can_grasp = true;
  s.tools[0].spec.max_speed = 1e3;
  EXPECT_EQ(allocations_during_ticks(s, 300), 0);
}

TEST(NoAllocation, BodyContactStage) {
  ScenarioSpec s = load_scenario(kDir + "drop_on_block.yaml");
  s.time_step = 0.004;  // lands after ~8 ticks: most of the counted ticks are in contact
  EXPECT_EQ(allocations_during_ticks(s, 100), 0);
}

// The counter works (so a zero above means something).
TEST(NoAllocation, CounterSeesAllocations) {
  const long before = g_allocations.load();
  auto* v = new std::string(100, 'x');
  delete v;
  EXPECT_GE(g_allocations.load() - before, 1);
}
