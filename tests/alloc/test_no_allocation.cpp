// The hot loop does not allocate: this binary counts every heap allocation — the C allocator
// (malloc, calloc, realloc, aligned allocations: CHOLMOD and other C libraries allocate there)
// and C++'s operator new (which this binary routes through the counted malloc) — and runs ticks
// of real scenarios after a warm-up, asserting that not a single allocation happens while the
// stages it watches (contact, grasp, rupture, body contact, CHOLMOD solves) demonstrably ran.

#include <gtest/gtest.h>

#include <malloc.h>

#include <atomic>
#include <cstdlib>
#include <cstring>
#include <new>
#include <string>

#include "engine/cut_swap.hpp"
#include "engine/damage.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"

namespace {
std::atomic<long> g_allocations{0};
/// This thread's allocations: the physics thread's, where the engine's own worker threads (the
/// preconditioner refresh) may allocate in parallel.
thread_local long t_allocations = 0;
}

// glibc's own entry points, which the interposed C allocator forwards to.
extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
void __libc_free(void*);

void* malloc(size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  ++t_allocations;
  return __libc_malloc(n);
}
void* calloc(size_t n, size_t s) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  ++t_allocations;
  return __libc_calloc(n, s);
}
void* realloc(void* p, size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  ++t_allocations;
  return __libc_realloc(p, n);
}
void* memalign(size_t a, size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  ++t_allocations;
  return __libc_memalign(a, n);
}
void* aligned_alloc(size_t a, size_t n) { return memalign(a, n); }
int posix_memalign(void** out, size_t a, size_t n) {
  void* p = memalign(a, n);
  if (!p) return ENOMEM;
  *out = p;
  return 0;
}
void free(void* p) { __libc_free(p); }
}

void* operator new(std::size_t n) {
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

/// What happened during the counted ticks.
struct Watched {
  long allocations = 0;
  int contact_ticks = 0;     ///< ticks with a tool touching tissue
  int grasp_ticks = 0;       ///< ticks with tissue held
  long ruptures = 0;         ///< elements ruptured during the counted ticks
  int body_contact_ticks = 0;
  int cg_iterations = 0;
  long thread_allocations = 0;  ///< on the ticking thread alone
  int64_t refreshes = 0;        ///< preconditioner factors swapped in
};

/// Warms up for `warmup` ticks, then counts allocations over `ticks` more. `drive` gives tool k's
/// pose at tick i (absent tools: none).
template <class Drive>
Watched run(const ScenarioSpec& spec, int warmup, int ticks, Drive drive) {
  const CompiledScenario sc = compile_scenario(spec);
  const Model& m = *sc.model;
  State s = State::initial(m);
  TickWorkspace w(m);
  std::vector<ToolInput> inputs(m.tools.size());
  auto inputs_at = [&](int i) {
    for (size_t t = 0; t < m.tools.size(); ++t) {
      inputs[t].tool = static_cast<int32_t>(t);
      inputs[t].seq = static_cast<uint64_t>(i + 1);
      inputs[t].pose = drive(sc, s, i);
    }
    return static_cast<int>(inputs.size());
  };
  for (int i = 0; i < warmup; ++i) tick(m, s, w, inputs.data(), inputs_at(i));
  Watched out;
  const long ruptured0 = s.damage_count[kRuptured];
  const long before = g_allocations.load(), thread_before = t_allocations;
  const int64_t refreshes_before = w.stepper().preconditioner_refreshes();
  for (int i = warmup; i < warmup + ticks; ++i) {
    const TickReport& r = tick(m, s, w, inputs.data(), inputs_at(i));
    out.contact_ticks += !r.tools.empty() && r.tools[0].contacts > 0;
    out.grasp_ticks += !s.tools.empty() && s.tools[0].grasped > 0;
    out.body_contact_ticks += r.body_contact.contacts > 0;
    out.cg_iterations += r.solve.iterations;
  }
  out.allocations = g_allocations.load() - before;
  out.thread_allocations = t_allocations - thread_before;
  out.refreshes = w.stepper().preconditioner_refreshes() - refreshes_before;
  out.ruptures = s.damage_count[kRuptured] - ruptured0;
  return out;
}

const std::string kDir = std::string(STROMA_SOURCE_DIR) + "/scenarios/";

/// Into the liver from above, then the jaws close on the second half (grasp).
ToolPose press_then_grasp(const CompiledScenario&, const State&, int i, int total) {
  ToolPose p;
  p.position = {-1.5, 5.5 - 1.0 * std::min(i, total / 2) / (total / 2), 0.5};
  p.jaw = i < total / 2 ? 0.3 : 0.0;
  return p;
}

}  // namespace

