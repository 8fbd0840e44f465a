#pragma once
/// \file accuracy_suite.hpp
/// `stroma bench accuracy`: run time against error on the reference problems of
/// tests/data/refs (copied from the CalculiX/analytic references):
///  - cantilever_static (refs/a): tip deflection under gravity, against the converged
///    reference −1.4735e-3 m; sweeps mesh × element model × linear solver and tolerance;
///  - block_compression (refs/c): bonded block, ν = 0.49, pressed 1 %: top force against
///    0.3049 N (volumetric locking of linear tets), with CalculiX C3D4 on the same mesh;
///  - indentation (refs/e): rigid sphere 1 mm into a soft bonded block, force against 0.019604 N;
///    sweeps mesh grading at the contact, penalty stiffness, element model;
///  - viscoelastic (the lectures' closed form): a standard-linear-solid bar under sinusoidal
///    strain, its complex modulus E* against E0[1 − g + g·iωτ/(1 + iωτ)]; sweeps steps per
///    period, ωτ over three decades, element model;
///  - fibres (closed form): a stable Neo-Hookean bar with HGO fibres pulled along and across
///    them, the uniaxial stress at the stretch reached against the applied load; sweeps the
///    stretch (1.03 … 1.3) and the mesh;
///  - cantilever_dynamic (refs/d): first bending frequency measured from the tip's motion after
///    gravity is switched on, against 16.100 Hz; sweeps mesh × time step, CG tolerance, CG
///    iteration cap, warm start, element model, and symplectic Euler at its largest stable step.
/// Each configuration: error, wall time per tick and per simulated second (median of runs).
/// Output: a CSV per problem (Pareto-optimal points marked), a log–log PNG plot per problem
/// (gnuplot, when installed: one series per sweep; only the Pareto front's points are labelled,
/// numbered 1, 2, … in time order), the numbers' table (<problem>_pareto.md beside the CSV) and
/// Markdown tables.

#include <string>
#include <vector>

namespace stroma {

/// One configuration's outcome.
struct AccuracyPoint {
  std::string problem, label;  ///< label: the configuration, e.g. "h 2.5 mm, dt 1 ms, CG 1e-6"
  std::string sweep;           ///< which factor this point varies ("mesh x dt", "CG tolerance", …)
  double value = 0;            ///< the measured quantity (m or Hz)
  double reference = 0;
  double error = 0;            ///< |value − reference| / |reference|
  /// Dynamic, mesh × dt sweep: |f − f_mesh| / f_mesh against the same mesh at the smallest
  /// step — the time integrator's share of the error (−1: not computed). Block: the CalculiX
  /// C3D4 force on the same mesh.
  double time_error = -1;
  double ms_per_tick = 0;      ///< dynamic: median over runs; static: 0
  double s_per_sim_s = 0;      ///< dynamic: wall seconds per simulated second; static: solve seconds
  int nodes = 0;
  bool pareto = false;         ///< no other point of the problem is both faster and more accurate
  /// false: the point does not solve the problem as stated (a peer whose material differs from
  /// the reference's, e.g. Bullet's neo-Hookean given μ, λ unchanged: its error is partly a
  /// material error), so it is shown but neither on nor against the Pareto front.
  bool same_problem = true;
  bool ok = true;              ///< false: the run failed (diverged, no oscillation found)
  std::string failure;         ///< why it failed ("" if ok)
};

/// Options of `stroma bench accuracy`.
struct AccuracyOptions {
  bool quick = false;       ///< fewer levels and runs: a few minutes
  int runs = 3;             ///< timing repetitions (median)
  std::string source_dir;   ///< repository (scenarios/, meshes)
  std::string out_dir = "out/bench/accuracy";
  bool progress = true;
  /// The Bullet peer program (build/bench/stroma_bench_bullet), run in the same benchmark and
  /// put on the same tables and plots; empty: no peers.
  std::string peer_program;
  /// Run only this problem ("cantilever" (static and dynamic), "indentation",
  /// "block_compression", "viscoelastic", "fibres" or "fibre_ring"; empty: all).
  std::string only;
};

/// Runs the problems (all, or options.only); writes CSVs, plots and Pareto number tables and
/// prints Markdown tables; returns every point.
std::vector<AccuracyPoint> run_accuracy_suite(const AccuracyOptions& options);

/// `stroma bench accuracy --replot DIR`: redraws the plots from CSVs in the suite's format without
/// running anything. For every problem with a csv_dir/<problem>.csv or csv_dir/accuracy_<problem>.csv
/// (the Pareto column as it stands), writes the gnuplot script <stem>.gp and the Pareto number
/// table <stem>_pareto.md beside the CSV and the plot to png_dir/<stem>.png, and prints the number
/// tables. Returns the points read.
std::vector<AccuracyPoint> replot_accuracy_csvs(const std::string& csv_dir, const std::string& png_dir);

struct ThickRing;

/// The inhomogeneous fibre problem (bench/accuracy/thick_ring.hpp): a quarter of the ring,
/// nr × nθ cells in (R, θ) and one layer in z (plane strain: both faces slide in their planes),
/// fibre directions read from the mesh (`direction: mesh`), the dead inner pressure as nodal
/// forces on the inner facets; static Newton with CHOLMOD in load steps. value: the inner
/// surface's mean radial displacement (m); reference: the 1-D solution's; error: relative.
/// Writes the mesh and scenario to out_dir.
AccuracyPoint run_fibre_ring(const std::string& out_dir, const ThickRing& ring, int nr, int ntheta, int runs);

}  // namespace stroma
