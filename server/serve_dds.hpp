#pragma once
/// \file serve_dds.hpp
/// `serve`'s DDS side, one part owning its options (ServeDdsOptions): the participant (loopback
/// only by default; DDS Security with --security), the topics with per-tool command partitions
/// on a protected domain, the scene published once (transient-local), and the three threads that
/// join the physics loop to DDS — publisher (state frames at --publish-hz, status at 10 Hz,
/// damage and topology events), input (controls into the loop's queue, every tool command into
/// its commands port — engine/tool_commands.hpp checks and counts them; CRTK servo_cp with
/// --crtk) and feedback (one ToolFeedback per active tool per tick; CRTK measured_cp/cf).
/// None of them is the physics thread, which never waits on DDS.

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "dds/dds_participant.hpp"
#include "runtime/physics_loop.hpp"
#include "scene/compiled_scenario.hpp"
#include "server/input_counters.hpp"
#include "server/serve.hpp"
#include "server/state_publisher.hpp"

namespace stroma {

class CrtkBridge;
struct Endpoints;

class ServeDds {
 public:
  /// The participant (Cyclone's receive thread at SCHED_FIFO `receive_priority` when > 0 and
  /// allowed), the endpoints, the CRTK devices (--crtk) and the scene published. Throws
  /// std::runtime_error on DDS failures, having closed what it opened.
  ServeDds(const ServeDdsOptions& o, int receive_priority, const CompiledScenario& scenario);
  ~ServeDds();  ///< joins the threads, then closes every DDS entity and the domain's threads
  ServeDds(const ServeDds&) = delete;
  ServeDds& operator=(const ServeDds&) = delete;

  /// Starts the publisher, input and feedback threads on `loop` until it finishes or `stop`
  /// (the input and feedback threads at real-time priority below the physics thread when
  /// `io_realtime`, best effort if denied). `solver` is SimStatus.solver.
  void start(PhysicsLoop& loop, const std::atomic<bool>& stop, const std::string& solver, bool io_realtime);
  /// Joins the threads (after the loop has finished).
  void join();

  const DdsParticipant& participant() const { return pp_; }
  const InputCounters& counters() const { return counters_; }
  uint64_t status_sent() const { return status_sent_.load(); }
  const CrtkBridge* crtk() const { return crtk_.get(); }

 private:
  ServeDdsOptions o_;
  DdsParticipant pp_;
  std::unique_ptr<Endpoints> ep_;
  uint64_t session_ = 0;  ///< a new id per server run: renderers that outlive a server reset on it
  SurfaceExtractor surfaces_;
  std::unique_ptr<CrtkBridge> crtk_;
  InputCounters counters_;
  std::atomic<uint64_t> status_sent_{0};
  std::thread publisher_, inputs_, feedback_;
};

}  // namespace stroma