TEST(NoAllocation, ImplicitEulerJacobiPcgWithContactAndGrasp) {
  ScenarioSpec s = load_scenario(kDir + "liver.yaml");
  s.tools[0].spec.timeout = 100;
  s.tools[0].spec.max_speed = 1e3;
  const Watched w = run(s, 5, 400, [](const CompiledScenario& c, const State& st, int i) {
    return press_then_grasp(c, st, i, 405);
  });
  EXPECT_EQ(w.allocations, 0);
  EXPECT_GT(w.contact_ticks, 50) << "the counted ticks must include contact";
  EXPECT_GT(w.grasp_ticks, 50) << "the counted ticks must include grasping";
}

// Multirate ticks (fem_every 4, secant model): tissue steps, the tools' models captured and
// rendered every tick.
TEST(NoAllocation, MultirateTicksWithContact) {
  ScenarioSpec s = load_scenario(kDir + "liver.yaml");
  s.tools[0].spec.timeout = 100;
  s.tools[0].spec.max_speed = 1e3;
  s.solver.fem_every = 4;
  s.solver.haptic_secant = true;
  const Watched w = run(s, 8, 400, [](const CompiledScenario& c, const State& st, int i) {
    return press_then_grasp(c, st, i, 408);
  });
  EXPECT_EQ(w.allocations, 0);
  EXPECT_GT(w.contact_ticks, 50) << "the counted ticks must include contact";
}

TEST(NoAllocation, WarpedCholeskyPreconditionerWithCholmodSolves) {
  ScenarioSpec s = load_scenario(kDir + "cantilever_dynamic.yaml");
  s.solver.preconditioner_refresh = 0;  // the rest factor alone: no worker (next test)
  const Watched w = run(s, 5, 100, [](const CompiledScenario&, const State&, int) { return ToolPose{}; });
  EXPECT_EQ(w.allocations, 0);
  EXPECT_GT(w.cg_iterations, 0) << "each CG iteration applies the CHOLMOD factor";
}

// With the factor refreshed on a worker thread: the worker allocates (CHOLMOD's factorisation
// workspace), the ticking thread never does — the hand-off swaps buffers and factor objects.
TEST(NoAllocation, WarpedCholeskyRefreshedOnAWorkerThread) {
  ScenarioSpec s = load_scenario(kDir + "cantilever_dynamic.yaml");
  s.solver.preconditioner_refresh = 4;
  const Watched w = run(s, 5, 100, [](const CompiledScenario&, const State&, int) { return ToolPose{}; });
  EXPECT_EQ(w.thread_allocations, 0);
  EXPECT_GE(w.refreshes, 20) << "factors must have been swapped in during the counted ticks";
  EXPECT_GT(w.allocations, w.thread_allocations) << "the worker's factorisations allocate, and are counted";
}

TEST(NoAllocation, BlockJacobiQrRotationSymplectic) {
  ScenarioSpec s = load_scenario(kDir + "liver.yaml");
  s.solver.preconditioner = Preconditioner::BlockJacobi;
  s.bodies[0].material.rotation = RotationMethod::QR;
  s.tools[0].spec.timeout = 100;
  s.tools[0].spec.max_speed = 1e3;
  auto drive = [](const CompiledScenario& c, const State& st, int i) { return press_then_grasp(c, st, i, 205); };
  const Watched implicit = run(s, 5, 200, drive);
  EXPECT_EQ(implicit.allocations, 0);
  EXPECT_GT(implicit.contact_ticks, 0);
  s.solver.integrator = Integrator::SymplecticEuler;
  s.time_step = 1e-5;
  EXPECT_EQ(run(s, 5, 100, drive).allocations, 0);
}

