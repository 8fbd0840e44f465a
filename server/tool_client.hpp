#pragma once
/// \file tool_client.hpp
/// `stroma tool`: a DDS tool client. Publishes stroma_ToolCommand from a timed trajectory
/// (YAML/CSV, interpolated) or from stdin lines, receives stroma_ToolFeedback, logs round trips.
/// With `crtk`, it is a CRTK client of `serve --crtk` instead (docs/CRTK.md): enables the device
/// through rt/NAME/state_command, sends rt/NAME/servo_cp, and times each pose's round trip to the
/// first rt/NAME/measured_cp that carries it — the same measure as Stroma's own path, to compare
/// the two in one run (bench/realtime.sh CRTK=1).

#include <string>

namespace stroma {

/// Options of `stroma tool`.
struct ToolClientOptions {
  std::string name = "probe";
  std::string script;        ///< trajectory; empty: read commands from stdin
  double rate = 1000;        ///< Hz (script mode)
  double duration = 0;       ///< s; 0: the script's length (script mode) or until EOF (stdin)
  std::string out_csv;       ///< per-command log: seq, sent, received, round trip, force
  std::string dds_config;
  std::string security_dir;  ///< --security: a `stroma security init` directory (protected domain)
  std::string identity = "tool";  ///< --identity: the client identity in it (NAME.pem, permissions_NAME.p7s)
  int domain = 0;
  double wait_server = 10;   ///< s to wait for the server's command reader before starting
  bool realtime = true;      ///< try SCHED_FIFO for the send and receive threads
  /// Script mode: replay the script from its start each time it ends (for --duration longer
  /// than the script; a script meant to loop ends where it starts).
  bool loop = false;
  bool crtk = false;         ///< --crtk: CRTK topics (ROS 2 wire format) instead of Stroma's own
  /// --resume: send the first pose, then RESUME a paused server (`serve --paused`), so its
  /// first tick already has this tool where the script starts (e.g. jaws closed on a needle
  /// before gravity takes it). A protected domain needs an operator identity.
  bool resume = false;
};

/// Runs the client; returns the exit code (0 ok, 1 no server / no feedback, 2 bad input).
int run_tool_client(const ToolClientOptions& o);

}  // namespace stroma
