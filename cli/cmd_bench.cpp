/// \file cmd_bench.cpp
/// `stroma bench stability` (numerical-stability stress suite) and `stroma bench accuracy`
/// (run time against error on the reference problems, optional Bullet peers). The suites live
/// in bench/ (library stroma_bench_suites).

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>

#include "bench/accuracy/accuracy_suite.hpp"
#include "bench/stability/stability_suite.hpp"
#include "cli/commands.hpp"
#include "runtime/output_dir.hpp"
#include "tissue/input_error.hpp"

namespace fs = std::filesystem;

namespace stroma::cli {

void add_bench(CLI::App& app, std::vector<Command>& out) {
  auto* bench = app.add_subcommand("bench", "Measured claims: run time against error, numerical-stability stress suite");
  bench->require_subcommand(1);
  auto sto = std::make_shared<StabilityOptions>();
  sto->source_dir = STROMA_SOURCE_DIR;
  auto* stab = bench->add_subcommand("stability", "Stress cases (time step x stiffness x Poisson x mesh quality; extreme loads) with pass criteria");
  stab->add_flag("--quick", sto->quick, "A subset that runs in under a minute (what ctest runs)");
  stab->add_option("--only", sto->only, "Run only the cases whose name contains this text (e.g. dropped)");
  stab->add_option("--newton", sto->newton_iterations, "Run every case with this many Newton iterations per tick (solver.newton_iterations)")
      ->check(CLI::Range(1, 50));
  stab->add_option("--csv", sto->csv, "Write every case's figures here");
  stab->add_flag("--markdown", sto->markdown, "Print the table as Markdown (docs/STABILITY.md)");
  stab->add_option("--source-dir", sto->source_dir, "Repository with scenarios/ (default: where stroma was built from)")
      ->check(CLI::ExistingDirectory);
  stab->footer("Pass: no NaN/Inf ever; total energy (kinetic + elastic + gravity + contact) never above its start\n"
               "(for driven cases: above its value when the drive stops) by more than 1 % of the energies seen;\n"
               "no element inverted at the end; every tick advanced (CG capped ticks are reported).\n"
               "Exit status 1 if any case fails.");
  out.push_back({stab, [sto] {
                   const auto results = run_stability_suite(*sto);
                   const long failed =
                       std::count_if(results.begin(), results.end(), [](const StabilityResult& r) { return !r.pass; });
                   fmt::print("{} of {} cases passed\n", results.size() - failed, results.size());
                   return failed ? 1 : 0;
                 }});

  struct AccuracyArgs {
    AccuracyOptions o;
    bool peers = false;
    std::string replot;  ///< redraw from the CSVs in this directory instead of running
  };
  auto aco = std::make_shared<AccuracyArgs>();
  aco->o.source_dir = STROMA_SOURCE_DIR;
  auto* acc = bench->add_subcommand("accuracy", "Run time against error on the reference problems (cantilever static and dynamic, bonded block, sphere indentation, visco-elastic bar, fibre-reinforced bar and inflated fibre ring), with Pareto fronts");
  acc->add_flag("--quick", aco->o.quick, "Fewer levels: a few minutes");
  acc->add_option("--runs", aco->o.runs, "Timing repetitions per configuration (median)")->capture_default_str()->check(CLI::Range(1, 50));
  acc->add_option("--out", aco->o.out_dir, "Output directory (CSV, PNG plots, gnuplot scripts)")->capture_default_str();
  acc->add_option("--only", aco->o.only, "Run one problem only (cantilever: static and dynamic; with --peers: only its peer)")
      ->check(CLI::IsMember({"cantilever", "indentation", "block_compression", "viscoelastic", "fibres", "fibre_ring"}));
  acc->add_flag("--peers", aco->peers, "Also run the Bullet peers (build/bench/stroma_bench_bullet) on the same problems and meshes and put them on the same tables and plots (adds ~25 min; ~12 min with --quick)");
  acc->add_option("--source-dir", aco->o.source_dir, "Repository with scenarios/ (default: where stroma was built from)")
      ->check(CLI::ExistingDirectory);
  acc->add_option("--replot", aco->replot,
                  "Run nothing: redraw the plots from DIR/<problem>.csv or DIR/accuracy_<problem>.csv (the suite's CSV "
                  "format) into --out (default: beside the CSVs); the gnuplot scripts and Pareto number tables go beside the CSVs")
      ->check(CLI::ExistingDirectory)
      ->excludes("--quick")
      ->excludes("--peers")
      ->excludes("--only");
  acc->footer("References: tip deflection -1.4735e-3 m (refs/a, converged C3D10), first frequency 16.100 Hz\n"
              "(refs/d), block top force 0.3049 N (refs/c), indentation force 0.019604 N at 1 mm (refs/e).\n"
              "Writes <problem>.csv, <problem>.png (only the Pareto front's points labelled, numbered in time order) and\n"
              "<problem>_pareto.md (the numbers' configurations) per problem into --out and prints Markdown tables.");
  out.push_back({acc, [aco, acc] {
                   AccuracyOptions o = aco->o;
                   if (!aco->replot.empty()) {
                     const std::string png_dir = acc->get_option("--out")->count() > 0 ? o.out_dir : aco->replot;
                     ensure_writable_dir(png_dir);
                     const auto points = replot_accuracy_csvs(aco->replot, png_dir);
                     if (points.empty())
                       throw InputError("", 0, "--replot",
                                        fmt::format("no <problem>.csv or accuracy_<problem>.csv in {}", aco->replot));
                     fmt::print("{} points redrawn; plots in {}/\n", points.size(), png_dir);
                     return 0;
                   }
                   ensure_writable_dir(o.out_dir);
                   if (aco->peers) {
                     const fs::path peer = fs::canonical("/proc/self/exe").parent_path() / "bench" / "stroma_bench_bullet";
                     if (!fs::exists(peer))
                       throw InputError("", 0, "--peers",
                                        fmt::format("{} not found (it is built when libbullet-dev is installed: scripts/setup.sh)",
                                                    peer.string()));
                     o.peer_program = peer.string();
                   }
                   const auto points = run_accuracy_suite(o);
                   const long failed =
                       std::count_if(points.begin(), points.end(), [](const AccuracyPoint& p) { return !p.ok; });
                   fmt::print("{} configurations, {} failed to produce a measurement; results in {}/\n", points.size(), failed,
                              o.out_dir);
                   return 0;
                 }});
}

}  // namespace stroma::cli
