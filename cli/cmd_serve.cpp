/// \file cmd_serve.cpp
/// `stroma serve` (the real-time server) and `stroma tool` (a DDS tool client). Built with
/// STROMA_WITH_DDS.

#include "cli/commands.hpp"
#include "server/serve.hpp"
#include "server/tool_client.hpp"

namespace stroma::cli {

void add_serve(CLI::App& app, std::vector<Command>& out) {
  auto srv = std::make_shared<ServeOptions>();
  auto* serve = app.add_subcommand("serve", "Run a scenario in real time (one tick per time step of wall time) and serve it over DDS");
  serve->add_option("scenario", srv->scenario, "Scenario YAML file or SOFA scene .scn (a dynamic one: static scenarios have no time to serve)")
      ->required()
      ->check(CLI::ExistingFile);
  serve->add_option("--security", srv->dds.security_dir, "Run a protected domain (DDS Security) with the identity 'server' of this 'stroma security init' directory: only permitted clients command tools, state and feedback are encrypted")->check(CLI::ExistingDirectory);
  serve->add_option("--dds-config", srv->dds.dds_config, "Cyclone DDS XML configuration (default: CYCLONEDDS_URI, else built-in loopback-only)")
      ->check(CLI::ExistingFile);
  serve->add_option("--domain", srv->dds.domain, "DDS domain id")->capture_default_str()->check(CLI::Range(0, 232));
  serve->add_option("--realtime", srv->timing.realtime, "auto: try SCHED_FIFO + mlockall, warn and go on if denied; fifo: required; off")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "fifo", "off"}));
  serve->add_option("--cpu", srv->timing.cpu, "Pin the physics thread to this CPU")->check(CLI::NonNegativeNumber);
  serve->add_option("--duration", srv->timing.duration, "Stop after this many wall seconds (default: until Ctrl-C or Control SHUTDOWN)")
      ->check(CLI::NonNegativeNumber);
  serve->add_option("--stats", srv->outputs.stats_file, "Write timing statistics (JSON) here at exit");
  serve->add_option("--publish-hz", srv->dds.publish_hz, "TissueState rate")->capture_default_str()->check(CLI::Range(1.0, 1000.0));
  serve->add_flag("--paused", srv->timing.start_paused, "Start paused (resume or step with stroma_Control)");
  serve->add_flag("--converge", srv->converge,
                  "Leave the solver to the engine at the scenario's tolerance (preconditioner, refresh and cap policy "
                  "auto, cap >= 1000): for SOFA scenes, which reproduce SOFA's capped unpreconditioned CG otherwise");
  serve->add_option("--spin-us", srv->timing.spin_us, "Wake this many microseconds early and spin to each deadline (0: sleep only)")
      ->capture_default_str()
      ->check(CLI::Range(0, 900));
  serve->add_option("--record", srv->outputs.record_file, "Log every accepted tool command and control with its tick (replay: stroma run --replay)");
  serve->add_option("--final-state", srv->outputs.final_state_file, "Write the final state (node,x,y,z CSV) at exit");
  serve->add_option("--budget-margin-ms", srv->timing.budget_margin_ms,
                    "Each tick's engine work must end this long before the next deadline: its time budget is the "
                    "period minus this (or solver.time_budget if smaller); what does not fit degrades stably")
      ->capture_default_str();
  serve->add_option("--phase-lead-us", srv->timing.phase_lead_us,
                    "Follow the tool commands' phase: shift the tick schedule (at most 2 % of a period per tick) "
                    "so that commands arrive this long before the tick that takes them; 0: fixed schedule")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  serve->add_flag("--crtk", srv->dds.crtk,
                  "Also expose each tool as a CRTK device in ROS 2's DDS conventions: rt/<tool>/servo_cp, "
                  "state_command in; measured_cp, measured_cf, operating_state out (docs/CRTK.md)");
  serve->footer(
      "Network: by default every DDS participant is on the loopback interface only, without multicast\n"
      "(secure by default). To serve on a LAN, copy dds/cyclonedds-loopback.xml, replace \"lo\" by\n"
      "your interface and pass it with --dds-config FILE (or set CYCLONEDDS_URI).\n"
      "Topics: stroma_TissueMesh, stroma_TissueState, stroma_SimStatus (out), stroma_Control (in); see docs/DDS.md.");
  out.push_back({serve, [srv] { return run_serve(*srv); }});
}

void add_tool(CLI::App& app, std::vector<Command>& out) {
  auto tco = std::make_shared<ToolClientOptions>();
  auto* tool = app.add_subcommand("tool", "Drive a tool of a running server over DDS from a trajectory or stdin, and log force feedback");
  tool->add_option("--name", tco->name, "Tool name (as in the scenario's tools:)")->capture_default_str();
  tool->add_option("--script", tco->script, "Trajectory (YAML keyframes or CSV t,x,y,z[,qw,qx,qy,qz][,jaw]); default: read 'x y z [qw qx qy qz] [jaw]' lines from stdin")
      ->check(CLI::ExistingFile);
  tool->add_option("--rate", tco->rate, "Command rate in Hz (script mode)")->capture_default_str()->check(CLI::Range(1.0, 10000.0));
  tool->add_option("--duration", tco->duration, "Seconds (default: the script's length / until end of stdin)")->check(CLI::NonNegativeNumber);
  tool->add_option("--out", tco->out_csv, "CSV log: seq, sent, received, round trip (ms), force");
  tool->add_option("--security", tco->security_dir, "Join a protected domain (DDS Security) with --identity from this 'stroma security init' directory")->check(CLI::ExistingDirectory);
  tool->add_option("--identity", tco->identity, "Client identity in the --security directory (NAME.pem, permissions_NAME.p7s)")->capture_default_str();
  tool->add_option("--dds-config", tco->dds_config, "Cyclone DDS XML (default: CYCLONEDDS_URI, else built-in loopback-only)")->check(CLI::ExistingFile);
  tool->add_option("--domain", tco->domain, "DDS domain id")->capture_default_str()->check(CLI::Range(0, 232));
  tool->add_option("--wait", tco->wait_server, "Seconds to wait for a server")->capture_default_str();
  tool->add_flag("!--no-realtime", tco->realtime, "Do not ask for SCHED_FIFO for the send/receive threads");
  tool->add_flag("--loop", tco->loop, "Replay the script from its start each time it ends (with a longer --duration)");
  tool->add_flag("--resume", tco->resume,
                 "Send the first pose, then RESUME a paused server (serve --paused): its first tick has this tool where the "
                 "script starts (e.g. jaws closed on a needle before gravity takes it); needs an operator identity on a "
                 "protected domain");
  tool->add_flag("--crtk", tco->crtk,
                 "Be a CRTK client of `serve --crtk` (docs/CRTK.md): enable the device, send rt/NAME/servo_cp and time "
                 "each pose's round trip to the first rt/NAME/measured_cp carrying it");
  out.push_back({tool, [tco] { return run_tool_client(*tco); }});
}

}  // namespace stroma::cli