// The damage scenario's own press: the counted ticks are those in which elements rupture (the
// tear exposes faces, masses move) while the probe is in contact. (Its solver is the engine's
// choice, whose refresh worker allocates off the ticking thread: only that thread is counted.)
TEST(NoAllocation, ContactDamageAndRuptureStages) {
  const ScenarioSpec s = load_scenario(kDir + "regression/liver_probe_damage.yaml");
  const Watched w = run(s, 1600, 400, [](const CompiledScenario& c, const State& st, int) {
    return c.tool_scripts[0].sample(st.time);
  });
  EXPECT_EQ(w.thread_allocations, 0);
  EXPECT_GT(w.ruptures, 0) << "the counted ticks must include ruptures";
  EXPECT_GT(w.contact_ticks, 100);
}

TEST(NoAllocation, BodyContactStage) {
  ScenarioSpec s = load_scenario(kDir + "drop_on_block.yaml");
  s.time_step = 0.004;  // lands after ~8 ticks: most of the counted ticks are in contact
  const Watched w = run(s, 5, 100, [](const CompiledScenario&, const State&, int) { return ToolPose{}; });
  EXPECT_EQ(w.thread_allocations, 0);  // (the engine's solver choice may refresh on a worker)
  EXPECT_GT(w.body_contact_ticks, 50);
}

// Cutting: the scalpel's ticks (the blade's sweep against the edges, contact on the cut
// surface's embedded points) and the swap of each cut model at the tick boundary (the state
// carried into the pre-sized new arrays) — but not the build, which runs off the physics thread.
TEST(NoAllocation, CuttingTicksAndTheTopologySwap) {
  const CompiledScenario sc = compile_scenario(load_scenario(kDir + "regression/liver_incision.yaml"));
  std::shared_ptr<const Model> m = sc.model;
  auto w = std::make_unique<TickWorkspace>(*m);
  State s = State::initial(*m);
  ToolInput in;
  long allocations = 0;
  int swaps = 0, cut_ticks = 0, contact_ticks = 0;
  for (int i = 0; i < 1400; ++i) {
    in.seq = static_cast<uint64_t>(i + 1);
    in.pose = sc.tool_scripts[0].sample(s.time);
    const bool counted = i >= 5;  // after a warm-up
    const long before = t_allocations;
    const TickReport& r = tick(*m, s, *w, &in, 1);
    const int cut = r.cut_edges;
    contact_ticks += counted && r.tools[0].contacts > 0;
    if (counted) allocations += t_allocations - before;
    if (cut == 0) continue;
    ++cut_ticks;
    CutBuild b = build_cut(*m, s.edge_cut);  // off the physics thread in `serve`: not counted
    const long before_swap = t_allocations;
    swaps += apply_cut(b, m, w, s);
    if (counted) allocations += t_allocations - before_swap;
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(swaps, 5) << "the counted ticks must include topology swaps";
  EXPECT_GT(cut_ticks, 20);
  EXPECT_GT(contact_ticks, 100) << "and contact on the cut surface";
  EXPECT_GT(m->collision_embedded.size(), 0u);
}

// The counters work (so a zero above means something): operator new, malloc and calloc.
TEST(NoAllocation, CounterSeesAllocations) {
  long before = g_allocations.load();
  auto* v = new std::string(100, 'x');
  delete v;
  EXPECT_GE(g_allocations.load() - before, 1);
  before = g_allocations.load();
  void* p = std::malloc(64);
  std::memset(p, 0, 64);
  std::free(p);
  EXPECT_EQ(g_allocations.load() - before, 1);
  before = g_allocations.load();
  void* q = std::calloc(8, 8);
  std::free(q);
  EXPECT_EQ(g_allocations.load() - before, 1);
}
