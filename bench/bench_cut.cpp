/// \file bench_cut.cpp
/// What a cut costs, on a scenario's mesh: a blade incises the body along a straight path over
/// many ticks, and each tick is timed by phase — finding the edges the blade crossed (the scan,
/// every tick), and, when that split a tetrahedron, rebuilding the topology, the cut FemModel,
/// a TimeStepper for it (what the engine will do off the physics thread) and carrying the state
/// over (what it will do at the swap). Then the cost of stepping the cut model against the uncut
/// one (implicit Euler, the scenario's solver settings, gravity), the same number of steps.
///
/// Usage: stroma_bench_cut SCENARIO [--runs R] [--ticks N] [--depth F] [--markdown]
/// Reports medians over runs of the per-run p50/p99/max (the machine is shared and noisy).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "bench/bench_stats.hpp"
#include "engine/model.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tissue/cut_blade.hpp"
#include "tissue/cut_model.hpp"
#include "tissue/time_stepper.hpp"

using namespace stroma;

using bench::median;
using bench::percentile;

namespace {

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// Per-run figures of one phase.
struct Phase {
  std::vector<double> p50, p99, max;
  void add(const std::vector<double>& v) {
    p50.push_back(percentile(v, 0.5));
    p99.push_back(percentile(v, 0.99));
    max.push_back(v.empty() ? 0 : *std::max_element(v.begin(), v.end()));
  }
};

/// Milliseconds per implicit step of `fem` from `s` over `steps` steps (median).
double step_ms(const FemModel& fem, const StepperSettings& settings, double h, TissueState s, int steps) {
  TimeStepper st(fem, settings);
  st.prepare(h);
  std::vector<double> t;
  for (int i = 0; i < steps; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    st.assemble(s, h, {});
    st.solve(s);
    st.integrate(s, h);
    t.push_back(ms_since(t0));
  }
  return median(t);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"The cost of cutting a scenario's mesh: per-tick phases of an incision, and stepping cut vs uncut"};
  std::string scenario;
  int runs = 5, ticks = 300;
  double depth = 0.25;
  bool markdown = false;
  app.add_option("scenario", scenario, "scenario YAML (every body the blade crosses is cut)")->required();
  app.add_option("--runs", runs, "repetitions (medians reported)")->check(CLI::Range(1, 1000));
  app.add_option("--ticks", ticks, "ticks of the incision")->check(CLI::Range(10, 100000));
  app.add_option("--depth", depth, "blade depth as a fraction of the body's height")->check(CLI::Range(0.01, 1.0));
  app.add_flag("--markdown", markdown, "print a Markdown table row");
  CLI11_PARSE(app, argc, argv);

