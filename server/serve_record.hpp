#pragma once
/// \file serve_record.hpp
/// `serve --record FILE`, one part owning its option: the session log (runtime/session_log.hpp:
/// every accepted command and control with its tick, replayable with `stroma run --replay`)
/// written by its own thread from the physics loop's queue — physics never waits on the disk.

#include <cstdint>
#include <cstdio>
#include <string>
#include <thread>

#include "runtime/physics_loop.hpp"
#include "server/serve.hpp"

namespace stroma {

/// What became of the --record log (written by the recorder thread; read after it joined).
struct RecordStatus {
  bool failed = false;          ///< a write failed: the log ends there
  std::string error;            ///< the system's reason (e.g. "No space left on device")
  int64_t stopped_at_tick = 0;  ///< the tick of the last event written before the failure
  uint64_t lines_written = 0;
};

class SessionRecorder {
 public:
  /// Opens the log and writes its header; nothing without --record. Throws std::runtime_error
  /// when the file cannot be written (before anything starts).
  SessionRecorder(const ServeOutputOptions& o, const std::string& scenario, bool converge);
  ~SessionRecorder();  ///< joins and closes if finish() was not called (an exception's path)
  SessionRecorder(const SessionRecorder&) = delete;
  SessionRecorder& operator=(const SessionRecorder&) = delete;

  bool active() const { return f_ != nullptr; }
  /// Starts the recorder thread on `loop` (it drains the loop's queue until the loop finishes).
  void start(PhysicsLoop& loop);
  /// After the loop has finished: joins the thread, closes the log and says whether it replays
  /// (false on any loss or error, said in the log). True without --record.
  bool finish(const PhysicsLoop& loop);
  const RecordStatus& status() const { return rs_; }

 private:
  std::string path_, scenario_;
  std::FILE* f_ = nullptr;
  RecordStatus rs_;
  std::thread thread_;
};

}  // namespace stroma
