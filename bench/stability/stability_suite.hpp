#pragma once
/// \file stability_suite.hpp
/// `stroma bench stability`: numerical-stability stress cases and their pass criteria.
///  - grid: time step × Young's modulus × Poisson's ratio × mesh (good; with slivers; with
///    elements initially inverted), the cantilever of refs/d released under gravity;
///  - extreme loads: the clamped end turned 180° in 0.1 s, large initial velocities, the tool
///    driven at 5 m/s into the liver, a bar dropped onto a fixed block (body contact).
/// A case passes when no NaN/Inf ever reaches the state, the total energy stays within the work
/// put in (never above its start plus 1 % of the energies involved; for driven cases, it does
/// not grow once the drive stops), inverted elements have recovered at the end, and every tick
/// either converged or reported hitting the CG cap with a finite state.

#include <string>
#include <vector>

namespace stroma {

/// Outcome of one stress case.
struct StabilityResult {
  std::string name;         ///< e.g. "grid dt=5ms E=1e4 nu=0.49 slivers"
  std::string group;        ///< "grid" or "extreme"
  bool pass = false;
  std::string why;          ///< the failed criteria ("" if passed)
  int ticks = 0;
  bool finite = true;
  double energy_ratio = 0;  ///< (max total energy − allowed) / energy scale; ≤ 0.01 passes
  int max_cg_iterations = 0;
  int cg_capped = 0;        ///< ticks that hit the CG cap (reported, finite)
  int recovered = 0;        ///< ticks redone in sub-steps
  int rolled_back = 0;      ///< ticks rolled back unadvanced
  double min_volume_ratio = 1;   ///< worst V/V₀ of any element at any tick (< 0: inverted)
  int inverted_start = 0, inverted_end = 0;
  double wall_seconds = 0;
};

/// Options of `stroma bench stability`.
struct StabilityOptions {
  bool quick = false;        ///< a subset that runs in well under a minute (ctest)
  std::string source_dir;    ///< the repository (scenarios/ and meshes)
  std::string csv;           ///< write every result here ("" = none)
  bool markdown = false;     ///< print the table in Markdown
  std::string only;          ///< run only the cases whose name contains this ("" = all)
  int newton_iterations = 0; ///< > 0: every case's solver.newton_iterations (0 = the scenarios')
  bool progress = true;
};

/// Runs the suite; returns the results in order (also printed).
std::vector<StabilityResult> run_stability_suite(const StabilityOptions& options);

}  // namespace stroma