  const std::shared_ptr<const Model> model = compile_model(load_scenario(scenario));
  const FemModel& fem = model->fem;
  const double h = model->fem_step;
  // The blade: a vertical edge from the top of the body down `depth` of its height, moving
  // along x through the middle of its y extent, across the whole body over the ticks.
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (int32_t n = 0; n < fem.num_nodes; ++n)
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], fem.rest[3 * n + k]);
      hi[k] = std::max(hi[k], fem.rest[3 * n + k]);
    }
  const double ymid = 0.5 * (lo[1] + hi[1]) + 1e-4 * (hi[1] - lo[1]);  // off the mesh's symmetry planes
  const double ztop = hi[2] + 0.01 * (hi[2] - lo[2]), zbot = hi[2] - depth * (hi[2] - lo[2]);
  const auto blade_x = [&](int tick) { return lo[0] - 0.01 * (hi[0] - lo[0]) + (hi[0] - lo[0]) * 1.02 * tick / ticks; };

  Phase scan, topology, cut_model, stepper, transfer;
  std::vector<double> rebuilds;
  CutTopology final_topo;
  double split_fraction = 0;
  for (int r = 0; r < runs; ++r) {
    const CutBase base = make_cut_base(fem);
    std::vector<double> edge_cut(base.adj.edges.size(), kEdgeUncut);
    CutTopology topo = build_cut_topology(base.tets, fem.rest, base.adj, edge_cut, base.node_ranges);
    TissueState s = TissueState::at_rest(fem);
    std::vector<double> t_scan, t_topo, t_model, t_stepper, t_transfer;
    for (int tick = 1; tick <= ticks; ++tick) {
      const double x0 = blade_x(tick - 1), x1 = blade_x(tick);
      const SweptBlade blade{{x0, ymid, ztop}, {x0, ymid, zbot}, {x1, ymid, ztop}, {x1, ymid, zbot}};
      auto t0 = std::chrono::steady_clock::now();
      const int n = cut_edges(fem.rest.data(), base.adj, blade, edge_cut);
      t_scan.push_back(ms_since(t0));
      if (n == 0) continue;
      t0 = std::chrono::steady_clock::now();
      CutTopology next = build_cut_topology(base.tets, fem.rest, base.adj, edge_cut, base.node_ranges);
      t_topo.push_back(ms_since(t0));
      if (next.num_dofs == topo.num_dofs && next.split_tets == topo.split_tets) {  // nothing separated yet
        topo = std::move(next);
        continue;
      }
      t0 = std::chrono::steady_clock::now();
      const FemModel cut = build_cut_fem_model(fem, next);
      t_model.push_back(ms_since(t0));
      t0 = std::chrono::steady_clock::now();
      {
        TimeStepper st(cut, model->stepper);
        st.prepare(h);
      }
      t_stepper.push_back(ms_since(t0));
      TissueState moved;
      t0 = std::chrono::steady_clock::now();
      transfer_state(s, continued_dofs(topo, next), moved);
      t_transfer.push_back(ms_since(t0));
      s = std::move(moved);
      topo = std::move(next);
    }
    scan.add(t_scan);
    topology.add(t_topo);
    cut_model.add(t_model);
    stepper.add(t_stepper);
    transfer.add(t_transfer);
    rebuilds.push_back(static_cast<double>(t_model.size()));
    final_topo = topo;
    split_fraction = static_cast<double>(topo.split_tets) / static_cast<double>(base.tets.size());
  }
  // Stepping cost, cut vs uncut, from rest under the scenario's loads.
  const FemModel cut = build_cut_fem_model(fem, final_topo);
  TissueState s_cut;
  {
    const CutBase base = make_cut_base(fem);
    const std::vector<double> none(base.adj.edges.size(), kEdgeUncut);
    const CutTopology uncut_topo = build_cut_topology(base.tets, fem.rest, base.adj, none, base.node_ranges);
    transfer_state(TissueState::at_rest(fem), continued_dofs(uncut_topo, final_topo), s_cut);
  }
  std::vector<double> uncut_ms, cut_ms;
  for (int r = 0; r < runs; ++r) {
    uncut_ms.push_back(step_ms(fem, model->stepper, h, TissueState::at_rest(fem), 200));
    cut_ms.push_back(step_ms(cut, model->stepper, h, s_cut, 200));
  }

  const auto row = [&](const char* name, const Phase& p) {
    std::printf("%-28s p50 %8.3f  p99 %8.3f  max %8.3f ms\n", name, median(p.p50), median(p.p99), median(p.max));
  };
  std::printf("%s: %d nodes, %zu tets; incision %d ticks, blade depth %.0f %% of the height; %d runs\n",
              model->name.c_str(), fem.num_nodes, fem.elements.size(), ticks, 100 * depth, runs);
  std::printf("after the incision: %d tets split (%.1f %%), %d copies, %d DOFs (+%d), %zu surface triangles (%d cut "
              "edges), %d rebuilds per run\n",
              final_topo.split_tets, 100 * split_fraction, static_cast<int>(final_topo.copies.size()),
              final_topo.num_dofs, final_topo.num_dofs - fem.num_nodes, final_topo.triangles.size(),
              final_topo.cut_edges, static_cast<int>(median(rebuilds)));
  row("scan (every tick)", scan);
  row("topology (edges cut)", topology);
  row("cut FemModel (split)", cut_model);
  row("TimeStepper + prepare", stepper);
  row("state transfer", transfer);
  std::printf("implicit step, uncut: %.3f ms; cut: %.3f ms (median of %d runs of 200 steps)\n", median(uncut_ms),
              median(cut_ms), runs);
  if (markdown)
    std::printf("| %s | %zu | %d | %.3f / %.3f | %.3f / %.3f | %.3f / %.3f | %.3f / %.3f | %.3f / %.3f | %.3f | %.3f |\n",
                model->name.c_str(), fem.elements.size(), final_topo.split_tets, median(scan.p50), median(scan.p99),
                median(topology.p50), median(topology.p99), median(cut_model.p50), median(cut_model.p99),
                median(stepper.p50), median(stepper.p99), median(transfer.p50), median(transfer.p99),
                median(uncut_ms), median(cut_ms));
  return 0;
}
