#pragma once
/// \file input_counters.hpp
/// What the server's input thread counts of the controls it forwards to physics. Tool commands
/// are checked and counted by the engine's one commands port (engine/tool_commands.hpp,
/// PhysicsLoop::commands()), whichever topic they came on — Stroma's ToolCommand, or CRTK's
/// servo_cp with --crtk — as they are from Python and `stroma run`.

#include <atomic>
#include <cstdint>

namespace stroma {

/// Control counters of the input thread, published in SimStatus and `serve --stats`.
struct InputCounters {
  std::atomic<uint64_t> controls{0}, controls_dropped{0};
};

}  // namespace stroma
