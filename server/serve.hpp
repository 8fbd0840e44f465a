#pragma once
/// \file serve.hpp
/// `stroma serve`: the real-time scenario server. No DDS header here: the CLI includes this.

#include <string>

namespace stroma {

/// Command-line options of `stroma serve`.
struct ServeOptions {
  std::string scenario;
  std::string dds_config;      ///< Cyclone XML file; empty: CYCLONEDDS_URI or built-in loopback
  std::string security_dir;    ///< --security: a `stroma security init` directory (protected domain)
  bool converge = false;       ///< --converge: the solver left to the engine (scene/solver_comparison.hpp)
  int domain = 0;
  std::string realtime = "auto";  ///< auto | fifo | off
  int cpu = -1;                ///< pin the physics thread to this CPU (−1: no pinning)
  double duration = 0;         ///< wall seconds, 0 = until SIGINT/SIGTERM or Control SHUTDOWN
  std::string stats_file;      ///< JSON statistics written at exit
  double publish_hz = 60;      ///< TissueState rate
  bool start_paused = false;
  int spin_us = 100;           ///< spin this long before each deadline (0: pure sleep)
  std::string record_file;     ///< session log of accepted commands and controls (replayable)
  std::string final_state_file;  ///< final state CSV written at exit (compare with a replay)
  /// Each tick's engine work ends this long before the next deadline (ms): its budget is the
  /// period minus this, or solver.time_budget when smaller. Must be ≥ 0 and < the period.
  double budget_margin_ms = 0.15;
  /// Phase-lock the tick schedule so tool commands arrive this long before the tick that takes
  /// them (µs; runtime/phase_lock.hpp); 0: free-running schedule. Must be < the period.
  double phase_lead_us = 200;
  /// --crtk: also expose each tool as a CRTK device on ROS 2's DDS conventions (docs/CRTK.md).
  bool crtk = false;
};

/// Runs the server; returns the process exit code (0 clean, 1 runtime fault, 2 bad input).
/// Throws InputError on a bad scenario.
int run_serve(const ServeOptions& options);

}  // namespace stroma
