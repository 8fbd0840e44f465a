/// \file bench_kernels.cpp
/// Google Benchmark of the hot kernels on real scenarios: rotation extraction, the element pass
/// (forces; forces + K·v + assembly), BSR SpMV, one CG solve, one whole tick.
/// Run: build/bench/stroma_bench_kernels --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
/// Counters: per_element / per_dof are ns per item of one call.

#include <benchmark/benchmark.h>

#include <random>
#include <string>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tissue/cholmod_solver.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/nodal_smoothing.hpp"
#include "tissue/rotation.hpp"

using namespace stroma;

namespace {

const char* kScenarioNames[] = {"liver", "armadillo", "cantilever_dynamic", "physical/liver_fine_16cm",
                              "physical/beam_k6_converged", "physical/armadillo_0p2m"};

std::shared_ptr<const Model> model_for(int i, RotationMethod rot = RotationMethod::Polar) {
  ScenarioSpec s = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/" + kScenarioNames[i] + ".yaml");
  for (auto& b : s.bodies) b.material.rotation = rot;
  return compile_model(s);
}

/// A state some way into the scenario (deformed, moving), so rotations and CG are realistic.
State warmed_state(const Model& m, TickWorkspace& w, int ticks = 100) {
  State s = State::initial(m);
  for (int k = 0; k < ticks; ++k) tick(m, s, w);
  return s;
}

void BM_PolarRotationBatch8(benchmark::State& st) {
  std::mt19937 g(3);
  std::uniform_real_distribution<double> u(-1, 1);
  double F[9][8], R[9][8];
  for (auto& row : F)
    for (double& v : row) v = u(g);
  for (auto _ : st) {
    benchmark::DoNotOptimize(F);
    polar_rotation_batch<8>(F, R);
    benchmark::DoNotOptimize(R);
    benchmark::ClobberMemory();
  }
  st.counters["ns_per_element"] = benchmark::Counter(8.0, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_PolarRotationBatch8);

template <int W>
void BM_PolarRotationBatchW(benchmark::State& st) {
  std::mt19937 g(3);
  std::uniform_real_distribution<double> u(-1, 1);
  double F[9][W], R[9][W];
  for (auto& row : F)
    for (double& v : row) v = u(g);
  for (auto _ : st) {
    benchmark::DoNotOptimize(F);
    polar_rotation_batch<W>(F, R);
    benchmark::DoNotOptimize(R);
    benchmark::ClobberMemory();
  }
  st.counters["ns_per_element"] = benchmark::Counter(double(W), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_PolarRotationBatchW<16>);
BENCHMARK(BM_PolarRotationBatchW<32>);



void BM_QrRotation(benchmark::State& st) {
  std::mt19937 g(3);
  std::uniform_real_distribution<double> u(-1, 1);
  double rest[9], e1[3] = {1, 0.1, 0}, e2[3] = {0.2, 1, 0.1}, R[9];
  edge_frame(e1, e2, rest);
  double c1[3] = {u(g), u(g), u(g)}, c2[3] = {u(g), u(g), u(g)};
  for (auto _ : st) {
    benchmark::DoNotOptimize(c1);
    benchmark::DoNotOptimize(c2);
    qr_rotation(rest, c1, c2, R);
    benchmark::DoNotOptimize(R);
    benchmark::ClobberMemory();
  }
  st.counters["ns_per_element"] = benchmark::Counter(1.0, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_QrRotation);

/// Element pass. arg0: scenario; arg1: 0 forces only, 1 forces + assembly (the implicit tick),
/// 2 forces + K·v (symplectic with stiffness damping), 3 energy only (the energy guard); arg2: 0 polar, 1 QR.
void BM_ElementPass(benchmark::State& st) {
  auto m = model_for(static_cast<int>(st.range(0)), st.range(2) ? RotationMethod::QR : RotationMethod::Polar);
  TickWorkspace w(*m);
  State s = warmed_state(*m, w);
  std::vector<double> f(m->fem.dofs()), kv(m->fem.dofs()), K(9 * m->fem.pattern.nnzb()), rot(9 * m->fem.elements.size());
  ElasticPass p;
  p.x = s.tissue.x.data();
  p.force = st.range(1) == 3 ? nullptr : f.data();
  if (st.range(1) == 2) {
    p.v = s.tissue.v.data();
    p.kv = kv.data();
    p.kv_beta = 1;
  }
  if (st.range(1) == 1) {
    p.kvals = K.data();
    p.k_beta = m->time_step;
    p.k_const = m->time_step * m->time_step;
    p.rotations = rot.data();
  }
  for (auto _ : st) {
    benchmark::DoNotOptimize(elastic_pass(m->fem, p));
    benchmark::ClobberMemory();
  }
  st.SetLabel(std::string(kScenarioNames[st.range(0)]) + (st.range(1) == 1 ? " forces+assembly" : st.range(1) == 2 ? " forces+Kv" : st.range(1) == 3 ? " energy" : " forces") + (st.range(2) ? " qr" : " polar"));
  st.counters["ns_per_element"] = benchmark::Counter(static_cast<double>(m->fem.elements.size()),
                                                     benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_ElementPass)->ArgsProduct({{0, 1, 3}, {0, 1, 2, 3}, {0, 1}})->Unit(benchmark::kMicrosecond);

/// The visco-elastic element pass (forces + assembly with the branches' history stress) on the
/// 16 cm liver with its tumour and a two-branch Prony series, against the same pass without the
/// history (arg 0: corotational without it, 1: visco-elastic corotational, 2: visco-elastic
/// stable Neo-Hookean, 3: stable Neo-Hookean without it).
void BM_ViscoElementPass(benchmark::State& st) {
  ScenarioSpec spec = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/physical/liver_16cm_tumour_visco.yaml");
  if (st.range(0) >= 2)
    for (auto& b : spec.bodies) b.material.model = ElementModel::StableNeoHookean;
  auto m = compile_model(spec);
  TickWorkspace w(*m);
  State s = warmed_state(*m, w);
  std::vector<double> f(m->fem.dofs()), K(9 * m->fem.pattern.nnzb());
  ElasticPass p;
  p.x = s.tissue.x.data();
  p.force = f.data();
  p.kvals = K.data();
  p.k_const = m->time_step * m->time_step;
  if (st.range(0) == 1 || st.range(0) == 2) {
    p.visco_q = s.tissue.visco_q.data();
    p.visco_s0 = s.tissue.visco_s0.data();
    p.visco_h = m->time_step;
  }
  for (auto _ : st) {
    benchmark::DoNotOptimize(elastic_pass(m->fem, p));
    benchmark::ClobberMemory();
  }
  const char* labels[] = {"corotational", "visco corotational", "visco stable neo-Hookean", "stable neo-Hookean"};
  st.SetLabel(labels[st.range(0)]);
  st.counters["ns_per_element"] = benchmark::Counter(static_cast<double>(m->fem.elements.size()),
                                                     benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_ViscoElementPass)->DenseRange(0, 3)->Unit(benchmark::kMicrosecond);

/// The implicit tick's element pass (forces + assembly) per element model on the same organ.
/// arg0: scenario; arg1: 0 corotational, 1 stable Neo-Hookean, 2 St. Venant-Kirchhoff,
/// 3 stable Neo-Hookean with fibres (k1 50 kPa, k2 8, along x).
void BM_ElementModel(benchmark::State& st) {
  ScenarioSpec s = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/" + kScenarioNames[st.range(0)] + ".yaml");
  const ElementModel models[] = {ElementModel::Corotational, ElementModel::StableNeoHookean,
                                 ElementModel::StVenantKirchhoff, ElementModel::StableNeoHookean};
  const char* names[] = {"corotational", "stable NH", "StVK", "stable NH + fibres"};
  for (auto& b : s.bodies) {
    b.material.model = models[st.range(1)];
    if (st.range(1) == 3) {
      FibreSpec f;
      f.k1 = 5e4;
      f.k2 = 8;
      b.material.fibres = f;
    }
  }
  auto m = compile_model(s);
  TickWorkspace w(*m);
  State state = warmed_state(*m, w);
  std::vector<double> f(m->fem.dofs()), K(9 * m->fem.pattern.nnzb());
  ElasticPass p;
  p.x = state.tissue.x.data();
  p.force = f.data();
  p.kvals = K.data();
  p.k_beta = m->time_step;
  p.k_const = m->time_step * m->time_step;
  for (auto _ : st) {
    benchmark::DoNotOptimize(elastic_pass(m->fem, p));
    benchmark::ClobberMemory();
  }
  st.SetLabel(std::string(kScenarioNames[st.range(0)]) + " " + names[st.range(1)]);
  st.counters["ns_per_element"] = benchmark::Counter(static_cast<double>(m->fem.elements.size()),
                                                     benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_ElementModel)->ArgsProduct({{0, 3}, {0, 1, 2, 3}})->Unit(benchmark::kMicrosecond);

void BM_Spmv(benchmark::State& st) {
  auto m = model_for(static_cast<int>(st.range(0)));
  TickWorkspace w(*m);
  State s = warmed_state(*m, w);
  std::vector<double> K;
  w.stepper().stiffness(s.tissue, K);
  std::vector<double> y(m->fem.dofs());
  for (auto _ : st) {
    bsr_spmv(m->fem.pattern, K.data(), s.tissue.x.data(), y.data());
    benchmark::DoNotOptimize(y.data());
    benchmark::ClobberMemory();
  }
  st.SetLabel(kScenarioNames[st.range(0)]);
  st.counters["blocks"] = m->fem.pattern.nnzb();
}
BENCHMARK(BM_Spmv)->DenseRange(0, 3)->Unit(benchmark::kMicrosecond);

/// The locking-free node domains' matrix-free product (NodalSystem::apply, one per CG
/// iteration) on the 16 cm liver in SI at ν 0.49, against the element matrix's SpMV on the same
/// one-ring pattern (docs/PERFORMANCE.md, "Locking-free").
void BM_NodalProduct(benchmark::State& st) {
  ScenarioSpec s = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/physical/liver_fine_16cm.yaml");
  s.bodies[0].material.poisson_ratio = 0.49;
  s.bodies[0].material.locking_free = LockingFreeSpec{};
  auto m = compile_model(s);
  TickWorkspace w(*m);
  State state = warmed_state(*m, w);
  NodalSystem ns(m->fem);
  std::vector<double> K(9 * static_cast<size_t>(m->fem.pattern.nnzb()), 0.0);
  ns.begin();
  ElasticPass p;
  p.x = state.tissue.x.data();
  p.kvals = K.data();
  p.k_const = 1.0;
  p.nodal_system = &ns;
  elastic_pass(m->fem, p);
  ns.finish();
  std::vector<double> y(m->fem.dofs());
  for (auto _ : st) {
    if (st.range(0) == 0) ns.apply(state.tissue.v.data(), y.data());
    else bsr_spmv(m->fem.pattern, K.data(), state.tissue.v.data(), y.data());
    benchmark::DoNotOptimize(y.data());
    benchmark::ClobberMemory();
  }
  st.SetLabel(st.range(0) == 0 ? "node domains, matrix-free" : "elements, BSR SpMV");
  st.counters["domains"] = m->fem.smoothing.domains();
  st.counters["patch_entries"] = static_cast<double>(m->fem.smoothing.patch_node.size());
}
BENCHMARK(BM_NodalProduct)->DenseRange(0, 1)->Unit(benchmark::kMicrosecond);

/// One CG solve of a warmed-up tick's system (cold start: the worst case of a tick).
void BM_CgSolve(benchmark::State& st) {
  auto m = model_for(static_cast<int>(st.range(0)));
  TickWorkspace w(*m);
  State s = warmed_state(*m, w);
  w.stepper().assemble(s.tissue, m->time_step, step_inputs(*m, s, w));
  int iters = 0;
  for (auto _ : st) {
    std::fill(s.tissue.dv.begin(), s.tissue.dv.end(), 0.0);
    iters = w.stepper().solve(s.tissue).iterations;
  }
  st.SetLabel(kScenarioNames[st.range(0)]);
  st.counters["cg_iterations"] = iters;
}
BENCHMARK(BM_CgSolve)->DenseRange(0, 1)->Unit(benchmark::kMicrosecond);

/// CHOLMOD on a warmed-up tick's system matrix: numeric factorisation (arg1 0), one solve with
/// that factor (1: cholmod_solve2, 2: the single-precision copy, tissue/supernodal_f32.hpp) —
/// the costs of refreshing a Cholesky preconditioner and of applying it once.
void BM_Cholmod(benchmark::State& st) {
  auto m = model_for(static_cast<int>(st.range(0)));
  TickWorkspace w(*m);
  State s = warmed_state(*m, w, 50);
  w.stepper().assemble(s.tissue, m->time_step, step_inputs(*m, s, w));
  std::vector<double> K;
  w.stepper().stiffness(s.tissue, K);
  // A = M + h(β + h)K with the model's masses: the shape of the implicit system.
  const double h = m->time_step;
  for (auto& k : K) k *= h * h + h * 0.01;
  for (int32_t i = 0; i < m->fem.num_nodes; ++i)
    for (int32_t slot = m->fem.pattern.row_ptr[i]; slot < m->fem.pattern.row_ptr[i + 1]; ++slot)
      if (m->fem.pattern.col[slot] == i)
        for (int k = 0; k < 3; ++k) K[9 * slot + 4 * k] += m->fem.mass[i] > 0 ? m->fem.mass[i] : 1.0;
  CholmodSolver chol(m->fem.pattern);
  if (st.range(1) == 2) chol.use_float_solves();
  if (!chol.factor(K.data())) st.SkipWithError("not positive definite");
  std::vector<double> b(m->fem.dofs(), 1.0), x(m->fem.dofs());
  for (auto _ : st) {
    if (st.range(1) == 0) benchmark::DoNotOptimize(chol.factor(K.data()));
    else chol.solve(b.data(), x.data());
    benchmark::ClobberMemory();
  }
  st.SetLabel(std::string(kScenarioNames[st.range(0)]) +
              (st.range(1) == 2 ? " solve float" : st.range(1) ? " solve" : " factor"));
  st.counters["dofs"] = static_cast<double>(m->fem.dofs());
  st.counters["L_entries"] = chol.factor_entries();
  st.counters["factor_flops"] = chol.factor_flops();
}
BENCHMARK(BM_Cholmod)->ArgsProduct({{0, 1, 3, 4, 5}, {0, 1, 2}})->Unit(benchmark::kMicrosecond);

void BM_Tick(benchmark::State& st) {
  auto m = model_for(static_cast<int>(st.range(0)));
  TickWorkspace w(*m);
  State s = warmed_state(*m, w);
  const State s0 = s;
  long n = 0;
  for (auto _ : st) {
    tick(*m, s, w);
    if (++n % 1000 == 0) s = s0;  // stay in the same regime
  }
  st.SetLabel(kScenarioNames[st.range(0)]);
}
BENCHMARK(BM_Tick)->DenseRange(0, 2)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
