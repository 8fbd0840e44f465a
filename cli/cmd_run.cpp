/// \file cmd_run.cpp
/// `stroma run` (headless, outputs into a directory) and `stroma check` (run, then compare the
/// final state with a stored reference).

#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "runtime/headless_runner.hpp"
#include "runtime/output_dir.hpp"
#include "runtime/session_log.hpp"
#include "runtime/state_io.hpp"
#include "scene/sofa_scene.hpp"
#include "scene/solver_comparison.hpp"
#include "scene/solver_report.hpp"
#include "tissue/input_error.hpp"

namespace fs = std::filesystem;

namespace stroma::cli {

CompiledScenario load(const std::string& path, const CompileOptions& options) {
  spdlog::debug("loading scenario {}", path);
  CompiledScenario sc = compile_scenario(load_scenario(path), options);
  for (const auto& n : sc.notes) spdlog::warn("{}", n);
  spdlog::info("scenario '{}': {} bodies, {} nodes, {} tetrahedra, dt {} s", sc.spec.name, sc.spec.bodies.size(),
               sc.model->fem.num_nodes, sc.model->fem.elements.size(), sc.spec.time_step);
  spdlog::info("{}", solver_summary(sc));
  return sc;
}

int explain_scenario(const std::string& path, long ticks) {
  if (is_sofa_scene_path(path)) {
    const SofaTranslation t = translate_sofa_scene_file(path);
    for (const auto& n : t.notes) fmt::print("# note: {}\n", n);
    fmt::print("{}", t.yaml);
  } else {
    fmt::print("# {} is a Stroma scenario already (--explain translates SOFA scenes, .scn)\n", path);
  }
  const CompiledScenario sc = load(path);  // also loads and compiles (else the same error as `run`)
  fmt::print("# {}\n", solver_summary(sc));
  if (sc.model->stepper.integrator != Integrator::ImplicitEuler) return 0;
  // What converging would cost and gain on this scene: both ticked alternately, same inputs.
  spdlog::info("comparing the solve as written with a converged one over {} ticks ...", ticks);
  const SolverComparison c = compare_with_converged(sc.spec, ticks);
  auto line = [&](const char* what, const SolverRun& r) {
    fmt::print("#   {:10s} {}: tick p50 {:.3f} ms, p99 {:.3f} ms; {:.1f} CG iterations; {} of {} ticks reached the "
               "tolerance\n",
               what, r.solver, r.tick_ms.p50, r.tick_ms.p99, r.iterations_mean, r.ticks_converged, c.ticks);
  };
  fmt::print("# What converging would cost and gain ({} ticks of each from rest, alternated; --explain-ticks N):\n",
             c.ticks);
  line("as written", c.as_written);
  line("converged", c.converged);
  fmt::print("#   the solve as written is off by up to {:.3g} m: {:.2f} % of the converged run's largest displacement "
             "({:.3g} m)\n",
             c.difference_max, 100.0 * c.difference_relative, c.converged.max_displacement);
  fmt::print("#   converged costs {:.2f}x the tick (p50); run it so: stroma run {} --converge\n",
             c.as_written.tick_ms.p50 > 0 ? c.converged.tick_ms.p50 / c.as_written.tick_ms.p50 : 0.0, path);
  return 0;
}

namespace {

void print_summary(const Model& m, const RunResult& r) {
  if (m.stepper.integrator == Integrator::Static) {
    fmt::print("static solve: {} equilibri{} in {} load increments, {} Newton iterations, relative residual {:.3g} ({}), "
               "{:.3f} s\n",
               r.steps + 1, r.steps ? "a" : "um", r.static_increments, r.newton_iterations, r.static_residual,
               r.static_converged ? "converged" : "NOT converged", r.wall_seconds);
  } else {
    fmt::print("{} steps, sim time {:.6g} s, wall {:.3f} s; step ms p50 {:.4f} p99 {:.4f} max {:.4f}; "
               "CG iterations mean {:.1f} max {}\n",
               r.steps, r.sim_time, r.wall_seconds, r.step_ms.p50, r.step_ms.p99, r.step_ms.max, r.cg_iterations_mean,
               r.cg_iterations_max);
    if (r.ticks_not_converged) fmt::print("warning: {} ticks hit the CG iteration cap\n", r.ticks_not_converged);
  }
  for (const ProbeModel& p : m.probes) {
    const Vec3 d = probe_displacement(m, r.final_state, p);
    fmt::print("probe {}: displacement [{:.6e}, {:.6e}, {:.6e}] m\n", p.name, d[0], d[1], d[2]);
  }
  for (size_t t = 0; t < m.tools.size() && t < r.final_tools.size(); ++t) {
    const Vec3& f = r.final_tools[t].force;
    fmt::print("tool {}: force on the tool [{:.6e}, {:.6e}, {:.6e}] N, {} contact points\n", m.tools[t].name, f[0],
               f[1], f[2], r.final_tools[t].contacts);
  }
  if (!r.ok) fmt::print("FAILED: {}\n", r.failure);
}

}  // namespace

void add_run(CLI::App& app, std::vector<Command>& out) {
  struct Args {
    std::string scenario, out, replay;
    long steps = -1;
    double duration = -1;
    int vtu_every = 0;
    bool quiet = false, no_metrics = false, explain = false, converge = false;
    long explain_ticks = 500;
  };
  auto a = std::make_shared<Args>();
  auto* run = app.add_subcommand("run", "Run a scenario headless as fast as possible and write results");
  run->add_option("scenario", a->scenario, "Scenario YAML file, or a SOFA scene (.scn; docs/SOFA.md)")
      ->required()
      ->check(CLI::ExistingFile);
  run->add_flag("--explain", a->explain,
                "Print the Stroma scenario a SOFA scene translates to (and what the translation decided), the solver "
                "it runs, and what converging its solves would cost and gain (measured: --explain-ticks), then exit");
  run->add_option("--explain-ticks", a->explain_ticks, "Ticks --explain runs the scene as written and converged")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  run->add_flag("--converge", a->converge,
                "Leave the solver to the engine at the scenario's tolerance (preconditioner, refresh and cap policy "
                "auto, cap >= 1000): for SOFA scenes, which reproduce SOFA's capped unpreconditioned CG otherwise");
  auto* o_steps = run->add_option("--steps", a->steps, "Number of ticks (static: further equilibria after t = 0, "
                                                        "following the tool scripts; overrides run: in the scenario)")
                      ->check(CLI::PositiveNumber);
  run->add_option("--duration", a->duration, "Simulated seconds (overrides run: in the scenario)")
      ->check(CLI::PositiveNumber)
      ->excludes(o_steps);
  run->add_option("--out", a->out, "Output directory (default: out/<scenario name>)");
  run->add_option("--vtu-every", a->vtu_every, "Also write a VTU every K ticks and series.pvd")->check(CLI::NonNegativeNumber);
  run->add_flag("--quiet", a->quiet, "No progress messages");
  run->add_flag("--no-metrics", a->no_metrics, "Skip metrics.csv (saves an energy pass per tick)");
  run->add_option("--replay", a->replay, "Re-execute a session recorded by 'stroma serve --record' (ticks and inputs)")
      ->check(CLI::ExistingFile)
      ->excludes(o_steps);
  run->footer("Writes summary.json, metrics.csv, final.vtu and final_state.csv into the output directory.\n"
              "A failed run (a tick that cannot advance, a static solve that does not converge) writes\n"
              "summary.json with \"status\": \"failed\" and no final state. Exit status: 0 ok, 1 failed, 2 bad input.");
  out.push_back({run, [a] {
                   if (a->explain) return explain_scenario(a->scenario, a->explain_ticks);
                   // A served session ran every tick under a time budget: its replay compiles the
                   // scenario as serve did (the same solver choice; --converge as it was served).
                   CompileOptions co;
                   co.budgeted = !a->replay.empty();
                   co.converge = a->converge;
                   if (!a->replay.empty() && !a->converge && session_log_converged(a->replay)) {
                     co.converge = true;
                     spdlog::info("--replay: the session was served with --converge: replayed with it");
                   }
                   const CompiledScenario sc = load(a->scenario, co);
                   RunOptions o;
                   if (a->steps > 0) o.steps = a->steps;
                   if (a->duration > 0) o.duration = a->duration;
                   o.out_dir = a->out.empty() ? (fs::path("out") / (sc.spec.name.empty() ? "run" : sc.spec.name)).string()
                                              : a->out;
                   o.vtu_every = a->vtu_every;
                   o.progress = !a->quiet;
                   o.metrics = !a->no_metrics;
                   o.replay = a->replay;
                   if (!a->replay.empty()) resolve_steps(sc, o);  // validates the log before any output
                   ensure_writable_dir(o.out_dir);
                   const RunResult r = run_headless(sc, o);
                   print_summary(*sc.model, r);
                   fmt::print("results in {}/ ({})\n", o.out_dir,
                              r.ok ? "summary.json, metrics.csv, final.vtu, final_state.csv"
                                   : "summary.json and metrics.csv of the failed run; no final state");
                   return r.ok ? 0 : 1;
                 }});
}

void add_check(CLI::App& app, std::vector<Command>& out) {
  struct Args {
    std::string scenario, reference, out;
    bool update = false, converge = false;
  };
  auto a = std::make_shared<Args>();
  auto* check = app.add_subcommand("check", "Run a scenario and compare its final state to a reference state");
  check->add_option("scenario", a->scenario, "Scenario YAML file, or a SOFA scene (.scn)")->required()->check(CLI::ExistingFile);
  check->add_option("reference", a->reference, "Reference state CSV (node,x,y,z), as written by run (final_state.csv)")
      ->required();
  check->add_option("--out", a->out, "Also write the run's outputs here");
  check->add_flag("--update", a->update, "Write the reference from this run instead of comparing");
  check->add_flag("--converge", a->converge, "Leave the solver to the engine at the scenario's tolerance (as run --converge)");
  check->footer("Tolerances come from the scenario's check: section (max_error, mean_error, metres).\n"
                "Exit status: 0 within tolerance, 1 outside (or the run failed), 2 bad input.");
  out.push_back({check, [a] {
                   CompileOptions co;
                   co.converge = a->converge;
                   const CompiledScenario sc = load(a->scenario, co);
                   const Model& model = *sc.model;
                   std::vector<double> ref;
                   if (!a->update) ref = read_state_csv(a->reference);  // fail before running
                   // (A cutting scenario ends with the cut model's DOFs: compared after the run.)
                   if (!ref.empty() && !model.cutting && ref.size() != model.fem.rest.size())
                     throw InputError(a->reference, 0, "",
                                      fmt::format("reference has {} nodes, the scenario has {}", ref.size() / 3,
                                                  model.fem.num_nodes));
                   RunOptions o;
                   o.out_dir = a->out;
                   o.progress = false;
                   o.metrics = !a->out.empty();
                   if (!a->out.empty()) ensure_writable_dir(a->out);
                   const RunResult r = run_headless(sc, o);
                   if (a->update) {
                     if (!r.ok) {
                       fmt::print("FAILED: {}; reference not written\n", r.failure);
                       return 1;
                     }
                     write_state_csv(a->reference, r.final_state);
                     fmt::print("reference written: {} ({} nodes, {} steps)\n", a->reference,
                                r.final_state.tissue.x.size() / 3, r.steps);
                     return 0;
                   }
                   if (r.ok && r.final_state.tissue.x.size() != ref.size()) {
                     fmt::print("check {}: the run ended with {} nodes, the reference has {} (the cuts separated the "
                                "mesh differently) -> FAIL\n",
                                sc.spec.name, r.final_state.tissue.x.size() / 3, ref.size() / 3);
                     return 1;
                   }
                   const StateDifference d = compare_positions(r.final_state.tissue.x, ref);
                   const CheckSpec& tol = sc.spec.check;
                   const bool ok = d.max_error <= tol.max_error && d.mean_error <= tol.mean_error && r.ok;
                   const std::string worst = d.worst_node >= 0 ? fmt::format(" at node {}", d.worst_node) : "";
                   if (!r.ok) fmt::print("the run failed: {}\n", r.failure);
                   fmt::print("check {}: {} steps; max nodal error {:.3e} m{} (tolerance {:.1e}); mean {:.3e} m "
                              "(tolerance {:.1e}) -> {}\n",
                              sc.spec.name, r.steps, d.max_error, worst, tol.max_error, d.mean_error, tol.mean_error,
                              ok ? "PASS" : "FAIL");
                   return ok ? 0 : 1;
                 }});
}

}  // namespace stroma::cli
