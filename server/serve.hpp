#pragma once
/// \file serve.hpp
/// `stroma serve`: the real-time scenario server, composed of parts that each own their options
/// — the DDS side (server/serve_dds.hpp: participant, topics, the publisher, input and feedback
/// threads, CRTK), the physics thread's schedule (runtime/physics_loop.hpp, realtime.hpp), the
/// session log (server/serve_record.hpp) and the statistics (server/serve_stats.hpp); run_serve
/// (server/serve.cpp) wires them. No DDS header here: the CLI includes this.

#include <string>

namespace stroma {

/// DDS: where `serve` talks and what it publishes (server/serve_dds.cpp).
struct ServeDdsOptions {
  int domain = 0;
  std::string dds_config;      ///< Cyclone XML file; empty: CYCLONEDDS_URI or built-in loopback
  std::string security_dir;    ///< --security: a `stroma security init` directory (protected domain)
  double publish_hz = 60;      ///< TissueState rate
  /// --crtk: also expose each tool as a CRTK device on ROS 2's DDS conventions (docs/CRTK.md).
  bool crtk = false;
};

/// The physics thread's schedule (runtime/physics_loop.hpp, runtime/realtime.hpp).
struct ServeTimingOptions {
  std::string realtime = "auto";  ///< auto | fifo | off
  int cpu = -1;                ///< pin the physics thread to this CPU (−1: no pinning)
  int spin_us = 100;           ///< spin this long before each deadline (0: pure sleep)
  /// Each tick's engine work ends this long before the next deadline (ms): its budget is the
  /// period minus this, or solver.time_budget when smaller. Must be ≥ 0 and < the period.
  double budget_margin_ms = 0.15;
  /// Phase-lock the tick schedule so tool commands arrive this long before the tick that takes
  /// them (µs; runtime/phase_lock.hpp); 0: free-running schedule. Must be < the period.
  double phase_lead_us = 200;
  bool start_paused = false;
  double duration = 0;         ///< wall seconds, 0 = until SIGINT/SIGTERM or Control SHUTDOWN
};

/// What `serve` writes besides DDS (server/serve_record.cpp, server/serve_stats.cpp).
struct ServeOutputOptions {
  std::string stats_file;        ///< JSON statistics written at exit
  std::string record_file;       ///< session log of accepted commands and controls (replayable)
  std::string final_state_file;  ///< final state CSV written at exit (compare with a replay)
};

/// Command-line options of `stroma serve`, by the part that owns them.
struct ServeOptions {
  std::string scenario;
  bool converge = false;       ///< --converge: the solver left to the engine (scene/solver_comparison.hpp)
  ServeDdsOptions dds;
  ServeTimingOptions timing;
  ServeOutputOptions outputs;
};

/// Runs the server; returns the process exit code (0 clean, 1 runtime fault, 2 bad input).
/// Throws InputError on a bad scenario (FILE:LINE: FIELD), OptionError on an option that cannot
/// work with it (runtime/option_error.hpp).
int run_serve(const ServeOptions& options);

}  // namespace stroma
